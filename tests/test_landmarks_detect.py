"""The detector on the sample project's photos (renders of the james scan with known cameras).

Truth: ``sample_projects/james/ground_truth.json`` — the scan's landmarks projected by the true
cameras, which the detector never sees. Errors are in % of the outer-eye distance the face has
at its depth (3-D distance × f / depth), as in benchmarks/bench_landmarks.py.
"""

from pathlib import Path

import cv2
import numpy as np
import pytest

from photomodel.errors import NoFaceFound
from photomodel.landmarks.detect import MESH_SIZE, _crop_matrix, _to_photo, detect_468
from photomodel.landmarks.mapping import MESH_OF_IBUG68
from photomodel.modeling.generic_mesh import FEATURE_ALIASES
from photomodel.samples.synthetic import load_ground_truth

SAMPLE_DIR = Path(__file__).resolve().parents[1] / "sample_projects" / "james"


def _photo(pid):
    return cv2.cvtColor(cv2.imread(str(SAMPLE_DIR / "photos" / f"neutral_{pid}.png")), cv2.COLOR_BGR2RGB)


@pytest.fixture(scope="module")
def truth():
    return load_ground_truth(SAMPLE_DIR / "ground_truth.json")


def _eye_px(truth, pid):
    cam = truth.cameras["neutral"][pid]
    eyes = truth.true_points(["eye_r_outer", "eye_l_outer"])
    return cam.f * np.linalg.norm(eyes[0] - eyes[1]) / cam.depth(eyes).mean()


def test_crop_pixels_map_back_onto_the_photo():
    # the crop's centre pixel lands on the crop centre, its x axis along the angle
    m = _crop_matrix(np.array([100.0, 50.0]), 96.0, np.radians(30), MESH_SIZE)
    np.testing.assert_allclose(_to_photo(m, np.array([[96.0, 96.0]])), [[100.0, 50.0]], atol=1e-9)
    step = _to_photo(m, np.array([[97.0, 96.0]])) - _to_photo(m, np.array([[96.0, 96.0]]))
    np.testing.assert_allclose(step[0], 0.5 * np.array([np.cos(np.radians(30)), np.sin(np.radians(30))]))


def test_eye_corners_of_the_front_photo(truth):
    face = detect_468(_photo("front"), name="front")
    assert face.faces_found == 1 and face.score > 0.9
    clean = truth.clean_points["neutral"]["front"]
    eye_px = _eye_px(truth, "front")
    for name in ("eye_r_outer", "eye_l_outer", "mouth_r", "mouth_l", "nose_tip"):
        err = np.linalg.norm(face.points[MESH_OF_IBUG68[FEATURE_ALIASES[name]], :2] - clean[name])
        assert err < 0.05 * eye_px, name  # 5 %: the benchmark's bar (measured 1-3 %)
    x0, y0, x1, y1 = face.box
    assert x0 < clean["eye_r_outer"][0] < clean["eye_l_outer"][0] < x1


def test_a_rolled_photo_is_levelled_before_the_face_mesh(truth):
    """At ~20° of roll the points follow the photo: the crop is turned to level the eyes."""
    image = _photo("three_quarter_left")
    h, w = image.shape[:2]
    rot = cv2.getRotationMatrix2D(((w - 1) / 2, (h - 1) / 2), 20.0, 1.0)
    rolled = cv2.warpAffine(image, rot, (w, h), borderValue=(115, 115, 115))
    clean = truth.clean_points["neutral"]["three_quarter_left"]
    eye_px = _eye_px(truth, "three_quarter_left")
    face = detect_468(rolled, name="rolled")
    errors = []
    for name in ("eye_l_outer", "eye_r_inner", "mouth_r", "mouth_l", "lip_upper", "nose_tip"):
        true_rolled = rot[:, :2] @ clean[name] + rot[:, 2]
        errors.append(np.linalg.norm(face.points[MESH_OF_IBUG68[FEATURE_ALIASES[name]], :2] - true_rolled))
    assert np.mean(errors) < 0.06 * eye_px  # unrolled this photo measures ~4 %


def test_no_face_is_an_error_naming_the_photo():
    blank = np.full((300, 400, 3), 128, np.uint8)
    with pytest.raises(NoFaceFound, match="IMG_0001.jpg.*by hand"):
        detect_468(blank, name="IMG_0001.jpg")


def test_the_image_must_be_rgb_uint8():
    with pytest.raises(ValueError, match="uint8"):
        detect_468(np.zeros((10, 10, 3), float))


def test_a_mirrored_photo_gives_the_mirrored_points(monkeypatch):
    """Flip-averaging makes the face mesh treat a photo and its mirror image alike."""
    from photomodel.landmarks import detect
    from photomodel.landmarks.mirror import MIRROR_468

    monkeypatch.setattr(detect, "FLIP_AVERAGE", True)
    image = _photo("front")
    face = detect_468(image, name="front")
    flipped = detect_468(np.ascontiguousarray(image[:, ::-1]), name="front mirrored")
    back = flipped.points[MIRROR_468, :2] * np.array([-1.0, 1.0]) + np.array([image.shape[1] - 1.0, 0.0])
    eye = np.linalg.norm(face.points[33, :2] - face.points[263, :2])
    # not exact: the detector's box and the crops' pixel grid are not mirror-symmetric
    assert np.median(np.linalg.norm(back - face.points[:, :2], axis=1)) < 0.01 * eye


def test_one_pass_near_a_known_face_and_none_where_there_is_none(truth):
    # the tracking mode: a crop where the face is (here the true features' box, grown as a tracked
    # model's face region is), no face detector; its points as close to the truth as the full
    # detector's (measured 1-3 % of the eye distance), and no face in a blank crop
    from photomodel.landmarks.detect import detect_468_near

    image = _photo("front")
    clean = truth.clean_points["neutral"]["front"]
    pts = np.array(list(clean.values()))
    lo, hi = pts.min(0), pts.max(0)
    pad = 0.15 * (hi - lo)
    d = np.subtract(clean["eye_l_outer"], clean["eye_r_outer"])
    face = detect_468_near(image, (*(lo - pad), *(hi + pad)), float(np.arctan2(d[1], d[0])))
    assert face is not None and face.score > 0.9
    eye_px = _eye_px(truth, "front")
    for name in ("eye_r_outer", "eye_l_outer", "mouth_r", "mouth_l", "nose_tip"):
        err = np.linalg.norm(face.points[MESH_OF_IBUG68[FEATURE_ALIASES[name]], :2] - clean[name])
        assert err < 0.05 * eye_px, name
    assert detect_468_near(np.full((300, 400, 3), 128, np.uint8), (100, 50, 300, 250), 0.0) is None
