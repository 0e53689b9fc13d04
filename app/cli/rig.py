"""``facestudio rig``: the ARKit-style rig of the fitted neutral, stored in the project.

    facestudio rig PROJECT [--neutral NAME] [--method transfer|multilinear] [--json]

``transfer`` (the default): ICT-FaceKit's expressions are put onto the fitted neutral by deformation
transfer (:mod:`photomodel.rig`). ``multilinear``: the neutral and the other fitted (photographed)
expressions, registered onto the neutral as the tracker's face model registers them, place the person
in the multilinear model's identity space (seed 000) and the model predicts the 51 shapes
(:mod:`photomodel.people.personal_rig`; the model file is built beforehand by
``python -m photomodel.people.model_file``). Either is stored in the project the same way
(``results/rig.npz``, format version 4; the rig record's ``report.method`` says which), so ``track``
and ``export`` take it alike.
"""

from __future__ import annotations

import json
import time
from pathlib import Path

import numpy as np

from app.cli.common import add_json_flag, check_writable
from app.cli.progress import command_progress
from photomodel.errors import FaceStudioError, ProjectError
from photomodel.exchange.mesh import read_mesh
from photomodel.modeling.generic_mesh import load_generic_mesh
from photomodel.people.model_file import MODEL_PEOPLE, model_path
from photomodel.people.multilinear import MultilinearModel
from photomodel.people.personal_rig import predict_rig
from photomodel.project import load_project, read_fitted_mesh, save_project, store_rig
from photomodel.rig.build import RigBuilder
from tracking.face_from_project import model_expressions, register_expression

NAME = "rig"
#: How the shapes are made (the first is the default).
METHODS = ("transfer", "multilinear")


def photographed_faces(project, neutral: str, vertices: np.ndarray) -> dict:
    """{name: (n, 3) mm} the project's other fitted expressions, each registered onto the neutral's
    ``vertices`` over the face (a similarity, rigid when it was fitted with the neutral's cameras)."""
    weight = load_generic_mesh().face_mask.astype(float)
    out = {}
    for e in project.expressions:
        if e.name == neutral or e.result is None or not e.result.mesh_obj:
            continue
        V, _ = read_fitted_mesh(project, e.name)
        if V.shape != vertices.shape:
            raise ProjectError(f"expression {e.name!r}: its fitted mesh is not on the generic mesh; fit it again")
        out[e.name], _ = register_expression(V, vertices, weight, scale=e.cameras_from != neutral)
    return out


def multilinear_rig(project, neutral: str, vertices: np.ndarray):
    """The rig the multilinear model predicts (:func:`photomodel.people.personal_rig.predict_rig`)."""
    path = model_path(MODEL_PEOPLE)
    if not path.is_file():
        raise FaceStudioError(
            f"the multilinear model {path} is missing; build it: python -m photomodel.people.model_file"
        )
    model = MultilinearModel.load(path)
    if model.mean.shape != (vertices.size,):
        raise FaceStudioError(f"the multilinear model {path} is of another mesh; build it again")
    return predict_rig(model, vertices, photographed_faces(project, neutral, vertices))


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
        t0 = time.perf_counter()
        if args.method == "multilinear":
            progress(f"{neutral}: the ARKit shapes from the multilinear model", 0.05)
            rig = multilinear_rig(project, neutral, vertices)
        else:
            progress(f"{neutral}: deformation transfer of the ARKit shapes", 0.05)
            rig = RigBuilder(load_generic_mesh()).rig(vertices)
            rig.report["method"] = "transfer"
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
        "method": args.method,
        "file": project.rig.file,
        "photographed": [e.name for e in project.expressions if e.name != neutral and e.result is not None],
        "max_displacement_mm": dict(zip(rig.names, np.round(moved, 2).tolist(), strict=True)),
        **report,
    }
    if args.json:
        print(json.dumps(out, indent=1))
    elif args.method == "multilinear":
        print(
            f"rig of {neutral!r}: {len(rig.names)} ARKit shapes predicted by the multilinear model in "
            f"{project.rig.file}, {report['seconds']:.1f} s"
        )
        print(f"  shapes photographed on their own: {', '.join(report['given_shapes']) or 'none'}")
        for name, mix in report["given_mixes"].items():
            print(f"  {name} seen as: {', '.join(f'{k} {v:.2f}' for k, v in mix.items()) or 'the neutral'}")
        return 0
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
    r.add_argument(
        "--method",
        choices=METHODS,
        default=METHODS[0],
        help="deformation transfer of ICT-FaceKit's shapes (default), or the multilinear model's prediction "
        "from the neutral and the photographed expressions",
    )
    add_json_flag(r)
