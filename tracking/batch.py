"""Tracking a video driven by project files: ``facestudio track`` (Pighin et al. 2002, §6.2).

:func:`track_video` reads the footage, fits the face model to every frame with
:class:`tracking.frame_fit.FrameFitter` (pose, then expression; each frame predicted from the two before,
§6.2) and writes into an output folder:

* ``track.json`` — everything: the run's settings (video, camera, model and its source, first pose,
  options) and one record per frame (:func:`frame_record`); the source of truth for continuing;
* ``track.csv`` — one row per frame (:data:`CSV_COLUMNS`), for spreadsheets;
* ``weights.png``, ``rotation.png``, ``translation.png``, ``rms.png`` — plots like Figs. 12–19
  (:mod:`tracking.plots`);
* ``overlay.mp4`` — the model rendered over the footage, alpha blended, with its silhouette
  outlined (written when the whole video is tracked), and ``overlay_last.png``, its last frame.

Cancel-safe and resumable: the results are written atomically (temporary file, fsync,
:func:`os.replace`) every :data:`SAVE_EVERY` frames, when ``cancel()`` says stop and on Ctrl-C, so
the files on disk are always complete and valid for the frames they list. A second run with the same
settings on the same folder continues after the last saved frame, its prediction restored from the
last two saved frames (the JSON keeps the parameters at full precision, so a resumed run computes
what an uninterrupted one would). Other settings in the folder are refused unless ``restart``.

Correcting a frame: when frame N diverged or drifted, ``correct_frame=N`` with ``correct_pose`` (that
frame's clicks or pose, the first-pose format) keeps frames 0 .. N−1, fits frame N from the user's
pose in several rounds like frame 0, and tracks on from there; ``track.json`` records the correction
(``corrections``) so that continuing reproduces it (see :func:`track_video`).

Where the pieces come from
--------------------------
* **Video**: a file OpenCV's :class:`cv2.VideoCapture` reads (a kept decoder), or a folder of
  PNG/JPG frames in natural name order (``f2.png`` before ``f10.png``). Frames are RGB in [0, 1].
* **Face model**: the blend-shape model of the project's fitted and textured expressions
  (:func:`project_face_model`; ``facestudio fit`` then ``facestudio texture`` make them), recorded
  with its source in ``track.json``. A caller may pass its own :class:`tracking.facemodel.FaceModel`
  with a ``model_source``.
* **First frame's pose** (the user's part, §6.2): a JSON file (:func:`load_first_pose`) with the
  video camera's focal length and either a pose or the image positions of at least six of the
  project's features in frame 0 (solved by :func:`tracking.frame_fit.pose_from_clicks`). By default it is
  ``<video stem>.first_pose.json`` beside a video file, or ``first_pose.json`` in a frame folder;
  the sample video ships one (13 clicks with 0.5 px noise).
"""

from __future__ import annotations

import csv
import io
import json
import math
import os
import re
import tempfile
import time
from collections.abc import Callable, Iterator
from dataclasses import asdict, dataclass, field
from pathlib import Path

import cv2
import numpy as np

from photomodel.camera import focal_mm_to_px, rodrigues, rotation_vector
from photomodel.errors import FaceStudioError, FitError
from photomodel.exchange.files import atomic_write_bytes, encode_png
from tracking.facemodel import CONTROL_REGIONS, FaceModel, render_model
from tracking.frame_fit import DIVERGED_RMS, FrameFitter, FrameState, TrackOptions, pose_from_clicks, track_frames
from tracking.plots import track_plots

__all__ = [
    "FORMAT",
    "VERSION",
    "SAVE_EVERY",
    "CSV_COLUMNS",
    "VideoError",
    "VideoFrames",
    "FirstPose",
    "TrackResult",
    "track_video",
    "project_face_model",
    "load_first_pose",
    "default_first_pose_path",
    "default_out_dir",
    "frame_record",
    "STARTS",
    "load_track_results",
    "write_overlay_video",
]

FORMAT = "facestudio-track"
VERSION = 1
#: Results are written after every this many tracked frames (and at the end, on cancel, on Ctrl-C).
SAVE_EVERY = 5
#: Head rotation of a face looking straight at the camera (head +y up → camera −y, +z out of the
#: face → towards the camera); plotted angles are relative to it.
FACING = np.diag([1.0, -1.0, -1.0])
IMAGE_SUFFIXES = (".png", ".jpg", ".jpeg")
OVERLAY_ALPHA = 0.5
OVERLAY_FPS = 10.0


class VideoError(FaceStudioError):
    """The video (file or frame folder) is missing, unreadable or inconsistent."""


# ----------------------------------------------------------------------------- video


def _natural_key(path: Path):
    return [int(s) if s.isdigit() else s.lower() for s in re.split(r"(\d+)", path.name)]


