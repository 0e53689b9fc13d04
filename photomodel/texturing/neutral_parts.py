"""The neutral's mouth texture from the photos where the mouth is neutral (beyond Pighin).

Pighin's texture blends every photo that sees a surface point (§5.2.1): the photos of one
expression are assumed to show the same face. Stills picked from a real clip, or a handful of
portraits, rarely do: a smile or a word in one of them puts teeth and stretched lips into the
neutral's texture over a closed mouth. A tracker that matches the model's pixels to the video
then matches that painted smile instead of moving the mouth — on the real-clip sample the
tracked mouth corner sat 12 px inside the detected one on every smiling frame (the mouth's
geometry neutral, its painted smile already wide).

:func:`expressive_mouth_masks` says, for each photo of the **neutral** expression, which pixels
to leave out of the texture: where its mouth shows an expression
(:func:`photomodel.photos.intake.mouth_expression` of the face mesh's iBUG points, above
:data:`~photomodel.photos.intake.NEUTRAL_MOUTH_UP_TO` and more than
:data:`~photomodel.photos.intake.SAME_MOUTH_WITHIN` above the most neutral photo's — the same
rule by which the fit leaves such a photo's mouth clicks out), the region around the lips
(the face mesh's outer lip contour grown by :data:`MOUTH_MARGIN` outer-eye distances: the
corners move that far in a smile). Those texels come from the neutral photos, or the hole filler.
When no photo's mouth is neutral nothing is left out: the most neutral mouth is still the best
the photos have (the fit warns about it).
"""

from __future__ import annotations

import cv2
import numpy as np

from photomodel.landmarks.mapping import IBUG68_NAMES, estimate_yaw_deg, ibug68_from_mesh
from photomodel.photos.intake import NEUTRAL_MOUTH_UP_TO, SAME_MOUTH_WITHIN, mouth_expression

__all__ = ["MOUTH_MARGIN", "MOUTH_OUTER_468", "expressive_mouth_masks", "mouth_scores"]

#: The face mesh's outer lip contour (MediaPipe's 468-point topology), in order around the mouth.
MOUTH_OUTER_468 = (61, 146, 91, 181, 84, 17, 314, 405, 321, 375, 291, 409, 270, 269, 267, 0, 37, 39, 40, 185)
#: How far around the lips the left-out region reaches, in outer-eye distances: a broad smile
#: moves the mouth corners 0.15–0.25 of them outwards and lifts the cheeks beside them.
MOUTH_MARGIN = 0.25


def mouth_scores(points468: list) -> list[float | None]:
    """:func:`~photomodel.photos.intake.mouth_expression` of each photo's face mesh points
    ((468, 3) or None: no face found → None)."""
    out = []
    for pts in points468:
        if pts is None:
            out.append(None)
            continue
        p68, _ = ibug68_from_mesh(np.asarray(pts, float), estimate_yaw_deg(np.asarray(pts, float)))
        named = {IBUG68_NAMES[i]: p68[i] for i in range(68) if np.all(np.isfinite(p68[i]))}
        out.append(mouth_expression(named))
    return out


def _mouth_region(shape: tuple, pts: np.ndarray) -> np.ndarray:
    """(H, W) bool: the outer lip contour of face mesh points ``pts`` filled and grown by
    :data:`MOUTH_MARGIN` outer-eye distances."""
    p68, _ = ibug68_from_mesh(pts, estimate_yaw_deg(pts))
    eye = float(np.linalg.norm(p68[45] - p68[36])) if np.all(np.isfinite(p68[[36, 45]])) else 0.0
    if eye <= 0:  # no eye line: the mouth's own width stands in for it (about 0.8 of it)
        eye = float(np.linalg.norm(pts[291, :2] - pts[61, :2])) / 0.8
    mask = np.zeros(shape, np.uint8)
    cv2.fillPoly(mask, [np.round(pts[list(MOUTH_OUTER_468), :2]).astype(np.int32)], 1)
    r = max(1, int(round(MOUTH_MARGIN * eye)))
    mask = cv2.dilate(mask, cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * r + 1, 2 * r + 1)))
    return mask.astype(bool)


def expressive_mouth_masks(shapes: list[tuple], points468: list) -> list[np.ndarray | None]:
    """For each photo (image ``shapes[k]`` = (H, W), face mesh ``points468[k]`` (468, 3) or None),
    the (H, W) bool pixels to leave out of the neutral's texture — its mouth region where its
    mouth shows an expression and another photo's is neutral (module notes) — or None: keep all."""
    scores = mouth_scores(points468)
    known = [s for s in scores if s is not None]
    if not known or min(known) > NEUTRAL_MOUTH_UP_TO:
        return [None] * len(scores)
    keep_up_to = max(NEUTRAL_MOUTH_UP_TO, min(known) + SAME_MOUTH_WITHIN)
    return [
        None if s is None or s <= keep_up_to else _mouth_region(shape[:2], np.asarray(pts, float))
        for s, shape, pts in zip(scores, shapes, points468, strict=True)
    ]
