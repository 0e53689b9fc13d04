"""``facestudio track``: head pose and expression through a video (:func:`tracking.run.track_video`).

    facestudio track PROJECT --video PATH [--out DIR] [--first-pose JSON] [--focal-px F] [--frames N]
                     [--restart] [--correct FRAME --pose JSON] [--no-overlay] [--json]

A first Ctrl-C stops after the frame being tracked (the frames so far are saved, a rerun
continues); a second one stops at once.
"""

from __future__ import annotations

import json
import math
import signal
import sys
from dataclasses import replace
from pathlib import Path

from app.cli.common import add_json_flag, check_expression_names, check_writable, column_width, expression_names
from app.cli.progress import command_progress
from photomodel.errors import FaceStudioError
from tracking.frame_fit import TrackOptions
from tracking.run import track_video
from tracking.track_result import default_out_dir, load_track_results

NAME = "track"


def check_args(args) -> None:
    """The arguments checked before any work; FaceStudioError naming the bad one."""
    if args.frames is not None and args.frames < 1:
        raise FaceStudioError(f"--frames {args.frames}: track at least one frame")
    if args.focal_px is not None and not args.focal_px > 0:
        raise FaceStudioError(f"--focal-px {args.focal_px}: the focal length must be a positive number of pixels")
    if (args.correct is None) != (args.pose is None):
        raise FaceStudioError(
            "--correct FRAME and --pose FILE go together: the frame to correct and its pose "
            "(clicks of frame FRAME in the first-pose format)"
        )
    if not (args.landmark_weight >= 0 and math.isfinite(args.landmark_weight)):
        raise FaceStudioError(
            f"--landmark-weight {args.landmark_weight}: give a number of 0 or more (0: the image alone)"
        )
    if not Path(args.video).exists():
        raise FaceStudioError(f"{args.video} does not exist (give a video file or a folder of frames)")
    check_expression_names(args.project, expression_names(args.expressions))


def run(args) -> int:
    check_args(args)
    out_dir = args.out if args.out is not None else default_out_dir(args.project, args.video)
    check_writable(out_dir)
    stop = []

    def on_sigint(signum, frame):  # first Ctrl-C: stop after this frame; a second one stops now
        stop.append(signum)
        signal.signal(signal.SIGINT, signal.default_int_handler)
        print("\nfacestudio: stopping after this frame (Ctrl-C again to stop at once)", file=sys.stderr)

    previous = signal.signal(signal.SIGINT, on_sigint)
    try:
        with command_progress(args, NAME) as show:
            result = track_video(
                args.project,
                args.video,
                args.out,
                expressions=expression_names(args.expressions),
                first_pose=args.first_pose,
                focal_px=args.focal_px,
                max_frames=args.frames,
                basis=args.basis,
                restart=args.restart,
                correct_frame=args.correct,
                correct_pose=args.pose,
                overlay=not args.no_overlay,
                options=replace(TrackOptions(), landmarks=args.landmark_weight),
                progress=lambda done, total: show.counter(Path(args.video).name, done, total),
                cancel=lambda: bool(stop),
            )
    except KeyboardInterrupt:
        print(
            f"facestudio: cancelled; {_frames_saved(out_dir)} frames saved in {out_dir}, rerun to continue",
            file=sys.stderr,
        )
        return 130
    finally:
        signal.signal(signal.SIGINT, previous)
    return _report(args, result)


def _frames_saved(out_dir) -> int:
    """Frames listed in ``out_dir``'s track.json (0 if none or unreadable)."""
    try:
        doc = load_track_results(out_dir)
    except FaceStudioError:
        return 0
    return 0 if doc is None else len(doc["frames"])


def summary(args, result) -> dict:
    """The JSON object of a track run."""
    rms = [f["rms"] for f in result.frames]
    return {
        "project": str(Path(args.project)),
        "video": str(Path(args.video)),
        "out_dir": str(result.out_dir),
        "frames": len(result.frames),
        "tracked": result.tracked,
        "resumed_from": result.resumed_from,
        "corrected": result.corrected,
        "complete": result.complete,
        "cancelled": result.cancelled,
        "fps": round(result.fps, 3),
        "diverged_frames": result.diverged,
        "mean_rms": float(sum(rms) / len(rms)) if rms else None,
        "files": {k: str(v) for k, v in result.files.items()},
        "first_pose": result.first_pose,
        "redetected": sum(f.get("start") == "detected" for f in result.frames),
        "ignored_files": [str(p) for p in result.ignored],
    }


