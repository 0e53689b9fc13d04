"""Synthetic facial expressions of the ``james`` scan: smooth deformation fields driven by its landmarks.

Pighin et al. (2002) §6.1.1 build their face model from several *basic expressions* of one
person, each modelled from photographs (§5). Our sample data is a single neutral head scan, so
the sample expressions are made by deforming it with smooth, plausible displacement fields
defined on 3D space in the neutral head frame (mm, :mod:`photomodel.camera` conventions) and
placed by the scan's iBUG-68 landmarks:

* ``open_mouth`` — a jaw rotation (:data:`JAW_ANGLE_DEG`) about a left–right axis at ear height
  of everything below the *mandible line* (from the lip line back to the jaw joints), with a
  smooth ramp across the line and a fade-out down the neck. The axis lies
  :data:`JAW_PIVOT_BEHIND_MM` behind the jaw joints: a real jaw rotates *and* glides forward, and
  that combined motion is a rotation about such a virtual centre (the chin goes mostly down);
* ``smile`` — the mouth corners (iBUG 48, 54) move up, outwards and back with a Gaussian falloff;
* ``brows_raised`` — the brows (iBUG 17–26) move up with a Gaussian falloff around the brow
  line, held still below the upper eyelids;
* ``frown`` (an extra expression, :data:`EXTRA_EXPRESSIONS`, that the sample video never uses:
  the tracking benchmark gives the model one expression more than the video) — the brows move
  down and towards the midline with the same falloff.

The same field deforms the scan (for the photos and the video) and the generic mesh's true
position on the scan (:func:`photomodel.samples.synthetic.true_correspondence`) — so the ground-truth
geometry of every expression on the generic mesh is known exactly. Tests, benchmarks and the
sample generators use this module; the tracker never does.
"""

from __future__ import annotations

import numpy as np

from photomodel.camera import rodrigues
from photomodel.samples.synthetic import true_correspondence

__all__ = [
    "EXPRESSION_NAMES",
    "EXTRA_EXPRESSIONS",
    "OUTSIDE_EXPRESSIONS",
    "JAW_ANGLE_DEG",
    "expression_displacement",
    "expression_displacements",
    "deformed_scan_vertices",
    "true_expression_geometry",
]

#: The basic expressions of the sample, neutral first (E_1 of §6.1.1).
EXPRESSION_NAMES = ("neutral", "smile", "open_mouth", "brows_raised")
#: Further expressions available to models but not used by the sample video.
EXTRA_EXPRESSIONS = ("frown",)
#: Expressions outside every model's set (truth of the tracking benchmark's sequence ``g`` only).
OUTSIDE_EXPRESSIONS = ("cheek_smile", "surprise")
#: Brow motion of ``frown`` (mm): down, and towards the midline.
FROWN_DOWN_MM, FROWN_IN_MM = 3.5, 3.0

#: Jaw opening of ``open_mouth`` (degrees): the chin moves ~17 mm down and ~10 mm back.
JAW_ANGLE_DEG = 6.0
#: The virtual jaw axis lies this far (mm) behind the ear-level jaw landmarks (iBUG 0, 16).
JAW_PIVOT_BEHIND_MM = 80.0
#: Width (mm) of the smooth ramp across the mandible line (lips and jaw line stretch over it).
JAW_RAMP_MM = 5.0
#: Below the chin the neck follows the jaw less and less, down to this far (mm) below it.
NECK_FADE_MM = 30.0
#: Mouth-corner displacement of ``smile`` (mm): outwards (subject's left/right), up, back.
SMILE_OUT_MM, SMILE_UP_MM, SMILE_BACK_MM = 4.5, 4.0, 2.0
#: Gaussian falloff radius (σ, mm) of the smile around each corner.
SMILE_SIGMA_MM = 11.0
#: Brow lift of ``brows_raised`` (mm) and its Gaussian falloff (σ, mm) from the brow line.
BROW_LIFT_MM = 6.0
BROW_SIGMA_MM = 11.0
#: The lift fades to zero over this height (mm) going down from the brow line to the eyelids.
BROW_EYELID_RAMP_MM = 8.0
#: ``cheek_smile``: mouth-corner motion (mm: out, up, back) and its Gaussian falloff (σ, mm); the
#: cheek lift (mm, up and forward) about a point :data:`CHEEK_BELOW_EYE_MM` below each lower lid,
#: falloff σ :data:`CHEEK_SIGMA_MM`; the lower lid's lift (mm) within :data:`LID_SIGMA_MM` of it.
CHEEK_SMILE_MOVE_MM = (3.0, 5.5, 2.5)
CHEEK_SMILE_SIGMA_MM = 8.0
CHEEK_LIFT_MM = (3.5, 1.0)
CHEEK_BELOW_EYE_MM = 16.0
CHEEK_SIGMA_MM = 10.0
LOWER_LID_LIFT_MM = 1.8
LID_SIGMA_MM = 6.0
#: ``surprise``: brow lift (mm) and falloff (σ, mm), jaw opening (deg), lower-lip drop (mm, down)
#: within :data:`LIP_SIGMA_MM` of the lower lip's middle.
SURPRISE_BROW_MM = 8.0
SURPRISE_BROW_SIGMA_MM = 14.0
SURPRISE_JAW_DEG = 3.0
LOWER_LIP_DROP_MM = 3.5
LIP_SIGMA_MM = 9.0


