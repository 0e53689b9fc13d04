"""Editing the expressions of a tracked video: ``facestudio edit`` (Yang et al. 2012, §3.1.4–5).

A short sequence of steps over arrays (:func:`edit_track`):

1. the results of ``facestudio track`` (``track.json``) and the footage they name are read, the
   project's face model rebuilt (:func:`tracking.arkit_face.model_for_results`, as the review does);
2. optionally the expression weights of the whole clip are solved again, temporally smooth
   (:func:`tracking.smooth.smooth_clip`, §3.1.4);
3. the edits are applied to the weight curves (:mod:`tracking.edit`, §4–5);
4. each frame whose parameters changed is warped by the expression flow
   (:func:`tracking.expression_flow.edit_frame`, §4), the pixels it does not show filled from the
   clip's most similar frame (nearest tracked region weights) or the model's texture; the other
   frames are copied;
5. the frames are written as lossless PNGs and, when asked, as a video at the footage's frame rate
   (:func:`write_video`).

Video writing uses PyAV (FFmpeg's libraries; a kept library): it encodes H.264 and copies the
footage's audio stream packet for packet (OpenCV's writer cannot carry audio). The edits, with the
smoothing settings, are stored in ``edits.json`` beside ``track.json`` (:mod:`tracking.edit`).
"""

from __future__ import annotations

import os
from dataclasses import asdict, dataclass, field
from fractions import Fraction
from pathlib import Path

import av
import cv2
import numpy as np

from photomodel.errors import FaceStudioError
from photomodel.photos.video import VideoFrames
from photomodel.project import load_project
from photomodel.rendering.renderer import get_renderer
from tracking.arkit_face import model_for_results
from tracking.edit import edited_alphas, edits_document, save_edits
from tracking.expression_flow import FlowOptions, edit_frame
from tracking.frame_fit import FrameFitter
from tracking.smooth import SmoothOptions, smooth_clip, weight_curves
from tracking.track_result import load_track_results, state_of

__all__ = ["EditReport", "most_similar_frames", "edit_track", "write_frames", "write_video"]

#: A frame whose parameters changed by less than this (mm RMS units of α) is copied unedited.
UNCHANGED_ALPHA = 1e-6


@dataclass
class EditReport:
    """What :func:`edit_track` did.

    Attributes
    ----------
    frames : int, frames written.
    edited : int, frames whose expression changed (the others are copies).
    filled_similar, filled_texture : int, pixels over all frames taken from the most similar frame /
        from the model's texture (what the clip does not show).
    frames_dir : Path or None, the PNG frames; video : Path or None; audio : bool, audio copied.
    edits_json : Path, the edits file written beside the track.
    weights : (T, R, m) float, tracked (or smoothed) weights; edited_weights : the same after the edits.
    """

    frames: int
    edited: int
    filled_similar: int
    filled_texture: int
    frames_dir: Path | None
    video: Path | None
    audio: bool
    edits_json: Path
    weights: np.ndarray = field(repr=False)
    edited_weights: np.ndarray = field(repr=False)

    def to_json(self) -> dict:
        return {
            "frames": self.frames,
            "edited": self.edited,
            "filled_similar_px": self.filled_similar,
            "filled_texture_px": self.filled_texture,
            "frames_dir": None if self.frames_dir is None else str(self.frames_dir),
            "video": None if self.video is None else str(self.video),
            "audio": self.audio,
            "edits_json": str(self.edits_json),
        }


def most_similar_frames(weights: np.ndarray, targets: np.ndarray) -> np.ndarray:
    """(T',) for each target weights (T', R, m) the frame of ``weights`` (T, R, m) nearest to it
    (Euclidean over all regions' weights: the paper's DTW distance ``‖β'_i − β_j‖``, §4)."""
    A = np.asarray(weights, float).reshape(len(weights), -1)
    B = np.asarray(targets, float).reshape(len(targets), -1)
    d = (B * B).sum(1)[:, None] - 2 * B @ A.T + (A * A).sum(1)[None]
    return np.argmin(d, axis=1)


