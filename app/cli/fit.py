"""``facestudio fit``: cameras recovered and the face mesh fitted to the clicked photos.

    facestudio fit PROJECT [--expression NAME] [--no-refine] [--json] [--dry-run]

The photos are checked at load: one whose file is now of another size than the project records
(the clicks are in the recorded photo's pixels) is an error naming it and both sizes, before any
work; a missing photo is a warning (the fit needs only the stored clicks).
"""

from __future__ import annotations

import argparse
import json
import re
import sys
from pathlib import Path

from app.cli.common import add_json_flag, check_writable, column_width, new_files_in, sigint_deferred
from app.cli.progress import command_progress
from photomodel.errors import PhotoError, ProjectError
from photomodel.modeling.fit import FitOptions, fit_expression, fit_order, uses_person_prior
from photomodel.modeling.generic_mesh import load_generic_mesh
from photomodel.modeling.mouth import expression_note
from photomodel.modeling.rbf import deform_vertices
from photomodel.photos.reading import photo_size
from photomodel.prior.face_prior import prior_deformer
from photomodel.project import load_project, record_fit, save_results

NAME = "fit"

#: What a fit under the person prior does with automatic clicks (one photo, or weighed ones).
_PRIOR_NOTE = (
    "automatic clicks move the face off the generic head's shape only as far as the detector is sure "
    "of them, so the RMS against them is about its error"
)


def run(args) -> int:
    project = load_project(args.project)
    if args.expression is not None:
        project.expression(args.expression)  # an unknown name is an error before any work
    # an expression that reuses another's cameras (cameras_from) is fitted after it
    names = fit_order(project, None if args.expression is None else [args.expression])
    mesh = load_generic_mesh()
    project.check_vertices(len(mesh.vertices))
    try:
        project.check_photos()
    except ProjectError as e:  # the fit needs only the clicks; say so and go on
        print(f"facestudio: warning: {e} (fitting from the stored clicks)", file=sys.stderr)
    check_photo_sizes(project, names)
    if not args.dry_run:
        folder = Path(args.project).absolute().parent
        check_writable(folder, folder / "results")
    results = _fit_all(args, project, names, mesh)
    out = {"project": str(Path(args.project)), "expressions": []}
    for name, result in results:
        entry = {"name": name, **result.report}
        entry["cameras"] = {pid: c.to_dict() for pid, c in zip(result.photo_ids, result.cameras, strict=True)}
        out["expressions"].append(entry)
        if not args.json:
            print(format_report(name, result.report, result.report.get("dropped", [])))
    if not args.dry_run:
        # the meshes, then the project file; Ctrl-C waits until this is done
        results_dir = Path(args.project).absolute().parent / "results"
        with sigint_deferred() as interrupted, new_files_in(results_dir):  # a refused write leaves no new mesh
            save_results(project, fits={name: result.vertices for name, result in results}, faces=mesh.faces)
        if interrupted:
            print("facestudio: interrupted while saving; the results were saved completely", file=sys.stderr)
        if not args.json:
            print(f"saved results into {args.project}")
    if args.json:
        print(json.dumps(out, indent=1))
    return 0


def _fit_all(args, project, names: list[str], mesh) -> list:
    """``[(name, FitResult)]`` of every expression in ``names``, in order, recorded in ``project``."""
    results = []
    options = FitOptions(
        refine=not args.no_refine,
        weigh_auto_clicks=args.weigh_auto_clicks,
        person_prior=not args.no_person_prior,
    )
    # the localised face prior (seed 004) wraps the RBF deformation; every click is still met
    deform = prior_deformer(mesh, deform_vertices) if args.face_prior else None
    with command_progress(args, NAME) as progress:
        for i, name in enumerate(names):

            def stage(label, frac, i=i, name=name):  # which expression, and the whole run's fraction
                progress(f"{name} ({i + 1}/{len(names)}): {label}", (i + frac) / len(names))

            result = fit_expression(project, name, mesh, options, progress=stage, deform=deform)
            results.append((name, result))
            # in memory at once: an expression fitted next may take its cameras from this one
            record_fit(project, name, result)
    return results


def check_photo_sizes(project, names: list[str]) -> None:
    """Raise :class:`ProjectError` naming each photo of ``names`` whose file is now of another
    size than the project records (the clicks are in the recorded size's pixels). Missing or
    unreadable photos are left to :meth:`Project.check_photos`'s warning."""
    problems = []
    for name in names:
        for photo in project.expression(name).photos:
            path = project.photo_path(photo)
            if not path.is_file():
                continue
            try:
                w, h = photo_size(path)
            except PhotoError:
                continue
            if (w, h) != (photo.width, photo.height):
                problems.append(
                    f"expression {name!r}, photo {photo.id!r}: {path} is now {w}x{h} pixels but the project's "
                    f"clicks are on a {photo.width}x{photo.height} photo"
                )
    if problems:
        raise ProjectError(
            "; ".join(problems) + ": the photo file was replaced since it was added; put the original back, "
            "or add the new photo again (facestudio add-photos) and click it"
        )


