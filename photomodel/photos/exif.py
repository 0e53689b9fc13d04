"""The lens of a photograph from its EXIF tags: a first guess of the focal length.

:func:`focal_mm_36_from_exif` gives the 35 mm-equivalent focal length (the lens that would
frame the same view on a 36 × 24 mm sensor) from, in this order:

1. ``FocalLengthIn35mmFilm`` (tag 0xA405), when present and > 0;
2. ``FocalLength`` (0x920A) × 36 / the sensor's long side, the sensor's size in mm being the
   image's pixel size divided by ``FocalPlaneXResolution`` / ``FocalPlaneYResolution``
   (0xA20E / 0xA20F, pixels per unit of ``FocalPlaneResolutionUnit``, 0xA210: 2 inch, 3 cm,
   4 mm, 5 µm). The focal-plane resolution counts pixels of the camera's original image, so the
   pixel size is that of ``ExifImageWidth`` / ``ExifImageHeight`` (0xA002 / 0xA003) when those
   tags are present (an image resized after shooting keeps its tags) and the file's own size
   otherwise.

Anything else — no EXIF, a missing tag, a zero or non-numeric value, a corrupt EXIF block, a
file that is not an image — gives ``None``: a focal length is a guess the fit improves on, and a
photo without one is normal, never an error. A value outside :data:`PLAUSIBLE_35MM` (from a
fisheye to the longest telephoto) is treated as corrupt and also gives ``None``.

Project units: a photo's ``focal_mm_guess`` is "mm on a sensor 36 mm wide *across the image's
width*" (:func:`photomodel.camera.focal_mm_to_px`), which is the 35 mm equivalent for a landscape
image but not for one stored in portrait orientation; :func:`focal_mm_guess_from_exif` does that
conversion for an image of a given size.

EXIF is read with Pillow, a kept library (the Python imaging library, maintained for decades)
and now a main dependency of Face Studio rather than a test-only one: OpenCV, which reads our
images, does not expose EXIF tags at all (it only applies the orientation tag), and parsing the
TIFF structure inside a JPEG's APP1 segment by hand (byte order, IFD offsets, rational types,
maker quirks) is exactly the kind of code that breaks on real cameras' files. Pillow opens files
lazily, so this reads the header and the EXIF block, not the pixels.
"""

from __future__ import annotations

import math
import os
import warnings

from PIL import Image

EXIF_IFD = 0x8769
TAG_MAKE = 0x010F
TAG_MODEL = 0x0110
TAG_FOCAL_LENGTH = 0x920A
TAG_FOCAL_LENGTH_35MM = 0xA405
TAG_EXIF_IMAGE_WIDTH = 0xA002
TAG_EXIF_IMAGE_HEIGHT = 0xA003
TAG_FOCAL_PLANE_X_RES = 0xA20E
TAG_FOCAL_PLANE_Y_RES = 0xA20F
TAG_FOCAL_PLANE_RES_UNIT = 0xA210

#: FocalPlaneResolutionUnit → millimetres per unit (EXIF 2.3: 2 = inch, 3 = cm; 4 = mm and
#: 5 = µm are used by some cameras)
RESOLUTION_UNIT_MM = {2: 25.4, 3: 10.0, 4: 1.0, 5: 1e-3}

#: 35 mm-equivalent focal lengths (mm) taken as real; outside this is a corrupt tag
PLAUSIBLE_35MM = (4.0, 2000.0)

FULL_FRAME_WIDTH_MM = 36.0


def focal_mm_36_from_exif(path: str | os.PathLike) -> float | None:
    """The 35 mm-equivalent focal length (mm) recorded in an image file's EXIF, or ``None``.

    Parameters
    ----------
    path : str or PathLike
        an image file (JPEG, TIFF, WebP, PNG with an eXIf chunk... whatever Pillow opens).

    Returns
    -------
    float or None
        the focal length a lens would need on a 36 × 24 mm sensor for the same field of view
        across the image's long side; ``None`` when the file does not say (see the module
        docstring for the tags read). Never raises for a bad file or bad tags.
    """
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")  # Pillow warns "Corrupt EXIF data" and then copes
            f = _focal_35mm(path)
    except Exception:  # a file we cannot read is a photo without a focal length
        return None
    if f is None or not (PLAUSIBLE_35MM[0] <= f <= PLAUSIBLE_35MM[1]):
        return None
    return f


