"""The Qt-free state of interactive editing (tracking/edit_session.py)."""

import numpy as np
import pytest

from photomodel.rendering.renderer import get_renderer
from tracking.blendshape_face import render_model
from tracking.edit import EditError, load_edits
from tracking.edit_session import EditSession
from tracking.frame_fit import FrameFitter, FrameState
from tracking.synthetic_sequences.expressions import EXPRESSION_NAMES
from tracking.synthetic_sequences.ground_truth import BACKGROUND_RGB, sample_face_model, video_truth

SMILE = EXPRESSION_NAMES.index("smile")


@pytest.fixture(scope="module")
def session_parts():
    """Four frames around the sample's smile peak, rendered from the model at the true weights."""
    model = sample_face_model(EXPRESSION_NAMES)
    truth = video_truth(40)
    fitter = FrameFitter(model, truth.focal_px, truth.width, truth.height)
    bg = np.broadcast_to(np.asarray(BACKGROUND_RGB, np.float32), (truth.height, truth.width, 3))
    frames, states = [], []
    for i in range(10, 14):
        Wv = model.vertex_weights(truth.weights[i])
        frames.append(render_model(get_renderer(), truth.camera(i), model, model.blend_geometry(Wv), Wv, bg).image)
        states.append(
            FrameState(truth.R[i], truth.t[i] + truth.R[i] @ model.centre, model.alpha_of_weights(truth.weights[i]))
        )
    return fitter, frames, states, truth.weights[10:14]


def test_scale_undo_redo_and_scrub(session_parts, tmp_path):
    fitter, frames, states, W = session_parts
    s = EditSession(fitter, frames, states)
    before, after = s.curves()
    np.testing.assert_allclose(before[:, 1:], W[:, 1:], atol=1e-9)  # the states are the truth
    s.scale("smile", 0.0, (1, 3))
    _, after = s.curves()
    assert after[0, 1, SMILE] == pytest.approx(W[0, 1, SMILE])  # outside the span
    # ramping down inside it: 3 frames of ramp from frame 1, so frame 2 is half way, (2 − 1 + 1) / 4
    # (the weight exactly halved; asserted as `<` before, which held or not by rounding)
    assert after[2, 1, SMILE] == pytest.approx(0.5 * W[2, 1, SMILE], rel=1e-9)
    original, edited = s.frame_pair(3)
    np.testing.assert_array_equal(original, frames[3])
    assert np.abs(edited - original).max() > 0.1  # the smile went
    assert s.undo() and s.edits == [] and not s.undo()
    np.testing.assert_allclose(s.curves()[1], before)
    assert s.redo() and len(s.edits) == 1 and not s.redo()
    s.replace((1, 2), 0)
    with pytest.raises(EditError, match="grin"):
        s.scale("grin", 2.0)
    assert len(s.edits) == 2  # a refused edit is not added
    out = s.export(tmp_path, tmp_path / "frames")
    assert len(list(out.glob("frame_*.png"))) == 4
    assert [e["op"] for e in load_edits(tmp_path)["edits"]] == ["scale", "replace"]
