"""Ground-truth tests of the RBF scattered-data interpolant (§5.1.2, Eq. 3)."""

import numpy as np
import pytest

from photomodel.errors import FitError
from photomodel.modeling import rbf
from photomodel.modeling.rbf import MM_PER_INCH, RBFInterpolant, deform_vertices


def face_surface(n, rng):
    """n points on the front of a head-sized ellipsoid (semi-axes 75 × 100 × 90 mm)."""
    th = rng.uniform(-1.2, 1.2, n)
    ph = rng.uniform(-1.0, 1.0, n)
    return np.column_stack([75 * np.sin(th) * np.cos(ph), 100 * np.sin(ph), 90 * np.cos(th) * np.cos(ph)])


@pytest.fixture(params=[13, 250], ids=["13 centres", "250 centres"])
def cloud(request):
    rng = np.random.default_rng(request.param)
    X = face_surface(request.param, rng)
    U = rng.normal(scale=5.0, size=(request.param, 3))  # ~5 mm displacements
    return X, U


def paper_solution(X, U, Q, length_in=64.0):
    """Independent reference: the paper's system written literally, in inches, unscaled,
    solved with numpy's general LU; evaluated at Q. Returns (values (m, 3), c, M, t)."""
    Xi, Qi = X / MM_PER_INCH, Q / MM_PER_INCH
    n = len(Xi)
    phi = np.exp(-np.linalg.norm(Xi[:, None] - Xi[None], axis=2) / length_in)
    P = np.hstack([Xi, np.ones((n, 1))])
    A = np.block([[phi, P], [P.T, np.zeros((4, 4))]])
    sol = np.linalg.solve(A, np.vstack([U, np.zeros((4, U.shape[1]))]))
    c, MT, t = sol[:n], sol[n : n + 3], sol[n + 3]
    phiq = np.exp(-np.linalg.norm(Qi[:, None] - Xi[None], axis=2) / length_in)
    return phiq @ c + Qi @ MT + t, c, MT / MM_PER_INCH, t


def test_exact_interpolation_at_centres(cloud):
    X, U = cloud
    f = RBFInterpolant.fit(X, U)
    # rescaled condition number ≈ 4e4 (250 centres), values ~5 mm: round-off ~ 4e4·1e-16·5 ≈ 2e-11 mm
    np.testing.assert_allclose(f(X), U, atol=1e-8)
    assert f.condition_number < 1e5, f.condition_number


def test_side_conditions_hold(cloud):
    X, U = cloud
    f = RBFInterpolant.fit(X, U)
    c = f.coeffs
    # relative to the size of the terms being summed (cancellation at double precision)
    assert np.all(np.abs(c.sum(axis=0)) <= 1e-10 * np.abs(c).sum(axis=0))
    assert np.all(np.abs(c.T @ X) <= 1e-10 * (np.abs(c).T @ np.abs(X)))


def test_matches_independent_dense_solve(cloud):
    X, U = cloud
    Q = face_surface(400, np.random.default_rng(7)) * 1.1  # off the centres, a bit outside
    f = RBFInterpolant.fit(X, U)
    ref, c, M_T, t = paper_solution(X, U, Q)
    # the reference's condition number is ~1e6 (250 centres): ~1e-9 mm of round-off expected
    np.testing.assert_allclose(f(Q), ref, atol=1e-7)
    # the paper's coefficients (kernel φ itself, inch units do not change c)
    np.testing.assert_allclose(f.coeffs, c, atol=1e-6 * np.abs(c).max())
    np.testing.assert_allclose(f.linear, M_T, atol=1e-9)
    # the values are mm in both systems, so t agrees as is; M differs by the inch conversion
    np.testing.assert_allclose(f.offset, t, atol=1e-7)


