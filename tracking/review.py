"""Tracking results opened for review: the state of the studio's tracking view, without Qt.

:class:`TrackReview` holds one results folder — its ``track.json`` (:mod:`tracking.track_result`), the
frame records, the footage of the tracked frames and the plots (:mod:`tracking.plots`) — and, built
on first use, a :class:`tracking.frame_fit.FrameFitter` of the run's model and camera, which renders
a frame's overlay (:func:`tracking.overlay_video.overlay_frame`, the code path of ``overlay.mp4``)
and places the project's pose features where the tracked model puts them (the start of a
correction). :class:`app.qt.tracking_view.TrackingView` shows one; nothing here computes tracking.
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from photomodel.errors import FaceStudioError
from photomodel.photos.video import VideoFrames
from photomodel.project import load_project
from tracking.arkit_face import model_for_results
from tracking.blendshape_face import render_model
from tracking.frame_fit import DIVERGED_RMS, FrameFitter
from tracking.overlay_video import overlay_frame
from tracking.plots import track_plots
from tracking.track_result import load_track_results, state_of

__all__ = ["TrackReview"]


class TrackReview:
    """The tracking results of one folder, as read for viewing (:meth:`open`).

    Attributes
    ----------
    out_dir : Path, the results folder (absolute).
    doc : dict, its ``track.json``.
    records : list of dict, the frame records (``doc["frames"]``), in frame order.
    footage : list of (H, W, 3) uint8 RGB, the tracked frames of the video (empty when it cannot be
        read; then :attr:`footage_error` says why).
    footage_error : str, why a frame has no picture ("" when all is well).
    plots : dict file name → (H, W, 3) uint8 RGB, :func:`tracking.plots.track_plots` of the records.
    """

    def __init__(self, out_dir: str | os.PathLike, doc: dict):
        self.out_dir = Path(out_dir).absolute()
        self.doc = doc
        self.records: list[dict] = list(doc["frames"])
        self.footage: list[np.ndarray] = []  # uint8 RGB, one per tracked frame
        self.footage_error = ""
        self._fitter: FrameFitter | None = None
        if self.records:
            try:
                video = VideoFrames(doc["video"]["path"])
                self.footage = [np.round(f * 255).astype(np.uint8) for _, f in video.frames(0, len(self.records))]
            except FaceStudioError as exc:
                self.footage_error = str(exc)
        regions = doc["model"]["regions_with_parameters"]
        self.plots = (
            track_plots(self.records, regions, doc["model"]["expressions"], DIVERGED_RMS) if self.records else {}
        )

    @classmethod
    def open(cls, out_dir: str | os.PathLike) -> TrackReview:
        """The results in ``out_dir``; FaceStudioError when its ``track.json`` is missing or unreadable."""
        out = Path(out_dir).absolute()
        doc = load_track_results(out)
        if doc is None:
            raise FaceStudioError(f"{out} holds no track.json (run Track video… first)")
        return cls(out, doc)

    @property
    def frame_count(self) -> int:
        """Frames tracked."""
        return len(self.records)

    def footage_frame(self, index: int) -> np.ndarray | None:
        """Frame ``index`` of the footage as (H, W, 3) float32 in [0, 1]; None when it could not be read."""
        if index < len(self.footage):
            return self.footage[index].astype(np.float32) / 255.0
        return None

    def fitter(self) -> FrameFitter:
        """A :class:`FrameFitter` of the run's model (the project's, rebuilt from the project file
        the results name) and camera, built once."""
        if self._fitter is None:
            cam = self.doc["camera"]
            model = model_for_results(load_project(self.doc["project"]), self.doc)
            self._fitter = FrameFitter(model, cam["focal_px"], cam["width"], cam["height"])
        return self._fitter

    def overlay(self, index: int, frame: np.ndarray) -> np.ndarray:
        """``frame`` with the model at frame ``index``'s parameters rendered over it
        (:func:`tracking.overlay_video.overlay_frame`); FaceStudioError when the model cannot be built."""
        return overlay_frame(self.fitter(), frame, self.records[index])

    def rendered(self, index: int) -> np.ndarray:
        """(H, W, 3) float32: the model alone at frame ``index``'s pose and expression, rendered with its
        textures on black (the right half of a clone's side-by-side view); FaceStudioError when the model
        cannot be built."""
        fitter = self.fitter()
        model = fitter.model
        st = state_of(self.records[index])
        Wv = model.vertex_weights(model.region_weights(st.alpha))
        return render_model(fitter.renderer, fitter.camera(st), model, model.blend_geometry(Wv), Wv).image

    def side_by_side(self, index: int) -> np.ndarray | None:
        """(H, 2W, 3) float32: the footage of frame ``index`` | :meth:`rendered` — for cloned results (the
        footage is the other person's, the model this project's), as ``facestudio clone``'s video; None
        when the footage could not be read."""
        frame = self.footage_frame(index)
        if frame is None:
            return None
        return np.concatenate([frame, np.asarray(self.rendered(index), np.float32)], axis=1)

    def feature_positions(self, index: int, project) -> dict[str, tuple[float, float]]:
        """{feature: (u, v)} image px: ``project``'s pose features where the tracked model puts them
        in frame ``index`` (its pose and expression there, projected by the video camera; clamped to
        the image so that a model that left it still has markers to drag)."""
        fitter = self.fitter()
        model = fitter.model
        st = state_of(self.records[index])
        names = project.feature_names(pose_only=True)
        X = model.blend_geometry(model.vertex_weights(model.region_weights(st.alpha)))[project.feature_vertices(names)]
        uv = fitter.camera(st).project(X)
        uv[:, 0] = np.clip(uv[:, 0], -0.5, fitter.W - 0.5)
        uv[:, 1] = np.clip(uv[:, 1], -0.5, fitter.H - 0.5)
        return {n: (float(u), float(v)) for n, (u, v) in zip(names, uv, strict=True)}

    def correction_settings(self) -> dict:
        """The :func:`tracking.run.track_video` arguments that re-track these results (a correction):
        ``video``, ``expressions``, ``first_pose`` (the recorded JSON) and ``focal_px``."""
        d = self.doc
        return {
            "video": Path(d["video"]["path"]),
            "expressions": list(d["model"]["expressions"]),
            "first_pose": d["first_pose"]["spec"],
            "focal_px": float(d["camera"]["focal_px"]),
        }