def focal_mm_guess_from_exif(path: str | os.PathLike, width: int, height: int) -> float | None:
    """:func:`focal_mm_36_from_exif` in the project's units for a ``width × height`` image:
    mm on a 36 mm-wide sensor across the image's *width* (``Photo.focal_mm_guess``). Equal to
    the 35 mm equivalent for landscape images; × height / width for portrait ones (the same
    field of view across a shorter side). ``None`` when the EXIF has no focal length."""
    f = focal_mm_36_from_exif(path)
    if f is None or width <= 0 or height <= 0:
        return None
    return f * max(width, height) / width


def _focal_35mm(path) -> float | None:

    with Image.open(path) as img:
        exif = img.getexif()
        size = img.size
        tags = dict(exif)  # IFD0: a few writers put the Exif-IFD tags here
        tags.update(exif.get_ifd(EXIF_IFD))

    f35 = _number(tags.get(TAG_FOCAL_LENGTH_35MM))
    if f35 is not None and f35 > 0:
        return f35

    f = _number(tags.get(TAG_FOCAL_LENGTH))
    xres = _number(tags.get(TAG_FOCAL_PLANE_X_RES))
    unit_tag = tags.get(TAG_FOCAL_PLANE_RES_UNIT, 2)  # EXIF's default: inch
    unit = RESOLUTION_UNIT_MM.get(_integer(unit_tag))
    if f is None or f <= 0 or xres is None or xres <= 0 or unit is None:
        return None
    yres = _number(tags.get(TAG_FOCAL_PLANE_Y_RES))
    if yres is None or yres <= 0:
        yres = xres  # square pixels
    w_px = _integer(tags.get(TAG_EXIF_IMAGE_WIDTH))
    h_px = _integer(tags.get(TAG_EXIF_IMAGE_HEIGHT))
    if w_px is None or w_px <= 0:
        w_px = size[0]
    if h_px is None or h_px <= 0:
        h_px = size[1]
    sensor_long_mm = max(w_px / xres, h_px / yres) * unit
    if not sensor_long_mm > 0:
        return None
    return f * FULL_FRAME_WIDTH_MM / sensor_long_mm


def camera_identity(path: str | os.PathLike) -> str | None:
    """A name for the camera and lens setting that took a photo, from its EXIF, or ``None``.

    ``"<Make> <Model> <FocalLength> mm"`` (e.g. ``"Apple iPhone 12 4.2 mm"``): photos with the
    same name were taken by one camera at one focal length, and so can share a focal length in
    a fit (``Photo.camera_group``). ``None`` when the file does not record its make, model and
    focal length (a zoom lens at an unknown setting is no shared camera). Never raises.
    """
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            with Image.open(path) as img:
                exif = img.getexif()
                tags = dict(exif)
                tags.update(exif.get_ifd(EXIF_IFD))
    except Exception:  # not an image Pillow reads, or a corrupt EXIF block: no identity
        return None
    make, model = (str(tags.get(t, "")).strip(" \x00") for t in (TAG_MAKE, TAG_MODEL))
    f = _number(tags.get(TAG_FOCAL_LENGTH))
    if not model or f is None or f <= 0:
        return None
    if make and model.lower().startswith(make.lower()):
        make = ""  # "Canon" + "Canon EOS R5": the model names the make already
    return " ".join(x for x in (make, model, f"{round(f, 1):g} mm") if x)


def _number(v) -> float | None:
    """A finite float from an EXIF value (int, float, Pillow's IFDRational, a 1-tuple), else None."""
    if isinstance(v, tuple) and len(v) == 1:
        v = v[0]
    if isinstance(v, (bytes, str, bool)) or v is None:
        return None
    try:
        x = float(v)  # IFDRational with a zero denominator gives nan
    except (TypeError, ValueError, ZeroDivisionError):
        return None
    return x if math.isfinite(x) else None


def _integer(v) -> int | None:
    x = _number(v)
    return None if x is None or x != int(x) else int(x)


__all__ = ["camera_identity", "focal_mm_36_from_exif", "focal_mm_guess_from_exif"]
