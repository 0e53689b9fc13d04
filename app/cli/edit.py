"""``facestudio edit``: the command line of expression editing in video (:mod:`tracking.edit_video`).

    facestudio edit PROJECT --track results/track_clip/ --scale smile=0.5 [--span 10:40]
                    [--replace 60:90@75] [--no-smooth] --out edited.mp4 [--json]

Its arguments are parsed into the edit list of ``edits.json`` (:mod:`tracking.edit`) and checked
against the track (expression names, frames) before the smoothing starts; without ``--scale`` or
``--replace`` the edits already stored beside the track are written again.
"""

from __future__ import annotations

import json
import re
from pathlib import Path

from app.cli.common import add_json_flag, check_writable, new_outputs
from app.cli.progress import command_progress
from photomodel.errors import FaceStudioError
from tracking.edit import check_edit, load_edits
from tracking.edit_video import edit_track
from tracking.smooth import SmoothOptions
from tracking.track_result import load_track_results

NAME = "edit"
VIDEO_SUFFIXES = (".mp4", ".mov", ".mkv", ".avi")


def _span(text: str, what: str) -> list[int]:
    m = re.fullmatch(r"\s*(\d+)\s*:\s*(\d+)\s*", text or "")
    if not m or int(m[1]) > int(m[2]):
        raise FaceStudioError(f"{what} {text!r}: give FIRST:LAST frames, e.g. 10:40")
    return [int(m[1]), int(m[2])]


def edits_from_args(args) -> list[dict]:
    """The edit list of ``--scale NAME=F`` (with ``--span``) and ``--replace A:B@F``."""
    edits = []
    span = _span(args.span, "--span") if args.span else None
    for s in args.scale or []:
        name, _, factor = s.partition("=")
        try:
            f = float(factor)
        except ValueError:
            raise FaceStudioError(f"--scale {s!r}: give EXPRESSION=FACTOR, e.g. smile=0.5") from None
        e = {"op": "scale", "expression": name.strip(), "factor": f}
        if span is not None:
            e["span"] = span
        edits.append(e)
    for r in args.replace or []:
        span_text, _, frame = r.partition("@")
        if not frame.strip().isdigit():
            raise FaceStudioError(f"--replace {r!r}: give FIRST:LAST@FRAME, e.g. 60:90@75")
        edits.append({"op": "replace", "span": _span(span_text, "--replace"), "frame": int(frame)})
    return edits


def checked_edits(args) -> list[dict]:
    """The edits of the arguments (or those stored beside the track), each checked against the
    track's expressions and frames: an unknown name or a frame outside the clip is an error
    before any work."""
    doc = load_track_results(args.track)
    if doc is None:
        raise FaceStudioError(f"{args.track} holds no track.json (run facestudio track first)")
    edits = edits_from_args(args)
    if not edits:
        stored = load_edits(args.track)
        if stored is None or not stored["edits"]:
            raise FaceStudioError(
                "nothing to edit: give --scale EXPRESSION=FACTOR or --replace FIRST:LAST@FRAME "
                f"(or store edits in {Path(args.track) / 'edits.json'})"
            )
        edits = stored["edits"]
    names = doc["model"]["expressions"]
    for e in edits:
        check_edit(e, names, len(doc["frames"]))
    return edits


def run(args) -> int:
    edits = checked_edits(args)
    out = Path(args.out)
    video = out if out.suffix.lower() in VIDEO_SUFFIXES else None
    frames_dir = None if video else out
    outputs = [out] if video is None else [out, out.with_name(out.stem + "_frames")]
    check_writable(out.absolute().parent if video else out, args.track)
    smooth = None if args.no_smooth else SmoothOptions(second_difference=args.smoothness)
    with command_progress(args, NAME) as progress, new_outputs([*outputs, Path(args.track) / "edits.json"]):
        report = edit_track(
            args.track,
            edits,
            smooth=smooth,
            out_video=video,
            frames_dir=frames_dir,
            project=args.project,
            progress=progress.counter,
        )
    if args.json:
        print(json.dumps(report.to_json()))
        return 0
    print(f"{report.edited} of {report.frames} frames edited; PNG frames in {report.frames_dir}")
    if report.video is not None:
        print(f"video: {report.video} ({'audio copied' if report.audio else 'the footage has no audio'})")
    if report.filled_similar or report.filled_texture:
        print(
            f"pixels the clip did not show: {report.filled_similar} from the most similar frame, "
            f"{report.filled_texture} from the model's texture"
        )
    print(f"edits stored in {report.edits_json}")
    return 0


def add_parser(sub) -> None:
    e = sub.add_parser(
        NAME,
        help="edit the expressions of a tracked video (magnify, suppress, replace) and "
        "write the edited frames and video",
    )
    e.add_argument("project", help="project file (*.facestudio.json) the video was tracked with")
    e.add_argument(
        "--track",
        type=Path,
        required=True,
        help="the results folder of `facestudio track` (holds track.json); edits.json is written there",
    )
    e.add_argument(
        "--scale",
        action="append",
        metavar="EXPRESSION=FACTOR",
        help="multiply an expression's weight (0: suppress, >1: magnify); repeatable",
    )
    e.add_argument("--span", metavar="FIRST:LAST", help="frames the --scale edits apply to (default: all)")
    e.add_argument(
        "--replace",
        action="append",
        metavar="FIRST:LAST@FRAME",
        help="replace frames FIRST..LAST by an interpolation through FRAME's expression; repeatable",
    )
    e.add_argument(
        "--no-smooth",
        action="store_true",
        help="edit the per-frame tracked weights (default: solve the whole clip smooth first)",
    )
    e.add_argument(
        "--smoothness",
        type=float,
        default=SmoothOptions.second_difference,
        help="second-difference weight of the smooth solve, relative to a frame's data term",
    )
    e.add_argument(
        "--out",
        type=Path,
        required=True,
        help="a video file (.mp4: H.264, the footage's audio copied; PNG frames beside it) or a folder of PNGs",
    )
    add_json_flag(e)
