"""``facestudio rig`` and ``facestudio export``: the ARKit-style rig and the animated glTF / Live Link CSV.

    facestudio rig PROJECT [--neutral NAME] [--json]
    facestudio export PROJECT --glb out.glb [--track results/track_x/ | --livelink take.csv]
                      [--csv out.csv] [--json]

``rig`` puts ICT-FaceKit's expressions onto the fitted neutral (:mod:`photomodel.rig`) and stores
them in the project (``results/rig.npz``, format version 4). ``export`` writes one mesh with every
blend shape as a morph target (:mod:`tracking.performance`); ``--track`` animates it with a
tracked video (weights, and the head pose in the video camera's frame), ``--livelink`` with a
Live Link Face take (the rig's weights; the head turned by its yaw/pitch/roll), and ``--csv``
writes the tracked performance as a Live Link Face CSV (the rig's weights fitted to each frame).
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import numpy as np

from photomodel.camera import rodrigues
from photomodel.errors import FaceStudioError, ProjectError
from photomodel.exchange.gltf_animation import Performance, write_rigged_glb
from photomodel.exchange.livelink import ROTATION_COLUMNS, read_livelink_csv, write_livelink_csv
from photomodel.exchange.mesh import read_mesh
from photomodel.modeling.generic_mesh import load_generic_mesh
from photomodel.project import load_project, save_project, store_rig
from photomodel.rig.build import RigBuilder
from photomodel.rig.ict import ARKIT_SHAPES
from tracking.face_from_project import model_expressions
from tracking.performance import arkit_weights, blend_shapes, track_performance, tracked_arkit_weights
from tracking.track_result import FACING, load_track_results

__all__ = ["add_rig_parsers", "cmd_rig", "cmd_export"]


def cmd_rig(args) -> int:
    """``facestudio rig``: the rig of the fitted neutral, stored in the project."""
    project = load_project(args.project)
    neutral = args.neutral or model_expressions(project)[0]
    result = project.expression(neutral).result
    if result is None or not result.mesh_obj:
        raise ProjectError(f"expression {neutral!r} is not fitted; run `facestudio fit` first")
    vertices, _faces = read_mesh(project.resolve(result.mesh_obj))
    t0 = time.perf_counter()
    rig = RigBuilder(load_generic_mesh()).rig(vertices)
    report = {**rig.report, "seconds": round(time.perf_counter() - t0, 2)}
    store_rig(project, neutral=neutral, names=rig.names, deltas=rig.deltas, report=report)
    save_project(project)
    moved = np.linalg.norm(rig.deltas, axis=2).max(axis=1)
    out = {
        "project": str(args.project),
        "neutral": neutral,
        "shapes": len(rig.names),
        "file": project.rig.file,
        "photographed": [e.name for e in project.expressions if e.name != neutral and e.result is not None],
        "max_displacement_mm": dict(zip(rig.names, np.round(moved, 2).tolist(), strict=True)),
        **report,
    }
    if args.json:
        print(json.dumps(out, indent=1))
    else:
        print(
            f"rig of {neutral!r}: {len(rig.names)} ARKit shapes (ICT-FaceKit by deformation transfer) in "
            f"{project.rig.file}, {report['seconds']:.1f} s"
        )
        print(
            f"  ICT registered onto the generic mesh: landmark RMS {report['landmark_rms_rigid_mm']:.2f} mm "
            f"(similarity) -> {report['landmark_rms_mm']:.2f} mm (non-rigid)"
        )
        print(f"  ICT identity fitted to the neutral: {report['identity_rms_mm']:.2f} mm RMS over the face")
        print(f"  photographed expressions kept beside it: {', '.join(out['photographed']) or 'none'}")
    return 0


def _livelink_performance(path: Path, names: list[str], fps: float, focal_px: float = 1000.0) -> Performance:
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


def cmd_export(args) -> int:
    """``facestudio export``: the rigged (and animated) glb, and the Live Link CSV of a track."""
    if args.track and args.livelink:
        raise FaceStudioError("give --track or --livelink, not both")
    if args.csv and not args.track:
        raise FaceStudioError("--csv writes a tracked performance: give --track too")
    project = load_project(args.project)
    doc = load_track_results(args.track) if args.track else None
    if args.track and doc is None:
        raise FaceStudioError(f"{args.track}: no track.json; run `facestudio track` first")
    names = doc["model"]["expressions"] if doc else None
    shapes, model = blend_shapes(project, names)
    if args.csv and shapes.rig_shapes == 0:  # before anything is written
        raise FaceStudioError(
            "--csv writes the rig's ARKit weights: the project has no rig; run `facestudio rig` first"
        )
    perf = None
    if doc is not None:
        perf = track_performance(doc, shapes.names)
    elif args.livelink:
        perf = _livelink_performance(args.livelink, shapes.names, args.fps)
    write_rigged_glb(
        args.glb,
        shapes.neutral,
        shapes.faces,
        shapes.deltas,
        shapes.names,
        uv=shapes.uv,
        texture=shapes.texture_png,
        performance=perf,
    )
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
        rig_names = shapes.names[: shapes.rig_shapes]
        arkit = tracked_arkit_weights(doc, rig_names)
        if arkit is None:  # a track of the photographed expressions: said in ARKit's shapes by fitting
            arkit = arkit_weights(shapes, perf.weights, model.face_mask)
        full = np.zeros((len(arkit), len(ARKIT_SHAPES)))
        full[:, [ARKIT_SHAPES.index(n) for n in shapes.names[: shapes.rig_shapes]]] = arkit
        head = np.radians([r["head_rotation_deg"] for r in doc["frames"]])  # pitch, yaw, roll
        rot = np.zeros((len(full), len(ROTATION_COLUMNS)))
        rot[:, :3] = head[:, [1, 0, 2]]
        write_livelink_csv(args.csv, full, float(doc["video"]["fps"]), rot)
        out["csv"] = str(args.csv)
    if args.json:
        print(json.dumps(out, indent=1))
    else:
        print(
            f"wrote {args.glb}: {out['targets']} morph targets ({shapes.rig_shapes} rig shapes, "
            f"{shapes.photographed} photographed expression x region), {out['frames']} animated frames"
        )
        if args.csv:
            print(f"wrote {args.csv}: Live Link Face CSV, {out['frames']} frames")
    return 0


def add_rig_parsers(sub: argparse._SubParsersAction) -> None:
    """The ``rig`` and ``export`` sub-commands."""
    r = sub.add_parser(
        "rig",
        help="ARKit-style blend shapes on the fitted neutral (ICT-FaceKit by deformation "
        "transfer), stored in the project",
    )
    r.add_argument("project", help="project file (*.facestudio.json) with its neutral fitted")
    r.add_argument("--neutral", help="the expression the rig displaces (default: 'neutral', else the first)")
    r.add_argument("--json", action="store_true", help="print one JSON object instead of the summary")
    r.set_defaults(func=cmd_rig)
    e = sub.add_parser(
        "export",
        help="the face with every blend shape as a glTF morph target, animated by a "
        "track or a Live Link take; a track as Live Link CSV",
    )
    e.add_argument("project", help="project file (*.facestudio.json), fitted and textured")
    e.add_argument("--glb", type=Path, required=True, help="the binary glTF file to write (*.glb)")
    e.add_argument("--track", type=Path, help="a tracking results folder (results/track_<video>/): animate it")
    e.add_argument("--livelink", type=Path, help="a Live Link Face CSV take: animate the rig with it")
    e.add_argument("--fps", type=float, default=60.0, help="the --livelink take's frame rate (default 60)")
    e.add_argument("--csv", type=Path, help="also write the --track performance as a Live Link Face CSV")
    e.add_argument("--json", action="store_true", help="print one JSON object instead of the summary")
    e.set_defaults(func=cmd_export)
