"""Tests of photomodel.alignment: the (weighted) Umeyama similarity against known similarities, and
the moves of cameras and points it drives."""

from __future__ import annotations

import numpy as np
import pytest

from photomodel.alignment import align_to_truth, camera_errors, similarity_transform, transform_cameras
from photomodel.camera import Camera, orbit_camera, rodrigues, rotation_angle_deg

S_TRUE = 1.07
R_TRUE = rodrigues(np.array([0.2, -0.4, 0.3]))
T_TRUE = np.array([4.0, -2.0, 9.0])


@pytest.fixture(scope="module")
def points():
    return np.random.default_rng(11).normal(0.0, 50.0, (60, 3))


def moved(points, s=S_TRUE, R=R_TRUE, t=T_TRUE):
    return s * points @ R.T + t


def weighted_cost(src, dst, w, s, R, t):
    return float(w @ np.sum((dst - (s * src @ R.T + t)) ** 2, axis=1))


def test_a_known_similarity_is_recovered_exactly(points):
    s, R, t = similarity_transform(points, moved(points))
    assert s == pytest.approx(S_TRUE, rel=1e-12)
    np.testing.assert_allclose(R, R_TRUE, atol=1e-12)
    np.testing.assert_allclose(t, T_TRUE, atol=1e-10)
    # rigid: the rotation and translation of a motion without scale
    s, R, t = similarity_transform(points, moved(points, s=1.0), scale=False)
    assert s == 1.0
    np.testing.assert_allclose(R, R_TRUE, atol=1e-12)
    np.testing.assert_allclose(t, T_TRUE, atol=1e-10)


def test_points_with_zero_weight_do_not_count(points):
    dst = moved(points)
    dst[:15] += np.random.default_rng(2).normal(0.0, 30.0, (15, 3))  # outliers
    w = np.ones(len(points))
    w[:15] = 0.0
    for scale, s_true in ((True, S_TRUE), (False, 1.0)):
        target = dst if scale else moved(points, s=1.0)
        if not scale:
            target[:15] = dst[:15]
        s, R, t = similarity_transform(points, target, w, scale=scale)
        assert s == pytest.approx(s_true, rel=1e-12)
        np.testing.assert_allclose(R, R_TRUE, atol=1e-12)
        np.testing.assert_allclose(t, T_TRUE, atol=1e-9)


def test_integer_weights_are_repeated_points(points):
    """Weight k = the pair given k times: the weighted similarity of noisy data equals the plain
    one of the repeated points (this pins the weighted means, covariance and variance)."""
    rng = np.random.default_rng(4)
    dst = moved(points) + rng.normal(0.0, 2.0, points.shape)
    k = rng.integers(1, 5, len(points))
    weighted = similarity_transform(points, dst, k.astype(float))
    repeated = similarity_transform(np.repeat(points, k, axis=0), np.repeat(dst, k, axis=0))
    assert weighted[0] == pytest.approx(repeated[0], rel=1e-12)
    np.testing.assert_allclose(weighted[1], repeated[1], atol=1e-12)
    np.testing.assert_allclose(weighted[2], repeated[2], atol=1e-9)
    # scaling all weights changes nothing
    again = similarity_transform(points, dst, 3.5 * k)
    assert again[0] == pytest.approx(weighted[0], rel=1e-12)


@pytest.mark.parametrize("scale", [True, False])
def test_the_weighted_similarity_is_the_least_squares_minimum(points, scale):
    rng = np.random.default_rng(5)
    dst = moved(points, s=S_TRUE if scale else 1.0) + rng.normal(0.0, 3.0, points.shape)
    w = rng.uniform(0.0, 1.0, len(points)) ** 2
    s, R, t = similarity_transform(points, dst, w, scale=scale)
    best = weighted_cost(points, dst, w, s, R, t)
    for _ in range(50):  # any nearby similarity (or motion) costs more
        dR = rodrigues(rng.normal(0.0, 1e-3, 3))
        ds = 1.0 + (rng.normal(0.0, 1e-3) if scale else 0.0)
        assert weighted_cost(points, dst, w, s * ds, dR @ R, t + rng.normal(0.0, 1e-2, 3)) > best


def test_a_mirror_image_still_gives_a_rotation(points):
    mirror = points * [-1.0, 1.0, 1.0]
    for w in (None, np.linspace(0.5, 1.5, len(points))):
        _, R, _ = similarity_transform(points, mirror, w)
        assert np.linalg.det(R) == pytest.approx(1.0)
        np.testing.assert_allclose(R @ R.T, np.eye(3), atol=1e-12)


def test_moving_the_scene_keeps_every_image(points):
    cams = [orbit_camera(a, 640, 480, distance_mm=600.0) for a in (-40.0, 0.0, 35.0)]
    moved_cams = transform_cameras(cams, S_TRUE, R_TRUE, T_TRUE)
    for a, b in zip(cams, moved_cams, strict=True):
        np.testing.assert_allclose(b.project(moved(points)), a.project(points), atol=1e-9)
    # aligning the reconstruction with its truth gives the truth back, with no camera error
    back_cams, back_points = align_to_truth(moved_cams, moved(points), points)
    np.testing.assert_allclose(back_points, points, atol=1e-9)
    err = camera_errors(back_cams, cams)
    assert err["rot_err_deg"].max() < 1e-5 and err["centre_err_mm"].max() < 1e-6  # arccos near 0: ~1e-6 deg
    assert err["focal_err_pct"].max() == 0.0
    assert isinstance(back_cams[0], Camera)
    assert rotation_angle_deg(back_cams[0].R, cams[0].R) < 1e-5
