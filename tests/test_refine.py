"""Ground-truth tests of triangulation and curve correspondences (§5.1.3)."""

import numpy as np
import pytest

from photomodel.camera import orbit_camera
from photomodel.errors import FitError
from photomodel.modeling.refine import curve_observations, place_at_depth, refine_points, triangulate

AXES = np.array([75.0, 100.0, 90.0])  # head-sized ellipsoid, mm


def ellipsoid(theta, phi):
    """Points on the ellipsoid at longitude theta (0 = front, + towards +x) and latitude phi."""
    theta, phi = np.broadcast_arrays(theta, phi)
    return np.column_stack(
        [AXES[0] * np.sin(theta) * np.cos(phi), AXES[1] * np.sin(phi), AXES[2] * np.cos(theta) * np.cos(phi)]
    )


def face_cloud(n, seed):
    rng = np.random.default_rng(seed)
    return rng.normal(size=(n, 3)) * [50.0, 70.0, 40.0]


@pytest.fixture
def cameras():
    # three photos round the face with different lenses and distances
    return [
        orbit_camera(-40, 1200, 1600, focal_mm=50, distance_mm=600),
        orbit_camera(0, 1200, 1600, focal_mm=85, distance_mm=900, elevation_deg=5),
        orbit_camera(35, 1200, 1600, focal_mm=35, distance_mm=450),
    ]


def project_all(cameras, X):
    return np.stack([c.project(X) for c in cameras])


def rms_3d(P, X):
    return float(np.sqrt(np.mean(np.sum((P - X) ** 2, axis=1))))


# ---------------------------------------------------------------------------------------------
# triangulation
@pytest.mark.parametrize("refine", [True, False])
def test_triangulation_exact_on_clean_data(cameras, refine):
    X = face_cloud(500, 0)
    obs = project_all(cameras, X)
    obs[2, :100] = np.nan  # some points seen in two photos only
    tri = triangulate(cameras, obs, refine=refine)
    # exact rays meet in one point; only round-off remains (~1e-13 mm measured)
    assert np.abs(tri.points - X).max() < 1e-6
    assert np.nanmax(tri.residual_px) < 1e-6
    assert tri.ok.all()
    np.testing.assert_array_equal(tri.n_views, np.r_[np.full(100, 2), np.full(400, 3)])
    points, residual = tri  # unpacks like a (points, residual_px) pair
    assert points.shape == (500, 3) and residual.shape == (500,)


def test_one_pixel_noise_matches_predicted_error(cameras):
    """With σ = 1 px per coordinate the maximum-likelihood error covariance of a point is
    σ² (JᵀJ)⁻¹ (J the stacked projection Jacobians at the true point). The empirical RMS 3D
    error over 2000 points must agree with the predicted one; the sampling error of an RMS of
    2000 squared errors is ~3 %, so ±15 % is a safe band that still catches a bias."""
    X = face_cloud(2000, 1)
    rng = np.random.default_rng(2)
    obs = project_all(cameras, X) + rng.normal(size=(3, 2000, 2))
    tri = triangulate(cameras, obs)

    # predicted: numerical Jacobians of each camera's projection at the true points
    eps = 1e-4
    J = np.zeros((2000, 6, 3))
    for a in range(3):
        dX = np.zeros(3)
        dX[a] = eps
        J[:, :, a] = np.concatenate([(c.project(X + dX) - c.project(X - dX)) / (2 * eps) for c in cameras], axis=1)
    cov = np.linalg.inv(np.einsum("nki,nkj->nij", J, J))
    predicted = float(np.sqrt(np.mean(np.trace(cov, axis1=1, axis2=2))))
    measured = rms_3d(tri.points, X)
    assert 0.3 < predicted < 0.8  # sanity: ~0.4 mm/px pixel footprint (measured 0.54 mm)
    assert 0.85 * predicted < measured < 1.15 * predicted, (measured, predicted)
    # the residual of an unbiased fit with 2k−3 degrees of freedom: E[rms²] = σ²·(2k−3)/k
    assert abs(np.sqrt(np.mean(tri.residual_px**2)) - np.sqrt((2 * 3 - 3) / 3)) < 0.05