class VideoFrames:
    """Frames of a video file or of a folder of images, as (H, W, 3) float32 RGB in [0, 1].

    Parameters
    ----------
    path : a video file (anything :class:`cv2.VideoCapture` decodes) or a folder of PNG/JPG frames.

    Raises
    ------
    VideoError naming the path when it is missing, not decodable, empty, or (folders) holds a frame
    that is unreadable or of another size than the first.
    """

    def __init__(self, path: str | os.PathLike):
        self.path = Path(path).absolute()
        if not self.path.exists():
            raise VideoError(f"the video {self.path} does not exist")
        self.is_folder = self.path.is_dir()
        self.fps = OVERLAY_FPS
        if self.is_folder:
            self.files = sorted((p for p in self.path.iterdir() if p.suffix.lower() in IMAGE_SUFFIXES),
                                key=_natural_key)  # fmt: skip
            if not self.files:
                raise VideoError(f"the frame folder {self.path} holds no PNG or JPG images")
            self.count: int | None = len(self.files)
            first = self._read_image(self.files[0])
        else:
            self.files = []
            cap = self._open()
            try:
                ok, bgr = cap.read()
                if not ok or bgr is None:
                    raise VideoError(f"the video {self.path} has no frame OpenCV can decode (empty or corrupt)")
                n = int(cap.get(cv2.CAP_PROP_FRAME_COUNT))
                self.count = n if n > 0 else None  # containers may not say
                fps = float(cap.get(cv2.CAP_PROP_FPS))
                self.fps = fps if math.isfinite(fps) and fps > 0 else OVERLAY_FPS
            finally:
                cap.release()
            first = bgr
        self.height, self.width = first.shape[:2]

    def _open(self):
        cap = cv2.VideoCapture(str(self.path))
        if not cap.isOpened():
            cap.release()
            raise VideoError(f"the video {self.path} cannot be opened by OpenCV (corrupt or unknown format); "
                             f"a folder of PNG/JPG frames works too")  # fmt: skip
        return cap

    def _read_image(self, path: Path) -> np.ndarray:
        img = cv2.imread(str(path), cv2.IMREAD_COLOR)
        if img is None:
            raise VideoError(f"the frame {path} is not an image OpenCV can read (corrupt or unknown format)")
        return img

    def frames(self, start: int = 0, stop: int | None = None) -> Iterator[tuple[int, np.ndarray]]:
        """Yield ``(index, frame)`` for frames ``start`` .. ``stop − 1`` (to the end if None)."""
        if self.is_folder:
            for i in range(start, len(self.files) if stop is None else min(stop, len(self.files))):
                bgr = self._read_image(self.files[i])
                if bgr.shape[:2] != (self.height, self.width):
                    raise VideoError(f"the frame {self.files[i]} is {bgr.shape[1]}x{bgr.shape[0]}, but the first "
                                     f"frame is {self.width}x{self.height}")  # fmt: skip
                yield i, _to_rgb(bgr)
            return
        cap = self._open()
        try:
            for _ in range(start):  # decoding from the start is the reliable way to reach a frame
                if not cap.grab():
                    return
            i = start
            while stop is None or i < stop:
                ok, bgr = cap.read()
                if not ok or bgr is None:
                    return
                yield i, _to_rgb(bgr)
                i += 1
        finally:
            cap.release()


def _to_rgb(bgr: np.ndarray) -> np.ndarray:
    return cv2.cvtColor(bgr, cv2.COLOR_BGR2RGB).astype(np.float32) / 255.0


# ----------------------------------------------------------------------------- model, first pose


def project_face_model(project, names=None) -> tuple[FaceModel, str]:
    """The face model to track ``project`` with, and a sentence saying where it comes from: the
    blend-shape model of its fitted and textured expressions
    (:func:`tracking.project_model.face_model_from_project`; ``names`` picks them, E_1 first).

    Raises
    ------
    FitError, ProjectError
        fewer than two expressions, or one not fitted or textured (the message says which and the
        command that does it), or a missing or damaged mesh or texture file.
    """
    from tracking.project_model import face_model_from_project

    model, report = face_model_from_project(project, names)
    reg = "; ".join(f"{n} {r['rms_mm']:.2f} mm" for n, r in report["registration"].items())
    return model, (f"project: the expressions {', '.join(model.names)} fitted and textured from the project's "
                   f"photos (§6.1.1), registered onto {model.names[0]} by their rest of the face (RMS: {reg})")


@dataclass
class FirstPose:
    """The first frame's parameters and the video camera.

    Attributes
    ----------
    state : FrameState, model pose (centre convention of :mod:`tracking.frame_fit`) and expression.
    focal_px : float, the video camera's focal length in pixels.
    source : str, where it came from (file and kind), for the record.
    spec : dict, the JSON it was read from (compared when a run continues).
    """

    state: FrameState
    focal_px: float
    source: str
    spec: dict = field(default_factory=dict)


