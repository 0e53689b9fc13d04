"""The wireframe overlay (photomodel.modeling.wireframe): lines on the surface, carried by deformations,
hidden lines removed."""

from __future__ import annotations

import numpy as np
import pytest

from photomodel.camera import orbit_camera
from photomodel.modeling.generic_mesh import load_generic_mesh
from photomodel.modeling.wireframe import CURVE, GRID, OUTLINE, line_points, mesh_lines, project_lines, visible_points


def _grid_mesh(n: int = 21, size: float = 100.0):
    """A flat square (z = 0) of n × n vertices facing +z, two triangles per cell (CCW from +z)."""
    xs = np.linspace(-size / 2, size / 2, n)
    X, Y = np.meshgrid(xs, xs)
    V = np.column_stack([X.ravel(), Y.ravel(), np.zeros(n * n)])
    i = np.arange(n - 1)
    a = (i[:, None] * n + i[None, :]).ravel()
    F = np.concatenate([np.column_stack([a, a + 1, a + n + 1]), np.column_stack([a, a + n + 1, a + n])])
    return V, F


def _sphere(radius=80.0, n_lat=40, n_lon=80):
    lat = np.linspace(-np.pi / 2, np.pi / 2, n_lat)
    lon = np.linspace(-np.pi, np.pi, n_lon, endpoint=False)
    LA, LO = np.meshgrid(lat[1:-1], lon, indexing="ij")
    V = radius * np.column_stack(
        [np.cos(LA).ravel() * np.sin(LO).ravel(), np.sin(LA).ravel(), np.cos(LA).ravel() * np.cos(LO).ravel()]
    )
    rows, cols = n_lat - 2, n_lon
    F = []
    for r in range(rows - 1):
        for c in range(cols):
            a, b = r * cols + c, r * cols + (c + 1) % cols
            F += [[a, b, b + cols], [a, b + cols, a + cols]]
    return V, np.array(F)


def test_horizontal_lines_lie_on_their_levels():
    V, F = _grid_mesh()
    lines = mesh_lines(V, F, spacing_mm=10.0, angle_step_deg=30.0)
    P = line_points(lines, V)
    grid = lines.kind == GRID
    # the iso-lines of y: both endpoints of a segment at the same level, a multiple of 10 mm
    # (a piecewise-linear field is cut exactly; 1e-6 is the level offset that avoids vertices)
    horizontal = grid & (np.abs(P[:, 0, 1] - P[:, 1, 1]) < 1e-9)
    y = P[horizontal, :, 1]
    assert horizontal.sum() > 100
    np.testing.assert_allclose(y, np.round(y / 10.0) * 10.0 + 1e-6, atol=1e-9)
    # every grid segment's endpoints lie on edges of its triangle: inside the square
    assert np.all(np.abs(P[grid][..., :2]) <= 50.0 + 1e-9)


def test_outline_is_the_boundary():
    V, F = _grid_mesh(n=11)
    lines = mesh_lines(V, F)
    outline = line_points(lines, V)[lines.kind == OUTLINE]
    assert len(outline) == 4 * 10  # 10 edges per side of the square
    assert np.all(np.isclose(np.abs(outline[..., :2]).max(axis=-1), 50.0))


def test_lines_follow_a_deformation():
    """Points on edges are affine combinations: an affine map of the mesh maps them exactly."""
    mesh = load_generic_mesh()
    lines = mesh_lines(mesh.vertices, mesh.faces, curves=mesh.curves)
    assert {GRID, OUTLINE, CURVE} <= set(np.unique(lines.kind).tolist())
    A = np.array([[1.1, 0.1, 0.0], [0.0, 0.9, 0.2], [0.05, 0.0, 1.0]])
    t = np.array([3.0, -4.0, 10.0])
    moved = line_points(lines, mesh.vertices @ A.T + t)
    np.testing.assert_allclose(moved, line_points(lines, mesh.vertices) @ A.T + t, atol=1e-9)
    # a curve segment joins consecutive curve vertices
    brow = mesh.curves["brow_l"]
    P = line_points(lines, mesh.vertices)[lines.kind == CURVE]
    assert np.any(np.all(np.isclose(P[:, 0], mesh.vertices[brow[0]]), axis=1))


def test_hidden_lines_are_removed_on_a_sphere():
    V, F = _sphere()
    cam = orbit_camera(0.0, 400, 400, distance_mm=500.0)
    lines = mesh_lines(V, F, spacing_mm=10.0, angle_step_deg=15.0)
    uv, visible = project_lines(cam, V, F, lines)
    mid = line_points(lines, V).mean(axis=1)
    # the camera sits on +z: the front half is visible, the back half hidden; a band around the
    # silhouette (|z| < 15 mm) is where the depth tolerance legitimately decides either way
    front, back = mid[:, 2] > 15.0, mid[:, 2] < -15.0
    assert visible[front].mean() > 0.99
    assert visible[back].mean() < 0.01
    assert uv.shape == (len(lines), 2, 2)


def test_visible_points_outside_the_image_are_not_visible():
    cam = orbit_camera(0.0, 100, 100, distance_mm=500.0)
    depth = np.full((50, 50), np.inf, dtype=np.float32)
    pts = np.array([[0.0, 0.0, 0.0], [1000.0, 0.0, 0.0], [0.0, 0.0, 600.0]])  # centre, far right, behind
    assert visible_points(cam, pts, depth).tolist() == [True, False, False]


def test_bad_arguments():
    V, F = _grid_mesh(n=3)
    with pytest.raises(ValueError):
        mesh_lines(V[:, :2], F)
    with pytest.raises(ValueError):
        mesh_lines(V, F, spacing_mm=0.0)
    with pytest.raises(ValueError):
        project_lines(orbit_camera(0.0, 10, 10), V, F, mesh_lines(V, F), depth_scale=0.0)
