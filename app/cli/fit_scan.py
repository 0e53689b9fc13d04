"""``facestudio fit-scan``: fit the studio's face mesh to a 3D scan and store it as the neutral's fit.

    facestudio fit-scan PROJECT scan.ply|obj|stl [--expression NAME] [--landmarks FILE]
                        [--unit m|dm|inch|cm|mm] [--json]

The scan (a mesh or a point cloud, holes, noise and stray points allowed) is fitted with the
localised face prior (:mod:`photomodel.prior.scan_fit`). Landmarks: ``--landmarks`` (a JSON
list or a text file of 68 ``x y z`` rows in the scan's units, iBUG order), else the project's
fitted expression's mesh (from its photos) is aligned onto the scan and its landmark vertices
used, else the generic head's. Units: ``--unit``, else from the landmarks' scale, else the scan's
size (a head is ~0.3 m across). The result is moved into the frame of the expression's photo fit
(the similarity of the two meshes' face regions: the cameras stay valid, so texturing from the
photos works), or the generic head's frame when the expression has no fit, and stored as the
expression's fit (mesh files + project): :func:`photomodel.prior.scan_expression.fit_scan_as_expression`,
which the studio's *Fit → Add scan…* runs too. A scan with no face in it: exit status 2, nothing written.
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np

from app.cli.common import check_writable
from photomodel.errors import ProjectError
from photomodel.exchange.mesh import read_mesh
from photomodel.modeling.generic_mesh import load_generic_mesh
from photomodel.prior.scan_expression import fit_scan_as_expression
from photomodel.prior.scan_fit import UNITS
from photomodel.project import load_project
from photomodel.project.results import save_results

__all__ = ["add_parser", "run"]


NAME = "fit-scan"


def add_parser(subparsers) -> None:
    """Register ``fit-scan`` on the CLI's sub-parsers."""
    p = subparsers.add_parser(
        NAME, help="fit the face mesh to a 3D scan (PLY/OBJ/STL; holes, noise allowed) as an expression's fit"
    )
    p.add_argument("project", help="project file (*.facestudio.json)")
    p.add_argument("scan", help="the scan: a mesh or point cloud (.ply, .obj, .stl)")
    p.add_argument("--expression", help="the expression whose fit the scan becomes (default: the first, the neutral)")
    p.add_argument("--landmarks", help="68 iBUG landmarks on the scan (JSON list or text, x y z per row, scan units)")
    p.add_argument("--unit", choices=sorted(UNITS), help="the scan's unit (default: guessed from its size)")
    p.add_argument("--json", action="store_true", help="print one JSON object instead of the summary")


def _read_landmarks(path: str) -> np.ndarray:
    text = Path(path).read_text(encoding="utf-8")
    try:
        L = np.asarray(json.loads(text), float)
    except ValueError:
        L = np.loadtxt(path, dtype=float)
    if L.shape != (68, 3) or not np.all(np.isfinite(L)):
        raise ProjectError(f"{path}: need 68 rows of x y z (iBUG order), got shape {L.shape}")
    return L


def run(args) -> int:
    project = load_project(args.project)
    folder = Path(args.project).absolute().parent
    check_writable(folder, folder / "results")  # before the fit, not after it
    name = args.expression or project.expressions[0].name
    expression = project.expression(name)
    mesh = load_generic_mesh()
    template = None
    if expression.result is not None and expression.result.mesh_obj:
        template = read_mesh(project.resolve(expression.result.mesh_obj))[0]
    made = fit_scan_as_expression(
        project,
        name,
        args.scan,
        mesh,
        template=template,
        landmarks=_read_landmarks(args.landmarks) if args.landmarks else None,
        unit_mm=UNITS[args.unit] if args.unit else None,
    )
    expression.result = made.result
    save_results(project, fits={name: made.vertices}, faces=mesh.faces)
    report = made.report
    out = {"project": str(Path(args.project)), "expression": name, **report}
    if args.json:
        print(json.dumps(out, indent=1))
    else:
        print(
            f"{name}: fitted to {args.scan} (unit {report['unit']}, {report['face_inliers']:.0%} of the face "
            f"on the scan, {report['seconds']:.1f} s); stored as the expression's fit",
            file=sys.stdout,
        )
    return 0
