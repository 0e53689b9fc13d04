"""``facestudio rig``: the ARKit-style rig of the fitted neutral, stored in the project.

    facestudio rig PROJECT [--neutral NAME] [--json]

ICT-FaceKit's expressions are put onto the fitted neutral (:mod:`photomodel.rig`) and stored in
the project (``results/rig.npz``, format version 4).
"""

from __future__ import annotations

import json
import time
from pathlib import Path

import numpy as np

from app.cli.common import add_json_flag, check_writable
from app.cli.progress import command_progress
from photomodel.errors import ProjectError
from photomodel.exchange.mesh import read_mesh
from photomodel.modeling.generic_mesh import load_generic_mesh
from photomodel.project import load_project, save_project, store_rig
from photomodel.rig.build import RigBuilder
from tracking.face_from_project import model_expressions

NAME = "rig"


def run(args) -> int:
    project = load_project(args.project)
    neutral = args.neutral or model_expressions(project)[0]
    result = project.expression(neutral).result
    if result is None or not result.mesh_obj:
        raise ProjectError(f"expression {neutral!r} is not fitted; run `facestudio fit` first")
    folder = Path(args.project).absolute().parent
    check_writable(folder, folder / "results")
    with command_progress(args, NAME) as progress:
        progress(f"{neutral}: reading the fitted mesh", 0.0)
        vertices, _faces = read_mesh(project.resolve(result.mesh_obj))
        progress(f"{neutral}: deformation transfer of the ARKit shapes", 0.05)
        t0 = time.perf_counter()
        rig = RigBuilder(load_generic_mesh()).rig(vertices)
        report = {**rig.report, "seconds": round(time.perf_counter() - t0, 2)}
        progress(f"{neutral}: saving", 0.95)
        store_rig(project, neutral=neutral, names=rig.names, deltas=rig.deltas, report=report)
        save_project(project)
        progress(f"{neutral}: saving", 1.0)
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


def add_parser(sub) -> None:
    r = sub.add_parser(
        NAME,
        help="ARKit-style blend shapes on the fitted neutral (ICT-FaceKit by deformation "
        "transfer), stored in the project",
    )
    r.add_argument("project", help="project file (*.facestudio.json) with its neutral fitted")
    r.add_argument("--neutral", help="the expression the rig displaces (default: 'neutral', else the first)")
    add_json_flag(r)
