"""Cloning in the studio: another project's tracked performance on this project's face, as ``facestudio clone``.

:class:`CloneJob` is one run of :func:`tracking.clone.clone_track` prepared on the GUI thread — which
project A and which of its track results (:func:`track_results_of`), the method, this project's file
(B) and the results folder (:func:`tracking.clone.default_clone_dir`, ``<B>/results/<track>_from_<A>``)
— and run in a worker (:meth:`CloneJob.run`, with the studio's ``progress(message, fraction)`` and
``cancel()``). Cloning reads B's project *file*, so a project never saved cannot take a performance.
The results are B's tracking results, opened by the tracking view like B's own. No Qt.
"""

from __future__ import annotations

import os
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

from photomodel.errors import FaceStudioError, ProjectError
from photomodel.project import FILE_SUFFIX
from tracking.clone import METHODS, CloneResult, clone_track, default_clone_dir
from tracking.track_result import load_track_results


def track_results_of(project_path: str | os.PathLike) -> list[Path]:
    """The tracking results of project file ``project_path``: the folders ``results/*/`` beside it that
    hold a ``track.json`` with frames, by name (absolute)."""
    results = Path(project_path).absolute().parent / "results"
    if not results.is_dir():
        return []
    found = []
    for folder in sorted(p for p in results.iterdir() if p.is_dir()):
        try:
            doc = load_track_results(folder)
        except FaceStudioError:  # an unreadable track.json is not offered (opening it names the problem)
            continue
        if doc is not None and doc["frames"]:
            found.append(folder)
    return found


@dataclass
class CloneJob:
    """One clone of a saved project A's tracked performance onto the saved project B.

    Attributes
    ----------
    project_a : Path, A's project file (absolute).
    track : Path, A's results folder (holds ``track.json``).
    project_b : Path, B's project file (absolute): the studio's.
    method : str, one of :data:`tracking.clone.METHODS`.
    out_dir : Path, B's results folder (absolute).
    """

    project_a: Path
    track: Path
    project_b: Path
    method: str
    out_dir: Path

    @classmethod
    def prepare(
        cls,
        project_b: str | os.PathLike | None,
        project_a: str | os.PathLike,
        track: str | os.PathLike,
        method: str,
        out_dir: str | os.PathLike | None = None,
    ) -> CloneJob:
        """A job cloning ``track`` of ``project_a`` onto the project saved at ``project_b``;
        :class:`ProjectError` when B has no file yet, A is not a project file, is B itself, or
        ``track`` holds no ``track.json``; ``ValueError`` for an unknown method."""
        if project_b is None:
            raise ProjectError("save the project first: cloning reads the project file")
        if method not in METHODS:
            raise ValueError(f"method must be one of {', '.join(METHODS)}, got {method!r}")
        a, b, tr = Path(project_a).absolute(), Path(project_b).absolute(), Path(track).absolute()
        if not a.is_file() or not a.name.endswith(FILE_SUFFIX):
            raise ProjectError(f"{a} is not a project file (*{FILE_SUFFIX})")
        if not (tr / "track.json").is_file():
            raise ProjectError(f"{tr} holds no tracking results (track.json)")
        out = default_clone_dir(a, tr, b) if out_dir is None else Path(out_dir).absolute()
        return cls(a, tr, b, method, out)

    def run(
        self, progress: Callable[[str, float], None] | None = None, cancel: Callable[[], bool] | None = None
    ) -> CloneResult:
        """Clone (worker thread): :func:`tracking.clone.clone_track`'s result, written to :attr:`out_dir`."""
        return clone_track(
            self.project_a, self.track, self.project_b, self.method, self.out_dir, progress=progress, cancel=cancel
        )


__all__ = ["CloneJob", "track_results_of"]
