"""Reading a photograph: oriented, complete, at a working resolution — the one photo reader.

Every photo Face Studio reads (a photo added to a project, ``facestudio new``, the project's
photo check, texturing) goes through :func:`read_photo`, which

* **applies the EXIF orientation** (OpenCV's ``IMREAD_COLOR`` does so by default, in
  ``cv2.imread`` and ``cv2.imdecode`` alike; ``IMREAD_UNCHANGED`` does *not*, which is why no
  photo is read with it). The ``width``/``height`` a project stores are the oriented size, and
  clicks are pixels of the oriented original photo (:mod:`photomodel.camera`'s conventions).
* **refuses a photo that decodes only partly** with a :class:`PhotoError` naming the file.
  OpenCV returns a truncated JPEG as an image whose missing part is grey, with only a libjpeg
  warning on stderr, so the file's structure is checked first (:func:`truncation_problem`): a
  JPEG must hold an end-of-image marker (``FF D9``) after its last start-of-scan marker
  (``FF DA``) — the entropy-coded data cannot contain ``FF D9`` (a data byte ``FF`` is always
  followed by ``00``), and an embedded EXIF thumbnail's own markers come *before* the main
  image's scans, so this holds for a complete file with a thumbnail, with a progressive scan
  sequence or with bytes appended after it (a phone's second picture) and fails for a file cut
  anywhere after its headers. A PNG must end with its ``IEND`` chunk (trailing bytes after it are
  tolerated). Other formats (WebP, BMP, PPM, TIFF) are refused by OpenCV itself when cut short.
  Pillow, which Face Studio uses for EXIF, is not used to decode: it would be a second image
  reader whose pixels (colour management, orientation) might differ from OpenCV's.
* **bounds memory on very large photos**: a photo whose longer side exceeds
  :data:`MAX_WORKING_SIDE` (6000 px, ≈ 81 MB as 8-bit RGB) is decoded at 1/2, 1/4 or 1/8 of
  its size (``cv2.IMREAD_REDUCED_COLOR_*``: libjpeg decodes a JPEG directly at the reduced size,
  never holding the full one), then resized down if still larger. Other formats (PNG, TIFF…)
  are decoded in full and averaged down (``cv2.INTER_AREA``): OpenCV's reduced read of those
  decodes in full anyway and then drops pixels, so only JPEG saves memory this way — the
  format of every camera's large photos. The size is known before
  decoding from the file header (Pillow reads only the header). The original file is kept and
  untouched; :attr:`PhotoImage.scale` maps between the working image and the original's pixels
  (:func:`to_original`, :func:`to_working`), so clicks stay in original pixels.
* gives a **fingerprint** (:func:`fingerprint`, a 32 × 32 grey thumbnail) by which two photos
  that are the same image — the same file twice, or one re-saved or resized — are found
  (:func:`duplicate_pairs`): their thumbnails differ by at most :data:`DUPLICATE_MEAN_DIFF`
  grey levels on average, whereas two different views of a head (even frames of one video a
  few degrees apart) differ by several. A duplicate is a warning, not an error.
"""

from __future__ import annotations

import os
import re
import warnings
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np
from PIL import Image

from photomodel.errors import PhotoError

#: The longer side (px) of the working image: photos larger than this are decoded reduced.
MAX_WORKING_SIDE = 6000
#: Image file suffixes Face Studio reads as photos (lower case): what OpenCV decodes.
PHOTO_SUFFIXES = (".jpg", ".jpeg", ".png", ".webp", ".tif", ".tiff", ".bmp", ".ppm", ".pgm")
#: Photo files Face Studio does not read, and what to do instead: a folder's such files are
#: listed (:func:`unreadable_photos_in_folder`) rather than passed over in silence. OpenCV's
#: wheels decode none of these (HEIF/AVIF need codecs it is built without; raw files need
#: demosaicing, and their embedded previews are small and lens-corrected differently).
UNREADABLE_PHOTO_SUFFIXES = {
    **dict.fromkeys((".heic", ".heif", ".avif"), "export it as JPEG; on a phone, choose the Most Compatible format"),
    **dict.fromkeys(
        (".dng", ".cr2", ".cr3", ".nef", ".arw", ".raf", ".orf", ".rw2", ".pef", ".srw"),
        "a camera raw file: develop it to JPEG or TIFF first",
    ),
    ".gif": "convert it to PNG",
}
#: Two photos whose 32 × 32 grey thumbnails differ by at most this many grey levels (0-255)
#: on average are the same image. Re-encoding a JPEG at quality 75 or resizing it changes the
#: thumbnail by well under 1 level; a head turned by 2-3 degrees changes it by 3 or more.
DUPLICATE_MEAN_DIFF = 1.5
FINGERPRINT_SIZE = 32

