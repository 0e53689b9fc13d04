"""The overlay: the face model rendered over the footage at its tracked parameters.

:func:`overlay_frame` draws one frame (alpha blend, occluded pixels tinted, silhouette outlined,
frame index and RMS; for a track in ARKit terms, the shapes weighing most); the
studio's tracking view shows it while scrubbing. :func:`write_overlay_video` writes every tracked
frame's as ``overlay.mp4``, atomically.
"""

from __future__ import annotations

import os
import queue
import tempfile
import threading
from pathlib import Path

import cv2
import numpy as np

from photomodel.photos.video import VideoError, VideoFrames
from photomodel.rendering.renderer import Renderer
from tracking.blendshape_face import render_model
from tracking.frame_fit import FrameFitter, outlier_pixels
from tracking.track_result import state_of

__all__ = ["OVERLAY_ALPHA", "OCCLUDED_RGB", "occluded_pixels", "overlay_frame", "write_overlay_video"]

OVERLAY_ALPHA = 0.5
#: Tint of the occluded pixels (magenta: unlike skin, hair or the usual backgrounds), blended at
#: :data:`OVERLAY_ALPHA`.
OCCLUDED_RGB = (1.0, 0.0, 1.0)
#: :func:`occluded_pixels`: the render's shading is matched to the frame's over a Gaussian of
#: this share of the face's size (the square root of its pixel count): a cheek in shade, not a nose.
SHADING_SIGMA_FACE = 0.12
#: :func:`occluded_pixels`: an occluder covers at least this share of the face's pixels (a closed
#: eye is about 1 %, a hand over the mouth 10 % and more).
MIN_OCCLUDER_SHARE = 0.02
#: :func:`occluded_pixels`: pixels nearer the model's silhouette than this share of the face's size
#: are not tinted (hair framing the face, the silhouette a few pixels off).
EDGE_BAND_FACE = 0.08
#: ARKit shapes written on an overlay frame (those weighing most, over 0.05).
OVERLAY_SHAPES = 3