def test_reproduces_affine_maps_exactly(cloud):
    X, _ = cloud
    rng = np.random.default_rng(3)
    A = np.eye(3) + rng.normal(scale=0.1, size=(3, 3))
    b = rng.normal(scale=10.0, size=3)
    f = RBFInterpolant.fit(X, X @ A.T + b)
    # the side conditions make the radial part orthogonal to affine functions: c = 0
    assert np.abs(f.coeffs).max() < 1e-7
    np.testing.assert_allclose(f.linear, A.T, atol=1e-10)
    np.testing.assert_allclose(f.offset, b, atol=1e-8)
    Q = rng.normal(scale=300.0, size=(1000, 3))  # far outside the face too
    np.testing.assert_allclose(f(Q), Q @ A.T + b, atol=1e-8)


def test_scalar_values_and_kernel_length():
    rng = np.random.default_rng(0)
    X = face_surface(20, rng)
    u = rng.normal(size=20)
    f = RBFInterpolant.fit(X, u)
    assert f(X).shape == (20,)
    np.testing.assert_allclose(f(X), u, atol=1e-9)
    Q = face_surface(50, rng)
    g = RBFInterpolant.fit(X, u, length_in=4.0)
    ref, *_ = paper_solution(X, u[:, None], Q, length_in=4.0)
    np.testing.assert_allclose(g(Q), ref[:, 0], atol=1e-8)
    assert np.abs(g(Q) - f(Q)).max() > 1e-3  # the length is honoured


def test_locality_and_smoothness():
    """Moving one of 13 features by 5 mm: the field is 5 mm there, dies off with distance,
    does not overshoot and is continuous."""
    rng = np.random.default_rng(0)
    X = face_surface(13, rng)
    U = np.zeros((13, 3))
    U[0] = [0.0, 0.0, 5.0]
    f = RBFInterpolant.fit(X, U)
    Q = face_surface(5000, np.random.default_rng(1))
    mag = np.linalg.norm(f(Q), axis=1)
    dist = np.linalg.norm(Q - X[0], axis=1)
    bands = [(0, 20), (20, 50), (50, 100), (100, 250)]
    band_means = [mag[(dist >= lo) & (dist < hi)].mean() for lo, hi in bands]
    assert all(a > b for a, b in zip(band_means, band_means[1:], strict=False)), band_means
    assert band_means[-1] < 0.1 * 5.0  # measured ≈ 0.07 mm far across the face
    # e^{-r/L} with L ≫ face ≈ the 3D biharmonic spline r: it hardly overshoots (measured < 5 mm)
    assert mag.max() <= 5.0 * 1.05
    # continuity: along a segment through the moved centre, 1 mm steps change f by < 1 mm
    # (the kernel is a cone at its centre; measured ≈ 0.48 mm per mm step)
    line = X[0] + np.linspace(-60, 60, 121)[:, None] * np.array([1.0, 0.0, 0.0])
    steps = np.linalg.norm(np.diff(f(line), axis=0), axis=1)
    assert steps.max() < 1.0


def test_chunked_evaluation_matches(monkeypatch, cloud):
    X, U = cloud
    f = RBFInterpolant.fit(X, U)
    Q = face_surface(1000, np.random.default_rng(5))
    full = f(Q)
    monkeypatch.setattr(rbf, "_CHUNK_ELEMENTS", 3 * len(X) + 1)  # 3 query rows per chunk
    np.testing.assert_allclose(f(Q), full, atol=1e-10)  # BLAS may sum a 1-row block differently


def test_smoothing_approximates():
    rng = np.random.default_rng(2)
    X = face_surface(60, rng)
    U = rng.normal(scale=1.0, size=(60, 3))
    exact = RBFInterpolant.fit(X, U)
    smooth = RBFInterpolant.fit(X, U, smoothing=1e-3)
    err = np.abs(smooth(X) - U).max()
    assert 1e-3 < err < np.abs(U).max()  # no longer interpolates, but stays near the data
    Q = face_surface(500, rng)
    assert np.abs(smooth(Q)).max() < np.abs(exact(Q)).max()  # and is tamer in between