def _smoothstep(x: np.ndarray, lo: float, hi: float) -> np.ndarray:
    """C¹ ramp: 0 for ``x <= lo``, 1 for ``x >= hi``."""
    s = np.clip((np.asarray(x, float) - lo) / (hi - lo), 0.0, 1.0)
    return s * s * (3.0 - 2.0 * s)


def _polyline_distance(points: np.ndarray, polyline: np.ndarray) -> np.ndarray:
    """(n,) distance in mm from each point to an open polyline (k, 3)."""
    a, b = polyline[:-1], polyline[1:]
    ab = b - a
    t = np.einsum("nsd,sd->ns", points[:, None, :] - a[None], ab) / np.maximum((ab * ab).sum(1), 1e-12)
    t = np.clip(t, 0.0, 1.0)
    closest = a[None] + t[..., None] * ab[None]
    return np.linalg.norm(points[:, None, :] - closest, axis=2).min(axis=1)


def _open_mouth(points: np.ndarray, L: np.ndarray, angle_deg: float = JAW_ANGLE_DEG) -> np.ndarray:
    # jaw joints: a little below and in front of the ear-level jaw landmarks iBUG 0 and 16
    joint = np.array([0.0, 0.5 * (L[0, 1] + L[16, 1]) - 5.0, 0.5 * (L[0, 2] + L[16, 2]) + 5.0])
    pivot = joint - np.array([0.0, 0.0, JAW_PIVOT_BEHIND_MM])
    lip_line = 0.5 * (L[62] + L[66])  # between the lips, on the midline
    # mandible line in the (y, z) plane: from the lip line back to the pivot; "below" = jaw
    d = np.array([lip_line[1] - joint[1], lip_line[2] - joint[2]])
    normal = np.array([-d[1], d[0]]) / np.linalg.norm(d)  # points up/forwards of the line
    if normal[0] < 0:
        normal = -normal
    rel = points[:, 1:3] - lip_line[1:3]
    below = -(rel @ normal)  # mm below the mandible line
    weight = _smoothstep(below, -0.5 * JAW_RAMP_MM, 0.5 * JAW_RAMP_MM)
    chin_y = L[8, 1]
    weight = weight * _smoothstep(points[:, 1], chin_y - NECK_FADE_MM, chin_y)
    R = rodrigues(np.array([np.radians(angle_deg), 0.0, 0.0]))
    rotated = (points - pivot) @ R.T + pivot
    return weight[:, None] * (rotated - points)


def _corners(points: np.ndarray, L: np.ndarray, out_up_back: tuple, sigma: float) -> np.ndarray:
    out = np.zeros_like(points)
    o, u, b = out_up_back
    for corner, side in ((48, -1.0), (54, 1.0)):  # iBUG 48: subject's right corner (−x)
        r2 = ((points - L[corner]) ** 2).sum(1)
        out += np.exp(-r2 / (2.0 * sigma**2))[:, None] * np.array([side * o, u, -b])
    return out


def _smile(points: np.ndarray, L: np.ndarray) -> np.ndarray:
    return _corners(points, L, (SMILE_OUT_MM, SMILE_UP_MM, SMILE_BACK_MM), SMILE_SIGMA_MM)


def _gaussian(points: np.ndarray, centre: np.ndarray, sigma: float) -> np.ndarray:
    return np.exp(-((points - centre) ** 2).sum(1) / (2.0 * sigma**2))


def _cheek_smile(points: np.ndarray, L: np.ndarray) -> np.ndarray:
    out = _corners(points, L, CHEEK_SMILE_MOVE_MM, CHEEK_SMILE_SIGMA_MM)
    up, fwd = CHEEK_LIFT_MM
    for lid in (L[[40, 41]].mean(0), L[[46, 47]].mean(0)):  # lower lids: right eye, left eye
        cheek = lid + np.array([0.0, -CHEEK_BELOW_EYE_MM, -2.0])
        out += _gaussian(points, cheek, CHEEK_SIGMA_MM)[:, None] * np.array([0.0, up, fwd])
        below = _smoothstep(lid[1] - points[:, 1], -1.0, 1.5)  # under the lid line only
        out[:, 1] += LOWER_LID_LIFT_MM * _gaussian(points, lid, LID_SIGMA_MM) * below
    return out


