"""``facestudio track-many``: many shots tracked in parallel on Dask (:mod:`tracking.many_shots`).

    facestudio track-many PROJECT VIDEO... [--workers N] [--scheduler ADDR] [--out DIR] [--frames N]
                          [--threads N] [--expressions a,b] [--no-overlay] [--json]

Each shot's first pose is ``<video stem>.first_pose.json`` beside the video, else the landmark
detector's (as for ``track``). Exit status 1 when a shot failed, 130 when cancelled.
"""

from __future__ import annotations

import json
import signal
import sys
from pathlib import Path
from typing import TYPE_CHECKING

from app.cli.common import check_expression_names, check_writable, column_width, expression_names
from app.cli.progress import StageProgress, command_progress
from photomodel.errors import FaceStudioError

if TYPE_CHECKING:  # the batch module loads Dask: imported where track-many runs
    from tracking.many_shots import BatchProgress, BatchResult

NAME = "track-many"


def check_args(args) -> None:
    """The arguments checked before any work; FaceStudioError naming the bad one."""
    if args.frames is not None and args.frames < 1:
        raise FaceStudioError(f"--frames {args.frames}: track at least one frame")
    if args.workers is not None and args.workers < 1:
        raise FaceStudioError(f"--workers {args.workers}: at least one worker")
    if args.threads is not None and args.threads < 1:
        raise FaceStudioError(f"--threads {args.threads}: at least one thread")
    if not Path(args.project).is_file():
        raise FaceStudioError(f"{args.project} does not exist (give the project file, *.facestudio.json)")
    for video in args.videos:
        if not Path(video).exists():
            raise FaceStudioError(f"{video} does not exist (give a video file or a folder of frames)")
    check_expression_names(args.project, expression_names(args.expressions))


def run(args) -> int:
    check_args(args)
    check_writable(args.out if args.out is not None else Path(args.project).absolute().parent / "results")
    stop = []

    def on_sigint(signum, frame):  # first Ctrl-C: every shot saves and stops; a second one stops now
        stop.append(signum)
        signal.signal(signal.SIGINT, signal.default_int_handler)
        print("\nfacestudio: stopping every shot after its frame (Ctrl-C again to stop at once)", file=sys.stderr)

    previous = signal.signal(signal.SIGINT, on_sigint)
    # an optional heavy library (Dask, ~1-2 s to import): only the command that needs it loads it
    from tracking.many_shots import track_many  # noqa: PLC0415

    try:
        with command_progress(args, NAME) as show:
            result = track_many(
                args.project,
                args.videos,
                args.out,
                workers=args.workers,
                scheduler=args.scheduler,
                threads=args.threads,
                max_frames=args.frames,
                expressions=expression_names(args.expressions),
                overlay=not args.no_overlay,
                progress=batch_display(show),
                stop=lambda: bool(stop),
            )
    except KeyboardInterrupt:
        print("facestudio: cancelled; every shot keeps the frames it saved, rerun to continue", file=sys.stderr)
        return 130
    finally:
        signal.signal(signal.SIGINT, previous)
    if args.json:
        print(json.dumps(result.summary() | {"files": {k: str(v) for k, v in result.files.items()}}, indent=1))
    else:
        print_batch(result)
    if result.cancelled:
        print("facestudio: cancelled; the frames tracked so far are saved, rerun to continue", file=sys.stderr)
        return 130
    return 1 if result.failed else 0


def batch_display(show: StageProgress):
    """``progress(BatchProgress)`` on the command's progress: shots ended of all (frames/s
    overall, failures), each failed shot written above it with its cause."""
    told = []

    def progress(state: BatchProgress) -> None:
        for r in state.finished[len(told) :]:
            told.append(r)
            if r.status == "failed":
                show.write(f"facestudio: {r.video} failed: {r.error}")
        detail = (
            f"{state.ended} of {state.shots}, {state.frames} frames, {state.fps:.2f} frames/s, {state.failed} failed"
        )
        show("shots", state.ended / state.shots if state.shots else 1.0, detail)

    return progress


def print_batch(result: BatchResult) -> None:
    """The human summary of ``track-many``: one line per shot, then the totals and the summary files."""
    wid = column_width((Path(s.video).name for s in result.shots), "shot")
    for s in result.shots:
        what = {
            "tracked": f"{s.tracked} frames tracked at {s.fps:.2f} frames/s"
            + (f" (continuing after frame {s.resumed_from - 1})" if s.resumed_from else ""),
            "skipped": "already tracked, skipped",
            "cancelled": f"cancelled after {s.frames} frames",
            "failed": f"FAILED: {s.error}",
        }[s.status]
        print(f"{Path(s.video).name:<{wid}} {what}; {s.frames} frames in {s.out_dir}")
    where = f"{result.workers} workers" + (f" of {result.scheduler}" if result.scheduler else "")
    print(
        f"{len(result.shots)} shots ({result.failed} failed), {result.tracked_frames} frames in "
        f"{result.seconds:.1f} s on {where} (start-up {result.startup_s:.1f} s)"
    )
    for name, path in result.files.items():
        print(f"  {name:<5} {path}")


def add_parser(sub) -> None:
    m = sub.add_parser(
        NAME,
        help="track many shots in parallel on Dask (this machine's cores, or a "
        "cluster): each shot's results where `track` puts them, a summary",
    )
    m.add_argument("project", help="project file (*.facestudio.json); on a cluster, in a folder every worker reads")
    m.add_argument(
        "videos",
        nargs="+",
        help="video files or frame folders, one shot each (first pose of each: "
        "<video stem>.first_pose.json beside it, as for `track`)",
    )
    m.add_argument(
        "--workers", type=int, help="worker processes on this machine (default: one per core, at most one per shot)"
    )
    m.add_argument(
        "--scheduler",
        metavar="ADDR",
        help="a running Dask scheduler (tcp://host:8786): track on its workers instead of this machine's",
    )
    m.add_argument(
        "--threads",
        type=int,
        help="threads each worker's renderer and OpenCV may use (default: cores / workers; 1 on a cluster)",
    )
    m.add_argument(
        "--out",
        type=Path,
        help="folder of the shots' results folders and the summary (default: "
        "<project folder>/results); a rerun continues what is there",
    )
    m.add_argument("--frames", type=int, help="track only the first N frames of each shot")
    m.add_argument(
        "--expressions",
        help="comma-separated expressions of the face model, neutral first (default: every expression of the project)",
    )
    m.add_argument("--no-overlay", action="store_true", help="do not write the shots' overlay videos")
    m.add_argument("--json", action="store_true", help="print one JSON object (the summary) instead of the table")
