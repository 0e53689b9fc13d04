"""The studio's fitting (app/studio/fitting.py) without Qt: fits, overlays and click residuals of the
sample project, scored against its ground_truth.json (true cameras, noise-free clicks, σ = 1 px noise)."""

from __future__ import annotations

import copy
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from app.studio.fitting import FitState, Fitting, click_residuals, predicted_uv, worst_clicks
from photomodel.alignment import align_to_truth, camera_errors
from photomodel.modeling.fit import fit_expression
from photomodel.modeling.rbf import deform_vertices
from photomodel.prior.face_prior import prior_deformer
from photomodel.project import load_project, record_fit

REPO = Path(__file__).resolve().parents[1]
PROJECT = REPO / "sample_projects" / "james" / "james.facestudio.json"


@pytest.fixture(scope="module")
def fitted(mesh):
    """``(project, Fitting, FitState)``: the neutral of the sample fitted once through :class:`Fitting`."""
    project = load_project(PROJECT)
    fitting = Fitting(mesh)
    result, seconds, cold = fitting.compute(copy.deepcopy(project), "neutral")
    assert cold and seconds > 0  # the first fit builds the RBF solves
    state = FitState.of_result(record_fit(project, "neutral", result), result, seconds)
    return project, fitting, state


@pytest.fixture
def true_fit(sample_truth):
    """The truth as a fit without a mesh: the true cameras and 3D feature points."""
    return FitState(sample_truth.cameras["neutral"], sample_truth.features_3d, None, {})


def test_imports_no_qt():
    code = "import sys, app.studio.fitting; assert not [m for m in sys.modules if m.startswith('PySide6')]"
    subprocess.run([sys.executable, "-c", code], cwd=REPO, check=True)


def test_fit_finds_the_true_cameras_and_refits_warm(fitted, sample_truth, mesh):
    project, fitting, state = fitted
    result = state.result
    assert _camera_errors(result, sample_truth)["rot_err_deg"].max() < 1.0  # as tests/test_fit.py: measured ≤ 0.4°
    assert state.vertices.shape == mesh.vertices.shape and not state.saved
    assert state.warm_start() is result and set(state.cameras) == set(result.photo_ids)

    again, seconds, cold = fitting.compute(copy.deepcopy(project), "neutral", previous=state.warm_start())
    assert not cold and seconds > 0  # the same clicks: the cached RBF solves serve the refit
    assert _camera_errors(again, sample_truth)["rot_err_deg"].max() < 1.0


def _camera_errors(result, truth) -> dict:
    """The fit's cameras moved onto the truth by the similarity of its 3D feature points, against the true ones."""
    cams, _ = align_to_truth(result.cameras, result.points_3d, truth.true_points(result.feature_names))
    return camera_errors(cams, [truth.cameras["neutral"][pid] for pid in result.photo_ids])


def test_residuals_of_the_true_cameras_are_the_click_noise(true_fit, sample_truth):
    photos = load_project(PROJECT).expression("neutral").photos
    res = click_residuals(true_fit, photos)
    px = np.array([v for d in res.values() for v in d.values()])
    # |2-D Gaussian noise| with σ = 1 px is Rayleigh: median √(2 ln 2) = 1.18 px (≈ 600 clicks: ±0.05),
    # and a click beyond 5 σ has odds of 4e-6
    assert len(px) > 500 and 1.05 < np.median(px) < 1.3 and px.max() < 5.0
    worst = worst_clicks(res, 5)
    assert [w[0] for w in worst] == sorted(px, reverse=True)[:5]
    pid, name = worst[0][1:]
    photo = next(p for p in photos if p.id == pid)
    photo.hidden.add(name)  # a hidden click is not measured
    assert name not in click_residuals(true_fit, photos)[pid]
    assert click_residuals(None, photos) == {}


def test_predicted_clicks_are_the_true_ones(true_fit, fitted, sample_truth):
    for pid, clean in sample_truth.clean_points["neutral"].items():
        for name, uv in clean.items():  # the true point through the true camera: the noise-free click
            np.testing.assert_allclose(predicted_uv(true_fit, pid, name, None), uv, atol=1e-3)
    assert predicted_uv(true_fit, "no_such_photo", "nose_tip", None) is None
    assert predicted_uv(None, "front", "nose_tip", None) is None
    # the fitted mesh's vertex through the fitted camera lands near the noise-free click
    project, _, state = fitted
    names = [n for n in sample_truth.clean_points["neutral"]["front"] if n in project.feature_names()]
    errs = [
        np.linalg.norm(
            predicted_uv(state, "front", n, project.feature(n).vertex)
            - sample_truth.clean_points["neutral"]["front"][n]
        )
        for n in names
    ]
    assert len(errs) > 20 and np.median(errs) < 2.0


