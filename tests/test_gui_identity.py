"""The rig dock's identity sliders (pytest-qt, offscreen): a new face from the people model, shown in the
3D view as the model says, saved as a project that opens with its rig.

The people model here is a small one of the generic mesh built in the test (8 synthetic people, every
one of the model's 52 expressions; :func:`photomodel.people.multilinear.build_model`), so the test does not
depend on the 68 MB model file (built from ICT data by ``python -m photomodel.people.model_file``); the
wiring is the same for any model file.
"""

from __future__ import annotations

import numpy as np
import pytest

pytest.importorskip("PySide6")
pytest.importorskip("pytestqt")

from PySide6.QtCore import Qt  # noqa: E402
from PySide6.QtWidgets import QFileDialog  # noqa: E402
from studio_window import close_studio, open_studio  # noqa: E402

from app.qt.rig_panel import IDENTITY_STEPS  # noqa: E402
from app.studio.identity import SIGMA_RANGE, IdentityFace  # noqa: E402
from photomodel.people.dataset import EXPRESSIONS  # noqa: E402
from photomodel.people.multilinear import MultilinearModel, build_model  # noqa: E402
from photomodel.project import load_project, load_rig_shapes, read_fitted_mesh  # noqa: E402


@pytest.fixture(scope="module")
def people_model_file(tmp_path_factory, mesh):
    """A people model of the generic mesh: 8 people (a linear deformation of the head each) × the 52
    expressions (a smooth displacement each, scaled per person), ranks (40, full, full)."""
    rng = np.random.default_rng(7)
    V = mesh.vertices
    X = (V - V.mean(axis=0)) / np.ptp(V, axis=0).max()
    people, E = 8, len(EXPRESSIONS)
    P = [X @ (0.08 * rng.standard_normal((3, 3))) * 100.0 for _ in range(people)]  # mm
    D = [np.sin(X @ rng.standard_normal((3, 3)) * 3.0) * 2.0 for _ in range(E)]
    D[0] = np.zeros_like(V)  # the neutral
    T = np.stack([np.stack([V + P[i] + (1.0 + 0.2 * i) * D[e] for e in range(E)], axis=1) for i in range(people)], 1)
    model = build_model(
        T.reshape(len(V) * 3, people, E), (40, None, None), EXPRESSIONS, [f"p{i}" for i in range(people)]
    )
    return model.save(tmp_path_factory.mktemp("people") / "people.npz")


@pytest.fixture
def window(qtbot, tmp_path, errors, fitted_project_copy):
    w = open_studio(qtbot, tmp_path, fitted_project_copy)
    yield w
    close_studio(w)


def _neutral(model: MultilinearModel, identity: np.ndarray) -> np.ndarray:
    """The model's own evaluation (Eq. 5) of the neutral of ``identity``, (n, 3)."""
    return model.face(identity, model.expression_rows[0]).reshape(-1, 3)


def test_identity_sliders_make_a_new_face_that_saves_as_a_project(
    qtbot, window, errors, people_model_file, tmp_path, monkeypatch
):
    model = MultilinearModel.load(people_model_file)
    panel = window.rig_panel.identity
    panel.model_file = people_model_file
    window.rig_dock.show()
    window.rig_dock.raise_()
    assert not panel.sliders and window.model.identity_vertices() is None  # off until ticked
    panel.setChecked(True)  # the group's check box
    assert 3 <= len(panel.sliders) == window.model.identity.modes <= 8 and not errors

    # all sliders at 0: the mean face, i.e. the mean of the model's people's neutrals (linear in identity)
    mean_face = np.mean([_neutral(model, w) for w in model.identity_rows], axis=0)
    shown, caption = window.view3d.vertices()
    np.testing.assert_allclose(shown, mean_face, atol=1e-6)
    assert "the mean face" in caption

    # mode 1 to +1.5σ, mode 3 to −1σ (by the sliders): the model's face at those identity weights
    panel.sliders[0].setValue(IDENTITY_STEPS // 2)
    panel.sliders[2].setValue(-IDENTITY_STEPS // 3)
    face = window.model.identity
    B, sigma = face.directions, face.sigma
    # the sliders: columns of the identity mode, the people's spread along each, the face's change largest first
    np.testing.assert_allclose(B @ B.T, np.eye(len(B)), atol=1e-9)
    spread = ((model.identity_rows - model.identity_rows.mean(axis=0)) @ B.T).std(axis=0)
    np.testing.assert_allclose(spread, sigma, rtol=1e-9)
    change = [np.linalg.norm(np.einsum("abc,b->ac", model.core, s * b)) for s, b in zip(sigma, B, strict=True)]
    assert np.all(np.diff(change) <= 1e-9) and change[-1] > 1e-3 * change[0]
    w = model.identity_rows.mean(axis=0) + 0.5 * SIGMA_RANGE * sigma[0] * B[0] - SIGMA_RANGE / 3 * sigma[2] * B[2]
    expected = _neutral(model, w)
    shown, caption = window.view3d.vertices()
    np.testing.assert_allclose(shown, expected, atol=1e-6)
    assert np.abs(expected - mean_face).max() > 1.0  # the face did change (mm)
    assert "mode 1 +1.5σ" in caption and "mode 3 -1.0σ" in caption
    window.view3d.render_image(400, 400).save("/tmp/identity_face.png")
    window.rig_dock.grab().save("/tmp/identity_dock.png")

    # Save as project…: the neutral fitted, the model's 51 shapes its rig, the skin borrowed
    target = tmp_path / "newface" / "newface.facestudio.json"
    monkeypatch.setattr(QFileDialog, "getSaveFileName", lambda *a, **k: (str(target), ""))
    qtbot.mouseClick(panel.save_button, Qt.MouseButton.LeftButton)
    assert panel.last_saved == target and not errors, errors
    p = load_project(target)
    V, _ = read_fitted_mesh(p, "neutral")
    np.testing.assert_allclose(V, expected, atol=1e-3)  # OBJ precision
    names, deltas = load_rig_shapes(p)
    assert names == list(EXPRESSIONS[1:]) and p.rig.source == "multilinear" and p.rig.neutral == "neutral"
    faces = IdentityFace(model, window.model.identity.values.copy()).faces()
    np.testing.assert_allclose(deltas, faces[1:] - faces[0], atol=1e-3)  # float32 mm
    assert p.expression("neutral").result.texture is not None and p.resolve("results/neutral_texture.png").is_file()

    # Mean face: every slider back to 0
    qtbot.mouseClick(panel.mean_button, Qt.MouseButton.LeftButton)
    assert all(s.value() == 0 for s in panel.sliders)
    np.testing.assert_allclose(window.view3d.vertices()[0], mean_face, atol=1e-6)

    # the new face opens in the studio with its rig, which poses it
    assert window.open_project(target, ask_to_save=False)
    assert not panel.isChecked() and window.model.identity_vertices() is None
    rig = window.model.rig()
    assert rig is not None and rig.arkit == 51
    window.model.set_rig_weight("jawOpen", 1.0)
    k = EXPRESSIONS.index("jawOpen")
    np.testing.assert_allclose(window.view3d.vertices()[0], faces[k], atol=2e-3)


def test_a_missing_people_model_says_how_to_build_it(qtbot, window, errors, tmp_path):
    panel = window.rig_panel.identity
    panel.model_file = tmp_path / "nowhere.npz"
    panel.setChecked(True)
    assert not panel.sliders and window.model.identity_vertices() is None
    assert "python -m photomodel.people.model_file" in panel.hint.text() and panel.hint.isVisible()
