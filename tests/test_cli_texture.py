"""``facestudio texture`` as a user runs it: on a copy of the sample project, fitted first (the
session's fitted sample).

Textures are 256² here (the default is 1024²) to keep the file fast; the command does the same
work at any size.
"""

from __future__ import annotations

import contextlib
import io
import json
import os
import shutil
import signal
from pathlib import Path

import cv2
import numpy as np
import pytest
import trimesh

import photomodel.exchange.files as files
import photomodel.texturing.job
from app.cli import main
from photomodel.exchange.gltf import METRES_PER_MM
from photomodel.exchange.mesh import read_mesh
from photomodel.project import load_project

SAMPLE = Path(__file__).resolve().parents[1] / "sample_projects" / "james"
SIZE = 256
PHOTOS = {"right", "three_quarter_right", "front", "three_quarter_left", "left"}


@pytest.fixture(scope="module")
def fitted(fitted_sample):
    """The folder of the sample fitted (and textured) once per session (conftest's
    ``fitted_sample``; read it, do not change it): the texture command textures it again."""
    return fitted_sample.parent


@pytest.fixture
def project_copy(fitted, tmp_path):
    """A fresh copy of the fitted project (tests may damage it)."""
    shutil.copytree(fitted, tmp_path / "james")
    return tmp_path / "james" / "james.facestudio.json"


@pytest.fixture(scope="module")
def textured(fitted, tmp_path_factory):
    """The fitted project textured once: (project file, JSON output)."""
    folder = tmp_path_factory.mktemp("textured") / "james"
    shutil.copytree(fitted, folder)
    project = folder / "james.facestudio.json"

    out = io.StringIO()
    with contextlib.redirect_stdout(out):
        assert main(["texture", str(project), "--size", str(SIZE), "--json"]) == 0
    return project, json.loads(out.getvalue())


def _snapshot(folder: Path) -> dict:
    return {p.relative_to(folder).as_posix(): p.read_bytes() for p in folder.rglob("*") if p.is_file()}


def test_texture_records_every_output_in_the_project(textured):
    path, out = textured
    entry = out["expressions"][0]
    assert entry["name"] == "neutral" and entry["size"] == SIZE
    assert set(entry["photos"]) == PHOTOS
    assert 0.8 < entry["coverage"] <= 1.0  # five photos around the face see nearly all of it
    tex = load_project(path).expression("neutral").result.texture
    assert tex is not None and tex.size == SIZE
    assert tex.image == "results/neutral_texture.png"
    assert set(tex.weight_maps) == PHOTOS
    assert tex.exports == {
        "obj": "results/neutral_textured.obj",
        "glb": "results/neutral.glb",
        "ply": "results/neutral_colors.ply",
    }
    folder = path.parent
    for rel in [tex.image, *tex.weight_maps.values(), *tex.exports.values(), "results/neutral_textured.mtl"]:
        assert (folder / rel).is_file(), rel
    assert not list(folder.glob("results/.*"))  # no temporary files left behind
    image = cv2.imread(str(folder / tex.image))
    assert image.shape == (SIZE, SIZE, 3)
    weights = cv2.imread(str(folder / tex.weight_maps["front"]), cv2.IMREAD_UNCHANGED)
    assert weights.shape == (SIZE, SIZE) and weights.max() == 255  # grey, 0..1 → black..white


def test_exports_reopen_with_the_fitted_mesh_and_the_texture(textured):
    path, _ = textured
    project = load_project(path)
    result = project.expression("neutral").result
    vertices, faces = read_mesh(project.resolve(result.mesh_obj))
    texture = cv2.cvtColor(cv2.imread(str(project.resolve(result.texture.image))), cv2.COLOR_BGR2RGB)

    glb = trimesh.load(project.resolve(result.texture.exports["glb"]), process=False, force="mesh")
    assert len(glb.vertices) >= len(vertices)  # seam copies only (none for the open face mask)
    # float32 metres: 0.2 m has a spacing of 1.5e-8 m, so 1e-4 mm is ample
    np.testing.assert_allclose(glb.vertices[: len(vertices)] / METRES_PER_MM, vertices, atol=1e-4)
    np.testing.assert_array_equal(np.asarray(glb.visual.material.baseColorTexture.convert("RGB")), texture)

    obj = trimesh.load(project.resolve(result.texture.exports["obj"]), process=False)
    assert len(obj.vertices) == len(glb.vertices) and len(obj.faces) == len(faces)
    assert obj.visual.material.image.size == (SIZE, SIZE)
    np.testing.assert_allclose(obj.visual.uv, glb.visual.uv, atol=1e-6)

    ply = trimesh.load(project.resolve(result.texture.exports["ply"]), process=False)
    assert len(ply.vertices) == len(vertices)
    np.testing.assert_allclose(ply.vertices, vertices, atol=1e-4)
    # skin-coloured on average: red > green > blue (and not the black of an unsampled vertex)
    mean = ply.visual.vertex_colors[:, :3].astype(float).mean(axis=0)
    assert mean[0] > mean[1] > mean[2] and mean[0] > 80


