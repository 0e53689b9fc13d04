"""Exact closest points on a triangle surface (:class:`TriangleSurface`) and barycentric coordinates.

Used wherever one surface is matched onto another: ICT's head registered onto the generic mesh
(:mod:`photomodel.rig.registration`), and, in the samples, the generic mesh onto the james scan and
distances to the scan (:mod:`photomodel.samples.synthetic`). No spatial-index dependency: a k-d
tree over samples of the triangles finds candidates and :func:`trimesh.triangles.closest_point`
the exact answer.
"""

from __future__ import annotations

import numpy as np
from scipy.spatial import cKDTree
from trimesh.triangles import closest_point

from photomodel.rendering.renderer import vertex_normals

__all__ = ["TriangleSurface", "barycentric_coordinates"]


def barycentric_coordinates(points: np.ndarray, triangles: np.ndarray) -> np.ndarray:
    """(n, 3) barycentric coordinates of ``points`` (n, 3) in ``triangles`` (n, 3, 3), clipped to
    [0, 1] (points are expected on or next to their triangle)."""
    tri = triangles
    e0, e1, e2 = tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0], points - tri[:, 0]
    d00, d01, d11 = (e0 * e0).sum(1), (e0 * e1).sum(1), (e1 * e1).sum(1)
    d20, d21 = (e2 * e0).sum(1), (e2 * e1).sum(1)
    den = np.where(np.abs(d00 * d11 - d01**2) > 1e-18, d00 * d11 - d01**2, 1.0)
    b1 = (d11 * d20 - d01 * d21) / den
    b2 = (d00 * d21 - d01 * d20) / den
    return np.clip(np.column_stack([1.0 - b1 - b2, b1, b2]), 0.0, 1.0)


class TriangleSurface:
    """Exact closest-point queries on a triangle surface (no spatial-index dependency).

    Every triangle is covered by a barycentric grid of sample points no farther than
    ``spacing_mm`` from any point of the triangle; a k-d tree over the samples yields
    candidate triangles and :func:`trimesh.triangles.closest_point` the exact answer.
    The result is exact: if the best candidate is at distance ``d`` and the k-th sample
    is farther than ``d + spacing_mm``, no triangle outside the candidates can be closer
    (each has a sample within ``spacing_mm`` of its own closest point); otherwise the
    query is repeated with more candidates.

    Parameters
    ----------
    vertices : (n, 3) float, mm.
    faces : (m, 3) int.
    spacing_mm : float
        sample coverage radius.
    """

    def __init__(self, vertices: np.ndarray, faces: np.ndarray, spacing_mm: float = 2.0):
        self.vertices = np.asarray(vertices, float)
        self.faces = np.asarray(faces, np.int64)
        self.triangles = self.vertices[self.faces]
        self.spacing = float(spacing_mm)
        tri = self.triangles
        longest = np.linalg.norm(tri - np.roll(tri, 1, axis=1), axis=2).max(axis=1)
        subdiv = np.maximum(1, np.ceil(longest / self.spacing).astype(int))
        samples, owner = [], []
        for m in np.unique(subdiv):
            sel = np.flatnonzero(subdiv == m)
            i, j = np.meshgrid(np.arange(m + 1), np.arange(m + 1), indexing="ij")
            keep = i + j <= m
            bary = np.column_stack([i[keep], j[keep], m - i[keep] - j[keep]]) / m
            samples.append(np.einsum("sk,tkd->tsd", bary, tri[sel]).reshape(-1, 3))
            owner.append(np.repeat(sel, len(bary)))
        self._samples = np.concatenate(samples)
        self._owner = np.concatenate(owner)
        self._tree = cKDTree(self._samples)
        cross = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
        self.face_normals = cross / np.maximum(np.linalg.norm(cross, axis=1, keepdims=True), 1e-12)
        # outward vertex normals (area-weighted), for normals at closest points
        self.vertex_normals = vertex_normals(self.vertices, self.faces)

    def closest(self, points: np.ndarray, k: int = 24) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Closest surface points.

        Parameters
        ----------
        points : (n, 3) float, mm.

        Returns
        -------
        closest : (n, 3) float, mm.
        distance : (n,) float, mm.
        face : (n,) int, triangle holding each closest point.
        """

        points = np.asarray(points, float)
        if points.ndim != 2 or points.shape[1] != 3:
            raise ValueError(f"points must be an (n, 3) array of mm positions, got shape {points.shape}")
        n = len(points)
        out, dist, face = np.zeros((n, 3)), np.full(n, np.inf), np.zeros(n, np.int64)
        todo = np.arange(n)
        while len(todo):
            kk = min(k, len(self._samples))
            for chunk in np.array_split(todo, max(1, len(todo) * kk // 400_000)):
                d_k, idx = self._tree.query(points[chunk], kk)
                d_k, idx = d_k.reshape(len(chunk), kk), idx.reshape(len(chunk), kk)
                cand = self._owner[idx]
                c = closest_point(self.triangles[cand.ravel()], np.repeat(points[chunk], kk, axis=0))
                c = c.reshape(len(chunk), kk, 3)
                d = np.linalg.norm(c - points[chunk, None], axis=2)
                j = d.argmin(axis=1)
                a = np.arange(len(chunk))
                out[chunk], dist[chunk], face[chunk] = c[a, j], d[a, j], cand[a, j]
                proven = (dist[chunk] + self.spacing <= d_k[:, -1]) | (kk == len(self._samples))
                dist[chunk[~proven]] = -1.0  # marker: query again with more candidates
            todo = todo[dist[todo] < 0]
            k *= 4
        return out, dist, face

    def normals_at(self, points: np.ndarray, face: np.ndarray) -> np.ndarray:
        """(n, 3) unit normals at surface ``points`` on triangles ``face``: the vertex
        normals interpolated barycentrically (smooth across edges)."""
        bary = barycentric_coordinates(points, self.triangles[face])
        n = np.einsum("nk,nkd->nd", bary, self.vertex_normals[self.faces[face]])
        return n / np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-12)
