"""Tests of photomodel.texturing.weights: the weight maps g_k = F_k P_k (V_k) of §5.2.1–5.2.3."""

from __future__ import annotations

import numpy as np
import pytest

from photomodel.camera import orbit_camera
from photomodel.texturing.weights import (
    apply_single_view,
    blend,
    cubic_ramp,
    feather,
    image_feather_map,
    positional_certainty,
    select_views,
    view_directions,
    view_similarity,
)


def unit(deg: float) -> np.ndarray:
    """Horizontal unit direction at azimuth ``deg`` (0 = +z, +90 = +x)."""
    a = np.radians(deg)
    return np.array([np.sin(a), 0.0, np.cos(a)])


# ----------------------------------------------------------------------------- feathering


def test_cubic_ramp_is_smooth_and_monotone():
    t = np.linspace(-0.5, 1.5, 2001)
    r = cubic_ramp(t)
    assert r[t <= 0].max() == 0.0 and r[t >= 1].min() == 1.0
    assert cubic_ramp(0.5) == pytest.approx(0.5)
    assert cubic_ramp(0.25) == pytest.approx(3 * 0.25**2 - 2 * 0.25**3)
    assert np.all(np.diff(r) >= 0)
    # zero slope at both ends: a finite difference of h gives 3h² (second order)
    h = 1e-3
    assert cubic_ramp(h) / h < 1e-2 and (1 - cubic_ramp(1 - h)) / h < 1e-2


def test_feather_ramps_with_the_distance_to_the_boundary_in_mm():
    # a half plane: columns 0..9 invisible, 10.. visible; OpenCV's exact L2 distance from a
    # visible pixel centre to the nearest invisible one is (column − 9) pixels
    B = np.zeros((20, 60), bool)
    B[:, 10:] = True
    F = feather(B, width=8.0, pixel_size=(0.5, 0.5))  # 8 mm = 16 pixels
    cols = np.arange(60)
    expected = np.where(cols >= 10, cubic_ramp((cols - 9) * 0.5 / 8.0), 0.0)
    np.testing.assert_allclose(F[10], expected, atol=1e-5)
    assert F[:, :10].max() == 0.0 and F[:, 26:].min() == 1.0


def test_feather_measures_non_square_pixels_in_mm():
    # pixels 0.5 mm wide and 0.25 mm tall: the same 4 mm ramp spans 8 columns but 16 rows
    B = np.ones((64, 64), bool)
    B[:, :4] = False
    B[:4, :] = False
    F = feather(B, width=4.0, pixel_size=(0.25, 0.5))
    row = F[40, 4:14]  # along a row, away from the left boundary (far from the top one)
    col = F[4:22, 40]  # along a column, away from the top boundary
    assert row[7] > 0.99 and row[3] < 0.9  # reaches 1 at ~8 columns
    assert col[15] > 0.99 and col[7] < 0.9  # reaches 1 at ~16 rows
    # the ramps agree at equal distances in mm (resampling costs a little accuracy)
    np.testing.assert_allclose(row[:7], col[1:15:2], atol=0.08)


def test_feather_edge_cases():
    assert feather(np.zeros((5, 5), bool), 3.0).max() == 0.0
    assert feather(np.ones((5, 5), bool), 3.0).min() == 1.0
    B = np.eye(5, dtype=bool)
    np.testing.assert_array_equal(feather(B, 0.0), B.astype(np.float32))
    with pytest.raises(ValueError, match="width"):
        feather(B, -1.0)


def test_image_feather_map_ramps_at_silhouettes_and_occluding_contours():
    depth = np.full((50, 80), np.inf, np.float32)
    depth[5:45, 5:75] = 500.0  # the head
    depth[15:35, 30:50] = 470.0  # a nose in front of it: a 30 mm step
    F = image_feather_map(depth, width_mm=3.0, mm_per_px=0.5)  # 6-pixel ramp
    assert F[~np.isfinite(depth)].max() == 0.0
    assert F[25, 17] == 1.0  # far from every boundary
    assert F[25, 30] == 0.0 and F[25, 29] == 0.0  # both sides of the contour
    assert 0.0 < F[25, 27] < 1.0  # ramping up away from the contour
    # a gentle slope (1 mm per pixel) is not a contour
    slope = np.tile(np.arange(80, dtype=np.float32) + 500.0, (50, 1))
    assert image_feather_map(slope, 3.0, 0.5)[25, 10:70].min() == 1.0


# ----------------------------------------------------------------------------- certainty


def test_positional_certainty_is_the_cosine_to_the_camera():
    cam = orbit_camera(0.0, 100, 100, distance_mm=500.0)  # centre (0, 0, 500)
    pts = np.array([[0.0, 0.0, 0.0], [0.0, 0.0, 0.0], [0.0, 0.0, 0.0], [100.0, 0.0, 0.0]])
    n = np.array([unit(0), unit(60), unit(180), unit(0)])
    P = positional_certainty(cam, pts, n)
    expected_last = 500.0 / np.hypot(100.0, 500.0)  # off-axis point: d_k is tilted
    np.testing.assert_allclose(P, [1.0, 0.5, 0.0, expected_last], atol=1e-6)
    assert positional_certainty(cam, pts[2:3], n[2:3], clip=False)[0] == pytest.approx(-1.0)


