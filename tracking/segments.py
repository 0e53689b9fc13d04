"""A long clip tracked as two segments at once, one in a second process (no Qt; beyond the paper).

Pighin et al. (2002, §6.2) track frame after frame, each predicted from the two before, so one
clip is one chain and the fit of a frame uses one core: the per-frame work is many small numpy
and OpenGL calls that a second thread cannot share (Python's lock), and BLAS is held to one
thread (:func:`tracking.frame_fit.single_threaded_blas`). On the two-core machine the second core
sat half idle while the real clip was tracked. :func:`tracking.run.track_video` therefore splits a
fresh run of a long clip at a frame ``s`` of its middle third: this process tracks frames ``0 .. s − 1`` as
before, and a second process (``spawn``: its own OpenGL context and its own detector networks)
tracks ``s − WARM_FRAMES .. the end`` (``s`` near the middle, where the face is seen best:
:func:`plan_split`) — its first frame fitted from the landmark detector's pose
in several rounds, as a re-detected frame is (``start: "detected"``), the next
:data:`WARM_FRAMES` tracked only to settle the prediction and the expression, and dropped. Its
records from frame ``s`` on are appended once this process has reached ``s``; frame ``s`` is
``start: "predicted"`` like its neighbours.

What the user sees stays the same: one ``track.json`` of contiguous frames, the overlay video,
the plots. Progress counts the frames of both segments; a cancel stops both and keeps the first
segment's frames (the results on disk are always a contiguous run of frames from 0, so that a
later run continues them: the second segment's frames are tracked again then). A run that
continues earlier results, corrects a frame, or tracks fewer than ``2 ×`` :data:`MIN_FRAMES`
frames is not split; nor is a clip where the detector finds no face near the seam.
"""

from __future__ import annotations

import multiprocessing as mp
import queue as queue_mod
import signal
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from photomodel.errors import FaceStudioError
from photomodel.photos.stills import look_at_frame
from photomodel.photos.video import frame_uint8
from tracking.detected_pose import detected_spec

__all__ = ["MIN_FRAMES", "WARM_FRAMES", "SegmentWorker", "plan_split"]

#: A clip is split only when each segment would have at least this many frames: the seam costs a
#: fit in several rounds and :data:`WARM_FRAMES` frames tracked twice, and a second process ~2 s
#: to start (imports, OpenGL context, the model).
MIN_FRAMES = 120
#: Frames the second segment tracks before the seam and drops: its first frame is fitted from the
#: detector's pose, and the prediction needs two tracked frames before it extrapolates.
WARM_FRAMES = 6
#: Frames looked at for the seam: this many, spread over the clip's middle third.
SEAM_CANDIDATES = 9


@dataclass
class Split:
    """Where the second segment starts: it fits frame ``begin`` from ``spec`` (the detector's
    first-pose JSON of that frame) and keeps its records from frame ``seam`` on."""

    begin: int
    seam: int
    spec: dict


