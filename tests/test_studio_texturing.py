"""The studio's texturing (app/studio/texturing.py) without Qt: a texture made from the fitted sample's
photographs, and the stored one read back, their texels checked against the photographs' pixels."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from app.studio import project_file
from app.studio.texturing import (
    compute_texture,
    read_stored_texture,
    stored_texture_wanted,
    texture_inputs,
)
from photomodel.errors import FitError, ProjectError
from photomodel.photos.reading import read_photo

REPO = Path(__file__).resolve().parents[1]


@pytest.fixture(scope="module")
def opened(fitted_sample, mesh):
    """``(project, fits)``: the fitted sample as the studio opens it (read it, do not change it)."""
    return project_file.open_project(fitted_sample, mesh)


def _texel_error(job, project, fit, mesh) -> np.ndarray:
    """Per face vertex seen square-on by the front photo: |texel − the photo's pixel| (mean of RGB, 0–255)."""
    cam = fit.cameras["front"]
    V, F = fit.vertices, mesh.faces
    normals = np.zeros_like(V)
    for k in range(3):
        np.add.at(normals, F[:, k], np.cross(V[F[:, 1]] - V[F[:, 0]], V[F[:, 2]] - V[F[:, 0]]))
    normals /= np.linalg.norm(normals, axis=1, keepdims=True)
    view = cam.center - V
    view /= np.linalg.norm(view, axis=1, keepdims=True)
    seen = np.flatnonzero(mesh.face_mask & (np.sum(normals * view, axis=1) > 0.9))
    photo = read_photo(project.photo_path(project.expression(job.expression).photo("front")), max_side=None)
    uv = np.round(cam.project(V[seen])).astype(int)
    pixels = photo.image[uv[:, 1], uv[:, 0]].astype(float)  # uint8 RGB at full size
    image, tuv = job.texture.image, job.texture.uv[seen]
    S = image.shape[0]
    rows = np.clip(((1.0 - tuv[:, 1]) * S).astype(int), 0, S - 1)  # row 0 is v = 1
    cols = np.clip((tuv[:, 0] * S).astype(int), 0, S - 1)
    return np.abs(image[rows, cols].astype(float) - pixels).mean(axis=1)


def test_imports_no_qt():
    code = "import sys, app.studio.texturing; assert not [m for m in sys.modules if m.startswith('PySide6')]"
    subprocess.run([sys.executable, "-c", code], cwd=REPO, check=True)


def test_stored_texture_is_read_back_with_the_photographs_colours(opened, mesh):
    project, fits = opened
    assert stored_texture_wanted(project, "neutral", fits["neutral"])
    assert not stored_texture_wanted(project, "neutral", None) and not stored_texture_wanted(project, "nope", None)
    tex = read_stored_texture(project, "neutral", fits["neutral"], mesh)
    assert tex.saved and tex.vertices is fits["neutral"].vertices and tex.job.expression == "neutral"
    err = _texel_error(tex.job, project, fits["neutral"], mesh)
    # measured: median 2.3, 90th percentile 7.7 grey levels (the photos blend where they overlap)
    assert len(err) > 300 and np.median(err) < 5.0 and np.percentile(err, 90) < 15.0
    vd = tex.view_dependent()  # the stored texture's photographs read now
    assert vd is tex.view_dependent()


def test_texture_made_in_a_worker_has_the_photographs_colours(opened, mesh):
    project, fits = opened
    inputs = texture_inputs(project, "smile", fits["smile"], mesh)
    snapshot, name, vertices, faces, face_mask = inputs
    assert snapshot is not project and name == "smile" and vertices is fits["smile"].vertices
    steps = []
    job = compute_texture(inputs, 256, progress=lambda *a: steps.append(a))
    assert job.expression == "smile" and job.texture.image.shape == (256, 256, 3) and steps
    err = _texel_error(job, project, fits["smile"], mesh)
    # a quarter of the stored texture's side, a texel spans more of the skin: measured median 3.7,
    # 90th percentile 13 grey levels
    assert np.median(err) < 8.0 and np.percentile(err, 90) < 25.0


def test_texture_needs_a_fitted_mesh(opened, mesh):
    project, fits = opened
    with pytest.raises(FitError, match="'neutral' is not fitted yet"):
        texture_inputs(project, "neutral", None, mesh)
    broken = type(fits["neutral"])(fits["neutral"].cameras, fits["neutral"].points_3d, None, {})
    with pytest.raises(FitError, match="fitted mesh is missing"):
        texture_inputs(project, "neutral", broken, mesh)
    with pytest.raises(ProjectError, match="could not be read"):
        read_stored_texture(project, "neutral", broken, mesh)
