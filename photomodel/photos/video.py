"""Reading the footage to track: a video file or a folder of frame images, as RGB in [0, 1].

* **A video file**: anything OpenCV's :class:`cv2.VideoCapture` decodes; its frame count and frame
  rate are read from the container when it says (:data:`DEFAULT_FPS` otherwise).
* **A frame folder**: images of any type a photo may be (:data:`IMAGE_SUFFIXES`, the modeling
  core's list) named by one frame-name pattern (:func:`frame_files`: the most common pattern with
  a number; other images are ignored and listed in ``ignored``) in natural name order
  (``f2.png`` before ``f10.png``), all of the first one's size. Hidden files are not frames:
  macOS writes a ``._frame_0001.png`` beside each file it copies to some drives, as many as the
  frames, and sorting first their pattern would otherwise win the tie.

Errors are :class:`VideoError` naming the file.
"""

from __future__ import annotations

import math
import os
import re
from collections.abc import Iterator
from pathlib import Path

import cv2
import numpy as np

from photomodel.errors import FaceStudioError
from photomodel.photos.reading import PHOTO_SUFFIXES, files_in_folder, name_order

__all__ = ["IMAGE_SUFFIXES", "DEFAULT_FPS", "VideoError", "VideoFrames", "frame_files", "frame_pattern", "frame_uint8"]

#: Frame image suffixes: those of a photo.
IMAGE_SUFFIXES = PHOTO_SUFFIXES
#: Frame rate of a frame folder, or of a video file whose container gives none.
DEFAULT_FPS = 10.0


class VideoError(FaceStudioError):
    """The video (file or frame folder) is missing, unreadable or inconsistent."""


def frame_pattern(path: Path) -> str:
    """The frame-name pattern of an image file: its name with every run of digits as ``#``
    (``frame_0012.png`` → ``frame_#.png``), lower case."""
    return re.sub(r"\d+", "#", path.name.lower())


def frame_files(images: list[Path]) -> tuple[list[Path], list[Path]]:
    """The frames of a folder's images and the images that are not frames.

    The frames are the images of the most common :func:`frame_pattern` that has a number in it
    (ties: the one whose first file sorts first), in natural order (``f2.png`` before
    ``f10.png``); every other image (a contact sheet, a poster frame, ``notes.png``) is ignored
    and returned, sorted, so that the caller can say so. A folder without numbered names keeps
    all its images."""
    groups: dict[str, list[Path]] = {}
    for p in sorted(images, key=name_order):
        groups.setdefault(frame_pattern(p), []).append(p)
    numbered = [k for k in groups if "#" in k]
    if not numbered:
        return sorted(images, key=name_order), []
    best = max(numbered, key=lambda k: len(groups[k]))  # max keeps the first of equals
    ignored = sorted((p for k, ps in groups.items() if k != best for p in ps), key=name_order)
    return groups[best], ignored


class VideoFrames:
    """Frames of a video file or of a folder of images, as (H, W, 3) float32 RGB in [0, 1].

    Parameters
    ----------
    path : a video file (anything :class:`cv2.VideoCapture` decodes) or a folder of PNG/JPG frames.

    Attributes
    ----------
    path : Path (absolute); is_folder : bool; files : list of Path (a folder's frames, in order);
    ignored : list of Path, a folder's images that do not match its frame-name pattern (:func:`frame_files`);
    count : int or None, the number of frames (None when the container does not say);
    fps : float; width, height : int, the first frame's size.

    Raises
    ------
    VideoError naming the path when it is missing, not decodable, empty, or (folders) holds a frame
    that is unreadable or of another size than the first.
    """

    def __init__(self, path: str | os.PathLike):
        self.path = Path(path).absolute()
        if not self.path.exists():
            raise VideoError(f"the video {self.path} does not exist")
        self.is_folder = self.path.is_dir()
        self.fps = DEFAULT_FPS
        self.ignored: list[Path] = []
        if self.is_folder:
            images = files_in_folder(self.path, IMAGE_SUFFIXES)  # hidden files are not frames
            if not images:
                raise VideoError(
                    f"the frame folder {self.path} holds no images (looked for {', '.join(IMAGE_SUFFIXES)})"
                )
            self.files, self.ignored = frame_files(images)
            self.count: int | None = len(self.files)
            first = self._read_image(self.files[0])
        else:
            self.files = []
            cap = self._open()
            try:
                ok, bgr = cap.read()
                if not ok or bgr is None:
                    raise VideoError(f"the video {self.path} has no frame OpenCV can decode (empty or corrupt)")
                n = int(cap.get(cv2.CAP_PROP_FRAME_COUNT))
                self.count = n if n > 0 else None  # containers may not say
                fps = float(cap.get(cv2.CAP_PROP_FPS))
                self.fps = fps if math.isfinite(fps) and fps > 0 else DEFAULT_FPS
            finally:
                cap.release()
            first = bgr
        self.height, self.width = first.shape[:2]

    def _open(self):
        cap = cv2.VideoCapture(str(self.path))
        if not cap.isOpened():
            cap.release()
            raise VideoError(
                f"the video {self.path} cannot be opened by OpenCV (corrupt or unknown format); "
                f"a folder of PNG/JPG frames works too"
            )
        return cap

    def _read_image(self, path: Path) -> np.ndarray:
        img = cv2.imread(str(path), cv2.IMREAD_COLOR)
        if img is None:
            raise VideoError(f"the frame {path} is not an image OpenCV can read (corrupt or unknown format)")
        return img

    def frames(self, start: int = 0, stop: int | None = None) -> Iterator[tuple[int, np.ndarray]]:
        """Yield ``(index, frame)`` for frames ``start`` .. ``stop − 1`` (to the end if None)."""
        if self.is_folder:
            for i in range(start, len(self.files) if stop is None else min(stop, len(self.files))):
                bgr = self._read_image(self.files[i])
                if bgr.shape[:2] != (self.height, self.width):
                    raise VideoError(
                        f"the frame {self.files[i]} is {bgr.shape[1]}x{bgr.shape[0]}, but the first "
                        f"frame is {self.width}x{self.height}"
                    )
                yield i, _to_rgb(bgr)
            return
        cap = self._open()
        try:
            for _ in range(start):  # decoding from the start is the reliable way to reach a frame
                if not cap.grab():
                    return
            i = start
            while stop is None or i < stop:
                ok, bgr = cap.read()
                if not ok or bgr is None:
                    return
                yield i, _to_rgb(bgr)
                i += 1
        finally:
            cap.release()


def frame_uint8(frame: np.ndarray) -> np.ndarray:
    """A frame as the detector and an image file take it: (H, W, 3) uint8 RGB (float frames are in
    [0, 1]; a decoded frame comes back to its own bytes)."""
    img = np.asarray(frame)
    return img if img.dtype == np.uint8 else np.round(np.clip(img, 0.0, 1.0) * 255.0).astype(np.uint8)


def _to_rgb(bgr: np.ndarray) -> np.ndarray:
    return cv2.cvtColor(bgr, cv2.COLOR_BGR2RGB).astype(np.float32) / 255.0
