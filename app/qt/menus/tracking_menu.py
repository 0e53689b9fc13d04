"""The *Tracking* menu (§6.2): the first pose of a video, a video tracked in the tracking view
(:class:`~app.qt.tracking_view.TrackingView`: the footage with the model overlaid, a frame scrubber,
the parameter curves), tracking results opened from a folder, and another project's performance
cloned onto this face (:class:`~app.qt.clone_dialog.CloneDialog`)."""

from __future__ import annotations

from functools import partial
from pathlib import Path

from PySide6.QtCore import QObject
from PySide6.QtWidgets import QFileDialog, QMenu, QMenuBar, QMessageBox

from app.qt.clone_dialog import CloneDialog
from app.qt.menus import make_action


class TrackingMenu(QObject):
    """The *Tracking* menu of ``window`` (a :class:`~app.qt.main_window.MainWindow`)."""

    def __init__(self, window):
        super().__init__(window)
        self.window = window
        A = partial(make_action, window)
        self.act_track_video = A(
            "&Track video…",
            self.track_video_dialog,
            tip="estimate head pose and expression weights in every frame of a video (§6.2)",
        )
        self.act_first_pose = A(
            "Set &first pose…",
            lambda: window.tracking_view.first_pose_dialog(),
            tip="click the pose features in frame 0 of a video (the pose tracking starts from)",
        )
        self.act_open_tracking = A(
            "&Open results…", self.open_tracking_dialog, tip="show the tracking results of a folder (its track.json)"
        )
        self.act_clone = A(
            "&Clone from another project…",
            lambda: self.clone_dialog(),
            tip="another person's tracked performance on this face (facestudio clone), the two side by side",
        )
        self.clone_dialog_widget = None

    def build(self, menubar: QMenuBar) -> QMenu:
        tr = menubar.addMenu("T&racking")
        tr.addAction(self.act_first_pose)
        tr.addAction(self.act_track_video)
        tr.addAction(self.act_open_tracking)
        tr.addSeparator()
        tr.addAction(self.act_clone)
        return tr

    def connect_worker(self) -> None:
        """The status bar's "tracking … into …" is replaced by how the run ended (after the
        tracking view, connected first, has written its ``last_message``)."""
        track = self.window.tracking_view.jobs
        for ended in (track.finished, track.failed, track.cancelled):
            ended.connect(self._on_tracking_ended)

    def show_tracking(self) -> None:
        self.window.tracking_dock.show()
        self.window.tracking_dock.raise_()

    def _saved(self, cannot: str, what: str) -> bool:
        """Whether the project file is saved and up to date (asking to save changes): ``what`` (tracking,
        cloning) builds the face model from the saved fits and textures."""
        window, model = self.window, self.window.model
        if model.path is None:
            window.show_error(cannot, f"save the project first: {what} reads the project file")
            return False
        if model.modified:
            answer = QMessageBox.question(
                window,
                f"Save before {what}",
                f"{what.capitalize()} builds the face model from the saved project (its fitted meshes and "
                "textures). Save the changes now?",
                QMessageBox.StandardButton.Save | QMessageBox.StandardButton.Cancel,
                QMessageBox.StandardButton.Save,
            )
            if answer != QMessageBox.StandardButton.Save or not window.save():
                return False
        return True

    def clone_dialog(self, modal: bool = True):
        """Open :class:`~app.qt.clone_dialog.CloneDialog` on the saved project; ``modal`` runs it with
        ``exec()``, otherwise it is shown and returned (tests). None when the project is not saved."""
        if not self._saved("Cannot clone", "cloning"):
            return None
        dlg = self.clone_dialog_widget = CloneDialog(self.window)
        if modal:
            dlg.exec()
        else:
            dlg.show()
        return dlg

    def track_video_dialog(self) -> bool:
        """Choose a video file and track it in the tracking view (results in the default folder)."""
        window, model = self.window, self.window.model
        if not self._saved("Cannot track", "tracking"):
            return False
        start = str(Path(model.path).parent / "video")
        path, _ = QFileDialog.getOpenFileName(
            window, "Track video", start, "Videos (*.mp4 *.avi *.mov *.mkv *.webm);;All files (*)"
        )
        if not path:
            return False
        self.show_tracking()
        ok = window.tracking_view.start_tracking(path)
        window.show_status(window.tracking_view.last_message, 0 if ok else 6000)
        return ok

    def _on_tracking_ended(self, *_):
        self.window.show_status(self.window.tracking_view.last_message, 20000)

    def open_tracking_dialog(self) -> bool:
        """Choose a tracking results folder and show it in the tracking view."""
        model = self.window.model
        start = str(Path(model.path).parent / "results") if model.path is not None else ""
        folder = QFileDialog.getExistingDirectory(self.window, "Open tracking results", start)
        if not folder:
            return False
        self.show_tracking()
        return self.window.tracking_view.load_results(folder)
