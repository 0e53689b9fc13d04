"""The localised face prior (photomodel.prior.face_prior) against faces of known weights.

The prior here is trained on ICT-FaceKit's own mesh from its first identity modes (a few levels,
so the test stays fast); faces generated from those modes with known coefficients are the truth.
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy.sparse.linalg import lsqr

from photomodel.closest_points import TriangleSurface
from photomodel.modeling.rbf import deform_vertices
from photomodel.prior import face_prior as fp
from photomodel.rendering.renderer import vertex_normals
from photomodel.rig.ict import load_ict

MODES = 20
LEVELS = ((None, 6), (70.0, 5), (40.0, 4))


@pytest.fixture(scope="module")
def ict_prior():
    ict = load_ict()
    modes = ict.identities[:MODES]
    prior = fp.build_face_prior(ict.neutral, ict.faces, modes, np.ones(len(ict.neutral)), levels=LEVELS)
    return ict, modes, prior


def _face(ict, modes, seed):
    c = np.random.default_rng(seed).uniform(-1.5, 1.5, len(modes))
    return ict.neutral + np.einsum("k,knd->nd", c, modes)


def test_patches_are_a_partition_of_unity():
    rng = np.random.default_rng(0)
    V = rng.normal(0.0, 40.0, (600, 3))
    phi = fp._partition(V, np.arange(len(V)), 30.0)
    assert np.allclose(np.asarray(phi.sum(axis=0)).ravel(), 1.0)
    assert phi.shape[0] > 3  # several patches, each local


def test_prior_spans_the_training_modes(ict_prior):
    """Every training mode is (nearly) in the span of the levels: the localisation loses little."""
    ict, modes, prior = ict_prior
    for k in (MODES - 1,):  # the last, least smooth mode
        d = modes[k].ravel()
        x = lsqr(prior.basis, d, iter_lim=60)[0]
        # a patch keeps 98 % of its variance per level; the residual is the 2 % left, well under 20 %
        assert np.linalg.norm(prior.basis @ x - d) < 0.2 * np.linalg.norm(d)


def test_face_recovered_from_landmarks_and_partial_points(ict_prior):
    ict, modes, prior = ict_prior
    truth = _face(ict, modes, 1)
    # a similarity the fit must undo, landmarks plus the points of the upper face only
    s, t = 1.1, np.array([5.0, -3.0, 20.0])
    upper = np.flatnonzero(ict.neutral[:, 1] > np.median(ict.neutral[:, 1]))[::15]
    idx = np.concatenate([ict.landmarks, upper])
    fit = fp.fit_face_prior(prior, ict.neutral, idx, s * truth[idx] + t, ridge=0.05)
    back = (fit.vertices - t) / s
    err = np.linalg.norm(back - truth, axis=1)
    base = np.linalg.norm(ict.neutral - truth, axis=1)
    lower = ict.neutral[:, 1] < np.median(ict.neutral[:, 1])
    assert fit.scale == pytest.approx(s, rel=0.02)
    # the points' half within 0.5 mm; the half without points filled from the statistics:
    # at least 3x closer than the mean face (the truth's distance from it is ~2-4 mm)
    assert err[~lower].mean() < 0.5
    assert err[lower].mean() < base[lower].mean() / 3


def test_weights_stay_in_the_box(ict_prior):
    ict, modes, prior = ict_prior
    far = ict.neutral + 30.0 * modes[0]  # 30 σ: no face the prior knows
    idx = ict.landmarks
    fit = fp.fit_face_prior(prior, ict.neutral, idx, far[idx], similarity=False, landmark_box=2.0)
    assert np.abs(fit.weights).max() <= 2.0 + 1e-6


def test_dense_stage_ignores_stray_points_and_fills_a_hole(ict_prior):
    ict, modes, prior = ict_prior
    truth = _face(ict, modes, 2)
    rng = np.random.default_rng(3)
    nose = np.linalg.norm(truth - truth[ict.landmarks[30]], axis=1) < 25.0
    pts = truth[~nose] + rng.normal(0.0, 0.3, (int((~nose).sum()), 3))
    stray = pts[::20] + rng.uniform(8.0, 20.0, (len(pts[::20]), 1)) * rng.normal(size=(len(pts[::20]), 3))
    cloud = np.concatenate([pts, stray])
    normals = np.concatenate([vertex_normals(truth, ict.faces)[~nose], np.tile([0.0, 0.0, 1.0], (len(stray), 1))])
    fit = fp.fit_face_prior(
        prior, ict.neutral, ict.landmarks, truth[ict.landmarks], scan=fp.ScanData(cloud, normals), dense_iterations=2
    )
    err = np.linalg.norm(fit.vertices - truth, axis=1)
    # noise 0.3 mm per axis, strays beyond the cut-off ignored; the tight dense box (2 σ) keeps
    # some of the truth's ±1.5 σ faces a few tenths of a millimetre out at the ears and neck
    assert np.median(err[~nose]) < 0.5 and err[~nose].mean() < 0.8
    assert err[nose].mean() < 1.5  # the hole (no point) filled from the landmarks and the statistics


def test_prior_deformer_honours_every_click(ict_prior):
    ict, modes, prior = ict_prior
    truth = _face(ict, modes, 4)
    idx = ict.landmarks
    V = fp.PriorDeformer(prior, deform_vertices)(ict.neutral, idx, truth[idx])
    assert np.allclose(V[idx], truth[idx], atol=1e-6)


def _trough(n=41, step=2.0):
    """A square mesh on the trough z = 0.005 x² (mm), ``n`` × ``n`` vertices ``step`` mm apart in x
    and y, centred (curved: the RBF's affine part needs centres off one plane)."""
    x = (np.arange(n) - (n - 1) / 2) * step
    X, Y = np.meshgrid(x, x, indexing="ij")
    V = np.column_stack([X.ravel(), Y.ravel(), 0.005 * X.ravel() ** 2])
    i, j = np.meshgrid(np.arange(n - 1), np.arange(n - 1), indexing="ij")
    a = (i * n + j).ravel()
    faces = np.concatenate([np.column_stack([a, a + n, a + 1]), np.column_stack([a + 1, a + n, a + n + 1])])
    return V, faces


def test_outside_clicks_is_the_distance_to_their_outline_in_any_frame():
    # clicks on a 40 mm square (and its centre) in a turned plane: a point 7 mm beyond an edge,
    # in the plane or lifted off it, is 7 mm outside; the square's inside is 0. Exact by geometry.
    square = np.array([[-20, -20, 0], [20, -20, 0], [20, 20, 0], [-20, 20, 0], [0, 0, 0], [5, -3, 0]], float)
    c, s = np.cos(0.7), np.sin(0.7)
    R = np.array([[1, 0, 0], [0, c, -s], [0, s, c]]) @ np.array([[c, 0, s], [0, 1, 0], [-s, 0, c]])
    t = np.array([10.0, -40.0, 300.0])
    points = np.array([[27, 0, 0], [0, -27, 4], [10, 10, -3], [-20, 20, 0]], float)
    d = fp._outside_clicks(points @ R.T + t, square @ R.T + t)
    assert np.allclose(d, [7.0, 7.0, 0.0, 0.0], atol=1e-9)
    # clicks on a line span no outline: nothing is outside
    line = np.column_stack([np.linspace(0, 30, 5), np.zeros(5), np.zeros(5)])
    assert np.all(fp._outside_clicks(points, line) == 0.0)


def test_slide_onto_offsets_between_the_clicks_and_fades_beyond_them():
    # the prior's surface a trough, the clicks over a 40 mm square (x, y) at offsets
    # h = 1 + 0.05 x along the surface normal: the interpolant reproduces an affine h exactly (its
    # affine part), so inside the square every vertex is lifted by h along its normal, and d mm
    # outside (the clicks' least spread is along z, by symmetry) by h·exp(−(d/fade)²): analytic.
    # Tolerance 0.02 mm: a target's closest point on the flat facets lies up to 0.019 mm from its
    # vertex (measured), so the offsets are met to ~0.006 mm; the fade changes vertices by up to 3 mm
    V, faces = _trough()
    surf = TriangleSurface(V, faces)
    normal = surf.normals_at(*surf.closest(V)[::2])
    clicks = np.array([[x, y] for x in (-20.0, -10.0, 0.0, 10.0, 20.0) for y in (-20.0, 0.0, 20.0)])
    idx = np.array([np.argmin(np.linalg.norm(V[:, :2] - p, axis=1)) for p in clicks])
    h = 1.0 + 0.05 * V[:, 0]
    targets = V[idx] + normal[idx] * h[idx, None]
    out = fp.slide_onto(V, faces, V, idx, targets, fade_mm=5.0)
    outside = np.maximum(np.abs(V[:, :2]).max(axis=1) - 20.0, 0.0)  # distance outside the square
    assert np.allclose(out, V + normal * (h * np.exp(-((outside / 5.0) ** 2)))[:, None], atol=0.02)
    assert np.allclose(out[idx], targets)
    # an outline (vertices of a 60 mm square) widens where the offset is kept: faded beyond ±30 mm
    outline = np.flatnonzero(np.abs(V[:, :2]).max(axis=1) == 30.0)
    wide = fp.slide_onto(V, faces, V, idx, targets, fade_mm=5.0, outline=outline)
    beyond = np.maximum(np.abs(V[:, :2]).max(axis=1) - 30.0, 0.0)
    assert np.allclose(wide, V + normal * (h * np.exp(-((beyond / 5.0) ** 2)))[:, None], atol=0.02)
    # without the fade the offset's trend goes on beyond the clicks (the earlier behaviour)
    assert np.allclose(fp.slide_onto(V, faces, V, idx, targets, fade_mm=0.0), V + normal * h[:, None], atol=0.02)


def test_surface_similarity_finds_a_known_pose_whatever_the_targets_place_on_the_skin():
    # targets anywhere on an ellipsoid's facets (not at vertices, not paired to any), moved by a
    # known similarity: pairing each with its closest point on the model's surface recovers that
    # similarity from a start 3° and 2 mm off. Exact data: only the re-pairing's convergence
    # (linear, like ICP's) limits it: 30 re-pairings left the scale 5e-4 off, 300 pass 1e-4.
    import trimesh

    sphere = trimesh.creation.icosphere(subdivisions=3, radius=1.0)
    X = np.asarray(sphere.vertices) * np.array([80.0, 100.0, 60.0])
    faces = np.asarray(sphere.faces)
    rng = np.random.default_rng(5)
    tri = rng.choice(len(faces), 60, replace=False)
    w = rng.dirichlet(np.ones(3), 60)
    on_skin = np.einsum("kj,kjd->kd", w, X[faces[tri]])
    c, s_ = np.cos(0.3), np.sin(0.3)
    R = np.array([[c, -s_, 0], [s_, c, 0], [0, 0, 1]])
    s, t = 1.1, np.array([5.0, -20.0, 400.0])
    P = s * on_skin @ R.T + t
    a = np.deg2rad(3.0)
    R0 = np.array([[1, 0, 0], [0, np.cos(a), -np.sin(a)], [0, np.sin(a), np.cos(a)]]) @ R
    s1, R1, t1 = fp._surface_similarity(X, faces, P, np.ones(60), (s, R0, t + 2.0), iterations=300)
    assert abs(s1 - s) < 1e-4
    assert np.allclose(R1, R, atol=1e-4)
    assert np.allclose(t1, t, atol=1e-3)
