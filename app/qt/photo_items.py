"""What a photo view paints: the click markers, the predicted ghost, the fitted mesh's lines, and
the photo itself (read at its working resolution, or a grey placeholder naming why not).

Markers are coloured by their reprojection error after a fit (green < 1 px, yellow ~2 px,
red ≥ 4 px; white before any fit); hidden features are drawn hollow and grey; automatic clicks
(the landmark detector's, ``"source": "auto"`` in the file) are violet diamonds until the artist
drags them (then they are the artist's clicks, round; undo makes them automatic again). All
markers keep their size on screen (``ItemIgnoresTransformations``); the mesh's lines are
drawn with cosmetic (screen-width) pens.
"""

from __future__ import annotations

import math

import numpy as np
from PySide6.QtCore import QByteArray, QDataStream, QPointF, QRectF, Qt
from PySide6.QtGui import QBrush, QColor, QFont, QImage, QPainter, QPainterPath, QPen
from PySide6.QtWidgets import QGraphicsItem

from photomodel.errors import FaceStudioError
from photomodel.photos.reading import read_photo

MARKER_RADIUS_PX = 5.0
OVERLAY_COLORS = {0: QColor(0, 200, 255, 150), 1: QColor(255, 170, 0, 200), 2: QColor(255, 235, 0, 230)}
DRAWN_CURVE_COLOR = QColor(255, 60, 200)
#: Automatic clicks (the landmark detector's) are violet diamonds.
AUTO_COLOR = QColor(190, 110, 255)
#: The ghost marker of the active feature's predicted position (the current fit projected).
PREDICTED_COLOR = QColor(0, 230, 255)


def residual_color(px: float | None) -> QColor:
    """Marker colour for a reprojection error in pixels (None: not fitted yet)."""
    if px is None or not math.isfinite(px):
        return QColor(255, 255, 255)
    # green (0 px) → yellow (2 px) → red (4 px and more)
    x = min(max(px / 4.0, 0.0), 1.0)
    if x < 0.5:
        return QColor(int(510 * x), 220, 40)
    return QColor(255, int(220 * (1.0 - x) * 2), 40)