def plan_split(run, start: int, correct_frame, segments: int, min_frames: int | None = None) -> Split | None:
    """The :class:`Split` of :func:`tracking.run.track_video`'s run ``run`` (its ``_Run``), or None
    when the run is tracked in one piece (module docstring): ``segments`` < 2, a continued run
    (``start`` > 0), a correction, a clip whose length the container does not say, one shorter
    than ``2 × min_frames`` (default :data:`MIN_FRAMES`) frames, or no face found in the middle third.

    The second segment starts where the face is seen best: of :data:`SEAM_CANDIDATES` frames
    spread over the middle third, the one whose face-mesh points move least between the
    detector's shifted crops (:func:`photomodel.photos.stills.look_at_frame`'s ``spread_pct``,
    which tells a hand over the face, as the stills' choice does): a detector's pose under a hand
    would start the segment off (measured on the real clip, a seam in its hand-over-mouth stretch:
    the two tracks 1.7–4.7° apart for 10 frames, 0.1° after 50)."""
    count, min_frames = run.video.count, MIN_FRAMES if min_frames is None else min_frames
    if segments < 2 or start > 0 or correct_frame is not None or not count:
        return None
    total = count if run.max_frames is None else min(count, run.max_frames)
    if total < 2 * min_frames:
        return None
    lo, hi = max(min_frames, total // 3), min(total - min_frames, 2 * total // 3)
    wanted = set(np.linspace(lo, hi, SEAM_CANDIDATES).round().astype(int).tolist())
    looks = []
    for i, rgb in run.video.frames(min(wanted), max(wanted) + 1):
        if i in wanted:
            image = frame_uint8(rgb)
            look = look_at_frame(i, image)
            if look is not None:
                looks.append((look.spread_pct, i, image))
    for _, begin, image in sorted(looks, key=lambda t: t[:2]):
        spec = detected_spec(image, run.project, run.first.focal_px, name=f"frame {begin}")
        if spec is not None:
            return Split(begin, begin + WARM_FRAMES, spec)
    return None


class SegmentWorker:
    """The second segment, tracked in a process of its own (started here).

    ``track``: :func:`tracking.run.track_segment` (passed by name to the process), ``conf`` what it
    needs to open the same run there (the project's path, the video's, the face model, the first
    pose, the options); ``split`` the :class:`Split`; ``stop`` the frame after the last to track
    (None: the end). Raises what ``multiprocessing`` raises when the process cannot start."""

    def __init__(self, track: Callable, conf: dict, split: Split, stop: int | None):
        ctx = mp.get_context("spawn")
        self.split = split
        self.done = ctx.Value("i", 0)  # frames from the seam on tracked so far
        self._stop = ctx.Event()
        self._queue = ctx.Queue()
        # the work goes through a queue (its feeder thread never blocks this one), not as the
        # process's arguments: those are written to the new process's pipe by start(), which
        # blocks on a process that died while starting (a script without a __main__ guard)
        # (put after start(): a start that raises — a daemonic process, a script without the
        # guard re-run in the new process — leaves no feeder thread to wait for at exit)
        self._jobs = ctx.Queue()
        self._process = ctx.Process(
            target=_main,
            args=(self._jobs, self._stop, self.done, self._queue),
            name="facestudio-track-segment",
            daemon=True,
        )
        self._process.start()
        self._jobs.put((track, conf, split, stop))

    def results(self, wait: Callable[[], bool]) -> tuple[list[dict], bool, bool]:
        """The second segment's records (frames from the seam on), whether it ran to its end and
        whether it was cancelled. ``wait()`` is called every 0.2 s while it works (progress, the
        user's cancel); True stops it (its frames are then dropped: ``([], False, True)``).
        Raises FaceStudioError naming what went wrong in the process."""
        while True:
            try:
                kind, *payload = self._queue.get(timeout=0.2)
                break
            except queue_mod.Empty:
                if wait():
                    self.stop()
                    return [], False, True
                if not self._process.is_alive() and self._queue.empty():
                    raise FaceStudioError(
                        f"the second tracking segment's process ended without results "
                        f"(exit code {self._process.exitcode})"
                    ) from None
        self._process.join(timeout=10)
        if kind == "error":
            raise FaceStudioError(f"tracking frames {self.split.begin}.. in a second process: {payload[0]}")
        records, ended, cancelled = payload
        return records, ended, cancelled

    def stop(self) -> None:
        """Stop the process (after the frame it is fitting; killed if it does not end in 10 s)."""
        self._stop.set()
        self._jobs.cancel_join_thread()  # a process that never read its work: do not wait to hand it over
        self._process.join(timeout=10)
        if self._process.is_alive():
            self._process.kill()
            self._process.join()


def _main(jobs, stop_event, done, results) -> None:
    """The second process: track the segment ``jobs`` holds, put ``("ok", records, ended,
    cancelled)`` or ``("error", message)`` on ``results``."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # Ctrl-C is the first process's to handle
    try:
        track, conf, split, stop = jobs.get()

        def progress(done_frames: int, _total) -> None:  # frames 0 .. done_frames − 1 are behind
            done.value = max(0, done_frames - split.seam)

        records, ended, cancelled = track(conf, split, stop, progress, stop_event.is_set)
        results.put(("ok", [r for r in records if r["frame"] >= split.seam], ended, cancelled))
    except BaseException as exc:  # noqa: BLE001 — reported to the first process
        results.put(("error", f"{type(exc).__name__}: {exc}"))