def default_first_pose_path(video: str | os.PathLike) -> Path:
    """``<video stem>.first_pose.json`` beside a video file, ``first_pose.json`` in a frame folder."""
    v = Path(video).absolute()
    return v / "first_pose.json" if v.is_dir() else v.with_name(f"{v.stem}.first_pose.json")


def default_out_dir(project_path: str | os.PathLike, video: str | os.PathLike) -> Path:
    """``<project folder>/results/track_<video stem>`` (absolute)."""
    return Path(project_path).absolute().parent / "results" / f"track_{Path(video).absolute().stem}"


def _vector(spec: dict, key: str, shape: tuple, where: str) -> np.ndarray:
    try:
        a = np.asarray(spec[key], float)
    except (TypeError, ValueError) as exc:
        raise FitError(f"{where}: {key!r} must be numbers of shape {shape}") from exc
    if a.shape != shape or not np.all(np.isfinite(a)):
        raise FitError(f"{where}: {key!r} must be finite numbers of shape {shape}, got {spec[key]!r}")
    return a


def _read_pose_spec(spec: dict | str | os.PathLike, frame: int = 0) -> tuple[dict, str]:
    """The pose JSON object of frame ``frame`` (a path or the parsed dict) and how to name it in errors."""
    if isinstance(spec, dict):
        try:  # what is recorded in track.json must survive JSON (no numpy scalars, no NaN)
            spec = json.loads(json.dumps(spec, allow_nan=False))
        except (TypeError, ValueError) as exc:
            raise FitError(f"the pose of frame {frame} is not plain JSON: {exc}") from exc
        return spec, "first pose" if frame == 0 else f"the pose of frame {frame}"
    path = Path(spec)
    kind = "first-pose" if frame == 0 else "pose"
    if not path.is_file():
        if frame == 0:
            raise FitError(f"the first-pose file {path} does not exist: write the first frame's pose or clicks "
                           f"there (see docs/tracking.md) or pass --first-pose")  # fmt: skip
        raise FitError(f"the pose file {path} does not exist: write frame {frame}'s pose or clicks there "
                       f"(the first-pose format, see docs/tracking.md)")  # fmt: skip
    try:
        spec = json.loads(path.read_text())
    except (OSError, ValueError) as exc:
        raise FitError(f"{path}: not a JSON {kind} file: {exc}") from exc
    if not isinstance(spec, dict):
        raise FitError(f"{path}: the {kind} file must hold a JSON object")
    return spec, str(path)


def _spec_focal(spec: dict, where: str, width: int) -> float | None:
    """The focal length (px) a pose JSON gives (``focal_px``, or ``focal_mm`` on a 36 mm-wide sensor); None if none."""
    if "focal_px" in spec:
        return float(_vector(spec, "focal_px", (), where))
    if "focal_mm" in spec:
        return focal_mm_to_px(float(_vector(spec, "focal_mm", (), where)), width)
    return None


def load_first_pose(spec: dict | str | os.PathLike, project, model: FaceModel, width: int, height: int,
                    focal_px: float | None = None, *, frame: int = 0) -> FirstPose:  # fmt: skip
    """The first frame's pose from a first-pose JSON (a path or the parsed dict).

    The JSON object::

        {"focal_px": 560.0,                    # or "focal_mm" (36 mm-wide sensor)
         "clicks": {"nose_tip": [u, v], ...},  # ≥ 6 project features in frame 0, px (centres at integers)
         // or a pose, X_cam = R X + t with X in the head frame (mm):
         "R": [[...], [...], [...]],           # or "rotation_vector": [rx, ry, rz] (radians)
         "t_mm": [tx, ty, tz],
         "weights": {"mouth": {"smile": 0.3}}  # optional start expression (default neutral)
        }

    ``focal_px`` (the command line's ``--focal-px``) overrides the file's. ``frame``: the frame the
    clicks or pose are of — the same format gives a user's correction of a later frame
    (:func:`track_video`'s ``correct_pose``); it only changes the messages. Raises :class:`FitError`
    naming the file and the field.
    """
    spec, where = _read_pose_spec(spec, frame)
    return _pose_from_spec(spec, where, project, model, width, height, focal_px, frame)


