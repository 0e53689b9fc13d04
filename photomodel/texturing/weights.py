"""Blending weights of the texture extraction: weight maps ``g_k`` (Pighin et al. 2002, §5.2.1–5.2.3).

The texture colour at a surface point ``m`` is the convex combination (§5.2.1)

    T(m) = Σ_k g_k(m) C_k(x_k, y_k) / Σ_k g_k(m),

with one weight map per photograph, built from the paper's considerations:

1. *self-occlusion* — ``g_k = 0`` unless ``m`` is front-facing and visible in photo ``k``
   (:mod:`photomodel.texturing.visibility`);
2. *smoothness* — the binary visibility map is **feathered**: ramped from 1 to 0 near its
   boundaries with a cubic polynomial (§5.2.2 step 1; :func:`feather`, :func:`cubic_ramp`);
3. *positional certainty* ``P_k(m) = n · d_k`` (:func:`positional_certainty`);
4. *view similarity* (view-dependent rendering only, §5.2.3):
   ``V_k(d) = d · d_k − d_ℓ · d_{ℓ+1}`` for the two photos ``ℓ, ℓ+1`` whose view
   directions are nearest to the new one, 0 for the others (:func:`view_similarity`;
   :func:`select_views` picks the two that *bracket* the new direction, which keeps the
   blend continuous when the cameras are unevenly spaced).

The weights are ``g_k = F_k P_k`` for the cylindrical texture (§5.2.2 step 3) and
``g_k = F_k P_k V_k`` for view-dependent rendering (§5.2.3).

Feathering
----------
``F = cubic_ramp(dist / width)`` where ``dist`` is the Euclidean distance (mm) to the
nearest invisible pixel (OpenCV's exact distance transform) and
``cubic_ramp(t) = 3t² − 2t³`` (the smooth cubic with zero slope at both ends, so the ramp
joins the flat 0 and 1 regions without a crease). The distance is measured in millimetres on
the surface, not in pixels, so the same width serves a 256² preview texture and a 2048²
export: a map whose pixels are not square in mm (the cylindrical texture) is resampled to
square pixels for the transform. The default width :data:`FEATHER_WIDTH_MM` = 6 mm is the
measured optimum of ``benchmarks/bench_texture.py --feather-sweep`` (held-out PSNR of the
fitted model over widths 0–16 mm; see docs/texturing.md): it is several times the fitted
mesh's typical surface error (1–2 mm), so a seam where a photograph stops contributing —
around the nose, where the fitted geometry is least certain — is spread over a band wider
than the misregistration it would otherwise show, yet narrow enough to keep the sharpest
(most frontal) photograph dominant over most of the face.

Beyond the paper: :func:`apply_single_view` replaces the blend by the single best photograph
(argmax of ``g_k``) where a per-point weight ``s`` says so — the ears and hair of §5.2.4,
which the generic mesh has no separate parts for — with ``s`` ramped so that the switch from
blend to single view leaves no seam.
"""

from __future__ import annotations

from collections.abc import Sequence

import cv2
import numpy as np

from photomodel.camera import Camera

__all__ = [
    "FEATHER_WIDTH_MM",
    "DEPTH_JUMP_MM",
    "cubic_ramp",
    "feather",
    "image_feather_map",
    "positional_certainty",
    "view_directions",
    "select_views",
    "view_similarity",
    "apply_single_view",
    "blend",
]

#: Default feathering width (mm on the surface), see the module notes.
FEATHER_WIDTH_MM = 6.0
#: Depth step (mm) between neighbouring pixels of a depth map that marks an occluding contour
#: (:func:`image_feather_map`). On a continuous face surface neighbouring pixels differ by the
#: pixel footprint (~0.3 mm for a head filling a 1000-pixel photo) times the slope, i.e. under
#: 4 mm up to 85° from the viewing direction; the nose over the cheek steps by ≥ 10 mm.
DEPTH_JUMP_MM = 5.0


