"""The studio's tracking view: track a video in a worker, then scrub through the result (§6.2).

:class:`TrackingView` (docked by the main window, *Tracking → Track video…* / *Open results…*)
runs the model's :class:`~app.studio.tracking.TrackJob` (:meth:`StudioModel.track_job
<app.studio_state.StudioModel.track_job>`: prepared here on the GUI thread, :meth:`TrackJob.run
<app.studio.tracking.TrackJob.run>` in its own :class:`~app.qt.workers.JobController`) behind a
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
that frame in the worker (a :class:`~app.studio.tracking.TrackJob` with ``correct_frame``/``correct_pose``),
behind the same cancellable progress dialog as *Track video…*.

Nothing here computes tracking itself: the state of the shown results — ``track.json``, the frame
records, the footage, the plots and the :class:`tracking.frame_fit.FrameFitter` of the run's model
and camera that renders overlays on the GUI thread (the renderer is per thread) — is a Qt-free
:class:`tracking.review.TrackReview`; the view shows it.
"""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING

import cv2
import numpy as np
from PySide6.QtCore import Qt
from PySide6.QtGui import QPixmap
from PySide6.QtWidgets import (
    QCheckBox,
    QFileDialog,
    QHBoxLayout,
    QLabel,
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
from app.qt.first_pose_dialog import ClickCanvas, FirstPoseDialog
from app.qt.progress import close_progress, open_progress, update_progress
from app.qt.texture_views import to_qimage
from app.qt.workers import JobController
from app.studio.tracking import TrackJob
from app.studio_state import StudioModel
from photomodel.errors import FaceStudioError, ProjectError
from tracking.plots import MARGINS
from tracking.review import TrackReview

if TYPE_CHECKING:
    from tracking.review import TrackReview

# the first-pose dialog lives in app/qt/first_pose_dialog.py; its names stay importable from here
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
        try:
            job = self.model.track_job(video, max_frames=self._frames_to_track(max_frames))
        except ProjectError as exc:  # the project has no file yet
            self._error("Cannot track", str(exc))
            return False
        self._run(job, f"Tracking {job.video.name}…")
        return True

    def start_correction(self, frame: int, pose: dict, max_frames: int | None = None) -> bool:
        """Re-track the shown results from ``frame`` on, frame ``frame`` fitted from ``pose`` (the
        first-pose JSON object: clicks of that frame, or R/t), in the worker behind the progress
        dialog (the model's :class:`~app.studio.tracking.TrackJob` with ``correct_frame``/``correct_pose``).

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
        settings = self.review.correction_settings()
        video = settings.pop("video")
        try:
            job = self.model.track_job(
                video,
                self.out_dir,
                self._frames_to_track(max_frames),
                correct_frame=int(frame),
                correct_pose=pose,
                **settings,
            )
        except ProjectError as exc:  # the project has no file yet
            self._error("Cannot correct", str(exc))
            return False
        self._pending_frame = int(frame)
        self._run(job, f"Re-tracking {job.video.name} from frame {frame}…")
        return True

    def _frames_to_track(self, max_frames: int | None) -> int | None:
        """``max_frames``, or the "frames to track" box's when None (0 there: the whole video, None)."""
        return max_frames if max_frames is not None else (self.limit_box.value() or None)

    def _run(self, job: TrackJob, label: str) -> None:
        """``job`` (prepared by the model) run in the worker, behind the progress dialog."""
        self._pending_out = job.out_dir
        self.jobs.start(job.run)
        self._progress = open_progress(self, "Tracking", label, self.jobs.cancel)
        self.last_message = f"{label[0].lower()}{label[1:-1]} into {job.out_dir}…"

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
