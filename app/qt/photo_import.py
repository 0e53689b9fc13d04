"""Photos in with automatic landmarks: *File → New from photos…*, *New from video…* and *Add
photos…*, in a worker.

Both call the Qt-free core of ``facestudio new`` (:mod:`photomodel.photos.intake`: photos read and
checked, a face found in each, landmarks placed, the view estimated) in a
:class:`~app.qt.workers.JobController` worker behind the shared cancellable progress dialog, so
the window stays responsive over a folder of large photos. Cancel takes effect after the photo
being read (the core reports progress once a photo); the project is untouched then.

* **New from photos…** asks for a folder and where to save the project, writes the project with
  the core function, then opens it (the clicks it placed are automatic: violet diamonds in the
  photo views, see :mod:`app.qt.photo_view`).
* **New from video…** opens :class:`~app.qt.new_from_video.NewFromVideoDialog` (the clip, where the
  project goes, the stills) and makes the project as ``facestudio new --video`` does
  (:func:`photomodel.photos.stills.new_project_from_video`: stills picked where the face is clear
  and least expressive across the head's turn, written beside the project), then opens it. Cancel
  while the clip is looked at writes nothing; later, the stills written are removed again. With
  its checkbox *Track the whole clip and build the rig* it runs ``facestudio auto``'s chain instead
  (:class:`~app.qt.new_from_video.AutoChainRunner`).
* **Add photos…** (and photos dropped on the window) adds the photos to the current expression
  of a snapshot of the project; the new photos — with their automatic clicks — go into the
  studio as one undoable edit (the feature definitions they need, then the photos: one undo
  takes both back). A project with no photo yet first gets the features ``facestudio new``
  starts with (:func:`~photomodel.photos.intake.default_features`: the 68 points the detector
  places), so photos dropped on a new studio window are clicked as ``new`` would click them.

A photo without a face, or with several (the largest is used), is named in the status bar; the
core's warnings (two views of the same image …) likewise. A photo that cannot be read (truncated,
not an image) is left out of *Add photos…* and named, the others added; when none could be, a
message says why. (*New from photos…* and the command line refuse the whole set instead, naming
the file: nothing half-made is written.)
"""

from __future__ import annotations

from pathlib import Path

from PySide6.QtCore import QObject
from PySide6.QtWidgets import QFileDialog

from app.qt.new_from_video import AutoChainRunner, NewFromVideoDialog
from app.qt.progress import close_progress, update_progress
from app.qt.workers import JobController
from app.studio.commands import AddPhotosCommand, DefineFeaturesCommand
from photomodel.errors import Cancelled
from photomodel.photos.intake import add_photos, default_features, new_project_from_photos
from photomodel.photos.stills import new_project_from_video
from photomodel.project import FILE_SUFFIX, save_project