def _pose_from_spec(spec: dict, where: str, project, model: FaceModel, width: int, height: int,
                    focal_px: float | None, frame: int) -> FirstPose:  # fmt: skip
    """:func:`load_first_pose` of a parsed JSON object named ``where`` in errors."""
    if focal_px is None:
        focal_px = _spec_focal(spec, where, width)
        if focal_px is None:
            raise FitError(f"{where}: the video camera's focal length is missing: give 'focal_px' (or 'focal_mm' "
                           f"for a 36 mm-wide sensor) or pass --focal-px")  # fmt: skip
    if not (math.isfinite(focal_px) and focal_px > 0):
        raise FitError(f"{where}: the focal length must be a positive number of pixels, got {focal_px}")
    if "clicks" in spec:
        clicks = spec["clicks"]
        if not isinstance(clicks, dict) or not clicks:
            raise FitError(f"{where}: 'clicks' must map feature names to [u, v] pixels")
        names = list(clicks)
        try:
            vertices = project.feature_vertices(names)
        except FaceStudioError as exc:
            raise FitError(f"{where}: {exc}") from exc
        uv = np.array([_vector(clicks, n, (2,), f"{where}: clicks") for n in names])
        try:
            state = pose_from_clicks(model, vertices, uv, focal_px, width, height)
        except FitError as exc:
            raise FitError(f"{where}: {exc} (clicks of frame {frame})") from exc
        source = f"{where}: {len(names)} clicked features, pose by tracking.frame_fit.pose_from_clicks"
    elif "R" in spec or "rotation_vector" in spec:
        R = _vector(spec, "R", (3, 3), where) if "R" in spec else rodrigues(_vector(spec, "rotation_vector", (3,),
                                                                                      where))  # fmt: skip
        if not np.allclose(R @ R.T, np.eye(3), atol=1e-6) or np.linalg.det(R) < 0:
            raise FitError(f"{where}: 'R' is not a rotation matrix")
        if "t_mm" not in spec:
            raise FitError(f"{where}: a pose needs 't_mm' (X_cam = R X + t, mm) besides the rotation")
        t = _vector(spec, "t_mm", (3,), where)
        state = FrameState(R, t + R @ model.centre, np.zeros(sum(model.n_alpha)))
        source = f"{where}: pose given"
    else:
        raise FitError(f"{where}: give either 'clicks' (≥ 6 features of frame {frame}) or a pose ('R' or "
                       f"'rotation_vector', and 't_mm')")  # fmt: skip
    if "weights" in spec:
        state.alpha = model.alpha_of_weights(_weights_array(spec["weights"], model, where))
    return FirstPose(state, float(focal_px), source, spec)


def _weights_array(weights, model: FaceModel, where: str) -> np.ndarray:
    """(R, m) region weights from {region: {expression: w}} (neutral = 1 − the others)."""
    W = np.tile(np.eye(model.m)[0], (len(CONTROL_REGIONS), 1))
    if not isinstance(weights, dict):
        raise FitError(f"{where}: 'weights' must map regions to {{expression: weight}}")
    for r, ws in weights.items():
        if r not in CONTROL_REGIONS[1:] or not isinstance(ws, dict):
            raise FitError(f"{where}: 'weights' has unknown region {r!r}; regions: {', '.join(CONTROL_REGIONS[1:])}")
        ri = CONTROL_REGIONS.index(r)
        for e, w in ws.items():
            if e not in model.names[1:]:
                raise FitError(f"{where}: 'weights.{r}' has unknown expression {e!r}; "
                               f"expressions: {', '.join(model.names[1:])}")  # fmt: skip
            W[ri, model.names.index(e)] = float(w)
        W[ri, 0] = 1.0 - W[ri, 1:].sum()
    return W


# ----------------------------------------------------------------------------- records


#: Columns of ``track.csv`` before the weights (``w_<region>_<expression>``) and after them.
CSV_COLUMNS = (
    ["frame", "rx_rad", "ry_rad", "rz_rad", "pitch_deg", "yaw_deg", "roll_deg", "tx_mm", "ty_mm", "tz_mm",
     "cx_mm", "cy_mm", "cz_mm"],
    ["rms", "pixels", "diverged", "steps", "evaluations", "seconds", "start"],
)  # fmt: skip
#: Where a frame's fit started (a record's ``start``): the first pose (frame 0), the prediction from
#: the frames before (§6.2), or a pose the user gave for that frame (a correction).
STARTS = ("first_pose", "predicted", "user")