def edit_frames(
    fitter: FrameFitter, frames, states, edits: list[dict], flow: FlowOptions | None = None, progress=None, only=None
) -> tuple[list, np.ndarray, dict]:
    """The edited frames of a clip (steps 3–4 of the module docstring).

    Parameters
    ----------
    fitter : FrameFitter (model and camera).
    frames : sequence of T (H, W, 3) float32 in [0, 1].
    states : sequence of T FrameState, tracked (or smoothed) parameters.
    edits : list of edit dicts (:mod:`tracking.edit`).
    flow : FlowOptions, optional.
    progress : callable ``(frame)``, optional.
    only : sequence of int, optional, the frames to write (default all; the most similar frame is
        still chosen from the whole clip).

    Returns
    -------
    images : list of the written (H, W, 3) float32 frames; alphas : (T, a) edited parameters;
    counts : {"edited", "filled_similar", "filled_texture"}.
    """
    model = fitter.model
    renderer = get_renderer()
    alphas = np.array([s.alpha for s in states]).reshape(len(states), fitter.n_alpha)
    new = edited_alphas(model, alphas, edits)
    W, W_new = weight_curves(model, alphas), weight_curves(model, new)
    similar = most_similar_frames(W, W_new)
    counts = {"edited": 0, "filled_similar": 0, "filled_texture": 0}
    out = []
    for n, t in enumerate(range(len(states)) if only is None else only):
        frame, st = np.asarray(frames[t], np.float32), states[t]
        if np.abs(new[t] - alphas[t]).max(initial=0.0) < UNCHANGED_ALPHA:
            out.append(frame)
        else:
            j = int(similar[t])
            sim = None if j == t else (np.asarray(frames[j], np.float32), fitter.camera(states[j]), alphas[j])
            res = edit_frame(renderer, model, fitter.camera(st), frame, alphas[t], new[t], sim, flow)
            out.append(res.image)
            counts["edited"] += 1
            counts["filled_similar"] += res.filled_similar
            counts["filled_texture"] += res.filled_texture
        if progress is not None:
            progress(n)
    return out, new, counts


def write_frames(folder: str | os.PathLike, images) -> Path:
    """Write ``images`` ((H, W, 3) float in [0, 1]) as ``frame_00000.png``… into ``folder``
    (8-bit, lossless: the footage's own 8 bits come back exactly where nothing moved)."""
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    for i, img in enumerate(images):
        bgr = cv2.cvtColor(np.clip(np.rint(np.asarray(img) * 255.0), 0, 255).astype(np.uint8), cv2.COLOR_RGB2BGR)
        if not cv2.imwrite(str(folder / f"frame_{i:05d}.png"), bgr):
            raise FaceStudioError(f"cannot write the frame {folder / f'frame_{i:05d}.png'}")
    return folder


