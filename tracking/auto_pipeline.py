"""From a phone clip to an ARKit-animated, textured face in one go: ``facestudio auto`` (no Qt).

:func:`run_auto` chains the stages a user runs by hand, each writing what the by-hand command
writes, into one folder ``DIR`` that the studio opens and where any stage can be redone by hand:

1. ``stills`` — frames picked from the clip (:func:`photomodel.photos.stills.new_project_from_video`,
   ``facestudio new --video``): ``DIR/<clip>.facestudio.json`` and ``DIR/<clip>_stills/``;
2. ``fit`` — cameras and mesh of every expression (``facestudio fit``);
3. ``texture`` — the cylindrical texture (``facestudio texture``);
4. ``rig`` — ICT-FaceKit's 51 ARKit shapes on the fitted neutral (``facestudio rig``);
5. ``track`` — the whole clip in ARKit terms (:mod:`tracking.arkit_face`, ``facestudio track
   --basis arkit``): ``DIR/results/track_<clip>/``; then the landmark error of every frame
   against the detector (:func:`tracking.detected_pose.detected_features`) and the frames lost
   and recovered (lost: the tracked features over :data:`tracking.detected_pose.LOST_PX` from the
   detector's, or no face found; recovered: tracked again within 10 frames);
6. ``export`` — the animated glb (its ARKit channels the tracked weights) and the Live Link CSV
   (:func:`tracking.performance.export_track`), read back (:func:`glb_summary`).

Resuming: a stage whose result is already in ``DIR`` is not run again (a project there, fits,
textures, a rig, the track — which :func:`tracking.run.track_video` continues after its last saved
frame). So Ctrl-C at any point leaves a project that opens, and running ``auto`` again goes on.
"""

from __future__ import annotations

import os
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from photomodel.alignment import similarity_transform
from photomodel.errors import FaceStudioError
from photomodel.exchange.gltf_animation import read_animated_weights
from photomodel.exchange.validator import validate_glb
from photomodel.modeling.fit import FitOptions, fit_expression, fit_order
from photomodel.modeling.generic_mesh import load_generic_mesh
from photomodel.modeling.mouth import expression_note
from photomodel.photos.intake import default_features
from photomodel.photos.stills import StillsError, new_project_from_video
from photomodel.photos.video import VideoFrames
from photomodel.project import (
    FILE_SUFFIX,
    load_project,
    read_fitted_mesh,
    record_fit,
    save_project,
    save_results,
    store_rig,
)
from photomodel.rig.build import RigBuilder
from photomodel.texturing.job import encode_texture_outputs, texture_expression
from tracking.detected_pose import LOST_PX, landmark_error_px, pose_features
from tracking.landmark_checks import LandmarkChecks
from tracking.performance import export_track
from tracking.run import track_video
from tracking.track_result import load_track_results

__all__ = ["STAGES", "AutoError", "AutoResult", "run_auto", "depth_ratio", "glb_summary", "lost_and_recovered"]

#: The stages, in order, with their share of the progress bar (rough wall-time shares).
STAGES = (("stills", 0.08), ("fit", 0.12), ("texture", 0.05), ("rig", 0.03), ("track", 0.67), ("export", 0.05))
#: The landmark figures (error against the detector, lost / recovered) check every this-many-th
#: tracked frame with the full detector (~40–90 ms a 640×360 frame: on every frame it took a
#: sixth of ``auto``'s time); a mean over a third of the frames.
LANDMARK_EVERY = 3
#: Texels per side of the texture ``auto`` extracts.
TEXTURE_SIZE = 1024


class AutoError(FaceStudioError):
    """The clip cannot make a face: the message names what was tried."""


