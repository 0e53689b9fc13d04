"""Tests of photomodel.project.results: a fit and a texture stored into a project, and saved with it.

A stand-in fit (two cameras, two points, a tetrahedron for the mesh) and a stand-in texture keep
this fast; ``facestudio fit`` / ``texture`` and the studio, which call these functions, are tested
end to end in tests/test_cli*.py, tests/test_studio_model.py and tests/test_gui_texture.py.
"""

from __future__ import annotations

import re
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest
from project_samples import sample_camera, sample_project, temp_files

import photomodel.exchange.mesh
import photomodel.project.results
from photomodel.errors import FitError, ProjectError
from photomodel.exchange.mesh import read_mesh
from photomodel.project import (
    TextureResult,
    expression_result,
    load_project,
    record_fit,
    save_project,
    save_results,
    store_fit_result,
    store_texture_result,
)

VERTICES = np.array([[0.0, 0.0, 0.0], [10.0, 0.0, 0.0], [0.0, 10.0, 0.0], [0.0, 0.0, 10.0]])
FACES = np.array([[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]])


def _fit(shift: float = 0.0):
    """What :func:`photomodel.modeling.fit.fit_expression` returns, as far as storing reads it."""
    return SimpleNamespace(
        photo_ids=["front", "left"],
        cameras=[sample_camera(0.0), sample_camera(90.0)],
        feature_names=["nose_tip", "eye_l"],
        points_3d=np.array([[0.0, -1.5, 102.25], [1, 2, 3]]),
        vertices=VERTICES + shift,
        report={"rms_px": 0.5, "views": []},
    )


def _texture(folder: Path, name: str = "neutral"):
    """A texture job, its encoded files in ``folder`` and their paths (as encode_texture_outputs gives)."""
    rel = {
        "image": f"results/{name}_texture.png",
        "weight_maps": {"front": f"results/{name}_weights_front.png"},
        "obj": f"results/{name}_textured.obj",
        "mtl": f"results/{name}_textured.mtl",
        "glb": f"results/{name}.glb",
        "ply": f"results/{name}_colors.ply",
    }
    paths = [rel["image"], *rel["weight_maps"].values(), rel["mtl"], rel["obj"], rel["glb"], rel["ply"]]
    files = {folder / p: f"{p} of {name}".encode() for p in paths}
    job = SimpleNamespace(expression=name, size=64, report={"coverage": 0.9})
    return job, files, rel


@pytest.fixture
def saved(tmp_path):
    """A saved project (no photos needed) whose neutral expression has no mesh files yet."""
    p = sample_project(tmp_path)
    p.expression("neutral").result.mesh_obj = p.expression("neutral").result.mesh_ply = None
    save_project(p)
    return p


def test_expression_result_is_the_fit_record():
    fit = _fit()
    r = expression_result(fit)
    assert list(r.cameras) == ["front", "left"] and r.cameras["left"] is fit.cameras[1]
    np.testing.assert_array_equal(r.points_3d["nose_tip"], [0.0, -1.5, 102.25])
    assert r.report is fit.report and r.mesh_obj is None and r.mesh_ply is None and r.texture is None
    r = expression_result(fit, mesh_obj="a.obj", mesh_ply="a.ply")
    assert (r.mesh_obj, r.mesh_ply) == ("a.obj", "a.ply")


def test_record_fit_replaces_the_result_and_its_texture(saved):
    saved.expression("neutral").result.texture = TextureResult(size=8, image="t.png")
    r = record_fit(saved, "neutral", _fit())
    assert saved.expression("neutral").result is r and r.texture is None and r.mesh_obj is None
    with pytest.raises(ProjectError, match="no expression 'grin'"):
        record_fit(saved, "grin", _fit())


def test_store_fit_result_writes_the_meshes_next_to_the_project(saved, tmp_path):
    store_fit_result(saved, "neutral", _fit(), FACES)
    r = saved.expression("neutral").result
    assert (r.mesh_obj, r.mesh_ply) == ("results/neutral.obj", "results/neutral.ply")
    for rel in (r.mesh_obj, r.mesh_ply):
        v, f = read_mesh(tmp_path / rel)
        np.testing.assert_allclose(v, VERTICES)
        np.testing.assert_array_equal(f, FACES)
    unsaved = sample_project()
    with pytest.raises(FitError, match="save the project before storing results"):
        store_fit_result(unsaved, "neutral", _fit(), FACES)


def test_save_results_writes_the_meshes_then_the_project(saved, tmp_path):
    before = saved.path.read_bytes()
    record_fit(saved, "neutral", _fit())
    written = save_results(saved, fits={"neutral": VERTICES}, faces=FACES)
    assert written == saved.path == tmp_path / "james.facestudio.json"
    assert Path(str(written) + ".bak").read_bytes() == before  # the previous file is kept
    q = load_project(written)
    r = q.expression("neutral").result
    assert (r.mesh_obj, r.mesh_ply) == ("results/neutral.obj", "results/neutral.ply")
    np.testing.assert_allclose(read_mesh(q.resolve(r.mesh_ply))[0], VERTICES)
    assert r.report == {"rms_px": 0.5, "views": []}
    assert temp_files(tmp_path) == [] and temp_files(tmp_path / "results") == []


def test_save_results_stores_a_texture(saved, tmp_path):
    job, files, rel = _texture(tmp_path)
    save_results(saved, textures=[(job, files, rel)])
    for path, data in files.items():
        assert path.read_bytes() == data
    t = load_project(saved.path).expression("neutral").result.texture
    assert (t.size, t.image, t.weight_maps) == (64, rel["image"], rel["weight_maps"])
    assert t.exports == {"obj": rel["obj"], "glb": rel["glb"], "ply": rel["ply"]} and t.report == {"coverage": 0.9}