def cubic_ramp(t: np.ndarray) -> np.ndarray:
    """The cubic ramp ``3t² − 2t³`` of ``t`` clipped to ``[0, 1]`` (§5.2.2 step 1).

    Parameters
    ----------
    t : array
        normalised distance to the visibility boundary (0 at the boundary, 1 at the width).

    Returns
    -------
    array of ``t``'s shape, float
        0 for ``t ≤ 0``, 1 for ``t ≥ 1``, monotone, with zero slope at both ends.
    """
    t = np.clip(np.asarray(t, dtype=np.float32), 0.0, 1.0)
    return t * t * (3.0 - 2.0 * t)


def feather(binary: np.ndarray, width: float, *, pixel_size=(1.0, 1.0)) -> np.ndarray:
    """Feathered visibility map ``F`` of a binary map (§5.2.2 step 1).

    Parameters
    ----------
    binary : (H, W) bool
        1 where the point is visible (the binary visibility map).
    width : float
        ramp width, in the units of ``pixel_size`` (mm); ``0`` returns the binary map.
    pixel_size : (float, float)
        ``(sy, sx)``: size of one pixel along rows and columns (mm per pixel). Distances
        are Euclidean in these units.

    Returns
    -------
    (H, W) float32
        ``cubic_ramp(dist / width)``, ``dist`` the distance from a pixel centre to the
        nearest invisible pixel centre (at least one pixel inside the map): 0 on invisible
        pixels, rising to 1 at ``width`` from the boundary. Pixels beyond the map's edge
        do not count as invisible (OpenCV's distance transform ignores the frame), so a
        map cut by the texture's border is not ramped there.
    """

    B = np.asarray(binary, dtype=bool)
    if B.ndim != 2:
        raise ValueError(f"binary map must be (H, W), got shape {B.shape}")
    sy, sx = (float(s) for s in pixel_size)
    if not (sy > 0 and sx > 0):
        raise ValueError(f"pixel_size must be positive, got {pixel_size}")
    if width < 0:
        raise ValueError(f"feather width must be >= 0, got {width}")
    if width == 0 or not B.any():
        return B.astype(np.float32)
    if B.all():
        return np.ones(B.shape, np.float32)
    H, W = B.shape
    unit = min(sy, sx)
    # resample to square pixels of side `unit` for the (isotropic) distance transform
    Hs, Ws = max(1, round(H * sy / unit)), max(1, round(W * sx / unit))
    src = B.astype(np.uint8)
    if (Hs, Ws) != (H, W):
        src = cv2.resize(src, (Ws, Hs), interpolation=cv2.INTER_NEAREST)
    dist = cv2.distanceTransform(src, cv2.DIST_L2, cv2.DIST_MASK_PRECISE)
    F = cubic_ramp(dist * np.float32(unit / width))
    if (Hs, Ws) != (H, W):
        F = cv2.resize(F, (W, H), interpolation=cv2.INTER_LINEAR)
        F[~B] = 0.0
    return F


def image_feather_map(
    depth: np.ndarray,
    width_mm: float,
    mm_per_px: float,
    *,
    jump_mm: float = DEPTH_JUMP_MM,
) -> np.ndarray:
    """Feathered visibility map ``F_k(x_k, y_k)`` in a photograph's own pixels (§5.2.3).

    View-dependent rendering indexes ``F_k`` by image coordinates: the binary map is the
    set of pixels where the model is seen, less the pixels on an occluding contour (a depth
    step larger than ``jump_mm`` to a 4-neighbour), so the weight ramps to 0 both at the
    silhouette and along the contour where a nearer part (the nose) hides a farther one.

    Parameters
    ----------
    depth : (H, W) float
        the model's depth map from the photograph's camera (``inf`` on background).
    width_mm : float
        ramp width on the surface (mm).
    mm_per_px : float
        size of one pixel on the surface (mm): ``Z / f`` at the model's typical depth.
    jump_mm : float
        depth step that marks an occluding contour.

    Returns
    -------
    (H, W) float32
    """
    D = np.asarray(depth, dtype=np.float32)
    inside = np.isfinite(D)
    Df = np.where(inside, D, np.float32(1e7))
    edge = np.zeros_like(inside)
    dv = np.abs(np.diff(Df, axis=0)) > jump_mm
    dh = np.abs(np.diff(Df, axis=1)) > jump_mm
    edge[1:] |= dv
    edge[:-1] |= dv
    edge[:, 1:] |= dh
    edge[:, :-1] |= dh
    return feather(inside & ~edge, width_mm, pixel_size=(mm_per_px, mm_per_px))


