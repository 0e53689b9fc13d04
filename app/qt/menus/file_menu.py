"""The *File* menu: the project file's life in the window, and photos in and out.

New, open (with recovery of a newer autosave), save, save as, recent files (``QSettings``), an
unsaved-changes prompt, and the autosave timer's work: ``<file>.autosave``, or for a never-saved
project a recovery file in the user's data folder (``QStandardPaths.AppDataLocation``, see
:mod:`app.qt.recovery`), offered at the next start. *New from photos…* / *New from video…* and
*Add photos with automatic landmarks…* run in the window's :class:`~app.qt.photo_import.PhotoImporter`;
*Add photos…* adds the photos alone, each one's starting view guessed from its file name
(:func:`guess_preset`). Every failure is shown in a dialog whose text is the cause
(e.g. ``james.facestudio.json: expressions[0].photos[2].points.nose_tip: expected [u, v] …``).
"""

from __future__ import annotations

from functools import partial
from pathlib import Path

from PySide6.QtCore import QDateTime, QLockFile, QObject
from PySide6.QtGui import QKeySequence
from PySide6.QtWidgets import QFileDialog, QMenu, QMenuBar, QMessageBox

from app.qt.menus import make_action
from app.qt.menus.texture_menu import REEXTRACT_HINT
from app.qt.recovery import default_recovery_file, default_recovery_folder, lock_recovery_file, recovery_files
from app.studio.commands import AddExpressionCommand, AddPhotosCommand, RemovePhotoCommand
from app.studio_state import IMAGE_SUFFIXES, MissingPhotos, newer_autosave, remove_autosave
from photomodel.camera import PRESET_AZIMUTH_DEG
from photomodel.errors import FaceStudioError, ProjectError
from photomodel.photos.intake import gather_photo_files
from photomodel.project import FILE_SUFFIX

MAX_RECENT = 8
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


def error_cause(exc: BaseException) -> str:
    """An exception in words for a message box: our own errors' messages as they are, anything
    unexpected with its type; never a traceback."""
    if isinstance(exc, FaceStudioError):
        return str(exc)
    if isinstance(exc, RecursionError):
        return f"the file is nested too deeply to be read ({exc})"
    return f"{type(exc).__name__}: {exc}"


