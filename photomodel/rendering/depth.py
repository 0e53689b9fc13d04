"""Depth-map visibility: is a point hidden by the surface a depth map was rendered from?

The test of Pighin et al. (2002), §5.2.1: "with the aid of this depth map, we can quickly classify
the visibility of each face point by applying the viewing transformation and comparing the
resulting depth to the corresponding value in the depth map." It is the one depth test of Face
Studio: texturing (:mod:`photomodel.texturing.visibility` adds the front-facing test of §5.2.1
and the depth maps), the fitted-mesh wireframe overlay
(:func:`photomodel.modeling.wireframe.visible_points`) and the synthetic artist who decides which
features to click (:func:`photomodel.samples.synthetic.visible`) all call :func:`depth_visible`;
they differ only in how the map is read at a point (:func:`surface_depth`).

* :func:`project_points` — pixel positions and depths of many world points (OpenCV, fast).
* :func:`depth_visible` — inside the image, in front of the camera, and not behind the
  depth map by more than ``tol_mm``.
* :func:`surface_depth` — the depth map read at pixel positions, three ways.

Depth comparison details
------------------------
The depth at the projected position is interpolated *bilinearly* between the four
surrounding pixel centres, so a point on a sloped surface is compared with the surface
depth at exactly its position, not at the nearest pixel centre (which would differ by up to
half a pixel times the slope). Background pixels (``inf``) are replaced by a far sentinel
before interpolation: a point whose neighbourhood includes background lies on a silhouette,
where it is in front of the interpolated value and therefore classified visible — points
on a silhouette are seen edge-on and get a vanishing positional certainty anyway
(:func:`photomodel.texturing.weights.positional_certainty`). That is the default lookup
(``"bilinear"``); :func:`surface_depth` says what the other two do and who reads the map that
way. The default tolerance of 1.5 mm is well
under the depth step of every occlusion on a face (the nose over the cheek: ≥ 10 mm; an
eyelid over the eye: ~3 mm) and well over the interpolation error of a triangle surface
drawn at ≥ 0.2 mm per pixel.
"""

from __future__ import annotations

import cv2
import numpy as np

from photomodel.camera import Camera
from photomodel.rendering.sampling import sample_image

__all__ = ["DEPTH_TOL_MM", "FAR_SENTINEL_MM", "project_points", "depth_visible", "surface_depth"]

#: Default depth-comparison tolerance (mm), see the module notes.
DEPTH_TOL_MM = 1.5
#: Stand-in for ``inf`` (background) in depth maps before bilinear interpolation (mm).
FAR_SENTINEL_MM = 1.0e7


