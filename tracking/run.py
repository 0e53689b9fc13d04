"""Tracking one video of a project, cancel-safe and resumable: ``facestudio track`` (Pighin et al. 2002, §6.2).

:func:`track_video` reads the footage (:mod:`photomodel.photos.video`), fits the face model to every frame with
:class:`tracking.frame_fit.FrameFitter` (pose, then expression; each frame predicted from the two before,
§6.2) and writes into an output folder:

* ``track.json`` and ``track.csv`` — the run's settings and one record per frame
  (:mod:`tracking.track_result`); ``track.json`` is the source of truth for continuing;
* ``weights.png``, ``rotation.png``, ``translation.png``, ``rms.png`` — plots like Figs. 12–19
  (:mod:`tracking.plots`);
* ``overlay.mp4`` — the model rendered over the footage, alpha blended, with its silhouette
  outlined (written when the whole video is tracked), and ``overlay_last.png``, its last frame
  (:mod:`tracking.overlay_video`).

Cancel-safe and resumable: the results are written atomically every :data:`SAVE_EVERY` frames
(less often once writing the growing file would cost more than 1/:data:`SAVE_OVERHEAD` of the
fitting), when ``cancel()`` says stop and on Ctrl-C, so the files on disk are always complete and valid for
the frames they list. A second run with the same settings on the same folder continues after the
last saved frame, its prediction restored from the last two saved frames (the JSON keeps the
parameters at full precision, so a resumed run computes what an uninterrupted one would). Other
settings in the folder are refused unless ``restart``.

Correcting a frame: when frame N diverged or drifted, ``correct_frame=N`` with ``correct_pose`` (that
frame's clicks or pose, the first-pose format) keeps frames 0 .. N−1, fits frame N from the user's
pose in several rounds like frame 0, and tracks on from there; ``track.json`` records the correction
(``corrections``) so that continuing reproduces it (see :func:`track_video`).

Where the pieces come from
--------------------------
* **Video**: a file OpenCV decodes or a folder of PNG/JPG frames (:class:`photomodel.photos.video.VideoFrames`).
* **Face model**: with a rig (``facestudio rig``), by default the neutral and the rig's ARKit shapes
  (``basis="arkit"``, :mod:`tracking.arkit_face`; ``"both"`` adds the photographed expressions per
  region); without one, or with ``basis="photographed"``, the blend-shape model of the project's
  fitted and textured expressions (:func:`tracking.face_from_project.project_face_model`;
  ``facestudio fit`` then ``facestudio texture`` make them), recorded with its source and basis in
  ``track.json``. A caller may pass its own :class:`tracking.blendshape_face.FaceModel` with a
  ``model_source``.
* **First frame's pose** (the user's part, §6.2): a JSON file (:mod:`tracking.first_pose`) with the
  video camera's focal length and either a pose or the image positions of at least six of the
  project's features in frame 0; by default ``<video stem>.first_pose.json`` beside a video file,
  or ``first_pose.json`` in a frame folder — and when there is none, the landmark detector's
  positions of the pose features in frame 0 (:mod:`tracking.detected_pose`, beyond the paper).
* **Re-initialisation** (beyond the paper): the detector checks the track every few frames and
  after a diverged one; a frame that lost the face is fitted again from the detector's pose
  (``start: "detected"``, :class:`tracking.detected_pose.Redetector`).

:func:`track_video` is a sequence of steps: read and check what the run tracks with (:class:`_Run`),
make the ``track.json`` document and take the earlier results of the folder into it, apply a
correction, find where fits start from a pose, track the frames (saving as it goes), then write
the final results, plots and overlay video.
"""

from __future__ import annotations

import os
import sys
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import cv2
import numpy as np