@dataclass
class AutoResult:
    """What :func:`run_auto` did: the project, the track folder, the files and the figures
    (:meth:`as_dict` is ``facestudio auto --json``'s ``auto`` object)."""

    project: Path
    track_dir: Path
    glb: Path
    csv: Path | None
    stages: dict = field(default_factory=dict)
    skipped: list = field(default_factory=list)
    frames: int = 0
    track_fps: float = 0.0
    fit_rms_px: float = float("nan")
    depth_ratio: float = float("nan")
    landmark_err_px: float = float("nan")
    lost: int = 0
    recovered: int = 0
    glb_info: dict = field(default_factory=dict)
    total_s: float = 0.0
    #: (frames,) px each tracked frame's landmark error against the detector (NaN: no face found,
    #: or the frame was fitted again from the detector's pose).
    landmark_errors: np.ndarray | None = None
    #: What the neutral's fit says the user should know (:func:`photomodel.modeling.mouth.expression_note`:
    #: stills that all show an expression, so the neutral is fitted as that expression).
    notes: list = field(default_factory=list)

    def as_dict(self) -> dict:
        return {
            "total_s": round(self.total_s, 2),
            "stages": {f"{k}_s": round(v, 2) for k, v in self.stages.items()},
            "frames": self.frames,
            "track_fps": round(self.track_fps, 3),
            "fit_rms_px": _num(self.fit_rms_px),
            "depth_ratio": _num(self.depth_ratio),
            "landmark_err_px": _num(self.landmark_err_px),
            "lost": self.lost,
            "recovered": self.recovered,
            "glb": self.glb_info,
            "project": str(self.project),
            "track_dir": str(self.track_dir),
            "csv": None if self.csv is None else str(self.csv),
            "resumed_stages": list(self.skipped),
            "notes": list(self.notes),
        }


def _num(v: float):
    return None if v is None or not np.isfinite(v) else round(float(v), 4)


def depth_ratio(vertices: np.ndarray, mesh) -> float:
    """Depth extent of the fitted face after the similarity onto the generic mesh, over the generic
    mesh's (1.0: the generic head's proportions; as ``benchmarks/autofit.py`` measures it)."""
    face = mesh.face_mask
    s, R, t = similarity_transform(vertices[face], mesh.vertices[face])
    return float(np.ptp((vertices[face] @ (s * R).T + t)[:, 2]) / np.ptp(mesh.vertices[face][:, 2]))