def test_gauss_newton_beats_ray_midpoint_with_mixed_resolutions():
    """The linear ray fit weighs views by mm, the refinement by pixels (beyond the paper).
    With one photo 4× sharper than the others, pixel weighting is the ML answer and must be
    clearly better (measured over 6 seeds: 0.43 vs 0.50–0.52 mm RMS)."""
    cams = [orbit_camera(-35, 4000, 6000), orbit_camera(0, 1000, 1500), orbit_camera(35, 1000, 1500)]
    X = face_cloud(3000, 3)
    obs = project_all(cams, X) + np.random.default_rng(4).normal(size=(3, 3000, 2))
    gn = rms_3d(triangulate(cams, obs).points, X)
    linear = rms_3d(triangulate(cams, obs, refine=False).points, X)
    assert gn < 0.9 * linear, (gn, linear)


def test_single_view_and_unobserved_points(cameras):
    X = face_cloud(4, 5)
    obs = project_all(cameras, X)
    obs[1:, 0] = np.nan  # point 0: one photo
    obs[:, 1] = np.nan  # point 1: none
    tri = triangulate(cameras, obs)
    assert np.isnan(tri.points[:2]).all() and np.isnan(tri.residual_px[:2]).all()
    np.testing.assert_allclose(tri.points[2:], X[2:], atol=1e-6)
    np.testing.assert_array_equal(tri.n_views, [1, 0, 3, 3])
    problems = tri.problems(["nose", "chin", "a", "b"])
    assert set(problems) == {0, 1}
    assert "nose: seen in 1 photo(s)" in problems[0] and "chin: seen in 0" in problems[1]


def test_parallel_rays_are_flagged_not_solved():
    X = face_cloud(10, 6)
    same = orbit_camera(0, 1000, 1500)
    close = orbit_camera(0.5, 1000, 1500)
    far = orbit_camera(30, 1000, 1500)
    # the same camera twice: exactly parallel rays, a singular system that must not raise
    tri = triangulate([same, same.copy()], project_all([same, same], X))
    assert np.isnan(tri.points).all() and tri.near_parallel.all()
    np.testing.assert_allclose(tri.parallax_deg, 0.0, atol=1e-5)
    # 0.5° apart: solvable in exact arithmetic, but 1 px would move the depth by ~5 cm
    tri = triangulate([same, close], project_all([same, close], X))
    assert tri.near_parallel.all() and np.isnan(tri.points).all()
    assert "nearly parallel" in tri.problems()[0]
    # the threshold is the caller's: lowered, the clean data are recovered
    tri = triangulate([same, close], project_all([same, close], X), min_parallax_deg=0.1)
    np.testing.assert_allclose(tri.points, X, atol=1e-5)
    tri = triangulate([same, far], project_all([same, far], X))
    assert not tri.near_parallel.any() and np.all(np.abs(tri.parallax_deg - 30) < 15)


def test_place_at_depth_keeps_the_rays_and_takes_the_reference_depth():
    """Views a degree apart measure no depth: each point goes on its rays at the reference's depth."""
    X = face_cloud(200, 7)
    cams = [orbit_camera(a, 1000, 1500, distance_mm=600) for a in (-0.8, 0.0, 0.7)]
    obs = project_all(cams, X)
    axis = np.mean([c.R[2] for c in cams], axis=0)
    a = axis / np.linalg.norm(axis)
    # the true depth as reference: the truth, to round-off (the rays meet there)
    tri = place_at_depth(cams, obs, X, axis)
    np.testing.assert_allclose(tri.points, X, atol=1e-6)
    assert tri.ok.all() and np.nanmax(tri.residual_px) < 1e-6
    # a reference 10 mm off in depth: the point's depth is the reference's, and it stays on its
    # rays — across the line of sight it moves by 10 mm × the slant of its ray, not 10 mm
    ref = X + 10.0 * a
    tri = place_at_depth(cams, obs, ref, axis)
    np.testing.assert_allclose(tri.points @ a, ref @ a, atol=1e-9)
    lateral = lambda d: np.linalg.norm(d - (d @ a)[:, None] * a, axis=1)  # noqa: E731
    slant = lateral(X - cams[1].center) / ((X - cams[1].center) @ a)
    # (each camera's ray has its own slant: the cameras ~10 mm apart at 600 mm add ≤ 0.02)
    assert np.all(lateral(tri.points - X) <= 10.0 * (slant + 0.02))
    assert np.nanmax(tri.residual_px) < 0.5  # still on the rays: the views barely disagree
    # where triangulation gives up (rays < 2° apart), every point is placed; one view is not enough
    assert triangulate(cams, obs).near_parallel.all()
    obs[1:, :5] = np.nan
    tri = place_at_depth(cams, obs, X, axis)
    assert np.isnan(tri.points[:5]).all() and tri.ok[5:].all()
    assert "seen in 1 photo" in tri.problems()[0]