from photomodel.errors import FaceStudioError, FitError
from photomodel.exchange.files import atomic_write_bytes, encode_png
from photomodel.photos.video import VideoFrames
from photomodel.project import load_project
from tracking.arkit_face import basis_of, tracking_face_model
from tracking.blendshape_face import FaceModel
from tracking.detected_pose import REDETECT_EVERY, Redetector, detected_spec, video_focal_px
from tracking.first_pose import (
    FirstPose,
    default_first_pose_path,
    load_first_pose,
    pose_from_spec,
    read_pose_spec,
    spec_focal,
)
from tracking.frame_fit import DIVERGED_RMS, FrameFitter, TrackOptions, single_threaded_blas, track_frames
from tracking.overlay_stream import OverlayStream
from tracking.plots import track_plots
from tracking.segments import SegmentWorker, Split, plan_split
from tracking.track_result import (
    continue_results,
    default_out_dir,
    frame_record,
    load_track_results,
    new_results,
    record_correction,
    save_results,
    state_of,
)

__all__ = ["SAVE_EVERY", "SEGMENTS", "WORK_FACE_PX", "TrackResult", "track_segment", "track_video"]

#: Results are written after every this many tracked frames (and at the end, on cancel, on Ctrl-C).
SAVE_EVERY = 5
#: … or less often: a save waits until the frames fitted since the last one took this many times as
#: long as writing the file did (saves cost at most ~5 % of the fitting; on the real clip's first 60
#: frames, re-encoding the growing track.json every 5 frames took 8 % and grew with every frame).
SAVE_OVERHEAD = 20.0
#: :func:`track_video`'s default ``segments``: two (a fresh run of a long clip tracked as two
#: segments at once, :mod:`tracking.segments`) where the machine has two cores or more.
SEGMENTS = 2 if (os.cpu_count() or 1) >= 2 else 1
#: Frames are fitted reduced by an integer factor so that the face is at most about this long (px;
#: its longer side in the image, so that a face lying on its side — a phone clip whose rotation
#: was not applied — is reduced as an upright one is): the cost grows with the covered pixels, and
#: the benchmark's 300×300 sample (face ~150 px) is tracked to 0.5° at full size. The real clip's
#: face (~265 px of 640×360) is fitted at 320×180. Poses do not depend on the image scale;
#: ``track.json`` keeps the video's camera and pixels.
WORK_FACE_PX = 120


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
    ignored : list of Path, images of a frame folder that are not frames (:func:`photomodel.photos.video.frame_files`).
    first_pose : str, where frame 0's pose came from (a file, or the landmark detector).
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
    ignored: list = field(default_factory=list)
    first_pose: str = ""

    @property
    def fps(self) -> float:
        return self.tracked / self.seconds if self.seconds > 0 else 0.0

    @property
    def diverged(self) -> int:
        return sum(bool(f["diverged"]) for f in self.frames)


