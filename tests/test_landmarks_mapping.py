"""The 468 → iBUG-68 mapping, the yaw's view preset and the far-side rule (no detector run)."""

import numpy as np

from photomodel.camera import PRESET_AZIMUTH_DEG
from photomodel.landmarks.mapping import (
    MESH_CURVES,
    MESH_OF_IBUG68,
    OUTLINE_CONFIDENCE,
    PROFILE_FROM_DEG,
    curves_from_mesh,
    features_from_mesh,
    ibug68_from_mesh,
    ibug_index,
    placed_ibug,
    preset_for_yaw,
)
from photomodel.modeling.generic_mesh import CURVE_LANDMARKS, FEATURE_ALIASES, IBUG68_NAMES


def test_every_ibug_point_has_its_own_mesh_point():
    assert MESH_OF_IBUG68.shape == (68,)
    assert len(set(MESH_OF_IBUG68.tolist())) == 68
    assert MESH_OF_IBUG68.min() >= 0 and MESH_OF_IBUG68.max() < 468
    # MediaPipe's anatomical points: outer eye corners 33/263, mouth corners 61/291, the
    # same sides as iBUG (r = the subject's right)
    assert MESH_OF_IBUG68[FEATURE_ALIASES["eye_r_outer"]] == 33
    assert MESH_OF_IBUG68[FEATURE_ALIASES["eye_l_outer"]] == 263
    assert MESH_OF_IBUG68[FEATURE_ALIASES["mouth_r"]] == 61
    assert MESH_OF_IBUG68[FEATURE_ALIASES["mouth_l"]] == 291


def test_feature_names_resolve_to_ibug_indices():
    assert ibug_index("jaw_03") == 3
    assert ibug_index("eye_r_outer") == 36
    assert ibug_index("lip_inner_7") == 67
    assert ibug_index("extra_007") is None


def test_view_presets_follow_the_azimuth_convention():
    assert preset_for_yaw(0.0) == "front"
    assert preset_for_yaw(40.0) == "three_quarter_left"  # + : the camera sees the subject's left
    assert preset_for_yaw(-40.0) == "three_quarter_right"
    assert preset_for_yaw(70.0) == "left" and preset_for_yaw(-70.0) == "right"
    assert all(preset_for_yaw(y) in PRESET_AZIMUTH_DEG for y in np.linspace(-90, 90, 37))


def test_far_side_points_are_placed_in_three_quarter_views_and_hidden_in_profiles():
    # 300-W's semi-frontal convention: all 68 marked up to a three-quarter view
    assert placed_ibug(0.0).all() and placed_ibug(50.0).all() and placed_ibug(-50.0).all()
    profile_left = placed_ibug(70.0)  # camera at the subject's left: their right side hides
    assert not profile_left[IBUG68_NAMES.index("jaw_02")]
    assert profile_left[IBUG68_NAMES.index("jaw_14")]
    assert profile_left[IBUG68_NAMES.index("nose_bridge_3")]
    assert not placed_ibug(-70.0)[IBUG68_NAMES.index("jaw_14")]


def test_far_side_jaw_points_move_out_to_the_outline():
    mesh = np.zeros((468, 3))
    mesh[:, 0] = np.linspace(0.0, 100.0, 468)  # a face 100 px wide between x = 0 and 100 ...
    mesh[:, 1] = np.tile([0.0, 120.0], 234)  # ... and 120 px high
    mesh[33, :2], mesh[263, :2] = (30.0, 40.0), (70.0, 40.0)  # eyes level
    mesh[MESH_OF_IBUG68[2], :2] = (20.0, 60.0)  # the far-side jaw point inside the outline
    mesh[MESH_OF_IBUG68[14], :2] = (80.0, 60.0)  # the near side one
    uv, confidence = ibug68_from_mesh(mesh, 40.0)  # camera at the subject's left: right side far
    np.testing.assert_allclose(uv[2], (0.0, 60.0), atol=0.2)  # out to the outline, same height
    np.testing.assert_allclose(uv[14], (80.0, 60.0))  # near side: where the mesh has it
    assert confidence[2] <= OUTLINE_CONFIDENCE < confidence[14]


def test_features_carry_mesh_points_and_confidences():
    mesh = np.random.default_rng(0).uniform(0, 500, (468, 3))
    names = ["eye_l_outer", "jaw_02", "chin", "extra_001"]
    points, confidence = features_from_mesh(mesh, 70.0, names)
    assert set(points) == {"eye_l_outer", "chin"}  # jaw_02 hidden in a profile, extra_001 unmapped
    np.testing.assert_array_equal(points["eye_l_outer"], mesh[263, :2])
    assert set(confidence) == set(points)
    assert all(0.0 < c <= 1.0 for c in confidence.values())
    _, front = ibug68_from_mesh(mesh, 0.0)
    assert front[IBUG68_NAMES.index("jaw_05")] < 0.5 * front[FEATURE_ALIASES["eye_r_outer"]]  # the outline weighs less


def test_curves_pass_through_the_clicks_on_them_end_to_end():
    """An automatic curve starts and ends on the automatic clicks of its curve's first and last
    landmarks and passes through those in between, in the curve's order (§5.1.3 binds a drawing
    end to end to the mesh curve through those landmarks)."""
    assert set(MESH_CURVES) <= set(CURVE_LANDMARKS)
    for name, contour in MESH_CURVES.items():
        waypoints = [int(MESH_OF_IBUG68[i]) for i in CURVE_LANDMARKS[name]]
        assert contour[0] == waypoints[0] and contour[-1] == waypoints[-1], name
        at = [contour.index(w) for w in waypoints]  # each landmark's face-mesh point is on the contour...
        assert at == sorted(at), name  # ...in order
        assert len(set(contour)) == len(contour), name
    mesh = np.random.default_rng(1).uniform(0, 500, (468, 3))
    curves = curves_from_mesh(mesh, 30.0)
    assert set(curves) == set(MESH_CURVES)
    np.testing.assert_array_equal(curves["lip_lower"], mesh[list(MESH_CURVES["lip_lower"]), :2])
    assert curves_from_mesh(mesh, PROFILE_FROM_DEG + 1.0) == {}  # a profile hides half the lips
