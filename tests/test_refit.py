"""Interactive refits (photomodel.modeling.refit): the same answers as the plain pipeline, from caches."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from photomodel.errors import FitError
from photomodel.modeling.fit import FitOptions, fit_expression
from photomodel.modeling.generic_mesh import load_generic_mesh
from photomodel.modeling.rbf import deform_vertices
from photomodel.modeling.refit import CachedDeformer, Refitter
from photomodel.project import load_project

PROJECT = Path(__file__).resolve().parents[1] / "sample_projects" / "james" / "james.facestudio.json"


@pytest.fixture(scope="module")
def mesh():
    return load_generic_mesh()


@pytest.fixture(scope="module")
def fitted(mesh):
    project = load_project(PROJECT)
    return project, fit_expression(project, "neutral", mesh)


@pytest.fixture(scope="module")
def refitter(mesh, fitted):
    """One refitter for the module, with its caches built by a cold fit (the expensive part)."""
    project, _ = fitted
    r = Refitter(mesh)
    r.cold = r.fit(project, "neutral")
    return r


def test_cached_deformer_equals_deform_vertices(mesh):
    rng = np.random.default_rng(3)
    V = mesh.vertices
    idx = rng.choice(len(V), 60, replace=False)
    deformer = CachedDeformer()
    for _ in range(3):
        T = V[idx] + rng.normal(scale=3.0, size=(len(idx), 3))
        got = deformer(V, idx, T)
        want = deform_vertices(V, idx, T)
        # the interpolant is linear in the displacements: W (T - V[idx]) is the same sum of the
        # same terms, up to rounding of an (n+4)-system with condition ~1e4 (mm-sized values)
        np.testing.assert_allclose(got, want, atol=1e-8)
        np.testing.assert_array_equal(got[idx], T)  # exact interpolation, as deform_vertices does
    assert (deformer.misses, deformer.hits) == (1, 2)
    # options are part of the key
    T = V[idx] + 1.0
    np.testing.assert_allclose(
        deformer(V, idx, T, smoothing=1e-4), deform_vertices(V, idx, T, smoothing=1e-4), atol=1e-8
    )
    assert deformer.misses == 2


def test_cached_deformer_errors_and_fallbacks(mesh):
    V = mesh.vertices
    idx = np.array([10, 20, 30, 40, 500, 900])
    deformer = CachedDeformer(max_entries=1)
    T = V[idx].copy()
    T[2, 0] = np.nan
    with pytest.raises(FitError, match="vertex 30"):
        deformer(V, idx, T)
    # a vertex constrained twice with the same target: merged by the plain solver
    idx2 = np.concatenate([idx, idx[:1]])
    T2 = np.concatenate([V[idx] + 1.0, V[idx[:1]] + 1.0])
    np.testing.assert_allclose(deformer(V, idx2, T2), deform_vertices(V, idx2, T2), atol=1e-8)
    with pytest.raises(FitError, match="outside the mesh"):
        deformer(V, np.array([0, 1, 2, len(V)]), V[:4])
    with pytest.raises(ValueError):
        CachedDeformer(max_entries=0)


def test_cold_refit_is_the_plain_fit(refitter, fitted):
    project, plain = fitted
    result = refitter.cold
    np.testing.assert_allclose(result.vertices, plain.vertices, atol=1e-6)
    for a, b in zip(result.cameras, plain.cameras, strict=True):
        np.testing.assert_allclose(a.R, b.R, atol=1e-12)
    assert result.report["rms_px"] == pytest.approx(plain.report["rms_px"], rel=1e-9)


def test_warm_refit_is_one_more_curve_pass(mesh, fitted, refitter):
    project, plain = fitted
    hits = refitter.deformer.hits
    warm = refitter.fit(project, "neutral", previous=plain)
    assert refitter.deformer.hits >= hits + 2  # pose-only and full vertex sets both cached
    # close to the full fit: the curve passes settle to well under a millimetre on average
    assert np.linalg.norm(warm.vertices - plain.vertices, axis=1).mean() < 0.2
    # Without the final camera re-estimation the warm refit is exactly one more curve pass:
    # curves parameterised on the two-pass result, one pass, equals the third pass.
    paper = FitOptions(bundle_all=False)
    two = fit_expression(project, "neutral", mesh, paper)
    warm_paper = Refitter(mesh, paper).fit(project, "neutral", previous=two)
    three = fit_expression(project, "neutral", mesh, replace(paper, curve_passes=3))
    np.testing.assert_allclose(warm_paper.vertices, three.vertices, atol=1e-6)


def test_refit_after_a_moved_click_follows_the_click(mesh, fitted, refitter):
    project, plain = fitted
    misses = refitter.deformer.misses
    photo = project.expression("neutral").photo("front")
    old = photo.points["jaw_05"].copy()
    try:
        photo.points["jaw_05"] = old + np.array([6.0, 0.0])
        moved = refitter.fit(project, "neutral", previous=plain)
        scratch = fit_expression(project, "neutral", mesh)
    finally:
        photo.points["jaw_05"] = old
    assert refitter.deformer.misses == misses  # the moved click kept the vertex set: no new solve
    v = project.feature("jaw_05").vertex
    # the click moved 6 px to the right in the front photo: its vertex follows the click
    k = moved.photo_ids.index("front")
    du = moved.cameras[k].project(moved.vertices[[v]])[0, 0] - plain.cameras[k].project(plain.vertices[[v]])[0, 0]
    assert du > 1.0
    # and the refit agrees with a fit from scratch of the edited clicks (same as above: ≈ a curve pass)
    assert np.linalg.norm(moved.vertices - scratch.vertices, axis=1).mean() < 0.2


def test_warm_start_of_another_mesh_is_ignored(fitted, refitter):
    project, plain = fitted
    result = refitter.fit(project, "neutral", previous=np.zeros((5, 3)))
    np.testing.assert_allclose(result.vertices, plain.vertices, atol=1e-6)
