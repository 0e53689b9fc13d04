"""The detector's features on every k-th frame of a clip, found in a background thread (no Qt).

``facestudio auto`` reports the track's landmark error against the full detector
(:func:`tracking.detected_pose.detected_features`: face detector and face mesh on the whole frame)
on every :data:`tracking.auto_pipeline.LANDMARK_EVERY`-th frame. Those detections do not depend on
the track, so :class:`LandmarkChecks` finds them while the clip is tracked: the tracker keeps about
1.5 of two cores busy (the software rasteriser's threads and numpy), and the checks fill the rest
— they took 9 s of ``auto``'s 132 s on the real clip after tracking (2026-12-05). Each thread
runs its own copy of the networks (:mod:`photomodel.landmarks.nets`), so the thread and the
tracker's own detector passes do not wait for each other.
"""

from __future__ import annotations

import threading
from collections.abc import Sequence
from pathlib import Path

from photomodel.photos.video import VideoFrames
from tracking.detected_pose import detected_features

__all__ = ["LandmarkChecks"]


class LandmarkChecks:
    """Detect ``names`` on frames 0, k, 2k, … below ``count`` of ``clip`` in a daemon thread.

    :meth:`detections` waits for the thread and returns what it found; a frame it did not reach
    (stopped, or the clip ended early) is detected there and then, so the result never depends
    on timing. :meth:`stop` ends the thread after its current frame (a cancelled run)."""

    def __init__(self, clip: str | Path, names: Sequence[str], every: int, count: int | None):
        self.clip, self.names, self.every, self.count = Path(clip), list(names), int(every), count
        self._found: dict[int, dict | None] = {}
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, name="landmark-checks", daemon=True)
        self._thread.start()

    def _run(self) -> None:
        try:
            for i, frame in VideoFrames(self.clip).frames(0, self.count):
                if self._stop.is_set():
                    return
                if i % self.every == 0:
                    self._found[i] = detected_features(frame, self.names)
        except Exception:  # noqa: BLE001 — whatever it missed is detected in the foreground
            return

    def stop(self) -> None:
        """End the thread after the frame it is on."""
        self._stop.set()
        self._thread.join()

    def detections(self, n: int) -> dict[int, dict | None]:
        """``{i: detected features or None}`` of the checked frames below ``n`` (0, k, 2k, …),
        after the thread has ended; frames it did not reach are decoded and detected here."""
        self._thread.join()
        wanted = range(0, n, self.every)
        missing = {i for i in wanted if i not in self._found}
        if missing:
            for i, frame in VideoFrames(self.clip).frames(0, max(missing) + 1):
                if i in missing:
                    self._found[i] = detected_features(frame, self.names)
        return {i: self._found.get(i) for i in wanted}