def test_store_texture_result_records_it_without_saving(saved, tmp_path):
    before = saved.path.read_bytes()
    job, files, rel = _texture(tmp_path)
    store_texture_result(saved, job, files, rel)
    assert saved.expression("neutral").result.texture.image == rel["image"]
    assert all(p.is_file() for p in files) and saved.path.read_bytes() == before
    job, files, rel = _texture(tmp_path, "smile")  # smile is not fitted
    with pytest.raises(FitError, match="'smile' is no longer fitted; its texture is not stored"):
        store_texture_result(saved, job, files, rel)
    assert not any(p.exists() for p in files)


def test_save_results_into_another_folder_records_the_files_there(saved, tmp_path):
    """Save as: the result files are written next to the new file and recorded relative to it."""
    other = tmp_path / "elsewhere" / "copy.facestudio.json"
    record_fit(saved, "neutral", _fit())
    job, files, rel = _texture(other.parent)
    save_results(saved, other, fits={"neutral": VERTICES}, faces=FACES, textures=[(job, files, rel)])
    q = load_project(other)
    r = q.expression("neutral").result
    assert (r.mesh_obj, r.texture.image, r.texture.exports["glb"]) == ("results/neutral.obj", rel["image"], rel["glb"])
    assert q.resolve(r.mesh_obj) == other.parent / "results" / "neutral.obj" and q.resolve(r.mesh_obj).is_file()
    assert q.resolve(r.texture.image).is_file() and not (tmp_path / "results").exists()


def test_an_invalid_project_writes_no_result_file(saved, tmp_path):
    before = saved.path.read_bytes()
    record_fit(saved, "neutral", _fit())
    saved.expression("neutral").photos[0].points["nosetip"] = np.array([1.0, 2.0])
    job, files, rel = _texture(tmp_path)
    with pytest.raises(ProjectError, match=r"points\.nosetip: no feature named 'nosetip'"):
        save_results(saved, fits={"neutral": VERTICES}, faces=FACES, textures=[(job, files, rel)])
    assert not (tmp_path / "results").exists() and saved.path.read_bytes() == before


def test_a_failed_result_file_leaves_the_project_file_as_it_was(saved, tmp_path, monkeypatch):
    before = saved.path.read_bytes()
    record_fit(saved, "neutral", _fit())
    real = photomodel.exchange.mesh.write_mesh

    def disk_full_at_the_ply(path, vertices, faces):
        if Path(path).suffix == ".ply":
            raise OSError(28, "No space left on device")
        return real(path, vertices, faces)

    monkeypatch.setattr(photomodel.project.results, "write_mesh", disk_full_at_the_ply)  # where results looks it up
    with pytest.raises(ProjectError) as ei:
        save_results(saved, fits={"neutral": VERTICES}, faces=FACES)
    assert str(ei.value).startswith(
        f"{tmp_path / 'results' / 'neutral.ply'}: could not write the fitted mesh: No space left on device"
    )
    assert saved.path.read_bytes() == before
    assert temp_files(tmp_path) == [] and temp_files(tmp_path / "results") == []


def test_interrupted_before_the_project_file_the_previous_one_stays(saved, tmp_path, monkeypatch):
    """Killed after the result files, before the project file: the previous project file is intact
    with the meshes of its own fit (the new ones went under new names), every file whole."""
    store_fit_result(saved, "neutral", _fit(), FACES)
    save_project(saved)
    before = saved.path.read_bytes()
    record_fit(saved, "neutral", _fit(shift=1.0))

    def killed(*args, **kwargs):
        raise KeyboardInterrupt

    monkeypatch.setattr(photomodel.project.results, "write_project", killed)
    with pytest.raises(KeyboardInterrupt):
        save_results(saved, fits={"neutral": VERTICES + 1.0}, faces=FACES)
    assert saved.path.read_bytes() == before
    r = load_project(saved.path).expression("neutral").result
    for rel in (r.mesh_obj, r.mesh_ply):  # the old pair: the stored result and its mesh, one fit
        np.testing.assert_allclose(read_mesh(tmp_path / rel)[0], VERTICES)
    assert temp_files(tmp_path) == [] and temp_files(tmp_path / "results") == []


def test_a_refit_switches_to_new_mesh_files_and_removes_the_old(saved, tmp_path):
    record_fit(saved, "neutral", _fit())
    save_results(saved, fits={"neutral": VERTICES}, faces=FACES)
    first = saved.expression("neutral").result.mesh_obj
    assert first == "results/neutral.obj"
    record_fit(saved, "neutral", _fit(shift=1.0))
    save_results(saved, fits={"neutral": VERTICES + 1.0}, faces=FACES)
    r = load_project(saved.path).expression("neutral").result
    assert re.fullmatch(r"results/neutral\.[0-9a-f]{8}\.obj", r.mesh_obj) and r.mesh_ply == r.mesh_obj[:-3] + "ply"
    np.testing.assert_allclose(read_mesh(tmp_path / r.mesh_ply)[0], VERTICES + 1.0)
    assert sorted(p.name for p in (tmp_path / "results").glob("neutral*")) == sorted(
        Path(p).name for p in (r.mesh_obj, r.mesh_ply)
    )  # the replaced fit's files are gone
    record_fit(saved, "neutral", _fit(shift=2.0))  # and the next re-fit takes the plain names again
    save_results(saved, fits={"neutral": VERTICES + 2.0}, faces=FACES)
    r = load_project(saved.path).expression("neutral").result
    assert (r.mesh_obj, r.mesh_ply) == ("results/neutral.obj", "results/neutral.ply")
    assert len(list((tmp_path / "results").glob("neutral*"))) == 2
