"""The studio's tracking view: track a video in a worker, then scrub through the result (§6.2).

:class:`TrackingView` (docked by the main window, *Tracking → Track video…* / *Open results…*)
runs :func:`tracking.run.track_video` in its own :class:`~app.qt.workers.JobController` behind a
cancellable progress dialog; the results land in :func:`tracking.track_result.default_out_dir`
(``<project folder>/results/track_<video stem>``), cancel-safe and resumable, exactly as
``facestudio track`` writes them. It then shows

* the footage frame with the model rendered over it — :func:`tracking.overlay_video.overlay_frame`, the
  code path of ``overlay.mp4`` — or the bare frame (a switch);
* a frame scrubber (slider, frame label; ←/→ step a frame, Home/End jump);
* an *Edit* tab (:class:`app.qt.edit_panel.EditPanel`, issue 16): scale or replace a weight curve
  over a span, the edited frame beside the original, undo/redo, export;
* the parameter curves of :func:`tracking.plots.track_plots` (weights per region, rotation,
  translation, RMS: the paper's Figs. 12–19), each with a vertical marker at the current frame
  drawn on a copy of the plot image (:func:`plot_with_marker`).

A frame that diverged or drifted is corrected where it is shown: *Correct pose here…* opens the
click dialog of the first pose (:class:`FirstPoseDialog`) on that frame, its pose features placed
where the tracked model puts them, so the user only drags the wrong ones; accepting re-tracks from
that frame in the worker (:func:`tracking.run.track_video`'s ``correct_frame``/``correct_pose``),
behind the same cancellable progress dialog as *Track video…*.

Nothing here computes tracking itself: the state of the shown results — ``track.json``, the frame
records, the footage, the plots and the :class:`tracking.frame_fit.FrameFitter` of the run's model
and camera that renders overlays on the GUI thread (the renderer is per thread) — is a Qt-free
:class:`tracking.review.TrackReview`; the view shows it.
"""

from __future__ import annotations

import json
import math
import os
from pathlib import Path
from typing import TYPE_CHECKING

import cv2
import numpy as np
from PySide6.QtCore import QPointF, QRectF, Qt, Signal
from PySide6.QtGui import QColor, QImage, QPainter, QPen, QPixmap
from PySide6.QtWidgets import (
    QCheckBox,
    QDialog,
    QDoubleSpinBox,
    QFileDialog,
    QHBoxLayout,
    QLabel,
    QListWidget,
    QListWidgetItem,
    QMessageBox,
    QProgressDialog,
    QPushButton,
    QScrollArea,
    QSizePolicy,
    QSlider,
    QSpinBox,
    QSplitter,
    QTabWidget,
    QVBoxLayout,
    QWidget,
)

from app.qt.edit_panel import EditPanel
from app.qt.progress import close_progress, open_progress, update_progress
from app.qt.texture_views import to_qimage
from app.qt.workers import JobController
from app.studio_state import StudioModel
from photomodel.camera import focal_mm_to_px
from photomodel.errors import FaceStudioError
from photomodel.photos.video import VideoError, VideoFrames
from tracking.detected_pose import detected_spec, video_focal_px
from tracking.face_from_project import project_face_model
from tracking.first_pose import default_first_pose_path
from tracking.frame_fit import FrameFitter, pose_from_clicks
from tracking.overlay_video import overlay_frame
from tracking.plots import MARGINS
from tracking.review import TrackReview
from tracking.run import track_video
from tracking.track_result import default_out_dir

if TYPE_CHECKING:
    from tracking.review import TrackReview

__all__ = ["MARKER_COLOR", "plot_with_marker", "TrackingView", "ClickCanvas", "FirstPoseDialog"]

#: Colour (RGB) of the current-frame marker on the plots.
MARKER_COLOR = (255, 120, 0)
#: Order and titles of the plot tabs (file names of :func:`tracking.plots.track_plots`).
PLOT_TABS = (
    ("weights.png", "Weights"),
    ("rotation.png", "Rotation"),
    ("translation.png", "Translation"),
    ("rms.png", "RMS"),
)


def plot_with_marker(image: np.ndarray, frames: np.ndarray, frame: int) -> np.ndarray:
    """A copy of a :func:`tracking.plots.track_plots` image with a vertical line at ``frame``.

    Parameters
    ----------
    image : (H, W, 3) uint8 RGB, a plot (one panel or panels stacked, all of one width).
    frames : (T,) the frame indices the plot was drawn over (its x range is their min..max).
    frame : int, where to draw the marker.

    Returns
    -------
    (H, W, 3) uint8 RGB. The x mapping is :func:`tracking.plots.line_panel`'s (margins
    :data:`tracking.plots.MARGINS`, a single frame centred in a range of ±0.5).
    """
    img = np.array(image, np.uint8, copy=True)
    if img.ndim != 3 or img.shape[2] != 3:
        raise ValueError(f"a plot must be an (H, W, 3) RGB image, got shape {img.shape}")
    x = np.asarray(frames, float)
    x0, x1 = (float(x.min()), float(x.max())) if x.size else (0.0, 1.0)
    if x1 - x0 < 1e-9:
        x0, x1 = x0 - 0.5, x1 + 0.5
    ml, mr = MARGINS[0], MARGINS[1]
    pw = img.shape[1] - ml - mr
    u = int(round(ml + (float(frame) - x0) / (x1 - x0) * pw))
    cv2.line(img, (u, 0), (u, img.shape[0] - 1), MARKER_COLOR, 2)
    return img


