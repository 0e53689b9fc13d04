"""*Tracking → Clone from another project…*: another person's tracked performance on this face, side by side.

:class:`CloneDialog` picks project A (one of the project's ``people``, or any project file through
*Browse…*), one of A's tracking results (``results/*/track.json``, :func:`app.studio.cloning.track_results_of`)
and the method (:data:`tracking.clone.METHODS`), then runs the model's :class:`~app.studio.cloning.CloneJob`
(:func:`tracking.clone.clone_track`, as ``facestudio clone``) in its own
:class:`~app.qt.workers.JobController` behind a cancellable progress dialog. The result — B's tracking
results, ``<B>/results/<track>_from_<A>`` — opens in the tracking view like B's own, A is added to the
project's ``people``, and the dialog shows A's frame | B rendered at the frame's pose and expression
(:meth:`tracking.review.TrackReview.side_by_side`, the tracking view's own review and renderer),
scrubbable with a slider (←/→ step a frame).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from PySide6.QtCore import Qt
from PySide6.QtGui import QPixmap
from PySide6.QtWidgets import (
    QComboBox,
    QDialog,
    QFileDialog,
    QFormLayout,
    QHBoxLayout,
    QLabel,
    QMessageBox,
    QProgressDialog,
    QPushButton,
    QSizePolicy,
    QSlider,
    QVBoxLayout,
)

from app.qt.progress import close_progress, open_progress, update_progress
from app.qt.texture_views import to_qimage
from app.qt.workers import JobController
from app.studio.cloning import CloneJob, track_results_of
from photomodel.errors import FaceStudioError
from tracking.clone import METHODS

__all__ = ["CloneDialog", "METHOD_TIPS"]

#: What each method needs and does (the method box's tooltips).
METHOD_TIPS = {
    "multilinear": "seed 000's multilinear people model: A's expression on B's identity "
    "(the model file is built beforehand: python -m photomodel.people.model_file)",
    "mapping": "seed 001: A's and B's own expression spaces mapped into each other "
    "(each project needs at least two photographed expressions)",
    "displacement": "A's movement from A's neutral, aligned, added to B's neutral",
    "names": "ARKit rig weights copied by name (both projects need a rig: Rig ▸ Build rig)",
}


class CloneDialog(QDialog):
    """Clone a performance of another project onto the window's project and show the two side by side.

    Parameters
    ----------
    window : MainWindow, whose model (B, saved) takes the performance and whose tracking view opens it.

    Attributes
    ----------
    source_combo : editable QComboBox, project A's file (the project's ``people`` listed).
    track_combo : QComboBox, A's tracking results folders.
    method_combo : QComboBox, :data:`tracking.clone.METHODS`.
    clone_button, browse_button : QPushButton
    slider : QSlider, the frame shown side by side.
    image : (H, 2W, 3) float32 or None, the side-by-side image shown.
    result : tracking.clone.CloneResult or None, the last clone.
    jobs : JobController, the cloning worker.
    """

    def __init__(self, window):
        super().__init__(window)
        self.window = window
        self.model = window.model
        self.setWindowTitle("Clone from another project")
        self.result = None
        self.job: CloneJob | None = None
        self.image: np.ndarray | None = None
        self.last_message = ""
        self._pixmap: QPixmap | None = None
        self._progress: QProgressDialog | None = None
        self.jobs = JobController(self.model, self)
        self.jobs.progress.connect(lambda stage, f: update_progress(self._progress, stage, f))
        self.jobs.finished.connect(self._on_finished)
        self.jobs.failed.connect(self._on_failed)
        self.jobs.cancelled.connect(self._on_cancelled)

        self.source_combo = QComboBox()
        self.source_combo.setEditable(True)
        self.source_combo.setMinimumWidth(420)
        self.source_combo.setToolTip("project A (*.facestudio.json): the person whose tracked performance is cloned")
        for ref in self.model.project.people:
            self.source_combo.addItem(str(self.model.project.person_path(ref)))
        self.source_combo.setCurrentIndex(-1)
        self.source_combo.currentTextChanged.connect(self.set_source)
        self.browse_button = QPushButton("Browse…")
        self.browse_button.clicked.connect(self.browse)
        self.track_combo = QComboBox()
        self.track_combo.setToolTip("A's tracking results (results/track_*): the performance to clone")
        self.method_combo = QComboBox()
        for i, m in enumerate(METHODS):
            self.method_combo.addItem(m)
            self.method_combo.setItemData(i, METHOD_TIPS[m], Qt.ItemDataRole.ToolTipRole)
        self.method_combo.setToolTip("how A's faces become B's; hover over a method for what it needs")
        self.clone_button = QPushButton("Clone")
        self.clone_button.setDefault(True)
        self.clone_button.clicked.connect(lambda: self.start())
        self.clone_button.setEnabled(False)
        self.jobs.busy_changed.connect(lambda busy: self._update_buttons())

        self.caption = QLabel(f"Put another person's tracked performance on <b>{self.model.project.name}</b>.")
        self.caption.setWordWrap(True)
        self.frame_label = QLabel("<i>no clone yet</i>")
        self.frame_label.setAlignment(Qt.AlignmentFlag.AlignCenter)
        self.frame_label.setMinimumSize(480, 240)
        self.frame_label.setSizePolicy(QSizePolicy.Policy.Ignored, QSizePolicy.Policy.Ignored)
        self.slider = QSlider(Qt.Orientation.Horizontal)
        self.slider.setEnabled(False)
        self.slider.valueChanged.connect(self.show_frame)
        self.index_label = QLabel("frame –")
        self.index_label.setMinimumWidth(110)
        self._lay_out()
        self.resize(900, 560)

    def _lay_out(self) -> None:
        source = QHBoxLayout()
        source.addWidget(self.source_combo, 1)
        source.addWidget(self.browse_button)
        form = QFormLayout()
        form.addRow("Project A", source)
        form.addRow("Tracking results", self.track_combo)
        method = QHBoxLayout()
        method.addWidget(self.method_combo, 1)
        method.addWidget(self.clone_button)
        form.addRow("Method", method)
        scrub = QHBoxLayout()
        scrub.addWidget(self.slider, 1)
        scrub.addWidget(self.index_label)
        heads = QHBoxLayout()
        self.left_title, self.right_title = QLabel("<b>A</b> (tracked)"), QLabel("<b>B</b> (cloned)")
        for t in (self.left_title, self.right_title):
            t.setAlignment(Qt.AlignmentFlag.AlignCenter)
            heads.addWidget(t, 1)
        lay = QVBoxLayout(self)
        lay.addWidget(self.caption)
        lay.addLayout(form)
        lay.addLayout(heads)
        lay.addWidget(self.frame_label, 1)
        lay.addLayout(scrub)

    # ------------------------------------------------------------------ choosing A and its track
    @property
    def source(self) -> Path | None:
        text = self.source_combo.currentText().strip()
        return Path(text) if text else None

    @property
    def track(self) -> Path | None:
        data = self.track_combo.currentData()
        return None if data is None else Path(data)

    def browse(self) -> bool:
        """Choose project A's file."""
        start = str(self.model.path.parent.parent) if self.model.path is not None else ""
        path, _ = QFileDialog.getOpenFileName(self, "Project A", start, "Face Studio projects (*.facestudio.json)")
        if not path:
            return False
        self.source_combo.setCurrentText(path)
        return True

    def set_source(self, path: str | Path | None = None) -> int:
        """List the tracking results of project file ``path`` (default: the box's); returns how many."""
        if path is not None and str(path) != self.source_combo.currentText():
            self.source_combo.setCurrentText(str(path))  # comes back here through currentTextChanged
            return self.track_combo.count()
        self.track_combo.clear()
        src = self.source
        if src is not None and src.is_file():
            for folder in track_results_of(src):
                self.track_combo.addItem(folder.name, str(folder))
        self._update_buttons()
        return self.track_combo.count()

    def _update_buttons(self) -> None:
        self.clone_button.setEnabled(self.track_combo.count() > 0 and not self.jobs.busy)

    # ------------------------------------------------------------------ cloning
    def start(self, method: str | None = None) -> bool:
        """Clone the chosen track of A onto the project by ``method`` (default: the box's) in the worker,
        behind a cancellable progress dialog; False (with a message box) when nothing was started."""
        if self.jobs.busy:
            return False
        if method is not None:
            self.method_combo.setCurrentText(method)
        if self.source is None or self.track is None:
            self._error("Cannot clone", "choose project A and one of its tracking results first")
            return False
        try:
            job = self.model.clone_job(self.source, self.track, self.method_combo.currentText())
        except (FaceStudioError, ValueError) as exc:
            self._error("Cannot clone", str(exc))
            return False
        self.job = job
        self.jobs.start(job.run)
        self._progress = open_progress(self, "Clone", f"Cloning {job.track.name} ({job.method})…", self.jobs.cancel)
        self.last_message = f"cloning {job.track.name} of {job.project_a.name} ({job.method}) into {job.out_dir}…"
        return True

    def _close_progress(self) -> None:
        close_progress(self._progress, self.jobs.cancel)
        self._progress = None

    def _on_finished(self, result) -> None:
        self._close_progress()
        self.result = result
        self.model.add_person(self.job.project_a)  # B refers to A (the project's people)
        view = self.window.tracking_view
        self.window.tracking_dock.show()
        if not view.load_results(result.out_dir):
            return
        self.last_message = (
            f"cloned {result.frames} frames of {self.job.track.name} ({self.job.method}) into {result.out_dir}"
        )
        self.window.show_status(self.last_message, 20000)
        self.caption.setText(
            f"<b>{self.job.project_a.name}</b> → <b>{self.model.project.name}</b>: {self.last_message}"
        )
        self.left_title.setText(f"<b>A</b>: {self.job.project_a.name.split('.')[0]} (tracked)")
        self.right_title.setText(f"<b>B</b>: {self.model.project.name} ({self.job.method})")
        self.slider.blockSignals(True)
        self.slider.setRange(0, max(result.frames - 1, 0))
        self.slider.setValue(0)
        self.slider.blockSignals(False)
        self.slider.setEnabled(result.frames > 0)
        self.show_frame(0)

    def _on_failed(self, message: str) -> None:
        self._close_progress()
        self._error("Cloning failed", message)

    def _on_cancelled(self) -> None:
        self._close_progress()
        self.last_message = "cloning cancelled; nothing written"

    def _error(self, title: str, message: str) -> None:
        self.last_message = message
        QMessageBox.critical(self, title, message)

    # ------------------------------------------------------------------ side by side
    @property
    def review(self):
        """The tracking view's review of the cloned results (None before a clone)."""
        view = self.window.tracking_view
        if self.result is None or view.out_dir != self.result.out_dir:
            return None
        return view.review

    def show_frame(self, index: int) -> None:
        """A's frame ``index`` | B rendered there; the tracking view follows."""
        review = self.review
        if review is None or not review.frame_count:
            return
        index = int(np.clip(index, 0, review.frame_count - 1))
        self.index_label.setText(f"frame {index} / {review.frame_count - 1}")
        try:
            image = review.side_by_side(index)
        except FaceStudioError as exc:
            self.frame_label.setText(f"B cannot be rendered: {exc}")
            return
        if image is None:
            self.frame_label.setText(review.footage_error or f"frame {index} of A's footage could not be read")
            return
        self.image = image
        self._pixmap = QPixmap.fromImage(to_qimage(np.round(np.clip(image, 0, 1) * 255).astype(np.uint8)))
        self._fit_pixmap()
        self.window.tracking_view.set_frame(index)

    def _fit_pixmap(self) -> None:
        if self._pixmap is not None:
            size = self.frame_label.contentsRect().size()
            self.frame_label.setPixmap(
                self._pixmap.scaled(size, Qt.AspectRatioMode.KeepAspectRatio, Qt.TransformationMode.FastTransformation)
            )

    def resizeEvent(self, event):
        super().resizeEvent(event)
        self._fit_pixmap()

    def keyPressEvent(self, event):
        steps = {Qt.Key.Key_Left: -1, Qt.Key.Key_Right: 1}
        if self.slider.isEnabled() and event.key() in steps:
            self.slider.setValue(self.slider.value() + steps[event.key()])
            event.accept()
            return
        super().keyPressEvent(event)

    def done(self, r: int) -> None:
        self.jobs.shutdown()
        super().done(r)
