"""facestudio clone (tracking.clone): a performance cloned onto the same face comes back unchanged."""

import json
import shutil

import numpy as np

from app.cli import main as facestudio
from photomodel.photos.video import VideoFrames
from photomodel.project import load_project
from tracking.blendshape_face import CONTROL_REGIONS
from tracking.face_from_project import face_model_from_project
from tracking.track_result import FACING, FORMAT, VERSION, load_track_results, save_results


def _track_doc(project_path, model, weights, video):
    """A hand-made track.json of ``model``: frames of the given region weights (f, R, m), facing the camera."""
    frames = []
    for i, W in enumerate(weights):
        t = np.array([0.0, 0.0, 600.0])
        frames.append(
            {
                "frame": i,
                "rotation_vector": [np.pi, 0.0, 0.0],
                "R": FACING.tolist(),
                "t_mm": t.tolist(),
                "centre_mm": (FACING @ model.centre + t).tolist(),
                "head_rotation_deg": [0.0, 0.0, 0.0],
                "alpha": model.alpha_of_weights(W).tolist(),
                "weights": {
                    r: dict(zip(model.names, map(float, W[k]), strict=True)) for k, r in enumerate(CONTROL_REGIONS) if k
                },
                "rms": 0.01,
                "pixels": 100,
                "diverged": False,
                "steps": 1,
                "evaluations": 1,
                "seconds": 0.1,
                "start": "predicted",
            }
        )
    return {
        "format": FORMAT,
        "version": VERSION,
        "project": str(project_path),
        "video": {"path": str(video.path), "kind": "file", "width": video.width, "height": video.height, "fps": 25.0},
        "camera": {
            "focal_px": 1.5 * video.width,
            "width": video.width,
            "height": video.height,
            "convention": "X_cam = R X + t",
        },
        "model": {
            "source": "test",
            "expressions": list(model.names),
            "regions": list(CONTROL_REGIONS),
            "regions_with_parameters": [r for r, a in zip(CONTROL_REGIONS, model.n_alpha, strict=True) if a],
            "n_alpha": list(model.n_alpha),
            "centre_mm": model.centre.tolist(),
        },
        "first_pose": {"source": "test", "spec": {}},
        "options": {},
        "max_frames": None,
        "complete": True,
        "corrections": [],
        "frames": frames,
    }


def test_clone_onto_the_same_face_by_displacement_gives_the_weights_back(fitted_project_copy, tmp_path, capsys):
    project = load_project(fitted_project_copy)
    model, _ = face_model_from_project(project)
    rng = np.random.default_rng(0)
    W = np.zeros((4, len(CONTROL_REGIONS), model.m))
    W[:, :, 0] = 1.0
    W[:, 1:, 1:] = rng.uniform(0.0, 0.4, (4, len(CONTROL_REGIONS) - 1, model.m - 1)) / model.m
    W[:, 1:, 0] = 1.0 - W[:, 1:, 1:].sum(axis=2)
    src = tmp_path / "track_a"
    src.mkdir()
    video = VideoFrames(fitted_project_copy.parent / "video" / "james_track.mp4")
    save_results(src, _track_doc(fitted_project_copy, model, W, video), True)
    out = tmp_path / "cloned"
    argv = ["clone", "--from", str(fitted_project_copy), "--track", str(src), "--to", str(fitted_project_copy)]
    assert facestudio([*argv, "--method", "displacement", "--out", str(out), "--json"]) == 0
    summary = json.loads(capsys.readouterr().out)
    assert summary["frames"] == 4
    side = VideoFrames(summary["files"]["video"])  # A's frames | B rendered
    assert (side.width, side.height) == (2 * video.width, video.height) and side.count == 4
    doc = load_track_results(out)  # B's results open as tracking results
    assert doc["cloned_from"]["method"] == "displacement"
    for rec, Wf in zip(doc["frames"], W, strict=True):
        for k, region in enumerate(CONTROL_REGIONS):
            if k:
                got = [rec["weights"][region][n] for n in model.names]
                np.testing.assert_allclose(got, Wf[k], atol=1e-6)  # least squares of an exact blend
        np.testing.assert_allclose(rec["R"], FACING)
    # export --glb --track takes B's cloned results as it takes B's own tracking
    glb = tmp_path / "cloned.glb"
    assert facestudio(["export", str(fitted_project_copy), "--glb", str(glb), "--track", str(out)]) == 0
    assert glb.stat().st_size > 0


def test_clone_records_the_other_person_in_the_project(fitted_project_copy, tmp_path):
    """B's project file refers to A afterwards (format version 6, ``people``), once however often it clones."""
    a = tmp_path / "alice" / "alice.facestudio.json"
    shutil.copytree(fitted_project_copy.parent, a.parent)
    (a.parent / fitted_project_copy.name).rename(a)
    model, _ = face_model_from_project(load_project(a))
    W = np.zeros((2, len(CONTROL_REGIONS), model.m))
    W[:, :, 0] = 1.0
    src = a.parent / "results" / "track_a"
    src.mkdir(parents=True)
    save_results(src, _track_doc(a, model, W, VideoFrames(a.parent / "video" / "james_track.mp4")), True)
    argv = ["clone", "--from", str(a), "--track", str(src), "--to", str(fitted_project_copy), "--no-video"]
    for _ in range(2):
        assert facestudio([*argv, "--method", "displacement"]) == 0
    assert load_project(fitted_project_copy).people == ["../alice/alice.facestudio.json"]
    assert load_track_results(fitted_project_copy.parent / "results" / "track_a_from_alice")["frames"]