# ---------------------------------------------------------------------------------------------
def test_deform_vertices_lands_constrained_exactly():
    rng = np.random.default_rng(0)
    V = face_surface(2000, rng)
    idx = rng.choice(2000, 13, replace=False)
    T = V[idx] + rng.normal(scale=5.0, size=(13, 3))
    out = deform_vertices(V, idx, T)
    assert out.shape == V.shape
    np.testing.assert_array_equal(out[idx], T)
    # the snap only removed round-off: the interpolant itself reaches the targets
    f = RBFInterpolant.fit(V[idx], T - V[idx])
    np.testing.assert_allclose(V[idx] + f(V[idx]), T, atol=1e-9)
    np.testing.assert_allclose(out, V + f(V), atol=1e-9)


def test_deform_vertices_is_translation_and_rotation_equivariant():
    """Eq. (3) is radial + affine, so moving the whole world moves the answer with it."""
    rng = np.random.default_rng(1)
    V = face_surface(500, rng)
    idx = rng.choice(500, 30, replace=False)
    T = V[idx] + rng.normal(scale=3.0, size=(30, 3))
    th = 0.4
    Rz = np.array([[np.cos(th), -np.sin(th), 0], [np.sin(th), np.cos(th), 0], [0, 0, 1]])
    shift = np.array([100.0, -50.0, 2000.0])
    a = deform_vertices(V, idx, T) @ Rz.T + shift
    b = deform_vertices(V @ Rz.T + shift, idx, T @ Rz.T + shift)
    np.testing.assert_allclose(a, b, atol=1e-8)


def test_deform_vertices_duplicate_constraints():
    rng = np.random.default_rng(4)
    V = face_surface(300, rng)
    idx = np.array([1, 2, 3, 4, 5, 6, 3])
    T = V[idx] + 1.0
    out = deform_vertices(V, idx, T)  # repeat with the same target: merged
    np.testing.assert_allclose(out, V + 1.0, atol=1e-9)
    T[-1] += 2.0
    with pytest.raises(FitError, match="vertex 3 and vertex 3"):
        deform_vertices(V, idx, T)
    # two distinct vertices at the same place (a UV seam) pulled apart: named
    V2 = np.vstack([V, V[10]])
    with pytest.raises(FitError, match="vertex 10 and vertex 300"):
        deform_vertices(V2, np.array([10, 20, 30, 40, 300]), np.vstack([V2[[10, 20, 30, 40]], V2[300] + 1]))


@pytest.mark.parametrize(
    "centres, values, match",
    [
        (np.zeros((3, 3)) + [[0, 0, 0], [1, 0, 0], [0, 1, 0]], np.zeros((3, 3)), "at least 4"),
        (np.array([[0, 0, 0], [10, 0, 0], [0, 10, 0], [10, 10, 0], [5, 5, 0]]), np.zeros((5, 3)), "coplanar"),
        (np.array([[0, 0, 0], [10, 0, 0], [0, 10, 0], [0, 0, np.nan]]), np.zeros((4, 3)), "centre 3"),
        (np.eye(4, 3) * 10, np.array([[0, 0, 0], [0, np.inf, 0], [0, 0, 0], [0, 0, 0]]), "value of centre 1"),
        (np.eye(4, 3), np.zeros((5, 3)), "one row per centre"),
        (np.zeros((4, 2)), np.zeros((4, 3)), r"\(n, 3\)"),
    ],
)
def test_bad_inputs_raise_fiterror(centres, values, match):
    with pytest.raises(FitError, match=match):
        RBFInterpolant.fit(centres, values)


def test_bad_deform_arguments():
    V = face_surface(50, np.random.default_rng(0))
    with pytest.raises(FitError, match="outside the mesh"):
        deform_vertices(V, np.array([1, 2, 3, 99]), np.zeros((4, 3)))
    with pytest.raises(FitError, match="4 constrained vertices but 3 targets"):
        deform_vertices(V, np.array([1, 2, 3, 4]), np.zeros((3, 3)))
    with pytest.raises(FitError, match="indices"):
        deform_vertices(V, np.array([1.0, 2.0, 3.0, 4.0]), np.zeros((4, 3)))
    with pytest.raises(FitError, match="smoothing"):
        deform_vertices(V, np.arange(4), V[:4], smoothing=-1.0)
