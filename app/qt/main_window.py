"""The studio's main window: a shell that assembles the photo tabs, the docks, the menus and the toolbar.

Layout: the current expression's photos fill the centre (:class:`~app.qt.photo_tabs.PhotoTabs`,
one :class:`~app.qt.photo_view.PhotoView` per tab, the tab title showing the photo's reprojection
RMS after a fit); the docks (:mod:`app.qt.docks`) hold the
:class:`~app.qt.feature_list.FeaturePanel` on the left and the :class:`~app.qt.view3d.View3D` on
the right, the weight maps, the expressions side by side, tracking and the rig. The toolbar
(:mod:`app.qt.main_toolbar`) holds the expression, the editing mode (points / draw curve), the fit
and overlay switches, and the current photo's starting view and camera group.

Each menu is a module of :mod:`app.qt.menus` holding its actions and the work behind them: *File*
(:mod:`~app.qt.menus.file_menu`: project files, autosave and recovery, photos in and out), *Edit*,
*Expression*, *Fit*, *Texture* (§5.2), *Tracking* (§6.2), *Rig* and *View*. The window keeps each
action under its ``act_*`` name and the public methods scripts and tests drive (``open_project``,
``run_fit``, ``run_texture`` …), each handing over to its menu; it offers the widgets a public
status and progress API (:meth:`MainWindow.show_status`, :meth:`MainWindow.open_progress`,
:meth:`MainWindow.show_error`).

Everything the window shows observes one :class:`~app.studio_state.StudioModel`; edits are
:mod:`app.studio.commands` pushed on the model's undo stack (:class:`~app.studio.undo.UndoStack`); fits run in a worker
(:class:`~app.qt.workers.FitController`), textures, rigs and photo imports in
:class:`~app.qt.workers.JobController` workers behind cancellable progress dialogs. Every failure
is shown in a dialog whose text is the cause.
"""

from __future__ import annotations

import sys
import traceback
from dataclasses import fields

from PySide6.QtCore import QSettings, Qt, QTimer, Signal
from PySide6.QtGui import QGuiApplication
from PySide6.QtWidgets import QApplication, QMainWindow, QMessageBox, QProgressDialog

from app.qt import progress
from app.qt.docks import build_docks
from app.qt.main_toolbar import MainToolBar
from app.qt.menus import actions_of
from app.qt.menus.edit_menu import EditMenu
from app.qt.menus.expression_menu import ExpressionMenu
from app.qt.menus.file_menu import FileMenu, guess_preset
from app.qt.menus.fit_menu import FitMenu
from app.qt.menus.rig_menu import RigMenu
from app.qt.menus.texture_menu import TextureMenu
from app.qt.menus.tracking_menu import TrackingMenu
from app.qt.menus.view_menu import ViewMenu
from app.qt.photo_import import PhotoImporter
from app.qt.photo_tabs import PhotoTabs
from app.qt.photo_view import PhotoView
from app.qt.qt_compat import check_pyside
from app.qt.workers import FitController, JobController
from app.studio_state import StudioModel

#: Qt platforms without a screen: error boxes there do not block (:func:`run_studio`).
HEADLESS_PLATFORMS = ("offscreen", "minimal")
#: Autosave period (ms).
AUTOSAVE_INTERVAL_MS = 60_000