def positional_certainty(camera: Camera, points: np.ndarray, normals: np.ndarray, *, clip: bool = True) -> np.ndarray:
    """Positional certainty ``P_k(m) = n · d_k`` (§5.2.1, consideration 3; Kurihara & Arai 1991).

    Parameters
    ----------
    camera : Camera
        photo ``k``.
    points : (n, 3) float
        surface points ``m`` in mm.
    normals : (n, 3) float
        outward unit normals at ``points``.
    clip : bool
        clip at 0 (back-facing points get no weight); ``False`` returns the signed cosine.

    Returns
    -------
    (n,) float32
        the cosine between the normal and the unit direction ``d_k`` from ``m`` to the
        camera centre.
    """

    # in camera coordinates the camera centre is the origin: d_k = -X_cam / |X_cam|
    # (cv2.transform: ~10× faster than numpy's matmul on (n, 3) arrays)
    RT = np.column_stack([camera.R, camera.t])
    pts = np.ascontiguousarray(points, dtype=np.float32).reshape(-1, 1, 3)
    nrm = np.ascontiguousarray(normals, dtype=np.float32).reshape(-1, 1, 3)
    if len(pts) == 0:
        return np.zeros(0, np.float32)
    Xc = cv2.transform(pts, RT).reshape(-1, 3)
    Nc = cv2.transform(nrm, camera.R).reshape(-1, 3)
    dist = np.sqrt(np.einsum("ij,ij->i", Xc, Xc))
    cos = -np.einsum("ij,ij->i", Nc, Xc) / np.maximum(dist, np.float32(1e-12))
    return np.maximum(cos, 0.0) if clip else cos


def view_directions(cameras: Sequence[Camera], centre: np.ndarray) -> np.ndarray:
    """Unit view directions ``d_k``: from the head ``centre`` towards each camera centre.

    Parameters
    ----------
    cameras : k Camera
    centre : (3,) float, mm (e.g. the centroid of the model).

    Returns
    -------
    (k, 3) float
    """
    c = np.asarray(centre, dtype=float).reshape(3)
    d = np.array([cam.center - c for cam in cameras], dtype=float).reshape(-1, 3)
    n = np.linalg.norm(d, axis=1, keepdims=True)
    if np.any(n == 0):
        raise ValueError("a camera centre coincides with the head centre; no view direction")
    return d / n


def select_views(d: np.ndarray, directions: np.ndarray) -> tuple[int, int]:
    """The two photographs ``ℓ, ℓ+1`` whose view directions are nearest to ``d`` (§5.2.3).

    ``ℓ`` is the nearest photograph (largest ``d · d_k``). The second is the nearest of the
    photographs that lie *beyond* ``d`` as seen from ``ℓ`` — those with
    ``d · d_k > d_ℓ · d_k``, i.e. a positive ``V_k(d)`` — so that ``ℓ, ℓ+1`` bracket ``d``
    like consecutive cameras of the paper's rig ("positioned roughly in the same plane").
    For evenly spaced cameras this is simply the second nearest; for uneven spacing (the
    sample rig: −75°, −35°, 0°, +40°, +80°) the plain second-nearest would switch from one
    side to the other at a point where its weight is not zero, and the rendering would jump
    (see ``tests/test_weights.py``). When no photograph lies beyond ``d`` (a view outside the
    photographed arc) the second index repeats the first.

    Parameters
    ----------
    d : (3,) float, unit view direction of the new view.
    directions : (k, 3) float, unit ``d_k`` of the photographs (:func:`view_directions`), k ≥ 1.

    Returns
    -------
    (int, int)
    """
    dirs = np.asarray(directions, dtype=float).reshape(-1, 3)
    if len(dirs) == 0:
        raise ValueError("no photographs to select from")
    d = np.asarray(d, dtype=float).reshape(3)
    cos = dirs @ d
    nearest = int(np.argmax(cos))
    beyond = cos - dirs @ dirs[nearest] > 1e-12
    beyond[nearest] = False
    if not beyond.any():
        return nearest, nearest
    second = int(np.flatnonzero(beyond)[np.argmax(cos[beyond])])
    return nearest, second