def frame_record(index: int, result, model: FaceModel, seconds: float, start: str = "predicted") -> dict:
    """One frame's JSON record.

    Keys: ``frame``; ``rotation_vector`` (3,) rad and ``R`` (3, 3) with ``t_mm`` (3,):
    ``X_cam = R X + t`` for head-frame points X (the project's camera convention); ``centre_mm``
    (3,): the model centre in camera space; ``head_rotation_deg`` (3,): rotation vector of
    ``R · FACINGᵀ`` in degrees (pitch, yaw, roll about the camera axes); ``alpha``: the expression
    parameters (concatenated per region); ``weights`` {region: {expression: w}} of each control
    region (rest excluded: it is always neutral); ``rms`` (image RMS, intensity in [0, 1]),
    ``pixels`` covered, ``diverged``, ``steps`` (accepted LM steps), ``evaluations`` (renderings),
    ``seconds``; ``start``: where the fit started (:data:`STARTS`: ``"first_pose"``,
    ``"predicted"``, or ``"user"`` for a corrected frame). Floats at full precision: a run continues
    from them exactly.
    """
    if start not in STARTS:
        raise ValueError(f"start must be one of {STARTS}, got {start!r}")
    st = result.state
    R = np.asarray(st.R, float)
    return {
        "frame": int(index),
        "rotation_vector": rotation_vector(R).tolist(),
        "R": R.tolist(),
        "t_mm": (st.t - R @ model.centre).tolist(),
        "centre_mm": np.asarray(st.t, float).tolist(),
        "head_rotation_deg": np.degrees(rotation_vector(R @ FACING.T)).tolist(),
        "alpha": np.asarray(st.alpha, float).tolist(),
        "weights": {r: dict(zip(model.names, map(float, result.weights[i]), strict=True))
                    for i, r in enumerate(CONTROL_REGIONS) if i},  # fmt: skip
        "rms": float(result.rms),
        "pixels": int(result.pixels),
        "diverged": bool(result.diverged),
        "steps": len(result.history),
        "evaluations": int(result.evaluations),
        "seconds": float(seconds),
        "start": start,
    }


def _state_of(rec: dict) -> FrameState:
    return FrameState(np.array(rec["R"], float), np.array(rec["centre_mm"], float), np.array(rec["alpha"], float))


def _csv_bytes(frames: list[dict], regions: list[str], names: list[str]) -> bytes:
    head, tail = CSV_COLUMNS
    wcols = [(r, e) for r in regions for e in names]
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(head + [f"w_{r}_{e}" for r, e in wcols] + tail)
    for f in frames:
        row = [f["frame"], *f["rotation_vector"], *f["head_rotation_deg"], *f["t_mm"], *f["centre_mm"]]
        row += [f["weights"][r][e] for r, e in wcols]
        row += [f["rms"], f["pixels"], int(f["diverged"]), f["steps"], f["evaluations"], f["seconds"],
                f.get("start", "")]
        w.writerow([repr(v) if isinstance(v, float) else v for v in row])
    return buf.getvalue().encode()


def load_track_results(out_dir: str | os.PathLike) -> dict | None:
    """The ``track.json`` of ``out_dir`` (None if there is none); :class:`FaceStudioError` if unreadable."""
    path = Path(out_dir) / "track.json"
    if not path.is_file():
        return None
    try:
        doc = json.loads(path.read_text())
    except (OSError, ValueError) as exc:
        raise FaceStudioError(f"{path}: cannot read the tracking results ({exc}); remove it or pass --restart") from exc
    if not isinstance(doc, dict) or doc.get("format") != FORMAT or not isinstance(doc.get("frames"), list):
        raise FaceStudioError(f"{path}: not a Face Studio tracking file; choose another --out or pass --restart")
    if doc.get("version") != VERSION:
        raise FaceStudioError(f"{path}: tracking file version {doc.get('version')} (this Face Studio writes "
                              f"{VERSION}); pass --restart")  # fmt: skip
    return doc


# ----------------------------------------------------------------------------- overlay


def overlay_frame(fitter: FrameFitter, frame: np.ndarray, rec: dict, renderer=None) -> np.ndarray:
    """(H, W, 3) float32: the model at ``rec``'s parameters rendered over ``frame`` (alpha
    :data:`OVERLAY_ALPHA`), its silhouette outlined in green (red when the frame diverged), and
    the frame index with its RMS written in the corner."""
    model = fitter.model
    st = _state_of(rec)
    Wv = model.vertex_weights(model.region_weights(st.alpha))
    r = render_model(renderer or fitter.renderer, fitter.camera(st), model, model.blend_geometry(Wv), Wv,
                     background=frame)  # fmt: skip
    out = frame.copy()
    m = r.mask
    out[m] = (1 - OVERLAY_ALPHA) * frame[m] + OVERLAY_ALPHA * r.image[m]
    img = np.round(np.clip(out, 0, 1) * 255).astype(np.uint8)
    # closed first: the model's cracks (triangles dropped at texture-atlas seams) are not silhouette
    closed = cv2.morphologyEx(m.astype(np.uint8), cv2.MORPH_CLOSE, np.ones((5, 5), np.uint8))
    contours, _ = cv2.findContours(closed, cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_NONE)
    color = (230, 40, 40) if rec["diverged"] else (40, 220, 60)
    cv2.drawContours(img, contours, -1, color, 1, cv2.LINE_AA)
    cv2.putText(img, f"{rec['frame']}  rms {rec['rms']:.3f}", (6, 16), cv2.FONT_HERSHEY_SIMPLEX, 0.45,
                (255, 255, 255), 1, cv2.LINE_AA)  # fmt: skip
    return img.astype(np.float32) / 255.0


