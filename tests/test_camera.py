"""The camera model (photomodel.camera): projection, rays, presets, rotations, focal units, (de)serialisation.

Every expected value is worked out by hand from the conventions written in the module docstring
(``X_cam = R X + t``, ``u = f x/z + (W-1)/2``, ``v = f y/z + (H-1)/2``, y down, +z out of the face,
36 mm sensor) or from an independent formula (``np.cross``, the paper's Eq. (1) in its ``s``/``η``
form), never from the function under test itself.
Tolerances: the hand values are exact or rounded to ~1e-12 relative; 1e-9 (px, mm, or unitless
for rotations) covers float64 rounding through a few matrix products at ~1000-unit scales.
"""

from __future__ import annotations

import json

import numpy as np
import pytest

from photomodel.camera import (
    PRESET_AZIMUTH_DEG,
    Camera,
    cross_matrix,
    focal_mm_to_px,
    focal_px_to_mm,
    look_at,
    orbit_camera,
    preset_camera,
    rodrigues,
    rotation_angle_deg,
    rotation_vector,
)

TOL = 1e-9  # see module docstring

#: 90° about +y (x → -z, z → x): a camera with this R at t = (0, 0, 400) sits at +x 400 mm.
RY90 = np.array([[0.0, 0.0, 1.0], [0.0, 1.0, 0.0], [-1.0, 0.0, 0.0]])


def rz(deg):
    c, s = np.cos(np.radians(deg)), np.sin(np.radians(deg))
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


# ----------------------------------------------------------------------------- projection


def test_projection_of_a_hand_computed_pinhole_example():
    # 641 × 481 image: principal point ((641-1)/2, (481-1)/2) = (320, 240)
    cam = Camera(np.eye(3), [0.0, 0.0, 500.0], 1000.0, 641, 481)
    np.testing.assert_array_equal(cam.principal_point, [320.0, 240.0])
    np.testing.assert_array_equal(cam.K, [[1000.0, 0.0, 320.0], [0.0, 1000.0, 240.0], [0.0, 0.0, 1.0]])
    # (10, -5, 0) → camera (10, -5, 500) → u = 1000·10/500 + 320 = 340, v = 1000·(-5)/500 + 240 = 230
    # (0, 0, 250) → camera (0, 0, 750) → the principal point
    X = np.array([[10.0, -5.0, 0.0], [0.0, 0.0, 250.0]])
    np.testing.assert_allclose(cam.project(X), [[340.0, 230.0], [320.0, 240.0]], atol=TOL)
    np.testing.assert_allclose(cam.depth(X), [500.0, 750.0], atol=TOL)


def test_projection_of_a_rotated_camera():
    cam = Camera(RY90, [0.0, 0.0, 400.0], 1000.0, 641, 481)
    # R X: (0, 20, 0) → (0, 20, 0); (50, 0, 0) → (0, 0, -50); (0, 0, 100) → (100, 0, 0); then + t
    X = np.array([[0.0, 20.0, 0.0], [50.0, 0.0, 0.0], [0.0, 0.0, 100.0]])
    np.testing.assert_allclose(cam.to_camera(X), [[0.0, 20.0, 400.0], [0.0, 0.0, 350.0], [100.0, 0.0, 400.0]], atol=TOL)
    # u = 1000 x/z + 320, v = 1000 y/z + 240
    np.testing.assert_allclose(cam.project(X), [[320.0, 290.0], [320.0, 240.0], [570.0, 240.0]], atol=TOL)
    np.testing.assert_allclose(cam.depth(X), [400.0, 350.0, 400.0], atol=TOL)
    # centre −Rᵀt = −(−400, 0, 0); the optical axis (third row of R) points back along −x
    np.testing.assert_allclose(cam.center, [400.0, 0.0, 0.0], atol=TOL)
    np.testing.assert_allclose(cam.view_direction, [-1.0, 0.0, 0.0], atol=TOL)
    # the paper's parameters: η = 1/t_z, s = f/t_z
    assert cam.eta == pytest.approx(1 / 400.0, rel=1e-15) and cam.s == pytest.approx(2.5, rel=1e-15)