_EXIF_ORIENTATION = 0x0112
_REDUCED = {
    1: cv2.IMREAD_COLOR,
    2: cv2.IMREAD_REDUCED_COLOR_2,
    4: cv2.IMREAD_REDUCED_COLOR_4,
    8: cv2.IMREAD_REDUCED_COLOR_8,
}
_PNG_IEND = b"IEND\xaeB`\x82"  # the IEND chunk type and its (fixed) CRC


@dataclass
class PhotoImage:
    """A decoded photo at its working resolution.

    Attributes
    ----------
    path : Path, the file read.
    image : (h, w, 3) uint8 RGB, EXIF orientation applied, at most :data:`MAX_WORKING_SIDE`
        (or the ``max_side`` asked for) on its longer side.
    width, height : int, the size of the oriented *original* photo in pixels (what a project
        stores and clicks refer to).
    scale : float, working-image pixels per original pixel (1.0 when read at full size);
        ``image.shape[1] / width``.
    """

    path: Path
    image: np.ndarray
    width: int
    height: int
    scale: float

    @property
    def reduced(self) -> bool:
        """True when the working image is smaller than the original."""
        return self.image.shape[:2] != (self.height, self.width)


def read_photo(path: str | os.PathLike, max_side: int | None = MAX_WORKING_SIDE) -> PhotoImage:
    """Decode a photo: EXIF orientation applied, refused when truncated, reduced when very large.

    Parameters
    ----------
    path : str or PathLike, an image file.
    max_side : int or None, the largest longer side (px) of the working image; ``None``: the
        full size whatever it is.

    Returns
    -------
    PhotoImage

    Raises
    ------
    PhotoError
        naming the file, when it does not exist, is not an image OpenCV reads, is truncated or
        cannot be decoded.
    """
    path = Path(path)
    data = _read_bytes(path)
    if not data:
        raise PhotoError(f"{path.name}: the file is empty (0 bytes; {path})")
    problem = truncation_problem(data)
    if problem:
        raise PhotoError(f"{path.name}: {problem}; the file is damaged or was not copied whole ({path})")
    width, height = _header_size(path)
    factor = 1
    # libjpeg decodes a JPEG at 1/2, 1/4, 1/8 by scaling its DCT blocks (a proper low-pass, never
    # the full image in memory); other decoders would decode in full and then drop pixels
    # (aliasing), so those are decoded in full and averaged down (INTER_AREA) below
    if max_side is not None and width and height and data[:3] == b"\xff\xd8\xff":
        while factor < 8 and max(width, height) / factor > max_side:
            factor *= 2
    try:
        img = cv2.imdecode(np.frombuffer(data, np.uint8), _REDUCED[factor])
    except cv2.error:  # OpenCV asserts on some malformed headers instead of returning None
        img = None
    if img is None or img.ndim != 3 or img.size == 0:
        raise PhotoError(f"{path.name}: not an image this program can decode (unknown format or damaged; {path})")
    if factor == 1 or not width:
        height, width = img.shape[:2]  # the decoder's oriented size is the truth at full size
    elif (img.shape[1] > img.shape[0]) != (width > height) and img.shape[0] != img.shape[1]:
        width, height = height, width  # the decoder did not apply the header's orientation (PNG)
    if max_side is not None and max(img.shape[:2]) > max_side:
        s = max_side / max(img.shape[:2])
        size = (max(1, round(img.shape[1] * s)), max(1, round(img.shape[0] * s)))
        img = cv2.resize(img, size, interpolation=cv2.INTER_AREA)
    rgb = cv2.cvtColor(img, cv2.COLOR_BGR2RGB)
    return PhotoImage(path=path, image=rgb, width=int(width), height=int(height), scale=rgb.shape[1] / width)


def photo_size(path: str | os.PathLike) -> tuple[int, int]:
    """``(width, height)`` of the oriented original photo, from a full check and decode at the
    working resolution (:func:`read_photo`); :class:`PhotoError` naming the file otherwise."""
    p = read_photo(path)
    return p.width, p.height


def truncation_problem(data: bytes) -> str | None:
    """Why an image file's bytes are cut short, or ``None`` (see the module docstring).

    Only JPEG and PNG are checked here (recognised by their signatures); other formats are
    left to the decoder, which refuses them when cut short.
    """
    if data[:3] == b"\xff\xd8\xff":  # JPEG
        last_scan = data.rfind(b"\xff\xda")
        if last_scan < 0:
            return "truncated JPEG (no image data after the headers)"
        if data.rfind(b"\xff\xd9") < last_scan:
            return "truncated JPEG (the image data stops before its end marker)"
    elif data[:8] == b"\x89PNG\r\n\x1a\n" and data.rfind(_PNG_IEND) < 0:
        return "truncated PNG (no IEND chunk at the end)"
    return None


def to_original(uv: np.ndarray, scale: float) -> np.ndarray:
    """(..., 2) pixel positions in a working image of ``scale`` → the original photo's pixels
    (pixel centres at integers in both: ``u = (u' + 0.5) / scale − 0.5``)."""
    return (np.asarray(uv, float) + 0.5) / scale - 0.5


