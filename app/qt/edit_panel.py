"""The *Edit* tab of the studio's tracking view: expression editing of a tracked clip (issue 16, Yang et al. 2012).

Thin widgets over :class:`tracking.edit_session.EditSession` (the Qt-free state: edits with undo and
redo, curves before and after, one frame edited beside the original, export):

* a region and expression to edit, a span (two spin boxes, or a drag across :class:`CurvePlot`),
  a factor and a ramp → *Apply scale* (magnify > 1, suppress < 1);
  *Replace span through frame N* (§5.2);
* :class:`CurvePlot`: the chosen weight curve as tracked (grey, dashed) and as edited (orange),
  the span shaded, the shown frame marked;
* a frame scrubber showing the footage frame beside the edited one
  (:meth:`EditSession.frame_pair`, rendered on the GUI thread like the view's overlays);
* *Undo* / *Redo* (the session's own stack: the tracking view has no studio undo stack);
* *Export…*: every frame written (PNG folder, or ``.mp4`` with its PNG frames beside it) and the
  edits saved to ``edits.json`` beside ``track.json``, in a :class:`~app.qt.workers.JobController`
  worker behind a cancellable progress dialog.

:class:`EditPanel` is built by :class:`app.qt.tracking_view.TrackingView` and fed a
:class:`tracking.review.TrackReview` by :meth:`EditPanel.set_review`.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from PySide6.QtCore import QPointF, QRectF, Qt, Signal
from PySide6.QtGui import QColor, QPainter, QPainterPath, QPen, QPixmap
from PySide6.QtWidgets import (
    QComboBox,
    QDoubleSpinBox,
    QFileDialog,
    QGridLayout,
    QHBoxLayout,
    QLabel,
    QMessageBox,
    QPushButton,
    QSizePolicy,
    QSlider,
    QSpinBox,
    QVBoxLayout,
    QWidget,
)

from app.qt.progress import close_progress, open_progress, update_progress
from app.qt.texture_views import to_qimage
from app.qt.workers import JobController
from photomodel.errors import Cancelled, FaceStudioError
from tracking.edit import DEFAULT_RAMP, edits_document, save_edits
from tracking.edit_session import EditSession
from tracking.edit_video import edit_frames, write_frames, write_video
from tracking.track_result import state_of

__all__ = ["CurvePlot", "EditPanel", "export_session"]

ORIGINAL_COLOR = QColor(140, 140, 140)
EDITED_COLOR = QColor(255, 120, 0)
SPAN_COLOR = QColor(80, 140, 255, 50)


def export_session(session: EditSession, track_dir, out, progress=None, cancel=None) -> Path:
    """:meth:`EditSession.export` with progress and cancel (the worker's function): every frame
    edited (``progress(stage, fraction)`` per frame; ``cancel()`` polled, raising
    :class:`~photomodel.errors.Cancelled`), written to ``out`` (PNG folder, or ``.mp4`` with
    ``<stem>_frames/`` beside it), then ``track_dir/edits.json``. Returns ``out``."""
    n = session.frame_count

    def step(i):
        if cancel is not None and cancel():
            raise Cancelled()
        if progress is not None:
            progress(f"edited frame {i + 1} of {n}", (i + 1) / max(n, 1) * 0.9)

    images, _, _ = edit_frames(session.fitter, session.frames, session.states, session.edits, progress=step)
    out = Path(out)
    if progress is not None:
        progress("writing", 0.92)
    if out.suffix.lower() == ".mp4":
        write_frames(out.with_name(out.stem + "_frames"), images)
        write_video(out, images, session.fps)
    else:
        write_frames(out, images)
    save_edits(track_dir, edits_document(session.edits, n, None))
    return out


class CurvePlot(QWidget):
    """One weight curve over the frames: tracked (grey dashed) and edited (orange), the span shaded,
    the current frame marked. A left-button drag across it selects a span (:attr:`span_dragged`)."""

    span_dragged = Signal(int, int)
    frame_clicked = Signal(int)
    MARGIN = 28.0

    def __init__(self, parent=None):
        super().__init__(parent)
        self.original: np.ndarray | None = None
        self.edited: np.ndarray | None = None
        self.span = (0, 0)
        self.frame = 0
        self.title = ""
        self._press: int | None = None
        self.setMinimumSize(300, 160)
        self.setSizePolicy(QSizePolicy.Policy.Expanding, QSizePolicy.Policy.Expanding)

    def set_curves(self, original, edited, title: str = "") -> None:
        self.original, self.edited = np.asarray(original, float), np.asarray(edited, float)
        self.title = title
        self.update()

    def _range(self) -> tuple[float, float]:
        lo = min(0.0, float(self.original.min()), float(self.edited.min()))
        hi = max(1.0, float(self.original.max()), float(self.edited.max()))
        return lo, hi

    def to_x(self, t: float) -> float:
        n = len(self.original) if self.original is not None else 1
        w = self.width() - 2 * self.MARGIN
        return self.MARGIN + (t / max(n - 1, 1)) * w

    def to_frame(self, x: float) -> int:
        n = len(self.original) if self.original is not None else 1
        w = self.width() - 2 * self.MARGIN
        return int(np.clip(round((x - self.MARGIN) / max(w, 1.0) * max(n - 1, 1)), 0, max(n - 1, 0)))

    def _to_y(self, v: float, lo: float, hi: float) -> float:
        h = self.height() - 2 * self.MARGIN
        return self.MARGIN + (hi - v) / (hi - lo) * h

    def paintEvent(self, event):
        p = QPainter(self)
        p.setRenderHint(QPainter.RenderHint.Antialiasing)
        p.fillRect(self.rect(), QColor(255, 255, 255))
        if self.original is None or not len(self.original):
            return
        lo, hi = self._range()
        a, b = self.span
        x0, x1 = self.to_x(a - 0.5 if a > 0 else a), self.to_x(b + 0.5 if b < len(self.original) - 1 else b)
        p.fillRect(QRectF(x0, self.MARGIN, x1 - x0, self.height() - 2 * self.MARGIN), SPAN_COLOR)
        p.setPen(QPen(QColor(200, 200, 200), 1))
        for v in (0.0, 1.0):
            y = self._to_y(v, lo, hi)
            p.drawLine(QPointF(self.MARGIN, y), QPointF(self.width() - self.MARGIN, y))
            p.drawText(QPointF(4, y + 4), f"{v:g}")
        for curve, pen in (
            (self.original, QPen(ORIGINAL_COLOR, 2, Qt.PenStyle.DashLine)),
            (self.edited, QPen(EDITED_COLOR, 2.5)),
        ):
            path = QPainterPath()
            for t, v in enumerate(curve):
                pt = QPointF(self.to_x(t), self._to_y(float(v), lo, hi))
                path.moveTo(pt) if t == 0 else path.lineTo(pt)
            p.setPen(pen)
            p.drawPath(path)
            if len(curve) == 1:
                p.drawEllipse(QPointF(self.to_x(0), self._to_y(float(curve[0]), lo, hi)), 3, 3)
        p.setPen(QPen(QColor(0, 0, 0), 1))
        x = self.to_x(self.frame)
        p.drawLine(QPointF(x, self.MARGIN), QPointF(x, self.height() - self.MARGIN))
        p.drawText(QPointF(self.MARGIN, 16), f"{self.title}   — tracked (dashed), edited (orange); drag to pick a span")
        p.drawText(QPointF(self.MARGIN, self.height() - 8), f"frame 0 … {len(self.original) - 1}")

    def mousePressEvent(self, event):
        if self.original is None or event.button() != Qt.MouseButton.LeftButton:
            return super().mousePressEvent(event)
        self._press = self.to_frame(event.position().x())

    def mouseReleaseEvent(self, event):
        if self._press is None:
            return super().mouseReleaseEvent(event)
        a, b = sorted((self._press, self.to_frame(event.position().x())))
        self._press = None
        if a == b:
            self.frame_clicked.emit(a)
        else:
            self.span_dragged.emit(a, b)


class EditPanel(QWidget):
    """Edit the expressions of the tracked clip shown by the tracking view (module docstring).

    Attributes
    ----------
    session : EditSession or None, the edits of the shown results.
    review : TrackReview or None.
    original, edited : (H, W, 3) float32 or None, the frame pair now shown.
    jobs : JobController, the export worker.
    last_message : str
    """

    def __init__(self, model, parent=None):
        super().__init__(parent)
        self.session: EditSession | None = None
        self.review = None
        self.original: np.ndarray | None = None
        self.edited: np.ndarray | None = None
        self.last_message = ""
        self.last_export: Path | None = None
        self._progress = None
        self._pixmaps: list[QPixmap | None] = [None, None]
        self.jobs = JobController(model, self)
        self.jobs.progress.connect(lambda s, f: update_progress(self._progress, s, f))
        self.jobs.finished.connect(self._on_exported)
        self.jobs.failed.connect(self._on_export_failed)
        self.jobs.cancelled.connect(self._on_export_cancelled)
        self.jobs.busy_changed.connect(lambda *_: self._update_buttons())

        self.region_box = QComboBox()
        self.expression_box = QComboBox()
        self.first_box, self.last_box, self.frame_box = QSpinBox(), QSpinBox(), QSpinBox()
        self.factor_box = QDoubleSpinBox()
        self.factor_box.setRange(0.0, 3.0)
        self.factor_box.setSingleStep(0.1)
        self.factor_box.setValue(0.5)
        self.factor_box.setToolTip("the expression's weight times this factor (0 suppresses, > 1 magnifies)")
        self.ramp_box = QSpinBox()
        self.ramp_box.setRange(0, 50)
        self.ramp_box.setValue(DEFAULT_RAMP)
        self.ramp_box.setToolTip("frames over which the factor ramps in and out at span ends inside the clip")
        self.scale_button = QPushButton("Apply scale")
        self.replace_button = QPushButton("Replace span through frame")
        self.undo_button, self.redo_button = QPushButton("Undo"), QPushButton("Redo")
        self.export_button = QPushButton("Export…")
        self.cancel_button = QPushButton("Cancel export")
        self.plot = CurvePlot()
        self.original_label, self.edited_label = QLabel(), QLabel()
        for lab in (self.original_label, self.edited_label):
            lab.setAlignment(Qt.AlignmentFlag.AlignCenter)
            lab.setMinimumSize(150, 150)
            lab.setSizePolicy(QSizePolicy.Policy.Ignored, QSizePolicy.Policy.Ignored)
        self.slider = QSlider(Qt.Orientation.Horizontal)
        self.index_label = QLabel("frame –")
        self.edits_label = QLabel("no edits")
        self.edits_label.setWordWrap(True)

        self.region_box.currentIndexChanged.connect(lambda *_: self._refresh_plot())
        self.expression_box.currentIndexChanged.connect(lambda *_: self._refresh_plot())
        self.first_box.valueChanged.connect(lambda *_: self._refresh_plot())
        self.last_box.valueChanged.connect(lambda *_: self._refresh_plot())
        self.scale_button.clicked.connect(lambda: self.apply_scale())
        self.replace_button.clicked.connect(lambda: self.apply_replace())
        self.undo_button.clicked.connect(lambda: self.undo())
        self.redo_button.clicked.connect(lambda: self.redo())
        self.export_button.clicked.connect(lambda: self.export())
        self.cancel_button.clicked.connect(self.jobs.cancel)
        self.slider.valueChanged.connect(self._show_frame)
        self.plot.span_dragged.connect(self.set_span)
        self.plot.frame_clicked.connect(self.set_frame)
        self._lay_out()
        self._update_buttons()

    def _lay_out(self):
        g = QGridLayout()
        g.addWidget(QLabel("region"), 0, 0)
        g.addWidget(self.region_box, 0, 1)
        g.addWidget(QLabel("expression"), 0, 2)
        g.addWidget(self.expression_box, 0, 3)
        g.addWidget(QLabel("span"), 1, 0)
        g.addWidget(self.first_box, 1, 1)
        g.addWidget(QLabel("to"), 1, 2)
        g.addWidget(self.last_box, 1, 3)
        g.addWidget(QLabel("factor"), 2, 0)
        g.addWidget(self.factor_box, 2, 1)
        g.addWidget(QLabel("ramp"), 2, 2)
        g.addWidget(self.ramp_box, 2, 3)
        g.addWidget(self.scale_button, 2, 4)
        g.addWidget(QLabel("frame"), 3, 0)
        g.addWidget(self.frame_box, 3, 1)
        g.addWidget(self.replace_button, 3, 2, 1, 3)
        buttons = QHBoxLayout()
        for b in (self.undo_button, self.redo_button, self.export_button, self.cancel_button):
            buttons.addWidget(b)
        buttons.addStretch(1)
        pair = QHBoxLayout()
        for title, lab in (("original", self.original_label), ("edited", self.edited_label)):
            col = QVBoxLayout()
            col.addWidget(QLabel(title), 0, Qt.AlignmentFlag.AlignHCenter)
            col.addWidget(lab, 1)
            pair.addLayout(col, 1)
        scrub = QHBoxLayout()
        scrub.addWidget(self.slider, 1)
        scrub.addWidget(self.index_label)
        lay = QVBoxLayout(self)
        lay.addLayout(g)
        lay.addLayout(buttons)
        lay.addWidget(self.edits_label)
        lay.addWidget(self.plot, 2)
        lay.addLayout(pair, 3)
        lay.addLayout(scrub)

    # ------------------------------------------------------------------ state
    def set_review(self, review) -> None:
        """Edit the clip of ``review`` (a :class:`tracking.review.TrackReview`); a fresh session.
        The face model is built on first use (:meth:`ensure_session`)."""
        self.review, self.session = review, None
        self.original = self.edited = None
        n = review.frame_count if review is not None else 0
        doc = review.doc if review is not None else None
        for box in (self.region_box, self.expression_box):
            box.blockSignals(True)
            box.clear()
        if doc is not None:
            regions = doc["model"]["regions"]
            for r in doc["model"]["regions_with_parameters"]:
                self.region_box.addItem(r, regions.index(r))
            self.expression_box.addItems(list(doc["model"]["expressions"])[1:])
            if "mouth" in doc["model"]["regions_with_parameters"]:
                self.region_box.setCurrentText("mouth")
        for box in (self.region_box, self.expression_box):
            box.blockSignals(False)
        for box in (self.first_box, self.last_box, self.frame_box):
            box.blockSignals(True)
            box.setRange(0, max(n - 1, 0))
            box.blockSignals(False)
        self.first_box.setValue(0)
        self.last_box.setValue(max(n - 1, 0))
        self.slider.blockSignals(True)
        self.slider.setRange(0, max(n - 1, 0))
        self.slider.setValue(0)
        self.slider.blockSignals(False)
        self.plot.original = self.plot.edited = None
        self.plot.update()
        self.original_label.clear()
        self.edited_label.clear()
        self._update_buttons()
        if self.isVisible() and review is not None:  # the tab is shown: edit the new results at once
            self.refresh()

    def ensure_session(self) -> EditSession | None:
        """The :class:`EditSession` of the shown results, built on first use (the footage as float
        frames, the tracked states, the run's model and camera); None (with a dialog) when it cannot be."""
        if self.session is None and self.review is not None and self.review.frame_count:
            r = self.review
            if len(r.footage) < r.frame_count:
                self._error("Cannot edit", r.footage_error or "the footage of the tracked frames cannot be read")
                return None
            try:
                fitter = r.fitter()
            except FaceStudioError as exc:
                self._error("Cannot edit", str(exc))
                return None
            frames = [r.footage_frame(i) for i in range(r.frame_count)]
            states = [state_of(rec) for rec in r.records]
            self.session = EditSession(fitter, frames, states, fps=float(r.doc["video"].get("fps") or 25.0))
        return self.session

    @property
    def expression(self) -> str:
        return self.expression_box.currentText()

    @property
    def region_index(self) -> int:
        """Index of the chosen region in the model's regions (the R axis of :meth:`EditSession.curves`)."""
        return int(self.region_box.currentData())

    @property
    def span(self) -> tuple[int, int]:
        a, b = self.first_box.value(), self.last_box.value()
        return (a, b) if a <= b else (b, a)

    def set_span(self, first: int, last: int) -> None:
        """The span to edit (a drag across the curve lands here)."""
        self.first_box.setValue(int(first))
        self.last_box.setValue(int(last))

    def curve(self) -> tuple[np.ndarray, np.ndarray]:
        """(T,) the chosen region's weight of the chosen expression, tracked and edited."""
        s = self.ensure_session()
        before, after = s.curves()
        k = list(s.fitter.model.names).index(self.expression)
        return before[:, self.region_index, k], after[:, self.region_index, k]

    # ------------------------------------------------------------------ edits
    def apply_scale(self, factor: float | None = None) -> bool:
        """Scale the chosen expression over the span by ``factor`` (default the factor box)."""
        if factor is not None:
            self.factor_box.setValue(float(factor))
        a, b = self.span
        return self._edit(
            {
                "op": "scale",
                "expression": self.expression,
                "factor": float(self.factor_box.value()),
                "span": [a, b],
                "ramp": int(self.ramp_box.value()),
            }
        )

    def apply_replace(self, frame: int | None = None) -> bool:
        """Replace the span by an interpolation through ``frame``'s expression (default the frame box)."""
        if frame is not None:
            self.frame_box.setValue(int(frame))
        a, b = self.span
        return self._edit({"op": "replace", "span": [a, b], "frame": int(self.frame_box.value())})

    def _edit(self, edit: dict) -> bool:
        s = self.ensure_session()
        if s is None:
            return False
        try:
            s.add(edit)
        except FaceStudioError as exc:
            self._error("Cannot edit", str(exc))
            return False
        self.last_message = f"{edit['op']} {edit.get('expression', '')} frames {edit['span'][0]}–{edit['span'][1]}"
        self._changed()
        return True

    def undo(self) -> bool:
        ok = self.session is not None and self.session.undo()
        self._changed()
        return ok

    def redo(self) -> bool:
        ok = self.session is not None and self.session.redo()
        self._changed()
        return ok

    def _changed(self) -> None:
        self._refresh_plot()
        self._show_frame(self.slider.value())
        self._update_buttons()

    # ------------------------------------------------------------------ view
    def set_frame(self, index: int) -> None:
        if self.review is not None and self.review.frame_count:
            self.slider.setValue(int(np.clip(index, 0, self.review.frame_count - 1)))
            self._show_frame(self.slider.value())

    def refresh(self) -> None:
        """Build the session if needed and draw the curve and the shown frame pair."""
        if self.ensure_session() is not None:
            self._changed()

    def _refresh_plot(self) -> None:
        s = self.session
        if s is None or not self.expression or self.region_box.currentData() is None:
            return
        before, after = self.curve()
        self.plot.span = self.span
        self.plot.frame = self.slider.value()
        self.plot.set_curves(before, after, f"{self.region_box.currentText()}: {self.expression}")
        ops = [
            f"{e['op']} {e.get('expression', '')} ×{e['factor']:g} {e['span'][0]}–{e['span'][1]}"
            if e["op"] == "scale"
            else f"replace {e['span'][0]}–{e['span'][1]} @ {e['frame']}"
            for e in s.edits
        ]
        self.edits_label.setText("edits: " + "; ".join(ops) if ops else "no edits")

    def _show_frame(self, index: int) -> None:
        s = self.session
        if s is None:
            return
        index = int(np.clip(index, 0, s.frame_count - 1))
        self.original, self.edited = s.frame_pair(index)
        changed = bool(np.any(self.original != self.edited))
        self.index_label.setText(f"frame {index} / {s.frame_count - 1}" + ("  edited" if changed else ""))
        for i, (img, lab) in enumerate(((self.original, self.original_label), (self.edited, self.edited_label))):
            self._pixmaps[i] = QPixmap.fromImage(to_qimage(np.round(np.clip(img, 0, 1) * 255).astype(np.uint8)))
            lab.setPixmap(
                self._pixmaps[i].scaled(
                    lab.contentsRect().size(),
                    Qt.AspectRatioMode.KeepAspectRatio,
                    Qt.TransformationMode.FastTransformation,
                )
            )
        self.plot.frame = index
        self.plot.update()

    def resizeEvent(self, event):
        super().resizeEvent(event)
        if self.session is not None and self.original is not None:
            self._show_frame(self.slider.value())

    def _update_buttons(self) -> None:
        has = self.review is not None and self.review.frame_count > 0
        busy = self.jobs.busy
        for b in (self.scale_button, self.replace_button):
            b.setEnabled(has and not busy)
        self.undo_button.setEnabled(bool(self.session and self.session.edits) and not busy)
        self.redo_button.setEnabled(bool(self.session and self.session.can_redo) and not busy)
        self.export_button.setEnabled(has and not busy)
        self.cancel_button.setEnabled(busy)

    # ------------------------------------------------------------------ export
    def export(self, out: str | Path | None = None) -> bool:
        """Write every edited frame to ``out`` (asked for when None: a folder for PNGs or an ``.mp4``)
        and ``edits.json`` beside ``track.json``, in the worker behind a cancellable progress dialog."""
        s = self.ensure_session()
        if s is None or self.jobs.busy:
            return False
        if out is None:
            start = str(self.review.out_dir / "edited.mp4")
            out, _ = QFileDialog.getSaveFileName(
                self, "Export the edited clip", start, "Video (*.mp4);;PNG frames folder (*)"
            )
            if not out:
                return False
        # a snapshot: later edits on the GUI thread do not reach the running export
        snap = EditSession(s.fitter, s.frames, s.states, s.fps)
        snap.edits = [dict(e) for e in s.edits]
        track_dir = self.review.out_dir
        self.jobs.start(lambda progress, cancel: export_session(snap, track_dir, out, progress, cancel))
        self._progress = open_progress(
            self, "Export", f"Exporting the edited clip to {Path(out).name}…", self.jobs.cancel
        )
        self.last_message = f"exporting to {out}…"
        return True

    def _close_progress(self):
        close_progress(self._progress, self.jobs.cancel)
        self._progress = None

    def _on_exported(self, out):
        self._close_progress()
        self.last_export = Path(out)
        edits = self.review.out_dir / "edits.json"
        self.last_message = f"exported {self.session.frame_count} frames to {out}; edits in {edits}"

    def _on_export_failed(self, message: str):
        self._close_progress()
        self._error("Export failed", message)

    def _on_export_cancelled(self):
        self._close_progress()
        self.last_message = "export cancelled"

    def _error(self, title: str, message: str) -> None:
        self.last_message = message
        QMessageBox.critical(self, title, message)