# long: a 50-line numpy docstring for 20 parameters; the body is 12 lines of named steps
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
    basis: str | None = None,
    save_every: int = SAVE_EVERY,
    restart: bool = False,
    correct_frame: int | None = None,
    correct_pose: dict | str | os.PathLike | None = None,
    plots: bool = True,
    overlay: bool = True,
    redetect: int = REDETECT_EVERY,
    progress: Callable[[int, int | None], None] | None = None,
    cancel: Callable[[], bool] | None = None,
    segments: int = SEGMENTS,
) -> TrackResult:
    """Track ``video`` with the face model of the project at ``project_path``; write the results.

    Parameters
    ----------
    project_path : the project file (``*.facestudio.json``).
    video : a video file or a folder of PNG/JPG frames (:class:`photomodel.photos.video.VideoFrames`).
    out_dir : output folder (default ``<project folder>/results/track_<video stem>``); created.
    model, model_source : the face model and a sentence on its origin (default
        :func:`tracking.face_from_project.project_face_model` of the project's ``expressions``, default
        all, neutral first).
    first_pose : first-pose JSON path or dict (:func:`tracking.first_pose.load_first_pose`); default
        :func:`tracking.first_pose.default_first_pose_path` when that file exists, else the
        landmark detector's pose of frame 0 (:func:`tracking.detected_pose.detected_spec`; focal
        length ``focal_px``, else :func:`tracking.detected_pose.video_focal_px`).
    focal_px : the video camera's focal length in pixels, overriding the first-pose file's.
    max_frames : track frames 0 .. max_frames − 1 only (a later run may raise it and continue).
    options : :class:`tracking.frame_fit.TrackOptions`.
    basis : the expression basis when ``model`` is not given (:data:`tracking.arkit_face.BASES`):
        ``"arkit"`` (the rig's shapes), ``"photographed"`` or ``"both"``; default ``"arkit"`` when
        the project has a rig, else ``"photographed"``.
    save_every : write the results after every this many frames.
    restart : discard results of other settings in ``out_dir`` instead of refusing to continue.
    correct_frame, correct_pose : the user's correction of a tracked frame N = ``correct_frame``
        (both or neither): ``correct_pose`` is frame N's pose in the first-pose format (a path or the
        parsed dict, :func:`tracking.first_pose.load_first_pose`: usually ≥ 6 features clicked in
        frame N; its focal length, if given, must be the run's). The results in ``out_dir`` (same settings) keep frames
        0 .. N−1 unchanged; frame N is fitted from that pose in several rounds, like frame 0
        (:func:`tracking.frame_fit.track_frames`' ``first_rounds``), and recorded with
        ``start: "user"``; the frames after it are tracked from there as usual. ``track.json`` keeps the list of
        corrections (``corrections``: frame, source, spec); corrections of frames ≥ N are dropped
        with those frames. Prediction does not reach back across a corrected frame (frame N + 1
        starts from frame N alone, like frame 1 from frame 0), so a later rerun continues exactly.
    plots, overlay : write the plots (at the end of every run, cancelled or not) and the overlay
        video (only once the video, or its first ``max_frames``, is tracked).
    redetect : the landmark detector checks the tracking every this many frames and after every
        diverged frame, and a frame that lost the face is fitted again from the detector's pose
        (:class:`tracking.detected_pose.Redetector`); 0 turns it off.
    progress : ``progress(done, total)`` after each frame (``total`` None if the video does not say).
    cancel : ``cancel() -> bool`` checked after each frame; True saves and stops.
    segments : 2 (the default, :data:`SEGMENTS`): a fresh run of a long clip is tracked as two
        segments at once, the second in another process (:mod:`tracking.segments`); 1: one chain
        of frames, as the paper tracks (a caller running several tracks at once, like
        :mod:`tracking.many_shots`, passes 1).

    Returns
    -------
    TrackResult

    Raises
    ------
    ProjectError, VideoError, FitError, FaceStudioError naming what is wrong (a correction: no
    results to correct, the frame out of range or beyond the tracked frames, a malformed pose file);
    KeyboardInterrupt after saving the frames tracked so far.
    """
    _check_request(correct_frame, correct_pose, restart)
    run = _Run.open(
        project_path, video, out_dir, model, model_source, expressions, first_pose, focal_px, max_frames, options, basis
    )
    run.redetect = int(redetect)
    doc, correct_frame = _results_to_continue(run, project_path, max_frames, restart, correct_frame, correct_pose)
    start = len(doc["frames"])
    starts = _fit_starts(run, doc, start)
    fitter = _start_fitter(run, doc)
    # the overlay video drawn while the clip is tracked (tracking.overlay_stream)
    stream = OverlayStream(run.out / "overlay.mp4", run.video, fitter) if overlay else None
    try:
        for rec in doc["frames"] if stream is not None else ():  # tracked before (resumed, corrected)
            stream.add(rec)
        split = plan_split(run, start, correct_frame, segments)
        if split is None:
            ended, cancelled, seconds = _fit_frames(
                run, doc, fitter, starts, start, save_every, progress, cancel, stream
            )
        else:
            ended, cancelled, seconds = _fit_in_segments(
                run, doc, fitter, starts, save_every, progress, cancel, stream, split
            )
        files = _write_outputs(run, doc, ended, plots, stream)
    finally:
        if stream is not None:
            stream.abort()  # nothing after finish(); else the half-drawn overlay is dropped
    return _track_result(run, doc, start, ended, cancelled, seconds, files, correct_frame)


