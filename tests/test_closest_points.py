"""Tests of photomodel.closest_points: exact closest points on a triangle surface, barycentric coordinates."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh
from trimesh.proximity import closest_point_naive

from photomodel.closest_points import TriangleSurface, barycentric_coordinates


def test_closest_points_are_exact_on_a_coarse_and_a_fine_surface():
    """Against trimesh's brute force over every triangle: the same distances to rounding, whether the
    triangles are larger than the sample spacing (a coarse sphere) or smaller."""
    rng = np.random.default_rng(0)
    for subdivisions in (1, 4):
        sphere = trimesh.creation.icosphere(subdivisions=subdivisions, radius=50.0)
        surface = TriangleSurface(sphere.vertices, sphere.faces, spacing_mm=2.0)
        points = rng.normal(size=(300, 3)) * 40.0
        closest, dist, face = surface.closest(points)
        _, d_ref, _ = closest_point_naive(sphere, points)
        np.testing.assert_allclose(dist, d_ref, atol=1e-9)
        np.testing.assert_allclose(np.linalg.norm(closest - points, axis=1), dist, atol=1e-9)
        # each closest point lies in the triangle named for it
        bary = barycentric_coordinates(closest, surface.triangles[face])
        np.testing.assert_allclose(np.einsum("nk,nkd->nd", bary, surface.triangles[face]), closest, atol=1e-9)
        # and the normal there points out of the sphere
        assert (np.einsum("nd,nd->n", surface.normals_at(closest, face), closest) > 0).all()


def test_barycentric_coordinates_are_clipped_to_the_triangle():
    tri = np.array([[[0.0, 0, 0], [1, 0, 0], [0, 1, 0]]] * 2)
    b = barycentric_coordinates(np.array([[0.25, 0.25, 0.0], [2.0, 0.0, 0.0]]), tri)
    np.testing.assert_allclose(b[0], [0.5, 0.25, 0.25])
    assert b.min() >= 0.0 and b.max() <= 1.0


def test_points_must_be_n_by_3():
    sphere = trimesh.creation.icosphere(subdivisions=1)
    with pytest.raises(ValueError, match=r"\(n, 3\)"):
        TriangleSurface(sphere.vertices, sphere.faces).closest(np.zeros((4, 2)))
