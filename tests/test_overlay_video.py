"""Tests of tracking.overlay_video (and the plots of tracking.plots) as a run writes them:
``overlay.mp4``, ``overlay_last.png`` and the plot images of ``straight`` (tests/conftest.py)."""

from __future__ import annotations

import cv2

from photomodel.exchange.files import decode_png

FRAMES = 6


def test_plots_and_overlay_are_written(straight, tmp_path):
    for name in ("weights", "rotation", "translation", "rms"):
        img = decode_png(straight.files[name].read_bytes())
        assert img.ndim == 3 and img.shape[0] >= 200 and img.shape[1] >= 600, name
        assert img.std() > 10 and (img < 128).any(), name  # curves and text, not a blank canvas
    cap = cv2.VideoCapture(str(straight.files["overlay"]))
    n = 0
    while True:
        ok, bgr = cap.read()
        if not ok:
            break
        assert bgr.shape == (300, 300, 3)
        n += 1
    cap.release()
    assert n == FRAMES
    last = decode_png(straight.files["overlay_last"].read_bytes())
    assert last.shape == (300, 300, 3)
    # the silhouette is outlined in green: many pixels green-dominant
    g = last.astype(int)
    assert ((g[..., 1] > 150) & (g[..., 0] < 120) & (g[..., 2] < 120)).sum() > 200


def test_overlay_tints_an_occluder_and_little_else():
    import numpy as np

    from tracking.frame_fit import FrameFitter
    from tracking.overlay_video import overlay_frame
    from tracking.synthetic_sequences.ground_truth import render_video_frame, sample_face_model, video_truth

    model, truth, i = sample_face_model(), video_truth(8), 3
    frame = render_video_frame(truth, i).astype(np.float32)
    R = truth.R[i]
    rec = {
        "frame": i,
        "rms": 0.0,
        "diverged": False,
        "R": R.tolist(),
        "centre_mm": (truth.t[i] + R @ model.centre).tolist(),
        "alpha": model.alpha_of_weights(truth.weights[i]).tolist(),
    }
    # a blue-grey card over the middle of the face (the truth: where the model is not the face)
    card = np.zeros(frame.shape[:2], bool)
    card[150:190, 120:180] = True
    frame[card] = (0.35, 0.45, 0.75)
    fitter = FrameFitter(model, truth.focal_px, truth.width, truth.height)
    tinted = overlay_frame(fitter, frame, rec)
    magenta = (tinted[..., 0] > tinted[..., 1] + 0.2) & (tinted[..., 2] > tinted[..., 1] + 0.2)
    # most of the card is drawn occluded (its pixels the model covers and that differ from the
    # skin by more than 3x the median residual); almost nothing outside it
    assert magenta[card].mean() > 0.8
    assert magenta[~card].sum() < 0.1 * card.sum()
