"""Which surface points each photograph sees: depth-map visibility (Pighin et al. 2002, §5.2.1).

The paper's recipe, verbatim: "we first render the face model using the recovered viewing
parameters and save the resulting depth map from the Z-buffer. Then, with the aid of this
depth map, we can quickly classify the visibility of each face point by applying the viewing
transformation and comparing the resulting depth to the corresponding value in the depth
map." Consideration 1 of §5.2.1 adds that a point must also be *front-facing*
(``n · d_k > 0``).

* :func:`render_depth` — the depth map (``Z_cam`` in mm, ``inf`` off the mesh) of a mesh
  seen by a camera, drawn by the one renderer (:mod:`photomodel.rendering.renderer`).
* :func:`photomodel.rendering.depth.depth_visible` — inside the image, in front of the
  camera, and not behind the depth map by more than ``tol_mm`` (the one depth test, with its
  details; the wireframe overlay and the synthetic artist use it too).
* :func:`front_facing` — ``n · d_k > min_cos`` with ``d_k`` the unit direction from the
  point to the camera centre.
* :func:`visible` — both; :func:`vertex_visibility` — the ``(k, N)`` table for a mesh's
  vertices in ``k`` photos.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from photomodel.camera import Camera
from photomodel.rendering.depth import DEPTH_TOL_MM, depth_visible
from photomodel.rendering.renderer import get_renderer, vertex_normals
from photomodel.texturing.weights import positional_certainty

__all__ = ["render_depth", "front_facing", "visible", "vertex_visibility"]


def render_depth(camera: Camera, vertices: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """Depth map of a mesh seen by ``camera`` (the Z-buffer of §5.2.1).

    Parameters
    ----------
    camera : Camera
        pose and intrinsics; the map is ``camera.height × camera.width``.
    vertices : (N, 3) float
        mm, world (head) frame.
    faces : (M, 3) int
        triangles.

    Returns
    -------
    (H, W) float32
        ``Z_cam`` in mm of the nearest surface at each pixel centre, ``inf`` on the background.
    """

    return get_renderer().render_depth(camera, vertices, faces)


def front_facing(camera: Camera, points: np.ndarray, normals: np.ndarray, min_cos: float = 0.0) -> np.ndarray:
    """Whether surface points face the camera: ``n · d_k > min_cos`` (§5.2.1, consideration 1).

    Parameters
    ----------
    camera : Camera
    points : (n, 3) float, mm.
    normals : (n, 3) float
        outward unit normals.
    min_cos : float
        threshold on the cosine between the normal and the direction to the camera centre.

    Returns
    -------
    (n,) bool
    """

    return positional_certainty(camera, points, normals, clip=False) > min_cos


def visible(
    camera: Camera,
    points: np.ndarray,
    normals: np.ndarray,
    depth: np.ndarray,
    *,
    tol_mm: float = DEPTH_TOL_MM,
    min_cos: float = 0.0,
    lookup: str = "bilinear",
) -> np.ndarray:
    """Self-occlusion test of §5.2.1: front-facing and not hidden in the depth map.

    Parameters
    ----------
    camera : Camera
    points : (n, 3) float, mm.
    normals : (n, 3) float, outward unit normals.
    depth : (H, W) float, :func:`render_depth` of the surface from ``camera``.
    tol_mm, lookup, min_cos : see :func:`photomodel.rendering.depth.depth_visible` and
        :func:`front_facing`.

    Returns
    -------
    (n,) bool
    """
    seen = depth_visible(camera, points, depth, tol_mm=tol_mm, lookup=lookup)
    return seen & front_facing(camera, points, normals, min_cos)


def vertex_visibility(
    cameras: Sequence[Camera],
    vertices: np.ndarray,
    faces: np.ndarray,
    *,
    depths: Sequence[np.ndarray] | None = None,
    tol_mm: float = DEPTH_TOL_MM,
    min_cos: float = 0.0,
) -> np.ndarray:
    """Visibility of a mesh's own vertices in ``k`` photos.

    Parameters
    ----------
    cameras : k Camera
    vertices : (N, 3) float, mm.
    faces : (M, 3) int.
    depths : k (H, W) float, optional
        the mesh's depth maps from ``cameras``; rendered when omitted.
    tol_mm, min_cos : see :func:`visible`.

    Returns
    -------
    (k, N) bool
    """

    V = np.asarray(vertices, dtype=float)
    normals = vertex_normals(V, faces)
    if depths is None:
        depths = [render_depth(c, V, faces) for c in cameras]
    if len(depths) != len(cameras):
        raise ValueError(f"{len(cameras)} cameras but {len(depths)} depth maps")
    return np.array(
        [visible(c, V, normals, d, tol_mm=tol_mm, min_cos=min_cos) for c, d in zip(cameras, depths, strict=True)]
    ).reshape(len(cameras), len(V))