def _report(args, result) -> int:
    out = summary(args, result)
    if result.ignored:
        names = ", ".join(p.name for p in result.ignored[:5]) + (" …" if len(result.ignored) > 5 else "")
        print(
            f"facestudio: {len(result.ignored)} image(s) in the frame folder do not match its frame names and were "
            f"ignored: {names}",
            file=sys.stderr,
        )
    if args.json:
        print(json.dumps(out, indent=1))
    else:
        resumed = f" (continuing after frame {result.resumed_from - 1})" if result.resumed_from else ""
        if result.corrected is not None:
            resumed = f" (from frame {result.corrected}, corrected to the given pose)"
        print(
            f"tracked {result.tracked} frames{resumed} at {result.fps:.2f} frames/s; {len(result.frames)} frames "
            f"in the results, {result.diverged} diverged, {out['redetected']} fitted again from the landmark "
            f"detector, mean image RMS {out['mean_rms'] or 0:.4f}"
        )
        print(f"  first pose: {result.first_pose}")
        wid = column_width(out["files"], "")
        for name, path in out["files"].items():
            print(f"  {name:<{wid}} {path}")
    if result.cancelled:
        print(
            f"facestudio: cancelled; {len(result.frames)} frames saved in {result.out_dir}, rerun to continue",
            file=sys.stderr,
        )
        return 130
    return 0


def add_parser(sub) -> None:
    k = sub.add_parser(
        NAME, help="track head pose and expression through a video: JSON + CSV per frame, plots, overlay video"
    )
    k.add_argument(
        "project",
        help="project file (*.facestudio.json) with its expressions fitted and textured; "
        "a neutral one alone tracks head pose, more expressions add expression",
    )
    k.add_argument("--video", required=True, help="video file (anything OpenCV decodes) or folder of PNG/JPG frames")
    k.add_argument(
        "--out",
        type=Path,
        help="output folder (default: <project folder>/results/track_<video name>); a rerun continues what is there",
    )
    k.add_argument(
        "--first-pose",
        type=Path,
        help="first frame's pose or clicks, JSON (default: <video stem>.first_pose.json beside the video if there "
        "is one, else found by the landmark detector; see docs/tracking.md)",
    )
    k.add_argument(
        "--focal-px",
        type=float,
        help="the video camera's focal length in pixels (overrides the first-pose file's; default: the "
        "project's cameras of the video's size, else 0.9 x the frame width)",
    )
    k.add_argument("--frames", type=int, help="track only the first N frames (a later run may raise N)")
    k.add_argument(
        "--expressions",
        help="comma-separated expressions of the face model, neutral first (default: every expression of the project)",
    )
    k.add_argument(
        "--basis",
        choices=("arkit", "photographed", "both"),
        help="the expression basis: the rig's 51 ARKit shapes, the photographed expressions per region, or both "
        "(default: arkit when the project has a rig, else photographed)",
    )
    k.add_argument("--restart", action="store_true", help="discard earlier results in the output folder")
    k.add_argument(
        "--correct",
        type=int,
        metavar="FRAME",
        help="correct tracked frame FRAME (e.g. a diverged one) with --pose: keep frames 0..FRAME-1, fit "
        "FRAME from that pose, track on from there",
    )
    k.add_argument(
        "--pose",
        type=Path,
        metavar="FILE",
        help="frame FRAME's pose for --correct: JSON like the first-pose file (clicks of that frame, or R/t_mm)",
    )
    k.add_argument("--no-overlay", action="store_true", help="do not write the overlay video")
    k.add_argument(
        "--landmark-weight",
        type=float,
        default=TrackOptions().landmarks,
        metavar="K",
        help="weight of the landmark detector's features in each frame's fit, against the whole image's "
        f"(default {TrackOptions().landmarks}; 0: the image alone, as the paper)",
    )
    add_json_flag(k)
