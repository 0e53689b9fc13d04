"""``facestudio auto``: a short real clip end to end (project, glb, CSV, figures), resuming, and a clip with no face."""

import json

import cv2
import numpy as np
import pytest
from real_clips import short_clip

from app.cli import main
from photomodel.project import load_project
from tracking.auto_pipeline import STAGES, run_auto


def test_auto_makes_a_project_the_studio_opens_and_an_animated_glb(tmp_path, capsys):
    clip = short_clip(tmp_path / "talk.mp4", 48)
    out = tmp_path / "talk_auto"
    # Ctrl-C (a cancel) once the track has a frame: the project opens, the track is saved
    seen = []

    def progress(stage, fraction, detail=""):
        seen.append((stage, detail))

    with pytest.raises(KeyboardInterrupt):
        run_auto(clip, out, max_frames=3, stills=4, progress=progress, cancel=lambda: ("track", "frame 1 of 3") in seen)
    assert load_project(out / "talk.facestudio.json").rig is not None
    assert len(json.loads((out / "results" / "track_talk" / "track.json").read_text())["frames"]) == 1
    # run again: the stages done are found, the track goes on from frame 1
    rc = main(["auto", str(clip), "--out", str(out), "--frames", "3", "--stills", "4", "--json"])
    assert rc == 0
    report = json.loads(capsys.readouterr().out)["auto"]
    assert report["resumed_stages"] == ["stills", "fit", "texture", "rig"]
    assert set(report["stages"]) == {f"{name}_s" for name, _ in STAGES}
    assert report["frames"] == 3 and report["fit_rms_px"] < 5.0
    # the fit's word on stills that all show an expression (none, or that one), read back on resuming
    assert all(note.startswith("expression not fitted") for note in report["notes"])
    assert 0.6 < report["depth_ratio"] < 1.4
    glb = report["glb"]
    assert glb["targets"] == glb["expected_targets"] >= 40 and glb["frames"] == glb["expected_frames"] == 3
    assert glb["validator_errors"] in (0, -1)  # -1: the validator is not installed
    project = load_project(out / "talk.facestudio.json")  # the studio opens what auto left
    assert project.rig is not None and project.expression("neutral").result.texture is not None
    assert (out / "talk.glb").is_file() and (out / "talk.csv").is_file()
    assert json.loads((out / "results" / "track_talk" / "track.json").read_text())["model"]["basis"] == "arkit"
    # a third run finds every stage but the export done
    assert main(["auto", str(clip), "--out", str(out), "--frames", "3", "--json", "--no-validate"]) == 0
    again = json.loads(capsys.readouterr().out)["auto"]
    assert again["resumed_stages"] == ["stills", "fit", "texture", "rig", "track"]


def test_a_clip_without_a_face_is_a_clear_error(tmp_path, capsys):
    clip = tmp_path / "wall.mp4"
    writer = cv2.VideoWriter(str(clip), cv2.VideoWriter_fourcc(*"mp4v"), 24.0, (160, 120))
    for i in range(6):
        writer.write(np.full((120, 160, 3), 90 + i, np.uint8))
    writer.release()
    assert main(["auto", str(clip), "--out", str(tmp_path / "out"), "--json"]) == 2
    captured = capsys.readouterr()
    err = json.loads(captured.out)["error"]
    assert err["type"] == "AutoError" and "no usable face" in err["message"] and "Tried" in err["message"]
    assert not list((tmp_path / "out").glob("*.facestudio.json"))