def test_projection_agrees_with_the_papers_eq_1():
    """x = s (r_x·m + t_x) / (1 + η r_z·m), y likewise, measured from the optical centre (§5.1.1)."""
    rng = np.random.default_rng(0)
    R = rodrigues([0.2, -0.5, 0.1])
    cam = Camera(R, [12.0, -7.0, 650.0], 1500.0, 1000, 1333)
    m = rng.uniform(-90.0, 90.0, (20, 3))
    denom = 1.0 + cam.eta * (m @ R[2])
    xy = np.column_stack([cam.s * (m @ R[0] + cam.t[0]), cam.s * (m @ R[1] + cam.t[1])]) / denom[:, None]
    np.testing.assert_allclose(cam.project(m) - [499.5, 666.0], xy, atol=TOL)


def test_rays_round_trip():
    cam = Camera(rodrigues([0.1, 0.7, -0.05]), [5.0, 3.0, 600.0], 1200.0, 1000, 1333)
    rng = np.random.default_rng(1)
    X = rng.uniform(-100.0, 100.0, (50, 3))
    origin, d = cam.rays(cam.project(X))
    np.testing.assert_allclose(origin, cam.center, atol=TOL)
    np.testing.assert_allclose(np.linalg.norm(d, axis=1), 1.0, atol=TOL)
    to_point = X - origin
    # each point lies on its ray, in front of the camera: (X − o) = |X − o| d
    # (1e-6 mm: the pixel → ray → mm chain loses ~1e-12 relative on ~600 mm lengths)
    np.testing.assert_allclose(to_point, np.linalg.norm(to_point, axis=1, keepdims=True) * d, atol=1e-6)
    # the ray of the principal point is the optical axis
    _, d0 = cam.rays(cam.principal_point)
    np.testing.assert_allclose(d0[0], cam.view_direction, atol=TOL)


# ----------------------------------------------------------------------------- presets / orbit


def test_front_preset_geometry():
    cam = preset_camera("front", 1000, 1333)
    np.testing.assert_allclose(cam.center, [0.0, 0.0, 600.0], atol=TOL)  # 600 mm in front of the face
    np.testing.assert_allclose(cam.view_direction, [0.0, 0.0, -1.0], atol=TOL)
    assert cam.f == pytest.approx(50.0 / 36.0 * 1000.0, rel=1e-15)  # 50 mm lens, 36 mm sensor
    np.testing.assert_allclose(cam.project(np.zeros((1, 3)))[0], [499.5, 666.0], atol=TOL)
    # world up is image up (v smaller); the subject's left (+x) is the image's right, as seen face to face
    up, left = cam.project(np.array([[0.0, 10.0, 0.0], [10.0, 0.0, 0.0]]))
    f = cam.f
    np.testing.assert_allclose(up, [499.5, 666.0 - f * 10 / 600], atol=TOL)
    np.testing.assert_allclose(left, [499.5 + f * 10 / 600, 666.0], atol=TOL)


@pytest.mark.parametrize("name", sorted(PRESET_AZIMUTH_DEG))
def test_presets_sit_on_a_600_mm_circle_at_their_azimuth(name):
    expected = {  # 600 (sin a, 0, cos a); 600/√2 = 424.2640687119285
        "front": [0.0, 0.0, 600.0],
        "left": [600.0, 0.0, 0.0],
        "right": [-600.0, 0.0, 0.0],
        "three_quarter_left": [424.2640687119285, 0.0, 424.2640687119285],
        "three_quarter_right": [-424.2640687119285, 0.0, 424.2640687119285],
    }
    cam = preset_camera(name, 800, 600)
    np.testing.assert_allclose(cam.center, expected[name], atol=TOL)
    np.testing.assert_allclose(cam.R @ cam.R.T, np.eye(3), atol=TOL)
    assert np.linalg.det(cam.R) == pytest.approx(1.0, abs=TOL)
    np.testing.assert_allclose(cam.view_direction, -np.asarray(expected[name]) / 600.0, atol=TOL)
    assert (cam.width, cam.height) == (800, 600)


def test_unknown_preset_is_refused_with_the_choices():
    with pytest.raises(ValueError, match="three_quarter_left"):
        preset_camera("profile", 100, 100)


