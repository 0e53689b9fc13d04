"""``facestudio texture``: the texture of each fitted expression from the photos, and its exports.

    facestudio texture PROJECT [--expression NAME] [--size 1024] [--json]

Every file is encoded in memory first, then all are written (each atomically) with the project
file last (:func:`photomodel.project.save_results`).
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

from app.cli.common import add_json_flag, check_writable, new_outputs, sigint_deferred
from app.cli.progress import command_progress
from photomodel.errors import FaceStudioError
from photomodel.modeling.generic_mesh import load_generic_mesh
from photomodel.project import load_project, save_results
from photomodel.texturing.job import TEXTURE_SIZES, encode_texture_outputs, fitted_expressions, texture_expression

NAME = "texture"


def run(args) -> int:
    lo, hi = TEXTURE_SIZES
    if not lo <= args.size <= hi:
        raise FaceStudioError(f"--size {args.size}: the texture size must be between {lo} and {hi} texels")
    project = load_project(args.project)
    names = fitted_expressions(project, args.expression)
    folder = Path(args.project).absolute().parent
    check_writable(folder, folder / "results")
    prepared = _prepare(args, project, names)
    # commit: every file atomically, then the project; Ctrl-C waits until this is done
    written = [path for _name, _job, files, _rel, _report in prepared for path in files]
    with sigint_deferred() as interrupted, new_outputs(written):  # a refused write leaves no new file behind
        save_results(project, textures=[(job, files, rel) for _name, job, files, rel, _report in prepared])
    if interrupted:
        print("facestudio: interrupted while saving; the results were saved completely", file=sys.stderr)
    out = {"project": str(Path(args.project)), "expressions": []}
    for name, _job, _files, rel, report in prepared:
        out["expressions"].append({"name": name, "size": args.size, **report, "files": _files_of(rel)})
        if not args.json:
            _print_expression(args, name, rel, report)
    if args.json:
        print(json.dumps(out, indent=1))
    else:
        print(f"saved results into {args.project}")
    return 0


def _prepare(args, project, names: list[str]) -> list[tuple]:
    """``[(name, job, files, rel, report)]``: each expression textured and its files encoded."""
    generic = load_generic_mesh()
    prepared = []
    with command_progress(args, NAME) as progress:
        for i, name in enumerate(names):

            def stage(label, frac, i=i, name=name):
                progress(f"{name} ({i + 1}/{len(names)}): {label}", (i + frac) / len(names))

            # §5.2.4: ears, hair and neck from the single best photo (needs the generic topology)
            job = texture_expression(
                project,
                name,
                args.size,
                face_mask=generic.face_mask,
                progress=lambda label, f, stage=stage: stage(label, 0.8 * f),
            )
            stage("encoding exports", 0.8)
            files, rel = encode_texture_outputs(project, job)
            prepared.append((name, job, files, rel, job.report))
        progress("done", 1.0)
    return prepared


def _files_of(rel: dict) -> dict:
    keys = ("image", "weight_maps", "obj", "mtl", "glb", "ply")
    return dict(zip(("texture", *keys[1:]), (rel[k] for k in keys), strict=True))


def _print_expression(args, name: str, rel: dict, report: dict) -> None:
    print(
        f"expression {name!r}: {args.size}x{args.size} texture from {len(report['photos'])} photos "
        f"({', '.join(report['photos'])}), {report['coverage']:.1%} of the surface seen, "
        f"{report['extract_s']:.2f} s"
    )
    print(f"  texture  {rel['image']}")
    for pid, path in rel["weight_maps"].items():
        print(f"  weights  {path}  ({pid})")
    print(f"  exports  {rel['obj']} (+ .mtl), {rel['glb']}, {rel['ply']}")


def add_parser(sub) -> None:
    t = sub.add_parser(
        NAME,
        help="extract the texture of the fitted face from the photos and export it (OBJ+MTL+PNG, glb, coloured PLY)",
    )
    t.add_argument("project", help="project file (*.facestudio.json), fitted with `facestudio fit`")
    t.add_argument("--expression", help="texture only this expression (default: every fitted one)")
    t.add_argument("--size", type=int, default=1024, help="texture size in texels per side (default 1024)")
    add_json_flag(t)