def test_refine_points_with_a_depth_reference_places_instead_of_triangulating():
    X = face_cloud(30, 8)
    cams = [orbit_camera(a, 1000, 1500, distance_mm=600) for a in (-0.8, 0.0, 0.8)]
    obs = project_all(cams, X)
    axis = np.mean([c.R[2] for c in cams], axis=0)
    verts = np.arange(30)
    plain = refine_points(cams, X, point_vertices=verts, point_observations=obs)
    assert len(plain.vertices) == 0 and len(plain.dropped) == 30  # all nearly parallel
    held = refine_points(cams, X, point_vertices=verts, point_observations=obs, depth_reference=(X, axis))
    np.testing.assert_array_equal(held.vertices, verts)
    np.testing.assert_allclose(held.targets, X, atol=1e-6)


def test_rays_meeting_behind_the_cameras():
    cams = [orbit_camera(-30, 1000, 1500), orbit_camera(30, 1000, 1500)]
    behind = np.array([[0.0, 10.0, 2500.0]])  # behind both cameras (they sit at z ≈ 520 mm)
    obs = project_all(cams, behind)  # lines through these pixels meet at that point
    tri = triangulate(cams, obs)
    assert tri.behind_camera.all() and np.isnan(tri.points).all()
    assert "behind a camera" in tri.problems()[0]


def test_malformed_observations(cameras):
    with pytest.raises(FitError, match="one row per camera"):
        triangulate(cameras, np.zeros((2, 5, 2)))
    obs = np.zeros((3, 5, 2))
    obs[1, 4, 0] = np.nan
    with pytest.raises(FitError, match="point 4 in photo 1 has only one NaN"):
        triangulate(cameras, obs)
    obs[1, 4, 0] = np.inf
    with pytest.raises(FitError, match="infinite"):
        triangulate(cameras, obs)


# ---------------------------------------------------------------------------------------------
# curves
PHI = 0.3  # the curve runs at 30 mm above the equator ...
THETA_END = 1.3  # ... from the front (θ = 0) round to the side of the head (θ = 1.3 rad ≈ 75°)


@pytest.fixture
def curve_scene():
    """A 12-vertex mesh polyline on a known 3D curve and three photos that see all of it, the
    front one strongly foreshortened at the lateral end and the side one at the front end."""
    cams = [
        orbit_camera(0, 1200, 1600, focal_mm=50),
        orbit_camera(40, 1200, 1600, focal_mm=85, distance_mm=900),
        orbit_camera(75, 1200, 1600, focal_mm=35, distance_mm=450),
    ]
    theta = THETA_END * np.linspace(0, 1, 12) ** 1.3  # uneven vertex spacing, like a mesh
    truth = ellipsoid(theta, PHI)
    normals = truth / AXES**2
    normals /= np.linalg.norm(normals, axis=1, keepdims=True)
    for c in cams:  # every vertex faces every camera (the scene needs no occlusion test)
        to_cam = c.center - truth
        to_cam /= np.linalg.norm(to_cam, axis=1, keepdims=True)
        assert np.sum(normals * to_cam, axis=1).min() > 0.03  # grazing (≈ 87°) at worst
    polyline = np.arange(3, 15)
    mesh = np.zeros((20, 3))
    # the "current fitted mesh" is not the truth: 2 % too big and shifted by ~2 mm
    mesh[polyline] = (truth - truth.mean(axis=0)) * 1.02 + truth.mean(axis=0) + [1.5, -1.0, 0.5]
    return cams, mesh, polyline, truth


