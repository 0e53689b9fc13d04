"""Expression edits and edits.json (tracking/edit.py, Yang et al. 2012 §4–5, Eq. 25)."""

import json

import numpy as np
import pytest

from tracking.blendshape_face import WEIGHT_RANGE
from tracking.edit import (
    EditError,
    apply_edits,
    edited_alphas,
    edits_document,
    load_edits,
    replace_span,
    save_edits,
    scale_expression,
    scale_factors,
)
from tracking.synthetic_sequences.expressions import EXPRESSION_NAMES
from tracking.synthetic_sequences.ground_truth import sample_face_model, video_truth

SMILE = EXPRESSION_NAMES.index("smile")
MOUTH = 1


@pytest.fixture(scope="module")
def truth():
    return video_truth(40)  # the sample's weight curves: smile peaks at frame 12, 0.8


def test_scale_is_eq_25_on_one_expression(truth):
    W = truth.weights
    for f in (0.0, 0.5, 1.2):
        E = scale_expression(W, SMILE, np.full(len(W), f))
        # β' = β0 + f (β − β0) on the smile: its weight times f, the neutral takes the rest
        np.testing.assert_allclose(E[:, :, SMILE], f * W[:, :, SMILE])
        np.testing.assert_allclose(E[:, :, 0], W[:, :, 0] + (1 - f) * W[:, :, SMILE])
        others = [k for k in range(W.shape[2]) if k not in (0, SMILE)]
        np.testing.assert_array_equal(E[:, :, others], W[:, :, others])
        np.testing.assert_allclose(E.sum(axis=2), 1.0)
    # ×3 would take the smile to 2.4: each frame's change is shortened into WEIGHT_RANGE
    E = scale_expression(W, SMILE, np.full(len(W), 3.0))
    assert E.max() <= WEIGHT_RANGE[1] + 1e-12 and E.min() >= WEIGHT_RANGE[0] - 1e-12


def test_factor_ramps_over_a_span_and_curves_interpolate():
    f = scale_factors({"op": "scale", "expression": "smile", "factor": 0.0, "span": [10, 30], "ramp": 3}, 40)
    assert np.all(f[:10] == 1.0) and np.all(f[31:] == 1.0)
    np.testing.assert_allclose(f[13:28], 0.0)  # inside the ramps: the factor itself
    assert np.all(np.diff(f[9:14]) < 0) and np.all(np.diff(f[27:32]) > 0)  # no jump at the span's ends
    # a span reaching the clip's end does not ramp there
    f = scale_factors({"op": "scale", "expression": "smile", "factor": 2.0, "span": [30, 39]}, 40)
    assert f[39] == 2.0
    c = scale_factors({"op": "scale", "expression": "smile", "curve": [[0, 1.0], [20, 0.0], [40, 1.0]]}, 41)
    np.testing.assert_allclose(c[[0, 10, 20, 30, 40]], [1.0, 0.5, 0.0, 0.5, 1.0])


def test_replace_passes_through_the_chosen_frame_at_the_centre(truth):
    W = truth.weights
    E = replace_span(W, 20, 30, 12)  # replace the open mouth's rise by an interpolation through the smile
    np.testing.assert_allclose(E[25], W[12])  # §5.2: the chosen expression at the span's centre
    np.testing.assert_array_equal(E[:20], W[:20])
    np.testing.assert_array_equal(E[31:], W[31:])
    np.testing.assert_allclose(E[22], W[19] + (W[12] - W[19]) * 3 / 6)  # linear from the frame before
    np.testing.assert_allclose(E.sum(axis=2), 1.0)


def test_edited_alphas_reach_the_edited_weights(truth):
    model = sample_face_model(EXPRESSION_NAMES)
    alphas = np.array([model.alpha_of_weights(w) for w in truth.weights])
    edits = [
        {"op": "scale", "expression": "smile", "factor": 0.5, "span": [5, 20]},
        {"op": "replace", "span": [25, 35], "frame": 12},
    ]
    new = edited_alphas(model, alphas, edits)
    got = np.array([model.region_weights(a) for a in new])
    np.testing.assert_allclose(got[:, 1:], apply_edits(model, truth.weights, edits)[:, 1:], atol=1e-9)


@pytest.mark.parametrize(
    "edit, words",
    [
        ({"op": "scale", "expression": "grin", "factor": 0.5}, "grin"),
        ({"op": "scale", "expression": "smile"}, "factor or a curve"),
        ({"op": "scale", "expression": "smile", "factor": 1, "span": [30, 50]}, "span 30:50"),
        ({"op": "replace", "span": [5, 9], "frame": 99}, "frame 99"),
        ({"op": "replace", "frame": 3}, "span"),
        ({"op": "blur"}, "unknown edit op"),
    ],
)
def test_bad_edits_are_named(truth, edit, words):
    model = sample_face_model(EXPRESSION_NAMES)
    with pytest.raises(EditError, match=words):
        apply_edits(model, truth.weights, [edit])


def test_edits_json_round_trip_and_refusals(tmp_path):
    edits = [{"op": "scale", "expression": "smile", "factor": 0.5, "span": [1, 3]}]
    path = save_edits(tmp_path, edits_document(edits, 6, {"second_difference": 2.0}))
    assert path == tmp_path / "edits.json"
    doc = load_edits(tmp_path)
    assert doc["format"] == "facestudio-edits" and doc["version"] == 1 and doc["edits"] == edits
    assert load_edits(tmp_path / "nowhere") is None
    path.write_text(json.dumps({**doc, "version": 7}))
    with pytest.raises(EditError, match="version 7"):
        load_edits(tmp_path)
    path.write_text("{not json")
    with pytest.raises(EditError, match="cannot read"):
        load_edits(tmp_path)