def _results_to_continue(run, project_path, max_frames, restart: bool, correct_frame, correct_pose):
    """The results document of this run: the earlier results of the same settings in ``run.out``
    (kept up to the corrected frame, with the correction applied), else new ones. Returns it and
    the corrected frame (None without a correction)."""
    doc = new_results(project_path, run.video, run.model, run.model_source, run.first, run.options, max_frames)
    doc["model"]["basis"] = run.basis
    _take_earlier_results(run, doc, restart, correct_frame)
    if correct_frame is not None:
        correct_frame = _apply_correction(run, doc, correct_frame, correct_pose)
    return doc, correct_frame


def _start_fitter(run, doc: dict) -> FrameFitter:
    """Make the output folder and the frame fitter (and its working-size copy, ``run.work``)."""
    run.out.mkdir(parents=True, exist_ok=True)
    fitter = FrameFitter(run.model, run.first.focal_px, run.video.width, run.video.height, run.options)
    run.work = _work_fitter(fitter, run.first.state)
    doc["work_factor"] = run.work_factor = fitter.W // run.work.W
    return fitter


def _track_result(
    run, doc: dict, start: int, ended, cancelled: bool, seconds: float, files, correct_frame
) -> TrackResult:
    """The :class:`TrackResult` of a run that fitted frames ``start`` .. on."""
    records = doc["frames"]
    return TrackResult(
        run.out,
        records,
        start,
        len(records) - start,
        ended,
        cancelled,
        seconds,
        files,
        correct_frame,
        list(run.video.ignored),
        doc["first_pose"]["source"],
    )


def _check_request(correct_frame, correct_pose, restart: bool) -> None:
    """A correction needs its frame and its pose, and is not a restart."""
    if (correct_frame is None) != (correct_pose is None):
        raise FaceStudioError("a correction needs both the frame (--correct) and its pose (--pose)")
    if correct_frame is not None and restart:
        raise FaceStudioError("--restart discards the results a correction keeps: restart or correct, not both")


@dataclass
class _Run:
    """What a run tracks with, read and checked before anything is written (:meth:`open`)."""

    project: object  # photomodel.project.Project
    video: VideoFrames
    model: FaceModel
    model_source: str
    first: FirstPose
    options: TrackOptions
    max_frames: int | None
    out: Path
    basis: str = "photographed"
    redetect: int = REDETECT_EVERY
    work: FrameFitter | None = None  # the fitter of the reduced frames (:func:`_work_fitter`)
    work_factor: int = 1
    project_path: Path | None = None  # the project file (a second segment opens it again)

    @classmethod
    def open(
        cls,
        project_path,
        video,
        out_dir,
        model,
        model_source,
        expressions,
        first_pose,
        focal_px,
        max_frames,
        options,
        basis=None,
    ) -> _Run:
        """The project, the footage, the face model, the first pose and the output folder of
        :func:`track_video`'s arguments (the same names); raises what they raise."""
        project = load_project(project_path)
        frames_in = VideoFrames(video)
        if model is None:
            model, model_source, basis = tracking_face_model(project, basis, expressions)
        else:
            basis = basis_of(model)
        model_source = model_source or "given by the caller"
        if first_pose is None and default_first_pose_path(frames_in.path).is_file():
            first_pose = default_first_pose_path(frames_in.path)
        if first_pose is None:
            fp = _detected_first_pose(project, model, frames_in, focal_px)
        else:
            fp = load_first_pose(first_pose, project, model, frames_in.width, frames_in.height, focal_px)
        options = options or TrackOptions()
        if max_frames is not None and max_frames < 1:
            raise FaceStudioError(f"the frame limit must be at least 1, got {max_frames}")
        out = Path(out_dir).absolute() if out_dir is not None else default_out_dir(project_path, video)
        return cls(
            project,
            frames_in,
            model,
            model_source,
            fp,
            options,
            max_frames,
            out,
            basis,
            project_path=Path(project_path),
        )

    @property
    def json_path(self) -> Path:
        return self.out / "track.json"

    def pose(self, spec: dict, where: str, frame: int) -> FirstPose:
        """Frame ``frame``'s pose from a parsed pose JSON (:func:`tracking.first_pose.pose_from_spec`),
        with the run's camera."""
        return pose_from_spec(
            spec, where, self.project, self.model, self.video.width, self.video.height, self.first.focal_px, frame
        )