class MainWindow(QMainWindow):
    """The Face Studio window.

    Parameters
    ----------
    model : StudioModel, optional (default: a new one with an empty project)
    settings : QSettings, optional (default: the user's; tests pass their own file)
    autosave_interval_ms : int, the autosave period (0 disables the timer)
    recovery_file : path, optional
        where this window autosaves a never-saved project (default: a new file of its own,
        :func:`~app.qt.recovery.default_recovery_file`, in ``recovery_folder``). A given file is
        this window's even if it exists: :meth:`offer_recovery` offers it first.
    recovery_folder : path, optional
        the folder of recovery files scanned by :meth:`offer_recovery` (default: the parent of
        ``recovery_file`` if given, else :func:`~app.qt.recovery.default_recovery_folder`).

    Unexpected errors (:meth:`report_unexpected`, the studio's ``sys.excepthook``) are kept in
    :attr:`unexpected_errors` and announced by :attr:`unexpected_error` (``"Type: message"``).
    """

    unexpected_error = Signal(str)

    def __init__(
        self,
        model: StudioModel | None = None,
        settings: QSettings | None = None,
        autosave_interval_ms: int = AUTOSAVE_INTERVAL_MS,
        recovery_file=None,
        recovery_folder=None,
    ):
        check_pyside()
        super().__init__()
        self.model = model if model is not None else StudioModel()
        self.settings = settings if settings is not None else QSettings("FaceStudio", "studio")
        self.undo_stack = self.model.undo_stack  # the model's: cleared on new/open, clean when saved
        self.fits = FitController(self.model, self)
        self.jobs = JobController(self.model, self)  # Texture → Extract texture
        self.rig_jobs = JobController(self.model, self)  # Rig → Build rig
        self.scan_jobs = JobController(self.model, self)  # Fit → Add scan…
        self.importer = PhotoImporter(self)  # New from photos…, photos added with automatic landmarks
        self.blocking_dialogs = True  # run_studio: False on a headless platform (offscreen, minimal)
        self.unexpected_errors: list[str] = []  # report_unexpected: "Type: message" of each
        self._error_box: QMessageBox | None = None
        self._unexpected_in_box = 0  # errors in the box now shown

        self.setWindowTitle("Face Studio")
        self.resize(1500, 920)
        self.setAcceptDrops(True)
        self.setDockNestingEnabled(True)

        self.tabs = PhotoTabs(self.model, self.undo_stack)
        self.setCentralWidget(self.tabs)
        self.docks = build_docks(self, self.model, self.undo_stack)
        for f in fields(self.docks):  # the panels and docks by name: window.view3d, window.rig_dock …
            setattr(self, f.name, getattr(self.docks, f.name))
        self.panel.jump_requested.connect(self.jump_to)
        self.panel.photo_requested.connect(self.show_photo)

        self.file_menu = FileMenu(self, recovery_file, recovery_folder)
        self.edit_menu = EditMenu(self)
        self.expression_menu = ExpressionMenu(self)
        self.fit_menu = FitMenu(self)
        self.texture_menu = TextureMenu(self)
        self.tracking_menu = TrackingMenu(self)
        self.rig_menu = RigMenu(self)
        self.view_menu = ViewMenu(self)
        self.fit_label = self.fit_menu.fit_label
        self.statusBar().addPermanentWidget(self.fit_label)
        self._build_menus()

        actions = {}
        for menu in self._menus():  # act_* kept on the window: scripts, tests and the monkey trigger them
            actions.update(actions_of(menu))
        for name, action in actions.items():
            setattr(self, name, action)
        self.toolbar = MainToolBar(self.model, self.undo_stack, self.tabs, actions, self)
        self.addToolBar(self.toolbar)
        self.expr_combo = self.toolbar.expr_combo
        self.preset_combo = self.toolbar.preset_combo
        self.camera_group_edit = self.toolbar.camera_group_edit

        self._connect_signals()

        self.autosave_timer = QTimer(self)
        self.autosave_timer.timeout.connect(self.autosave)
        if autosave_interval_ms > 0:
            self.autosave_timer.start(autosave_interval_ms)

        self.on_project_replaced()

    # ------------------------------------------------------------------ assembly
    def _menus(self) -> tuple:
        return (
            self.file_menu,
            self.edit_menu,
            self.expression_menu,
            self.fit_menu,
            self.texture_menu,
            self.tracking_menu,
            self.rig_menu,
            self.view_menu,
        )

    def _build_menus(self) -> None:
        mb = self.menuBar()
        for menu in self._menus()[:-1]:
            menu.build(mb)
        self.view_menu.build(mb, self.docks.toggle_actions())

    def _connect_signals(self):
        """The window follows the model, the undo stack and the workers (in this order: the
        tabs are rebuilt before the texture of a newly shown expression is drawn)."""
        m = self.model
        m.project_replaced.connect(self.on_project_replaced)
        m.expression_changed.connect(lambda *_: self.tabs.rebuild())
        m.photos_changed.connect(lambda *_: self.tabs.rebuild())
        m.photo_changed.connect(lambda *_: self.toolbar.sync_photo())
        m.fit_changed.connect(self.fit_menu.on_fit_changed)
        m.texture_changed.connect(self.texture_menu.on_texture_changed)
        m.texture_load_failed.connect(self.texture_menu.on_texture_load_failed)
        m.expression_changed.connect(lambda *_: self.texture_menu.on_texture_changed(self.model.expression_name))
        m.modified_changed.connect(lambda value: self.setWindowModified(bool(value)))
        m.path_changed.connect(lambda *_: self._update_title())
        self.undo_stack.index_changed.connect(self._on_edit)
        self.fits.overlay_photos = self.tabs.overlay_photo_ids  # computed in the fit's worker
        self.fit_menu.connect_worker()
        self.texture_menu.connect_worker()
        self.rig_menu.connect_worker()
        self.tracking_menu.connect_worker()
        self.tabs.rebuilt.connect(self.toolbar.sync_expressions)
        self.tabs.rebuilt.connect(self.toolbar.sync_photo)
        self.tabs.photo_shown.connect(self.toolbar.sync_photo)
        self.tabs.status_message.connect(self.show_status)

    def _on_edit(self, *_):
        self.fits.schedule_refit()

    def on_project_replaced(self):
        """Show the model's (new) project: its tabs, title, fit and texture."""
        self.tabs.rebuild()
        self._update_title()
        self.setWindowModified(self.model.modified)
        self.fit_menu.on_fit_changed(self.model.expression_name)
        self.texture_menu.on_project_replaced()  # a texture read with the project

    def _update_title(self):
        p = self.model.project
        where = str(p.path) if p.path is not None else "not saved"
        self.setWindowTitle(f"{p.name} — {where} [*] — Face Studio")

    # ------------------------------------------------------------------ status, progress and errors
    def show_status(self, text: str, ms: int = 6000) -> None:
        """``text`` in the status bar for ``ms`` milliseconds (0: until the next message)."""
        self.statusBar().showMessage(text, ms)

    def open_progress(self, title: str, label: str, on_cancel, min_duration_ms: int = 300) -> QProgressDialog:
        """A window-modal progress dialog over this window (:func:`app.qt.progress.open_progress`);
        close it with :func:`app.qt.progress.close_progress`."""
        return progress.open_progress(self, title, label, on_cancel, min_duration_ms=min_duration_ms)

    def show_error(self, title: str, message: str) -> None:
        """A dialog whose text is the cause (never a bare traceback).

        Modal, except where nobody could close it (:attr:`blocking_dialogs` False: a headless
        run, see :func:`run_studio`): then a non-modal box and a line on stderr.
        """
        if self.blocking_dialogs:
            QMessageBox.critical(self, title, message)
            return
        sys.stderr.write(f"facestudio: {title}: {message}\n")
        box = QMessageBox(QMessageBox.Icon.Critical, title, message, parent=self)
        box.setWindowModality(Qt.WindowModality.NonModal)
        box.setAttribute(Qt.WidgetAttribute.WA_DeleteOnClose)
        box.show()

    def report_unexpected(self, exc_type, exc, tb) -> None:
        """The studio's ``sys.excepthook``: an error nobody expected, shown without blocking.

        The traceback goes to stderr and :attr:`unexpected_errors` (``"Type: message"`` each;
        tests assert on it), :attr:`unexpected_error` is emitted, and one non-modal box shows the
        cause first and the tracebacks under "Show Details" — never ``exec()``, so a headless run
        (offscreen, a test, a script) goes on and the artist can still save.
        """
        text = "".join(traceback.format_exception(exc_type, exc, tb))
        sys.stderr.write(text)
        summary = f"{exc_type.__name__}: {exc}"
        self.unexpected_errors.append(summary)
        box = self._error_box
        if box is None:
            box = self._error_box = QMessageBox(QMessageBox.Icon.Critical, "Unexpected error", "", parent=self)
            box.setWindowModality(Qt.WindowModality.NonModal)
            box.setInformativeText("The project is still open; save it under a new name if in doubt.")
        # one box however many errors come: a later error is added to the one still shown
        self._unexpected_in_box = self._unexpected_in_box + 1 if box.isVisible() else 1
        n = self._unexpected_in_box
        box.setText(summary if n == 1 else f"{summary}\n(and {n - 1} earlier unexpected error{'s' * (n > 2)})")
        box.setDetailedText(text if n == 1 else box.detailedText() + "\n" + text)
        box.show()
        self.unexpected_error.emit(summary)

    @property
    def error_box(self) -> QMessageBox | None:
        """The box of unexpected errors (:meth:`report_unexpected`), None before the first."""
        return self._error_box

    # ------------------------------------------------------------------ project files (File menu)
    @property
    def recovery_file(self):
        """Where this window autosaves a never-saved project."""
        return self.file_menu.recovery_file

    @property
    def recovery_folder(self):
        """The folder of recovery files :meth:`offer_recovery` scans."""
        return self.file_menu.recovery_folder

    def maybe_save(self) -> bool:
        """Ask what to do with unsaved changes; False if the user cancels."""
        return self.file_menu.maybe_save()

    def new_project(self) -> bool:
        return self.file_menu.new_project()

    def open_project(self, path, *, ask_to_save: bool = True) -> bool:
        """Open a project file; on any problem say why and keep the current project."""
        return self.file_menu.open_project(path, ask_to_save=ask_to_save)

    def save(self) -> bool:
        return self.file_menu.save()

    def save_as(self) -> bool:
        return self.file_menu.save_as()

    def save_to(self, path) -> bool:
        """Save the project as ``path`` without a dialog; a failure is shown and False returned."""
        return self.file_menu.save_to(path)

    def autosave(self) -> None:
        """Autosave: ``<file>.autosave``, or for a never-saved project :attr:`recovery_file`."""
        self.file_menu.autosave()

    def offer_recovery(self) -> bool:
        """At start: offer the recovery files of never-saved projects, newest first.

        Offered: this window's own :attr:`recovery_file` if it exists (a file given to the
        constructor), then every file of :func:`~app.qt.recovery.recovery_files` in
        :attr:`recovery_folder` whose lock no running studio holds
        (:func:`~app.qt.recovery.lock_recovery_file`) — so another instance's project is never
        offered while that instance runs, and a crashed one's is. Yes opens it (without a file,
        marked modified) and makes it this window's recovery file; No deletes it and offers the
        next. Returns True if a project was recovered.
        """
        return self.file_menu.offer_recovery()

    def recent_files(self) -> list[str]:
        return self.file_menu.recent_files()

    # ------------------------------------------------------------------ photos
    def add_photos(self, files) -> int:
        """Add image files to the current expression; unreadable ones are named in one message."""
        return self.file_menu.add_photos(files)

    def add_photos_auto(self, files) -> bool:
        """Add image files to the current expression (made ``neutral`` when there is none) with
        automatic landmarks, in the importer's worker; False when an import is running."""
        return self.file_menu.add_photos_auto(files)

    def add_dropped(self, paths, *, automatic: bool = True) -> int:
        """Photos dropped on the window: files, and folders of photos (each folder's photos in name
        order, its HEIC/raw files named: :func:`photomodel.photos.intake.gather_photo_files`); what
        cannot be added is said in one message. ``automatic``: with automatic landmarks, in the
        importer's worker (as *Add photos with automatic landmarks…*; the photos arrive when it
        finishes); otherwise the photos alone, at once. Returns how many photos were taken."""
        return self.file_menu.add_dropped(paths, automatic=automatic)

    def remove_current_photo(self):
        self.file_menu.remove_current_photo()

    def new_expression_dialog(self):
        self.expression_menu.new_expression_dialog()

    def current_view(self) -> PhotoView | None:
        return self.tabs.current_view()

    def show_photo(self, photo_id: str) -> PhotoView | None:
        return self.tabs.show_photo(photo_id)

    def jump_to(self, photo_id: str, feature: str) -> None:
        """Show a click: its photo, zoomed in around it, with its feature active."""
        self.tabs.jump_to(photo_id, feature)

    @property
    def views(self) -> dict[str, PhotoView]:
        """The photo views by photo id (the current expression's)."""
        return self.tabs.views

    @property
    def mode(self) -> str:
        """The photos' editing mode (:data:`~app.qt.photo_view.POINTS` or :data:`~app.qt.photo_view.CURVE`)."""
        return self.tabs.mode

    def set_mode(self, mode: str):
        self.view_menu.set_mode(mode)

    # ------------------------------------------------------------------ fit, texture, rig, tracking
    def run_fit(self) -> bool:
        """Fit the current expression from scratch in the worker, with a cancellable progress dialog."""
        return self.fit_menu.run_fit()

    @property
    def fit_progress(self) -> QProgressDialog | None:
        """The progress dialog of the fit started by :meth:`run_fit`, None when none runs."""
        return self.fit_menu.progress_dialog

    @property
    def texture_mode(self) -> str:
        """How the 3D view draws a textured model (:data:`~app.qt.menus.texture_menu.TEXTURE_MODES`)."""
        return self.texture_menu.texture_mode

    def set_texture_mode(self, mode: str) -> None:
        """How the 3D view draws a textured model: one of :data:`~app.qt.menus.texture_menu.TEXTURE_MODES`."""
        self.texture_menu.set_texture_mode(mode)

    @property
    def texture_size(self) -> int:
        """Texels per side of the next texture (setting ``texture/size``)."""
        return self.texture_menu.texture_size

    @texture_size.setter
    def texture_size(self, value: int) -> None:
        self.texture_menu.texture_size = value

    def run_texture(self) -> bool:
        """Extract the current expression's texture in a worker, with a cancellable progress dialog."""
        return self.texture_menu.run_texture()

    @property
    def texture_progress(self) -> QProgressDialog | None:
        """The progress dialog of the texture being extracted, None when none is."""
        return self.texture_menu.progress_dialog

    def show_expressions(self) -> None:
        self.expression_menu.show_expressions()

    def run_build_rig(self) -> bool:
        """Build the rig of the fitted neutral in a worker (a few seconds), with a progress dialog."""
        return self.rig_menu.run_build_rig()

    def track_video_dialog(self) -> bool:
        """Choose a video file and track it in the tracking view (results in the default folder)."""
        return self.tracking_menu.track_video_dialog()

    def open_tracking_dialog(self) -> bool:
        """Choose a tracking results folder and show it in the tracking view."""
        return self.tracking_menu.open_tracking_dialog()

    # ------------------------------------------------------------------ drag and drop, closing
    def dragEnterEvent(self, event):
        if event.mimeData().hasUrls():
            event.acceptProposedAction()

    def dropEvent(self, event):
        files = [u.toLocalFile() for u in event.mimeData().urls() if u.isLocalFile()]
        projects = [f for f in files if f.endswith(".json")]
        if projects:
            self.open_project(projects[0])
        else:  # Shift held: the photos alone, to click by hand (as *Add photos…*)
            shift = bool(event.modifiers() & Qt.KeyboardModifier.ShiftModifier)
            self.add_dropped(files, automatic=not shift)
        event.acceptProposedAction()

    def closeEvent(self, event):
        if not self.maybe_save():
            event.ignore()
            return
        self.fits.shutdown()
        self.jobs.shutdown()
        self.rig_jobs.shutdown()
        self.scan_jobs.shutdown()
        self.importer.shutdown()
        self.tracking_view.jobs.shutdown()
        self.tracking_view.edit_panel.jobs.shutdown()  # an export of edited frames
        self.autosave_timer.stop()
        self.file_menu.drop_recovery()  # the project was saved, discarded or unchanged: nothing left to recover
        event.accept()


def _excepthook(exc_type, exc, tb):
    """Unexpected errors while no window is open: the traceback on stderr."""
    sys.stderr.write("".join(traceback.format_exception(exc_type, exc, tb)))


def run_studio(project: str | None = None, argv: list[str] | None = None) -> int:
    """Open the studio window (on ``project`` if given) and run the Qt event loop."""
    app = QApplication.instance() or QApplication(argv if argv is not None else sys.argv[:1])
    app.setOrganizationName("FaceStudio")
    app.setApplicationName("Face Studio")
    window = MainWindow()
    # headless (a script, CI): an error box nobody can close must not stop the run
    window.blocking_dialogs = QGuiApplication.platformName() not in HEADLESS_PLATFORMS
    window.show()
    sys.excepthook = window.report_unexpected
    if project is not None:
        window.open_project(project, ask_to_save=False)
    else:
        window.offer_recovery()
    return app.exec()


__all__ = ["MainWindow", "guess_preset", "run_studio"]
