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