def _detected_first_pose(project, model: FaceModel, video: VideoFrames, focal_px: float | None) -> FirstPose:
    """Frame 0's pose from the landmark detector (:mod:`tracking.detected_pose`), the focal length
    ``focal_px`` or the project's (:func:`tracking.detected_pose.video_focal_px`)."""
    focal_source = "given (--focal-px)"
    if focal_px is None:
        focal_px, focal_source = video_focal_px(project, video.width, video.height)
    frame = next(video.frames(0, 1))[1]
    spec = detected_spec(frame, project, focal_px)
    if spec is None:
        raise FitError(
            f"no face found in frame 0 of {video.path} by the landmark detector (or fewer than six of the "
            f"pose features): write the first frame's clicks into "
            f"{default_first_pose_path(video.path)} (see docs/tracking.md; `facestudio track` also takes them as "
            f"--first-pose FILE)"
        )
    fp = pose_from_spec(spec, "first pose", project, model, video.width, video.height, None, 0)
    fp.source = (
        f"landmark detector on frame 0: {len(spec['clicks'])} pose features, pose by "
        f"tracking.frame_fit.pose_from_clicks; focal length {focal_px:.1f} px, {focal_source}"
    )
    return fp


def _take_earlier_results(run: _Run, doc: dict, restart: bool, correct_frame: int | None) -> None:
    """The frames and corrections already in the output folder, into ``doc`` (unless ``restart``)."""
    old = None if restart else load_track_results(run.out)
    if old is not None:
        continue_results(doc, old, run.json_path)
    elif correct_frame is not None:
        raise FaceStudioError(f"{run.out} holds no tracking results to correct: track the video first")


def _check_correct_frame(frame, tracked: int, max_frames: int | None, path: Path) -> int:
    """``frame`` as the index of a tracked frame a correction may restart from; FaceStudioError otherwise."""
    if isinstance(frame, bool) or not isinstance(frame, (int, np.integer)):
        raise FaceStudioError(f"the frame to correct must be a frame index (an integer), got {frame!r}")
    frame = int(frame)
    if tracked == 0:
        raise FaceStudioError(f"{path}: no frames tracked yet, nothing to correct; track the video first")
    if not 0 <= frame < tracked:
        raise FaceStudioError(
            f"frame {frame} is out of range: {path} holds frames 0..{tracked - 1}; correct one of "
            f"those (track further first to reach a later frame)"
        )
    if max_frames is not None and frame >= max_frames:
        raise FaceStudioError(f"frame {frame} is beyond the frame limit {max_frames} (frames 0..{max_frames - 1})")
    return frame


def _apply_correction(run: _Run, doc: dict, frame, pose) -> int:
    """The user's pose ``pose`` of tracked frame ``frame``, checked and recorded in ``doc`` (the
    frames from ``frame`` on dropped); returns the frame index."""
    frame = _check_correct_frame(frame, len(doc["frames"]), run.max_frames, run.json_path)
    spec, where = read_pose_spec(pose, frame)
    given = spec_focal(spec, where, run.video.width)
    focal = run.first.focal_px
    if given is not None and abs(given - focal) > 1e-9 * focal:
        raise FitError(
            f"{where}: focal length {given} px, but the video camera of these results has "
            f"{focal} px (one camera per video; leave the focal length out)"
        )
    cp = run.pose(spec, where, frame)
    record_correction(doc, frame, cp.source, cp.spec)
    return frame


