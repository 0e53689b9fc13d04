"""The studio's project file (app/studio/project_file.py) without Qt: open, save with results, save as,
autosave and recovery of the sample project, the results read back checked against its ground_truth.json."""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from app.studio import project_file as pf
from app.studio.texturing import read_stored_texture
from photomodel.alignment import align_to_truth, camera_errors
from photomodel.exchange.mesh import read_mesh
from photomodel.project import load_project

REPO = Path(__file__).resolve().parents[1]


def test_imports_no_qt():
    code = "import sys, app.studio.project_file; assert not [m for m in sys.modules if m.startswith('PySide6')]"
    subprocess.run([sys.executable, "-c", code], cwd=REPO, check=True)


def test_blank_project_has_the_pose_features_and_one_expression(mesh):
    p = pf.blank_project(mesh, "someone")
    assert p.name == "someone" and p.path is None
    assert sum(f.pose for f in p.features) == 13  # the generic mesh's initial (pose) features
    assert [e.name for e in p.expressions] == [pf.DEFAULT_EXPRESSION]
    assert {c.name for c in p.curves} == set(mesh.curves)


def test_open_reads_photos_absolute_and_names_missing_ones(project_copy, mesh, tmp_path):
    project, fits = pf.open_project(project_copy, mesh)
    assert fits == {} and project.path == project_copy.absolute()  # the sample comes without results
    for photo in project.expression("neutral").photos:
        assert Path(photo.path).is_absolute() and Path(photo.path).is_file()
    moved = tmp_path / "moved.facestudio.json"
    shutil.copy(project_copy, moved)
    with pytest.raises(pf.MissingPhotos, match="neutral_front.png"):
        pf.open_project(moved, mesh)
    project, _ = pf.open_project(moved, mesh, allow_missing_photos=True)
    assert project.path == moved


def test_open_reads_the_fitted_meshes_and_cameras(fitted_project_copy, mesh, sample_truth):
    project, fits = pf.open_project(fitted_project_copy, mesh)
    assert set(fits) == {e.name for e in project.expressions}
    for name, fit in fits.items():
        assert fit.saved and fit.result is None and fit.vertices.shape == mesh.vertices.shape
        true_points = sample_truth.expression_features_3d[name]
        names = [n for n in fit.points_3d if n in true_points]
        ids = list(fit.cameras)
        cams, _ = align_to_truth(
            [fit.cameras[i] for i in ids], [fit.points_3d[n] for n in names], [true_points[n] for n in names]
        )
        err = camera_errors(cams, [sample_truth.cameras[name][i] for i in ids])
        assert err["rot_err_deg"].max() < 1.0, (name, err)  # as tests/test_fit.py: the fit's accuracy
    # a broken mesh file loses that fit's mesh, not the project
    ply = project.resolve(project.expression("smile").result.mesh_ply)
    obj = project.resolve(project.expression("smile").result.mesh_obj)
    ply.write_bytes(b"ply\nbroken")
    obj.unlink()
    _, fits = pf.open_project(fitted_project_copy, mesh)
    assert fits["smile"].vertices is None and not fits["smile"].saved and fits["neutral"].vertices is not None


def test_save_as_writes_the_results_into_the_new_folder(fitted_project_copy, mesh, tmp_path):
    project, fits = pf.open_project(fitted_project_copy, mesh)
    textures = {"neutral": read_stored_texture(project, "neutral", fits["neutral"], mesh)}
    for fit in fits.values():
        fit.saved = False  # as after a fit in the studio
    target = tmp_path / "elsewhere" / "copy.facestudio.json"
    assert pf.save_with_results(project, target, fits, textures, mesh.faces) == target
    assert project.path == target and all(f.saved for f in fits.values()) and textures["neutral"].saved
    doc = json.loads(target.read_text())
    saved = doc["expressions"][0]["result"]
    assert saved["mesh_ply"] == "results/neutral.ply"  # relative to the new folder
    for e in project.expressions:
        v, _ = read_mesh(target.parent / e.result.mesh_ply)
        np.testing.assert_allclose(v, fits[e.name].vertices, atol=1e-4)  # as fitted, to the file's precision
    assert (target.parent / saved["texture"]["image"]).is_file()
    _, fits_again = pf.open_project(target, mesh)  # the photos found from the new folder
    assert set(fits_again) == set(fits)


def test_autosave_recovery_and_its_removal(project_copy, mesh, tmp_path):
    project, _ = pf.open_project(project_copy, mesh)
    project.expression("neutral").photo("front").points["chin"] = np.array([400.0, 800.0])
    target = pf.autosave_target(project)
    assert target == pf.autosave_path(project_copy) == project_copy.with_name(project_copy.name + ".autosave")
    os.utime(project_copy, (0, 0))  # the project file older than its autosave
    assert pf.write_autosave(project, target) == target and project.path == project_copy
    assert pf.newer_autosave(project_copy) == target and not target.with_name(target.name + ".bak").exists()
    recovered, _ = pf.open_project(project_copy, mesh, recover=True)
    np.testing.assert_allclose(recovered.expression("neutral").photo("front").points["chin"], (400.0, 800.0))
    assert load_project(project_copy).expression("neutral").photo("front").points["chin"][0] != 400.0
    pf.remove_autosave(project_copy)
    assert not target.exists() and pf.newer_autosave(project_copy) is None

    # a never-saved project goes to the recovery file, or nowhere
    project.path = None
    assert pf.autosave_target(project) is None
    recovery = tmp_path / "recovery" / "untitled.facestudio.json"
    recovery.parent.mkdir()
    pf.write_autosave(project, pf.autosave_target(project, recovery))
    back, fits = pf.open_recovery(recovery, mesh)
    assert back.path is None and fits == {}
    assert all(Path(p.path).is_file() for p in back.expression("neutral").photos)  # the photos found again