def lost_and_recovered(err: np.ndarray, found: np.ndarray, every: int = 1) -> tuple[int, int]:
    """Lost frames (the detector finds the face but the tracked features are over
    :data:`~tracking.detected_pose.LOST_PX` from it, or it finds none) and how many of them are
    tracked again within 10 frames (as ``benchmarks/bench_track.py`` counts them); ``err`` and
    ``found`` are of every ``every``-th frame (the next checks within 10 frames decide)."""
    lost = (found & (err > LOST_PX)) | ~found
    ok = ~lost
    reach = max(1, 10 // max(int(every), 1))
    recovered = sum(bool(ok[i + 1 : i + 1 + reach].any()) for i in np.flatnonzero(lost))
    return int(lost.sum()), int(recovered)


def glb_summary(path: str | os.PathLike, arkit_names, validate: bool = True) -> dict:
    """The exported glb read back (pygltflib): ``targets``, ``frames``, ``validator_errors`` (the
    Khronos validator, :func:`photomodel.exchange.validator.validate_glb`; -1 when it is not
    installed) and ``arkit_channels_moving`` (ARKit targets whose animated weight varies by more
    than 0.05 over the frames)."""
    names, k, W = read_animated_weights(path)
    arkit = [i for i, n in enumerate(names) if n in set(arkit_names)]
    moving = int((np.ptp(W[:, arkit], axis=0) > 0.05).sum()) if arkit and len(W) else 0
    report = validate_glb(path) if validate else None
    return {
        "targets": k,
        "frames": len(W),
        "validator_errors": -1 if report is None else int(report["issues"]["numErrors"]),
        "arkit_channels_moving": moving,
    }


def _stage_clock(progress, result: AutoResult):
    """``stage(name)`` context timing a stage into ``result.stages`` and telling ``progress``."""
    starts = {}
    offset = {}
    acc = 0.0
    for name, share in STAGES:
        offset[name] = (acc, share)
        acc += share

    def tell(name: str, fraction: float, detail: str = "") -> None:
        a, share = offset[name]
        if progress is not None:
            progress(name, a + share * min(max(fraction, 0.0), 1.0), detail)

    def begin(name: str) -> None:
        starts[name] = time.perf_counter()
        tell(name, 0.0)

    def end(name: str) -> None:
        result.stages[name] = result.stages.get(name, 0.0) + time.perf_counter() - starts.pop(name)

    return begin, end, tell


@dataclass
class _Run:
    """What every stage of one :func:`run_auto` shares: the clip, the files, the result and the clock."""

    clip: Path
    video: VideoFrames
    project_path: Path
    track_dir: Path
    result: AutoResult
    mesh: object
    begin: Callable
    end: Callable
    tell: Callable
    cancel: Callable[[], bool] | None
    t_all: float


def run_auto(
    clip: str | os.PathLike,
    out_dir: str | os.PathLike | None = None,
    *,
    glb: str | os.PathLike | None = None,
    csv: str | os.PathLike | None = None,
    stills: int = 5,
    max_frames: int | None = None,
    validate: bool = True,
    progress: Callable[[str, float, str], None] | None = None,
    cancel: Callable[[], bool] | None = None,
) -> AutoResult:
    """Make, rig, track and export the face of ``clip`` into ``out_dir`` (see the module notes).

    Parameters
    ----------
    clip : a video file (or a folder of frames) OpenCV reads.
    out_dir : the folder of the project and every intermediate result (default ``<clip stem>_auto``
        beside the clip); a second run resumes what is there.
    glb, csv : the animated glb (default ``out_dir/<clip stem>.glb``) and the Live Link CSV
        (default ``out_dir/<clip stem>.csv``).
    stills : frames picked from the clip for the fit.
    max_frames : track only the first frames (tests; default the whole clip).
    validate : run the Khronos validator on the glb (when installed).
    progress : ``progress(stage, fraction of the whole, detail)``.
    cancel : ``cancel() -> bool``, checked between stages and between tracked frames: True stops
        there (KeyboardInterrupt) with what was done saved; a run again resumes.

    Raises
    ------
    AutoError when no usable face is in the clip (naming the frames looked at), or the fit cannot
    place one; KeyboardInterrupt after the running stage saved what it had.
    """
    run = _start(clip, out_dir, glb, csv, progress, cancel)
    _stills_stage(run, stills)
    _stop_if(cancel)
    project = load_project(run.project_path)
    names, neutral, vertices = _fit_stage(run, project)
    _stop_if(cancel)
    _texture_stage(run, project, names)
    _stop_if(cancel)
    _rig_stage(run, project, neutral, vertices)
    _stop_if(cancel)
    _track_stage(run, max_frames)
    _export_stage(run, validate)
    run.result.total_s = time.perf_counter() - run.t_all
    return run.result


def _start(clip, out_dir, glb, csv, progress, cancel) -> _Run:
    """Open the clip, name the files of ``out_dir`` (made if missing) and start the clock."""
    t_all = time.perf_counter()
    clip = Path(clip)
    video = VideoFrames(clip)  # VideoError naming the file when it cannot be read
    stem = video.path.stem if video.path.is_file() else video.path.name
    out = Path(out_dir) if out_dir is not None else video.path.parent / f"{stem}_auto"
    out.mkdir(parents=True, exist_ok=True)
    project_path = out / f"{stem}{FILE_SUFFIX}"
    track_dir = out / "results" / f"track_{stem}"
    glb = Path(glb) if glb is not None else out / f"{stem}.glb"
    csv = Path(csv) if csv is not None else out / f"{stem}.csv"
    result = AutoResult(project_path, track_dir, glb, csv)
    begin, end, tell = _stage_clock(progress, result)
    mesh = load_generic_mesh()
    return _Run(clip, video, project_path, track_dir, result, mesh, begin, end, tell, cancel, t_all)


def _stills_stage(run: _Run, stills: int) -> None:
    """1. Stills picked from the clip → a project (skipped when the project is there)."""
    run.begin("stills")
    if run.project_path.is_file():
        run.result.skipped.append("stills")
    else:
        features, curves = default_features(run.mesh)
        try:
            new_project_from_video(
                run.clip,
                run.project_path,
                features=features,
                curves=curves,
                count=stills,
                progress=lambda label, f: run.tell("stills", f, label),
            )
        except StillsError as exc:
            raise AutoError(
                f"no usable face in {run.clip}: {exc}. Tried: the landmark detector on frames spread over the "
                f"clip, the {stills} clearest unoccluded ones as stills"
            ) from exc
    run.end("stills")


def _fit_stage(run: _Run, project) -> tuple[list[str], str, np.ndarray]:
    """2. Fit every expression not fitted yet; the neutral's rms and depth ratio into the result.
    Returns the expressions in fit order, the neutral's name and its fitted vertices."""
    tell, result, mesh = run.tell, run.result, run.mesh
    run.begin("fit")
    names = fit_order(project, None)
    todo = [n for n in names if project.expression(n).result is None]
    if not todo:
        result.skipped.append("fit")
    fits = {}
    for i, name in enumerate(todo):
        try:
            res = fit_expression(
                project,
                name,
                mesh,
                FitOptions(),
                progress=lambda label, f, i=i, name=name: tell("fit", (i + f) / len(todo), f"{name}: {label}"),
            )
        except FaceStudioError as exc:
            raise AutoError(
                f"the stills of {run.clip} do not make a face: fitting {name!r} failed ({exc}); the stills and "
                f"their automatic clicks are in {run.project_path} (open it in the studio to correct them)"
            ) from exc
        record_fit(project, name, res)
        fits[name] = res.vertices
    if fits:
        save_results(project, fits=fits, faces=mesh.faces)
    neutral = names[0] if "neutral" not in names else "neutral"
    report = project.expression(neutral).result.report or {}
    result.fit_rms_px = float(report.get("rms_px", np.nan))
    result.notes = expression_note(report)
    vertices, _ = read_fitted_mesh(project, neutral)
    result.depth_ratio = depth_ratio(vertices, mesh)
    run.end("fit")
    return names, neutral, vertices


def _texture_stage(run: _Run, project, names: list[str]) -> None:
    """3. Texture every expression without a texture."""
    tell = run.tell
    run.begin("texture")
    untextured = [n for n in names if project.expression(n).result.texture is None]
    if not untextured:
        run.result.skipped.append("texture")
    prepared = []
    for i, name in enumerate(untextured):
        job = texture_expression(
            project,
            name,
            TEXTURE_SIZE,
            face_mask=run.mesh.face_mask,
            progress=lambda label, f, i=i, name=name: tell("texture", (i + f) / len(untextured), f"{name}: {label}"),
        )
        files, rel = encode_texture_outputs(project, job)
        prepared.append((job, files, rel))
    if prepared:
        save_results(project, textures=prepared)
    run.end("texture")


def _rig_stage(run: _Run, project, neutral: str, vertices: np.ndarray) -> None:
    """4. ICT-FaceKit's ARKit shapes onto the fitted neutral (skipped when rigged on that neutral)."""
    run.begin("rig")
    if project.rig is not None and project.rig.neutral == neutral:
        run.result.skipped.append("rig")
    else:
        run.tell("rig", 0.1, "ICT-FaceKit onto the fitted neutral")
        rig = RigBuilder(run.mesh).rig(vertices)
        store_rig(project, neutral=neutral, names=rig.names, deltas=rig.deltas, report=rig.report)
        save_project(project)
    run.end("rig")


def _track_stage(run: _Run, max_frames: int | None) -> None:
    """5. Track the clip in ARKit terms (continuing a saved track; skipped when it is complete),
    then the landmark figures — whose detections are found while the clip is tracked
    (:class:`tracking.landmark_checks.LandmarkChecks`). A cancel stops here with
    KeyboardInterrupt, the frames done saved."""
    result, video, track_dir, tell = run.result, run.video, run.track_dir, run.tell
    run.begin("track")
    done = load_track_results(track_dir) if track_dir.is_dir() else None
    total = video.count if max_frames is None else min(max_frames, video.count or max_frames)
    tracked = 0 if done is None else len(done["frames"])
    checks = LandmarkChecks(run.clip, pose_features(load_project(run.project_path)), LANDMARK_EVERY, total)
    try:
        if done is not None and (done.get("complete") or (total is not None and tracked >= total)):
            result.skipped.append("track")
            records = done["frames"]
            track_fps = 0.0
        else:
            tr = track_video(
                run.project_path,
                run.clip,
                track_dir,
                basis="arkit",
                max_frames=max_frames,
                progress=lambda n, tot: tell("track", n / tot if tot else 0.0, f"frame {n} of {tot or '?'}"),
                cancel=run.cancel,
            )
            records, track_fps = tr.frames, tr.fps
            if tr.cancelled:
                run.end("track")
                result.frames, result.track_fps = len(records), track_fps
                result.total_s = time.perf_counter() - run.t_all
                raise KeyboardInterrupt
        result.frames, result.track_fps = len(records), track_fps
        tell("track", 0.97, "landmark error against the detector")
        _landmark_figures(result, checks.detections(len(records)), records)
    finally:
        checks.stop()
    run.end("track")


def _export_stage(run: _Run, validate: bool) -> None:
    """6. The animated glb and the Live Link CSV, the glb read back into ``result.glb_info``."""
    result = run.result
    run.begin("export")
    doc = load_track_results(run.track_dir)
    info = export_track(load_project(run.project_path), doc, result.glb, result.csv)
    summary = glb_summary(result.glb, info["rig_names"], validate=validate)
    result.glb_info = {
        "targets": summary["targets"],
        "expected_targets": info["targets"],
        "frames": summary["frames"],
        "expected_frames": len(doc["frames"]),
        "validator_errors": summary["validator_errors"],
        "arkit_channels_moving": summary["arkit_channels_moving"],
    }
    run.end("export")
    run.tell("export", 1.0, "done")


def _stop_if(cancel) -> None:
    """Between stages: a cancel asked for stops here (what the stage wrote is saved)."""
    if cancel is not None and cancel():
        raise KeyboardInterrupt


def _landmark_figures(result: AutoResult, detections: dict[int, dict | None], records: list[dict]) -> None:
    """The tracked frames' landmark error against the detector's features ``detections`` ({i:
    features or None (no face)} of every :data:`LANDMARK_EVERY`-th frame): mean over the frames
    fitted from the prediction where the detector finds the face, and the lost / recovered counts."""
    if not records:
        return
    names = list(records[0].get("landmarks_xy") or [])
    if not names:
        return
    checked = [i for i in sorted(detections) if i < len(records)]
    found = np.array([detections[i] is not None for i in checked], bool)
    err = np.array(
        [landmark_error_px(records[i]["landmarks_xy"], detections[i]) if detections[i] else np.nan for i in checked],
        float,
    )
    kept = np.array([records[i].get("start") == "predicted" for i in checked], bool) & found
    result.landmark_errors = np.full(len(records), np.nan)
    result.landmark_errors[checked] = np.where(kept, err, np.nan)
    if kept.any():
        result.landmark_err_px = float(np.nanmean(err[kept]))
    result.lost, result.recovered = lost_and_recovered(np.nan_to_num(err, nan=np.inf), found, LANDMARK_EVERY)
