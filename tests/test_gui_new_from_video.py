"""*File → New from video…* with *Track the whole clip and build the rig*, as an artist runs it: the
dialog filled in and the box checked, ``facestudio auto``'s chain in a worker behind one progress
dialog naming the stage, cancelled while tracking (the project it left opens), run again on the same
folder (the stages done found, the track going on) and the project opened. The screenshots
docs/img/new_from_video.png and docs/img/new_from_video_progress.png are taken here
(``FACESTUDIO_SCREENSHOTS=1``)."""

from __future__ import annotations

import json
import os
from pathlib import Path

import pytest

pytest.importorskip("PySide6")
pytest.importorskip("pytestqt")

from PySide6.QtCore import QPoint, Qt  # noqa: E402
from PySide6.QtWidgets import QDialogButtonBox, QPushButton  # noqa: E402
from real_clips import short_clip  # noqa: E402

from app.qt.new_from_video import AUTO_CHECKBOX, STAGE_TITLES, stage_label  # noqa: E402
from tracking.auto_pipeline import STAGES  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
SHOTS = ROOT / "docs" / "img"
NAMES = [name for name, _ in STAGES]


def _fill_dialog(qtbot, w, clip, frames):
    """File → New from video…, the clip typed in, the box checked, the frames to track set."""
    w.file_menu.act_new_from_video.trigger()
    dialog = w.importer.video_dialog
    qtbot.waitExposed(dialog)
    assert dialog.auto_box.text() == AUTO_CHECKBOX and not dialog.auto_box.isChecked()  # off by default
    qtbot.keyClicks(dialog.clip_edit, str(clip))
    assert dialog.target() == clip.with_name("talk.facestudio.json")  # the project of stills beside the clip
    box = dialog.auto_box  # clicked on its square (the row is wider than the box and its text)
    qtbot.mouseClick(box, Qt.MouseButton.LeftButton, pos=QPoint(box.height() // 2, box.height() // 2))
    assert dialog.auto_box.isChecked() and dialog.target() == clip.with_name("talk_auto")  # auto's folder
    dialog.stills_box.setValue(4)
    dialog.frames_box.setValue(frames)
    return dialog


def _ok(qtbot, dialog):
    ok = dialog.buttons.button(QDialogButtonBox.StandardButton.Ok)
    assert ok.isEnabled()
    qtbot.mouseClick(ok, Qt.MouseButton.LeftButton)


def test_new_from_video_runs_the_whole_chain_cancel_and_resume(qtbot, studio_window, tmp_path, messages):
    clip = short_clip(tmp_path / "talk.mp4", 48)
    w, model = studio_window, studio_window.model
    w.act_auto.setChecked(False)
    runner = w.importer.auto
    folder, project = tmp_path / "talk_auto", tmp_path / "talk_auto" / "talk.facestudio.json"
    track = folder / "results" / "track_talk" / "track.json"

    dialog = _fill_dialog(qtbot, w, clip, frames=4)
    if os.environ.get("FACESTUDIO_SCREENSHOTS"):  # looked at by hand
        qtbot.wait(100)  # the note's new text laid out
        assert dialog.grab().save(str(SHOTS / "new_from_video.png"))
    # -- run, and Cancel in the progress dialog once the track has its first frame
    progress = []

    def on_progress(label, fraction):
        progress.append(label)
        if "frame 1 of 4" in label and runner.dialog is not None and not runner.dialog.wasCanceled():
            if os.environ.get("FACESTUDIO_SCREENSHOTS"):
                runner.dialog.show()
                assert runner.dialog.grab().save(str(SHOTS / "new_from_video_progress.png"))
            runner.dialog.findChild(QPushButton).click()  # its Cancel button

    runner.jobs.progress.connect(on_progress)
    _ok(qtbot, dialog)
    assert runner.busy and runner.dialog is not None
    qtbot.waitUntil(lambda: not runner.busy, timeout=120_000)
    runner.jobs.progress.disconnect(on_progress)
    assert not messages, messages
    assert runner.stages_seen == NAMES[:5]  # stopped in the track: no export
    assert stage_label("fit") in progress  # each stage named, with its number
    assert any(label.startswith(f"5 of 6 · track — {STAGE_TITLES['track']}\nframe") for label in progress)
    # the project left opens in the studio, rigged; the frames tracked are saved
    assert model.path == project and model.project.rig is not None
    done = len(json.loads(track.read_text())["frames"])
    assert 1 <= done < 4
    assert "goes on" in w.statusBar().currentMessage()
    assert not (folder / "talk.glb").exists()

    # -- again on the same clip and folder: the stages done are found, the track goes on
    dialog = _fill_dialog(qtbot, w, clip, frames=4)
    _ok(qtbot, dialog)
    qtbot.waitUntil(lambda: not runner.busy, timeout=120_000)
    assert not messages, messages
    assert runner.stages_seen == NAMES
    result = runner.result
    assert result.skipped == ["stills", "fit", "texture", "rig"] and result.frames == 4
    assert len(json.loads(track.read_text())["frames"]) == 4
    assert result.glb_info["frames"] == 4 and result.glb_info["targets"] == result.glb_info["expected_targets"]
    assert (folder / "talk.glb").is_file() and (folder / "talk.csv").is_file()
    assert model.path == project and model.project.rig is not None  # the studio opened the project
    assert "4 frames tracked in ARKit terms" in w.statusBar().currentMessage()


def test_the_box_unchecked_makes_a_project_of_stills(qtbot, studio_window, tmp_path, messages):
    """Unchecked, OK makes the project of stills only (``new --video``), saved where the dialog says."""
    clip = ROOT / "sample_projects" / "james" / "video" / "james_track.mp4"
    w, model = studio_window, studio_window.model
    w.act_auto.setChecked(False)
    w.file_menu.act_new_from_video.trigger()
    dialog = w.importer.video_dialog
    qtbot.keyClicks(dialog.clip_edit, str(tmp_path / "nothing.mp4"))
    assert not dialog.buttons.button(QDialogButtonBox.StandardButton.Ok).isEnabled()  # no such clip
    assert "no such clip" in dialog.note.text()
    dialog.clip_edit.clear()
    qtbot.keyClicks(dialog.clip_edit, str(clip))
    dialog.path_edit.clear()
    qtbot.keyClicks(dialog.path_edit, str(tmp_path / "me.facestudio.json"))
    dialog.stills_box.setValue(2)
    _ok(qtbot, dialog)
    qtbot.waitUntil(lambda: not w.importer.busy and model.path == tmp_path / "me.facestudio.json", timeout=60_000)
    assert not messages, messages
    assert 1 <= len(model.photos) <= 2 and model.project.rig is None
    assert not (tmp_path / "james_track_auto").exists()
