"""The studio's main window: photos in tabs, the feature panel, the 3D view, menus and project files.

Layout: the current expression's photos fill the centre (one :class:`~app.qt.photo_view.PhotoView`
per tab, the tab title showing the photo's reprojection RMS after a fit); the
:class:`~app.qt.feature_list.FeaturePanel` docks on the left and the :class:`~app.qt.view3d.View3D` on
the right. The toolbar holds the expression, the editing mode (points / draw curve), the fit
and overlay switches, and the current photo's starting view and camera group.

Everything the window shows observes one :class:`~app.studio_state.StudioModel`; edits are
:mod:`app.qt.commands` pushed on a :class:`QUndoStack`; fits run in a worker
(:class:`~app.qt.workers.FitController`). Files: new, open (with recovery of a newer autosave),
save, save as, recent files (``QSettings``), an unsaved-changes prompt, and an autosave timer
writing ``<file>.autosave`` (a never-saved project: a recovery file in the user's data folder,
``QStandardPaths.AppDataLocation``, offered at the next start).

Recovery files: each running studio autosaves a never-saved project to its *own* file,
``untitled-<pid>-<random>.recovery.facestudio.json``, and holds a :class:`QLockFile`
(``<file>.lock``) on it from before the first write until the project is saved, discarded or
the window closes. At start-up :meth:`MainWindow.offer_recovery` offers every recovery file in
the folder whose lock no live process holds (a crashed instance's lock is stale: Qt checks its
pid), so two studios running at once never overwrite, delete or recover each other's data.

Texture (§5.2): *Texture → Extract texture* runs :mod:`photomodel.texturing.job` in a worker
(:class:`~app.qt.workers.JobController`) behind a cancellable progress dialog; the 3D view then
shows the model with the cylindrical texture or view-dependently (a toggle), and the
:class:`~app.qt.texture_views.WeightMapPanel` dock shows the weight maps. A project saved with
textures shows them again when it is opened (read back from its files as each expression is
shown, :meth:`~app.studio_state.StudioModel.load_stored_texture`; a damaged file is named in the status
bar and that texture is simply not shown). *Expression → Side by
side* docks the :class:`~app.qt.texture_views.ExpressionsView`. *Tracking → Track video…* / *Open
results…* dock the :class:`~app.qt.tracking_view.TrackingView` (§6.2: the footage with the model
overlaid, a frame scrubber, the parameter curves). The *Rig* dock (:class:`~app.qt.rig_panel.RigPanel`)
lists the project's blend shapes (``facestudio rig``) with a slider each, posing the 3D view;
*Rig → Build rig* makes the rig of the fitted neutral in a worker and writes it next to the
project (``results/rig.npz``; the project file records it when saved). Every failure is shown in a
dialog whose text is the cause
(e.g. ``james.facestudio.json: expressions[0].photos[2].points.nose_tip: expected [u, v] …``).
"""

from __future__ import annotations

import os
import sys
import traceback
import uuid
from pathlib import Path

from PySide6.QtCore import QDateTime, QLockFile, QSettings, QStandardPaths, Qt, QTimer, Signal
from PySide6.QtGui import QAction, QActionGroup, QGuiApplication, QKeySequence, QUndoStack
from PySide6.QtWidgets import (
    QApplication,
    QComboBox,
    QDockWidget,
    QFileDialog,
    QInputDialog,
    QLabel,
    QLineEdit,
    QMainWindow,
    QMessageBox,
    QProgressDialog,
    QTabWidget,
)

from app.qt.commands import (
    AddExpressionCommand,
    AddPhotosCommand,
    RemovePhotoCommand,
    SetCameraGroupCommand,
    SetPresetCommand,
)
from app.qt.feature_list import FeaturePanel
from app.qt.photo_import import PhotoImporter
from app.qt.photo_view import CURVE, POINTS, PhotoView
from app.qt.progress import close_progress, open_progress, update_progress
from app.qt.qt_compat import check_pyside
from app.qt.rig_panel import RigPanel
from app.qt.texture_views import ExpressionsView, WeightMapPanel
from app.qt.tracking_view import TrackingView
from app.qt.view3d import View3D
from app.qt.workers import FitController, JobController
from app.studio_state import IMAGE_SUFFIXES, MissingPhotos, StudioModel, newer_autosave, remove_autosave
from photomodel.camera import PRESET_AZIMUTH_DEG
from photomodel.errors import FaceStudioError, ProjectError
from photomodel.photos.intake import gather_photo_files
from photomodel.project import FILE_SUFFIX

#: Qt platforms without a screen: error boxes there do not block (:func:`run_studio`).
HEADLESS_PLATFORMS = ("offscreen", "minimal")
#: Autosave period (ms).
AUTOSAVE_INTERVAL_MS = 60_000
MAX_RECENT = 8
#: Default texture size (texels per side); the setting ``texture/size`` overrides it.
DEFAULT_TEXTURE_SIZE = 1024
#: How the 3D view draws a textured model.
TEXTURE_MODES = ("untextured", "cylindrical", "view_dependent")
#: Appended to the message saying a stored texture cannot be shown.
REEXTRACT_HINT = " (Texture → Extract texture makes it again)"
#: How the recovery file of a never-saved project ends; every such file in the recovery folder is
#: offered at start-up unless a running studio holds its lock.
RECOVERY_SUFFIX = ".recovery" + FILE_SUFFIX
#: The single recovery file of studios before one file per instance (still offered at start-up).
RECOVERY_NAME = "untitled" + RECOVERY_SUFFIX


def default_recovery_folder() -> Path:
    """Where never-saved projects are autosaved: ``QStandardPaths.AppDataLocation`` (else ``~/.facestudio``)."""
    folder = QStandardPaths.writableLocation(QStandardPaths.StandardLocation.AppDataLocation)
    return Path(folder or Path.home() / ".facestudio")


def default_recovery_file(folder=None) -> Path:
    """A new, unique recovery file for this instance: ``<folder>/untitled-<pid>-<8 hex>.recovery.facestudio.json``.

    ``folder`` defaults to :func:`default_recovery_folder`. The pid says which process wrote it
    (for a person looking at the folder); the random part keeps two windows of one process apart.
    """
    folder = Path(folder) if folder is not None else default_recovery_folder()
    return folder / f"untitled-{os.getpid()}-{uuid.uuid4().hex[:8]}{RECOVERY_SUFFIX}"


def recovery_files(folder) -> list[Path]:
    """The recovery files in ``folder`` (``*.recovery.facestudio.json``), newest first; [] if none."""
    folder = Path(folder)
    if not folder.is_dir():
        return []
    found = [f for f in folder.glob("*" + RECOVERY_SUFFIX) if f.is_file()]
    return sorted(found, key=lambda f: (-f.stat().st_mtime, f.name))


def lock_recovery_file(path) -> QLockFile | None:
    """Take the lock ``<path>.lock`` of a recovery file; None if a running process holds it.

    A lock left by a process that is no longer running is stale and taken over. Locks never go
    stale by age (``setStaleLockTime(0)``): a studio may run for days.
    """
    lock = QLockFile(str(path) + ".lock")
    lock.setStaleLockTime(0)
    return lock if lock.tryLock(0) else None