class FileMenu(QObject):
    """The *File* menu of ``window`` (a :class:`~app.qt.main_window.MainWindow`) and the work behind it.

    ``recovery_file`` / ``recovery_folder``: as the window's parameters of those names.
    """

    def __init__(self, window, recovery_file=None, recovery_folder=None):
        super().__init__(window)
        self.window = window
        if recovery_file is not None:
            self.recovery_file = Path(recovery_file)
            self.recovery_folder = Path(recovery_folder) if recovery_folder is not None else self.recovery_file.parent
        else:
            self.recovery_folder = Path(recovery_folder) if recovery_folder is not None else default_recovery_folder()
            self.recovery_file = default_recovery_file(self.recovery_folder)
        self._recovery_lock: QLockFile | None = None  # held from before the first recovery autosave
        A = partial(make_action, window)
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
            lambda: window.importer.new_from_photos_dialog(),
            tip="a new project from a folder of photos, with automatic landmarks",
        )
        self.act_new_from_video = A(
            "New from &video…",
            lambda: window.importer.new_from_video_dialog(),
            tip="a new project from stills of a video of the person (the clearest, least "
            "expressive frames across the head's turn), with automatic landmarks; or, checked in the "
            "dialog, the whole chain of `facestudio auto` (fit, texture, rig, track, glb and CSV)",
        )
        self.act_add_photos_auto = A(
            "Add photos with automatic &landmarks…",
            self.add_photos_auto_dialog,
            tip="add photographs of the current expression and place their landmarks",
        )
        self.act_remove_photo = A("Remove current photo", self.remove_current_photo)
        self.act_quit = A("&Quit", window.close, QKeySequence.StandardKey.Quit)
        self.recent_menu: QMenu | None = None

    def build(self, menubar: QMenuBar) -> QMenu:
        f = menubar.addMenu("&File")
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
        return f

    @property
    def model(self):
        return self.window.model

    # ------------------------------------------------------------------ new, open
    def maybe_save(self) -> bool:
        """Ask what to do with unsaved changes; False if the user cancels."""
        if not self.model.modified:
            return True
        answer = QMessageBox.question(
            self.window,
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
                self.drop_recovery()
            return True
        return False

    def new_project(self) -> bool:
        if not self.maybe_save():
            return False
        self.window.fits.cancel()
        try:
            self.replace_project(lambda: self.model.new("untitled"))
        except Exception as exc:  # whatever went wrong, the window stays usable and says why
            self.window.show_error("Cannot start a new project", error_cause(exc))
            return False
        return True

    def replace_project(self, change) -> None:
        """Run ``change()``, which replaces the model's project (new, open, recover).

        The photo views are taken down first, so that none of them looks up a photo of the old
        project in the new one while Qt removes it from its tab; whatever ``change`` raises, the
        tabs are rebuilt for the project then open (the previous one when nothing changed).
        """
        tabs = self.window.tabs
        before, shown = self.model.project, tabs.current_view()
        shown = None if shown is None else shown.photo_id
        tabs.clear_views()
        try:
            change()
        except BaseException:
            self.window.on_project_replaced()
            if self.model.project is before and shown is not None:
                tabs.show_photo(shown)  # as it was
            raise

    def open_dialog(self) -> bool:
        start = str(self.model.path.parent) if self.model.path is not None else ""
        path, _ = QFileDialog.getOpenFileName(self.window, "Open project", start, PROJECT_FILTER)
        return bool(path) and self.open_project(path)

    def _ask_recover_autosave(self, path: Path) -> bool:
        """True when ``path`` has a newer autosave and the artist wants its changes back."""
        auto = newer_autosave(path)
        if auto is None:
            return False
        answer = QMessageBox.question(
            self.window,
            "Recover autosave",
            f"{auto.name} is newer than {path.name}: it holds changes that were not saved "
            "(e.g. before a crash). Recover them?",
            QMessageBox.StandardButton.Yes | QMessageBox.StandardButton.No,
            QMessageBox.StandardButton.Yes,
        )
        return answer == QMessageBox.StandardButton.Yes

    def _open_replacing(self, path: Path, recover: bool) -> bool:
        """Open ``path`` in the model; photos missing: ask, and open with placeholders if told
        (False when not). Errors of the file are raised."""
        self.window.fits.cancel()
        try:
            self.replace_project(lambda: self.model.open(path, recover=recover))
        except MissingPhotos as exc:
            answer = QMessageBox.question(
                self.window,
                "Missing photos",
                f"{exc}\n\nOpen the project anyway? The missing photos are shown as grey placeholders; "
                "their clicks are kept.",
                QMessageBox.StandardButton.Yes | QMessageBox.StandardButton.No,
                QMessageBox.StandardButton.No,
            )
            if answer != QMessageBox.StandardButton.Yes:
                self.window.show_status(f"{path.name} not opened: photos are missing")
                return False
            self.replace_project(lambda: self.model.open(path, recover=recover, allow_missing_photos=True))
        return True

    def open_project(self, path, *, ask_to_save: bool = True) -> bool:
        """Open a project file; on any problem say why and keep the current project."""
        if ask_to_save and not self.maybe_save():
            return False
        path = Path(path)
        recover = self._ask_recover_autosave(path)
        before = self.model.project
        try:
            if not self._open_replacing(path, recover):
                return False
        except FaceStudioError as exc:
            self.window.show_error("Cannot open the project", str(exc))
            return False
        except OSError as exc:
            self.window.show_error("Cannot open the project", f"{path}: {exc.strerror or exc}")
            return False
        except Exception as exc:  # e.g. RecursionError from a file nested thousands deep
            kept = "the previous project is still open" if self.model.project is before else "it is open as read"
            self.window.show_error("Cannot open the project", f"{path.name}: {error_cause(exc)} ({kept})")
            return False
        self.add_recent(path)
        text = f"opened {path}" + (" (recovered from the autosave)" if recover else "")
        problem = self.model.texture_problems.get(self.model.expression_name)
        if problem is not None:
            text += f"; {problem}{REEXTRACT_HINT}"
        self.window.show_status(text, 6000 if problem is None else 20000)
        return True

    # ------------------------------------------------------------------ save, autosave, recovery
    def save(self) -> bool:
        if self.model.path is None:
            return self.save_as()
        return self.save_to(self.model.path)

    def save_as(self) -> bool:
        p = self.model.project
        start = str(p.path) if p.path is not None else str(Path.cwd() / (p.name + FILE_SUFFIX))
        path, _ = QFileDialog.getSaveFileName(self.window, "Save project as", start, PROJECT_FILTER)
        if not path:
            return False
        if not path.endswith(".json"):
            path += FILE_SUFFIX
        if p.name == "untitled":
            p.name = Path(path).name.removesuffix(FILE_SUFFIX).removesuffix(".json") or "untitled"
        return self.save_to(Path(path))

    def save_to(self, path: Path) -> bool:
        """Save the project as ``path`` (no dialog); a failure is shown and False returned."""
        untitled = self.model.path is None
        try:
            written = self.model.save(path)
        except FaceStudioError as exc:
            self.window.show_error("Cannot save the project", str(exc))
            return False
        except OSError as exc:
            self.window.show_error("Cannot save the project", f"{path}: {exc.strerror or exc}")
            return False
        if untitled:  # it has a file now: its recovery file is obsolete
            self.drop_recovery()
        self.add_recent(written)
        self.window.show_status(f"saved {written}")
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
            self.window.show_status(f"autosave failed: {exc}", 10000)
            return
        if written is not None:
            self.window.show_status(f"autosaved to {written.name}", 3000)

    def offer_recovery(self) -> bool:
        """At start: offer the recovery files of never-saved projects, newest first (see
        :meth:`~app.qt.main_window.MainWindow.offer_recovery`). True if a project was recovered."""
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
            self.window,
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
            self.replace_project(lambda: self.model.recover(f))
        except Exception as exc:  # a damaged recovery file is named, never a traceback
            self.window.show_error("Cannot recover the project", f"{f}: {error_cause(exc)}")
            if lock is not None:
                lock.unlock()
            return False
        if lock is not None:  # the recovered project autosaves where it came from, still locked by us
            self.drop_recovery()
            self.recovery_file, self._recovery_lock = f, lock
        self.window.show_status(f"recovered the unsaved project from {f}")
        return True

    def drop_recovery(self) -> None:
        """Delete this window's recovery file and release its lock (saved, discarded or closed)."""
        self.recovery_file.unlink(missing_ok=True)
        if self._recovery_lock is not None:
            self._recovery_lock.unlock()
            self._recovery_lock = None

    # ------------------------------------------------------------------ recent files
    def recent_files(self) -> list[str]:
        value = self.window.settings.value("recent_files", [])
        if isinstance(value, str):
            value = [value]
        return [str(v) for v in (value or [])]

    def add_recent(self, path) -> None:
        path = str(Path(path).absolute())
        files = [f for f in self.recent_files() if f != path]
        self.window.settings.setValue("recent_files", [path, *files][:MAX_RECENT])
        self.window.settings.sync()

    def _fill_recent_menu(self):
        self.recent_menu.clear()
        files = self.recent_files()
        if not files:
            a = self.recent_menu.addAction("(none)")
            a.setEnabled(False)
        for f in files:
            self.recent_menu.addAction(f, lambda f=f: self.window.open_project(f))

    # ------------------------------------------------------------------ photos
    def add_photos_dialog(self) -> None:
        files, _ = QFileDialog.getOpenFileNames(self.window, "Add photos", "", IMAGE_FILTER)
        if files:
            self.add_photos(files)

    def add_photos_auto_dialog(self) -> None:
        files, _ = QFileDialog.getOpenFileNames(self.window, "Add photos with automatic landmarks", "", IMAGE_FILTER)
        if files:
            self.add_photos_auto(files)

    def add_photos_auto(self, files) -> bool:
        """Add image files to the current expression (made ``neutral`` when there is none) with
        automatic landmarks, in the importer's worker; False when an import is running."""
        if self.window.importer.busy:
            return False
        if self.model.expression_name is None:
            self.window.undo_stack.push(AddExpressionCommand(self.model, "neutral"))
        return self.window.importer.add_photos(files)

    def add_photos(self, files) -> int:
        """Add image files to the current expression; unreadable ones are named in one message."""
        if self.model.expression_name is None:
            self.window.undo_stack.push(AddExpressionCommand(self.model, "neutral"))
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
            self.window.undo_stack.push(AddPhotosCommand(self.model, expr, photos))
            self.window.show_photo(photos[0].id)
            self.window.show_status(
                f"added {len(photos)} photo(s); set each one's view in the toolbar if the guess is wrong"
            )
        if problems:
            self.window.show_error("Cannot add photos", "\n".join(problems))
        return len(photos)

    def add_dropped(self, paths, *, automatic: bool = True) -> int:
        """Photos dropped on the window (see :meth:`~app.qt.main_window.MainWindow.add_dropped`)."""
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
            self.window.show_error("Some of the dropped files were not added", "\n".join(problems))
        return taken

    def remove_current_photo(self):
        view = self.window.current_view()
        if view is not None:
            self.window.undo_stack.push(RemovePhotoCommand(self.model, view.expression, view.photo_id))
