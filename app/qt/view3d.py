"""The 3D view: the generic or fitted face mesh rendered by :mod:`photomodel.rendering.renderer`, orbit and zoom.

The image comes from the project's one renderer (headless moderngl, Lambert shading with a
head-light), so the 3D view shows exactly the geometry that texturing and tracking use. It is
rendered on the GUI thread: ~20 ms for a 400×400 view and 25–35 ms for the default 400×780 dock
on llvmpipe (``last_render_s``; measured by ``benchmarks/bench_gui.py``), under the 50 ms a drag
can afford. With a view-dependent texture it draws the fragment-shader frame of
:class:`~photomodel.texturing.view_dependent.ViewDependentTexture` — per-pixel §5.2.3 weights
and the floating-texture registration, as ``ViewDependentTexture.render`` by default — and takes
its depth for the feature dots: ~20–30 ms for the 400×780 dock on llvmpipe, where the numpy
path's plain blend plus a depth render took ~70–80 ms (the first frame also uploads the photos
and compiles the shaders, ~1 s). The registration of each pair of photos an orbit selects
(~0.2 s a pair) is computed ahead, off the GUI thread, as soon as the texture is shown (the
photos' surfaces one per event-loop turn, then the pairs in a worker thread: ~1.9 s for the
sample's eight pairs): an orbit of the 400×780 dock from −120° to 120° in 5° steps drew its 49
frames in 21 ms median, 62 ms at most, where computing each pair on its first frame had
stalled 4 frames, the longest 350 ms (``benchmarks/bench_texture.py``'s ``vd_orbit_*``, 2026-12-02).
Left-drag orbits, the wheel zooms, a click (press and release
without moving) on the mesh picks the nearest named feature as the active one; the project's
features are drawn as dots, the active one ringed and named; the pose feature to click next (the
first of the fit's checklist, :meth:`~app.studio_state.StudioModel.next_feature`) is ringed in orange and
named "next".
While a weight of the project's rig is not 0 (the studio's rig panel, :class:`~app.qt.rig_panel.RigPanel`)
the view shows the rig's neutral + Σ wᵢ·Δᵢ (:meth:`~app.studio_state.StudioModel.rig_vertices`), with the
neutral's cylindrical texture when that is the expression shown, else shaded. While the rig dock's
identity sliders are in use (:class:`~app.qt.rig_panel.IdentitySliders`) the view shows the new face
of the people model instead, shaded (:meth:`~app.studio_state.StudioModel.identity_vertices`).
"""

from __future__ import annotations

import math
import threading
import time

import numpy as np
from PySide6.QtCore import QPointF, QRectF, QSize, Qt, QTimer, Signal
from PySide6.QtGui import QColor, QImage, QPainter, QPen
from PySide6.QtWidgets import QSizePolicy, QWidget

from app.studio_state import StudioModel
from photomodel.camera import focal_mm_to_px, orbit_camera
from photomodel.modeling.wireframe import visible_points
from photomodel.rendering.renderer import get_renderer

#: A click within this many pixels of a feature's projection picks it.
PICK_RADIUS_PX = 14.0
#: A press that moves less than this (px) before release is a click, not an orbit.
CLICK_SLOP_PX = 3.0
BACKGROUND = (0.16, 0.16, 0.18)
#: The ring around the pose feature to click next.
NEXT_COLOR = QColor(255, 140, 0)


