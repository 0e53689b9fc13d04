"""The *Texture* menu (§5.2): extract the current expression's texture in a worker
(:mod:`photomodel.texturing.job` through :class:`~app.qt.workers.JobController`) behind a
cancellable progress dialog, its size, and how the 3D view draws it — untextured, with the
cylindrical texture, or view-dependently.

The :class:`~app.qt.texture_views.WeightMapPanel` dock opens with the first texture. A project
saved with textures shows them again when it is opened (read back from its files as each
expression is shown, :meth:`~app.studio_state.StudioModel.load_stored_texture`; a damaged file is
named in the status bar and that texture is simply not shown).
"""

from __future__ import annotations

from functools import partial

from PySide6.QtCore import QObject
from PySide6.QtGui import QActionGroup
from PySide6.QtWidgets import QInputDialog, QMenu, QMenuBar, QProgressDialog

from app.qt.menus import make_action
from app.qt.progress import close_progress, update_progress
from app.studio_state import StudioModel
from photomodel.errors import FaceStudioError

#: Default texture size (texels per side); the setting ``texture/size`` overrides it.
DEFAULT_TEXTURE_SIZE = 1024
#: How the 3D view draws a textured model.
TEXTURE_MODES = ("untextured", "cylindrical", "view_dependent")
#: Appended to the message saying a stored texture cannot be shown.
REEXTRACT_HINT = " (Texture → Extract texture makes it again)"