def test_overlays_are_drawn_around_the_face_and_cached(fitted, sample_truth):
    project, fitting, state = fitted
    made = fitting.overlays(state.result, ["front", "no_such_photo"], fitting.overlay_lines)
    assert set(made) == {"front"}  # a photo without a camera is skipped
    shown = fitting.overlay(state, "left")
    assert shown is not None and fitting.overlay(state, "left") is shown  # computed once, then cached
    assert fitting.overlay(state, "no_such_photo") is None and fitting.overlay(None, "left") is None
    for pid, overlay in (("front", made["front"]), ("left", shown)):
        assert overlay.note is None and len(overlay.segments) > 1000
        drawn = overlay.segments.reshape(-1, 2)
        lo, hi = drawn.min(axis=0), drawn.max(axis=0)
        seen = sample_truth.visible["neutral"][pid]
        clicks = np.array([uv for n, uv in sample_truth.clean_points["neutral"][pid].items() if n in seen])
        # every true click the photo sees lies inside the box of the drawn face (within a pixel)
        assert np.all(clicks >= lo - 1.0) and np.all(clicks <= hi + 1.0), (pid, lo, hi)


def test_the_fit_workers_renderer_outlives_its_tasks(mesh):
    """A QThreadPool worker runs each task under a fresh Python thread state, which empties
    ``threading.local``: the overlay's renderer is kept per OS thread instead, not rebuilt (and its
    OpenGL context leaked) for every fit."""
    import threading

    from PySide6.QtCore import QRunnable, QThreadPool

    fitting = Fitting(mesh)
    seen = []

    class Task(QRunnable):
        def __init__(self):
            super().__init__()
            self.done = threading.Event()

        def run(self):
            seen.append(fitting.thread_renderer())
            self.done.set()

    pool = QThreadPool()
    pool.setMaxThreadCount(1)
    pool.setExpiryTimeout(-1)  # as app.qt.workers.FitController's
    for _ in range(3):
        task = Task()
        pool.start(task)
        assert task.done.wait(30)  # not pool.waitForDone(): that ends the pool's threads
    pool.waitForDone(30_000)
    assert len(seen) == 3 and seen[0] is not None
    assert all(r is seen[0] for r in seen) and not seen[0].released


def test_studio_fit_uses_the_face_prior_like_the_cli(fitted, mesh):
    """The studio's fit from scratch is ``facestudio fit``'s default (the prior around the RBF);
    a refit after an edit deforms that fit by the cached RBF, meeting every click; without the
    prior the plain RBF fit comes back."""
    project, fitting, state = fitted
    cli = fit_expression(copy.deepcopy(project), "neutral", mesh, deform=prior_deformer(mesh, deform_vertices))
    # the refitter's cached RBF equals deform_vertices to rounding (tests/test_refit.py: 1e-8 mm)
    np.testing.assert_allclose(state.vertices, cli.vertices, atol=1e-6)
    assert fitting.refitter.wrapped is not None and fitting.refitter.wrapped.last is not None

    edited = copy.deepcopy(project)
    photo = edited.expression("neutral").photo("front")
    photo.points["jaw_05"] = photo.points["jaw_05"] + np.array([6.0, 0.0])
    hits = fitting.refitter.deformer.hits
    warm, seconds, cold = fitting.compute(edited, "neutral", previous=state.warm_start())
    assert not cold and fitting.refitter.deformer.hits > hits  # the full fit's answers: cached solves
    # the moved click is met: its vertex projects onto it in the front photo (the RBF snaps targets)
    v = edited.feature("jaw_05").vertex
    k = warm.photo_ids.index("front")
    uv = warm.cameras[k].project(warm.vertices[v][None])[0]
    assert np.linalg.norm(uv - photo.points["jaw_05"]) < 3.0  # the triangulated point, ~1 px from the click
    # elsewhere the refit stays on the full fit's face: a 6 px move is ~3 mm at one vertex, and the
    # RBF spreads it over its neighbours only (plus the one curve pass, ~0.04 mm: tests/test_refit.py)
    assert np.linalg.norm(warm.vertices - state.vertices, axis=1).mean() < 0.2

    plain = Fitting(mesh, face_prior=False).compute(copy.deepcopy(project), "neutral")[0]
    np.testing.assert_allclose(plain.vertices, fit_expression(project, "neutral", mesh).vertices, atol=1e-6)
