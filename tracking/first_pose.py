"""The first-pose file: the first frame's pose of a video, the user's part of tracking (§6.2).

A JSON object (:func:`load_first_pose`) with the video camera's focal length and either a pose or
the image positions of at least six of the project's features in the frame (solved by
:func:`tracking.frame_fit.pose_from_clicks`), optionally a start expression. By default it is
``<video stem>.first_pose.json`` beside a video file, or ``first_pose.json`` in a frame folder
(:func:`default_first_pose_path`); the sample video ships one (13 clicks with 0.5 px noise).

The same format gives a user's correction of a later tracked frame (``frame`` > 0: only the
messages change); :func:`read_pose_spec`, :func:`spec_focal` and :func:`pose_from_spec` are the
steps of :func:`load_first_pose`, used apart when a correction is checked against a run's camera.
"""

from __future__ import annotations

import json
import math
import os
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from photomodel.camera import focal_mm_to_px, rodrigues
from photomodel.errors import FaceStudioError, FitError
from tracking.blendshape_face import CONTROL_REGIONS, FaceModel
from tracking.frame_fit import FrameState, pose_from_clicks

__all__ = ["FirstPose", "default_first_pose_path", "load_first_pose", "read_pose_spec", "spec_focal", "pose_from_spec"]


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


def _vector(spec: dict, key: str, shape: tuple, where: str) -> np.ndarray:
    try:
        a = np.asarray(spec[key], float)
    except (TypeError, ValueError) as exc:
        raise FitError(f"{where}: {key!r} must be numbers of shape {shape}") from exc
    if a.shape != shape or not np.all(np.isfinite(a)):
        raise FitError(f"{where}: {key!r} must be finite numbers of shape {shape}, got {spec[key]!r}")
    return a


def read_pose_spec(spec: dict | str | os.PathLike, frame: int = 0) -> tuple[dict, str]:
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
            raise FitError(
                f"the first-pose file {path} does not exist: write the first frame's pose or clicks "
                f"there (see docs/tracking.md; `facestudio track` also takes one as --first-pose FILE)"
            )
        raise FitError(
            f"the pose file {path} does not exist: write frame {frame}'s pose or clicks there "
            f"(the first-pose format, see docs/tracking.md)"
        )
    try:
        spec = json.loads(path.read_text())
    except (OSError, ValueError) as exc:
        raise FitError(f"{path}: not a JSON {kind} file: {exc}") from exc
    if not isinstance(spec, dict):
        raise FitError(f"{path}: the {kind} file must hold a JSON object")
    return spec, str(path)


def spec_focal(spec: dict, where: str, width: int) -> float | None:
    """The focal length (px) a pose JSON gives (``focal_px``, or ``focal_mm`` on a 36 mm-wide sensor); None if none."""
    if "focal_px" in spec:
        return float(_vector(spec, "focal_px", (), where))
    if "focal_mm" in spec:
        return focal_mm_to_px(float(_vector(spec, "focal_mm", (), where)), width)
    return None


def load_first_pose(
    spec: dict | str | os.PathLike,
    project,
    model: FaceModel,
    width: int,
    height: int,
    focal_px: float | None = None,
    *,
    frame: int = 0,
) -> FirstPose:
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
    (:func:`tracking.run.track_video`'s ``correct_pose``); it only changes the messages. Raises
    :class:`FitError` naming the file and the field.
    """
    spec, where = read_pose_spec(spec, frame)
    return pose_from_spec(spec, where, project, model, width, height, focal_px, frame)


def pose_from_spec(
    spec: dict, where: str, project, model: FaceModel, width: int, height: int, focal_px: float | None, frame: int
) -> FirstPose:
    """:func:`load_first_pose` of a parsed JSON object named ``where`` in errors."""
    if focal_px is None:
        focal_px = spec_focal(spec, where, width)
        if focal_px is None:
            raise FitError(
                f"{where}: the video camera's focal length is missing: give 'focal_px' (or 'focal_mm' "
                f"for a 36 mm-wide sensor) or pass --focal-px"
            )
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
        R = (
            _vector(spec, "R", (3, 3), where)
            if "R" in spec
            else rodrigues(_vector(spec, "rotation_vector", (3,), where))
        )
        if not np.allclose(R @ R.T, np.eye(3), atol=1e-6) or np.linalg.det(R) < 0:
            raise FitError(f"{where}: 'R' is not a rotation matrix")
        if "t_mm" not in spec:
            raise FitError(f"{where}: a pose needs 't_mm' (X_cam = R X + t, mm) besides the rotation")
        t = _vector(spec, "t_mm", (3,), where)
        state = FrameState(R, t + R @ model.centre, np.zeros(model.n_params))
        source = f"{where}: pose given"
    else:
        raise FitError(
            f"{where}: give either 'clicks' (≥ 6 features of frame {frame}) or a pose ('R' or "
            f"'rotation_vector', and 't_mm')"
        )
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
                raise FitError(
                    f"{where}: 'weights.{r}' has unknown expression {e!r}; expressions: {', '.join(model.names[1:])}"
                )
            W[ri, model.names.index(e)] = float(w)
        W[ri, 0] = 1.0 - W[ri, 1:].sum()
    return W
