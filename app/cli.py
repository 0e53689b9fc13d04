"""The ``facestudio`` command.

    facestudio fit PROJECT [--expression NAME] [--no-refine] [--json] [--dry-run]
    facestudio texture PROJECT [--expression NAME] [--size 1024] [--json]
    facestudio sample-data
    facestudio studio [PROJECT]

Qt is imported only by commands that open windows; ``fit`` runs anywhere.
"""

from __future__ import annotations

import argparse
import contextlib
import json
import signal
import sys
import time
from pathlib import Path

from photomodel.errors import FaceStudioError, FitError, ProjectError

#: Texture sizes ``facestudio texture`` accepts (texels per side).
TEXTURE_SIZES = (8, 16384)


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
    if report.get("bundle"):
        b = report["bundle"]
        lines.append(f"  cameras re-estimated with all {b['points']} triangulated points: {b['rms_px']:.3f} px")
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


def _fitted_expressions(project, name: str | None) -> list[str]:
    """The expressions to texture: ``name`` or every fitted one; FitError if not fitted."""
    if name is not None:
        if project.expression(name).result is None:
            raise FitError(f"expression {name!r} has not been fitted yet: run "
                           f"`facestudio fit {project.path}` first")
        return [name]
    names = [e.name for e in project.expressions if e.result is not None]
    if not names:
        raise FitError(f"{project.path.name}: no expression has been fitted yet: run "
                       f"`facestudio fit {project.path}` first")
    return names


def _load_fitted(project, name: str):
    """(vertices (n, 3) mm, faces (m, 3), photo ids, cameras, RGB photos) of a fitted expression.

    Raises ProjectError naming the mesh or photo that is missing, unreadable or of the wrong size.
    """
    import cv2

    from photomodel.mesh_io import read_mesh

    expr = project.expression(name)
    result = expr.result
    if result.mesh_obj is None:
        raise FitError(f"expression {name!r} has no fitted mesh recorded: run `facestudio fit {project.path}`")
    mesh_path = project.resolve(result.mesh_obj)
    if not mesh_path.is_file():
        raise ProjectError(f"expression {name!r}: the fitted mesh {result.mesh_obj} does not exist "
                           f"(looked for {mesh_path}); run `facestudio fit {project.path}` again")
    try:
        vertices, faces = read_mesh(mesh_path)
    except Exception as exc:  # trimesh raises many kinds on a damaged file
        raise ProjectError(f"expression {name!r}: cannot read the fitted mesh {result.mesh_obj}: {exc}") from exc
    ids, cameras, photos = [], [], []
    for photo in expr.photos:
        cam = result.cameras.get(photo.id)
        if cam is None:
            continue  # the fit did not use this photo (no camera was recovered for it)
        path = project.photo_path(photo)
        who = f"expression {name!r}, photo {photo.id!r}"
        if not path.is_file():
            raise ProjectError(f"{who}: {photo.path} does not exist (looked for {path})")
        img = cv2.imread(str(path), cv2.IMREAD_COLOR)
        if img is None:
            raise ProjectError(f"{who}: {photo.path} is not an image OpenCV can read (corrupt or unknown format)")
        if img.shape[:2] != (cam.height, cam.width):
            raise ProjectError(f"{who}: {photo.path} is {img.shape[1]}x{img.shape[0]} but its camera is "
                               f"{cam.width}x{cam.height}; the photo changed since the fit")
        ids.append(photo.id)
        cameras.append(cam)
        photos.append(cv2.cvtColor(img, cv2.COLOR_BGR2RGB))
    if not cameras:
        raise FitError(f"expression {name!r}: no photo has a recovered camera; run `facestudio fit` first")
    return vertices, faces, ids, cameras, photos


def _encode_texture_outputs(project, name: str, vertices, faces, ids, tex) -> tuple[dict, dict]:
    """Encode every file of ``facestudio texture`` in memory: ({abs path: bytes}, relative paths)."""
    from photomodel.exchange.files import encode_png
    from photomodel.exchange.gltf import encode_glb
    from photomodel.exchange.obj import encode_textured_obj
    from photomodel.exchange.ply import encode_colored_ply
    from photomodel.exchange.uv import merge_uv_seams

    rel = project.default_texture_paths(name)
    # per-corner uv in the mesh's face order: the texture's seam-split rendering mesh, merged
    uv = merge_uv_seams(faces, tex.seam_vertices, tex.seam_faces, tex.seam_uv)
    files = {project.resolve(rel["image"]): encode_png(tex.image)}
    for pid, w in zip(ids, tex.weight_maps, strict=True):
        files[project.resolve(rel["weight_maps"][pid])] = encode_png(w)  # black 0 … white 1
    obj = encode_textured_obj(project.resolve(rel["obj"]), vertices, faces, uv, None,
                              texture_path=project.resolve(rel["image"]), check_exists=False)
    files.update(obj.files)  # after the PNG it refers to
    files[project.resolve(rel["glb"])] = encode_glb(vertices, faces, uv=uv, texture=tex.image, name=name)
    files[project.resolve(rel["ply"])] = encode_colored_ply(vertices, faces, uv=uv, texture=tex.image)
    rel["weight_maps"] = {pid: rel["weight_maps"][pid] for pid in ids}
    return files, rel


