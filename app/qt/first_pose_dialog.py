"""The click dialog of a video frame's pose (§6.2): the first pose of a video, or a tracked frame's corrected.

:class:`FirstPoseDialog` shows a frame (:class:`ClickCanvas`, one draggable marker per clicked
feature) beside the project's pose features and a focal length; *Solve* runs
:func:`tracking.frame_fit.pose_from_clicks` and shows the model over the frame. In the first-pose
mode *Save* writes the clicks as the video's first pose (:mod:`tracking.first_pose`); in the
correction mode (:meth:`app.qt.tracking_view.TrackingView.correct_pose_dialog`) the tracking view
re-tracks from the frame with the solved pose.
"""

from __future__ import annotations

import json
import math
import os
from pathlib import Path

import cv2
import numpy as np
from PySide6.QtCore import QPointF, QRectF, Qt, Signal
from PySide6.QtGui import QColor, QImage, QPainter, QPen
from PySide6.QtWidgets import (
    QDialog,
    QDoubleSpinBox,
    QHBoxLayout,
    QLabel,
    QListWidget,
    QListWidgetItem,
    QMessageBox,
    QPushButton,
    QVBoxLayout,
    QWidget,
)

from app.qt.texture_views import to_qimage
from photomodel.camera import focal_mm_to_px
from photomodel.errors import FaceStudioError
from photomodel.photos.video import VideoError, VideoFrames
from tracking.detected_pose import detected_spec, video_focal_px
from tracking.face_from_project import project_face_model
from tracking.first_pose import default_first_pose_path
from tracking.frame_fit import FrameFitter, pose_from_clicks
from tracking.overlay_video import overlay_frame

__all__ = ["ClickCanvas", "FirstPoseDialog"]


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

        self._build_widgets()
        self.resize(760, 560)
        if clicks is not None:
            for name, uv in clicks.items():
                self.set_click(name, uv)
        elif not self.correct:
            self._prefill()
        if self.features.count():
            self.features.setCurrentRow(0)

    def _build_widgets(self) -> None:
        """The frame to click on the left; the features, the focal length and the buttons on the right."""
        self.canvas = ClickCanvas()
        self.canvas.set_image(np.round(self.frame_image * 255).astype(np.uint8))
        self.canvas.changed.connect(self._sync_list)
        self.features = QListWidget()
        for name in self.project.feature_names(pose_only=True):
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
