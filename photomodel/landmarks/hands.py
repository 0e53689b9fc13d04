"""Hands near the face in a photo: where a hand covers the face, so that texturing and tracking
leave it out.

A hand over the mouth or a cheek is not the face's skin: blended into a texture it paints
fingers onto the face, and a tracker fitting the face to it is pulled off. :func:`hand_mask`
says which pixels are a hand's. It runs MediaPipe's hand-landmark model from the same
``mediapipe==0.10.21`` wheel as the face mesh (Apache-2.0, :mod:`photomodel.landmarks.models`),
with ``cv2.dnn`` like the face mesh:

1. **Where to look**: a hand in front of the face lies on or beside it, so the 21-point hand
   model (``hand_landmark_full.tflite``, a 224×224 RGB crop in [0, 1]; outputs: 21 points in
   crop pixels, a hand-presence score) looks in :data:`WINDOWS` around the face's box, each
   :data:`WINDOW_SCALE` face sizes wide; a window whose presence is under
   :data:`MIN_HAND_SCORE` holds no hand. The wheel's palm detector (``palm_detection_full``,
   MediaPipe's first stage for hands anywhere in a photo) is not used: through ``cv2.dnn`` on
   the real clip it scored a frame with no hand 0.75 and missed two with a hand over the mouth
   (best 0.03–0.5), where the hand model's presence in windows around the face tells them
   apart (no hand ≤ 0.03; a hand 0.89–0.99).
2. **21 points per hand**: one more pass from a crop around the first pass's points (their box
   turned so that the wrist-to-knuckle line stands upright, :data:`POINTS_CROP_SCALE` times
   its side); hands found from two windows are merged, the surer kept.
3. **The mask**: the palm's polygon (wrist and the four knuckles) filled, each finger drawn
   from the wrist or its knuckle to its tip as a line :data:`FINGER_WIDTH` palm widths thick,
   and the whole grown by :data:`MARGIN` palm widths (the points sit on the bones' axes, the
   skin lies around them).
"""

from __future__ import annotations

import cv2
import numpy as np

from photomodel.errors import NoFaceFound
from photomodel.landmarks.detect import crop_image, crop_matrix, detect_468, to_photo
from photomodel.landmarks.models import HAND_MODEL, model_dir
from photomodel.landmarks.nets import run_net, thread_net

__all__ = ["MIN_HAND_SCORE", "hand_mask", "hand_points", "mask_of_hand"]

HAND_SIZE = 224  #: input side of the hand-landmark model, pixels
MIN_HAND_SCORE = 0.5  #: hand-presence score below which a crop holds no hand
POINTS_CROP_SCALE = 2.0  #: the second pass's crop over the 21 points' long side
#: Windows around the face the hand model looks in: ``(dx, dy, angle°)``, the centre moved by
#: ``dx, dy`` face sizes from the face's (a hand over the eyes, the nose, the mouth, a cheek, the
#: chin), all upright: the model finds a hand turned within a window, and the second pass turns
#: its crop to the hand's own angle. A hand above the forehead or well beside the face is not
#: looked for (it covers no face). The offsets and the windows turn with the face's roll (the eye
#: line's angle, :func:`hand_points`' ``angle``, to the nearest quarter turn): a face lying on its
#: side has its chin beside it.
WINDOWS = ((-0.35, 0.0, 0), (0.0, 0.0, 0), (0.35, 0.0, 0), (-0.35, 0.35, 0), (0.0, 0.35, 0), (0.35, 0.35, 0))
#: A quarter turn (radians): the face's roll is taken to the nearest one for the windows.
QUARTER = np.pi / 2
#: A window's side over the face's.
WINDOW_SCALE = 1.4
#: A finger's thickness in palm widths (index to little finger knuckles: four fingers side by side).
FINGER_WIDTH = 0.3
#: The mask grown by this many palm widths.
MARGIN = 0.08

