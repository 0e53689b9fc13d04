"""``facestudio clone``: one project's tracked performance on another project's face.

    facestudio clone --from A.facestudio.json --track A/results/track_x/ --to B.facestudio.json
                     [--method multilinear|mapping|displacement|names] [--out DIR] [--json]

Writes B's tracking results (``track.json`` + ``track.csv``, the format of ``facestudio track``; default
``<B's folder>/results/<track folder>_from_<A>``) so that ``edit`` and ``export --glb --track`` take them,
and ``side_by_side.mp4`` there (A's frames | B rendered with B's texture; ``--no-video`` skips it);
A is added to B's ``people`` (the project file's references to other projects).
The logic is :mod:`tracking.clone` (Qt-free); ``multilinear`` needs the model file
(``python -m photomodel.people.model_file``), ``names`` a rig in both projects (``facestudio rig``).
Standalone module with ``add_parser(subparsers)`` / ``run(args)`` for the CLI package.
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import numpy as np

from app.cli.common import check_writable
from photomodel.errors import FaceStudioError
from photomodel.people.model_file import MODEL_PEOPLE, model_path
from photomodel.people.multilinear import MultilinearModel
from photomodel.project import load_project, load_rig_shapes, save_project
from tracking.arkit_face import model_for_results
from tracking.clone import METHODS, cloned_results, map_faces, performance_faces, side_by_side_frames, weights_of_faces
from tracking.edit_video import write_video
from tracking.face_from_project import face_model_from_project
from tracking.track_result import load_track_results, save_results

__all__ = ["add_parser", "run"]


NAME = "clone"


def _out_folder(args) -> Path:
    """B's results folder: ``--out``, else ``<B's folder>/results/<track>_from_<A>``."""
    if args.out:
        return Path(args.out)
    a_stem = Path(args.source).stem.split(".")[0]
    return Path(args.to).absolute().parent / "results" / f"{Path(args.track).name}_from_{a_stem}"


def run(args) -> int:
    """Clone the performance (see the module notes); prints a summary (JSON with ``--json``)."""
    t0 = time.perf_counter()
    project_a, project_b = load_project(args.source), load_project(args.to)
    out = _out_folder(args)
    check_writable(out)  # before the long work
    doc_a = load_track_results(args.track)
    if doc_a is None or not doc_a["frames"]:
        raise FaceStudioError(f"{args.track} holds no tracked frames (track.json); run `facestudio track` first")
    model_a = model_for_results(project_a, doc_a)  # photographed expressions, or the rig's shapes (ARKit terms)
    model_b, _ = face_model_from_project(project_b)
    faces = performance_faces(model_a, doc_a)
    people_model = rigs = None
    if args.method == "multilinear":
        path = model_path(MODEL_PEOPLE)
        if not path.is_file():
            raise FaceStudioError(
                f"the multilinear model {path} is missing; build it: python -m photomodel.people.model_file"
            )
        people_model = MultilinearModel.load(path)
    elif args.method == "names":
        rigs = (load_rig_shapes(project_a), load_rig_shapes(project_b))
    mapped = map_faces(faces, model_a, model_b, args.method, people_model=people_model, rigs=rigs)
    W = weights_of_faces(model_b, mapped)
    said = np.array([model_b.blend_geometry(model_b.vertex_weights(w)) for w in W])
    residual = np.linalg.norm((said - mapped)[:, model_b.face_mask], axis=2).mean()
    out.mkdir(parents=True, exist_ok=True)
    cloned_from = {
        "project": str(Path(args.source).absolute()),
        "track": str(Path(args.track).absolute()),
        "method": args.method,
    }
    doc = cloned_results(doc_a, model_b, args.to, W, cloned_from)
    files = save_results(out, doc, bool(doc_a.get("complete")))
    if project_b.add_person(args.source) is not None:  # B refers to A (format version 6, `people`)
        save_project(project_b)
    files = {k: str(v) for k, v in files.items()}
    if not args.no_video:  # A's frames | B rendered with B's texture
        files["video"] = str(out / "side_by_side.mp4")
        write_video(files["video"], side_by_side_frames(doc, model_b, W), doc["video"].get("fps") or 25.0)
    summary = {
        "out": str(out),
        "frames": len(doc["frames"]),
        "method": args.method,
        "expressions": list(model_b.names),
        "weights_residual_mm": round(float(residual), 4),
        "files": files,
        "seconds": round(time.perf_counter() - t0, 2),
    }
    if args.json:
        print(json.dumps(summary, indent=1))
    else:
        print(
            f"cloned {summary['frames']} frames of {args.track} onto {args.to} ({args.method}) -> {out} "
            f"(B's expressions say the mapped faces to {summary['weights_residual_mm']:.3f} mm)"
        )
    return 0


def add_parser(subparsers) -> argparse.ArgumentParser:
    """The ``clone`` subcommand on the CLI's ``subparsers``."""
    c = subparsers.add_parser(NAME, help="put one project's tracked performance on another project's face")
    c.add_argument(
        "--from", dest="source", required=True, type=Path, help="project A (*.facestudio.json) that was tracked"
    )
    c.add_argument(
        "--track", required=True, type=Path, help="A's results folder of `facestudio track` (holds track.json)"
    )
    c.add_argument("--to", required=True, type=Path, help="project B (*.facestudio.json) to put the performance on")
    c.add_argument(
        "--method", choices=METHODS, default="multilinear", help="how A's faces become B's (default multilinear)"
    )
    c.add_argument("--out", type=Path, help="B's results folder (default <B>/results/<track>_from_<A>)")
    c.add_argument("--no-video", action="store_true", help="do not write the side-by-side video")
    c.add_argument("--json", action="store_true", help="print a JSON summary")
    return c