class PhotoImporter(QObject):
    """The two photo imports of a :class:`~app.qt.main_window.MainWindow`, one at a time."""

    def __init__(self, window):
        super().__init__(window)
        self.window = window
        self.jobs = JobController(window.model, self)
        self.jobs.progress.connect(lambda stage, frac: update_progress(self._dialog, stage, frac))
        self.jobs.finished.connect(self._on_finished)
        self.jobs.failed.connect(self._on_failed)
        self.jobs.cancelled.connect(self._on_cancelled)
        self._dialog = None
        self._pending = None  # what the running job's result is for
        self.auto = AutoChainRunner(window)  # New from video… with the whole chain
        self.video_dialog: NewFromVideoDialog | None = None  # the last New from video… dialog opened

    @property
    def busy(self) -> bool:
        return self.jobs.busy or self.auto.busy

    # ------------------------------------------------------------------ new project
    def new_from_photos_dialog(self) -> bool:
        folder = QFileDialog.getExistingDirectory(self.window, "New project from a folder of photos")
        if not folder:
            return False
        path = self._ask_project_path(Path(folder).parent / (Path(folder).name + FILE_SUFFIX))
        return path is not None and self.new_from_photos(folder, path)

    def new_from_photos(self, folder, path) -> bool:
        """Make a project of every photo in ``folder`` with automatic landmarks, save it as
        ``path`` and open it; in the worker, with progress and cancel."""
        path = self._new_project_path(path)
        if path is None:
            return False
        folder = Path(folder)
        features, curves = default_features(self.window.model.mesh)

        def work(progress, cancel):
            project, warnings = new_project_from_photos(
                folder, path, features=features, curves=curves, progress=_cancellable(progress, cancel)
            )
            save_project(project, path)  # a new file nobody else has open
            return warnings

        return self._start(work, ("new", path), f"Reading the photos of {folder.name}…")

    def new_from_video_dialog(self) -> NewFromVideoDialog | None:
        """Open the *New from video…* dialog (window-modal, not blocking); its OK makes the project
        of stills, or runs the whole chain (:meth:`start_from_dialog`). None when an import runs."""
        if self.busy:
            return None
        dialog = NewFromVideoDialog(self.window)
        dialog.accepted.connect(lambda: self.start_from_dialog(dialog))
        dialog.finished.connect(dialog.deleteLater)
        self.video_dialog = dialog
        dialog.open()
        return dialog

    def start_from_dialog(self, dialog: NewFromVideoDialog) -> bool:
        """What the accepted *New from video…* dialog asks for: the chain of ``facestudio auto``
        (:class:`~app.qt.new_from_video.AutoChainRunner`) or a project of stills."""
        clip, target = dialog.clip(), dialog.target()
        if dialog.whole_chain():
            return self.auto.start(clip, target, stills=dialog.stills(), max_frames=dialog.max_frames())
        return self.new_from_video(clip, target, count=dialog.stills())

    def new_from_video(self, clip, path, count: int = 5) -> bool:
        """Make a project of up to ``count`` stills of ``clip`` with automatic landmarks, save it
        as ``path`` and open it; in the worker, with progress and cancel."""
        path = self._new_project_path(path)
        if path is None:
            return False
        clip = Path(clip)
        features, curves = default_features(self.window.model.mesh)

        def work(progress, cancel):
            _, warnings, summary = new_project_from_video(
                clip, path, features=features, curves=curves, count=count, progress=_cancellable(progress, cancel)
            )
            frames = ", ".join(str(st["frame"]) for st in summary["stills"])
            return [
                f"stills: frames {frames} ({summary['frames_occluded']} of {summary['frames_looked_at']} "
                "frames looked at were occluded)",
                *warnings,
            ]

        return self._start(work, ("new", path), f"Looking at {clip.name} for stills…")

    def _ask_project_path(self, default: Path) -> Path | None:
        """Where to save a new project (the save dialog, starting at ``default``); None if cancelled."""
        path, _ = QFileDialog.getSaveFileName(
            self.window, "Save the new project as", str(default), f"Face Studio project (*{FILE_SUFFIX})"
        )
        return Path(path) if path else None

    def _new_project_path(self, path) -> Path | None:
        """``path`` with the project suffix, or None when an import runs or the open project's
        changes are not settled (saved or discarded)."""
        if self.busy or not self.window.maybe_save():
            return None
        path = Path(path)
        return path if path.name.endswith(FILE_SUFFIX) else path.with_name(path.name + FILE_SUFFIX)

    # ------------------------------------------------------------------ photos added
    def add_photos(self, files) -> bool:
        """Add image files to the current expression with automatic landmarks (worker)."""
        model = self.window.model
        if self.busy or model.expression_name is None:
            return False
        snapshot, expression = model.fit_snapshot(), model.expression_name
        if not any(e.photos for e in snapshot.expressions):
            # a project without photos yet gets the features `facestudio new` starts with (the
            # 68 points the detector places), defined with the photos in one undoable step
            have = {f.name for f in snapshot.features}
            snapshot.features += [f for f in default_features(model.mesh)[0] if f.name not in have]
        before = {p.id for p in snapshot.expression(expression).photos}
        files = [Path(f) for f in files]

        def work(progress, cancel):
            # a drop of many files: one that cannot be read is named, the others still come in
            warnings = add_photos(
                snapshot, expression, files, progress=_cancellable(progress, cancel), skip_unreadable=True
            )
            new = [p for p in snapshot.expression(expression).photos if p.id not in before]
            return snapshot, new, warnings

        return self._start(work, ("add", model.project, expression), f"Placing landmarks on {len(files)} photo(s)…")

    # ------------------------------------------------------------------ the worker
    def _start(self, work, pending, label: str) -> bool:
        if self.jobs.start(work) is None:
            return False
        self._pending = pending
        self._dialog = self.window.open_progress("Photos", label, self.jobs.cancel)
        return True

    def _close(self):
        close_progress(self._dialog, self.jobs.cancel)
        self._dialog = None

    def _on_finished(self, result):
        self._close()
        pending, self._pending = self._pending, None
        if pending[0] == "new":
            if self.window.open_project(pending[1], ask_to_save=False):
                self.window.show_status(_summary(result, "new project"), 15000)
            return
        _, project, expression = pending
        snapshot, photos, warnings = result
        model = self.window.model
        if project is not model.project:
            return
        if not photos:
            self.window.show_error("No photo added", "\n".join(warnings))  # each file's reason
            return
        missing = [f for f in snapshot.features if not model.has_feature(f.name)]
        stack = self.window.undo_stack
        stack.begin_macro(f"Add {len(photos)} photo(s) with automatic landmarks")
        if missing:
            stack.push(DefineFeaturesCommand(model, missing))
        stack.push(AddPhotosCommand(model, expression, photos))
        stack.end_macro()
        self.window.show_photo(photos[0].id)
        self.window.show_status(_summary(warnings, f"{len(photos)} photo(s) added"), 15000)

    def _on_failed(self, message: str):
        self._close()
        self._pending = None
        self.window.show_error("Cannot read the photos", message)

    def _on_cancelled(self):
        self._close()
        self._pending = None
        self.window.show_status("cancelled; nothing changed")

    def shutdown(self):
        self.jobs.shutdown()
        self.auto.shutdown()


def _cancellable(progress, cancel):
    """The core's ``progress(label, fraction)`` that also stops the intake when cancelled."""

    def report(label: str, fraction: float) -> None:
        if cancel():
            raise Cancelled("photo intake cancelled")
        progress(label, fraction)

    return report


def _summary(warnings: list[str], what: str) -> str:
    """The core's warnings (no face, several faces, duplicates) in one status line."""
    return what + (
        "; " + "; ".join(map(str, warnings))
        if warnings
        else "; automatic clicks are violet: drag the ones that are off, then Fit"
    )