#: The 21 points' chains drawn as fingers: thumb, index, middle, ring, little finger.
FINGERS = ((0, 1, 2, 3, 4), (5, 6, 7, 8), (9, 10, 11, 12), (13, 14, 15, 16), (17, 18, 19, 20))
#: The palm's outline: the wrist, the thumb's base and the four knuckles.
PALM = (0, 1, 5, 9, 13, 17)


def _run(net: cv2.dnn.Net, image: np.ndarray) -> dict[str, np.ndarray]:
    """All outputs of ``net`` by name for one (s, s, 3) float32 image."""
    names = list(net.getUnconnectedOutLayersNames())
    return dict(zip(names, run_net(net, image, names), strict=True))


def _upright(wrist: np.ndarray, knuckle: np.ndarray) -> float:
    """Crop angle (radians, :func:`photomodel.landmarks.detect.crop_matrix`) that turns the line
    from the wrist to the middle finger's knuckle upright (pointing to the crop's top)."""
    v = knuckle - wrist
    return float(np.arctan2(v[0], -v[1]))


def _roi_from_points(points: np.ndarray) -> tuple[np.ndarray, float, float]:
    angle = _upright(points[0], points[9])
    c, s = np.cos(angle), np.sin(angle)
    rot = np.array([[c, -s], [s, c]])
    local = points @ rot
    lo, hi = local.min(0), local.max(0)
    return rot @ ((lo + hi) / 2.0), float(np.max(hi - lo) * POINTS_CROP_SCALE), angle


def _hand_pass(image: np.ndarray, centre: np.ndarray, size: float, angle: float) -> tuple[np.ndarray, float]:
    matrix = crop_matrix(centre, size, angle, HAND_SIZE)
    out = _run(thread_net(model_dir() / HAND_MODEL), crop_image(image, matrix, HAND_SIZE))
    flat = [v.reshape(-1) for v in out.values()]
    # the outputs: 21 points (x, y, z in crop pixels), their world copy, presence, handedness;
    # MediaPipe's graph reads the points from "Identity" and the presence from "Identity_1"
    points = out["Identity"].reshape(21, 3) if "Identity" in out else next(f for f in flat if f.size == 63)
    presence = float(out["Identity_1"].reshape(-1)[0])
    if presence < 0.0 or presence > 1.0:  # a logit
        presence = 1.0 / (1.0 + np.exp(-presence))
    return to_photo(matrix, np.asarray(points).reshape(21, 3)[:, :2]), presence


def _windows(image: np.ndarray, face_box, angle: float = 0.0) -> list[tuple[np.ndarray, float, float]]:
    """Crops ``(centre, size, angle)`` the hand model looks in: around the face (the module
    docstring; offsets and crops turned by the face's roll ``angle``, radians), or tiles of the
    whole photo when no face is known."""
    h, w = image.shape[:2]
    if face_box is None:
        side = float(min(h, w))
        xs = np.linspace(side / 2, w - side / 2, max(1, int(np.ceil(w / side * 1.5))))
        ys = np.linspace(side / 2, h - side / 2, max(1, int(np.ceil(h / side * 1.5))))
        return [(np.array([x, y]), side, 0.0) for y in ys for x in xs]
    x0, y0, x1, y1 = face_box
    centre = np.array([(x0 + x1) / 2.0, (y0 + y1) / 2.0])
    size = float(max(x1 - x0, y1 - y0))
    # to the nearest quarter turn: an upright face's windows stay as they were (the model finds a
    # hand turned within a window); a face on its side or upside down gets them turned with it
    angle = QUARTER * round(angle / QUARTER)
    c, s = np.cos(angle), np.sin(angle)
    turn = np.array([[c, -s], [s, c]])  # the face's right and down in the photo (crop_matrix's turn)
    return [(centre + size * (turn @ [dx, dy]), WINDOW_SCALE * size, angle + np.radians(a)) for dx, dy, a in WINDOWS]


