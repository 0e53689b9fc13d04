"""photomodel.texture_job: the texture path shared by ``facestudio texture`` and the studio.

On a copy of the sample project fitted as ``facestudio fit`` does: the mesh is read from the
project's result file, the texture extracted (64² keeps this fast: the content of the texture is
tested in tests/test_texture.py), every file written and the record stored; cancel and progress.
"""

from __future__ import annotations

import shutil
from pathlib import Path

import pytest

from photomodel.errors import FitError
from photomodel.fit import Cancelled, fit_expression, store_fit_result
from photomodel.generic_mesh import load_generic_mesh
from photomodel.project import load_project, save_project
from photomodel.texture_job import (
    commit_texture,
    encode_texture_outputs,
    fitted_expressions,
    texture_expression,
)

SAMPLE = Path(__file__).resolve().parents[1] / "sample_projects" / "james"


@pytest.fixture(scope="module")
def fitted(tmp_path_factory):
    folder = tmp_path_factory.mktemp("job")
    shutil.copytree(SAMPLE, folder / "james", ignore=shutil.ignore_patterns("results"))
    path = folder / "james" / "james.facestudio.json"
    project = load_project(path)
    mesh = load_generic_mesh()
    with pytest.raises(FitError, match="no expression has been fitted"):
        fitted_expressions(project, None)
    store_fit_result(project, "neutral", fit_expression(project, "neutral", mesh), mesh.faces)
    save_project(project)
    return path, mesh


def test_texture_from_the_project_files_is_written_and_recorded(fitted):
    path, mesh = fitted
    project = load_project(path)
    assert fitted_expressions(project, None) == ["neutral"]
    stages = []
    job = texture_expression(project, "neutral", 64, face_mask=mesh.face_mask,
                             progress=lambda s, f: stages.append(f))
    assert stages[0] == 0.0 and stages[-1] == 1.0 and stages == sorted(stages)
    assert job.texture.image.shape == (64, 64, 3) and len(job.texture.weight_maps) == 5
    assert job.report["single_view_fallback"] and 0.5 < job.report["coverage"] <= 1.0
    files, rel = encode_texture_outputs(project, job)
    commit_texture(project, job, files, rel)
    save_project(project)
    stored = load_project(path).expression("neutral").result.texture
    assert stored.size == 64 and set(stored.weight_maps) == set(job.inputs.photo_ids)
    for f in [stored.image, rel["mtl"], *stored.weight_maps.values(), *stored.exports.values()]:
        assert (path.parent / f).is_file(), f


def test_cancel_stops_the_extraction(fitted):
    path, _ = fitted
    project = load_project(path)
    calls = []

    def cancel():  # polls: start, cylindrical raster, first photo — the third says stop
        calls.append(1)
        return len(calls) >= 3

    with pytest.raises(Cancelled):
        texture_expression(project, "neutral", 64, cancel=cancel)
    assert len(calls) == 3


def test_errors_name_the_cause(fitted):
    path, _ = fitted
    project = load_project(path)
    project.expression("neutral").result.mesh_obj = "results/nothing.obj"
    with pytest.raises(Exception, match="nothing.obj does not exist"):
        texture_expression(project, "neutral", 64)
    with pytest.raises(Exception, match="between 8 and 16384"):
        texture_expression(load_project(path), "neutral", 4)