class View3D(QWidget):
    """Orbitable 3D view of the current expression's fitted mesh (the generic mesh before a fit).

    Attributes
    ----------
    azimuth_deg, elevation_deg, distance_mm : float, the orbit camera.
    last_render_s : float or None, time of the last render.
    texture : (uv (M, 2), image, vertex_index (M,) or None, faces (F, 3) or None) or None, an
        optional cylindrical texture to render with (set by the texturing tools; the view only
        draws it).
    view_dependent : photomodel.texturing.view_dependent.ViewDependentTexture or None; when set, the mesh
        is drawn view-dependently (§5.2.3) for the view's camera instead: the fragment-shader path
        (``method="shader"``) with the floating-texture registration, the same rendering as
        ``ViewDependentTexture.render``'s default, at every frame of an orbit.
    """

    feature_picked = Signal(str)

    def __init__(self, model: StudioModel, parent=None):
        super().__init__(parent)
        self.model = model
        self.azimuth_deg = 25.0
        self.elevation_deg = 8.0
        self.distance_mm = 450.0
        self.focal_mm = 50.0  # on a 36 mm sensor spanning the widget's shorter side
        self.show_features = True
        self.texture = None
        self._view_dependent = None
        self._registration_stop: threading.Event | None = None
        self.registration_thread: threading.Thread | None = None
        self.last_render_s: float | None = None
        self._image: QImage | None = None
        self._depth = None
        self._camera = None
        self._render_serial = 0  # renders so far: what _visible_features was computed for
        self._features_cache = None
        self._dirty = True
        self._press = None
        self._orbiting = False
        self.setMinimumSize(160, 160)
        self.setSizePolicy(QSizePolicy.Policy.Expanding, QSizePolicy.Policy.Expanding)
        self.setMouseTracking(False)
        for sig in (
            model.project_replaced,
            model.expression_changed,
            model.fit_changed,
            model.features_changed,
            model.rig_changed,
            model.rig_weights_changed,
            model.identity_changed,
        ):
            sig.connect(self.invalidate)
        model.active_feature_changed.connect(lambda *_: self.update())
        model.points_changed.connect(lambda *_: self.update())  # the next feature to click may change
        self.next_feature: str | None = None  # as last painted

    def sizeHint(self) -> QSize:
        return QSize(360, 360)

    # ------------------------------------------------------------------ what is shown
    def vertices(self) -> tuple[np.ndarray, str]:
        """The vertices shown and a caption."""
        new_face = self.model.identity_vertices()
        if new_face is not None:
            values = self.model.identity.values
            moved = [f"mode {k + 1} {v:+.1f}σ" for k, v in enumerate(values) if v]
            return new_face, "new face (people model) — " + (", ".join(moved[:3]) or "the mean face")
        posed = self.model.rig_vertices()
        if posed is not None:
            rig = self.model.rig()
            moved = [f"{n} {w:.2f}" for n, w in zip(rig.names, rig.weights, strict=True) if w]
            more = f" +{len(moved) - 3}" if len(moved) > 3 else ""
            return posed, f"rig on {rig.neutral} — {', '.join(moved[:3])}{more}"
        fit = self.model.fit()
        if fit is not None and fit.vertices is not None:
            how = (
                " — view-dependent texture"
                if self.view_dependent is not None
                else " — cylindrical texture"
                if self.texture is not None
                else ""
            )
            return fit.vertices, f"fitted mesh — {self.model.expression_name}{how}"
        return self.model.mesh.vertices, "generic mesh (not fitted yet)"

    def set_texture(
        self,
        uv: np.ndarray | None,
        image: np.ndarray | None,
        *,
        vertex_index: np.ndarray | None = None,
        faces: np.ndarray | None = None,
    ) -> None:
        """Render with a texture; ``uv=None`` clears it.

        ``uv`` (N, 2) per mesh vertex with ``image`` (H, W, 3) uint8; or, for a mesh whose
        triangles cross the texture's seam, the seam-split rendering mesh of
        :meth:`photomodel.texturing.cylindrical.CylindricalTexture.render_mesh`: ``uv`` (M, 2) per rendering
        vertex, ``vertex_index`` (M,) its mesh vertex and ``faces`` (F, 3) its triangles.
        """
        if uv is None or image is None:
            self.texture = None
        else:
            index = None if vertex_index is None else np.asarray(vertex_index)
            self.texture = (np.asarray(uv), np.asarray(image), index, None if faces is None else np.asarray(faces))
        self.invalidate()

    def set_view_dependent(self, texture) -> None:
        """Draw with a :class:`~photomodel.texturing.view_dependent.ViewDependentTexture` (None: stop)."""
        self.view_dependent = texture
        self.invalidate()

    @property
    def view_dependent(self):
        return self._view_dependent

    @view_dependent.setter
    def view_dependent(self, texture) -> None:
        """A new view-dependent texture: the registration of the pairs of photographs an orbit
        selects is computed ahead, off the GUI thread, so that no frame of the orbit waits for a
        new pair's (~0.2 s each): the photographs' surfaces first, one per event-loop turn on
        this thread (they need its renderer), then the pairs in a worker thread."""
        if texture is self._view_dependent:
            return
        if self._registration_stop is not None:
            self._registration_stop.set()  # the worker stops after its current pair
        self._view_dependent = texture
        self._registration_stop = None
        if texture is not None:
            stop = self._registration_stop = threading.Event()
            QTimer.singleShot(0, lambda: self._prepare_registration(texture, stop, 0))

    def _prepare_registration(self, texture, stop: threading.Event, k: int) -> None:
        if stop.is_set() or texture is not self._view_dependent:
            return
        if k < len(texture.cameras):
            texture.prepare_surfaces([k])
            QTimer.singleShot(0, lambda: self._prepare_registration(texture, stop, k + 1))
            return
        self.registration_thread = threading.Thread(
            target=texture.register_pairs, kwargs={"cancel": stop.is_set}, name="vd-registration", daemon=True
        )
        self.registration_thread.start()

    def invalidate(self, *args) -> None:
        self._dirty = True
        self.update()

    def camera(self, width: int, height: int):
        V, _ = self.vertices()
        target = 0.5 * (V.min(axis=0) + V.max(axis=0))
        cam = orbit_camera(
            self.azimuth_deg,
            width,
            height,
            distance_mm=self.distance_mm,
            focal_mm=self.focal_mm,
            elevation_deg=self.elevation_deg,
            target=target,
        )
        cam.f = focal_mm_to_px(self.focal_mm, min(width, height))  # a tall dock still frames the head
        return cam

    def render_image(self, width: int | None = None, height: int | None = None) -> QImage:
        """Render now at the given size (default: the widget's) and return the image."""

        w = max(16, int(width or self.width()))
        h = max(16, int(height or self.height()))
        V, _ = self.vertices()
        cam = self.camera(w, h)
        t0 = time.perf_counter()
        faces = self.model.mesh.faces
        vd = self.view_dependent
        texture = self.texture
        if self.model.identity_vertices() is not None:  # a new face: shaded, nobody's photos
            vd = texture = None
        elif self.model.rig_vertices() is not None:  # the rig posed: its geometry, not the photos'
            vd = None
            if self.model.rig().neutral != self.model.expression_name:
                texture = None
        if vd is not None and len(vd.vertices) != len(V):
            vd = None  # made for another mesh
        if vd is not None:
            # the GPU path with the flow registration (floating textures), as a still frame;
            # its depth serves the feature dots
            out = vd.render(cam, background=BACKGROUND)
            rgb = np.ascontiguousarray((np.clip(out.color[..., :3], 0, 1) * 255 + 0.5).astype(np.uint8))
            depth = out.depth
        elif texture is not None:
            uv, image, index, tfaces = texture
            Vt, Ft = (V, faces) if index is None else (V[index], tfaces)
            # the photographs hold the lighting: no shading on top (as the view-dependent image)
            rgb, depth = get_renderer().render_rgb8(cam, Vt, Ft, background=BACKGROUND, uv=uv, texture=image)
        else:
            # the same image as render(...).color in 8 bits, without the face ids it does not need
            rgb, depth = get_renderer().render_rgb8(cam, V, faces, shading="lambert", background=BACKGROUND)
        self._image = QImage(rgb.data, w, h, 3 * w, QImage.Format.Format_RGB888).copy()
        self._depth = depth
        self._camera = cam
        self._render_serial += 1
        self.last_render_s = time.perf_counter() - t0
        self._dirty = False
        return self._image

    # ------------------------------------------------------------------ painting
    def paintEvent(self, event):
        p = QPainter(self)
        try:
            if self._dirty or self._image is None or self._image.size() != self.size():
                try:
                    self.render_image()
                except Exception as exc:  # no OpenGL: say so in the view instead of failing the window
                    p.fillRect(self.rect(), QColor(40, 40, 40))
                    p.setPen(QColor(230, 230, 230))
                    p.drawText(
                        self.rect(),
                        Qt.AlignmentFlag.AlignCenter | Qt.TextFlag.TextWordWrap,
                        f"3D view unavailable:\n{exc}",
                    )
                    return
            p.drawImage(0, 0, self._image)
            p.setRenderHint(QPainter.RenderHint.Antialiasing)
            if self.show_features:
                self._paint_features(p)
                self._paint_next(p)
            _, caption = self.vertices()
            p.setPen(QColor(220, 220, 220))
            p.drawText(QRectF(8, 4, self.width() - 16, 20), Qt.AlignmentFlag.AlignLeft, caption)
            p.setPen(QColor(160, 160, 160))
            p.drawText(
                QRectF(8, self.height() - 22, self.width() - 16, 18),
                Qt.AlignmentFlag.AlignLeft,
                "drag: orbit · wheel: zoom · click: pick feature",
            )
        finally:
            p.end()

    def _visible_features(self):
        """(names, uv (n, 2), visible (n,)) of the project's features in the last render.

        Kept until the next render or a change of the features: the view is painted again
        without a new render after every edit (the next feature to click may change), and the
        visibility test against the depth map is most of a paint's time."""
        if self._camera is None:
            return [], np.zeros((0, 2)), np.zeros(0, bool)
        V, _ = self.vertices()
        features = self.model.project.features  # the catalogue's features in the project, in order
        names = [f.name for f in features]
        verts = np.array([f.vertex for f in features], dtype=int)
        cached = self._features_cache  # (render serial, V, names, vertices, answer)
        if (
            cached is not None
            and cached[0] == self._render_serial
            and cached[1] is V
            and cached[2] == names
            and np.array_equal(cached[3], verts)
        ):
            return cached[4]
        out = (names,) + self._project_visible(V[verts]) if len(names) else ([], np.zeros((0, 2)), np.zeros(0, bool))
        self._features_cache = (self._render_serial, V, names, verts, out)
        return out

    def _project_visible(self, X: np.ndarray):

        uv = self._camera.project(X)
        vis = visible_points(self._camera, X, self._depth, tolerance_mm=3.0)
        return uv, vis

    def _paint_features(self, p: QPainter):
        names, uv, vis = self._visible_features()
        active = self.model.active_feature
        for name, (u, v), ok in zip(names, uv, vis, strict=True):
            if not ok:
                continue
            is_active = name == active
            p.setPen(QPen(QColor(0, 0, 0, 120), 0.8))
            p.setBrush(QColor(255, 230, 0) if is_active else QColor(0, 190, 255, 200))
            r = 4.0 if is_active else 1.8
            p.drawEllipse(QPointF(u, v), r, r)
        if active is not None:
            v = self._feature_vertex(active)
            if v is not None:
                V, _ = self.vertices()
                (uv1,), (ok,) = self._project_visible(V[[v]])
                if ok:
                    p.setPen(QPen(QColor(255, 230, 0), 2))
                    p.setBrush(Qt.BrushStyle.NoBrush)
                    p.drawEllipse(QPointF(*uv1), 8, 8)
                    p.drawText(QPointF(uv1[0] + 11, uv1[1] - 6), active)

    def _feature_vertex(self, name: str) -> int | None:
        m = self.model
        return m.project.feature(name).vertex if m.has_feature(name) else m.mesh.features.get(name)

    def _paint_next(self, p: QPainter):
        """Ring the pose feature to click next (orange), or say on which side it hides."""
        m = self.model
        self.next_feature = name = m.next_feature() if m.expression is not None else None
        if name is None:
            return
        V, _ = self.vertices()
        (uv,), (ok,) = self._project_visible(V[[self._feature_vertex(name)]])
        p.setPen(QPen(NEXT_COLOR, 2.5))
        p.setBrush(Qt.BrushStyle.NoBrush)
        if ok:
            p.drawEllipse(QPointF(*uv), 12, 12)
            p.drawText(QPointF(uv[0] + 14, uv[1] + 16), f"next: {name}")
        p.drawText(
            QRectF(8, 24, self.width() - 16, 20),
            Qt.AlignmentFlag.AlignLeft,
            f"next to click: {name}" + ("" if ok else " (turn the head to see it)"),
        )

    # ------------------------------------------------------------------ interaction
    def pick(self, x: float, y: float) -> str | None:
        """The named feature (project's or generic mesh's) nearest a widget position, if visible."""
        if self._camera is None or self._dirty:
            self.render_image()
        V, _ = self.vertices()
        names, verts = [], []
        for name, vertex, _, _ in self.model.catalogue():
            names.append(name)
            verts.append(vertex)
        if not names:
            return None
        uv, vis = self._project_visible(V[np.array(verts)])
        d = np.hypot(uv[:, 0] - x, uv[:, 1] - y)
        d[~vis] = np.inf
        i = int(np.argmin(d))
        return names[i] if d[i] <= PICK_RADIUS_PX else None

    def mousePressEvent(self, event):
        if event.button() == Qt.MouseButton.LeftButton:
            self._press = event.position()
            self._last = event.position()
            self._orbiting = False
            event.accept()

    def mouseMoveEvent(self, event):
        if self._press is None:
            return
        pos = event.position()
        if not self._orbiting and math.hypot(pos.x() - self._press.x(), pos.y() - self._press.y()) > CLICK_SLOP_PX:
            self._orbiting = True
        if self._orbiting:
            d = pos - self._last
            self.azimuth_deg = (self.azimuth_deg - 0.4 * d.x() + 180.0) % 360.0 - 180.0
            self.elevation_deg = float(np.clip(self.elevation_deg + 0.4 * d.y(), -85.0, 85.0))
            self._last = pos
            self.invalidate()
        event.accept()

    def mouseReleaseEvent(self, event):
        if event.button() != Qt.MouseButton.LeftButton or self._press is None:
            return
        if not self._orbiting:
            name = self.pick(event.position().x(), event.position().y())
            if name is not None:
                self.model.set_active_feature(name)
                self.feature_picked.emit(name)
        self._press = None
        self._orbiting = False
        event.accept()

    def wheelEvent(self, event):
        steps = event.angleDelta().y() / 120.0
        self.distance_mm = float(np.clip(self.distance_mm * 0.88**steps, 200.0, 3000.0))
        self.invalidate()
        event.accept()

    def view_from(self, azimuth_deg: float, elevation_deg: float = 0.0) -> None:
        self.azimuth_deg, self.elevation_deg = azimuth_deg, elevation_deg
        self.invalidate()