def _same_hand(a: np.ndarray, b: np.ndarray) -> bool:
    lo, hi = np.maximum(a.min(0), b.min(0)), np.minimum(a.max(0), b.max(0))
    inter = float(np.prod(np.clip(hi - lo, 0.0, None)))
    area = min(float(np.prod(a.max(0) - a.min(0))), float(np.prod(b.max(0) - b.min(0))))
    return inter > 0.5 * max(area, 1e-9)


def hand_points(image: np.ndarray, face_box=None, angle: float = 0.0) -> list[tuple[np.ndarray, float]]:
    """The hands near the face in a photo: for each, its 21 points ((21, 2) photo pixels:
    MediaPipe's wrist, thumb, index … little finger, base to tip) and its presence in [0, 1].

    Parameters
    ----------
    image : (H, W, 3) uint8
        RGB photo.
    face_box : tuple of 4 float, optional
        ``x0, y0, x1, y1`` of the face (:attr:`photomodel.landmarks.detect.Face468.box`); the hand
        model looks at :data:`WINDOWS` around it. None: the face is detected first, and where
        there is none the photo is searched in tiles.
    angle : float
        the face's roll with ``face_box``: the angle (radians, image y down) of its eye line from
        the subject's right eye to the left (:func:`photomodel.landmarks.mapping.face_roll`);
        0 for an upright face; not used without ``face_box``.
    """
    if face_box is None:
        try:
            face_box = detect_468(image).box
        except NoFaceFound:
            face_box = None
    hands: list[tuple[np.ndarray, float]] = []
    for window in _windows(image, face_box, angle):
        points, presence = _hand_pass(image, *window)
        if presence < MIN_HAND_SCORE:
            continue
        points, presence = _hand_pass(image, *_roi_from_points(points))
        if presence < MIN_HAND_SCORE:
            continue
        same = [i for i, (q, _) in enumerate(hands) if _same_hand(points, q)]
        if not same:
            hands.append((points, presence))
        elif presence > hands[same[0]][1]:
            hands[same[0]] = (points, presence)
    return hands


def mask_of_hand(shape: tuple[int, int], points: np.ndarray) -> np.ndarray:
    """(H, W) bool: the pixels of one hand drawn from its 21 points (the module docstring, 3)."""
    p = np.asarray(points, float)[:, :2]
    palm = float(np.linalg.norm(p[5] - p[17]))  # index to little finger knuckle
    palm = max(palm, 0.5 * float(np.linalg.norm(p[9] - p[0])), 2.0)
    out = np.zeros(shape, np.uint8)
    cv2.fillPoly(out, [np.round(p[list(PALM)] * 16).astype(np.int32)], 1, shift=4)
    width = max(2, int(round(FINGER_WIDTH * palm)))
    for chain in FINGERS:
        line = p[[0, *chain]] if chain[0] == 0 else p[list(chain)]
        cv2.polylines(out, [np.round(line).astype(np.int32)], False, 1, width)
        for q in line:
            cv2.circle(out, tuple(int(v) for v in np.round(q)), width // 2, 1, -1)
    k = 1 + 2 * int(np.ceil(MARGIN * palm))
    return cv2.dilate(out, cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (k, k))) > 0


def hand_mask(image: np.ndarray, face_box=None, angle: float = 0.0) -> np.ndarray:
    """(H, W) bool: the pixels of ``image`` ((H, W, 3) uint8 RGB) covered by a hand near the face
    (every hand :func:`hand_points` finds, drawn by :func:`mask_of_hand`); all False when there
    is none. ``face_box``, ``angle``: see :func:`hand_points`.

    For texturing (:func:`photomodel.landmarks.segment.face_pixels` leaves these pixels out)
    and for tracking (a hand in front of the face is an occluder, not the face)."""
    mask = np.zeros(image.shape[:2], bool)
    for points, _ in hand_points(image, face_box, angle):
        mask |= mask_of_hand(image.shape[:2], points)
    return mask