def hand_drawn(cams, seed, reverse_view=2, noise_px=0.3):
    """The artist traces the true curve: dense samples of its projection with a different
    number and spacing of points in each photo, 0.3 px jitter, one photo drawn backwards."""
    rng = np.random.default_rng(seed)
    drawn = {}
    for v, q in enumerate((40, 90, 25)):
        if v == 1:
            theta = np.sort(np.r_[0.0, rng.uniform(0, THETA_END, q - 2), THETA_END])
        else:
            theta = np.linspace(0, THETA_END, q)
        d = cams[v].project(ellipsoid(theta, PHI)) + rng.normal(scale=noise_px, size=(q, 2))
        drawn[v] = d[::-1] if v == reverse_view else d
    return drawn


def test_curves_recover_polyline_vertices(curve_scene):
    cams, mesh, polyline, truth = curve_scene
    # clean drawings: only the 2 % error of the current mesh (it sets the arc-length spacing)
    # and chord-vs-arc differences remain; measured 0.14 mm max
    obs = curve_observations(cams, mesh, polyline, hand_drawn(cams, 0, noise_px=0.0))
    assert obs.shape == (3, 12, 2) and np.isfinite(obs).all()
    err = np.linalg.norm(triangulate(cams, obs).points - truth, axis=1)
    assert err.max() < 0.2, err
    # 0.3 px jitter on every drawn sample moves the ends and stretches the arc length unevenly;
    # over 40 seeds the RMS error was ≤ 0.49 mm (median 0.23) and the max ≤ 0.70 mm
    obs = curve_observations(cams, mesh, polyline, hand_drawn(cams, 0))
    err = np.linalg.norm(triangulate(cams, obs).points - truth, axis=1)
    assert np.sqrt(np.mean(err**2)) < 0.5 and err.max() < 0.8, err


def test_projected_arc_length_beats_3d_arc_length(curve_scene):
    """On a foreshortened view the 3D arc length misplaces vertices by tens of pixels (the
    lateral end is compressed in the front photo); the projected one stays within ~1 px."""
    cams, mesh, polyline, truth = curve_scene
    drawn = hand_drawn(cams, 1)
    true_px = project_all(cams, truth)
    err = {}
    err3 = {}
    for mode in ("projected", "3d"):
        obs = curve_observations(cams, mesh, polyline, drawn, parameterisation=mode)
        err[mode] = np.linalg.norm(obs - true_px, axis=2).max(axis=1)  # per photo, px
        err3[mode] = np.linalg.norm(triangulate(cams, obs).points - truth, axis=1).max()
    # foreshortened front and side photos: measured ≈ 0.7 / 0.5 px against ≈ 41 / 39 px;
    # the 40° photo sees the curve nearly flat-on: 1.5 px against 6.6 px
    assert err["projected"][0] < 2.0 and err["3d"][0] > 20.0
    assert np.all(err["projected"][[0, 2]] < 0.05 * err["3d"][[0, 2]])
    assert np.all(err["projected"] < err["3d"])
    assert err3["projected"] < 0.5 and err3["3d"] > 5.0  # measured 0.25 mm vs 18.6 mm


def test_drawing_direction_is_irrelevant(curve_scene):
    cams, mesh, polyline, _ = curve_scene
    drawn = hand_drawn(cams, 2, reverse_view=None)
    forward = curve_observations(cams, mesh, polyline, drawn)
    backward = curve_observations(cams, mesh, polyline, {v: d[::-1] for v, d in drawn.items()})
    np.testing.assert_allclose(backward, forward, atol=1e-9)
    # without orientation the reversed drawing pairs the ends the wrong way round
    wrong = curve_observations(cams, mesh, polyline, {0: drawn[0][::-1]}, orient=False)
    assert np.linalg.norm(wrong[0, 0] - forward[0, 0]) > 100