def view_similarity(d: np.ndarray, directions: np.ndarray) -> np.ndarray:
    """View-dependent term ``V_k(d)`` of §5.2.3 for every photograph.

    ``V_k(d) = d · d_k − d_ℓ · d_{ℓ+1}`` for the two photographs ``ℓ, ℓ+1`` of
    :func:`select_views` and 0 for the others: a single photograph when the new view
    matches its direction exactly, a smooth blend of the two otherwise.

    Parameters
    ----------
    d : (3,) float, unit direction of the new view.
    directions : (k, 3) float, unit directions of the photographs.

    Returns
    -------
    (k,) float
        non-negative; the blend uses only their ratio. Outside the photographed arc (no
        photograph beyond ``d``) the nearest photograph alone gets weight 1.
    """
    dirs = np.asarray(directions, dtype=float).reshape(-1, 3)
    d = np.asarray(d, dtype=float).reshape(3)
    d = d / np.linalg.norm(d)
    l0, l1 = select_views(d, dirs)
    V = np.zeros(len(dirs))
    if l0 == l1:
        V[l0] = 1.0
        return V
    base = float(dirs[l0] @ dirs[l1])
    V[l0] = float(d @ dirs[l0]) - base  # ≥ V[l1] > 0 by the choice of l0 and l1
    V[l1] = float(d @ dirs[l1]) - base
    return V


def apply_single_view(weights: np.ndarray, single: np.ndarray | None) -> np.ndarray:
    """Blend weights with the single-best-view fallback of §5.2.4 mixed in.

    ``g'_k = (1 − s) g_k / Σ_j g_j + s [k = argmax_j g_j]``: where ``s = 1`` only the
    photograph with the largest weight contributes (no smeared blend of a misregistered
    ear or of hair), where ``s = 0`` it is the plain blend, and a ramp of ``s`` joins them
    without a seam.

    Parameters
    ----------
    weights : (k, ...) float
        ``g_k``, non-negative.
    single : (...) float in [0, 1] or None
        the single-view weight ``s`` per point; ``None`` returns ``weights`` unchanged.

    Returns
    -------
    (k, ...) float32
        normalised to sum 1 where ``Σ g_k > 0`` (0 elsewhere) when ``single`` is given.
    """
    g = np.asarray(weights, dtype=np.float32)
    if single is None:
        return g
    s = np.clip(np.asarray(single, dtype=np.float32), 0.0, 1.0)
    if s.shape != g.shape[1:]:
        raise ValueError(f"single-view weights have shape {s.shape}, expected {g.shape[1:]}")
    k = len(g)
    flat = g.reshape(k, -1)
    total = flat.sum(axis=0)
    has = total > 0
    scale = np.divide(1.0 - s.reshape(-1), total, out=np.zeros_like(total), where=has)
    out = flat * scale
    best = np.argmax(flat, axis=0)
    out[best, np.arange(flat.shape[1])] += np.where(has, s.reshape(-1), 0.0)
    return out.reshape(g.shape).astype(np.float32, copy=False)


def blend(colors: np.ndarray, weights: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The convex combination ``Σ g_k C_k / Σ g_k`` of §5.2.1.

    Parameters
    ----------
    colors : (k, n, C) float or uint8
        colour of each point in each photograph.
    weights : (k, n) float
        ``g_k``, non-negative.

    Returns
    -------
    color : (n, C) float32
        blended colour; 0 where all weights vanish.
    total : (n,) float32
        ``Σ_k g_k``.
    """
    g = np.asarray(weights, dtype=np.float32)
    if g.ndim != 2 or np.shape(colors)[:2] != g.shape:
        raise ValueError(f"colors {np.shape(colors)} and weights {g.shape} must be (k, n, C) and (k, n)")
    total = g.sum(axis=0)
    num = np.zeros((g.shape[1], np.shape(colors)[2]), np.float32)
    for gk, ck in zip(g, colors, strict=True):  # k is small; avoids a (k, n, C) float temporary
        num += gk[:, None] * ck
    has = total > 0
    num[has] /= total[has, None]
    num[~has] = 0.0
    return num, total