class TrackingView(QWidget):
    """Track a video of the current project and inspect the result frame by frame.

    Parameters
    ----------
    model : StudioModel, whose saved project file is tracked (:attr:`StudioModel.path`).

    Attributes
    ----------
    review : TrackReview or None, the shown results (``track.json``, records, footage, plots).
    doc : dict or None, the shown ``track.json`` (``review.doc``).
    out_dir : Path or None, the folder it came from (``review.out_dir``).
    image : (H, W, 3) float32 or None, the image now shown (overlay or bare frame).
    jobs : JobController, the tracking worker.
    """

    def __init__(self, model: StudioModel, parent=None):
        super().__init__(parent)
        self.model = model
        self.review: TrackReview | None = None
        self.image: np.ndarray | None = None
        self._pixmap: QPixmap | None = None
        self._progress: QProgressDialog | None = None
        self._pending_out: Path | None = None
        self.last_message = ""
        self.jobs = JobController(model, self)
        self.jobs.progress.connect(self._on_progress)
        self.jobs.finished.connect(self._on_finished)
        self.jobs.failed.connect(self._on_failed)
        self.jobs.cancelled.connect(self._on_cancelled)

        self.caption = QLabel("<i>No tracking results: Tracking → Track video… or Open results…</i>")
        self.caption.setWordWrap(True)
        self.frame_label = QLabel()
        self.frame_label.setAlignment(Qt.AlignmentFlag.AlignCenter)
        self.frame_label.setMinimumSize(200, 200)
        self.frame_label.setSizePolicy(QSizePolicy.Policy.Ignored, QSizePolicy.Policy.Ignored)
        self.slider = QSlider(Qt.Orientation.Horizontal)
        self.slider.setEnabled(False)
        self.slider.valueChanged.connect(self._show_frame)
        self.index_label = QLabel("frame –")
        self.index_label.setMinimumWidth(150)
        self.overlay_box = QCheckBox("model overlay")
        self.overlay_box.setChecked(True)
        self.overlay_box.setToolTip(
            "the face model drawn over the frame at its tracked pose and expression; outline "
            "green (red: the frame diverged); magenta: pixels the tracker takes for not the "
            "face (a hand, hair, a reflection) and leaves out of the fit"
        )
        self.overlay_box.toggled.connect(lambda *_: self._show_frame(self.slider.value()))
        self.limit_box = QSpinBox()
        self.limit_box.setRange(0, 1_000_000)
        self.limit_box.setSpecialValueText("whole video")
        self.limit_box.setToolTip("track only the first N frames (a later run may raise it and continue)")
        self.first_pose_button = QPushButton("Set first pose…")
        self.first_pose_button.setToolTip("click the pose features in frame 0: tracking starts from that pose")
        self.first_pose_button.clicked.connect(lambda: self.first_pose_dialog())
        self.first_pose_dialog_widget: FirstPoseDialog | None = None
        self.correct_button = QPushButton("Correct pose here…")
        self.correct_button.setToolTip(
            "the shown frame's pose is wrong (diverged, drifted): drag its pose features "
            "into place, then re-track from this frame on"
        )
        self.correct_button.clicked.connect(lambda: self.correct_pose_dialog())
        self.correct_button.setEnabled(False)
        self.correct_dialog_widget: FirstPoseDialog | None = None
        self._pending_frame: int | None = None
        self.cancel_button = QPushButton("Cancel tracking")
        self.cancel_button.setEnabled(False)
        self.cancel_button.clicked.connect(self.jobs.cancel)
        self.jobs.busy_changed.connect(self.cancel_button.setEnabled)
        self.jobs.busy_changed.connect(lambda *_: self._update_buttons())

        self._lay_out()
        self.setFocusPolicy(Qt.FocusPolicy.StrongFocus)

    def _lay_out(self):
        """Controls on top, the frame with its scrubber on the left, the parameter plots on the right."""
        top = QHBoxLayout()
        top.addWidget(QLabel("frames to track"))
        top.addWidget(self.limit_box)
        top.addWidget(self.overlay_box)
        top.addStretch(1)
        top.addWidget(self.first_pose_button)
        top.addWidget(self.correct_button)
        top.addWidget(self.cancel_button)
        scrub = QHBoxLayout()
        scrub.addWidget(self.slider, 1)
        scrub.addWidget(self.index_label)
        left = QWidget()
        lv = QVBoxLayout(left)
        lv.setContentsMargins(0, 0, 0, 0)
        lv.addWidget(self.frame_label, 1)
        lv.addLayout(scrub)

        self.plot_tabs = QTabWidget()
        self.plot_labels: dict[str, QLabel] = {}
        for name, title in PLOT_TABS:
            label = QLabel()
            label.setAlignment(Qt.AlignmentFlag.AlignTop | Qt.AlignmentFlag.AlignLeft)
            area = QScrollArea()
            area.setWidget(label)
            area.setWidgetResizable(True)
            self.plot_labels[name] = label
            self.plot_tabs.addTab(area, title)
        # expression editing (issue 16): thin widgets over tracking.edit_session.EditSession
        self.edit_panel = EditPanel(self.model)
        self.plot_tabs.addTab(self.edit_panel, "Edit")
        self.plot_tabs.currentChanged.connect(
            lambda i: self.edit_panel.refresh() if self.plot_tabs.widget(i) is self.edit_panel else None
        )
        split = QSplitter(Qt.Orientation.Horizontal)
        split.addWidget(left)
        split.addWidget(self.plot_tabs)
        split.setStretchFactor(0, 2)
        split.setStretchFactor(1, 3)

        lay = QVBoxLayout(self)
        lay.addWidget(self.caption)
        lay.addLayout(top)
        lay.addWidget(split, 1)

    # ------------------------------------------------------------------ state
    @property
    def doc(self) -> dict | None:
        """The shown ``track.json`` (None without results)."""
        return None if self.review is None else self.review.doc

    @property
    def out_dir(self) -> Path | None:
        """The folder of the shown results (None without results)."""
        return None if self.review is None else self.review.out_dir

    @property
    def _records(self) -> list[dict]:
        return [] if self.review is None else self.review.records

    @property
    def frame_count(self) -> int:
        """Frames tracked in the shown results."""
        return len(self._records)

    @property
    def current_frame(self) -> int | None:
        """The frame index shown (None without results)."""
        return self.slider.value() if self._records else None

    def set_frame(self, index: int) -> None:
        """Show frame ``index`` (clamped to the tracked frames)."""
        if self._records:
            self.slider.setValue(int(np.clip(index, 0, len(self._records) - 1)))

    def keyPressEvent(self, event):
        key = event.key()
        steps = {Qt.Key.Key_Left: -1, Qt.Key.Key_Right: 1, Qt.Key.Key_PageUp: -10, Qt.Key.Key_PageDown: 10}
        if self._records and key in steps:
            self.set_frame(self.slider.value() + steps[key])
        elif self._records and key == Qt.Key.Key_Home:
            self.set_frame(0)
        elif self._records and key == Qt.Key.Key_End:
            self.set_frame(len(self._records) - 1)
        else:
            super().keyPressEvent(event)
            return
        event.accept()

    # ------------------------------------------------------------------ tracking
    def start_tracking(self, video: str | Path, max_frames: int | None = None) -> bool:
        """Track ``video`` with the saved project in the worker, behind a cancellable progress dialog.

        ``max_frames`` None uses the "frames to track" box (0: the whole video). Returns False
        (with a dialog saying why) when nothing was started.
        """
        if self.jobs.busy:
            self.last_message = "a video is already being tracked"
            return False
        project_path = self.model.path
        if project_path is None:
            self._error("Cannot track", "save the project first: tracking reads the project file")
            return False

        video = Path(video).absolute()
        self._run(project_path, video, default_out_dir(project_path, video), max_frames, f"Tracking {video.name}…")
        return True

    def start_correction(self, frame: int, pose: dict, max_frames: int | None = None) -> bool:
        """Re-track the shown results from ``frame`` on, frame ``frame`` fitted from ``pose`` (the
        first-pose JSON object: clicks of that frame, or R/t), in the worker behind the progress
        dialog (:func:`tracking.run.track_video` with ``correct_frame``/``correct_pose``).

        The run's settings come from the shown ``track.json`` (video, expressions, first pose, focal
        length) and its results folder; ``max_frames`` None uses the "frames to track" box (0: the
        whole video). Frames before ``frame`` are kept. Returns False (with a dialog saying why)
        when nothing was started.
        """
        if self.jobs.busy:
            self.last_message = "a video is already being tracked"
            return False
        if self.doc is None or self.out_dir is None:
            self._error("Cannot correct", "no tracking results are shown: track a video or open results first")
            return False
        project_path = self.model.path
        if project_path is None:
            self._error("Cannot correct", "save the project first: tracking reads the project file")
            return False
        settings = self.review.correction_settings()
        video = settings.pop("video")
        self._pending_frame = int(frame)
        self._run(
            project_path,
            video,
            self.out_dir,
            max_frames,
            f"Re-tracking {video.name} from frame {frame}…",
            correct_frame=int(frame),
            correct_pose=pose,
            **settings,
        )
        return True

    def _run(self, project_path, video: Path, out: Path, max_frames: int | None, label: str, **kwargs) -> None:
        """:func:`tracking.run.track_video` into ``out`` in the worker, behind the progress dialog."""
        if max_frames is None:
            max_frames = self.limit_box.value() or None
        self._pending_out = out

        def work(progress, cancel):

            def report(done, total):
                frac = done / total if total else 0.0
                progress(f"tracked frame {done} of {total if total else '?'}", frac)

            return track_video(
                project_path, video, out, max_frames=max_frames, progress=report, cancel=cancel, **kwargs
            )

        self.jobs.start(work)
        self._progress = open_progress(self, "Tracking", label, self.jobs.cancel)
        self.last_message = f"{label[0].lower()}{label[1:-1]} into {out}…"

    def tracked_feature_positions(self, index: int) -> dict[str, tuple[float, float]]:
        """{feature: (u, v)} image px: the project's pose features where the tracked model puts them
        in frame ``index`` (its pose and expression there, projected by the video camera; clamped to
        the image so that a model that left it still has markers to drag; :meth:`TrackReview.feature_positions`)."""
        return self.review.feature_positions(index, self.model.project)

    def correct_pose_dialog(self, frame: int | None = None, modal: bool = True) -> FirstPoseDialog | None:
        """Open :class:`FirstPoseDialog` in correction mode on tracked frame ``frame`` (default: the
        shown one), its features prefilled by :meth:`tracked_feature_positions`; accepting it
        (*Re-track from here*) calls :meth:`start_correction` with its clicks.

        ``modal`` runs it with ``exec()``; otherwise it is shown and returned (tests). None (with a
        message box) without results, while tracking, or when the frame cannot be read.
        """
        if self.jobs.busy:
            self._error("Cannot correct", "a video is being tracked: wait for it or cancel it first")
            return None
        if not self._records or self.doc is None:
            self._error("Cannot correct", "no tracking results are shown: track a video or open results first")
            return None
        frame = self.current_frame if frame is None else int(frame)
        if not 0 <= frame < len(self._records):
            self._error("Cannot correct", f"frame {frame} is not tracked (frames 0..{len(self._records) - 1})")
            return None
        try:
            clicks = self.tracked_feature_positions(frame)
            dlg = FirstPoseDialog(
                self.model.project,
                self.doc["video"]["path"],
                parent=self,
                frame=frame,
                clicks=clicks,
                focal_px=float(self.doc["camera"]["focal_px"]),
                model=self.review.fitter().model,
                correct=True,
            )
        except FaceStudioError as exc:
            self._error("Cannot correct the pose", str(exc))
            return None
        dlg.accepted.connect(lambda: self.start_correction(dlg.frame, dlg.spec()))
        self.correct_dialog_widget = dlg
        if modal:
            dlg.exec()
        else:
            dlg.show()
        return dlg

    def _update_buttons(self) -> None:
        self.correct_button.setEnabled(bool(self._records) and not self.jobs.busy)

    def first_pose_dialog(self, video: str | Path | None = None, modal: bool = True) -> FirstPoseDialog | None:
        """Open :class:`FirstPoseDialog` on ``video`` (asked for when None) with the current project.

        ``modal`` runs it with ``exec()``; otherwise it is shown and returned (tests). None (with a
        message box) when no video was chosen or frame 0 cannot be read.
        """
        if video is None:
            start = str(Path(self.model.path).parent / "video") if self.model.path is not None else ""
            video, _ = QFileDialog.getOpenFileName(
                self, "Set the first pose of a video", start, "Videos (*.mp4 *.avi *.mov *.mkv *.webm);;All files (*)"
            )
            if not video:
                return None
        try:
            dlg = FirstPoseDialog(self.model.project, video, parent=self)
        except FaceStudioError as exc:
            self._error("Cannot set the first pose", str(exc))
            return None
        self.first_pose_dialog_widget = dlg
        if modal:
            dlg.exec()
            self.last_message = dlg.last_message
        else:
            dlg.show()
        return dlg

    def _close_progress(self):
        close_progress(self._progress, self.jobs.cancel)
        self._progress = None

    def _on_progress(self, stage: str, fraction: float):
        update_progress(self._progress, stage, fraction)

    def _on_finished(self, result):
        self._close_progress()
        self.load_results(result.out_dir)
        self.last_message = (
            f"tracked {result.tracked} frames ({result.fps:.1f} frames/s), "
            f"{result.diverged} diverged; results in {result.out_dir}"
        )
        if result.corrected is not None:
            self.last_message = f"frame {result.corrected} corrected: re-{self.last_message}"
            self.set_frame(result.corrected)
        self._pending_frame = None
        self.caption.setText(self._caption() + f" — {result.tracked} frames tracked, {result.fps:.1f} frames/s")

    def _on_failed(self, message: str):
        self._close_progress()
        self._pending_frame = None
        self._error("Tracking failed", message)

    def _on_cancelled(self):
        self._close_progress()
        # the frames tracked before the cancel are saved (cancel-safe): show them
        out = self._pending_out
        if out is not None and (out / "track.json").is_file():
            self.load_results(out)
            if self._pending_frame is not None:
                self.set_frame(self._pending_frame)
        self._pending_frame = None
        self.last_message = f"tracking cancelled after {self.frame_count} frames; a new run continues from there"
        self.caption.setText(self._caption() + f" — {self.last_message}")

    def _error(self, title: str, message: str) -> None:
        self.last_message = message
        QMessageBox.critical(self, title, message)

    # ------------------------------------------------------------------ results
    def load_results(self, out_dir: str | Path) -> bool:
        """Show the tracking results in ``out_dir`` (its ``track.json``); False (with a dialog) if none."""

        try:
            self.review = TrackReview.open(out_dir)
        except FaceStudioError as exc:
            self._error("Cannot open the tracking results", str(exc))
            return False
        self.slider.blockSignals(True)
        self.slider.setRange(0, max(len(self._records) - 1, 0))
        self.slider.setValue(0)
        self.slider.blockSignals(False)
        self.slider.setEnabled(bool(self._records))
        self.caption.setText(self._caption())
        self.edit_panel.set_review(self.review)
        self._show_frame(0)
        self._update_buttons()
        return True

    def _caption(self) -> str:
        if self.doc is None:
            return ""
        d = self.doc
        n = len(self._records)
        total = d["video"].get("frames")
        state = "complete" if d.get("complete") else f"{n} of {total if total else '?'} frames"
        return f"<b>{Path(d['video']['path']).name}</b>: {n} frames tracked ({state}) — {self.out_dir}"

    def _fit_pixmap(self) -> None:
        """The frame scaled to the label (aspect kept, nearest pixel: the footage's pixels stay visible)."""
        if self._pixmap is not None:
            size = self.frame_label.contentsRect().size()
            self.frame_label.setPixmap(
                self._pixmap.scaled(size, Qt.AspectRatioMode.KeepAspectRatio, Qt.TransformationMode.FastTransformation)
            )

    def resizeEvent(self, event):
        super().resizeEvent(event)
        self._fit_pixmap()

    def _show_frame(self, index: int) -> None:
        if not self._records:
            self.image = self._pixmap = None
            self.frame_label.setText("no frames tracked")
            self.index_label.setText("frame –")
            for label in self.plot_labels.values():
                label.clear()
            return
        index = int(np.clip(index, 0, len(self._records) - 1))
        rec = self._records[index]
        self.index_label.setText(
            f"frame {index} / {len(self._records) - 1}   rms {rec['rms']:.3f}"
            + ("  DIVERGED" if rec["diverged"] else "")
            + ("  corrected" if rec.get("start") == "user" else "")
        )
        frame = self.review.footage_frame(index)
        if frame is not None:
            if self.overlay_box.isChecked():
                try:
                    frame = self.review.overlay(index, frame)
                except FaceStudioError as exc:
                    self.review.footage_error = f"no overlay: {exc}"
                    self.overlay_box.setChecked(False)
            self.image = frame
            self._pixmap = QPixmap.fromImage(to_qimage(np.round(np.clip(frame, 0, 1) * 255).astype(np.uint8)))
            self._fit_pixmap()
        else:
            self.image = self._pixmap = None
            self.frame_label.setText(self.review.footage_error or f"frame {index} of the footage could not be read")
        x = np.array([r["frame"] for r in self._records], float)
        for name, label in self.plot_labels.items():
            plot = self.review.plots.get(name)
            if plot is None:
                label.clear()
            else:
                label.setPixmap(QPixmap.fromImage(to_qimage(plot_with_marker(plot, x, rec["frame"]))))