def write_overlay_video(path: str | os.PathLike, video: VideoFrames, fitter: FrameFitter, frames: list[dict],
                        fps: float | None = None) -> np.ndarray | None:  # fmt: skip
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


# ----------------------------------------------------------------------------- batch


@dataclass
class TrackResult:
    """What :func:`track_video` did.

    Attributes
    ----------
    out_dir : Path
    frames : list of dict, every saved frame record (earlier runs' included), in frame order.
    resumed_from : int, frames already in ``out_dir`` when this run started.
    tracked : int, frames tracked by this run.
    complete : bool, the whole video (or its first ``max_frames``) is tracked; ``track.json``'s
        ``complete`` says whether the whole video is.
    cancelled : bool, stopped by ``cancel()``.
    seconds : float, fitting time of this run.
    files : dict name → Path of the files written.
    corrected : int or None, the frame this run corrected (re-tracked from the user's pose), if any.
    """

    out_dir: Path
    frames: list
    resumed_from: int
    tracked: int
    complete: bool
    cancelled: bool
    seconds: float
    files: dict
    corrected: int | None = None

    @property
    def fps(self) -> float:
        return self.tracked / self.seconds if self.seconds > 0 else 0.0

    @property
    def diverged(self) -> int:
        return sum(bool(f["diverged"]) for f in self.frames)


def _settings_differ(old: dict, new: dict) -> list[str]:
    """Names of the settings (video, camera, model, first pose, options) that differ."""
    differ = []
    for key in ("video", "camera", "model", "first_pose", "options"):
        a, b = old.get(key), json.loads(json.dumps(new.get(key)))
        if key == "video":  # the frame count may be learnt later; the path and size decide
            a = {k: (a or {}).get(k) for k in ("path", "width", "height")}
            b = {k: b.get(k) for k in ("path", "width", "height")}
        elif key == "first_pose":  # what it says, not where it was read from (a file or the recorded JSON)
            a, b = (a or {}).get("spec"), b.get("spec")
        if a != b:
            differ.append(key)
    return differ


def _check_corrections(corrections, path: Path) -> list[dict]:
    """The ``corrections`` of a ``track.json`` (list of ``{frame, source, spec}``), checked."""
    if corrections is None:
        return []
    ok = isinstance(corrections, list) and all(
        isinstance(c, dict) and type(c.get("frame")) is int and c["frame"] >= 0 and isinstance(c.get("spec"), dict)
        for c in corrections
    )  # fmt: skip
    if not ok:
        raise FaceStudioError(f"{path}: 'corrections' must be a list of {{frame, source, spec}}; pass --restart")
    return sorted(corrections, key=lambda c: c["frame"])


def _check_correct_frame(frame, tracked: int, max_frames: int | None, path: Path) -> int:
    """``frame`` as the index of a tracked frame a correction may restart from; FaceStudioError otherwise."""
    if isinstance(frame, bool) or not isinstance(frame, (int, np.integer)):
        raise FaceStudioError(f"the frame to correct must be a frame index (an integer), got {frame!r}")
    frame = int(frame)
    if tracked == 0:
        raise FaceStudioError(f"{path}: no frames tracked yet, nothing to correct; track the video first")
    if not 0 <= frame < tracked:
        raise FaceStudioError(f"frame {frame} is out of range: {path} holds frames 0..{tracked - 1}; correct one of "
                              f"those (track further first to reach a later frame)")  # fmt: skip
    if max_frames is not None and frame >= max_frames:
        raise FaceStudioError(f"frame {frame} is beyond the frame limit {max_frames} (frames 0..{max_frames - 1})")
    return frame