def test_orbit_camera_with_elevation_distance_target_and_lens():
    target = np.array([1.0, 2.0, 3.0])
    cam = orbit_camera(0.0, 640, 480, distance_mm=500.0, focal_mm=85.0, elevation_deg=30.0, target=target)
    # 500 (0, sin 30°, cos 30°) = (0, 250, 433.01270189221935)
    np.testing.assert_allclose(cam.center, target + [0.0, 250.0, 433.01270189221935], atol=TOL)
    np.testing.assert_allclose(cam.project(target[None])[0], [319.5, 239.5], atol=TOL)
    np.testing.assert_allclose(cam.depth(target[None]), [500.0], atol=TOL)
    assert cam.f == pytest.approx(85.0 * 640 / 36.0, rel=1e-15)
    # axes by hand: z_cam towards the target = (0, −sin 30°, −cos 30°), x_cam = (1, 0, 0) (no roll),
    # y_cam = z_cam × x_cam = (0, −cos 30°, sin 30°): image down is world down and towards the camera
    c30 = 0.8660254037844386
    np.testing.assert_allclose(cam.R, [[1.0, 0.0, 0.0], [0.0, -c30, 0.5], [0.0, -0.5, -c30]], atol=TOL)


def test_look_at_puts_the_target_on_the_axis_and_up_up():
    eye, target, up = np.array([300.0, 100.0, 500.0]), np.array([0.0, 10.0, 0.0]), np.array([0.0, 1.0, 0.0])
    R, t = look_at(eye, target, up=up)
    np.testing.assert_allclose(R @ R.T, np.eye(3), atol=TOL)
    assert np.linalg.det(R) == pytest.approx(1.0, abs=TOL)
    axis = (target - eye) / np.linalg.norm(target - eye)
    np.testing.assert_allclose(R @ axis, [0.0, 0.0, 1.0], atol=TOL)  # looks along +z_cam
    np.testing.assert_allclose(R @ eye + t, [0.0, 0.0, 0.0], atol=TOL)  # the eye is the camera origin
    assert (R @ up)[1] < 0  # world up is −y_cam (image up)
    assert abs((R @ up)[0]) < TOL  # and has no sideways part: no roll


# ----------------------------------------------------------------------------- rotations


def test_rodrigues_known_rotations():
    np.testing.assert_allclose(rodrigues([0.0, 0.0, np.pi / 2]), [[0, -1, 0], [1, 0, 0], [0, 0, 1]], atol=TOL)
    np.testing.assert_allclose(rodrigues([np.pi, 0.0, 0.0]), np.diag([1.0, -1.0, -1.0]), atol=TOL)
    np.testing.assert_allclose(rodrigues([0.0, np.radians(90.0), 0.0]), RY90, atol=TOL)
    np.testing.assert_array_equal(rodrigues(np.zeros(3)), np.eye(3))
    # below 1e-12 rad: I + X(v), the first-order term (the second is ~1e-26)
    v = np.array([1e-13, -2e-13, 3e-13])
    np.testing.assert_array_equal(rodrigues(v), np.eye(3) + cross_matrix(v))


@pytest.mark.parametrize("angle", [0.0, 1e-9, 0.3, 1.0, 2.5, np.pi - 1e-7])
def test_rotation_vector_inverts_rodrigues(angle):
    axis = np.array([0.36, -0.48, 0.8])  # a unit vector: 0.36² + 0.48² + 0.8² = 1
    w = angle * axis
    w_back = rotation_vector(rodrigues(w))
    if angle > 3.0:
        # within 1e-6 of π the axis comes from the symmetric part of R alone, which leaves out the
        # antisymmetric part of size sin θ ≈ 1e-7: ~π·1e-7 of error, 1e-6 allows for it
        np.testing.assert_allclose(w_back, w, atol=1e-6)
    else:
        # relative: the 1e-9 rad case must come back as itself, not as zero
        np.testing.assert_allclose(w_back, w, rtol=1e-9, atol=1e-15)