def overlay_frame(fitter: FrameFitter, frame: np.ndarray, rec: dict, renderer=None) -> np.ndarray:
    """(H, W, 3) float32: the model at ``rec``'s parameters rendered over ``frame`` (alpha
    :data:`OVERLAY_ALPHA`), the pixels :func:`occluded_pixels` finds occluded tinted
    :data:`OCCLUDED_RGB` (only when the fitter's error is robust), its
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
        occluded = occluded_pixels(frame, r.image, m, r.pixels)
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


def occluded_pixels(frame: np.ndarray, rendered: np.ndarray, mask: np.ndarray, pixels: np.ndarray) -> np.ndarray:
    """(H, W) bool: the pixels the overlay tints as occluded — of the model's ``pixels`` (flat
    indices of ``mask`` (H, W) bool) in ``frame`` against ``rendered`` ((H, W, 3) float in [0, 1]),
    those whose residual is an outlier (:func:`tracking.frame_fit.outlier_pixels`) once the
    render's shading is matched to the frame's (a smooth gain, :data:`SHADING_SIGMA_FACE` of the
    face's size: light from one side darkens a cheek, no occluder), away from the silhouette
    (:data:`EDGE_BAND_FACE`), opened by a 3×3 square (single pixels are the texture's fine
    detail) and in patches of at least :data:`MIN_OCCLUDER_SHARE` of
    the face (closed eyes and a lid's shadow are smaller than a hand)."""
    h, w = mask.shape
    occluded = np.zeros(mask.size, np.uint8)
    if not len(pixels):
        return occluded.reshape(h, w) > 0
    mf = mask.astype(np.float32)
    size = float(np.sqrt(mf.sum()))
    sigma = max(1.0, SHADING_SIGMA_FACE * size)

    def outliers(gain) -> np.ndarray:
        flat = frame.reshape(-1, 3)[pixels] - (rendered * gain).reshape(-1, 3)[pixels]
        return outlier_pixels(np.sqrt((np.clip(flat, -1, 1) ** 2).mean(axis=1)))

    # the gain from the pixels that are the face as rendered (an occluder's own colour would
    # bend the gain around it and draw a halo)
    face = np.zeros(mask.size, np.float32)
    face[pixels[~outliers(1.0)]] = 1.0
    face = face.reshape(mask.shape)
    lum_f = _wide_blur(frame.mean(axis=2) * face, sigma)
    lum_r = _wide_blur(rendered.mean(axis=2) * face, sigma)
    gain = np.where(lum_r > 1e-4, np.clip(lum_f / np.maximum(lum_r, 1e-4), 0.25, 4.0), 1.0)[..., None]
    occluded[pixels[outliers(gain)]] = 1
    # the silhouette's band: hair framing the face and the model's edge off the face's by a few
    # pixels, not an occluder (a hand over the face reaches inside it)
    inside = cv2.distanceTransform(_silhouette(mask), cv2.DIST_L2, 3) > EDGE_BAND_FACE * size
    occluded = occluded.reshape(h, w) & inside
    opened = cv2.morphologyEx(occluded.astype(np.uint8), cv2.MORPH_OPEN, np.ones((3, 3), np.uint8))
    n, labels, stats, _ = cv2.connectedComponentsWithStats(opened, connectivity=8)
    big = np.zeros(n, bool)
    big[1:] = stats[1:, cv2.CC_STAT_AREA] >= MIN_OCCLUDER_SHARE * mf.sum()
    return big[labels]


def _wide_blur(img: np.ndarray, sigma: float) -> np.ndarray:
    """``img`` (H, W) float32 blurred by a Gaussian of ``sigma`` pixels, computed on a copy reduced
    by ⌊σ / 3⌋ (area averaging) and brought back bilinearly: a Gaussian of σ ≥ 6 px has nothing left
    at the reduced copy's frequencies, and the full-size blur of a 640×360 frame at σ ≈ 25 px took
    9 ms, two per overlay frame (2026-12-05)."""
    f = int(sigma // 3)
    h, w = img.shape
    if f < 2 or min(h, w) < 8 * f:
        return cv2.GaussianBlur(img, (0, 0), sigma)
    small = cv2.resize(img, (max(1, w // f), max(1, h // f)), interpolation=cv2.INTER_AREA)
    small = cv2.GaussianBlur(small, (0, 0), sigma / f)
    return cv2.resize(small, (w, h), interpolation=cv2.INTER_LINEAR)


def _silhouette(mask: np.ndarray) -> np.ndarray:
    """(H, W) uint8 1 inside the model's outer outline: ``mask`` with its holes filled (the cracks
    at texture-atlas seams, an open mouth), so that only the outline is an edge."""
    closed = cv2.morphologyEx(mask.astype(np.uint8), cv2.MORPH_CLOSE, np.ones((5, 5), np.uint8))
    contours, _ = cv2.findContours(closed, cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_NONE)
    out = np.zeros(mask.shape, np.uint8)
    cv2.drawContours(out, contours, -1, 1, -1)
    return out


def write_overlay_video(
    path: str | os.PathLike,
    video: VideoFrames,
    fitter: FrameFitter,
    frames: list[dict],
    fps: float | None = None,
    workers: int | None = None,
) -> np.ndarray | None:
    """Write the overlay (:func:`overlay_frame`) of every tracked frame as an mp4 (OpenCV ``mp4v``),
    atomically (a temporary file moved into place). Returns the last overlay frame (RGB float) or None.

    The frames are drawn by ``workers`` threads (default :data:`OVERLAY_WORKERS`), each with its own
    OpenGL renderer, a few frames ahead of the writer, which takes them in order: the rendering,
    OpenCV's filters and numpy's large products release the interpreter's lock, so two threads use
    both cores (the overlay took ~20 s of ``auto``'s 132 s on the real clip drawn one by one)."""
    path = Path(path)
    by_index = {f["frame"]: f for f in frames}
    if not by_index:
        return None
    fd, tmp = tempfile.mkstemp(prefix=f".{path.stem}.", suffix=".mp4", dir=path.parent)
    os.close(fd)
    writer = cv2.VideoWriter(tmp, cv2.VideoWriter_fourcc(*"mp4v"), fps or video.fps, (video.width, video.height))
    last = None
    pool = _OverlayPool(fitter, workers or OVERLAY_WORKERS)
    try:
        if not writer.isOpened():
            raise VideoError(f"OpenCV cannot write an mp4 video to {path.parent}")
        for img in pool.drawn(video.frames(0, max(by_index) + 1), by_index):
            writer.write(np.round(np.clip(img[..., ::-1], 0, 1) * 255).astype(np.uint8))
            last = img
        writer.release()
        os.chmod(tmp, 0o644)
        os.replace(tmp, path)
    except BaseException:
        writer.release()
        Path(tmp).unlink(missing_ok=True)
        raise
    finally:
        pool.close()
    return last


#: Threads drawing overlay frames (:func:`write_overlay_video`).
OVERLAY_WORKERS = max(1, min(2, os.cpu_count() or 1))
#: Frames drawn ahead of the writer, per thread (bounds the memory: a 640×360 frame is 2.8 MB).
_AHEAD = 4


class _OverlayPool:
    """Threads drawing :func:`overlay_frame`, each with its own renderer, made and released in it
    (an OpenGL context belongs to the thread that created it)."""

    def __init__(self, fitter: FrameFitter, workers: int):
        self.fitter = fitter
        self.jobs: queue.Queue = queue.Queue()
        self.results: dict[int, object] = {}
        self.ready = threading.Condition()
        self.threads = [
            threading.Thread(target=self._work, name=f"overlay-{k}", daemon=True) for k in range(max(1, workers))
        ]
        for t in self.threads:
            t.start()

    def _work(self) -> None:
        renderer = None
        try:
            while (job := self.jobs.get()) is not None:
                seq, frame, rec = job
                try:
                    if rec is not None and renderer is None:
                        renderer = Renderer()
                    out = frame if rec is None else overlay_frame(self.fitter, frame, rec, renderer=renderer)
                except BaseException as exc:  # noqa: BLE001 — raised again by the writer's thread
                    out = exc
                with self.ready:
                    self.results[seq] = out
                    self.ready.notify_all()
        finally:
            if renderer is not None:
                renderer.release()

    def _take(self, seq: int) -> np.ndarray:
        with self.ready:
            self.ready.wait_for(lambda: seq in self.results)
            out = self.results.pop(seq)
        if isinstance(out, BaseException):
            raise out
        return out

    def drawn(self, frames, by_index: dict):
        """The overlay of each ``(i, frame)`` of ``frames`` (the frame itself where ``i`` was not
        tracked), in order; at most :data:`_AHEAD` frames per thread drawn ahead."""
        sent = taken = 0
        for i, frame in frames:
            self.jobs.put((sent, frame, by_index.get(i)))
            sent += 1
            if sent - taken >= _AHEAD * len(self.threads):
                yield self._take(taken)
                taken += 1
        while taken < sent:
            yield self._take(taken)
            taken += 1

    def close(self) -> None:
        """Stop the threads (after the frames they are on) and wait for them."""
        while True:  # frames not drawn yet are dropped (an error or an interrupt ended the writing)
            try:
                self.jobs.get_nowait()
            except queue.Empty:
                break
        for _ in self.threads:
            self.jobs.put(None)
        for t in self.threads:
            t.join()