def load_photo_image(path, width: int, height: int) -> tuple[QImage, str | None, float]:
    """The photo as a QImage at its working resolution, through the modeling core's one reader
    (:func:`photomodel.photos.reading.read_photo`: EXIF orientation applied — a phone's
    portrait photo stands up, as its clicks were placed —, a truncated file refused, a very
    large one reduced), the reason it cannot be shown (``None`` when it can) and its scale
    (working pixels per original pixel). Unreadable: a grey placeholder of the stored size
    naming the reason, scale 1."""
    try:
        photo = read_photo(path)
    except FaceStudioError as exc:
        reason = str(exc)
    else:
        a = np.ascontiguousarray(photo.image)
        image = QImage(a.data, a.shape[1], a.shape[0], 3 * a.shape[1], QImage.Format.Format_RGB888).copy()
        return image, None, photo.scale
    ph = QImage(max(width, 1), max(height, 1), QImage.Format.Format_RGB32)
    ph.fill(QColor(90, 90, 90))
    p = QPainter(ph)
    p.setPen(QColor(230, 230, 230))
    f = QFont()
    f.setPixelSize(max(12, width // 40))
    p.setFont(f)
    p.drawText(ph.rect(), Qt.AlignmentFlag.AlignCenter | Qt.TextFlag.TextWordWrap, f"photo not shown\n{reason}")
    p.end()
    return ph, reason, 1.0


class PointItem(QGraphicsItem):
    """A click marker: constant size on screen, coloured by its reprojection error."""

    def __init__(self, name: str, uv, pose: bool):
        super().__init__()
        self.name = name
        self.pose = pose
        self.residual: float | None = None
        self.active = False
        self.hidden = False
        self.auto: float | None | bool = False  # False: the artist's click; else the detector's confidence
        self.setFlag(QGraphicsItem.GraphicsItemFlag.ItemIgnoresTransformations, True)
        # a repaint blits ~150 cached markers (~5 ms) instead of drawing them again (~25 ms)
        self.setCacheMode(QGraphicsItem.CacheMode.DeviceCoordinateCache)
        self.setZValue(10)
        self.setPos(QPointF(float(uv[0]), float(uv[1])))
        self.setAcceptHoverEvents(True)
        self._update_tip()

    def _update_tip(self):
        r = "not fitted" if self.residual is None else f"{self.residual:.2f} px from the fit"
        extra = ", pose feature" if self.pose else ""
        hid = " (hidden in this photo)" if self.hidden else ""
        auto = ""
        if self.is_auto:
            conf = "" if self.auto is True else f", confidence {self.auto:.2f}"
            auto = f" — automatic click{conf}; drag it to correct it"
        self.setToolTip(f"{self.name}{hid}: {r}{extra}{auto}")

    @property
    def is_auto(self) -> bool:
        return self.auto is not False

    def set_auto(self, auto: bool, confidence: float | None = None) -> None:
        """Mark the click as the detector's (with its confidence) or the artist's."""
        value = (True if confidence is None else float(confidence)) if auto else False
        if value != self.auto:
            self.auto = value
            self._update_tip()
            self.update()

    def _look(self):
        color = residual_color(self.residual).rgb()
        label = f"{self.residual:.1f}" if (self.active and self.residual is not None) else None
        return color, label, self.active, self.hidden

    def set_state(self, residual: float | None = None, active: bool | None = None, hidden: bool | None = None):
        before = self._look()
        self.residual = residual
        if active is not None and active != self.active:
            self.prepareGeometryChange()  # the label widens the bounding box
            self.active = active
            self.setZValue(11 if active else 10)
        if hidden is not None:
            self.hidden = hidden
        self._update_tip()
        if self._look() != before:  # repaint (and re-cache) only markers that look different
            self.update()

    def boundingRect(self) -> QRectF:
        r = MARKER_RADIUS_PX + 4
        return QRectF(-r, -r, 2 * r + (200 if self.active else 0), 2 * r)

    def paint(self, painter: QPainter, option, widget=None):
        painter.setRenderHint(QPainter.RenderHint.Antialiasing)
        r = MARKER_RADIUS_PX + (1.5 if self.active else 0.0)
        color = QColor(150, 150, 150) if self.hidden else residual_color(self.residual)
        painter.setBrush(Qt.BrushStyle.NoBrush)
        style = Qt.PenStyle.DashLine if self.hidden else Qt.PenStyle.SolidLine
        if self.is_auto:  # the detector's click: a violet diamond around the residual-coloured dot
            d = r + 1.5
            diamond = [QPointF(0, -d), QPointF(d, 0), QPointF(0, d), QPointF(-d, 0), QPointF(0, -d)]
            painter.setPen(QPen(QColor(0, 0, 0, 200), 3.0))
            painter.drawPolyline(diamond)
            painter.setPen(QPen(AUTO_COLOR, 1.8, style))
            painter.drawPolyline(diamond)
        else:
            painter.setPen(QPen(QColor(0, 0, 0, 200), 3.0))
            painter.drawEllipse(QPointF(0, 0), r, r)
            painter.setPen(QPen(color, 1.6, style))
            painter.drawEllipse(QPointF(0, 0), r, r)
        if not self.hidden:  # a dot at the exact position
            painter.setPen(Qt.PenStyle.NoPen)
            painter.setBrush(QBrush(color))
            painter.drawEllipse(QPointF(0, 0), 1.3, 1.3)
        if self.pose and not self.hidden:  # pose features get a tick above
            painter.setPen(QPen(color, 1.4))
            painter.drawLine(QPointF(0, -r - 3), QPointF(0, -r))
        if self.active:
            painter.setBrush(Qt.BrushStyle.NoBrush)
            painter.setPen(QPen(QColor(255, 255, 255), 2.0))
            painter.drawEllipse(QPointF(0, 0), r + 3, r + 3)
            f = painter.font()
            f.setPixelSize(12)
            f.setBold(True)
            painter.setFont(f)
            text = self.name if self.residual is None else f"{self.name}  {self.residual:.1f} px"
            painter.setPen(QColor(0, 0, 0, 220))
            painter.drawText(QPointF(r + 7, 5), text)
            painter.setPen(QColor(255, 255, 255))
            painter.drawText(QPointF(r + 6, 4), text)


class PredictedItem(QGraphicsItem):
    """The ghost marker: where the current fit puts the active feature in this photo."""

    def __init__(self):
        super().__init__()
        self.name = ""
        self.setFlag(QGraphicsItem.GraphicsItemFlag.ItemIgnoresTransformations, True)
        self.setZValue(9)  # under the clicks: a click on it lands on the photo, not on the ghost
        self.setVisible(False)

    def show_at(self, name: str, uv) -> None:
        self.name = name
        self.setPos(QPointF(float(uv[0]), float(uv[1])))
        self.setToolTip(f"{name}: where the current fit puts it")
        self.setVisible(True)
        self.update()

    def boundingRect(self) -> QRectF:
        r = MARKER_RADIUS_PX + 8
        return QRectF(-r, -r, 2 * r + 160, 2 * r)

    def paint(self, painter: QPainter, option, widget=None):
        painter.setRenderHint(QPainter.RenderHint.Antialiasing)
        r = MARKER_RADIUS_PX + 3
        for color, width in ((QColor(0, 0, 0, 160), 3.0), (PREDICTED_COLOR, 1.4)):
            painter.setPen(QPen(color, width, Qt.PenStyle.DashLine))
            painter.setBrush(Qt.BrushStyle.NoBrush)
            painter.drawEllipse(QPointF(0, 0), r, r)
            painter.drawLine(QPointF(-r - 4, 0), QPointF(-r + 3, 0))
            painter.drawLine(QPointF(r - 3, 0), QPointF(r + 4, 0))
            painter.drawLine(QPointF(0, -r - 4), QPointF(0, -r + 3))
            painter.drawLine(QPointF(0, r - 3), QPointF(0, r + 4))
        f = painter.font()
        f.setPixelSize(11)
        painter.setFont(f)
        painter.setPen(PREDICTED_COLOR)
        painter.drawText(QPointF(r + 6, r + 10), f"{self.name} (fit)")


def segments_path(uv: np.ndarray) -> QPainterPath:
    """A path of the segments ``uv`` (M, 2, 2): one move-to and one line-to per segment.

    Built by reading QPainterPath's QDataStream form (the element count, then per element its
    type and its x and y, big-endian) straight from a numpy buffer, as pyqtgraph's
    ``arrayToQPath`` does, instead of one Python call per element.
    """
    n = 2 * len(uv)
    elements = np.empty(n, dtype=[("type", ">i4"), ("x", ">f8"), ("y", ">f8")])
    points = np.asarray(uv, dtype=np.float64).reshape(-1, 2)
    elements["x"], elements["y"] = points[:, 0], points[:, 1]
    elements["type"][0::2] = 0  # QPainterPath.ElementType.MoveToElement
    elements["type"][1::2] = 1  # LineToElement
    fill_rule = 0  # Qt.FillRule.OddEvenFill, written after the elements
    data = np.array([n], ">i4").tobytes() + elements.tobytes() + np.array([fill_rule], ">i4").tobytes()
    buffer = QByteArray(data)  # kept alive while the stream reads it (PySide passes it by pointer)
    stream = QDataStream(buffer)
    path = QPainterPath()
    stream >> path
    return path


class LinesItem(QGraphicsItem):
    """Line segments in scene coordinates drawn with cosmetic (screen-width) pens, by kind."""

    def __init__(self, rect: QRectF):
        super().__init__()
        self._rect = QRectF(rect)
        self._paths: dict[int, QPainterPath] = {}
        self._count = 0
        self.setCacheMode(QGraphicsItem.CacheMode.DeviceCoordinateCache)  # redrawn on zoom, not on every repaint
        self.setZValue(5)

    def set_lines(self, uv: np.ndarray, kinds: np.ndarray) -> None:
        """``uv`` (M, 2, 2) px endpoints; ``kinds`` (M,) int (keys of :data:`OVERLAY_COLORS`)."""
        self.prepareGeometryChange()
        uv = np.asarray(uv, dtype=np.float64).reshape(-1, 2, 2)
        kinds = np.asarray(kinds)
        # one path of move-to/line-to pairs per kind, read at once from a numpy buffer: the same
        # pixels as drawLines of one QLineF per segment (checked pixel by pixel), but building
        # ~9000 QLineF objects in Python took ~6.5 ms of the GUI thread after every refit
        self._paths = {int(k): segments_path(uv[kinds == k]) for k in np.unique(kinds)}
        self._count = len(uv)
        if len(uv):
            lo, hi = uv.reshape(-1, 2).min(axis=0), uv.reshape(-1, 2).max(axis=0)
            self._rect = QRectF(QPointF(*lo), QPointF(*hi)).adjusted(-2, -2, 2, 2)
        self.update()

    def clear(self) -> None:
        self.prepareGeometryChange()
        self._paths = {}
        self._count = 0
        self.update()

    @property
    def count(self) -> int:
        return self._count

    def boundingRect(self) -> QRectF:
        return self._rect

    def paint(self, painter: QPainter, option, widget=None):
        painter.setRenderHint(QPainter.RenderHint.Antialiasing)
        painter.setBrush(Qt.BrushStyle.NoBrush)
        for kind, path in self._paths.items():
            pen = QPen(OVERLAY_COLORS.get(kind, QColor(0, 200, 255)), 1.6 if kind else 1.0)
            pen.setCosmetic(True)
            painter.setPen(pen)
            painter.drawPath(path)