def _fit_starts(run: _Run, doc: dict, start: int) -> dict[int, tuple[str, FirstPose | None]]:
    """Where fits start from a pose instead of the prediction: frame 0 and the user's corrections,
    ``{frame: (start kind, pose)}``. The poses of the corrections still ahead (the one just given,
    or one whose frame an interrupted run did not reach) are solved from their recorded JSON, as
    when they were given; those behind keep None."""
    starts: dict[int, tuple[str, FirstPose | None]] = {0: ("first_pose", run.first)}
    for c in doc["corrections"]:
        starts[c["frame"]] = ("user", None)
    for c in doc["corrections"]:
        if c["frame"] >= start:
            starts[c["frame"]] = (
                "user",
                run.pose(c["spec"], f"{run.json_path}: correction of frame {c['frame']}", c["frame"]),
            )
    return starts


def _fit_frames(
    run: _Run,
    doc: dict,
    fitter: FrameFitter,
    starts: dict,
    start: int,
    save_every: int,
    progress,
    cancel,
    stream,
    stop: int | None = None,
) -> tuple[bool, bool, float]:
    """Fit frames ``start`` .. (to the end or the frame limit; before ``stop`` when given) into
    ``doc["frames"]``, saving every ``save_every`` frames and on Ctrl-C (re-raised), each new record
    handed to ``stream`` (an :class:`~tracking.overlay_stream.OverlayStream`, or None). Returns
    (ended: the loop ran out of frames, cancelled, seconds of fitting)."""
    records = doc["frames"]
    count, limit = run.video.count, run.max_frames
    total = count if limit is None else (limit if count is None else min(limit, count))
    if stop is not None:
        limit = stop if limit is None else min(limit, stop)
    # the prediction restored from the last two saved frames, not reaching back across a start
    # (the first pose, a correction, a re-detection)
    detected = [r["frame"] for r in records[:start] if r.get("start") == "detected"]
    anchor = max([f for f in starts if f < start] + detected, default=0)
    states = [state_of(r) for r in records[max(anchor, start - 2) : start]]
    watch = Redetector(run.project, run.first.focal_px, run.redetect)
    if records[:start]:
        watch.last_diverged = bool(records[start - 1]["diverged"])
        # the colour match the last saved frame left (TrackOptions.colour_match): exactly where an
        # uninterrupted run would be
        run.work.colour = records[start - 1].get("colour_match")
    cancelled, ended, seconds = False, False, 0.0
    unsaved, since_save, save_cost = 0, 0.0, 0.0
    # BLAS single-threaded over the whole loop, not frame by frame (see single_threaded_blas)
    with single_threaded_blas():
        try:
            for i, frame in run.video.frames(start, limit):
                t0 = time.perf_counter()
                res, kind, states = _fit_frame(run, fitter, watch, i, frame, starts, states)
                dt = time.perf_counter() - t0
                seconds += dt
                records.append(frame_record(i, res, run.model, dt, kind))
                records[-1]["landmarks_xy"] = watch.landmarks(fitter, res.state)
                if run.work.colour is not None:
                    records[-1]["colour_match"] = run.work.colour.tolist()
                if stream is not None:
                    stream.add(records[-1])
                states = (states + [res.state])[-2:]
                unsaved += 1
                since_save += dt
                # every save_every frames, but writing the whole file (it grows with the clip) may take
                # at most 1/SAVE_OVERHEAD of the fitting time: quadratic in the clip's length otherwise
                if unsaved >= save_every and since_save >= SAVE_OVERHEAD * save_cost:
                    t_save = time.perf_counter()
                    save_results(run.out, doc, False)
                    save_cost, unsaved, since_save = time.perf_counter() - t_save, 0, 0.0
                if progress is not None:
                    progress(i + 1, total)
                if cancel is not None and cancel():
                    cancelled = True
                    break
            else:
                ended = True
        except KeyboardInterrupt:
            save_results(run.out, doc, False)
            raise
    return ended, cancelled, seconds