def project_points(camera: Camera, points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Pixel positions and depths of world points.

    Parameters
    ----------
    camera : Camera
    points : (n, 3) float, mm
        float32 input is projected in float32 (texturing projects millions of texels; at
        head scale float32 is exact to ~10⁻⁴ mm), anything else in float64.

    Returns
    -------
    uv : (n, 2) float
        pixels (``Camera.project``); meaningless where ``z <= 0``.
    z : (n,) float
        ``Z_cam`` in mm.
    """

    P = np.asarray(points)
    dt = np.float32 if P.dtype == np.float32 else np.float64
    P = np.ascontiguousarray(P, dtype=dt).reshape(-1, 1, 3)
    if len(P) == 0:
        return np.zeros((0, 2), dt), np.zeros(0, dt)
    # one 4×4 homogeneous map (u·w, v·w, 1, w) with w = Z_cam: OpenCV applies it and divides
    # in one pass, ~10× faster than numpy's matmul on (n, 3) arrays
    RT = np.column_stack([camera.R, camera.t])
    M = np.zeros((4, 4))
    M[:2] = (camera.K @ RT)[:2]
    M[2, 3] = 1.0
    M[3] = RT[2]
    out = cv2.perspectiveTransform(P, M).reshape(-1, 3)
    with np.errstate(divide="ignore"):
        z = 1.0 / out[:, 2]
    return out[:, :2], z


def depth_visible(
    camera: Camera,
    points: np.ndarray,
    depth: np.ndarray,
    *,
    tol_mm: float = DEPTH_TOL_MM,
    uv: np.ndarray | None = None,
    z: np.ndarray | None = None,
    lookup: str = "bilinear",
) -> np.ndarray:
    """Depth-map visibility test of §5.2.1 (occlusion and image bounds, not facing): the one
    depth test of Face Studio (texturing, the wireframe overlay, the synthetic artist).

    Parameters
    ----------
    camera : Camera
        the camera ``depth`` was rendered with.
    points : (n, 3) float
        mm, on (or within a fraction of a mm of) the surface that ``depth`` was rendered from.
    depth : (H, W) float
        depth map of that surface from ``camera`` (:func:`render_depth`), ``inf`` on background.
    tol_mm : float
        a point counts as visible when ``z <= depth(uv) + tol_mm``.
    uv, z : optional
        the result of :func:`project_points` if the caller already has it.
    lookup : ``"bilinear"``, ``"covered"`` or ``"max3x3"``
        how ``depth(uv)`` is read (:func:`surface_depth`).

    Returns
    -------
    (n,) bool
        projects where the lookup reads the map (for the bilinear ones: pixel centres span
        ``[0, W-1] × [0, H-1]``), lies in front of the camera and is not hidden by the rendered
        surface.
    """
    depth = np.asarray(depth)
    if depth.shape != (camera.height, camera.width):
        raise ValueError(f"depth map is {depth.shape}, camera image is {(camera.height, camera.width)}")
    if uv is None or z is None:
        uv, z = project_points(camera, points)
    surface, valid = surface_depth(depth, uv, lookup=lookup)
    with np.errstate(invalid="ignore"):
        return valid & (z > 0) & (z <= surface + tol_mm)


def surface_depth(depth: np.ndarray, uv: np.ndarray, *, lookup: str = "bilinear") -> tuple[np.ndarray, np.ndarray]:
    """The depth of the rendered surface at pixel positions ``uv`` (n, 2), and where the map has one.

    Parameters
    ----------
    depth : (H, W) float, ``Z_cam`` mm, ``inf`` on background.
    uv : (n, 2) float, pixels (centres at integers).
    lookup : str
        ``"bilinear"`` — between the four surrounding pixel centres, background read as a far
        surface (:data:`FAR_SENTINEL_MM`): a point on a silhouette is in front of it (texturing,
        see the module notes); read within ``[0, W-1] × [0, H-1]``.
        ``"covered"`` — between the *covered* ones of the four (weights renormalised): a point on
        a silhouette is compared with the surface beside it rather than with the background (what
        an artist sees and clicks: :func:`photomodel.samples.synthetic.visible`); read within
        ``[0, W-1] × [0, H-1]`` where at least one of the four is covered (needs ``W, H ≥ 2``).
        ``"max3x3"`` — the deepest of the 3×3 pixels around the nearest one, background far:
        tolerant along silhouettes on a coarse map (the wireframe overlay's half-resolution map,
        :func:`photomodel.modeling.wireframe.visible_points`); read where the nearest pixel is in the map.

    Returns
    -------
    surface : (n,) float, mm (float32 but for ``"covered"``, float64); meaningless where not ``valid``.
    valid : (n,) bool
    """
    H, W = depth.shape
    if lookup == "max3x3":
        col, row = np.rint(uv[:, 0]).astype(np.int64), np.rint(uv[:, 1]).astype(np.int64)
        valid = (col >= 0) & (col < W) & (row >= 0) & (row < H)
        d = np.where(np.isfinite(depth), depth, FAR_SENTINEL_MM).astype(np.float32)
        d = cv2.dilate(d, np.ones((3, 3), np.uint8))  # 3×3 maximum
        surface = np.zeros(len(uv), np.float32)
        surface[valid] = d[row[valid], col[valid]]
        return surface, valid
    with np.errstate(invalid="ignore"):
        valid = (uv[:, 0] >= 0) & (uv[:, 0] <= W - 1) & (uv[:, 1] >= 0) & (uv[:, 1] <= H - 1)
    if lookup == "bilinear":
        d = np.where(np.isfinite(depth), depth, FAR_SENTINEL_MM).astype(np.float32)
        return sample_image(d, uv, border_value=FAR_SENTINEL_MM), valid
    if lookup == "covered":
        surface, covered = _covered_bilinear(np.asarray(depth, float), uv)
        return surface, valid & covered
    raise ValueError(f"lookup must be 'bilinear', 'covered' or 'max3x3', got {lookup!r}")


def _covered_bilinear(depth: np.ndarray, uv: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Bilinear interpolation of ``depth`` (H, W) float64 at ``uv`` over the finite ones of the four
    surrounding pixels (positions clamped into the map); ``(surface, any of the four finite)``."""
    H, W = depth.shape
    u = np.clip(uv[:, 0], 0, W - 1)
    v = np.clip(uv[:, 1], 0, H - 1)
    u0 = np.minimum(np.floor(u).astype(int), W - 2)
    v0 = np.minimum(np.floor(v).astype(int), H - 2)
    fu, fv = u - u0, v - v0
    corners = np.stack([depth[v0, u0], depth[v0, u0 + 1], depth[v0 + 1, u0], depth[v0 + 1, u0 + 1]], 1)
    wts = np.stack([(1 - fu) * (1 - fv), fu * (1 - fv), (1 - fu) * fv, fu * fv], 1)
    finite = np.isfinite(corners)
    wts = np.where(finite, wts, 0.0)
    has = wts.sum(1) > 0
    total = np.where(has, wts.sum(1), 1.0)
    return np.where(has, (np.where(finite, corners, 0.0) * wts).sum(1) / total, np.inf), has
