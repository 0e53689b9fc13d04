"""The overlay video written while the clip is tracked (no Qt).

:func:`tracking.overlay_video.write_overlay_video` draws the overlay once every frame is tracked:
on the real-clip sample that was ~20 s after 80 s of tracking. The tracking loop leaves about
half a core of the two idle (its numpy work is one thread; the software rasteriser's threads
wait for it), so :class:`OverlayStream` draws each frame's overlay as soon as its record is
there, in a thread with its own OpenGL renderer, decoding the footage itself. The file is the
same: frames 0 … the last record's, each drawn by :func:`tracking.overlay_video.overlay_frame`
(a frame without a record as it is), written to a temporary file and moved into place by
:meth:`OverlayStream.finish` — or removed by :meth:`OverlayStream.abort` (a cancelled run, an
error), so a half-written overlay never replaces a whole one.
"""

from __future__ import annotations

import os
import tempfile
import threading
from pathlib import Path

import cv2
import numpy as np

from photomodel.photos.video import VideoError, VideoFrames
from photomodel.rendering.renderer import Renderer
from tracking.frame_fit import FrameFitter
from tracking.overlay_video import overlay_frame

__all__ = ["OverlayStream"]


class OverlayStream:
    """``overlay.mp4`` at ``path`` of ``video``'s frames, drawn in a thread as :meth:`add` hands it
    the tracked records (in frame order)."""

    def __init__(self, path: str | os.PathLike, video: VideoFrames, fitter: FrameFitter, fps: float | None = None):
        self.path, self.video, self.fitter = Path(path), video, fitter
        self.fps = fps or video.fps
        self._records: list[dict] = []
        self._closed = self._aborted = False
        self._ready = threading.Condition()
        self._error: BaseException | None = None
        self._last: np.ndarray | None = None
        fd, tmp = tempfile.mkstemp(prefix=f".{self.path.stem}.", suffix=".mp4", dir=self.path.parent)
        os.close(fd)
        self._tmp = Path(tmp)
        self._thread = threading.Thread(target=self._run, name="overlay-stream", daemon=True)
        self._thread.start()

    def add(self, record: dict) -> None:
        """The next tracked frame's record (frame indices increasing)."""
        with self._ready:
            self._records.append(record)
            self._ready.notify_all()

    def finish(self) -> np.ndarray | None:
        """Draw what is left, move the file into place; the last overlay frame (RGB float) or None
        (no record). Raises what the thread met (e.g. :class:`VideoError`)."""
        self._close(aborted=False)
        if self._error is not None:
            self._tmp.unlink(missing_ok=True)
            raise self._error
        if not self._records:
            self._tmp.unlink(missing_ok=True)
            return None
        os.chmod(self._tmp, 0o644)
        os.replace(self._tmp, self.path)
        return self._last

    def abort(self) -> None:
        """Stop after the frame being drawn and remove the temporary file (``path`` untouched)."""
        self._close(aborted=True)
        self._tmp.unlink(missing_ok=True)

    def _close(self, aborted: bool) -> None:
        with self._ready:
            self._closed = True
            self._aborted = self._aborted or aborted
            self._ready.notify_all()
        self._thread.join()

    def _record(self, k: int) -> dict | None:
        """The ``k``-th record once it is there; None when the stream is closed before it."""
        with self._ready:
            self._ready.wait_for(lambda: k < len(self._records) or self._closed)
            if self._aborted or k >= len(self._records):
                return None
            return self._records[k]

    def _run(self) -> None:
        writer = cv2.VideoWriter(
            str(self._tmp), cv2.VideoWriter_fourcc(*"mp4v"), self.fps, (self.video.width, self.video.height)
        )
        renderer = None
        try:
            if not writer.isOpened():
                raise VideoError(f"OpenCV cannot write an mp4 video to {self.path.parent}")
            frames = self.video.frames(0, None)
            k = 0
            while (rec := self._record(k)) is not None:
                for i, frame in frames:  # the footage up to the record's frame
                    if i == rec["frame"]:
                        renderer = renderer or Renderer()
                        self._last = overlay_frame(self.fitter, frame, rec, renderer=renderer)
                        writer.write(_bgr8(self._last))
                        break
                    if i > rec["frame"]:
                        raise VideoError(f"overlay: records out of order at frame {rec['frame']}")
                    writer.write(_bgr8(frame))
                else:
                    raise VideoError(f"{self.video.path} ended before frame {rec['frame']}")
                k += 1
        except BaseException as exc:  # noqa: BLE001 — raised again by finish()
            self._error = exc
        finally:
            writer.release()
            if renderer is not None:
                renderer.release()


def _bgr8(img: np.ndarray) -> np.ndarray:
    return np.round(np.clip(img[..., ::-1], 0, 1) * 255).astype(np.uint8)