def track_video(
    project_path: str | os.PathLike,
    video: str | os.PathLike,
    out_dir: str | os.PathLike | None = None,
    *,
    model: FaceModel | None = None,
    model_source: str | None = None,
    expressions=None,
    first_pose: dict | str | os.PathLike | None = None,
    focal_px: float | None = None,
    max_frames: int | None = None,
    options: TrackOptions | None = None,
    save_every: int = SAVE_EVERY,
    restart: bool = False,
    correct_frame: int | None = None,
    correct_pose: dict | str | os.PathLike | None = None,
    plots: bool = True,
    overlay: bool = True,
    progress: Callable[[int, int | None], None] | None = None,
    cancel: Callable[[], bool] | None = None,
) -> TrackResult:
    """Track ``video`` with the face model of the project at ``project_path``; write the results.

    Parameters
    ----------
    project_path : the project file (``*.facestudio.json``).
    video : a video file or a folder of PNG/JPG frames (:class:`VideoFrames`).
    out_dir : output folder (default ``<project folder>/results/track_<video stem>``); created.
    model, model_source : the face model and a sentence on its origin (default
        :func:`project_face_model` of the project's ``expressions``, default all, neutral first).
    first_pose : first-pose JSON path or dict (:func:`load_first_pose`); default
        :func:`default_first_pose_path`.
    focal_px : the video camera's focal length in pixels, overriding the first-pose file's.
    max_frames : track frames 0 .. max_frames − 1 only (a later run may raise it and continue).
    options : :class:`tracking.frame_fit.TrackOptions`.
    save_every : write the results after every this many frames.
    restart : discard results of other settings in ``out_dir`` instead of refusing to continue.
    correct_frame, correct_pose : the user's correction of a tracked frame N = ``correct_frame``
        (both or neither): ``correct_pose`` is frame N's pose in the first-pose format (a path or the
        parsed dict, :func:`load_first_pose`: usually ≥ 6 features clicked in frame N; its focal
        length, if given, must be the run's). The results in ``out_dir`` (same settings) keep frames
        0 .. N−1 unchanged; frame N is fitted from that pose in several rounds, like frame 0
        (:func:`tracking.frame_fit.track_frames`' ``first_rounds``), and recorded with ``start: "user"``;
        the frames after it are tracked from there as usual. ``track.json`` keeps the list of
        corrections (``corrections``: frame, source, spec); corrections of frames ≥ N are dropped
        with those frames. Prediction does not reach back across a corrected frame (frame N + 1
        starts from frame N alone, like frame 1 from frame 0), so a later rerun continues exactly.
    plots, overlay : write the plots (at the end of every run, cancelled or not) and the overlay
        video (only once the video, or its first ``max_frames``, is tracked).
    progress : ``progress(done, total)`` after each frame (``total`` None if the video does not say).
    cancel : ``cancel() -> bool`` checked after each frame; True saves and stops.

    Returns
    -------
    TrackResult

    Raises
    ------
    ProjectError, VideoError, FitError, FaceStudioError naming what is wrong (a correction: no
    results to correct, the frame out of range or beyond the tracked frames, a malformed pose file);
    KeyboardInterrupt after saving the frames tracked so far.
    """
    from photomodel.project import load_project

    if (correct_frame is None) != (correct_pose is None):
        raise FaceStudioError("a correction needs both the frame (--correct) and its pose (--pose)")
    if correct_frame is not None and restart:
        raise FaceStudioError("--restart discards the results a correction keeps: restart or correct, not both")
    project = load_project(project_path)
    frames_in = VideoFrames(video)
    if model is None:
        model, model_source = project_face_model(project, expressions)
    model_source = model_source or "given by the caller"
    if first_pose is None:
        first_pose = default_first_pose_path(frames_in.path)
    fp = load_first_pose(first_pose, project, model, frames_in.width, frames_in.height, focal_px)
    options = options or TrackOptions()
    if max_frames is not None and max_frames < 1:
        raise FaceStudioError(f"the frame limit must be at least 1, got {max_frames}")
    out = Path(out_dir).absolute() if out_dir is not None else default_out_dir(project_path, video)
    json_path = out / "track.json"

    regions = [r for r, a in zip(CONTROL_REGIONS, model.n_alpha, strict=True) if a]
    doc = {
        "format": FORMAT,
        "version": VERSION,
        "project": str(Path(project_path).absolute()),
        "video": {"path": str(frames_in.path), "kind": "frames" if frames_in.is_folder else "file",
                  "width": frames_in.width, "height": frames_in.height, "fps": frames_in.fps,
                  "frames": frames_in.count},  # fmt: skip
        "camera": {"focal_px": fp.focal_px, "width": frames_in.width, "height": frames_in.height,
                   "convention": "X_cam = R X + t (head frame, mm); pixel centres at integers"},  # fmt: skip
        "model": {"source": model_source, "expressions": list(model.names), "regions": list(CONTROL_REGIONS),
                  "regions_with_parameters": regions, "n_alpha": list(model.n_alpha),
                  "centre_mm": np.asarray(model.centre, float).tolist()},  # fmt: skip
        "first_pose": {"source": fp.source, "spec": fp.spec},
        "options": asdict(options),
        "max_frames": max_frames,
        "complete": False,
        "corrections": [],
        "frames": [],
    }
    old = None if restart else load_track_results(out)
    if old is not None:
        differ = _settings_differ(old, doc)
        if differ:
            raise FaceStudioError(f"{json_path} holds tracking with other settings (different "
                                  f"{', '.join(differ)}); pass --restart to start over or choose another --out")
        doc["frames"] = old["frames"]
        doc["first_pose"] = old["first_pose"]  # the same JSON: keep naming the file it first came from
        doc["corrections"] = _check_corrections(old.get("corrections"), json_path)
    elif correct_frame is not None:
        raise FaceStudioError(f"{out} holds no tracking results to correct: track the video first")
    records: list[dict] = doc["frames"]
    if any(r["frame"] != i for i, r in enumerate(records)):
        raise FaceStudioError(f"{json_path}: the frame records are not consecutive from 0; pass --restart")
    # where fits start from a pose instead of the prediction: frame 0 and the user's corrections
    size = (frames_in.width, frames_in.height)
    if correct_frame is not None:
        correct_frame = _check_correct_frame(correct_frame, len(records), max_frames, json_path)
        spec, where = _read_pose_spec(correct_pose, correct_frame)
        given = _spec_focal(spec, where, frames_in.width)
        if given is not None and abs(given - fp.focal_px) > 1e-9 * fp.focal_px:
            raise FitError(f"{where}: focal length {given} px, but the video camera of these results has "
                           f"{fp.focal_px} px (one camera per video; leave the focal length out)")  # fmt: skip
        cp = _pose_from_spec(spec, where, project, model, *size, fp.focal_px, correct_frame)
        del records[correct_frame:]
        doc["corrections"] = [c for c in doc["corrections"] if c["frame"] < correct_frame]
        doc["corrections"].append({"frame": correct_frame, "source": cp.source, "spec": cp.spec})
    start = len(records)
    starts = {0: ("first_pose", fp)}
    for c in doc["corrections"]:
        starts[c["frame"]] = ("user", None)
    # poses of the corrections still ahead (the one just given, or one whose frame an interrupted
    # run did not reach): solved from their recorded JSON, as when they were given
    for c in doc["corrections"]:
        if c["frame"] >= start:
            where = f"{json_path}: correction of frame {c['frame']}"
            starts[c["frame"]] = ("user", _pose_from_spec(c["spec"], where, project, model, *size, fp.focal_px,
                                                          c["frame"]))  # fmt: skip
    out.mkdir(parents=True, exist_ok=True)
    files = {"json": json_path, "csv": out / "track.csv"}

    def save(complete: bool) -> None:
        doc["complete"] = complete
        # CSV first: the JSON (what a continuation reads) is never ahead of what it lists
        atomic_write_bytes(files["csv"], _csv_bytes(records, regions, list(model.names)))
        atomic_write_bytes(files["json"], json.dumps(doc, indent=1).encode())

    fitter = FrameFitter(model, fp.focal_px, frames_in.width, frames_in.height, options)
    total = frames_in.count if max_frames is None else (
        max_frames if frames_in.count is None else min(max_frames, frames_in.count))  # fmt: skip
    # the prediction restored from the last two saved frames, not reaching back across a start
    anchor = max((f for f in starts if f < start), default=0)
    states = [_state_of(r) for r in records[max(anchor, start - 2) : start]]
    cancelled, ended, seconds = False, False, 0.0
    unsaved = 0
    try:
        it = frames_in.frames(start, max_frames)
        for i, frame in it:
            t0 = time.perf_counter()
            if i in starts:  # fitted from the pose in several rounds (track_frames' first_rounds)
                kind, pose = starts[i]
                (res,) = track_frames(fitter, [frame], pose.state)
                states = []
            else:
                kind = "predicted"
                (res,) = track_frames(fitter, [frame], fp.state, previous=states)
            dt = time.perf_counter() - t0
            seconds += dt
            records.append(frame_record(i, res, model, dt, kind))
            states = (states + [res.state])[-2:]
            unsaved += 1
            if unsaved >= save_every:
                save(False)
                unsaved = 0
            if progress is not None:
                progress(i + 1, total)
            if cancel is not None and cancel():
                cancelled = True
                break
        else:
            ended = True
    except KeyboardInterrupt:
        save(False)
        raise
    # a finished loop stopped at the frame limit or at the end of the video
    n = len(records)
    whole = ended and (max_frames is None or n < max_frames or (frames_in.count is not None and n >= frames_in.count))
    if whole:
        doc["video"]["frames"] = n
    save(whole)
    complete = ended
    if plots and records:
        for name, img in track_plots(records, regions, list(model.names), DIVERGED_RMS).items():
            files[name.removesuffix(".png")] = atomic_write_bytes(out / name, encode_png(img))
    if overlay and complete and records:
        last = write_overlay_video(out / "overlay.mp4", frames_in, fitter, records)
        files["overlay"] = out / "overlay.mp4"
        if last is not None:
            files["overlay_last"] = atomic_write_bytes(out / "overlay_last.png", encode_png(last))
    return TrackResult(out, records, start, len(records) - start, complete, cancelled, seconds, files, correct_frame)
