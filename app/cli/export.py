"""``facestudio export``: the rigged (and animated) glb, and the Live Link CSV of a track.

    facestudio export PROJECT --glb out.glb [--track results/track_x/ | --livelink take.csv]
                      [--csv out.csv] [--json]

One mesh with every blend shape as a morph target (:mod:`tracking.performance`); ``--track``
animates it with a tracked video (weights, and the head pose in the video camera's frame),
``--livelink`` with a Live Link Face take (the rig's weights; the head turned by its
yaw/pitch/roll), and ``--csv`` writes the tracked performance as a Live Link Face CSV (the rig's
weights fitted to each frame). Both files are encoded in memory before either is written, and a
write that fails removes the other: the glb is never left without the CSV asked for with it.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from app.cli.common import add_json_flag, check_file_writable, new_outputs
from app.cli.progress import command_progress
from photomodel.camera import rodrigues
from photomodel.errors import FaceStudioError
from photomodel.exchange.files import write_files
from photomodel.exchange.gltf_animation import Performance
from photomodel.exchange.livelink import ROTATION_COLUMNS, read_livelink_csv
from photomodel.project import load_project
from photomodel.rig.ict import ARKIT_SHAPES
from tracking.performance import blend_shapes, rigged_glb_bytes, track_livelink_bytes, track_performance
from tracking.track_result import FACING, load_track_results

NAME = "export"


def check_args(args) -> None:
    """The arguments checked before any work; FaceStudioError naming the bad one."""
    if args.track and args.livelink:
        raise FaceStudioError("give --track or --livelink, not both")
    if args.csv and not args.track:
        raise FaceStudioError("--csv writes a tracked performance: give --track too")
    if args.glb.suffix.lower() != ".glb":
        raise FaceStudioError(f"--glb {args.glb}: a binary glTF file name must end in .glb")
    if args.livelink is not None and not args.livelink.is_file():
        raise FaceStudioError(f"--livelink {args.livelink} does not exist (give a Live Link Face CSV take)")
    if not args.fps > 0:
        raise FaceStudioError(f"--fps {args.fps}: the take's frame rate must be a positive number")


def check_csv_rig(shapes) -> None:
    """FaceStudioError before anything is written when ``--csv`` is asked of a project without a rig."""
    if shapes.rig_shapes == 0:
        raise FaceStudioError(
            "--csv writes the rig's ARKit weights: the project has no rig; run `facestudio rig` first"
        )


def livelink_performance(path: Path, names: list[str], fps: float, focal_px: float = 1000.0) -> Performance:
    """A Live Link take on the rig's targets; the head at 0.5 m in front of a 1000-px camera, turned."""
    _codes, W, rot = read_livelink_csv(path)
    index = {n: i for i, n in enumerate(names)}
    weights = np.zeros((len(W), len(names)))
    for j, shape in enumerate(ARKIT_SHAPES):
        if shape in index:
            weights[:, index[shape]] = W[:, j]
    yaw, pitch, roll = (rot[:, ROTATION_COLUMNS.index(c)] for c in ("HeadYaw", "HeadPitch", "HeadRoll"))
    R = np.array([rodrigues(np.array([p, y, r])) @ FACING for p, y, r in zip(pitch, yaw, roll, strict=True)])
    t = np.tile([0.0, 0.0, 500.0], (len(W), 1))
    return Performance(np.arange(len(W)) / fps, weights, R, t, focal_px, 1280, 720)


def run(args) -> int:
    check_args(args)
    project = load_project(args.project)
    doc = load_track_results(args.track) if args.track else None
    if args.track and doc is None:
        raise FaceStudioError(f"{args.track}: no track.json; run `facestudio track` first")
    check_file_writable(args.glb, args.csv)
    with command_progress(args, NAME) as progress:
        progress("the face model and its blend shapes", 0.0)
        shapes, model = blend_shapes(project, doc["model"]["expressions"] if doc else None)
        if args.csv:
            check_csv_rig(shapes)
        perf = None
        if doc is not None:
            perf = track_performance(doc, shapes.names)
        elif args.livelink:
            perf = livelink_performance(args.livelink, shapes.names, args.fps)
        files = {}
        if args.csv:
            files[args.csv] = _livelink_csv(doc, shapes, perf, model, progress)
        progress("encoding the glb", 0.9)
        glb = rigged_glb_bytes(shapes, perf)
        progress("writing", 0.95)
        with new_outputs([args.glb, *files]):
            write_files({args.glb: glb, **files})
        progress("writing", 1.0)
    return _report(args, shapes, perf, doc)


def _livelink_csv(doc: dict, shapes, perf: Performance, model, progress) -> bytes:
    """The tracked performance as Live Link Face CSV bytes (:func:`tracking.performance.track_livelink_bytes`)."""
    return track_livelink_bytes(
        doc,
        shapes,
        perf,
        model.face_mask,
        progress=lambda done, n: progress("the rig's weights", 0.1 + 0.8 * done / n, f"frame {done} of {n}"),
    )


def _report(args, shapes, perf, doc) -> int:
    out = {
        "glb": str(args.glb),
        "targets": len(shapes.names),
        "rig_shapes": shapes.rig_shapes,
        "photographed_targets": shapes.photographed,
        "frames": 0 if perf is None else len(perf.times_s),
        "pose_frame": "video camera (glTF camera convention: +Y up, looking along -Z)",
        "arkit_tracked": bool(doc is not None and doc["model"].get("arkit")),
    }
    if args.csv:
        out["csv"] = str(args.csv)
    if args.json:
        print(json.dumps(out, indent=1))
        return 0
    print(
        f"wrote {args.glb}: {out['targets']} morph targets ({shapes.rig_shapes} rig shapes, "
        f"{shapes.photographed} photographed expression x region), {out['frames']} animated frames"
    )
    if args.csv:
        print(f"wrote {args.csv}: Live Link Face CSV, {out['frames']} frames")
    return 0


def add_parser(sub) -> None:
    e = sub.add_parser(
        NAME,
        help="the face with every blend shape as a glTF morph target, animated by a "
        "track or a Live Link take; a track as Live Link CSV",
    )
    e.add_argument("project", help="project file (*.facestudio.json), fitted and textured")
    e.add_argument("--glb", type=Path, required=True, help="the binary glTF file to write (*.glb)")
    e.add_argument("--track", type=Path, help="a tracking results folder (results/track_<video>/): animate it")
    e.add_argument("--livelink", type=Path, help="a Live Link Face CSV take: animate the rig with it")
    e.add_argument("--fps", type=float, default=60.0, help="the --livelink take's frame rate (default 60)")
    e.add_argument("--csv", type=Path, help="also write the --track performance as a Live Link Face CSV")
    add_json_flag(e)
