"""*File → New from video…*: the dialog, and the whole chain of ``facestudio auto`` it can run.

:class:`NewFromVideoDialog` asks for the clip, where the project goes, how many stills, and has a
checkbox **Track the whole clip and build the rig** (off by default):

* off — stills picked from the clip, given automatic landmarks, saved as the project and opened
  (:meth:`app.qt.photo_import.PhotoImporter.new_from_video`, ``facestudio new --video``);
* on — the chain of ``facestudio auto`` (:func:`tracking.auto_pipeline.run_auto`, not a copy of it):
  stills, cameras and mesh fitted, textured, rigged with the 51 ARKit shapes, the clip tracked in
  ARKit terms, the animated glb and the Live Link CSV exported — into one folder (the project, every
  intermediate result, ``<clip>.glb``, ``<clip>.csv``), the folder ``auto --out`` would take.
  :class:`AutoChainRunner` runs it in its own :class:`~app.qt.workers.JobController` worker behind
  one progress dialog that names the stage (``2 of 6 · fit — cameras and mesh`` and the stage's
  own step), then opens the project.

Cancel is ``auto``'s Ctrl-C: while tracking, the track stops after the frame and is saved; before
(stills, fit, texture) the stage under way is dropped, what earlier stages wrote is kept; between
stages nothing is lost. Either way the project left in the folder (when the stills were made) is
opened, and running the chain again on the same clip and folder — or ``facestudio auto CLIP --out
DIR`` — resumes: stages done are not run again, the track goes on after its last saved frame.
"""

from __future__ import annotations

from pathlib import Path

from PySide6.QtCore import QObject
from PySide6.QtWidgets import (
    QCheckBox,
    QDialog,
    QDialogButtonBox,
    QFileDialog,
    QFormLayout,
    QHBoxLayout,
    QLabel,
    QLineEdit,
    QPushButton,
    QSpinBox,
    QVBoxLayout,
    QWidget,
)

from app.qt.progress import close_progress, update_progress
from app.qt.workers import JobController
from photomodel.errors import Cancelled
from photomodel.project import FILE_SUFFIX
from tracking.auto_pipeline import STAGES, run_auto

__all__ = ["AUTO_CHECKBOX", "STAGE_TITLES", "AutoChainRunner", "NewFromVideoDialog", "stage_label"]

#: The video files the dialog offers (anything OpenCV decodes is read).
VIDEO_FILTER = "Videos (*.mp4 *.mov *.avi *.mkv *.webm *.m4v);;All files (*)"
#: The checkbox's text.
AUTO_CHECKBOX = "Track the whole clip and build the rig"
#: What each stage of :data:`tracking.auto_pipeline.STAGES` does, in the progress dialog's words.
STAGE_TITLES = {
    "stills": "stills picked from the clip",
    "fit": "cameras and mesh",
    "texture": "texture",
    "rig": "rig: the 51 ARKit shapes",
    "track": "the clip tracked in ARKit terms",
    "export": "animated glb and Live Link CSV",
}
#: Stages whose work :func:`run_auto` saves only when the stage ends: a cancel stops them at once
#: (as ``auto``'s second Ctrl-C does), the earlier stages' results kept. The track saves as it goes
#: and is stopped after its frame through ``run_auto(cancel=)`` instead.
_STOP_AT_ONCE = ("stills", "fit", "texture")


def stage_label(stage: str, detail: str = "") -> str:
    """The progress dialog's text for ``stage`` (a name of :data:`STAGES`) and its step ``detail``:
    ``"2 of 6 · fit — cameras and mesh\\nneutral: solving cameras"``."""
    names = [name for name, _ in STAGES]
    head = f"{names.index(stage) + 1} of {len(names)} · {stage} — {STAGE_TITLES.get(stage, stage)}"
    return head + (f"\n{detail}" if detail else "")


def auto_folder(clip: Path) -> Path:
    """The folder ``facestudio auto CLIP`` writes by default: ``<clip stem>_auto`` beside the clip."""
    return clip.with_name(f"{clip.stem}_auto")


def auto_project(clip: Path, folder: Path) -> Path:
    """The project file :func:`run_auto` writes in ``folder`` for ``clip``."""
    return folder / f"{clip.stem}{FILE_SUFFIX}"


