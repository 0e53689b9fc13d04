"""The face mesh's left-right mirror table (photomodel/landmarks/mirror.py)."""

import numpy as np

from photomodel.landmarks.mapping import MESH_OF_IBUG68
from photomodel.landmarks.mirror import MIRROR_468

# iBUG-68's own left/right mirror: jaw 0..16 reversed, brows 17..26 reversed, nose line fixed,
# nostrils 31..35 reversed, eyes 36..47 onto each other, the lips' mirrored order.
IBUG_MIRROR = np.array(
    list(range(16, -1, -1))
    + list(range(26, 16, -1))
    + [27, 28, 29, 30]
    + [35, 34, 33, 32, 31]
    + [45, 44, 43, 42, 47, 46, 39, 38, 37, 36, 41, 40]
    + [54, 53, 52, 51, 50, 49, 48, 59, 58, 57, 56, 55]
    + [64, 63, 62, 61, 60, 67, 66, 65]
)


def test_the_mirror_is_an_involution_with_a_midline():
    assert sorted(MIRROR_468) == list(range(468))
    np.testing.assert_array_equal(MIRROR_468[MIRROR_468], np.arange(468))
    midline = np.flatnonzero(MIRROR_468 == np.arange(468))
    assert {1, 4, 6, 8, 152, 168}.issubset(midline) and len(midline) < 40


def test_the_mirror_maps_the_ibug_points_onto_their_mirror_partners():
    # an independent check: the iBUG table was chosen point by point, the mirror by matching
    np.testing.assert_array_equal(MIRROR_468[MESH_OF_IBUG68], MESH_OF_IBUG68[IBUG_MIRROR])