def _fit_in_segments(
    run: _Run, doc: dict, fitter: FrameFitter, starts: dict, save_every: int, progress, cancel, stream, split: Split
) -> tuple[bool, bool, float]:
    """:func:`_fit_frames` of a fresh run in two segments (:mod:`tracking.segments`): frames before
    ``split.seam`` here, the rest in a second process, its records appended once this one has
    reached the seam. Progress counts both; a cancel stops both and keeps this segment's frames.
    Returns (ended, cancelled, seconds of the whole fit, wall clock)."""
    t0 = time.perf_counter()
    conf = {
        "project": str(run.project_path),
        "video": str(run.video.path),
        "model": run.model,
        "model_source": run.model_source,
        "first_pose": run.first.spec,
        "focal_px": run.first.focal_px,
        "max_frames": run.max_frames,
        "options": run.options,
        "redetect": run.redetect,
    }
    try:
        worker = SegmentWorker(track_segment, conf, split, run.max_frames)
    except Exception as exc:  # noqa: BLE001 — no second process here (a daemonic one, no __main__ guard): one chain
        print(f"facestudio: no second process for tracking ({exc!r}); one segment", file=sys.stderr)
        return _fit_frames(run, doc, fitter, starts, 0, save_every, progress, cancel, stream)
    total = [None]

    def both(done: int, of) -> None:
        total[0] = of
        if progress is not None:
            progress(done + worker.done.value, of)

    try:
        ended, cancelled, _ = _fit_frames(run, doc, fitter, starts, 0, save_every, both, cancel, stream, split.seam)
        if cancelled or len(doc["frames"]) < split.seam:  # cancelled, or the clip ended before the seam
            return ended and not cancelled, cancelled, time.perf_counter() - t0

        def wait() -> bool:
            both(split.seam, total[0])
            return cancel is not None and bool(cancel())

        try:
            records, ended, cancelled = worker.results(wait)
        except FaceStudioError as exc:  # the second process failed: its frames are tracked here
            print(f"facestudio: {exc}; tracking frames {split.seam}.. in this process", file=sys.stderr)
            ended, cancelled, _ = _fit_frames(run, doc, fitter, starts, split.seam, save_every, both, cancel, stream)
            return ended, cancelled, time.perf_counter() - t0
        for rec in records:
            doc["frames"].append(rec)
            if stream is not None:
                stream.add(rec)
        if progress is not None and records:
            progress(len(doc["frames"]), total[0])
        return ended, cancelled, time.perf_counter() - t0
    finally:
        worker.stop()


def track_segment(conf: dict, split: Split, stop: int | None, progress, cancel) -> tuple[list[dict], bool, bool]:
    """The second segment of :func:`_fit_in_segments`, run in its own process
    (:class:`tracking.segments.SegmentWorker`): the run of ``conf`` opened again, frame
    ``split.begin`` fitted from the detector's pose ``split.spec`` in several rounds, the frames
    after it tracked up to ``stop`` (None: the end). Returns (records, ended, cancelled)."""
    run = _Run.open(
        conf["project"],
        conf["video"],
        None,
        conf["model"],
        conf["model_source"],
        None,
        conf["first_pose"],
        conf["focal_px"],
        conf["max_frames"],
        conf["options"],
    )
    run.redetect = conf["redetect"]
    fitter = FrameFitter(run.model, run.first.focal_px, run.video.width, run.video.height, run.options)
    run.work = _work_fitter(fitter, run.first.state)
    pose = run.pose(split.spec, f"detector on frame {split.begin}", split.begin)
    doc: dict = {"frames": []}
    starts = {split.begin: ("detected", pose)}
    ended, cancelled, _ = _fit_frames(run, doc, fitter, starts, split.begin, 1 << 30, progress, cancel, None, stop)
    return doc["frames"], ended, cancelled