def test_views_without_drawing_are_nan(curve_scene):
    cams, mesh, polyline, _ = curve_scene
    drawn = hand_drawn(cams, 3)
    obs = curve_observations(cams, mesh, polyline, {1: drawn[1]})
    assert np.isnan(obs[[0, 2]]).all() and np.isfinite(obs[1]).all()
    # the drawing's end points are the polyline's end points (after orientation)
    np.testing.assert_allclose(obs[1, 0], drawn[1][0])
    np.testing.assert_allclose(obs[1, -1], drawn[1][-1])


def test_repeated_drawn_points_are_harmless(curve_scene):
    cams, mesh, polyline, _ = curve_scene
    d = hand_drawn(cams, 4)[0]
    stuttered = np.repeat(d, 2, axis=0)  # a tablet that reports every sample twice
    np.testing.assert_allclose(
        curve_observations(cams, mesh, polyline, {0: stuttered}),
        curve_observations(cams, mesh, polyline, {0: d}),
        atol=1e-9,
    )


@pytest.mark.parametrize(
    "drawn, polyline, match",
    [
        ({5: np.zeros((4, 2))}, None, "only 3 photos"),
        ({0: np.ones((3, 2))}, None, "2 distinct points"),
        ({0: np.array([[0.0, 0.0], [np.nan, 1.0]])}, None, "NaN"),
        ({0: np.zeros((4, 3))}, None, r"\(q, 2\)"),
        ({0: np.array([[0.0, 0.0], [1.0, 1.0]])}, np.array([3, 99]), "outside the mesh"),
        ({0: np.array([[0.0, 0.0], [1.0, 1.0]])}, np.array([3]), ">= 2 vertex"),
    ],
)
def test_bad_curves_raise(curve_scene, drawn, polyline, match):
    cams, mesh, default_polyline, _ = curve_scene
    with pytest.raises(FitError, match=match):
        curve_observations(cams, mesh, default_polyline if polyline is None else polyline, drawn)


# ---------------------------------------------------------------------------------------------
def test_refine_points_combines_clicks_and_curves(curve_scene):
    cams, mesh, polyline, truth = curve_scene
    # two extra clicked features on vertices 0 and 1, plus one clicked in a single photo (2)
    feats = ellipsoid(np.array([0.2, -0.3, 0.1]), np.array([-0.2, 0.0, 0.5]))
    clicks = project_all(cams, feats)
    clicks[1:, 2] = np.nan
    # a second curve sharing the first curve's end vertex 14 and the clicked vertex 0
    second = np.array([14, 16, 17, 0])
    mesh2 = mesh.copy()
    mesh2[[16, 17, 0]] = [truth[-1] + [0, -10, 0], truth[-1] + [0, -20, 0], feats[0]]
    second_truth = mesh2[second].copy()
    second_truth[0] = truth[-1]
    drawn2 = {v: c.project(second_truth) for v, c in enumerate(cams)}
    mesh2[[16, 17]] += 0.5  # the current mesh is a little off
    result = refine_points(
        cams,
        mesh2,
        point_vertices=np.array([0, 1, 2]),
        point_observations=clicks,
        curves=[(polyline, hand_drawn(cams, 5)), (second, drawn2)],
        point_names=["brow", "cheek", "temple"],
    )
    assert result.dropped == ["temple: seen in 1 photo(s); triangulation needs 2"]
    np.testing.assert_array_equal(result.vertices, np.r_[0, 1, np.arange(3, 15), 16, 17])
    got = dict(zip(result.vertices.tolist(), result.targets, strict=True))
    # clicked points win over curves and are exact on clean clicks
    np.testing.assert_allclose(got[0], feats[0], atol=1e-6)
    np.testing.assert_allclose(got[1], feats[1], atol=1e-6)
    # vertex 14 (shared): mean of two estimates, both within the curve tolerance
    assert np.linalg.norm(got[14] - truth[-1]) < 0.5
    assert result.targets.shape == (len(result.vertices), 3)
    assert np.all(result.residual_px < 2.0)