PROJECT_FILTER = f"Face Studio projects (*{FILE_SUFFIX});;JSON files (*.json);;All files (*)"
IMAGE_FILTER = "Images (" + " ".join(f"*{s}" for s in IMAGE_SUFFIXES) + ");;All files (*)"


def guess_preset(filename: str) -> str:
    """The starting view a file name suggests (``IMG_left.jpg`` → ``left``), else ``front``."""
    stem = Path(filename).stem.lower().replace("-", "_").replace(" ", "_")
    for preset in sorted(PRESET_AZIMUTH_DEG, key=len, reverse=True):
        if preset in stem:
            return preset
    if "3q" in stem or "three" in stem:
        return "three_quarter_right" if "right" in stem else "three_quarter_left"
    return "front"


class MainWindow(QMainWindow):
    """The Face Studio window.

    Parameters
    ----------
    model : StudioModel, optional (default: a new one with an empty project)
    settings : QSettings, optional (default: the user's; tests pass their own file)
    autosave_interval_ms : int, the autosave period (0 disables the timer)
    recovery_file : path, optional
        where this window autosaves a never-saved project (default: a new file of its own,
        :func:`default_recovery_file`, in ``recovery_folder``). A given file is this window's
        even if it exists: :meth:`offer_recovery` offers it first.
    recovery_folder : path, optional
        the folder of recovery files scanned by :meth:`offer_recovery` (default: the parent of
        ``recovery_file`` if given, else :func:`default_recovery_folder`).

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
        self.undo_stack = QUndoStack(self)
        self.fits = FitController(self.model, self)
        self.jobs = JobController(self.model, self)
        self.rig_jobs = JobController(self.model, self)  # Rig → Build rig
        self._rig_progress: QProgressDialog | None = None
        self.importer = PhotoImporter(self)  # New from photos…, photos added with automatic landmarks
        if recovery_file is not None:
            self.recovery_file = Path(recovery_file)
            self.recovery_folder = Path(recovery_folder) if recovery_folder is not None else self.recovery_file.parent
        else:
            self.recovery_folder = Path(recovery_folder) if recovery_folder is not None else default_recovery_folder()
            self.recovery_file = default_recovery_file(self.recovery_folder)
        self._recovery_lock: QLockFile | None = None  # held from before the first recovery autosave
        self.texture_mode = "cylindrical"
        self._texture_progress: QProgressDialog | None = None
        self._show_weights_for_stored = True  # the weight-map dock opens for the first stored texture
        self.views: dict[str, PhotoView] = {}
        self.mode = POINTS
        self.show_overlay = True
        self.show_curves = True
        self._progress: QProgressDialog | None = None
        self._rebuilding = False
        self.blocking_dialogs = True  # run_studio: False on a headless platform (offscreen, minimal)
        self.unexpected_errors: list[str] = []  # report_unexpected: "Type: message" of each
        self._error_box: QMessageBox | None = None
        self._unexpected_in_box = 0  # errors in the box now shown

        self.setWindowTitle("Face Studio")
        self.resize(1500, 920)
        self.setAcceptDrops(True)
        self.setDockNestingEnabled(True)

        self._build_docks()
        self.fit_label = QLabel("not fitted")
        self.statusBar().addPermanentWidget(self.fit_label)

        self._build_actions()
        self._build_menus()
        self._build_toolbar()

        self._connect_signals()

        self.autosave_timer = QTimer(self)
        self.autosave_timer.timeout.connect(self.autosave)
        if autosave_interval_ms > 0:
            self.autosave_timer.start(autosave_interval_ms)

        self._on_project_replaced()

    # ------------------------------------------------------------------ layout and signals
    def _build_docks(self):
        """The photo tabs in the centre and the docks around them: features, 3D view, weight maps,
        expressions side by side, tracking."""
        self.tabs = QTabWidget()
        self.tabs.setDocumentMode(True)
        # room under the text: some fonts draw "_" below the compact tab's text box, and photo ids
        # such as three_quarter_right then read "three quarter right" (issue 35)
        self.tabs.tabBar().setStyleSheet("QTabBar::tab { padding-bottom: 3px; }")
        self.tabs.currentChanged.connect(self._on_tab_changed)
        self.empty_label = QLabel("<h3>No photos yet</h3><p>Drop photos here, or use File → Add photos…</p>")
        self.empty_label.setAlignment(Qt.AlignmentFlag.AlignCenter)
        self.setCentralWidget(self.tabs)

        self.panel = FeaturePanel(self.model, undo_stack=self.undo_stack)
        self.panel.jump_requested.connect(self.jump_to)
        self.panel.photo_requested.connect(self.show_photo)
        left, right = Qt.DockWidgetArea.LeftDockWidgetArea, Qt.DockWidgetArea.RightDockWidgetArea
        bottom = Qt.DockWidgetArea.BottomDockWidgetArea
        dock = self.features_dock = self._dock("Features and fit", "features", self.panel, left, closable=False)

        self.view3d = View3D(self.model)
        dock3 = self.view3d_dock = self._dock("3D view", "view3d", self.view3d, right, closable=False)
        self.resizeDocks([dock, dock3], [330, 400], Qt.Orientation.Horizontal)

        self.weights_panel = WeightMapPanel(self.model)
        dockw = self.weights_dock = self._dock("Texture and weight maps", "weight_maps", self.weights_panel, right)
        self.splitDockWidget(dock3, dockw, Qt.Orientation.Vertical)  # under the 3D view
        dockw.hide()  # shown by the first texture

        self.expressions_view = ExpressionsView(self.model)
        docke = self.expressions_dock = self._dock(
            "Expressions side by side", "expressions", self.expressions_view, bottom
        )
        docke.hide()

        self.tracking_view = TrackingView(self.model)
        dockt = self.tracking_dock = self._dock("Tracking", "tracking", self.tracking_view, bottom)
        self.tabifyDockWidget(docke, dockt)
        dockt.hide()

        self.rig_panel = RigPanel(self.model)
        self.rig_dock = self._dock("Rig", "rig", self.rig_panel, left)
        self.tabifyDockWidget(dock, self.rig_dock)
        dock.raise_()

    def _dock(self, title: str, name: str, widget, area, *, closable: bool = True) -> QDockWidget:
        """A movable, floatable dock (closable unless told) holding ``widget``, added at ``area``."""
        dock = QDockWidget(title, self)
        dock.setObjectName(name)
        dock.setWidget(widget)
        features = QDockWidget.DockWidgetFeature.DockWidgetMovable | QDockWidget.DockWidgetFeature.DockWidgetFloatable
        if closable:
            features |= QDockWidget.DockWidgetFeature.DockWidgetClosable
        dock.setFeatures(features)
        self.addDockWidget(area, dock)
        return dock

    def _connect_signals(self):
        """The window follows the model, the undo stack and the workers."""
        m = self.model
        m.project_replaced.connect(self._on_project_replaced)
        m.expression_changed.connect(lambda *_: self._rebuild_tabs())
        m.photos_changed.connect(lambda *_: self._rebuild_tabs())
        m.photo_changed.connect(lambda *_: self._sync_preset())
        m.fit_changed.connect(self._on_fit_changed)
        m.texture_changed.connect(self._on_texture_changed)
        m.texture_load_failed.connect(self._on_texture_load_failed)
        m.expression_changed.connect(lambda *_: self._on_texture_changed(self.model.expression_name))
        m.modified_changed.connect(lambda value: self.setWindowModified(bool(value)))
        m.path_changed.connect(lambda *_: self._update_title())
        self.undo_stack.indexChanged.connect(self._on_edit)
        self.fits.overlay_photos = self._overlay_photo_ids  # computed in the fit's worker
        self.fits.started.connect(self._on_fit_started)
        self.fits.progress.connect(self._on_fit_progress)
        self.fits.finished.connect(self._on_fit_finished)
        self.fits.failed.connect(self._on_fit_failed)
        self.fits.cancelled.connect(self._on_fit_cancelled)
        self.jobs.progress.connect(self._on_texture_progress)
        self.jobs.finished.connect(self._on_texture_finished)
        self.jobs.failed.connect(self._on_texture_failed)
        self.jobs.cancelled.connect(self._on_texture_cancelled)
        self.rig_jobs.finished.connect(self._on_rig_finished)
        self.rig_jobs.failed.connect(self._on_rig_failed)
        self.rig_jobs.cancelled.connect(self._on_rig_cancelled)
        # the status bar's "tracking … into …" is replaced by how the run ended (after the
        # tracking view, connected first, has written its last_message)
        track = self.tracking_view.jobs
        for ended in (track.finished, track.failed, track.cancelled):
            ended.connect(self._on_tracking_ended)

    # ------------------------------------------------------------------ actions and menus
    def _action(self, text, slot=None, shortcut=None, checkable=False, checked=False, tip=None) -> QAction:
        a = QAction(text, self)
        if shortcut is not None:
            a.setShortcut(QKeySequence(shortcut))
        if checkable:
            a.setCheckable(True)
            a.setChecked(checked)
        if tip:
            a.setStatusTip(tip)
            a.setToolTip(tip)
        if slot is not None:
            (a.toggled if checkable else a.triggered).connect(slot)
        return a

    def _build_actions(self):
        A = self._action
        self.act_new = A("&New project", self.new_project, QKeySequence.StandardKey.New)
        self.act_open = A("&Open…", self.open_dialog, QKeySequence.StandardKey.Open)
        self.act_save = A("&Save", self.save, QKeySequence.StandardKey.Save)
        self.act_save_as = A("Save &as…", self.save_as, QKeySequence.StandardKey.SaveAs)
        self.act_add_photos = A(
            "Add &photos…",
            self.add_photos_dialog,
            "Ctrl+Shift+P",
            tip="add photographs of the current expression (or drop image files on the window)",
        )
        self.act_new_from_photos = A(
            "New from p&hotos…",
            lambda: self.importer.new_from_photos_dialog(),
            tip="a new project from a folder of photos, with automatic landmarks",
        )
        self.act_new_from_video = A(
            "New from &video…",
            lambda: self.importer.new_from_video_dialog(),
            tip="a new project from stills of a video of the person (the clearest, least "
            "expressive frames across the head's turn), with automatic landmarks",
        )
        self.act_add_photos_auto = A(
            "Add photos with automatic &landmarks…",
            self.add_photos_auto_dialog,
            tip="add photographs of the current expression and place their landmarks",
        )
        self.act_remove_photo = A("Remove current photo", self.remove_current_photo)
        self.act_quit = A("&Quit", self.close, QKeySequence.StandardKey.Quit)
        self.act_build_rig = A(
            "&Build rig",
            self.run_build_rig,
            tip="ARKit's blend shapes on the fitted neutral (as `facestudio rig`), written next to the project",
        )
        self.act_undo = self.undo_stack.createUndoAction(self, "&Undo")
        self.act_undo.setShortcut(QKeySequence.StandardKey.Undo)
        self.act_redo = self.undo_stack.createRedoAction(self, "&Redo")
        # Ctrl+Y (Windows' and Qt's Redo on Linux) and Ctrl+Shift+Z (macOS, Blender, GIMP) both redo
        redo_keys = [*QKeySequence.keyBindings(QKeySequence.StandardKey.Redo)]
        for extra in (QKeySequence("Ctrl+Y"), QKeySequence("Ctrl+Shift+Z")):
            if extra not in redo_keys:
                redo_keys.append(extra)
        self.act_redo.setShortcuts(redo_keys)
        self.act_delete = A("Delete click of the active feature", self._delete_click, tip="Delete key in a photo")
        self.act_hide = A("Hide / show the active feature in this photo", self._toggle_hidden, tip="H in a photo")
        self.act_new_expr = A("New &expression…", self.new_expression_dialog)
        self.act_fit = A(
            "&Fit", self.run_fit, "Ctrl+R", tip="recover the cameras, deform the generic mesh and refine it (§5.1)"
        )
        self.act_auto = A(
            "&Auto-refit after each edit",
            self._set_auto_refit,
            checkable=True,
            checked=True,
            tip="refit after every edit while a refit takes less than 0.3 s",
        )
        self.act_overlay = A("Fitted &wireframe overlay", self._set_overlay, "W", checkable=True, checked=True)
        self.act_curves = A("Drawn &curves", self._set_curves, checkable=True, checked=True)
        self.act_fit_view = A("Fit photo to window", self._fit_photo_view, "F")
        self.act_mode_points = A(
            "Click &points",
            lambda on: on and self.set_mode(POINTS),
            "P",
            checkable=True,
            checked=True,
            tip="left-click places the active feature; drag a marker to move it",
        )
        self.act_mode_curve = A(
            "Draw &curve",
            lambda on: on and self.set_mode(CURVE),
            "C",
            checkable=True,
            tip="click successive points (or drag) along a brow, lid or lip; Enter finishes",
        )
        group = QActionGroup(self)
        group.addAction(self.act_mode_points)
        group.addAction(self.act_mode_curve)
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
        tgroup = QActionGroup(self)
        for a in self.act_tex_modes.values():
            tgroup.addAction(a)
        self.act_side_by_side = A(
            "Expressions &side by side",
            self.show_expressions,
            tip="every fitted expression from the same camera, with its RMS",
        )
        self.act_track_video = A(
            "&Track video…",
            self.track_video_dialog,
            tip="estimate head pose and expression weights in every frame of a video (§6.2)",
        )
        self.act_first_pose = A(
            "Set &first pose…",
            lambda: self.tracking_view.first_pose_dialog(),
            tip="click the pose features in frame 0 of a video (the pose tracking starts from)",
        )
        self.act_open_tracking = A(
            "&Open results…", self.open_tracking_dialog, tip="show the tracking results of a folder (its track.json)"
        )

    def _build_menus(self):
        mb = self.menuBar()
        f = mb.addMenu("&File")
        for a in (self.act_new, self.act_new_from_photos, self.act_new_from_video, self.act_open):
            f.addAction(a)
        self.recent_menu = f.addMenu("Open &recent")
        self.recent_menu.aboutToShow.connect(self._fill_recent_menu)
        f.addSeparator()
        for a in (self.act_save, self.act_save_as):
            f.addAction(a)
        f.addSeparator()
        f.addAction(self.act_add_photos)
        f.addAction(self.act_add_photos_auto)
        f.addAction(self.act_remove_photo)
        f.addSeparator()
        f.addAction(self.act_quit)
        e = mb.addMenu("&Edit")
        for a in (self.act_undo, self.act_redo):
            e.addAction(a)
        e.addSeparator()
        e.addAction(self.act_delete)
        e.addAction(self.act_hide)
        x = mb.addMenu("E&xpression")
        x.addAction(self.act_new_expr)
        x.addAction(self.act_side_by_side)
        fm = mb.addMenu("F&it")
        fm.addAction(self.act_fit)
        fm.addAction(self.act_auto)
        t = mb.addMenu("&Texture")
        t.addAction(self.act_texture)
        t.addAction(self.act_texture_size)
        t.addSeparator()
        for a in self.act_tex_modes.values():
            t.addAction(a)
        tr = mb.addMenu("T&racking")
        tr.addAction(self.act_first_pose)
        tr.addAction(self.act_track_video)
        tr.addAction(self.act_open_tracking)
        rg = mb.addMenu("R&ig")
        rg.addAction(self.act_build_rig)
        rg.addAction(self.rig_dock.toggleViewAction())
        v = mb.addMenu("&View")
        for a in (self.act_mode_points, self.act_mode_curve):
            v.addAction(a)
        v.addSeparator()
        for a in (self.act_overlay, self.act_curves, self.act_fit_view):
            v.addAction(a)
        v.addSeparator()
        v.addAction(self.features_dock.toggleViewAction())
        v.addAction(self.view3d_dock.toggleViewAction())
        v.addAction(self.weights_dock.toggleViewAction())
        v.addAction(self.expressions_dock.toggleViewAction())
        v.addAction(self.tracking_dock.toggleViewAction())
        v.addAction(self.rig_dock.toggleViewAction())

    def _build_toolbar(self):
        tb = self.addToolBar("Main")
        tb.setObjectName("main")
        tb.addWidget(QLabel(" Expression "))
        self.expr_combo = QComboBox()
        self.expr_combo.setMinimumContentsLength(10)
        self.expr_combo.activated.connect(self._on_expr_combo)
        tb.addWidget(self.expr_combo)
        tb.addAction(self.act_new_expr)
        tb.addSeparator()
        tb.addAction(self.act_mode_points)
        tb.addAction(self.act_mode_curve)
        tb.addSeparator()
        tb.addAction(self.act_fit)
        tb.addAction(self.act_auto)
        tb.addAction(self.act_overlay)
        tb.addAction(self.act_texture)
        tb.addSeparator()
        tb.addWidget(QLabel(" Photo view "))
        self.preset_combo = QComboBox()
        for p in PRESET_AZIMUTH_DEG:
            self.preset_combo.addItem(p.replace("_", " "), p)
        self.preset_combo.setToolTip("the rough direction the current photo was taken from (starts the pose recovery)")
        self.preset_combo.activated.connect(self._on_preset_combo)
        tb.addWidget(self.preset_combo)
        tb.addWidget(QLabel(" Camera group "))
        self.camera_group_edit = QLineEdit()
        self._camera_group_target = None  # (expression, photo id) whose group the field shows
        self.camera_group_edit.setPlaceholderText("own camera")
        self.camera_group_edit.setMaximumWidth(140)
        self.camera_group_edit.setToolTip(
            "photos with the same camera group were taken with one camera and lens (frames of a video, "
            "a fixed lens) and share one focal length; empty: a camera of its own"
        )
        self.camera_group_edit.editingFinished.connect(self._on_camera_group_edited)
        tb.addWidget(self.camera_group_edit)
        tb.addAction(self.act_add_photos)

    # ------------------------------------------------------------------ errors
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

    def _status(self, text: str, ms: int = 6000) -> None:
        self.statusBar().showMessage(text, ms)

    # ------------------------------------------------------------------ project files
    def _update_title(self):
        p = self.model.project
        where = str(p.path) if p.path is not None else "not saved"
        self.setWindowTitle(f"{p.name} — {where} [*] — Face Studio")

    def maybe_save(self) -> bool:
        """Ask what to do with unsaved changes; False if the user cancels."""
        if not self.model.modified:
            return True
        answer = QMessageBox.question(
            self,
            "Unsaved changes",
            f"Save the changes to {self.model.project.name!r}?",
            QMessageBox.StandardButton.Save | QMessageBox.StandardButton.Discard | QMessageBox.StandardButton.Cancel,
            QMessageBox.StandardButton.Save,
        )
        if answer == QMessageBox.StandardButton.Save:
            return self.save()
        if answer == QMessageBox.StandardButton.Discard:
            if self.model.path is not None:
                remove_autosave(self.model.path)
            else:
                self._drop_recovery()
            return True
        return False

    def new_project(self) -> bool:
        if not self.maybe_save():
            return False
        self.fits.cancel()
        try:
            self._replace_project(lambda: self.model.new("untitled"))
        except Exception as exc:  # whatever went wrong, the window stays usable and says why
            self.show_error("Cannot start a new project", _cause(exc))
            return False
        self.undo_stack.clear()
        return True

    def _replace_project(self, change) -> None:
        """Run ``change()``, which replaces the model's project (new, open, recover).

        The photo views are taken down first, so that none of them looks up a photo of the old
        project in the new one while Qt removes it from its tab; whatever ``change`` raises, the
        tabs are rebuilt for the project then open (the previous one when nothing changed).
        """
        before, shown = self.model.project, self.current_view()
        shown = None if shown is None else shown.photo_id
        self._clear_tabs()
        try:
            change()
        except BaseException:
            if self.model.project is not before:  # replaced, then something failed: its edits start now
                self.undo_stack.clear()
            self._on_project_replaced()
            if self.model.project is before and shown is not None:
                self.show_photo(shown)  # as it was
            raise

    def open_dialog(self) -> bool:
        start = str(self.model.path.parent) if self.model.path is not None else ""
        path, _ = QFileDialog.getOpenFileName(self, "Open project", start, PROJECT_FILTER)
        return bool(path) and self.open_project(path)

    def open_project(self, path, *, ask_to_save: bool = True) -> bool:
        """Open a project file; on any problem say why and keep the current project."""
        if ask_to_save and not self.maybe_save():
            return False
        path = Path(path)
        recover = False
        auto = newer_autosave(path)
        if auto is not None:
            answer = QMessageBox.question(
                self,
                "Recover autosave",
                f"{auto.name} is newer than {path.name}: it holds changes that were not saved "
                "(e.g. before a crash). Recover them?",
                QMessageBox.StandardButton.Yes | QMessageBox.StandardButton.No,
                QMessageBox.StandardButton.Yes,
            )
            recover = answer == QMessageBox.StandardButton.Yes
        before = self.model.project
        try:
            self.fits.cancel()
            try:
                self._replace_project(lambda: self.model.open(path, recover=recover))
            except MissingPhotos as exc:
                answer = QMessageBox.question(
                    self,
                    "Missing photos",
                    f"{exc}\n\nOpen the project anyway? The missing photos are shown as grey placeholders; "
                    "their clicks are kept.",
                    QMessageBox.StandardButton.Yes | QMessageBox.StandardButton.No,
                    QMessageBox.StandardButton.No,
                )
                if answer != QMessageBox.StandardButton.Yes:
                    self._status(f"{path.name} not opened: photos are missing")
                    return False
                self._replace_project(lambda: self.model.open(path, recover=recover, allow_missing_photos=True))
        except FaceStudioError as exc:
            self.show_error("Cannot open the project", str(exc))
            return False
        except OSError as exc:
            self.show_error("Cannot open the project", f"{path}: {exc.strerror or exc}")
            return False
        except Exception as exc:  # e.g. RecursionError from a file nested thousands deep
            kept = "the previous project is still open" if self.model.project is before else "it is open as read"
            self.show_error("Cannot open the project", f"{path.name}: {_cause(exc)} ({kept})")
            return False
        self.undo_stack.clear()
        self._add_recent(path)
        text = f"opened {path}" + (" (recovered from the autosave)" if recover else "")
        problem = self.model.texture_problems.get(self.model.expression_name)
        if problem is not None:
            text += f"; {problem}{REEXTRACT_HINT}"
        self._status(text, 6000 if problem is None else 20000)
        return True

    def save(self) -> bool:
        if self.model.path is None:
            return self.save_as()
        return self._save_to(self.model.path)

    def save_as(self) -> bool:
        p = self.model.project
        start = str(p.path) if p.path is not None else str(Path.cwd() / (p.name + FILE_SUFFIX))
        path, _ = QFileDialog.getSaveFileName(self, "Save project as", start, PROJECT_FILTER)
        if not path:
            return False
        if not path.endswith(".json"):
            path += FILE_SUFFIX
        if p.name == "untitled":
            p.name = Path(path).name.removesuffix(FILE_SUFFIX).removesuffix(".json") or "untitled"
        return self._save_to(Path(path))

    def _save_to(self, path: Path) -> bool:
        untitled = self.model.path is None
        try:
            written = self.model.save(path)
        except FaceStudioError as exc:
            self.show_error("Cannot save the project", str(exc))
            return False
        except OSError as exc:
            self.show_error("Cannot save the project", f"{path}: {exc.strerror or exc}")
            return False
        self.undo_stack.setClean()
        if untitled:  # it has a file now: its recovery file is obsolete
            self._drop_recovery()
        self._add_recent(written)
        self._status(f"saved {written}")
        return True

    def autosave(self) -> None:
        """Autosave: ``<file>.autosave``, or for a never-saved project :attr:`recovery_file`."""
        if self.model.path is None and self._recovery_lock is None:
            # locked before it is written: an instance starting meanwhile must not offer it
            self.recovery_file.parent.mkdir(parents=True, exist_ok=True)
            self._recovery_lock = lock_recovery_file(self.recovery_file)  # None: written unlocked
        try:
            written = self.model.autosave(recovery=self.recovery_file)
        except (FaceStudioError, OSError) as exc:
            self._status(f"autosave failed: {exc}", 10000)
            return
        if written is not None:
            self._status(f"autosaved to {written.name}", 3000)

    def offer_recovery(self) -> bool:
        """At start: offer the recovery files of never-saved projects, newest first.

        Offered: this window's own :attr:`recovery_file` if it exists (a file given to the
        constructor), then every file of :func:`recovery_files` in :attr:`recovery_folder` whose
        lock no running studio holds (:func:`lock_recovery_file`) — so another instance's
        project is never offered while that instance runs, and a crashed one's is. Yes opens
        it (without a file, marked modified) and makes it this window's recovery file; No
        deletes it and offers the next. Returns True if a project was recovered.
        """
        if self.recovery_file.is_file() and self._offer_one_recovery(self.recovery_file, None):
            return True
        for f in recovery_files(self.recovery_folder):
            if f.absolute() == self.recovery_file.absolute():
                continue
            lock = lock_recovery_file(f)
            if lock is None:  # a running studio's
                continue
            if not f.is_file():  # deleted meanwhile
                lock.unlock()
                continue
            if self._offer_one_recovery(f, lock):
                return True
        return False

    def _offer_one_recovery(self, f: Path, lock: QLockFile | None) -> bool:
        when = QDateTime.fromSecsSinceEpoch(int(f.stat().st_mtime)).toString("yyyy-MM-dd hh:mm")
        answer = QMessageBox.question(
            self,
            "Recover unsaved project",
            f"A project that was never saved was autosaved at {when} (e.g. before a crash). Recover it?\n\n"
            f"(No deletes {f})",
            QMessageBox.StandardButton.Yes | QMessageBox.StandardButton.No,
            QMessageBox.StandardButton.Yes,
        )
        if answer != QMessageBox.StandardButton.Yes:
            f.unlink(missing_ok=True)
            if lock is not None:
                lock.unlock()
            return False
        try:
            self._replace_project(lambda: self.model.recover(f))
        except Exception as exc:  # a damaged recovery file is named, never a traceback
            self.show_error("Cannot recover the project", f"{f}: {_cause(exc)}")
            if lock is not None:
                lock.unlock()
            return False
        if lock is not None:  # the recovered project autosaves where it came from, still locked by us
            self._drop_recovery()
            self.recovery_file, self._recovery_lock = f, lock
        self.undo_stack.clear()
        self._status(f"recovered the unsaved project from {f}")
        return True

    def _drop_recovery(self) -> None:
        """Delete this window's recovery file and release its lock (saved, discarded or closed)."""
        self.recovery_file.unlink(missing_ok=True)
        if self._recovery_lock is not None:
            self._recovery_lock.unlock()
            self._recovery_lock = None

    def recent_files(self) -> list[str]:
        value = self.settings.value("recent_files", [])
        if isinstance(value, str):
            value = [value]
        return [str(v) for v in (value or [])]

    def _add_recent(self, path) -> None:
        path = str(Path(path).absolute())
        files = [f for f in self.recent_files() if f != path]
        self.settings.setValue("recent_files", [path, *files][:MAX_RECENT])
        self.settings.sync()

    def _fill_recent_menu(self):
        self.recent_menu.clear()
        files = self.recent_files()
        if not files:
            a = self.recent_menu.addAction("(none)")
            a.setEnabled(False)
        for f in files:
            self.recent_menu.addAction(f, lambda f=f: self.open_project(f))

    # ------------------------------------------------------------------ photos and expressions
    def add_photos_dialog(self) -> None:
        files, _ = QFileDialog.getOpenFileNames(self, "Add photos", "", IMAGE_FILTER)
        if files:
            self.add_photos(files)

    def add_photos_auto_dialog(self) -> None:
        files, _ = QFileDialog.getOpenFileNames(self, "Add photos with automatic landmarks", "", IMAGE_FILTER)
        if files:
            self.add_photos_auto(files)

    def add_photos_auto(self, files) -> bool:
        """Add image files to the current expression (made ``neutral`` when there is none) with
        automatic landmarks, in the importer's worker; False when an import is running."""
        if self.importer.busy:
            return False
        if self.model.expression_name is None:
            self.undo_stack.push(AddExpressionCommand(self.model, "neutral"))
        return self.importer.add_photos(files)

    def add_photos(self, files) -> int:
        """Add image files to the current expression; unreadable ones are named in one message."""
        if self.model.expression_name is None:
            self.undo_stack.push(AddExpressionCommand(self.model, "neutral"))
        expr = self.model.expression_name
        photos, problems = [], []
        taken = {p.id for p in self.model.photos}
        for f in files:
            try:
                photo = self.model.photo_from_file(f, expr, preset=guess_preset(f))
            except ProjectError as exc:
                problems.append(str(exc))
                continue
            while photo.id in taken:  # two files with the same stem in one drop
                photo.id += "_b"
            taken.add(photo.id)
            photos.append(photo)
        if photos:
            self.undo_stack.push(AddPhotosCommand(self.model, expr, photos))
            self.show_photo(photos[0].id)
            self._status(f"added {len(photos)} photo(s); set each one's view in the toolbar if the guess is wrong")
        if problems:
            self.show_error("Cannot add photos", "\n".join(problems))
        return len(photos)

    def remove_current_photo(self):
        view = self.current_view()
        if view is not None:
            self.undo_stack.push(RemovePhotoCommand(self.model, view.expression, view.photo_id))

    def new_expression_dialog(self):
        name, ok = QInputDialog.getText(self, "New expression", "Name of the expression (e.g. smile):")
        if not (ok and name.strip()):
            return
        # the paper photographs every expression with the same cameras: offer to reuse theirs
        cameras_from = None
        others = [e.name for e in self.model.project.expressions]
        if others:
            own = "its own cameras (recovered from its clicks)"
            choices = [f"the cameras of {o!r} (the same rig)" for o in others] + [own]
            choice, ok = QInputDialog.getItem(self, "New expression", "Photographed with:", choices, 0, False)
            if not ok:
                return
            cameras_from = None if choice == own else others[choices.index(choice)]
        try:
            self.undo_stack.push(AddExpressionCommand(self.model, name.strip(), cameras_from=cameras_from))
        except FaceStudioError as exc:
            self.show_error("Cannot add the expression", str(exc))

    def _on_expr_combo(self, index: int):
        name = self.expr_combo.itemData(index)
        if name is not None and name != self.model.expression_name:
            self.model.set_expression(name)

    def _on_preset_combo(self, index: int):
        view = self.current_view()
        preset = self.preset_combo.itemData(index)
        if view is not None and preset != view.photo.preset:
            self.undo_stack.push(SetPresetCommand(self.model, view.expression, view.photo_id, preset))

    def _on_camera_group_edited(self):
        """Enter or leaving the field: apply the camera group typed to the photo it was typed for."""
        pending = self._take_camera_group_edit()
        if pending is not None:
            self._apply_camera_group(*pending)

    def _take_camera_group_edit(self) -> tuple | None:
        """(project, expression, photo id, group) of a camera group typed but not yet applied, or None."""
        edit, target = self.camera_group_edit, self._camera_group_target
        if target is None or not edit.isModified():
            return None
        edit.setModified(False)
        return (self.model.project, *target, edit.text().strip() or None)

    def _apply_camera_group(self, project, expression: str, photo_id: str, group: str | None) -> None:
        if project is not self.model.project:  # typed in a project since closed
            return
        try:
            photo = self.model.photo(photo_id, expression)
        except FaceStudioError:  # the photo went away meanwhile
            return
        if group != photo.camera_group:
            self.undo_stack.push(SetCameraGroupCommand(self.model, expression, photo_id, group))

    def _sync_preset(self):
        """The toolbar's photo properties (starting view, camera group) show the current photo's."""
        # a group still being typed belongs to the photo shown until now; applied once the edit
        # that brought us here (a tab change, an undo) has finished: never push inside an undo
        pending = self._take_camera_group_edit()
        if pending is not None:
            QTimer.singleShot(0, self, lambda: self._apply_camera_group(*pending))
        view = self.current_view()
        self.preset_combo.setEnabled(view is not None)
        self.camera_group_edit.setEnabled(view is not None)
        if view is not None:
            i = self.preset_combo.findData(view.photo.preset)
            self.preset_combo.setCurrentIndex(i)
            self._camera_group_target = (view.expression, view.photo_id)
            self.camera_group_edit.setText(view.photo.camera_group or "")  # also clears isModified
        else:
            self._camera_group_target = None
            self.camera_group_edit.clear()

    # ------------------------------------------------------------------ photo tabs
    def current_view(self) -> PhotoView | None:
        w = self.tabs.currentWidget()
        return w if isinstance(w, PhotoView) else None

    def show_photo(self, photo_id: str) -> PhotoView | None:
        view = self.views.get(photo_id)
        if view is not None:
            self.tabs.setCurrentWidget(view)
        return view

    def _clear_tabs(self) -> None:
        """Take every photo view down (detached first: none looks its photo up again)."""
        was, self._rebuilding = self._rebuilding, True
        try:
            for view in self.views.values():
                view.detach()
            self.tabs.clear()
            for view in self.views.values():
                view.deleteLater()
            self.views = {}
        finally:
            self._rebuilding = was

    def _rebuild_tabs(self):
        current = self.current_view()
        keep = current.photo_id if current is not None else None
        self._rebuilding = True
        try:
            self._clear_tabs()
            expr = self.model.expression_name
            for photo in self.model.photos:
                view = PhotoView(self.model, self.undo_stack, expr, photo.id)
                view.set_mode(self.mode)
                view.set_overlay_visible(self.show_overlay)
                view.set_curves_visible(self.show_curves)
                view.status_message.connect(self._status)
                self.views[photo.id] = view
                self.tabs.addTab(view, photo.id)
                if view.missing:
                    self.tabs.setTabToolTip(self.tabs.count() - 1, view.missing)
            if not self.views:
                self.tabs.addTab(self.empty_label, "no photos")
        finally:
            self._rebuilding = False
        if keep in self.views:
            self.tabs.setCurrentWidget(self.views[keep])
        self._update_tab_titles()
        self._sync_expr_combo()
        self._sync_preset()

    def _overlay_photo_ids(self, expression: str) -> list[str]:
        """The photo on screen, if it shows ``expression``'s overlay (:attr:`FitController.overlay_photos`)."""
        view = self.current_view()
        if view is None or not self.show_overlay or view.expression != expression:
            return []
        return [view.photo_id]

    def _on_tab_changed(self, index: int):
        if self._rebuilding:
            return
        self._sync_preset()
        view = self.current_view()
        if view is not None:
            view.setFocus()

    def _update_tab_titles(self):
        fit = self.model.fit()
        rms = {}
        if fit is not None:
            rms = {v["photo"]: v.get("rms_px") for v in fit.report.get("views", [])}
        for i in range(self.tabs.count()):
            w = self.tabs.widget(i)
            if isinstance(w, PhotoView):
                r = rms.get(w.photo_id)
                self.tabs.setTabText(i, w.photo_id if r is None else f"{w.photo_id}  {r:.2f} px")

    def _sync_expr_combo(self):
        self.expr_combo.clear()
        for e in self.model.project.expressions:
            self.expr_combo.addItem(f"{e.name} ({len(e.photos)} photos)", e.name)
        i = self.expr_combo.findData(self.model.expression_name)
        self.expr_combo.setCurrentIndex(i)

    def jump_to(self, photo_id: str, feature: str) -> None:
        """Show a click: its photo, zoomed in around it, with its feature active."""
        view = self.show_photo(photo_id)
        if view is None:
            return
        try:
            self.model.set_active_feature(feature)
        except FaceStudioError:
            pass
        uv = view.photo.points.get(feature)
        if uv is not None:
            view.center_on_image(float(uv[0]), float(uv[1]), scale=max(view.scale_factor, 2.0))
        view.setFocus()

    # ------------------------------------------------------------------ modes and toggles
    def set_mode(self, mode: str):
        self.mode = mode
        for view in self.views.values():
            view.set_mode(mode)
        (self.act_mode_curve if mode == CURVE else self.act_mode_points).setChecked(True)
        if mode == CURVE:
            self._status(f"draw curve {self.model.active_curve}: click points along it, Enter to finish")

    def _set_overlay(self, on: bool):
        self.show_overlay = on
        for view in self.views.values():
            view.set_overlay_visible(on)

    def _set_curves(self, on: bool):
        self.show_curves = on
        for view in self.views.values():
            view.set_curves_visible(on)

    def _set_auto_refit(self, on: bool):
        self.fits.auto_refit = on

    def _fit_photo_view(self):
        view = self.current_view()
        if view is not None:
            view.user_zoomed = False
            view.fit_photo()

    def _delete_click(self):
        view = self.current_view()
        if view is not None:
            view.delete_active_click()

    def _toggle_hidden(self):
        view = self.current_view()
        if view is not None:
            view.toggle_active_hidden()

    # ------------------------------------------------------------------ fitting
    def run_fit(self) -> bool:
        """Fit the current expression from scratch in the worker, with a cancellable progress dialog."""
        if self.model.expression is None or not self.model.photos:
            self.show_error("Cannot fit", "a fit needs an expression with a photo; add photos first")
            return False
        if self.fits.busy:
            self.fits.cancel()
            self.fits.wait(10.0)
            QApplication.processEvents()
        task = self.fits.start(warm=False)
        if task is None:
            self._status("a fit is already running")
            return False
        self._progress = open_progress(self, "Fit", "Fitting…", self.fits.cancel, min_duration_ms=400)
        return True

    def _close_progress(self):
        close_progress(self._progress, self.fits.cancel)
        self._progress = None

    def _on_fit_started(self, expression: str, warm: bool):
        self.fit_label.setText("refitting…" if warm else "fitting…")

    def _on_fit_progress(self, stage: str, fraction: float):
        update_progress(self._progress, stage, fraction)

    def _on_fit_finished(self, expression: str, seconds: float):
        self._close_progress()

    def _on_fit_failed(self, message: str):
        explicit = self._progress is not None
        self._close_progress()
        self.fit_label.setText("fit failed")
        if explicit:
            self.show_error("The fit failed", message)
        else:
            self._status(f"refit failed: {message.splitlines()[0]}", 10000)

    def _on_fit_cancelled(self):
        self._close_progress()
        self.fit_label.setText("fit cancelled")
        self._status("fit cancelled; the previous result is kept")

    def _on_fit_changed(self, expression: str):
        if expression != self.model.expression_name:
            return
        fit = self.model.fit()
        if fit is None:
            self.fit_label.setText("not fitted")
        else:
            t = "" if fit.elapsed_s is None else f" ({fit.elapsed_s * 1000:.0f} ms)"
            self.fit_label.setText(f"RMS {fit.report.get('rms_px', float('nan')):.2f} px{t}")
        self._update_tab_titles()

    # ------------------------------------------------------------------ texture
    @property
    def texture_size(self) -> int:
        """Texels per side of the next texture (setting ``texture/size``)."""
        try:
            return int(self.settings.value("texture/size", DEFAULT_TEXTURE_SIZE))
        except (TypeError, ValueError):
            return DEFAULT_TEXTURE_SIZE

    @texture_size.setter
    def texture_size(self, value: int) -> None:
        self.settings.setValue("texture/size", int(value))

    def texture_size_dialog(self) -> None:
        size, ok = QInputDialog.getInt(self, "Texture size", "Texels per side:", self.texture_size, 64, 8192, 256)
        if ok:
            self.texture_size = size

    def run_texture(self) -> bool:
        """Extract the current expression's texture in a worker, with a cancellable progress dialog."""
        if self.jobs.busy:
            self._status("a texture is already being extracted")
            return False
        try:
            inputs = self.model.texture_inputs()
        except FaceStudioError as exc:
            self.show_error("Cannot extract the texture", str(exc))
            return False
        size = self.texture_size
        vertices = inputs[2]

        def work(progress, cancel):
            return StudioModel.compute_texture(inputs, size, progress=progress, cancel=cancel), vertices

        self.jobs.start(work)
        self._texture_progress = open_progress(self, "Texture", "Extracting the texture…", self.jobs.cancel)
        self._status(f"extracting a {size}×{size} texture of {inputs[1]!r}…", 0)
        return True

    def _close_texture_progress(self):
        close_progress(self._texture_progress, self.jobs.cancel)
        self._texture_progress = None

    def _on_texture_progress(self, stage: str, fraction: float):
        update_progress(self._texture_progress, stage, fraction)

    def _on_texture_finished(self, result):
        self._close_texture_progress()
        job, vertices = result
        if not self.model.apply_texture(job, vertices):
            self._status("the expression was refitted meanwhile: the texture was discarded")
            return
        self._status(
            f"texture of {job.expression!r}: {job.report['coverage']:.1%} of the surface seen, "
            f"{job.report['extract_s']:.2f} s; it is written with the project"
        )
        self.weights_dock.show()
        self._show_weights_for_stored = False

    # ------------------------------------------------------------------ rig
    def run_build_rig(self) -> bool:
        """Build the rig of the fitted neutral in a worker (a few seconds), with a progress dialog."""
        if self.rig_jobs.busy:
            self._status("a rig is already being built")
            return False
        try:
            if self.model.project.path is None:
                raise FaceStudioError("save the project first: the rig is written next to the project file")
            compute = self.model.compute_rig()
        except FaceStudioError as exc:
            self.show_error("Cannot build the rig", str(exc))
            return False

        def work(progress, cancel):
            progress("transferring ICT-FaceKit's 51 expressions onto the neutral…", 0.1)
            return compute()

        self.rig_jobs.start(work)
        self._rig_progress = open_progress(self, "Rig", "Building the rig…", self.rig_jobs.cancel)
        self._rig_progress.setRange(0, 0)  # busy: the transfer reports no steps
        self._status("building the rig…", 0)
        return True

    def _close_rig_progress(self):
        close_progress(self._rig_progress, self.rig_jobs.cancel)
        self._rig_progress = None

    def _on_rig_finished(self, result):
        self._close_rig_progress()
        neutral, rig = result
        try:
            self.model.set_rig(neutral, rig)
        except FaceStudioError as exc:
            self.show_error("Cannot store the rig", str(exc))
            return
        self.rig_dock.show()
        self.rig_dock.raise_()
        self._status(
            f"rig of {neutral!r}: {len(rig.names)} ARKit shapes in {self.model.project.rig.file}; "
            "save the project to keep it"
        )

    def _on_rig_failed(self, message: str):
        self._close_rig_progress()
        self._status("")
        self.show_error("Building the rig failed", message)

    def _on_rig_cancelled(self):
        self._close_rig_progress()
        self._status("rig building cancelled; nothing changed")

    def _on_texture_load_failed(self, expression: str, message: str):
        self._status(f"{message}{REEXTRACT_HINT}", 20000)

    def _on_texture_failed(self, message: str):
        self._close_texture_progress()
        self._status("")
        self.show_error("The texture extraction failed", message)

    def _on_texture_cancelled(self):
        self._close_texture_progress()
        self._status("texture extraction cancelled; nothing changed")

    def set_texture_mode(self, mode: str) -> None:
        """How the 3D view draws a textured model: one of :data:`TEXTURE_MODES`."""
        if mode not in TEXTURE_MODES:
            raise ValueError(f"texture mode must be one of {TEXTURE_MODES}, got {mode!r}")
        self.texture_mode = mode
        if not self.act_tex_modes[mode].isChecked():
            self.act_tex_modes[mode].setChecked(True)
        self._on_texture_changed(self.model.expression_name)

    def _on_texture_changed(self, expression):
        if expression != self.model.expression_name:
            return
        tex = self.model.texture()
        v3 = self.view3d
        if tex is not None and self._show_weights_for_stored:  # a project opened with its textures
            self._show_weights_for_stored = False
            self.weights_dock.show()
        if tex is None or self.texture_mode == "untextured":
            v3.view_dependent = None
            v3.set_texture(None, None)
            return
        if self.texture_mode == "view_dependent":
            try:
                vd = tex.view_dependent()
            except Exception as exc:  # e.g. no OpenGL for the depth maps
                self.show_error("Cannot draw the view-dependent texture", f"{type(exc).__name__}: {exc}")
                return
            v3.texture = None
            v3.set_view_dependent(vd)
        else:
            _, faces, uv = tex.job.texture.render_mesh(tex.vertices)
            v3.view_dependent = None
            v3.set_texture(uv, tex.job.texture.image, vertex_index=tex.job.texture.seam_vertices, faces=faces)

    def show_expressions(self) -> None:
        self.expressions_dock.show()
        self.expressions_dock.raise_()
        self.expressions_view.refresh()

    # ------------------------------------------------------------------ tracking
    def show_tracking(self) -> None:
        self.tracking_dock.show()
        self.tracking_dock.raise_()

    def track_video_dialog(self) -> bool:
        """Choose a video file and track it in the tracking view (results in the default folder)."""
        if self.model.path is None:
            self.show_error("Cannot track", "save the project first: tracking reads the project file")
            return False
        if self.model.modified:  # the face model is built from the saved fits and textures
            answer = QMessageBox.question(
                self,
                "Save before tracking",
                "Tracking builds the face model from the saved project (its fitted meshes and textures). "
                "Save the changes now?",
                QMessageBox.StandardButton.Save | QMessageBox.StandardButton.Cancel,
                QMessageBox.StandardButton.Save,
            )
            if answer != QMessageBox.StandardButton.Save or not self.save():
                return False
        start = str(Path(self.model.path).parent / "video")
        path, _ = QFileDialog.getOpenFileName(
            self, "Track video", start, "Videos (*.mp4 *.avi *.mov *.mkv *.webm);;All files (*)"
        )
        if not path:
            return False
        self.show_tracking()
        ok = self.tracking_view.start_tracking(path)
        self._status(self.tracking_view.last_message, 0 if ok else 6000)
        return ok

    def _on_tracking_ended(self, *_):
        self._status(self.tracking_view.last_message, 20000)

    def open_tracking_dialog(self) -> bool:
        """Choose a tracking results folder and show it in the tracking view."""
        start = str(Path(self.model.path).parent / "results") if self.model.path is not None else ""
        folder = QFileDialog.getExistingDirectory(self, "Open tracking results", start)
        if not folder:
            return False
        self.show_tracking()
        return self.tracking_view.load_results(folder)

    def _on_edit(self, *_):
        self.fits.schedule_refit()

    def _on_project_replaced(self):
        self._show_weights_for_stored = True
        self._rebuild_tabs()
        self._update_title()
        self.setWindowModified(self.model.modified)
        self._on_fit_changed(self.model.expression_name)
        self._on_texture_changed(self.model.expression_name)  # a texture read with the project

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

    def add_dropped(self, paths, *, automatic: bool = True) -> int:
        """Photos dropped on the window: files, and folders of photos (each folder's photos in name
        order, its HEIC/raw files named: :func:`photomodel.photos.intake.gather_photo_files`); what
        cannot be added is said in one message. ``automatic``: with automatic landmarks, in the
        importer's worker (as *Add photos with automatic landmarks…*; the photos arrive when it
        finishes); otherwise the photos alone, at once. Returns how many photos were taken."""
        files, skipped, errors = gather_photo_files(paths)
        problems = [str(e) for e in errors] + skipped
        taken = 0
        if files and not automatic:
            taken = self.add_photos([str(p) for p in files])
        elif files and self.add_photos_auto([str(p) for p in files]):
            taken = len(files)
        elif files:  # the importer is busy
            problems.insert(0, "photos are still being read from the last import: drop these again when it is done")
        if problems:
            self.show_error("Some of the dropped files were not added", "\n".join(problems))
        return taken

    def closeEvent(self, event):
        if not self.maybe_save():
            event.ignore()
            return
        self.fits.shutdown()
        self.jobs.shutdown()
        self.rig_jobs.shutdown()
        self.importer.shutdown()
        self.tracking_view.jobs.shutdown()
        self.tracking_view.edit_panel.jobs.shutdown()  # an export of edited frames
        self.autosave_timer.stop()
        self._drop_recovery()  # the project was saved, discarded or unchanged: nothing left to recover
        event.accept()


def _cause(exc: BaseException) -> str:
    """An exception in words for a message box: our own errors' messages as they are, anything
    unexpected with its type; never a traceback."""
    if isinstance(exc, FaceStudioError):
        return str(exc)
    if isinstance(exc, RecursionError):
        return f"the file is nested too deeply to be read ({exc})"
    return f"{type(exc).__name__}: {exc}"


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