def _work_fitter(fitter: FrameFitter, state) -> FrameFitter:
    """The fitter of the frames reduced by an integer factor so that the face at ``state`` (frame
    0's pose) is at most about :data:`WORK_FACE_PX` long; ``fitter`` itself when no reduction."""
    model = fitter.model
    uv = fitter.camera(state).project(model.geometry_at(state.alpha)[model.face_mask])
    k = max(1, int(np.ptp(uv, axis=0).max() // WORK_FACE_PX)) if np.all(np.isfinite(uv)) else 1
    if k == 1:
        return fitter
    return FrameFitter(model, fitter.f / k, fitter.W // k, fitter.H // k, fitter.options, fitter.renderer)


def _work_frame(frame: np.ndarray, work: FrameFitter) -> np.ndarray:
    """``frame`` reduced to ``work``'s size (area average over k × k blocks: pixel centres map
    exactly, ``x' = (x + ½)/k − ½``)."""
    h, w = work.H, work.W
    if frame.shape[:2] == (h, w):
        return frame
    k = frame.shape[1] // w
    return cv2.resize(frame[: h * k, : w * k], (w, h), interpolation=cv2.INTER_AREA)


def _fit_frame(
    run: _Run, fitter: FrameFitter, watch: Redetector, i: int, frame: np.ndarray, starts: dict, states: list
) -> tuple:
    """Fit frame ``i`` (on the reduced frame of ``run.work``): from a start pose (frame 0, a
    correction; several rounds), else from the prediction of ``states`` — and again from the
    detector's pose when the detector says the track lost the face
    (:class:`tracking.detected_pose.Redetector`, on the full frame with ``fitter``'s camera).
    Returns (FrameResult, start kind, the states the prediction continues from)."""
    work, small = run.work, _work_frame(frame, run.work)
    if i in starts:  # fitted from the pose in several rounds (track_frames' first_rounds)
        _, pose = starts[i]
        (res,) = track_frames(work, [small], pose.state)
        watch.last_diverged = bool(res.diverged)
        return res, starts[i][0], []
    marks = None
    if work.options.landmarks:

        def marks(_, start):  # the detector near where the prediction sees the face
            term = watch.landmark_term(frame, fitter, work, start)
            gate = work.options.landmark_gate_px
            if term is None or (gate > 0 and np.linalg.norm(term.residuals(start), axis=1).mean() < gate):
                return None
            return term

    (res,) = track_frames(work, [small], run.first.state, previous=states, landmarks=marks)
    spec = watch.restart_spec(i, frame, fitter, res)
    if spec is None:
        return res, "predicted", states
    pose = run.pose(spec, f"detector on frame {i}", i)
    (again,) = track_frames(work, [small], pose.state)
    watch.last_diverged = bool(again.diverged)
    return again, "detected", []


def _write_outputs(run: _Run, doc: dict, ended: bool, plots: bool, stream) -> dict[str, Path]:
    """The final ``track.json``/``track.csv`` (``complete`` when the whole video is tracked), the
    plots, and the overlay video of ``stream`` once the loop ``ended`` (else it is dropped);
    returns {name: path} of the files written."""
    records = doc["frames"]
    # a finished loop stopped at the frame limit or at the end of the video
    n, count, limit = len(records), run.video.count, run.max_frames
    whole = ended and (limit is None or n < limit or (count is not None and n >= count))
    if whole:
        doc["video"]["frames"] = n
    files = save_results(run.out, doc, whole)
    if plots and records:
        regions = doc["model"]["regions_with_parameters"]
        for name, img in track_plots(records, regions, list(run.model.names), DIVERGED_RMS).items():
            files[name.removesuffix(".png")] = atomic_write_bytes(run.out / name, encode_png(img))
    if stream is not None and ended and records:
        last = stream.finish()
        files["overlay"] = run.out / "overlay.mp4"
        if last is not None:
            files["overlay_last"] = atomic_write_bytes(run.out / "overlay_last.png", encode_png(last))
    return files
