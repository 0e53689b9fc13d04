"""*Fit → Add scan…*: a 3D scan of the head (PLY, OBJ, STL; holes, noise and stray points allowed)
fitted as the neutral's fit, as ``facestudio fit-scan`` does.

The scan is fitted in a :class:`~app.qt.workers.JobController` worker behind a cancellable
progress dialog (:meth:`app.studio_state.StudioModel.scan_fit_job`); the result becomes the first
expression's fit through an undoable :class:`~app.studio.commands.ScanFitCommand` (the clicks and
curves are not touched; *Edit → Undo* puts the previous fit back) and is shown in the 3D view.
The scan's unit is guessed from its size and where it lies does not matter (module notes of
:mod:`photomodel.prior.scan_expression`); the status bar names the unit taken. A file that cannot
be read or holds no face is said in a dialog, and nothing changes.
"""

from __future__ import annotations

from pathlib import Path

from PySide6.QtCore import QObject
from PySide6.QtWidgets import QFileDialog, QProgressDialog

from app.qt.menus import make_action
from app.qt.progress import close_progress, update_progress
from app.studio.commands import ScanFitCommand
from photomodel.errors import FaceStudioError

#: The file dialog's filter: the formats :func:`photomodel.prior.scan_fit.read_scan` reads.
SCAN_FILTER = "3D scans (*.ply *.obj *.stl);;All files (*)"


class AddScan(QObject):
    """The *Add scan…* action of the *Fit* menu of ``window`` and its worker."""

    def __init__(self, window):
        super().__init__(window)
        self.window = window
        self.jobs = window.scan_jobs
        self.progress_dialog: QProgressDialog | None = None
        self.last_message = ""  # the status message of the last scan fit (tests read it)
        self.act_add_scan = make_action(
            window,
            "Add &scan…",
            self.add_scan_dialog,
            tip="fit the neutral to a 3D scan of the head (PLY, OBJ, STL; holes, noise allowed), as `fit-scan`",
        )

    def connect_worker(self) -> None:
        self.jobs.progress.connect(lambda stage, f: update_progress(self.progress_dialog, stage, f))
        self.jobs.finished.connect(self._on_finished)
        self.jobs.failed.connect(self._on_failed)
        self.jobs.cancelled.connect(self._on_cancelled)

    def add_scan_dialog(self) -> bool:
        """Choose a scan file and fit it (:meth:`add_scan`)."""
        start = str(Path(self.window.model.path).parent) if self.window.model.path is not None else ""
        path, _ = QFileDialog.getOpenFileName(self.window, "Add scan", start, SCAN_FILTER)
        return bool(path) and self.add_scan(path)

    def add_scan(self, path) -> bool:
        """Fit the scan file ``path`` as the neutral's fit in the worker, with a progress dialog;
        False (and why, in a dialog or the status bar) when it cannot start."""
        window = self.window
        if self.jobs.busy:
            window.show_status("a scan is already being fitted")
            return False
        try:
            job = window.model.scan_fit_job(path)
        except FaceStudioError as exc:
            window.show_error("Cannot fit the scan", str(exc))
            return False
        if window.fits.busy:  # a photo fit finishing after the scan's would replace it
            window.fits.cancel()
            window.fits.wait(10.0)
        self.jobs.start(job)
        self.progress_dialog = window.open_progress("Add scan", f"Fitting {Path(path).name}…", self.jobs.cancel)
        window.show_status(f"fitting {Path(path).name}…", 0)
        return True

    def _close_progress(self) -> None:
        close_progress(self.progress_dialog, self.jobs.cancel)
        self.progress_dialog = None

    def _on_finished(self, made) -> None:
        self._close_progress()
        window, model = self.window, self.window.model
        window.undo_stack.push(ScanFitCommand(model, made))
        model.set_expression(made.expression)
        r = made.report
        self.last_message = (
            f"{made.expression!r} fitted to {Path(r['scan']).name}: its unit taken as {r['unit']} from its size, "
            f"{r['face_inliers']:.0%} of the face on the scan, {r['seconds']:.1f} s; Edit → Undo puts the "
            "previous fit back"
        )
        window.show_status(self.last_message, 20000)

    def _on_failed(self, message: str) -> None:
        self._close_progress()
        self.last_message = message
        self.window.show_status("")
        self.window.show_error("Cannot fit the scan", message)

    def _on_cancelled(self) -> None:
        self._close_progress()
        self.last_message = "scan fit cancelled; nothing changed"
        self.window.show_status(self.last_message)
