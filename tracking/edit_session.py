"""Editing a tracked clip's expressions interactively: the state the studio's tracking view would show, without Qt.

:class:`EditSession` holds one results folder's clip (footage, tracked or smoothed parameters, the
face model as :class:`tracking.frame_fit.FrameFitter`) and a list of edits (:mod:`tracking.edit`)
with undo and redo — scale a weight curve over a span, replace a span through a chosen frame —
and answers what a view needs: the weight curves before and after the edits, one frame edited
beside the original (:func:`tracking.expression_flow.edit_frame`), and the export
(:func:`tracking.edit_video.write_frames` / :func:`tracking.edit_video.write_video`, ``edits.json``).
Like :class:`tracking.review.TrackReview`, a widget observes it; nothing here imports Qt.
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from tracking.edit import check_edit, edited_alphas, edits_document, save_edits
from tracking.edit_video import edit_frames, write_frames, write_video
from tracking.frame_fit import FrameFitter
from tracking.smooth import weight_curves

__all__ = ["EditSession"]


class EditSession:
    """Edits of one clip with undo/redo.

    Parameters
    ----------
    fitter : FrameFitter, the clip's model and camera.
    frames : sequence of T (H, W, 3) float32 in [0, 1], the footage.
    states : sequence of T FrameState, tracked (or smoothed, :func:`tracking.smooth.smooth_clip`) parameters.
    fps : float, the footage's frame rate (export).
    """

    def __init__(self, fitter: FrameFitter, frames, states, fps: float = 25.0):
        if len(frames) != len(states):
            raise ValueError(f"need one state per frame: {len(frames)} frames, {len(states)} states")
        self.fitter, self.frames, self.states, self.fps = fitter, list(frames), list(states), float(fps)
        self.edits: list[dict] = []
        self._redo: list[dict] = []
        self.alphas = np.array([s.alpha for s in states]).reshape(len(states), fitter.n_alpha)

    @property
    def frame_count(self) -> int:
        return len(self.frames)

    @property
    def can_redo(self) -> bool:
        """Whether an undone edit is left to :meth:`redo`."""
        return bool(self._redo)

    def add(self, edit: dict) -> None:
        """Append ``edit`` (checked: :func:`tracking.edit.check_edit`); the redo list is cleared."""
        self.edits.append(check_edit(dict(edit), self.fitter.model.names, self.frame_count))
        self._redo.clear()

    def scale(self, expression: str, factor: float, span: tuple | None = None) -> None:
        """Scale a weight curve over ``span`` (first, last) — a drag of the curve in the view."""
        e = {"op": "scale", "expression": expression, "factor": float(factor)}
        if span is not None:
            e["span"] = [int(span[0]), int(span[1])]
        self.add(e)

    def replace(self, span: tuple, frame: int) -> None:
        """Replace frames ``span`` (first, last) through ``frame``'s expression (§5.2)."""
        self.add({"op": "replace", "span": [int(span[0]), int(span[1])], "frame": int(frame)})

    def undo(self) -> bool:
        """Take back the last edit; False when there is none."""
        if not self.edits:
            return False
        self._redo.append(self.edits.pop())
        return True

    def redo(self) -> bool:
        """Apply the last undone edit again; False when there is none."""
        if not self._redo:
            return False
        self.edits.append(self._redo.pop())
        return True

    def curves(self) -> tuple[np.ndarray, np.ndarray]:
        """(T, R, m) region weights before and after the edits (the view's weight curves)."""
        model = self.fitter.model
        return weight_curves(model, self.alphas), weight_curves(model, edited_alphas(model, self.alphas, self.edits))

    def frame_pair(self, index: int) -> tuple[np.ndarray, np.ndarray]:
        """Frame ``index`` as in the footage and as edited, (H, W, 3) float32 each (scrubbing)."""
        images, _, _ = edit_frames(self.fitter, self.frames, self.states, self.edits, only=[int(index)])
        return np.asarray(self.frames[index], np.float32), images[0]

    def export(self, track_dir: str | os.PathLike, out: str | os.PathLike, smooth: dict | None = None) -> Path:
        """Write every frame (PNG folder ``out``, or a video ``out`` with ``.mp4`` and its frames
        beside it) and ``track_dir/edits.json``; returns ``out``."""
        images, _, _ = edit_frames(self.fitter, self.frames, self.states, self.edits)
        out = Path(out)
        if out.suffix.lower() == ".mp4":
            write_frames(out.with_name(out.stem + "_frames"), images)
            write_video(out, images, self.fps)
        else:
            write_frames(out, images)
        save_edits(track_dir, edits_document(self.edits, self.frame_count, smooth))
        return out
