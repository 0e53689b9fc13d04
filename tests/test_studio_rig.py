"""The studio's rig (app/studio/rig.py) without Qt: the fitted sample's photographed expressions as
shapes on its neutral, checked against the true expression motion of ground_truth.json; a rig made,
stored, read back and posed."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from app.studio import project_file
from app.studio.rig import photographed_deltas, read_rig, rig_job, rig_neutral, store_new_rig
from photomodel.alignment import similarity_transform
from photomodel.errors import FitError, ProjectError

REPO = Path(__file__).resolve().parents[1]


@pytest.fixture
def opened(fitted_project_copy, mesh):
    """``(project, fits)``: a copy of the fitted sample as the studio opens it (the rig is written next to it)."""
    return project_file.open_project(fitted_project_copy, mesh)


def test_imports_no_qt():
    code = "import sys, app.studio.rig; assert not [m for m in sys.modules if m.startswith('PySide6')]"
    subprocess.run([sys.executable, "-c", code], cwd=REPO, check=True)


def test_photographed_shapes_move_the_features_as_the_truth_does(opened, mesh, sample_truth):
    project, fits = opened
    N = fits["neutral"].vertices
    names, deltas = photographed_deltas(project, fits, "neutral", N, mesh.face_mask)
    assert names == ["smile", "open_mouth", "brows_raised", "frown"]
    truth = sample_truth.expression_features_3d
    features = [f for f in project.features if f.name in truth["neutral"]]
    # the fitted neutral onto the true one: the rig's millimetres into the truth's
    s, R, _ = similarity_transform(N[[f.vertex for f in features]], [truth["neutral"][f.name] for f in features])
    for name, delta in zip(names, deltas, strict=True):
        moved = delta[[f.vertex for f in features]] @ (s * R).T
        true = np.array([truth[name][f.name] - truth["neutral"][f.name] for f in features])
        err = np.linalg.norm(moved - true, axis=1)
        # measured: median 0.42 mm, worst 1.7 mm, for true motions of up to 19 mm (open mouth)
        assert np.median(err) < 1.0 and err.max() < 3.0, (name, np.median(err), err.max())
        assert np.linalg.norm(true, axis=1).max() > 4.0  # each expression moves some feature visibly


def test_rig_made_stored_read_back_and_posed(opened, mesh):
    project, fits = opened
    assert read_rig(project, fits, mesh.face_mask) == (None, None)  # the sample has no rig yet
    assert rig_neutral(project) == "neutral"
    with pytest.raises(FitError, match="'neutral' is not fitted"):
        rig_job(project, {}, mesh)
    neutral, made = rig_job(project, fits, mesh)()
    assert neutral == "neutral" and made.deltas.shape[1:] == mesh.vertices.shape
    unsaved = project_file.blank_project(mesh, "unsaved")
    with pytest.raises(ProjectError, match="save the project first"):
        store_new_rig(unsaved, neutral, made)
    store_new_rig(project, neutral, made)
    assert project.resolve(project.rig.file).is_file()

    shown, problem = read_rig(project, fits, mesh.face_mask)
    assert problem is None and shown.neutral == "neutral" and shown.arkit == len(made.names)
    assert shown.names == list(made.names) + ["smile", "open_mouth", "brows_raised", "frown"]
    assert shown.posed() is shown.vertices and not shown.weights.any()
    assert shown.set_weight("smile", 2.0) and shown.weights[shown.names.index("smile")] == 1.0  # clipped
    assert not shown.set_weight("smile", 1.0)  # no change
    # the photographed smile at full weight: the fitted smile registered onto the neutral
    registered = fits["neutral"].vertices + shown.deltas[shown.names.index("smile")]
    np.testing.assert_allclose(shown.posed(), registered)
    with pytest.raises(ProjectError, match="no shape 'nope'"):
        shown.set_weight("nope", 0.5)
    assert shown.reset() and not shown.reset() and shown.posed() is shown.vertices

    without = {k: v for k, v in fits.items() if k != "neutral"}
    assert read_rig(project, without, mesh.face_mask) == (None, "the rig's neutral 'neutral' has no fitted mesh")