class ClickCanvas(QWidget):
    """A video frame with one draggable marker per clicked feature (image px, centres at integers).

    A press near a marker (≤ :attr:`GRAB_PX` screen px) drags it; elsewhere it places the
    feature :attr:`current` there. Emits :attr:`changed` after every placement or drag.
    """

    GRAB_PX = 8.0
    changed = Signal()

    def __init__(self, parent=None):
        super().__init__(parent)
        self.image: np.ndarray | None = None  # (H, W, 3) uint8 RGB
        self._qimage: QImage | None = None
        self.clicks: dict[str, tuple[float, float]] = {}
        self.current: str | None = None
        self._drag: str | None = None
        self.setMinimumSize(300, 300)
        self.setMouseTracking(False)

    def set_image(self, image: np.ndarray) -> None:
        self.image = np.ascontiguousarray(image)
        self._qimage = to_qimage(self.image)
        self.update()

    def _geometry(self) -> tuple[float, float, float]:
        """(scale, x0, y0): widget = x0 + scale · (u + 0.5)."""
        h, w = self.image.shape[:2]
        s = min(self.width() / w, self.height() / h)
        return s, (self.width() - s * w) / 2, (self.height() - s * h) / 2

    def to_image(self, x: float, y: float) -> tuple[float, float]:
        """Widget position → image pixel (u, v)."""
        s, x0, y0 = self._geometry()
        return (x - x0) / s - 0.5, (y - y0) / s - 0.5

    def to_widget(self, u: float, v: float) -> QPointF:
        """Image pixel (u, v) → widget position."""
        s, x0, y0 = self._geometry()
        return QPointF(x0 + s * (u + 0.5), y0 + s * (v + 0.5))

    def paintEvent(self, event):
        p = QPainter(self)
        p.fillRect(self.rect(), QColor(40, 40, 40))
        if self._qimage is None:
            return
        s, x0, y0 = self._geometry()
        h, w = self.image.shape[:2]
        p.drawImage(QRectF(x0, y0, s * w, s * h), self._qimage)
        for name, (u, v) in self.clicks.items():
            c = self.to_widget(u, v)
            color = QColor(255, 200, 0) if name == self.current else QColor(0, 230, 255)
            p.setPen(QPen(color, 1.5))
            p.drawEllipse(c, 4.0, 4.0)
            p.drawLine(c + QPointF(-6, 0), c + QPointF(6, 0))
            p.drawLine(c + QPointF(0, -6), c + QPointF(0, 6))
            p.drawText(c + QPointF(6, -6), name)

    def _near(self, pos: QPointF) -> str | None:
        best, dist = None, self.GRAB_PX
        for name, (u, v) in self.clicks.items():
            d = math.hypot(*(self.to_widget(u, v) - pos).toTuple())
            if d <= dist:
                best, dist = name, d
        return best

    def mousePressEvent(self, event):
        if self.image is None or event.button() != Qt.MouseButton.LeftButton:
            return super().mousePressEvent(event)
        pos = event.position()
        self._drag = self._near(pos) or self.current
        if self._drag is not None:
            self.current = self._drag
            self._place(pos)

    def mouseMoveEvent(self, event):
        if self._drag is not None:
            self._place(event.position())

    def mouseReleaseEvent(self, event):
        self._drag = None

    def _place(self, pos: QPointF) -> None:
        h, w = self.image.shape[:2]
        u, v = self.to_image(pos.x(), pos.y())
        self.clicks[self._drag] = (float(np.clip(u, -0.5, w - 0.5)), float(np.clip(v, -0.5, h - 0.5)))
        self.update()
        self.changed.emit()


