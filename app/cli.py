"""The ``facestudio`` command.

    facestudio fit PROJECT [--expression NAME] [--no-refine] [--json] [--dry-run]
    facestudio sample-data

Qt is imported only by commands that open windows; ``fit`` runs anywhere.
"""

from __future__ import annotations

import argparse
import json
import signal
import sys
from pathlib import Path

from photomodel.errors import FaceStudioError, ProjectError


def _progress_bar(enabled: bool):
    """A tqdm bar over pipeline stages on stderr (silent with --json unless a TTY)."""
    if not enabled:
        return None, lambda stage, frac: None
    from tqdm import tqdm

    bar = tqdm(total=100, file=sys.stderr, bar_format="{desc:<32} {bar} {percentage:3.0f}%", leave=False)

    def update(stage: str, frac: float) -> None:
        bar.set_description_str(stage)
        bar.n = int(round(frac * 100))
        bar.refresh()

    return bar, update


def _format_report(expr_name: str, report: dict, dropped: list[str]) -> str:
    lines = [
        f"expression {expr_name!r}: reprojection RMS {report['rms_px']:.3f} px "
        f"(pose features {report['pose']['rms_px']:.3f} px, {report['pose']['sweeps']} sweeps)"
    ]
    lines.append(f"  {'photo':<24} {'RMS px':>8} {'points':>7} {'focal mm':>9}")
    for v in report["views"]:
        rms = "-" if v["rms_px"] is None else f"{v['rms_px']:.3f}"
        lines.append(f"  {v['photo']:<24} {rms:>8} {v['points']:>7} {v['focal_mm']:>9.1f}")
    pts = sorted((p for p in report["points"] if p["rms_px"] is not None), key=lambda p: -p["rms_px"])
    lines.append(f"  worst points (of {len(report['points'])}):")
    for p in pts[:10]:
        tag = " (pose)" if p["pose"] else ""
        lines.append(f"    {p['feature']:<22} {p['rms_px']:7.3f} px in {p['views']} photos{tag}")
    for why in dropped:
        lines.append(f"  not used: {why}")
    return "\n".join(lines)


def cmd_fit(args) -> int:
    from photomodel.fit import FitOptions, fit_expression, store_fit_result
    from photomodel.generic_mesh import load_generic_mesh
    from photomodel.project import load_project, save_project

    project = load_project(args.project)
    names = [e.name for e in project.expressions] if args.expression is None else [args.expression]
    mesh = load_generic_mesh()
    project.check_vertices(len(mesh.vertices))
    try:
        project.check_photos()
    except ProjectError as e:  # the fit needs only the clicks; say so and go on
        print(f"facestudio: warning: {e} (fitting from the stored clicks)", file=sys.stderr)
    out = {"project": str(Path(args.project)), "expressions": []}
    bar, progress = _progress_bar(not args.json or sys.stderr.isatty())
    try:
        results = []
        for name in names:
            options = FitOptions(refine=not args.no_refine)
            result = fit_expression(project, name, mesh, options, progress=progress)
            results.append((name, result))
    finally:
        if bar is not None:
            bar.close()
    for name, result in results:
        if not args.dry_run:
            store_fit_result(project, name, result, mesh.faces)
        entry = {"name": name, **result.report}
        entry["cameras"] = {pid: c.to_dict() for pid, c in zip(result.photo_ids, result.cameras, strict=True)}
        out["expressions"].append(entry)
        if not args.json:
            print(_format_report(name, result.report, result.report.get("dropped", [])))
    if not args.dry_run:
        save_project(project)
        if not args.json:
            print(f"saved results into {args.project}")
    if args.json:
        print(json.dumps(out, indent=1))
    return 0


def cmd_sample_data(args) -> int:
    from photomodel.sample_data import sample_data_dir

    print(sample_data_dir())
    return 0


def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="facestudio", description="Face Studio: faces from photographs.")
    sub = p.add_subparsers(dest="command", required=True)
    f = sub.add_parser("fit", help="recover cameras and fit the face mesh to the clicked photos")
    f.add_argument("project", help="project file (*.facestudio.json)")
    f.add_argument("--expression", help="fit only this expression (default: all)")
    f.add_argument("--no-refine", action="store_true", help="stop after pose recovery + RBF (no refinement)")
    f.add_argument("--json", action="store_true", help="print one JSON object instead of the table")
    f.add_argument("--dry-run", action="store_true", help="report only; do not write into the project")
    f.set_defaults(func=cmd_fit)
    s = sub.add_parser("sample-data", help="fetch, verify and cache the sample data; print its folder")
    s.set_defaults(func=cmd_sample_data)
    return p


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    signal.signal(signal.SIGINT, signal.default_int_handler)
    try:
        return args.func(args)
    except FaceStudioError as e:
        print(f"facestudio: error: {e}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("facestudio: cancelled; nothing was written", file=sys.stderr)
        return 130


if __name__ == "__main__":
    sys.exit(main())