def to_working(uv: np.ndarray, scale: float) -> np.ndarray:
    """(..., 2) pixel positions in the original photo → a working image of ``scale``."""
    return (np.asarray(uv, float) + 0.5) * scale - 0.5


def fingerprint(image: np.ndarray) -> np.ndarray:
    """(32, 32) float32 grey thumbnail of an RGB ``image`` (any size), for :func:`duplicate_pairs`."""
    grey = cv2.cvtColor(np.ascontiguousarray(image), cv2.COLOR_RGB2GRAY)
    return cv2.resize(grey, (FINGERPRINT_SIZE, FINGERPRINT_SIZE), interpolation=cv2.INTER_AREA).astype(np.float32)


def duplicate_pairs(fingerprints: list[np.ndarray]) -> list[tuple[int, int]]:
    """Pairs ``(i, j)``, ``i < j``, of fingerprints that are the same image
    (mean absolute difference ≤ :data:`DUPLICATE_MEAN_DIFF` grey levels)."""
    if len(fingerprints) < 2:
        return []
    f = np.stack([np.asarray(x, np.float32).ravel() for x in fingerprints])
    diff = np.abs(f[:, None, :] - f[None, :, :]).mean(axis=2)
    i, j = np.nonzero(np.triu(diff <= DUPLICATE_MEAN_DIFF, k=1))
    return list(zip(i.tolist(), j.tolist(), strict=True))


def photos_in_folder(folder: str | os.PathLike) -> list[Path]:
    """The photo files (:data:`PHOTO_SUFFIXES`, any case) directly in ``folder``, in name order
    as a file browser shows them (case-insensitive, numbers by value: ``IMG_2`` before ``IMG_10``);
    :class:`PhotoError` when the folder does not exist or holds none."""
    folder = Path(folder)
    if not folder.is_dir():
        raise PhotoError(f"{folder}: no such folder")
    paths = files_in_folder(folder, PHOTO_SUFFIXES)
    if not paths:
        unreadable = unreadable_photos_in_folder(folder)
        if unreadable:
            raise PhotoError(
                f"{folder}: no photos this program reads in it; " + "; ".join(unreadable_note(p) for p in unreadable)
            )
        raise PhotoError(f"{folder}: no photos in it (looked for {', '.join(PHOTO_SUFFIXES)})")
    return paths


def unreadable_photos_in_folder(folder: str | os.PathLike) -> list[Path]:
    """The photo files directly in ``folder`` that :func:`photos_in_folder` passes over because
    they are not read (:data:`UNREADABLE_PHOTO_SUFFIXES`: HEIC, camera raw…), in name order."""
    folder = Path(folder)
    return files_in_folder(folder, tuple(UNREADABLE_PHOTO_SUFFIXES)) if folder.is_dir() else []


def unreadable_note(path: Path) -> str:
    """What to do about a photo file of an unread type (:data:`UNREADABLE_PHOTO_SUFFIXES`), naming it."""
    return (
        f"{path.name} is not read ({path.suffix.lstrip('.').upper()}: {UNREADABLE_PHOTO_SUFFIXES[path.suffix.lower()]})"
    )


def files_in_folder(folder: Path, suffixes: tuple[str, ...]) -> list[Path]:
    """The visible files directly in ``folder`` with one of ``suffixes`` (lower case, matched in
    any case), in name order (:func:`name_order`); hidden ones (``.name``) are left out."""
    return sorted(
        (p for p in folder.iterdir() if p.is_file() and p.suffix.lower() in suffixes and not p.name.startswith(".")),
        key=name_order,
    )


def name_order(path: Path) -> tuple:
    """Sort key of a file name: case-folded text and runs of digits by value, then the name
    (``re.split`` with a group alternates text and digits, so like compares with like)."""
    parts = re.split(r"(\d+)", path.name.casefold())
    return [int(x) if i % 2 else x for i, x in enumerate(parts)], path.name


def _read_bytes(path: Path) -> bytes:
    if not path.is_file():
        raise PhotoError(f"{path.name}: no such file (looked for {path})")
    try:
        return path.read_bytes()
    except OSError as exc:
        raise PhotoError(f"{path.name}: cannot be read: {exc.strerror or exc}") from exc


def _header_size(path: Path) -> tuple[int, int]:
    """The oriented ``(width, height)`` from the file header, without decoding the pixels;
    ``(0, 0)`` when Pillow cannot tell (the decoder's size is used then)."""
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")  # DecompressionBombWarning, corrupt EXIF: the size is all we need
            with Image.open(path) as im:
                w, h = im.size
                orientation = im.getexif().get(_EXIF_ORIENTATION, 1)
    except Image.DecompressionBombError as exc:
        raise PhotoError(f"{path.name}: too large to read safely ({exc}); reduce it first ({path})") from exc
    except Exception:  # Pillow lacks a format OpenCV has, or a corrupt header: decode to find out
        return 0, 0
    return (h, w) if orientation in (5, 6, 7, 8) else (w, h)