@contextlib.contextmanager
def _sigint_deferred():
    """Hold Ctrl-C while the outputs are being committed; yields a list that records it."""
    caught = []
    previous = signal.signal(signal.SIGINT, lambda signum, frame: caught.append(signum))
    try:
        yield caught
    finally:
        signal.signal(signal.SIGINT, previous)


def cmd_texture(args) -> int:
    from photomodel.exchange.files import write_files
    from photomodel.generic_mesh import load_generic_mesh
    from photomodel.project import TextureResult, load_project, save_project
    from photomodel.texture import cylindrical_texture, single_view_weights

    lo, hi = TEXTURE_SIZES
    if not lo <= args.size <= hi:
        raise FaceStudioError(f"--size {args.size}: the texture size must be between {lo} and {hi} texels")
    project = load_project(args.project)
    names = _fitted_expressions(project, args.expression)
    generic = load_generic_mesh()
    bar, progress = _progress_bar(not args.json or sys.stderr.isatty())
    prepared = []
    try:
        for i, name in enumerate(names):
            def stage(label, frac, i=i, name=name):
                progress(f"{name}: {label}", (i + frac) / len(names))

            stage("loading photos", 0.0)
            vertices, faces, ids, cameras, photos = _load_fitted(project, name)
            stage("extracting texture", 0.1)
            t0 = time.perf_counter()
            # §5.2.4: ears, hair and neck from the single best photo (needs the generic topology)
            single = (single_view_weights(vertices, generic.face_mask)
                      if len(vertices) == len(generic.vertices) else None)
            tex = cylindrical_texture(vertices, faces, cameras, photos, size=args.size, single_view=single)
            seconds = time.perf_counter() - t0
            stage("encoding exports", 0.8)
            files, rel = _encode_texture_outputs(project, name, vertices, faces, ids, tex)
            surface = int(tex.surface.sum())
            report = {"coverage": float(tex.coverage.sum() / max(surface, 1)), "extract_s": round(seconds, 3),
                      "photos": ids, "single_view_fallback": single is not None}
            prepared.append((name, files, rel, report))
        progress("done", 1.0)
    finally:
        if bar is not None:
            bar.close()

    # commit: every file atomically, then the project; Ctrl-C waits until this is done
    with _sigint_deferred() as interrupted:
        for name, files, rel, report in prepared:
            write_files(files)
            project.expression(name).result.texture = TextureResult(
                size=args.size, image=rel["image"], weight_maps=rel["weight_maps"],
                exports={"obj": rel["obj"], "glb": rel["glb"], "ply": rel["ply"]}, report=report)
        save_project(project)
    if interrupted:
        print("facestudio: interrupted while saving; the results were saved completely", file=sys.stderr)

    out = {"project": str(Path(args.project)), "expressions": []}
    for name, _files, rel, report in prepared:
        entry = {"name": name, "size": args.size, **report,
                 "files": {"texture": rel["image"], "weight_maps": rel["weight_maps"], "obj": rel["obj"],
                           "mtl": rel["mtl"], "glb": rel["glb"], "ply": rel["ply"]}}
        out["expressions"].append(entry)
        if not args.json:
            print(f"expression {name!r}: {args.size}x{args.size} texture from {len(report['photos'])} photos "
                  f"({', '.join(report['photos'])}), {report['coverage']:.1%} of the surface seen, "
                  f"{report['extract_s']:.2f} s")
            print(f"  texture  {rel['image']}")
            for pid, path in rel["weight_maps"].items():
                print(f"  weights  {path}  ({pid})")
            print(f"  exports  {rel['obj']} (+ .mtl), {rel['glb']}, {rel['ply']}")
    if args.json:
        print(json.dumps(out, indent=1))
    else:
        print(f"saved results into {args.project}")
    return 0


def cmd_sample_data(args) -> int:
    from photomodel.sample_data import sample_data_dir

    print(sample_data_dir())
    return 0


def cmd_studio(args) -> int:
    try:  # Qt is imported here only
        from app.qt_compat import check_pyside

        check_pyside()
        from app.main_window import run_studio
    except ImportError as exc:
        raise FaceStudioError(f"the studio cannot start: {exc}") from exc
    return run_studio(args.project)


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
    t = sub.add_parser("texture", help="extract the texture of the fitted face from the photos and export "
                                       "it (OBJ+MTL+PNG, glb, coloured PLY)")
    t.add_argument("project", help="project file (*.facestudio.json), fitted with `facestudio fit`")
    t.add_argument("--expression", help="texture only this expression (default: every fitted one)")
    t.add_argument("--size", type=int, default=1024, help="texture size in texels per side (default 1024)")
    t.add_argument("--json", action="store_true", help="print one JSON object instead of the summary")
    t.set_defaults(func=cmd_texture)
    s = sub.add_parser("sample-data", help="fetch, verify and cache the sample data; print its folder")
    s.set_defaults(func=cmd_sample_data)
    g = sub.add_parser("studio", help="open the studio window (click points, draw curves, fit, look)")
    g.add_argument("project", nargs="?", help="project file to open (*.facestudio.json)")
    g.set_defaults(func=cmd_studio)
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
