"""The *Rig* menu: *Build rig* makes the rig of the fitted neutral (``facestudio rig``: ARKit's
blend shapes) in a worker and writes it next to the project (``results/rig.npz``; the project file
records it when saved); the *Rig* dock (:class:`~app.qt.rig_panel.RigPanel`) lists the project's
blend shapes with a slider each, posing the 3D view."""

from __future__ import annotations

from PySide6.QtCore import QObject
from PySide6.QtWidgets import QMenu, QMenuBar, QProgressDialog

from app.qt.menus import make_action
from app.qt.progress import close_progress
from photomodel.errors import FaceStudioError


class RigMenu(QObject):
    """The *Rig* menu of ``window`` (a :class:`~app.qt.main_window.MainWindow`)."""

    def __init__(self, window):
        super().__init__(window)
        self.window = window
        self.jobs = window.rig_jobs
        self.progress_dialog: QProgressDialog | None = None
        self.act_build_rig = make_action(
            window,
            "&Build rig",
            self.run_build_rig,
            tip="ARKit's blend shapes on the fitted neutral (as `facestudio rig`), written next to the project",
        )

    def build(self, menubar: QMenuBar) -> QMenu:
        rg = menubar.addMenu("R&ig")
        rg.addAction(self.act_build_rig)
        rg.addAction(self.window.rig_dock.toggleViewAction())
        return rg

    def connect_worker(self) -> None:
        self.jobs.finished.connect(self._on_rig_finished)
        self.jobs.failed.connect(self._on_rig_failed)
        self.jobs.cancelled.connect(self._on_rig_cancelled)

    def run_build_rig(self) -> bool:
        """Build the rig of the fitted neutral in a worker (a few seconds), with a progress dialog."""
        window, model = self.window, self.window.model
        if self.jobs.busy:
            window.show_status("a rig is already being built")
            return False
        try:
            if model.project.path is None:
                raise FaceStudioError("save the project first: the rig is written next to the project file")
            compute = model.compute_rig()
        except FaceStudioError as exc:
            window.show_error("Cannot build the rig", str(exc))
            return False

        def work(progress, cancel):
            progress("transferring ICT-FaceKit's 51 expressions onto the neutral…", 0.1)
            return compute()

        self.jobs.start(work)
        self.progress_dialog = window.open_progress("Rig", "Building the rig…", self.jobs.cancel)
        self.progress_dialog.setRange(0, 0)  # busy: the transfer reports no steps
        window.show_status("building the rig…", 0)
        return True

    def _close_rig_progress(self):
        close_progress(self.progress_dialog, self.jobs.cancel)
        self.progress_dialog = None

    def _on_rig_finished(self, result):
        self._close_rig_progress()
        neutral, rig = result
        window = self.window
        try:
            window.model.set_rig(neutral, rig)
        except FaceStudioError as exc:
            window.show_error("Cannot store the rig", str(exc))
            return
        window.rig_dock.show()
        window.rig_dock.raise_()
        window.show_status(
            f"rig of {neutral!r}: {len(rig.names)} ARKit shapes in {window.model.project.rig.file}; "
            "save the project to keep it"
        )

    def _on_rig_failed(self, message: str):
        self._close_rig_progress()
        self.window.show_status("")
        self.window.show_error("Building the rig failed", message)

    def _on_rig_cancelled(self):
        self._close_rig_progress()
        self.window.show_status("rig building cancelled; nothing changed")