def test_human_output_names_the_files(project_copy, capsys):
    assert main(["texture", str(project_copy), "--size", "64", "--expression", "neutral"]) == 0
    out = capsys.readouterr().out
    assert "64x64 texture from 5 photos" in out and "results/neutral.glb" in out
    assert "saved results into" in out


def test_unfitted_expression_asks_for_a_fit_and_writes_nothing(tmp_path, capsys):
    shutil.copytree(SAMPLE, tmp_path / "james")
    project = tmp_path / "james" / "james.facestudio.json"
    before = _snapshot(tmp_path / "james")
    assert main(["texture", str(project), "--size", "64"]) == 2
    assert "run `facestudio fit" in capsys.readouterr().err
    assert main(["texture", str(project), "--expression", "neutral"]) == 2
    assert "'neutral' has not been fitted yet" in capsys.readouterr().err
    assert _snapshot(tmp_path / "james") == before


@pytest.mark.parametrize(
    "damage, message",
    [
        (lambda p: p.unlink(), "neutral_left.png does not exist"),
        (lambda p: p.write_bytes(b"\x89PNG\r\n\x1a\n not really"), "neutral_left.png: truncated PNG"),
    ],
)
def test_missing_or_corrupt_photo_is_named_and_nothing_is_written(project_copy, capsys, damage, message):
    damage(project_copy.parent / "photos" / "neutral_left.png")
    before = _snapshot(project_copy.parent)
    assert main(["texture", str(project_copy), "--size", "64"]) == 2
    err = capsys.readouterr().err
    assert message in err and "'left'" in err
    assert _snapshot(project_copy.parent) == before


def test_bad_size_is_refused(project_copy, capsys):
    assert main(["texture", str(project_copy), "--size", "4"]) == 2
    assert "--size 4" in capsys.readouterr().err


def test_ctrl_c_cancels_cleanly_with_nothing_written(project_copy, capsys, monkeypatch):

    def interrupted(*args, **kwargs):
        raise KeyboardInterrupt

    monkeypatch.setattr(photomodel.texturing.job, "cylindrical_texture", interrupted)  # where the job looks it up
    before = _snapshot(project_copy.parent)
    assert main(["texture", str(project_copy), "--size", "64"]) == 130
    assert "nothing was written" in capsys.readouterr().err
    assert _snapshot(project_copy.parent) == before


def test_a_new_fit_drops_the_texture_record(textured, tmp_path):
    shutil.copytree(textured[0].parent, tmp_path / "james")
    project = tmp_path / "james" / "james.facestudio.json"
    assert load_project(project).expression("neutral").result.texture is not None
    assert main(["fit", str(project), "--json", "--no-refine", "--expression", "neutral"]) == 0
    assert load_project(project).expression("neutral").result.texture is None  # it was for the old mesh


def test_ctrl_c_while_saving_waits_until_everything_is_saved(project_copy, capsys, monkeypatch):

    real = files.write_files

    def write_files_interrupted(batch):
        os.kill(os.getpid(), signal.SIGINT)  # the user presses Ctrl-C as the files are written
        return real(batch)

    monkeypatch.setattr(files, "write_files", write_files_interrupted)
    assert main(["texture", str(project_copy), "--size", "64", "--expression", "neutral"]) == 0
    assert "the results were saved completely" in capsys.readouterr().err
    tex = load_project(project_copy).expression("neutral").result.texture
    assert tex is not None and (project_copy.parent / tex.exports["glb"]).is_file()
    assert signal.getsignal(signal.SIGINT) is signal.default_int_handler  # restored


def test_one_photo_from_a_folder_to_a_textured_face(tmp_path, capsys):
    """A user with one photo: ``new --photos`` (the real detector), ``fit`` and ``texture``. The
    camera is placed against the generic head (its depth the face's); the texture is the photo's."""
    photos = tmp_path / "photos"
    photos.mkdir()
    shutil.copy(SAMPLE / "photos" / "neutral_three_quarter_left.png", photos)
    project = tmp_path / "me.facestudio.json"
    assert main(["new", str(project), "--photos", str(photos), "--json"]) == 0
    capsys.readouterr()
    assert main(["fit", str(project), "--json"]) == 0
    fit = json.loads(capsys.readouterr().out)["expressions"][0]
    assert "one photo" in fit["camera_solve"]["start"]
    # automatic clicks are less sure (σ 2.7 mm at the face, ~6 px per axis here) than people's faces
    # differ from the generic head's (1.5 mm): the face keeps near the generic head's shape and the
    # RMS against the clicks is about the detector's error (measured 11.7 px; 2-D σ ~9–10 px)
    assert fit["rms_px"] < 20.0
    assert main(["texture", str(project), "--size", str(SIZE), "--json"]) == 0
    tex = json.loads(capsys.readouterr().out)["expressions"][0]
    assert tex["photos"] == ["neutral_three_quarter_left"]
    assert cv2.imread(str(tmp_path / tex["files"]["texture"])) is not None