class NewFromVideoDialog(QDialog):
    """The clip, where the project goes, the stills, and whether to run the whole chain.

    The path field is the project file when the checkbox is off, the folder of the project and
    every result when it is on; each is filled in from the clip (beside it) until the artist
    edits it.
    """

    def __init__(self, parent: QWidget | None = None, clip: str | Path | None = None):
        super().__init__(parent)
        self.setWindowTitle("New project from a video of the person")
        self.clip_edit = QLineEdit()
        self.clip_edit.setPlaceholderText("a phone clip of one face (anything OpenCV decodes)")
        self.clip_button = QPushButton("Browse…")
        self.path_label = QLabel()
        self.path_edit = QLineEdit()
        self.path_button = QPushButton("Browse…")
        self.stills_box = QSpinBox()
        self.stills_box.setRange(2, 20)
        self.stills_box.setValue(5)
        self.stills_box.setToolTip("frames picked from the clip for the fit: the clearest, least expressive ones")
        self.auto_box = QCheckBox(AUTO_CHECKBOX)
        self.auto_box.setToolTip(
            "as `facestudio auto`: fit, texture, rig with the 51 ARKit shapes, track every frame in ARKit "
            "terms, export an animated glb and a Live Link CSV; a cancelled run resumes"
        )
        self.frames_box = QSpinBox()
        self.frames_box.setRange(0, 1_000_000)
        self.frames_box.setSpecialValueText("whole clip")
        self.frames_box.setToolTip("track only the first frames (a quick look); the whole clip by default")
        self.note = QLabel()
        self.note.setWordWrap(True)
        self.buttons = QDialogButtonBox(QDialogButtonBox.StandardButton.Ok | QDialogButtonBox.StandardButton.Cancel)
        self._path_edited = False
        self._layout()
        self.clip_button.clicked.connect(self._browse_clip)
        self.path_button.clicked.connect(self._browse_path)
        self.clip_edit.textChanged.connect(self._clip_changed)
        self.path_edit.textEdited.connect(self._mark_path_edited)
        self.auto_box.toggled.connect(self._auto_toggled)
        self.buttons.accepted.connect(self.accept)
        self.buttons.rejected.connect(self.reject)
        self._auto_toggled(False)
        if clip is not None:
            self.clip_edit.setText(str(clip))

    def _layout(self) -> None:
        form = QFormLayout()
        row = QHBoxLayout()
        row.addWidget(self.clip_edit, 1)
        row.addWidget(self.clip_button)
        form.addRow("Clip:", row)
        row = QHBoxLayout()
        row.addWidget(self.path_edit, 1)
        row.addWidget(self.path_button)
        form.addRow(self.path_label, row)
        form.addRow("Stills:", self.stills_box)
        form.addRow(self.auto_box)
        form.addRow("Frames to track:", self.frames_box)
        box = QVBoxLayout(self)
        box.addLayout(form)
        box.addWidget(self.note)
        box.addWidget(self.buttons)
        self.setMinimumWidth(560)

    # ------------------------------------------------------------------ what was asked
    def clip(self) -> Path | None:
        text = self.clip_edit.text().strip()
        return Path(text) if text else None

    def whole_chain(self) -> bool:
        return self.auto_box.isChecked()

    def target(self) -> Path | None:
        """The project file (checkbox off) or the folder of everything (on)."""
        text = self.path_edit.text().strip()
        return Path(text) if text else None

    def stills(self) -> int:
        return self.stills_box.value()

    def max_frames(self) -> int | None:
        return self.frames_box.value() or None

    # ------------------------------------------------------------------ reactions
    def _default_target(self) -> Path | None:
        clip = self.clip()
        if clip is None or not clip.stem:  # "/" while a path is typed
            return None
        return auto_folder(clip) if self.whole_chain() else clip.with_name(clip.stem + FILE_SUFFIX)

    def _fill_target(self) -> None:
        default = self._default_target()
        if not self._path_edited and default is not None:
            self.path_edit.setText(str(default))
        self._update_state()

    def _clip_changed(self, _text: str) -> None:
        self._fill_target()

    def _mark_path_edited(self, _text: str) -> None:
        self._path_edited = True
        self._update_state()

    def _auto_toggled(self, on: bool) -> None:
        self.path_label.setText("Project folder:" if on else "Project file:")
        self.frames_box.setEnabled(on)
        self._path_edited = False  # a file and a folder: the other kind's default
        self._fill_target()

    def _update_state(self) -> None:
        clip, target = self.clip(), self.target()
        ok = clip is not None and clip.exists() and target is not None
        self.buttons.button(QDialogButtonBox.StandardButton.Ok).setEnabled(ok)
        if clip is not None and not clip.exists():
            self.note.setText(f"<i>{clip}: no such clip</i>")
        elif self.whole_chain():
            self.note.setText(
                "<i>The project, every intermediate result, the animated glb and the Live Link CSV go in this "
                "folder; a run cancelled there resumes where it stopped. Tracking takes about a second a frame.</i>"
            )
        else:
            self.note.setText("<i>Stills with automatic landmarks; fit, texture, rig and track from the menus.</i>")

    def _browse_clip(self) -> None:
        clip, _ = QFileDialog.getOpenFileName(self, "A video of the person", self.clip_edit.text(), VIDEO_FILTER)
        if clip:
            self.clip_edit.setText(clip)

    def _browse_path(self) -> None:
        start = self.path_edit.text()
        if self.whole_chain():
            path = QFileDialog.getExistingDirectory(self, "Folder of the project and every result", start)
        else:
            path, _ = QFileDialog.getSaveFileName(
                self, "Save the new project as", start, f"Face Studio project (*{FILE_SUFFIX})"
            )
        if path:
            self._path_edited = True
            self.path_edit.setText(path)


