"""Tracking in the studio: a video tracked with the saved project, as ``facestudio track`` does.

:class:`TrackJob` is one run of :func:`tracking.run.track_video` (a new track, a continued one or a
correction from a frame) prepared on the GUI thread — which project file, which video, which results
folder — and run in a worker (:meth:`TrackJob.run`, with the studio's ``progress(message, fraction)``
and ``cancel()``). Tracking reads the project *file*, so a project never saved cannot be tracked.
The results folder is then opened for viewing by :class:`tracking.review.TrackReview`. No Qt.
"""

from __future__ import annotations

import os
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

from photomodel.errors import ProjectError
from tracking.run import track_video
from tracking.track_result import default_out_dir


@dataclass
class TrackJob:
    """One tracking run of a saved project.

    Attributes
    ----------
    project_path : Path, the project file tracked (absolute).
    video : Path, the video file or frame folder (absolute).
    out_dir : Path, the results folder (absolute): :func:`tracking.track_result.default_out_dir`
        unless given.
    max_frames : int or None, track frames 0 .. max_frames − 1 only (None: the whole video).
    settings : dict, the other keyword arguments of :func:`tracking.run.track_video`
        (``correct_frame``, ``correct_pose``, ``expressions``, ``first_pose``, ``focal_px``,
        ``plots``, ``overlay`` …).
    """

    project_path: Path
    video: Path
    out_dir: Path
    max_frames: int | None = None
    settings: dict = field(default_factory=dict)

    @classmethod
    def prepare(
        cls,
        project_path: str | os.PathLike | None,
        video: str | os.PathLike,
        out_dir: str | os.PathLike | None = None,
        max_frames: int | None = None,
        **settings,
    ) -> TrackJob:
        """A job tracking ``video`` with the project saved at ``project_path``; :class:`ProjectError`
        when the project has no file yet (``project_path`` None)."""
        if project_path is None:
            raise ProjectError("save the project first: tracking reads the project file")
        project_path, video = Path(project_path).absolute(), Path(video).absolute()
        out = default_out_dir(project_path, video) if out_dir is None else Path(out_dir).absolute()
        return cls(project_path, video, out, max_frames, dict(settings))

    def run(self, progress: Callable[[str, float], None] | None = None, cancel: Callable[[], bool] | None = None):
        """Track (worker thread): the :class:`tracking.run.TrackResult`, its results written to :attr:`out_dir`.

        ``progress(message, fraction)`` hears of every frame tracked (``"tracked frame 3 of 120"``);
        ``cancel()`` true stops the run after the frame in hand, its results kept for a later run.
        """
        report = None
        if progress is not None:

            def report(done: int, total: int | None) -> None:
                progress(f"tracked frame {done} of {total if total else '?'}", done / total if total else 0.0)

        return track_video(
            self.project_path,
            self.video,
            self.out_dir,
            max_frames=self.max_frames,
            progress=report,
            cancel=cancel,
            **self.settings,
        )


__all__ = ["TrackJob"]