def write_video(path: str | os.PathLike, images, fps: float, audio_from: str | os.PathLike | None = None) -> bool:
    """Encode ``images`` as H.264 (yuv420p, CRF 16) at ``fps`` into ``path`` with PyAV, copying the
    first audio stream of ``audio_from`` (a video file) when it has one. Returns whether audio was
    copied."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    images = list(images)
    H, W = images[0].shape[:2]
    src = None
    if audio_from is not None and Path(audio_from).is_file():
        src = av.open(str(audio_from))
    try:
        with av.open(str(path), "w") as out:
            rate = _fraction(fps)
            vs = out.add_stream("libx264", rate=rate, options={"crf": "16"})
            vs.width, vs.height, vs.pix_fmt = W + W % 2, H + H % 2, "yuv420p"
            a_in = next(iter(src.streams.audio), None) if src is not None else None
            a_out = out.add_stream_from_template(a_in) if a_in is not None else None
            for img in images:
                u8 = np.clip(np.rint(np.asarray(img) * 255.0), 0, 255).astype(np.uint8)
                if u8.shape[:2] != (vs.height, vs.width):
                    u8 = np.pad(u8, ((0, vs.height - H), (0, vs.width - W), (0, 0)), mode="edge")
                for packet in vs.encode(av.VideoFrame.from_ndarray(u8, format="rgb24")):
                    out.mux(packet)
            for packet in vs.encode():
                out.mux(packet)
            if a_in is not None:
                for packet in src.demux(a_in):
                    if packet.dts is None:
                        continue
                    packet.stream = a_out
                    out.mux(packet)
        return a_in is not None
    finally:
        if src is not None:
            src.close()


def _fraction(fps: float) -> Fraction:
    return Fraction(float(fps)).limit_denominator(1001)


def edit_track(
    track_dir: str | os.PathLike,
    edits: list[dict],
    *,
    smooth: SmoothOptions | None = None,
    out_video: str | os.PathLike | None = None,
    frames_dir: str | os.PathLike | None = None,
    flow: FlowOptions | None = None,
    project: str | os.PathLike | None = None,
    progress=None,
) -> EditReport:
    """Edit the expressions of the tracked video in ``track_dir`` (module docstring).

    Parameters
    ----------
    track_dir : the results folder of ``facestudio track`` (holds ``track.json``).
    edits : list of edit dicts (:mod:`tracking.edit`); stored in ``track_dir/edits.json``.
    smooth : SmoothOptions, optional; None keeps the per-frame tracked weights.
    out_video : a video file to write (``.mp4``), optional.
    frames_dir : a folder for the PNG frames, optional (default ``<out_video stem>_frames`` beside
        the video, or ``track_dir/edited_frames`` without one).
    project : the project file of the face model (default: the one ``track.json`` names).
    progress : callable ``(stage, done, total)``, optional.

    Raises
    ------
    FaceStudioError when the track, its project or its footage cannot be read, or an edit is invalid.
    """
    track_dir = Path(track_dir).absolute()
    doc = load_track_results(track_dir)
    if doc is None:
        raise FaceStudioError(f"{track_dir} holds no track.json (run facestudio track first)")
    records = doc["frames"]
    if not records:
        raise FaceStudioError(f"{track_dir}/track.json holds no tracked frame")
    report = progress or (lambda stage, done, total: None)
    model = model_for_results(load_project(doc["project"] if project is None else project), doc)
    cam = doc["camera"]
    fitter = FrameFitter(model, cam["focal_px"], cam["width"], cam["height"])
    video = VideoFrames(doc["video"]["path"])
    frames = [f for _, f in video.frames(0, len(records))]
    states = [state_of(r) for r in records[: len(frames)]]
    if smooth is not None:
        states = smooth_clip(
            fitter, frames, states, smooth, lambda k, t: report(f"smoothing (round {k + 1})", t + 1, len(frames))
        ).states
    images, new, counts = edit_frames(
        fitter, frames, states, edits, flow, lambda t: report("editing", t + 1, len(frames))
    )
    edits_json = save_edits(track_dir, edits_document(edits, len(frames), None if smooth is None else asdict(smooth)))
    if frames_dir is None:
        frames_dir = (
            Path(out_video).with_name(Path(out_video).stem + "_frames")
            if out_video is not None
            else track_dir / "edited_frames"
        )
    write_frames(frames_dir, images)
    audio = False
    if out_video is not None:
        audio = write_video(out_video, images, video.fps, None if video.is_folder else video.path)
    alphas = np.array([s.alpha for s in states]).reshape(len(states), fitter.n_alpha)
    return EditReport(
        len(images),
        counts["edited"],
        counts["filled_similar"],
        counts["filled_texture"],
        Path(frames_dir).absolute(),
        None if out_video is None else Path(out_video).absolute(),
        audio,
        edits_json,
        weight_curves(model, alphas),
        weight_curves(model, new),
    )
