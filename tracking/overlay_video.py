"""The overlay: the face model rendered over the footage at its tracked parameters.

:func:`overlay_frame` draws one frame (alpha blend, occluded pixels tinted, silhouette outlined,
frame index and RMS; for a track in ARKit terms, the shapes weighing most); the
studio's tracking view shows it while scrubbing. :func:`write_overlay_video` writes every tracked
frame's as ``overlay.mp4``, atomically.
"""

from __future__ import annotations

import os
import tempfile
from pathlib import Path

import cv2
import numpy as np

from photomodel.photos.video import VideoError, VideoFrames
from tracking.blendshape_face import render_model
from tracking.frame_fit import FrameFitter, outlier_pixels
from tracking.track_result import state_of

__all__ = ["OVERLAY_ALPHA", "OCCLUDED_RGB", "overlay_frame", "write_overlay_video"]

OVERLAY_ALPHA = 0.5
#: Tint of the occluded pixels (magenta: unlike skin, hair or the usual backgrounds), blended at
#: :data:`OVERLAY_ALPHA`.
OCCLUDED_RGB = (1.0, 0.0, 1.0)
#: ARKit shapes written on an overlay frame (those weighing most, over 0.05).
OVERLAY_SHAPES = 3


def overlay_frame(fitter: FrameFitter, frame: np.ndarray, rec: dict, renderer=None) -> np.ndarray:
    """(H, W, 3) float32: the model at ``rec``'s parameters rendered over ``frame`` (alpha
    :data:`OVERLAY_ALPHA`), the pixels the robust error takes for occluded tinted
    :data:`OCCLUDED_RGB` (the model's pixels whose residual is an outlier,
    :func:`tracking.frame_fit.outlier_pixels`, opened by a 3×3 square so that single pixels of
    texture detail are not drawn; only when the fitter's error is robust), its
    silhouette outlined in green (red when the frame diverged), and the frame index with its RMS
    written in the corner — and under it, for a track in ARKit terms (``rec["arkit"]``), the
    :data:`OVERLAY_SHAPES` shapes weighing most with their weights."""
    model = fitter.model
    st = state_of(rec)
    Wv = model.vertex_weights(model.region_weights(st.alpha))
    r = render_model(
        renderer or fitter.renderer, fitter.camera(st), model, model.blend_geometry(Wv), Wv, background=frame
    )
    out = frame.copy()
    m = r.mask
    out[m] = (1 - OVERLAY_ALPHA) * frame[m] + OVERLAY_ALPHA * r.image[m]
    if fitter.options.robust_scale is not None and len(r.pixels):
        flat = frame.reshape(-1, 3)[r.pixels] - r.image.reshape(-1, 3)[r.pixels]
        occluded = np.zeros(m.size, np.uint8)
        occluded[r.pixels[outlier_pixels(np.sqrt((np.clip(flat, -1, 1) ** 2).mean(axis=1)))]] = 1
        # opened: single outlier pixels are the texture's fine detail, not an occluder
        occluded = cv2.morphologyEx(occluded.reshape(m.shape), cv2.MORPH_OPEN, np.ones((3, 3), np.uint8)) > 0
        out[occluded] = (1 - OVERLAY_ALPHA) * frame[occluded] + OVERLAY_ALPHA * np.float32(OCCLUDED_RGB)
    img = np.round(np.clip(out, 0, 1) * 255).astype(np.uint8)
    # closed first: the model's cracks (triangles dropped at texture-atlas seams) are not silhouette
    closed = cv2.morphologyEx(m.astype(np.uint8), cv2.MORPH_CLOSE, np.ones((5, 5), np.uint8))
    contours, _ = cv2.findContours(closed, cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_NONE)
    color = (230, 40, 40) if rec["diverged"] else (40, 220, 60)
    cv2.drawContours(img, contours, -1, color, 1, cv2.LINE_AA)
    cv2.putText(
        img,
        f"{rec['frame']}  rms {rec['rms']:.3f}",
        (6, 16),
        cv2.FONT_HERSHEY_SIMPLEX,
        0.45,
        (255, 255, 255),
        1,
        cv2.LINE_AA,
    )
    top = sorted(rec.get("arkit", {}).items(), key=lambda kv: -kv[1])[:OVERLAY_SHAPES]
    for j, (name, w) in enumerate(kv for kv in top if kv[1] > 0.05):
        cv2.putText(
            img, f"{name} {w:.2f}", (6, 34 + 16 * j), cv2.FONT_HERSHEY_SIMPLEX, 0.4, (255, 255, 0), 1, cv2.LINE_AA
        )
    return img.astype(np.float32) / 255.0


def write_overlay_video(
    path: str | os.PathLike, video: VideoFrames, fitter: FrameFitter, frames: list[dict], fps: float | None = None
) -> np.ndarray | None:
    """Write the overlay (:func:`overlay_frame`) of every tracked frame as an mp4 (OpenCV ``mp4v``),
    atomically (a temporary file moved into place). Returns the last overlay frame (RGB float) or None."""
    path = Path(path)
    by_index = {f["frame"]: f for f in frames}
    if not by_index:
        return None
    fd, tmp = tempfile.mkstemp(prefix=f".{path.stem}.", suffix=".mp4", dir=path.parent)
    os.close(fd)
    writer = cv2.VideoWriter(tmp, cv2.VideoWriter_fourcc(*"mp4v"), fps or video.fps, (video.width, video.height))
    last = None
    try:
        if not writer.isOpened():
            raise VideoError(f"OpenCV cannot write an mp4 video to {path.parent}")
        for i, frame in video.frames(0, max(by_index) + 1):
            rec = by_index.get(i)
            img = frame if rec is None else overlay_frame(fitter, frame, rec)
            writer.write(np.round(np.clip(img[..., ::-1], 0, 1) * 255).astype(np.uint8))
            last = img
        writer.release()
        os.chmod(tmp, 0o644)
        os.replace(tmp, path)
    except BaseException:
        writer.release()
        Path(tmp).unlink(missing_ok=True)
        raise
    return last
