"""Tests of photomodel.rendering.depth (the depth test) and photomodel.texturing.visibility (depth maps,
facing, the visibility table) against analytic scenes (§5.2.1)."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh

from photomodel.camera import Camera, orbit_camera
from photomodel.rendering.depth import depth_visible, project_points
from photomodel.texturing.visibility import front_facing, render_depth, vertex_visibility, visible


def square(z: float, half: float, centre=(0.0, 0.0)) -> tuple[np.ndarray, np.ndarray]:
    """A square at depth ``z`` (world), facing +z (counter-clockwise seen from +z)."""
    cx, cy = centre
    v = np.array(
        [[cx - half, cy - half, z], [cx + half, cy - half, z], [cx + half, cy + half, z], [cx - half, cy + half, z]]
    )
    return v, np.array([[0, 1, 2], [0, 2, 3]])


@pytest.fixture(scope="module")
def occluded_scene():
    """A 200 mm wall at z = 0 and a 40 mm card 30 mm in front of it, seen from +z at 500 mm."""
    wall_v, wall_f = square(0.0, 100.0)
    card_v, card_f = square(30.0, 20.0)
    V = np.vstack([wall_v, card_v])
    F = np.vstack([wall_f, card_f + 4])
    cam = orbit_camera(0.0, 320, 240, distance_mm=500.0)
    return cam, V, F, render_depth(cam, V, F)


def test_render_depth_is_the_camera_z_of_the_nearest_surface(occluded_scene):
    cam, V, F, depth = occluded_scene
    assert depth.shape == (240, 320)
    # the camera sits at z = +500 looking down -z: the wall is 500 mm away, the card 470 mm;
    # float32 depth interpolation is good to ~1e-4 relative
    centre = depth[120, 160]
    assert centre == pytest.approx(470.0, abs=0.05)
    edge = depth[120, 100]  # the wall spans ±89 px about the centre, the card ±18 px
    assert edge == pytest.approx(500.0, abs=0.05)


def test_depth_visible_separates_occluded_from_seen_points(occluded_scene):
    cam, V, F, depth = occluded_scene
    behind_card = np.array([[0.0, 0.0, 0.0], [10.0, -5.0, 0.0]])  # on the wall, hidden by the card
    on_card = np.array([[0.0, 0.0, 30.0], [15.0, 15.0, 30.0]])
    beside = np.array([[60.0, 0.0, 0.0], [-50.0, 40.0, 0.0]])  # on the wall, clear of the card
    assert not depth_visible(cam, behind_card, depth).any()
    assert depth_visible(cam, on_card, depth).all()
    assert depth_visible(cam, beside, depth).all()


def test_depth_visible_rejects_points_outside_the_image_or_behind_the_camera(occluded_scene):
    cam, V, F, depth = occluded_scene
    outside = np.array([[400.0, 0.0, 0.0]])  # projects far to the right of the image
    behind = np.array([[0.0, 0.0, 700.0]])  # behind the camera (z_cam < 0)
    assert not depth_visible(cam, outside, depth).any()
    assert not depth_visible(cam, behind, depth).any()


def test_depth_tolerance_is_in_millimetres(occluded_scene):
    cam, V, F, depth = occluded_scene
    # a point 1 mm behind the card surface passes the 1.5 mm default, fails a 0.5 mm tolerance
    p = np.array([[5.0, 5.0, 29.0]])
    assert depth_visible(cam, p, depth).all()
    assert not depth_visible(cam, p, depth, tol_mm=0.5).any()


def test_depth_map_of_wrong_size_is_refused(occluded_scene):
    cam, V, F, depth = occluded_scene
    with pytest.raises(ValueError, match="depth map"):
        depth_visible(cam, np.zeros((1, 3)), depth[:-1])


def test_front_facing_is_the_sign_of_n_dot_direction_to_camera():
    cam = orbit_camera(0.0, 100, 100, distance_mm=500.0)  # centre at (0, 0, 500)
    pts = np.zeros((3, 3))
    normals = np.array([[0.0, 0.0, 1.0], [0.0, 0.0, -1.0], [1.0, 0.0, 0.0]])
    assert front_facing(cam, pts, normals).tolist() == [True, False, False]
    # 60° away from the camera direction: cos = 0.5
    n60 = np.array([[np.sin(np.radians(60)), 0.0, np.cos(np.radians(60))]])
    assert front_facing(cam, np.zeros((1, 3)), n60, min_cos=0.49).all()
    assert not front_facing(cam, np.zeros((1, 3)), n60, min_cos=0.51).any()


def test_project_points_matches_camera_project_in_float64_and_float32():
    cam = orbit_camera(30.0, 640, 480, distance_mm=700.0, elevation_deg=10.0, target=(5.0, 10.0, 20.0))
    rng = np.random.default_rng(0)
    X = rng.uniform(-100, 100, (500, 3))
    uv, z = project_points(cam, X)
    np.testing.assert_allclose(uv, cam.project(X), atol=1e-9)
    np.testing.assert_allclose(z, cam.depth(X), atol=1e-9)
    uv32, z32 = project_points(cam, X.astype(np.float32))
    assert uv32.dtype == np.float32
    # float32 at head scale: ~1e-4 px (7 significant digits on ~500 px)
    np.testing.assert_allclose(uv32, cam.project(X.astype(np.float32).astype(float)), atol=2e-3)


def test_vertex_visibility_of_a_sphere_matches_the_analytic_horizon():
    """On a convex sphere a vertex is visible exactly when it faces the camera centre."""
    sphere = trimesh.creation.icosphere(subdivisions=4, radius=80.0)
    V, F = np.asarray(sphere.vertices), np.asarray(sphere.faces)
    cams = [orbit_camera(a, 400, 400, distance_mm=600.0) for a in (0.0, 70.0)]
    vis = vertex_visibility(cams, V, F)
    assert vis.shape == (2, len(V))
    for cam, row in zip(cams, vis, strict=True):
        c = cam.center
        # analytic: the tangent cone from the centre touches the sphere where n·(c - p) = 0
        cos = np.einsum("ij,ij->i", V / 80.0, c - V) / np.linalg.norm(c - V, axis=1)
        clear = np.abs(cos) > 0.05  # skip the grazing band, where the polyhedron and the sphere differ
        assert np.array_equal(row[clear], cos[clear] > 0)


def test_visible_combines_depth_and_facing(occluded_scene):
    cam, V, F, depth = occluded_scene
    p = np.array([[60.0, 0.0, 0.0], [60.0, 0.0, 0.0]])
    n = np.array([[0.0, 0.0, 1.0], [0.0, 0.0, -1.0]])  # the same point seen from its back
    assert visible(cam, p, n, depth).tolist() == [True, False]


def test_camera_type_is_the_one_module():
    cam = Camera(np.eye(3), np.array([0.0, 0.0, 500.0]), 800.0, 100, 80)
    uv, z = project_points(cam, np.zeros((1, 3)))
    np.testing.assert_allclose(uv[0], cam.principal_point)
    assert z[0] == 500.0