def format_report(expr_name: str, report: dict, dropped: list[str]) -> str:
    """The human table of one expression's fit: RMS, cameras, suspect clicks, views, worst points."""
    lines = [
        f"expression {expr_name!r}: reprojection RMS {report['rms_px']:.3f} px "
        f"(pose features {report['pose']['rms_px']:.3f} px, {report['pose']['sweeps']} sweeps)"
    ]
    if report.get("cameras_from"):
        lines.append(f"  cameras of expression {report['cameras_from']!r} (same rig), kept fixed")
    if report.get("bundle"):
        lines += _camera_lines(report)
    lines += [f"  {line}" for line in expression_note(report)]
    lines += _suspect_lines(report.get("suspect_clicks") or [])
    wid = column_width((v["photo"] for v in report["views"]), "photo")
    lines.append(f"  {'photo':<{wid}} {'RMS px':>8} {'points':>7} {'focal mm':>9}")
    for v in report["views"]:
        rms = "-" if v["rms_px"] is None else f"{v['rms_px']:.3f}"
        lines.append(f"  {v['photo']:<{wid}} {rms:>8} {v['points']:>7} {v['focal_mm']:>9.1f}")
    pts = sorted((p for p in report["points"] if p["rms_px"] is not None), key=lambda p: -p["rms_px"])
    lines.append(f"  worst points (of {len(report['points'])}):")
    fwid = column_width((p["feature"] for p in pts[:10]), "feature")
    for p in pts[:10]:
        tag = " (pose)" if p["pose"] else ""
        lines.append(f"    {p['feature']:<{fwid}} {p['rms_px']:7.3f} px in {p['views']} photos{tag}")
    for why in grouped_reasons(dropped):
        lines.append(f"  not used: {why}")
    return "\n".join(lines)


def _camera_lines(report: dict) -> list[str]:
    b = report["bundle"]
    cs = report.get("camera_solve") or {}
    how = f" (start: {cs['start']}, noise σ̂ {cs['sigma_px']:.2f} px)" if cs else ""
    if len(report.get("views", [])) == 1:
        return [
            f"  one photo: its camera placed with {b['points']} clicked features against the generic "
            f"head, whose depth the face takes (one view cannot measure it){how}; {_PRIOR_NOTE} "
            "(drag the ones that are off)"
        ]
    lines = [f"  cameras placed with all {b['points']} features clicked in 2+ photos: {b['rms_px']:.3f} px{how}"]
    if uses_person_prior(cs):
        lines.append(
            f"  the most probable face under the person prior: {_PRIOR_NOTE} (drag the ones that "
            "are off; --no-person-prior fits them as they are)"
        )
    return lines


def _suspect_lines(suspects: list[dict]) -> list[str]:
    if not suspects:
        return []
    fwid = column_width((c["feature"] for c in suspects[:10]), "feature")
    pwid = column_width((c["photo"] for c in suspects[:10]), "photo")
    lines = [f"  suspect clicks ({len(suspects)}, left out of the fit; check them):"]
    for c in suspects[:10]:
        lines.append(f"    {c['feature']:<{fwid}} in {c['photo']:<{pwid}} {c['error_px']:8.1f} px off")
    return lines


def grouped_reasons(reasons: list[str]) -> list[str]:
    """``name: why`` lines that say the same of several features (up to their numbers: "3
    automatic click(s)…" and "4 automatic click(s)…") as one line naming them all, with the first
    one's reason as the example: the 16 jaw points of an automatic project are one line, not 16.
    Other lines are kept as they are, in order (the JSON report keeps every line)."""
    groups: dict[str, list[tuple[str, str]]] = {}
    order: list[str] = []
    for line in reasons:
        name, sep, why = line.partition(": ")
        key = re.sub(r"\d+", "#", why) if sep and " " not in name else line
        if key not in groups:
            order.append(key)
        groups.setdefault(key, []).append((name, why))
    out = []
    for key in order:
        members = groups[key]
        if len(members) < 3:
            out += [f"{name}: {why}" for name, why in members]
        else:
            names = ", ".join(name for name, _ in members)
            out.append(f"{len(members)} features for one reason ({names}), e.g. {members[0][0]}: {members[0][1]}")
    return out


def add_parser(sub) -> None:
    f = sub.add_parser(NAME, help="recover cameras and fit the face mesh to the clicked photos")
    f.add_argument("project", help="project file (*.facestudio.json)")
    f.add_argument(
        "--expression",
        help="fit only this expression (default: all; one that reuses another's "
        "cameras, cameras_from, is fitted after it)",
    )
    f.add_argument("--no-refine", action="store_true", help="stop after pose recovery + RBF (no refinement)")
    weigh = f.add_mutually_exclusive_group()
    weigh.add_argument(
        "--weigh-auto-clicks",
        dest="weigh_auto_clicks",
        action="store_const",
        const=True,
        help="weigh automatic clicks by the detector's confidence squared in the camera solve, "
        "and fit the most probable face under the person prior (default: when the photos "
        "with automatic clicks are of views ≥ 40° apart, e.g. a front and a three-quarter "
        "view; near-frontal video frames keep the clicks' RMS lower without)",
    )
    weigh.add_argument(
        "--no-weigh-auto-clicks",
        dest="weigh_auto_clicks",
        action="store_const",
        const=False,
        help="never weigh automatic clicks (every click counts alike)",
    )
    f.add_argument(
        "--no-person-prior",
        action="store_true",
        help="fit weighed automatic clicks as they are instead of the most probable face under the "
        "person prior (with several photos; one photo always uses it): the mesh then follows "
        "the detector's error",
    )
    f.add_argument(
        "--face-prior",
        action=argparse.BooleanOptionalAction,
        default=True,
        help="pull the mesh towards plausible faces (ICT's identities, localised) while every click is "
        "still met (default; benchmarks/bench_prior.py); --no-face-prior: the generic mesh deformed "
        "by the clicks alone, as before",
    )
    add_json_flag(f, "the table")
    f.add_argument("--dry-run", action="store_true", help="report only; do not write into the project")