def _surprise(points: np.ndarray, L: np.ndarray) -> np.ndarray:
    d = np.minimum(_polyline_distance(points, L[17:22]), _polyline_distance(points, L[22:27]))
    lid_top = L[[37, 38, 43, 44], 1].max()
    brow = np.exp(-(d**2) / (2.0 * SURPRISE_BROW_SIGMA_MM**2))
    brow *= _smoothstep(points[:, 1], lid_top, lid_top + BROW_EYELID_RAMP_MM) * _smoothstep(points[:, 2], 40.0, 70.0)
    out = _open_mouth(points, L, SURPRISE_JAW_DEG)
    out[:, 1] += SURPRISE_BROW_MM * brow
    lip = L[[57, 66]].mean(0)
    below = _smoothstep(L[66, 1] - points[:, 1], -0.5, 2.0)  # under the lips' meeting line
    out[:, 1] -= LOWER_LIP_DROP_MM * _gaussian(points, lip, LIP_SIGMA_MM) * below
    return out


def _brow_weight(points: np.ndarray, L: np.ndarray) -> np.ndarray:
    d = np.minimum(_polyline_distance(points, L[17:22]), _polyline_distance(points, L[22:27]))
    weight = np.exp(-(d**2) / (2.0 * BROW_SIGMA_MM**2))
    lid_top = L[[37, 38, 43, 44], 1].max()
    brow_low = L[17:27, 1].min()
    weight = weight * _smoothstep(points[:, 1], lid_top, max(brow_low, lid_top + BROW_EYELID_RAMP_MM))
    return weight * _smoothstep(points[:, 2], 40.0, 70.0)  # the face, not the sides of the head


def _brows_raised(points: np.ndarray, L: np.ndarray) -> np.ndarray:
    return _brow_weight(points, L)[:, None] * np.array([0.0, BROW_LIFT_MM, 0.0])


def _frown(points: np.ndarray, L: np.ndarray) -> np.ndarray:
    inward = -np.sign(points[:, 0]) * FROWN_IN_MM * _smoothstep(np.abs(points[:, 0]), 0.0, 15.0)
    move = np.column_stack([inward, np.full(len(points), -FROWN_DOWN_MM), np.zeros(len(points))])
    return _brow_weight(points, L)[:, None] * move


_FIELDS = {
    "smile": _smile,
    "open_mouth": _open_mouth,
    "brows_raised": _brows_raised,
    "frown": _frown,
    "cheek_smile": _cheek_smile,
    "surprise": _surprise,
}


def expression_displacement(name: str, points: np.ndarray, landmarks: np.ndarray) -> np.ndarray:
    """Displacement of the basic expression ``name`` at neutral-head ``points``.

    Parameters
    ----------
    name : str
        one of :data:`EXPRESSION_NAMES`, :data:`EXTRA_EXPRESSIONS` or :data:`OUTSIDE_EXPRESSIONS`
        (``"neutral"`` gives zeros).
    points : (n, 3) float
        neutral positions in mm, head frame.
    landmarks : (68, 3) float
        the neutral scan's iBUG-68 landmarks (``Scan.landmarks``), mm.

    Returns
    -------
    (n, 3) float
        displacement in mm; the expression's position is ``points + displacement``.
    """
    known = EXPRESSION_NAMES + EXTRA_EXPRESSIONS + OUTSIDE_EXPRESSIONS
    if name not in known:
        raise ValueError(f"unknown expression {name!r}; choose one of {known}")
    P = np.asarray(points, float)
    if P.ndim != 2 or P.shape[1] != 3:
        raise ValueError(f"points must be (n, 3) mm, got shape {P.shape}")
    L = np.asarray(landmarks, float)
    if L.shape != (68, 3):
        raise ValueError(f"landmarks must be (68, 3) iBUG-68 positions, got shape {L.shape}")
    if name == "neutral":
        return np.zeros_like(P)
    return _FIELDS[name](P, L)


def expression_displacements(points: np.ndarray, landmarks: np.ndarray, names=EXPRESSION_NAMES) -> np.ndarray:
    """(m, n, 3) float mm: :func:`expression_displacement` of every expression in ``names``."""
    return np.stack([expression_displacement(n, points, landmarks) for n in names])


def deformed_scan_vertices(scan, weights: np.ndarray, names=EXPRESSION_NAMES) -> np.ndarray:
    """The scan's vertices in a blend of the basic expressions.

    Parameters
    ----------
    scan : photomodel.samples.sample_data.Scan
    weights : (m,) or (n, m) float
        blending weights of ``names`` (sum 1), one row per scan vertex or shared by all.

    Returns
    -------
    (n, 3) float mm: ``V + Σ_k w_k d_k(V)`` (neutral has ``d = 0``).
    """
    D = expression_displacements(scan.vertices, scan.landmarks, names)
    W = np.broadcast_to(np.asarray(weights, float), (len(scan.vertices), len(names)))
    return scan.vertices + np.einsum("nk,knd->nd", W, D)


def true_expression_geometry(mesh, scan, names=EXPRESSION_NAMES) -> np.ndarray:
    """(m, n, 3) float mm: each basic expression's true geometry on the generic mesh.

    Row ``k`` is ``C + d_k(C)`` with ``C`` the generic vertices' true positions on the neutral
    scan (:func:`photomodel.samples.synthetic.true_correspondence`).
    """

    C = true_correspondence(mesh, scan)
    return C[None] + expression_displacements(C, scan.landmarks, names)