class AutoChainRunner(QObject):
    """Runs :func:`tracking.auto_pipeline.run_auto` for a :class:`~app.qt.main_window.MainWindow`
    in a worker, behind one progress dialog naming the stage, and opens the project it leaves.

    Attributes
    ----------
    stages_seen : the stage names reported by the running (or last) chain, in order.
    result : the last finished chain's :class:`~tracking.auto_pipeline.AutoResult` (None before).
    """

    def __init__(self, window):
        super().__init__(window)
        self.window = window
        self.jobs = JobController(window.model, self)
        self.jobs.progress.connect(self._on_progress)
        self.jobs.finished.connect(self._on_finished)
        self.jobs.failed.connect(self._on_failed)
        self.jobs.cancelled.connect(self._on_cancelled)
        self.dialog = None
        self.stages_seen: list[str] = []
        self.result = None
        self._pending = None  # (clip, folder, project file, the model's generation when it started)
        self._cancel_asked = False

    @property
    def busy(self) -> bool:
        return self.jobs.busy

    def start(self, clip, folder=None, *, stills: int = 5, max_frames: int | None = None) -> bool:
        """Run the chain on ``clip`` into ``folder`` (default ``<clip stem>_auto`` beside it); False
        when a chain runs or the open project's changes are not settled (saved or discarded)."""
        if self.busy or not self.window.maybe_save():
            return False
        clip = Path(clip)
        folder = Path(folder) if folder is not None else auto_folder(clip)
        project = auto_project(clip, folder)
        model = self.window.model
        if model.path is not None and Path(model.path).absolute() == project.absolute():
            # the chain writes this file: the studio must not hold (and autosave) an older copy meanwhile
            self.window.file_menu.replace_project(lambda: model.new("untitled"))
        state = {"stage": None}

        def work(progress, cancel):
            def report(stage: str, fraction: float, detail: str = "") -> None:
                state["stage"] = stage
                if stage in _STOP_AT_ONCE and cancel():
                    raise Cancelled(f"auto cancelled during {stage}")
                progress(stage_label(stage, detail), fraction)

            try:
                return run_auto(clip, folder, stills=stills, max_frames=max_frames, progress=report, cancel=cancel)
            except KeyboardInterrupt:  # run_auto's Ctrl-C: what the stages did is saved
                raise Cancelled(f"auto cancelled after {state['stage']}") from None

        if self.jobs.start(work) is None:
            return False
        self.stages_seen, self.result, self._cancel_asked = [], None, False
        self._pending = (clip, folder, project, model.generation)
        self.dialog = self.window.open_progress("New from video", stage_label("stills"), self.cancel)
        self.dialog.setMinimumWidth(480)
        return True

    def cancel(self) -> None:
        """Stop the chain: after the tracked frame, or at once before tracking (see the module notes)."""
        if self.busy:
            self._cancel_asked = True
            self.jobs.cancel()
            self.window.show_status("stopping the chain after this step; what is done is kept", 0)

    def wait(self, timeout_s: float = 30.0) -> bool:
        return self.jobs.wait(timeout_s)

    def _on_progress(self, label: str, fraction: float) -> None:
        stage = label.split(" · ", 1)[1].split(" ", 1)[0]
        if not self.stages_seen or self.stages_seen[-1] != stage:
            self.stages_seen.append(stage)
        update_progress(self.dialog, label, fraction)

    def _close(self):
        close_progress(self.dialog, self.cancel)
        self.dialog = None
        pending, self._pending = self._pending, None
        return pending

    def _on_finished(self, result) -> None:
        clip, folder, project, _ = self._close()
        self.result = result
        if self.window.open_project(project, ask_to_save=False):
            moving = result.glb_info.get("arkit_channels_moving", 0)
            self.window.show_status(
                f"{clip.name}: {result.frames} frames tracked in ARKit terms in {result.total_s:.0f} s; "
                f"{result.glb.name} ({moving} ARKit channel{'' if moving == 1 else 's'} moving) and "
                f"{result.csv.name} in {folder}",
                0,
            )

    def _on_failed(self, message: str) -> None:
        clip, folder, project, _ = self._close()
        self.window.show_error("Cannot make a face of the clip", message)
        if project.is_file():  # the stills (and fits) made before the failure are there to correct
            self.window.open_project(project, ask_to_save=False)

    def _on_cancelled(self) -> None:
        clip, folder, project, generation = self._close()
        if not self._cancel_asked or generation != self.window.model.generation:
            # another project was opened meanwhile: it stays open
            self.window.show_status(f"the chain on {clip.name} stopped; what is done is kept in {folder}", 0)
            return
        if project.is_file() and self.window.open_project(project, ask_to_save=False):
            self.window.show_status(
                f"cancelled; what is done is kept in {folder}: New from video… on {clip.name} into that folder "
                f"with “{AUTO_CHECKBOX}” (or `facestudio auto {clip.name} --out {folder}`) goes on",
                0,
            )
        else:
            self.window.show_status(f"cancelled before the stills of {clip.name} were made; nothing kept", 0)

    def shutdown(self) -> None:
        self.jobs.shutdown()