class FirstPoseDialog(QDialog):
    """Set the first frame's pose of a video, or correct a tracked frame's, by clicking the project's
    pose features (§6.2).

    Shows a frame, the project's pose features (``project.feature_names(pose_only=True)``) and a
    focal length. *Solve* runs :func:`tracking.frame_fit.pose_from_clicks` (≥ 6 clicks) and shows the
    model over the frame (:func:`tracking.overlay_video.overlay_frame`).

    * **First pose** (default): frame 0, pre-filled from an existing first-pose JSON
      (:func:`tracking.first_pose.load_first_pose` format); *Save* writes ``{"focal_px", "clicks"}``
      atomically to :attr:`path` (default :func:`tracking.first_pose.default_first_pose_path`).
    * **Correction** (``correct=True``, :meth:`TrackingView.correct_pose_dialog`): frame ``frame``,
      pre-filled with ``clicks`` (where the tracked model puts the features), the focal length fixed
      to the run's; *Re-track from here* solves (the clicks must give a pose) and accepts; the
      caller reads :meth:`spec`. Nothing is written.

    Parameters
    ----------
    project : photomodel.project.Project, whose features are clicked (and whose face model is fitted).
    video : path of the video file or frame folder.
    path : where to read/write the first pose (default beside the video; unused when correcting).
    frame : int, the frame shown and clicked (default 0).
    clicks : {feature: (u, v)} px, optional, initial marker positions (instead of the file's).
    focal_px : float, optional, the video camera's focal length (fixed when correcting).
    model : tracking.blendshape_face.FaceModel, optional, the face model to solve with (default: the
        project's, :func:`tracking.face_from_project.project_face_model`, built on the first *Solve*).
    correct : bool, correction mode (see above).

    Attributes
    ----------
    frame : int, the frame shown.
    frame_image : (H, W, 3) float32, that frame (``frame0``: the same, the name of the first-pose mode).
    canvas : ClickCanvas, the frame and the clicks (image px).
    features : QListWidget, the pose features (check marks: clicked).
    focal_box : QDoubleSpinBox, focal length in px.
    save_button : QPushButton, *Save* (first pose) or *Re-track from here* (correction).
    state : FrameState or None, the last solved pose.
    overlay : (H, W, 3) float32 or None, the last solved overlay image.
    last_message : str
    """

    def __init__(
        self,
        project,
        video: str | Path,
        path: str | Path | None = None,
        parent=None,
        *,
        frame: int = 0,
        clicks: dict | None = None,
        focal_px: float | None = None,
        model=None,
        correct: bool = False,
    ):
        super().__init__(parent)

        self.project = project
        self.video = Path(video).absolute()
        self.path = Path(path).absolute() if path is not None else default_first_pose_path(self.video)
        self.frame = int(frame)
        self.correct = bool(correct)
        self.state = None
        self.overlay: np.ndarray | None = None
        self.last_message = ""
        self._model = model
        self._fitter = None
        self._focal = None if focal_px is None else float(focal_px)
        frames = VideoFrames(self.video)  # raises VideoError naming the file
        shown = next(frames.frames(self.frame, self.frame + 1), None) if self.frame >= 0 else None
        if shown is None:
            raise VideoError(f"frame {self.frame} of {self.video} cannot be read (the video is shorter)")
        self.frame_image = shown[1]
        self.width, self.height = frames.width, frames.height
        self.setWindowTitle(
            f"Correct the pose of frame {self.frame} — {self.video.name}"
            if self.correct
            else f"First pose — {self.video.name}"
        )

        self.canvas = ClickCanvas()
        self.canvas.set_image(np.round(self.frame_image * 255).astype(np.uint8))
        self.canvas.changed.connect(self._sync_list)
        self.features = QListWidget()
        for name in project.feature_names(pose_only=True):
            item = QListWidgetItem(name)
            item.setData(Qt.ItemDataRole.UserRole, name)
            self.features.addItem(item)
        self.features.currentRowChanged.connect(self._select)
        self.focal_box = QDoubleSpinBox()
        self.focal_box.setRange(1.0, 1e6)
        self.focal_box.setDecimals(2)
        self.focal_box.setSuffix(" px")
        self.focal_box.setValue(self._focal if self._focal is not None else max(self.width, self.height) * 1.5)
        if self.correct:  # one camera per video: the run's
            self.focal_box.setEnabled(False)
        clear = QPushButton("Clear click")
        clear.clicked.connect(lambda: self.canvas.current and self.remove_click(self.canvas.current))
        self.solve_button = QPushButton("Solve")
        self.solve_button.clicked.connect(self.solve)
        self.save_button = QPushButton("Re-track from here" if self.correct else "Save")
        self.save_button.clicked.connect(self._confirm)
        close = QPushButton("Close")
        close.clicked.connect(self.reject)
        self.info = QLabel(
            f"drag the features that are off in frame {self.frame} (≥ 6 placed), Solve to preview, "
            f"then Re-track from here"
            if self.correct
            else "click each feature's position in frame 0 (≥ 6), then Solve"
        )
        self.info.setWordWrap(True)

        side = QVBoxLayout()
        side.addWidget(QLabel("pose features"))
        side.addWidget(self.features, 1)
        side.addWidget(clear)
        side.addWidget(QLabel("focal length"))
        side.addWidget(self.focal_box)
        side.addWidget(self.solve_button)
        side.addWidget(self.save_button)
        side.addWidget(close)
        row = QHBoxLayout()
        row.addWidget(self.canvas, 1)
        row.addLayout(side)
        lay = QVBoxLayout(self)
        lay.addLayout(row, 1)
        lay.addWidget(self.info)
        self.resize(760, 560)
        if clicks is not None:
            for name, uv in clicks.items():
                self.set_click(name, uv)
        elif not self.correct:
            self._prefill()
        if self.features.count():
            self.features.setCurrentRow(0)

    @property
    def frame0(self) -> np.ndarray:
        """The frame shown (frame 0 in the first-pose mode)."""
        return self.frame_image

    # ------------------------------------------------------------------ public API
    @property
    def clicks(self) -> dict[str, tuple[float, float]]:
        """{feature: (u, v)} image px of the features clicked so far (a copy)."""
        return dict(self.canvas.clicks)

    def set_click(self, name: str, uv) -> None:
        """Place feature ``name`` at image pixel ``uv`` = (u, v)."""
        u, v = (float(x) for x in uv)
        if not (math.isfinite(u) and math.isfinite(v)):
            raise ValueError(f"the click of {name!r} must be finite pixels, got {uv!r}")
        self.canvas.clicks[name] = (u, v)
        self.canvas.update()
        self._sync_list()

    def remove_click(self, name: str) -> None:
        self.canvas.clicks.pop(name, None)
        self.canvas.update()
        self._sync_list()

    def spec(self) -> dict:
        """The first-pose JSON object: ``{"focal_px": f, "clicks": {name: [u, v]}}`` (clicks of
        :attr:`frame`; when correcting, ``f`` is the run's focal length exactly)."""
        focal = self._focal if self.correct and self._focal is not None else float(self.focal_box.value())
        return {
            "focal_px": focal,
            "clicks": {n: [round(u, 3), round(v, 3)] for n, (u, v) in self.canvas.clicks.items()},
        }

    def solve(self) -> bool:
        """Pose from the clicks (:func:`tracking.frame_fit.pose_from_clicks`) and its overlay on the frame.

        False (with a message box) with fewer than 6 clicks or when no pose is found."""

        names = list(self.canvas.clicks)
        if len(names) < 6:
            return self._fail(f"{len(names)} features clicked: the pose of frame {self.frame} needs at least 6")
        try:
            model = self._face_model()
            vertices = self.project.feature_vertices(names)
            uv = np.array([self.canvas.clicks[n] for n in names], float)
            focal = float(self.spec()["focal_px"])
            state = pose_from_clicks(model, vertices, uv, focal, self.width, self.height)
            if self._fitter is None or self._fitter.f != focal:
                self._fitter = FrameFitter(model, focal, self.width, self.height)
            rec = {
                "R": state.R.tolist(),
                "centre_mm": state.t.tolist(),
                "alpha": state.alpha.tolist(),
                "frame": self.frame,
                "rms": 0.0,
                "diverged": False,
            }
            overlay = overlay_frame(self._fitter, self.frame_image, rec)
        except (FaceStudioError, cv2.error) as exc:
            return self._fail(f"no pose from these clicks: {exc}")
        self.state, self.overlay = state, overlay
        self.canvas.set_image(np.round(np.clip(overlay, 0, 1) * 255).astype(np.uint8))
        depth = float(state.t[2])
        self.last_message = f"pose from {len(names)} clicks: model centre {depth:.0f} mm from the camera"
        self.info.setText(self.last_message)
        return True

    def save(self, path: str | Path | None = None) -> bool:
        """Write :meth:`spec` atomically (temp file + ``os.replace``) to ``path`` (default :attr:`path`).

        False (with a message box) with fewer than 6 clicks or when the file cannot be written."""
        target = Path(path).absolute() if path is not None else self.path
        if len(self.canvas.clicks) < 6:
            return self._fail(f"{len(self.canvas.clicks)} features clicked: save at least 6")
        tmp = target.with_name(target.name + ".tmp")
        try:
            tmp.write_text(json.dumps(self.spec(), indent=1) + "\n")
            os.replace(tmp, target)
        except OSError as exc:
            tmp.unlink(missing_ok=True)
            return self._fail(f"cannot write {target}: {exc}")
        self.path = target
        self.last_message = f"first pose saved to {target}"
        self.info.setText(self.last_message)
        return True

    # ------------------------------------------------------------------ internals
    def _confirm(self) -> None:
        """*Save* (then close), or when correcting *Re-track from here*: accept once the clicks solve."""
        if self.correct:
            if self.solve():
                self.last_message = f"re-tracking from frame {self.frame} with {len(self.canvas.clicks)} features"
                self.accept()
        elif self.save():
            self.accept()

    def _face_model(self):
        if self._model is None:
            self._model, _ = project_face_model(self.project)
        return self._model

    def _prefill(self) -> None:
        if not self.path.is_file():
            self._prefill_detected()
            return
        try:
            spec = json.loads(self.path.read_text())
        except (OSError, ValueError) as exc:
            self.last_message = f"{self.path} is not readable JSON ({exc}); starting without clicks"
            self.info.setText(self.last_message)
            return
        if not isinstance(spec, dict):
            return

        try:
            if "focal_px" in spec:
                self.focal_box.setValue(float(spec["focal_px"]))
            elif "focal_mm" in spec:
                self.focal_box.setValue(focal_mm_to_px(float(spec["focal_mm"]), self.width))
            for name, uv in (spec.get("clicks") or {}).items():
                self.set_click(name, uv)
        except (TypeError, ValueError) as exc:
            self.last_message = f"{self.path}: some entries were ignored ({exc})"
            self.info.setText(self.last_message)

    def _prefill_detected(self) -> None:
        """No first-pose file yet: the landmark detector's pose features of the frame (~0.1 s) and
        the focal length of the project's cameras (:mod:`tracking.detected_pose`), for the user to
        check and drag."""
        focal, source = video_focal_px(self.project, self.width, self.height)
        self.focal_box.setValue(focal)
        spec = detected_spec(self.frame_image, self.project, focal)
        if spec is None:
            self.last_message = "the landmark detector found no face in this frame: click the features"
        else:
            for name, uv in spec["clicks"].items():
                self.set_click(name, uv)
            self.last_message = (
                f"{len(spec['clicks'])} features placed by the landmark detector (check them, "
                f"drag any that are off); focal length: {source}"
            )
        self.info.setText(self.last_message)

    def _select(self, row: int) -> None:
        item = self.features.item(row)
        self.canvas.current = item.data(Qt.ItemDataRole.UserRole) if item is not None else None
        self.canvas.update()

    def _sync_list(self) -> None:
        """Check marks on the clicked features; the list follows the canvas's current feature."""
        for i in range(self.features.count()):
            item = self.features.item(i)
            name = item.data(Qt.ItemDataRole.UserRole)
            item.setText(f"{name}  ✓" if name in self.canvas.clicks else name)
            if name == self.canvas.current and self.features.currentRow() != i:
                self.features.blockSignals(True)
                self.features.setCurrentRow(i)
                self.features.blockSignals(False)

    def _fail(self, message: str) -> bool:
        self.last_message = message
        QMessageBox.critical(self, "Correct pose" if self.correct else "First pose", message)
        return False
