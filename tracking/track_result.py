"""The tracking results of one video: ``track.json`` and ``track.csv`` in a results folder.

* ``track.json`` (:data:`FORMAT`, :data:`VERSION`) — the run's settings (``project``, ``video``,
  ``camera``, ``model``, ``first_pose``, ``options``, ``max_frames``), ``complete`` (the whole video
  is tracked), the user's ``corrections`` (frame, source, the pose JSON given) and one record per
  frame (:func:`frame_record`) at full precision: the source of truth for continuing a run.
* ``track.csv`` — one row per frame (:data:`CSV_COLUMNS` around the weights), for spreadsheets.

Both are written atomically (:func:`save_results`: temporary file, fsync, :func:`os.replace`), the CSV
first, so the files on disk are always complete and valid for the frames they list. A run continues
the results of the same settings (:func:`continue_results`); other settings are refused.
"""

from __future__ import annotations

import csv
import io
import json
import os
from dataclasses import asdict
from pathlib import Path

import numpy as np

from photomodel.camera import rotation_vector
from photomodel.errors import FaceStudioError
from photomodel.exchange.files import atomic_write_bytes
from tracking.blendshape_face import CONTROL_REGIONS, FaceModel
from tracking.frame_fit import FrameState, TrackOptions

__all__ = [
    "FORMAT",
    "VERSION",
    "FACING",
    "CSV_COLUMNS",
    "STARTS",
    "default_out_dir",
    "new_results",
    "continue_results",
    "record_correction",
    "frame_record",
    "state_of",
    "csv_bytes",
    "save_results",
    "load_track_results",
]

FORMAT = "facestudio-track"
VERSION = 1
#: Head rotation of a face looking straight at the camera (head +y up → camera −y, +z out of the
#: face → towards the camera); plotted angles are relative to it.
FACING = np.diag([1.0, -1.0, -1.0])


def default_out_dir(project_path: str | os.PathLike, video: str | os.PathLike) -> Path:
    """``<project folder>/results/track_<video stem>`` (absolute)."""
    return Path(project_path).absolute().parent / "results" / f"track_{Path(video).absolute().stem}"


def new_results(
    project_path: str | os.PathLike,
    video,
    model: FaceModel,
    model_source: str,
    first_pose,
    options: TrackOptions,
    max_frames: int | None,
) -> dict:
    """The ``track.json`` document of a run with no frames yet: its settings.

    ``video``: the :class:`photomodel.photos.video.VideoFrames` tracked; ``first_pose``: its
    :class:`tracking.first_pose.FirstPose`; the others as :func:`tracking.run.track_video` takes them.
    """
    regions = [r for r, a in zip(CONTROL_REGIONS, model.n_alpha, strict=True) if a]
    shared = model.shared_expressions
    return {
        "format": FORMAT,
        "version": VERSION,
        "project": str(Path(project_path).absolute()),
        "video": {
            "path": str(video.path),
            "kind": "frames" if video.is_folder else "file",
            "width": video.width,
            "height": video.height,
            "fps": video.fps,
            "frames": video.count,
        },
        "camera": {
            "focal_px": first_pose.focal_px,
            "width": video.width,
            "height": video.height,
            "convention": "X_cam = R X + t (head frame, mm); pixel centres at integers",
        },
        "model": {
            "source": model_source,
            "expressions": [n for n, s in zip(model.names, shared, strict=True) if not s],
            "arkit": [n for n, s in zip(model.names, shared, strict=True) if s],
            "regions": list(CONTROL_REGIONS),
            "regions_with_parameters": regions,
            "n_alpha": list(model.n_alpha),
            "n_shared": model.n_shared,
            "centre_mm": np.asarray(model.centre, float).tolist(),
        },
        "first_pose": {"source": first_pose.source, "spec": first_pose.spec},
        "options": asdict(options),
        "max_frames": max_frames,
        "complete": False,
        "corrections": [],
        "frames": [],
    }


def continue_results(doc: dict, old: dict, path: Path) -> None:
    """Take into the new run's ``doc`` (:func:`new_results`) the frames and corrections of the
    results ``old`` read from ``path``, which must have the same settings.

    Raises FaceStudioError when the settings differ (naming them), or the corrections or the frame
    records are malformed.
    """
    differ = _settings_differ(old, doc)
    if differ:
        raise FaceStudioError(
            f"{path} holds tracking with other settings (different "
            f"{', '.join(differ)}); pass --restart to start over or choose another --out"
        )
    doc["frames"] = old["frames"]
    doc["first_pose"] = old["first_pose"]  # the same JSON: keep naming the file it first came from
    doc["corrections"] = _check_corrections(old.get("corrections"), path)
    if any(r["frame"] != i for i, r in enumerate(doc["frames"])):
        raise FaceStudioError(f"{path}: the frame records are not consecutive from 0; pass --restart")


def record_correction(doc: dict, frame: int, source: str, spec: dict) -> None:
    """The user's correction of ``frame``: drop the records from ``frame`` on and the corrections of
    those frames, and record this one (``{frame, source, spec}``)."""
    del doc["frames"][frame:]
    doc["corrections"] = [c for c in doc["corrections"] if c["frame"] < frame]
    doc["corrections"].append({"frame": frame, "source": source, "spec": spec})


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
    )
    if not ok:
        raise FaceStudioError(f"{path}: 'corrections' must be a list of {{frame, source, spec}}; pass --restart")
    return sorted(corrections, key=lambda c: c["frame"])