class TextureMenu(QObject):
    """The *Texture* menu of ``window`` (a :class:`~app.qt.main_window.MainWindow`)."""

    def __init__(self, window):
        super().__init__(window)
        self.window = window
        self.jobs = window.jobs
        self.texture_mode = "cylindrical"
        self.progress_dialog: QProgressDialog | None = None
        self._show_weights_for_stored = True  # the weight-map dock opens for the first stored texture
        A = partial(make_action, window)
        self.act_texture = A(
            "Extract &texture",
            self.run_texture,
            "Ctrl+T",
            tip="blend the photos into a cylindrical texture of the fitted mesh (§5.2.2)",
        )
        self.act_texture_size = A("Texture si&ze…", self.texture_size_dialog)
        self.act_tex_modes = {
            "untextured": A("&Untextured", lambda on: on and self.set_texture_mode("untextured"), checkable=True),
            "cylindrical": A(
                "&Cylindrical texture",
                lambda on: on and self.set_texture_mode("cylindrical"),
                checkable=True,
                checked=True,
                tip="the view-independent texture map (§5.2.2)",
            ),
            "view_dependent": A(
                "&View-dependent texture",
                lambda on: on and self.set_texture_mode("view_dependent"),
                checkable=True,
                tip="blend the two photos nearest the 3D view's direction (§5.2.3)",
            ),
        }
        tgroup = QActionGroup(window)
        for a in self.act_tex_modes.values():
            tgroup.addAction(a)

    def build(self, menubar: QMenuBar) -> QMenu:
        t = menubar.addMenu("&Texture")
        t.addAction(self.act_texture)
        t.addAction(self.act_texture_size)
        t.addSeparator()
        for a in self.act_tex_modes.values():
            t.addAction(a)
        return t

    def connect_worker(self) -> None:
        """Follow the texture worker: its progress in the dialog, its result in the model."""
        self.jobs.progress.connect(self._on_texture_progress)
        self.jobs.finished.connect(self._on_texture_finished)
        self.jobs.failed.connect(self._on_texture_failed)
        self.jobs.cancelled.connect(self._on_texture_cancelled)

    # ------------------------------------------------------------------ size
    @property
    def texture_size(self) -> int:
        """Texels per side of the next texture (setting ``texture/size``)."""
        try:
            return int(self.window.settings.value("texture/size", DEFAULT_TEXTURE_SIZE))
        except (TypeError, ValueError):
            return DEFAULT_TEXTURE_SIZE

    @texture_size.setter
    def texture_size(self, value: int) -> None:
        self.window.settings.setValue("texture/size", int(value))

    def texture_size_dialog(self) -> None:
        size, ok = QInputDialog.getInt(
            self.window, "Texture size", "Texels per side:", self.texture_size, 64, 8192, 256
        )
        if ok:
            self.texture_size = size

    # ------------------------------------------------------------------ extraction
    def run_texture(self) -> bool:
        """Extract the current expression's texture in a worker, with a cancellable progress dialog."""
        window = self.window
        if self.jobs.busy:
            window.show_status("a texture is already being extracted")
            return False
        try:
            inputs = window.model.texture_inputs()
        except FaceStudioError as exc:
            window.show_error("Cannot extract the texture", str(exc))
            return False
        size = self.texture_size
        vertices = inputs[2]

        def work(progress, cancel):
            return StudioModel.compute_texture(inputs, size, progress=progress, cancel=cancel), vertices

        self.jobs.start(work)
        self.progress_dialog = window.open_progress("Texture", "Extracting the texture…", self.jobs.cancel)
        window.show_status(f"extracting a {size}×{size} texture of {inputs[1]!r}…", 0)
        return True

    def _close_texture_progress(self):
        close_progress(self.progress_dialog, self.jobs.cancel)
        self.progress_dialog = None

    def _on_texture_progress(self, stage: str, fraction: float):
        update_progress(self.progress_dialog, stage, fraction)

    def _on_texture_finished(self, result):
        self._close_texture_progress()
        job, vertices = result
        if not self.window.model.apply_texture(job, vertices):
            self.window.show_status("the expression was refitted meanwhile: the texture was discarded")
            return
        self.window.show_status(
            f"texture of {job.expression!r}: {job.report['coverage']:.1%} of the surface seen, "
            f"{job.report['extract_s']:.2f} s; it is written with the project"
        )
        self.window.weights_dock.show()
        self._show_weights_for_stored = False

    def on_texture_load_failed(self, expression: str, message: str):
        self.window.show_status(f"{message}{REEXTRACT_HINT}", 20000)

    def _on_texture_failed(self, message: str):
        self._close_texture_progress()
        self.window.show_status("")
        self.window.show_error("The texture extraction failed", message)

    def _on_texture_cancelled(self):
        self._close_texture_progress()
        self.window.show_status("texture extraction cancelled; nothing changed")

    # ------------------------------------------------------------------ the 3D view's texture
    def set_texture_mode(self, mode: str) -> None:
        """How the 3D view draws a textured model: one of :data:`TEXTURE_MODES`."""
        if mode not in TEXTURE_MODES:
            raise ValueError(f"texture mode must be one of {TEXTURE_MODES}, got {mode!r}")
        self.texture_mode = mode
        if not self.act_tex_modes[mode].isChecked():
            self.act_tex_modes[mode].setChecked(True)
        self.on_texture_changed(self.window.model.expression_name)

    def on_project_replaced(self) -> None:
        """Another project: its first stored texture opens the weight-map dock again, and the
        current expression's texture (read with the project) is shown."""
        self._show_weights_for_stored = True
        self.on_texture_changed(self.window.model.expression_name)

    def on_texture_changed(self, expression):
        """The 3D view draws the current expression's texture as :attr:`texture_mode` says."""
        window = self.window
        if expression != window.model.expression_name:
            return
        tex = window.model.texture()
        v3 = window.view3d
        if tex is not None and self._show_weights_for_stored:  # a project opened with its textures
            self._show_weights_for_stored = False
            window.weights_dock.show()
        if tex is None or self.texture_mode == "untextured":
            v3.view_dependent = None
            v3.set_texture(None, None)
            return
        if self.texture_mode == "view_dependent":
            try:
                vd = tex.view_dependent()
            except Exception as exc:  # e.g. no OpenGL for the depth maps
                window.show_error("Cannot draw the view-dependent texture", f"{type(exc).__name__}: {exc}")
                return
            v3.texture = None
            v3.set_view_dependent(vd)
        else:
            _, faces, uv = tex.job.texture.render_mesh(tex.vertices)
            v3.view_dependent = None
            v3.set_texture(uv, tex.job.texture.image, vertex_index=tex.job.texture.seam_vertices, faces=faces)