def test_rotation_vector_at_exactly_pi_gives_the_same_rotation():
    R = rodrigues(np.pi * np.array([0.0, 0.6, 0.8]))
    w = rotation_vector(R)
    assert np.linalg.norm(w) == pytest.approx(np.pi, abs=TOL)
    np.testing.assert_allclose(rodrigues(w), R, atol=TOL)  # ±axis: the same half turn


def test_cross_matrix_is_the_cross_product():
    rng = np.random.default_rng(2)
    for _ in range(5):
        v, a = rng.normal(size=3), rng.normal(size=3)
        np.testing.assert_allclose(cross_matrix(v) @ a, np.cross(v, a), atol=TOL)
    np.testing.assert_array_equal(cross_matrix([1.0, 2.0, 3.0]), [[0, -3, 2], [3, 0, -1], [-2, 1, 0]])


def test_rotation_angle_between_two_rotations():
    assert rotation_angle_deg(rz(30.0), np.eye(3)) == pytest.approx(30.0, abs=1e-9)
    assert rotation_angle_deg(rz(10.0), rz(-25.0)) == pytest.approx(35.0, abs=1e-9)
    assert rotation_angle_deg(RY90, RY90) == pytest.approx(0.0, abs=1e-5)  # arccos near 1: ~1e-8 rad
    assert rotation_angle_deg(np.diag([1.0, -1.0, -1.0]), np.eye(3)) == pytest.approx(180.0, abs=1e-9)


# ----------------------------------------------------------------------------- focal units


def test_focal_length_mm_and_px():
    assert focal_mm_to_px(50.0, 1000) == pytest.approx(1388.8888888888889, rel=1e-15)  # 50 · 1000 / 36
    assert focal_mm_to_px(36.0, 4000) == 4000.0  # a 36 mm lens on a 36 mm sensor: f = width
    assert focal_px_to_mm(2000.0, 1200) == pytest.approx(60.0, rel=1e-15)  # 2000 · 36 / 1200
    assert focal_px_to_mm(focal_mm_to_px(85.0, 1333), 1333) == pytest.approx(85.0, rel=1e-15)
    assert Camera(np.eye(3), [0, 0, 500], 2000.0, 1200, 900).focal_mm == pytest.approx(60.0, rel=1e-15)


# ----------------------------------------------------------------------------- (de)serialisation


def test_to_dict_has_the_project_file_keys_and_round_trips_through_json():
    cam = Camera(RY90, [1.5, -2.0, 400.0], 1234.5, 1000, 1333)
    d = cam.to_dict()
    assert d == {
        "rotation": [[0.0, 0.0, 1.0], [0.0, 1.0, 0.0], [-1.0, 0.0, 0.0]],
        "translation_mm": [1.5, -2.0, 400.0],
        "focal_px": 1234.5,
        "width": 1000,
        "height": 1333,
    }
    back = Camera.from_dict(json.loads(json.dumps(d)))
    np.testing.assert_array_equal(back.R, cam.R)
    np.testing.assert_array_equal(back.t, cam.t)
    assert (back.f, back.width, back.height) == (cam.f, cam.width, cam.height)
    # float64 values survive JSON exactly (repr round trip)
    odd = Camera(rodrigues([0.1, 0.2, 0.3]), [np.pi, np.e, 1 / 3], 1000.0 / 7, 1000, 1333)
    again = Camera.from_dict(json.loads(json.dumps(odd.to_dict())))
    np.testing.assert_array_equal(again.R, odd.R)
    np.testing.assert_array_equal(again.t, odd.t)
    assert again.f == odd.f


def test_constructor_coerces_types_and_copy_is_independent():
    cam = Camera([[1, 0, 0], [0, 1, 0], [0, 0, 1]], (0, 0, 500), 1000, 640.0, 480.0)
    assert cam.R.dtype == float and cam.t.dtype == float and cam.t.shape == (3,)
    assert isinstance(cam.f, float) and isinstance(cam.width, int) and isinstance(cam.height, int)
    c2 = cam.copy()
    c2.R[0, 0] = -1.0
    c2.t[2] = 1.0
    c2.f = 5.0
    assert cam.R[0, 0] == 1.0 and cam.t[2] == 500.0 and cam.f == 1000.0