#: Columns of ``track.csv`` before the weights (``w_<region>_<expression>``) and after them.
CSV_COLUMNS = (
    [
        "frame",
        "rx_rad",
        "ry_rad",
        "rz_rad",
        "pitch_deg",
        "yaw_deg",
        "roll_deg",
        "tx_mm",
        "ty_mm",
        "tz_mm",
        "cx_mm",
        "cy_mm",
        "cz_mm",
    ],
    ["rms", "pixels", "diverged", "steps", "evaluations", "seconds", "start"],
)
#: Where a frame's fit started (a record's ``start``): the first pose (frame 0), the prediction from
#: the frames before (§6.2), a pose the user gave for that frame (a correction), or the landmark
#: detector's pose when the track had lost the face (:mod:`tracking.detected_pose`).
STARTS = ("first_pose", "predicted", "user", "detected")


def frame_record(index: int, result, model: FaceModel, seconds: float, start: str = "predicted") -> dict:
    """One frame's JSON record.

    Keys: ``frame``; ``rotation_vector`` (3,) rad and ``R`` (3, 3) with ``t_mm`` (3,):
    ``X_cam = R X + t`` for head-frame points X (the project's camera convention); ``centre_mm``
    (3,): the model centre in camera space; ``head_rotation_deg`` (3,): rotation vector of
    ``R · FACINGᵀ`` in degrees (pitch, yaw, roll about the camera axes); ``alpha``: the expression
    parameters (concatenated per region); ``weights`` {region: {expression: w}} of each control
    region (rest excluded: it is always neutral) over the photographed expressions; ``arkit``
    {shape: w in [0, 1]} the rig's shapes' weights when the model has them (:mod:`tracking.arkit_face`,
    else empty); ``rms`` (image RMS, intensity in [0, 1]),
    ``pixels`` covered, ``diverged``, ``steps`` (accepted LM steps), ``evaluations`` (renderings),
    ``seconds``; ``start``: where the fit started (:data:`STARTS`: ``"first_pose"``,
    ``"predicted"``, ``"user"`` for a corrected frame, ``"detected"`` for a frame fitted again from
    the detector's pose). :func:`tracking.run.track_video` adds ``landmarks_xy``
    {feature: [u, v]} px, the model's projected pose features, and ``colour_match`` [[gain ×3],
    [offset ×3]] — the footage's colour match after the frame
    (:attr:`tracking.frame_fit.TrackOptions.colour_match`; absent before the first). Floats at full
    precision: a run continues from them exactly.
    """
    if start not in STARTS:
        raise ValueError(f"start must be one of {STARTS}, got {start!r}")
    st = result.state
    R = np.asarray(st.R, float)
    shared = model.shared_expressions
    arkit = {}
    if model.n_shared:
        row = np.asarray(result.weights, float)[-1]
        arkit = {n: float(np.clip(row[k], 0.0, 1.0)) for k, n in enumerate(model.names) if shared[k]}
    return {
        "frame": int(index),
        "rotation_vector": rotation_vector(R).tolist(),
        "R": R.tolist(),
        "t_mm": (st.t - R @ model.centre).tolist(),
        "centre_mm": np.asarray(st.t, float).tolist(),
        "head_rotation_deg": np.degrees(rotation_vector(R @ FACING.T)).tolist(),
        "alpha": np.asarray(st.alpha, float).tolist(),
        "weights": {
            r: {n: float(w) for n, w, s in zip(model.names, result.weights[i], shared, strict=True) if not s}
            for i, r in enumerate(CONTROL_REGIONS)
            if i
        },
        "arkit": arkit,
        "rms": float(result.rms),
        "pixels": int(result.pixels),
        "diverged": bool(result.diverged),
        "steps": len(result.history),
        "evaluations": int(result.evaluations),
        "seconds": float(seconds),
        "start": start,
    }


def state_of(rec: dict) -> FrameState:
    return FrameState(np.array(rec["R"], float), np.array(rec["centre_mm"], float), np.array(rec["alpha"], float))


def csv_bytes(frames: list[dict], regions: list[str], names: list[str], arkit: list[str] = ()) -> bytes:
    """``track.csv``: :data:`CSV_COLUMNS` around the weights ``w_<region>_<expression>`` and the
    ARKit shapes' ``arkit_<shape>`` (when the track has them)."""
    head, tail = CSV_COLUMNS
    wcols = [(r, e) for r in regions for e in names]
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(head + [f"w_{r}_{e}" for r, e in wcols] + [f"arkit_{n}" for n in arkit] + tail)
    for f in frames:
        row = [f["frame"], *f["rotation_vector"], *f["head_rotation_deg"], *f["t_mm"], *f["centre_mm"]]
        row += [f["weights"][r][e] for r, e in wcols]
        row += [f.get("arkit", {}).get(n, 0.0) for n in arkit]
        row += [
            f["rms"],
            f["pixels"],
            int(f["diverged"]),
            f["steps"],
            f["evaluations"],
            f["seconds"],
            f.get("start", ""),
        ]
        w.writerow([repr(v) if isinstance(v, float) else v for v in row])
    return buf.getvalue().encode()


def save_results(out_dir: Path, doc: dict, complete: bool) -> dict[str, Path]:
    """Write ``doc`` as ``track.json`` and its frames as ``track.csv`` into ``out_dir``, atomically,
    the CSV first: the JSON (what a continuation reads) is never ahead of what the CSV lists.
    Sets ``doc["complete"]``. Returns ``{"json": path, "csv": path}``."""
    files = {"json": out_dir / "track.json", "csv": out_dir / "track.csv"}
    doc["complete"] = complete
    model = doc["model"]
    table = csv_bytes(doc["frames"], model["regions_with_parameters"], model["expressions"], model.get("arkit", []))
    atomic_write_bytes(files["csv"], table)
    atomic_write_bytes(files["json"], json.dumps(doc, indent=1).encode())
    return files


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
        raise FaceStudioError(
            f"{path}: tracking file version {doc.get('version')} (this Face Studio writes {VERSION}); pass --restart"
        )
    return doc