# ----------------------------------------------------------------------------- view similarity


DIRS = np.array([unit(a) for a in (-75, -35, 0, 40, 80)])


def test_view_directions_point_from_the_centre_to_the_cameras():
    cams = [orbit_camera(a, 100, 100, distance_mm=600.0, target=(0.0, 10.0, 50.0)) for a in (-40, 0, 70)]
    d = view_directions(cams, np.array([0.0, 10.0, 50.0]))
    np.testing.assert_allclose(d, [unit(-40), unit(0), unit(70)], atol=1e-12)


def test_select_views_picks_the_two_nearest_directions():
    assert select_views(unit(19), DIRS) == (2, 3)
    assert select_views(unit(21), DIRS) == (3, 2)
    assert select_views(unit(-50), DIRS) == (1, 0)
    assert select_views(unit(0), DIRS[:1]) == (0, 0)


def test_select_views_brackets_the_new_direction():
    # at 2° the second-nearest photograph is the one at −35° (37° away, the one at +40° is 38°
    # away), but the view lies between 0° and +40°: those two are the pair of §5.2.3
    assert select_views(unit(2), DIRS) == (2, 3)
    assert select_views(unit(-2), DIRS) == (2, 1)
    assert select_views(unit(-85), DIRS) == (0, 0)  # beyond the last photograph


def test_view_similarity_is_the_papers_formula():
    d = unit(15)
    V = view_similarity(d, DIRS)
    base = DIRS[2] @ DIRS[3]
    expected = np.zeros(5)
    expected[2] = d @ DIRS[2] - base
    expected[3] = d @ DIRS[3] - base
    np.testing.assert_allclose(V, expected, atol=1e-12)


def test_view_similarity_uses_one_photo_when_the_view_matches_it():
    for k in range(5):
        V = view_similarity(DIRS[k], DIRS)
        assert V[k] > 0 and np.all(np.delete(V, k) <= 1e-12 * V[k])


def test_view_similarity_blends_evenly_halfway_and_continuously():
    V = view_similarity(unit(20), DIRS)  # halfway between 0° and 40°
    assert V[2] == pytest.approx(V[3]) and V[2] > 0
    # the share of photo 3 grows monotonically from 0 at 0° to 1 at 40°
    shares = []
    for a in np.linspace(0, 40, 21):
        V = view_similarity(unit(a), DIRS)
        shares.append(V[3] / (V[2] + V[3]))
    assert shares[0] == pytest.approx(0.0, abs=1e-12) and shares[-1] == pytest.approx(1.0)
    assert np.all(np.diff(shares) > 0)


def test_view_similarity_outside_the_arc_and_from_behind():
    V = view_similarity(unit(-90), DIRS)  # beyond the last photo: only the nearest one
    assert V[0] > 0 and np.count_nonzero(V) == 1
    # from behind, the two profiles bracket the view around the back of the head
    V = view_similarity(unit(178), DIRS)
    assert set(np.flatnonzero(V)) == {0, 4} and V[4] > V[0]


# ----------------------------------------------------------------------------- blending


def test_apply_single_view_interpolates_between_blend_and_best_photo():
    g = np.array([[0.2, 0.0, 0.5], [0.6, 0.0, 0.5], [0.2, 0.0, 0.0]], np.float32)  # (k=3, n=3)
    s0 = apply_single_view(g, np.zeros(3))
    np.testing.assert_allclose(s0[:, 0], [0.2, 0.6, 0.2])
    assert s0[:, 1].sum() == 0.0  # nothing sees point 1: stays unseen
    s1 = apply_single_view(g, np.ones(3))
    np.testing.assert_allclose(s1[:, 0], [0.0, 1.0, 0.0])
    half = apply_single_view(g, np.full(3, 0.5))
    np.testing.assert_allclose(half[:, 0], 0.5 * s0[:, 0] + 0.5 * s1[:, 0])
    np.testing.assert_allclose(half.sum(axis=0), [1.0, 0.0, 1.0], atol=1e-6)
    assert apply_single_view(g, None) is not None and np.array_equal(apply_single_view(g, None), g)


def test_blend_is_a_convex_combination():
    rng = np.random.default_rng(2)
    colors = rng.uniform(0, 255, (4, 100, 3)).astype(np.float32)
    g = rng.uniform(0, 1, (4, 100)).astype(np.float32)
    g[:, :10] = 0.0
    out, total = blend(colors, g)
    np.testing.assert_allclose(total, g.sum(axis=0), rtol=1e-6)
    expected = np.einsum("kn,knc->nc", g[:, 10:], colors[:, 10:]) / g[:, 10:].sum(axis=0)[:, None]
    np.testing.assert_allclose(out[10:], expected, rtol=1e-5)
    assert np.all(out[10:] >= colors[:, 10:].min(axis=0) - 1e-3)
    assert np.all(out[10:] <= colors[:, 10:].max(axis=0) + 1e-3)
    assert out[:10].max() == 0.0
    # uint8 colours are accepted as they come from the photographs
    out8, _ = blend(colors.astype(np.uint8), g)
    np.testing.assert_allclose(out8[10:], blend(colors.astype(np.uint8).astype(np.float32), g)[0][10:])
