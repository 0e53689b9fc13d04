"""Which surface points each photograph sees: depth-map visibility (Pighin et al. 2002, §5.2.1).

The paper's recipe, verbatim: "we first render the face model using the recovered viewing
parameters and save the resulting depth map from the Z-buffer. Then, with the aid of this
depth map, we can quickly classify the visibility of each face point by applying the viewing
transformation and comparing the resulting depth to the corresponding value in the depth
map." Consideration 1 of §5.2.1 adds that a point must also be *front-facing*
(``n · d_k > 0``).

* :func:`render_depth` — the depth map (``Z_cam`` in mm, ``inf`` off the mesh) of a mesh
  seen by a camera, drawn by the one renderer (:mod:`photomodel.rendering.renderer`).
* :func:`sample_image` — bilinear samples of an image at many sub-pixel positions
  (``cv2.remap``), the primitive texturing uses for colours, depths and feather maps.
* :func:`depth_visible` — inside the image, in front of the camera, and not behind the
  depth map by more than ``tol_mm``.
* :func:`front_facing` — ``n · d_k > min_cos`` with ``d_k`` the unit direction from the
  point to the camera centre.
* :func:`visible` — both; :func:`vertex_visibility` — the ``(k, N)`` table for a mesh's
  vertices in ``k`` photos.

Depth comparison details
------------------------
The depth at the projected position is interpolated *bilinearly* between the four
surrounding pixel centres, so a point on a sloped surface is compared with the surface
depth at exactly its position, not at the nearest pixel centre (which would differ by up to
half a pixel times the slope). Background pixels (``inf``) are replaced by a far sentinel
before interpolation: a point whose neighbourhood includes background lies on a silhouette,
where it is in front of the interpolated value and therefore classified visible — points
on a silhouette are seen edge-on and get a vanishing positional certainty anyway
(:func:`photomodel.texturing.weights.positional_certainty`). The default tolerance of 1.5 mm is well
under the depth step of every occlusion on a face (the nose over the cheek: ≥ 10 mm; an
eyelid over the eye: ~3 mm) and well over the interpolation error of a triangle surface
drawn at ≥ 0.2 mm per pixel.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from photomodel.camera import Camera

__all__ = [
    "DEPTH_TOL_MM",
    "FAR_SENTINEL_MM",
    "render_depth",
    "sample_image",
    "project_points",
    "depth_visible",
    "front_facing",
    "visible",
    "vertex_visibility",
]

#: Default depth-comparison tolerance (mm), see the module notes.
DEPTH_TOL_MM = 1.5
#: Stand-in for ``inf`` (background) in depth maps before bilinear interpolation (mm).
FAR_SENTINEL_MM = 1.0e7

# cv2.remap refuses destination images with a side of 32767 or more, so point lists are
# folded into rows of this many samples.
_REMAP_ROW = 4096


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
    from photomodel.rendering.renderer import get_renderer

    return get_renderer().render(camera, vertices, faces).depth


def sample_image(image: np.ndarray, uv: np.ndarray, *, border_value=0.0) -> np.ndarray:
    """Bilinear samples of ``image`` at sub-pixel positions (``cv2.remap``).

    Parameters
    ----------
    image : (H, W) or (H, W, C) uint8 or float32
        pixel centres at integer coordinates (:mod:`photomodel.camera`).
    uv : (n, 2) float
        positions ``(u, v)`` in pixels, ``u`` right, ``v`` down.
    border_value : float
        value of samples whose 2×2 neighbourhood leaves the image (constant border).

    Returns
    -------
    (n,) or (n, C), dtype of ``image``
        OpenCV interpolates with 1/32-pixel fixed-point weights, which is far below the
        accuracy of any recovered camera.
    """
    import cv2

    img = np.asarray(image)
    if img.dtype not in (np.uint8, np.float32):
        img = img.astype(np.float32)
    uv = np.asarray(uv, dtype=np.float32).reshape(-1, 2)
    n = len(uv)
    C = img.shape[2] if img.ndim == 3 else 0
    if n == 0:
        return np.zeros((0, C) if C else (0,), img.dtype)
    rows = -(-n // _REMAP_ROW)
    pad = rows * _REMAP_ROW - n
    maps = np.concatenate([uv, np.full((pad, 2), -10.0, np.float32)]).reshape(rows, _REMAP_ROW, 2)
    border = (float(border_value),) * 4
    out = cv2.remap(img, maps, None, cv2.INTER_LINEAR, borderMode=cv2.BORDER_CONSTANT, borderValue=border)
    return out.reshape(rows * _REMAP_ROW, *((C,) if C else ()))[:n]


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
    import cv2

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
) -> np.ndarray:
    """Depth-map visibility test of §5.2.1 (occlusion and image bounds, not facing).

    Parameters
    ----------
    camera : Camera
    points : (n, 3) float
        mm, on (or within a fraction of a mm of) the surface that ``depth`` was rendered from.
    depth : (H, W) float
        depth map of that surface from ``camera`` (:func:`render_depth`), ``inf`` on background.
    tol_mm : float
        a point counts as visible when ``z <= depth(uv) + tol_mm``.
    uv, z : optional
        the result of :func:`project_points` if the caller already has it.

    Returns
    -------
    (n,) bool
        projects inside the image (pixel centres span ``[0, W-1] × [0, H-1]``), lies in
        front of the camera and is not hidden by the rendered surface.
    """
    depth = np.asarray(depth)
    if depth.shape != (camera.height, camera.width):
        raise ValueError(f"depth map is {depth.shape}, camera image is {(camera.height, camera.width)}")
    if uv is None or z is None:
        uv, z = project_points(camera, points)
    W, H = camera.width, camera.height
    with np.errstate(invalid="ignore"):
        inside = (z > 0) & (uv[:, 0] >= 0) & (uv[:, 0] <= W - 1) & (uv[:, 1] >= 0) & (uv[:, 1] <= H - 1)
    d = np.where(np.isfinite(depth), depth, FAR_SENTINEL_MM).astype(np.float32)
    interp = sample_image(d, uv, border_value=FAR_SENTINEL_MM)
    return inside & (z <= interp + tol_mm)


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
    from photomodel.texturing.weights import positional_certainty

    return positional_certainty(camera, points, normals, clip=False) > min_cos


def visible(
    camera: Camera,
    points: np.ndarray,
    normals: np.ndarray,
    depth: np.ndarray,
    *,
    tol_mm: float = DEPTH_TOL_MM,
    min_cos: float = 0.0,
) -> np.ndarray:
    """Self-occlusion test of §5.2.1: front-facing and not hidden in the depth map.

    Parameters
    ----------
    camera : Camera
    points : (n, 3) float, mm.
    normals : (n, 3) float, outward unit normals.
    depth : (H, W) float, :func:`render_depth` of the surface from ``camera``.
    tol_mm, min_cos : see :func:`depth_visible` and :func:`front_facing`.

    Returns
    -------
    (n,) bool
    """
    return depth_visible(camera, points, depth, tol_mm=tol_mm) & front_facing(camera, points, normals, min_cos)


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
    from photomodel.rendering.renderer import vertex_normals

    V = np.asarray(vertices, dtype=float)
    normals = vertex_normals(V, faces)
    if depths is None:
        depths = [render_depth(c, V, faces) for c in cameras]
    if len(depths) != len(cameras):
        raise ValueError(f"{len(cameras)} cameras but {len(depths)} depth maps")
    return np.array(
        [visible(c, V, normals, d, tol_mm=tol_mm, min_cos=min_cos) for c, d in zip(cameras, depths, strict=True)]
    ).reshape(len(cameras), len(V))
