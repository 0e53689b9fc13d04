"""The ``facestudio`` command.

    facestudio new PROJECT (--photos DIR | --video CLIP [--stills 5] [--every K] [--stills-dir DIR])
                   [--expression neutral] [--camera-group NAME] [--features-from PROJECT] [--json]
    facestudio add-photos PROJECT --photos PATH... [--expression neutral] [--camera-group NAME] [--json]
    facestudio fit PROJECT [--expression NAME] [--no-refine] [--json] [--dry-run]
    facestudio texture PROJECT [--expression NAME] [--size 1024] [--json]
    facestudio track PROJECT --video PATH [--out DIR] [--first-pose JSON] [--focal-px F] [--frames N]
                     [--restart] [--correct FRAME --pose JSON] [--no-overlay] [--json]
    facestudio track-many PROJECT VIDEO... [--workers N] [--scheduler ADDR] [--out DIR] [--frames N]
                          [--threads N] [--expressions a,b] [--no-overlay] [--json]
    facestudio edit PROJECT --track DIR [--scale NAME=F] [--span A:B] [--replace A:B@F] [--no-smooth]
                    --out edited.mp4 [--json]
    facestudio rig PROJECT [--neutral NAME] [--json]
    facestudio export PROJECT --glb out.glb [--track DIR | --livelink take.csv] [--csv out.csv] [--json]
    facestudio sample-data
    facestudio studio [PROJECT]

Qt is imported only by commands that open windows; ``fit`` runs anywhere.
"""

from __future__ import annotations

import argparse
import contextlib
import json
import re
import signal
import sys
from pathlib import Path
from typing import TYPE_CHECKING

from tqdm import tqdm

from app.auto_command import add_parser as add_auto_parser
from app.edit_command import add_edit_parser
from app.rig_command import add_rig_parsers
from app.terminal_progress import StageProgress
from photomodel.errors import FaceStudioError, MissingClicks, ProjectError
from photomodel.landmarks import place_landmarks
from photomodel.modeling.fit import FitOptions, fit_expression, fit_order, uses_person_prior
from photomodel.modeling.generic_mesh import load_generic_mesh
from photomodel.photos.intake import add_photos, default_features, new_project_from_photos, photo_files
from photomodel.photos.reading import PHOTO_SUFFIXES
from photomodel.photos.stills import new_project_from_video
from photomodel.project import load_project, record_fit, save_project, save_results
from photomodel.samples.sample_data import sample_data_dir
from photomodel.texturing.job import TEXTURE_SIZES, encode_texture_outputs, fitted_expressions, texture_expression
from tracking.run import track_video
from tracking.track_result import default_out_dir, load_track_results

if TYPE_CHECKING:  # the batch module loads Dask: imported where track-many runs
    from tracking.many_shots import BatchProgress, BatchResult

#: Texture sizes ``facestudio texture`` accepts (texels per side).


def _progress_bar(enabled: bool, task: str):
    """The command's progress on stderr (:class:`app.terminal_progress.StageProgress`: a bar on a terminal,
    a line per stage and 10 % step in a log; silent with --json unless a TTY), twice: to close, to call."""
    progress = StageProgress(task, enabled=enabled)
    return progress, progress


#: What a fit under the person prior does with automatic clicks (one photo, or weighed ones).
_PRIOR_NOTE = (
    "automatic clicks move the face off the generic head's shape only as far as the detector is sure "
    "of them, so the RMS against them is about its error"
)


def _format_report(expr_name: str, report: dict, dropped: list[str]) -> str:
    lines = [
        f"expression {expr_name!r}: reprojection RMS {report['rms_px']:.3f} px "
        f"(pose features {report['pose']['rms_px']:.3f} px, {report['pose']['sweeps']} sweeps)"
    ]
    if report.get("cameras_from"):
        lines.append(f"  cameras of expression {report['cameras_from']!r} (same rig), kept fixed")
    if report.get("bundle"):
        b = report["bundle"]
        cs = report.get("camera_solve") or {}
        how = f" (start: {cs['start']}, noise σ̂ {cs['sigma_px']:.2f} px)" if cs else ""
        if len(report.get("views", [])) == 1:
            lines.append(
                f"  one photo: its camera placed with {b['points']} clicked features against the generic "
                f"head, whose depth the face takes (one view cannot measure it){how}; {_PRIOR_NOTE} "
                "(drag the ones that are off)"
            )
        else:
            lines.append(
                f"  cameras placed with all {b['points']} features clicked in 2+ photos: {b['rms_px']:.3f} px{how}"
            )
            if uses_person_prior(cs):
                lines.append(
                    f"  the most probable face under the person prior: {_PRIOR_NOTE} (drag the ones that "
                    "are off; --no-person-prior fits them as they are)"
                )
    suspects = report.get("suspect_clicks") or []
    if suspects:
        lines.append(f"  suspect clicks ({len(suspects)}, left out of the fit; check them):")
        for c in suspects[:10]:
            lines.append(f"    {c['feature']:<22} in {c['photo']:<20} {c['error_px']:8.1f} px off")
    lines.append(f"  {'photo':<24} {'RMS px':>8} {'points':>7} {'focal mm':>9}")
    for v in report["views"]:
        rms = "-" if v["rms_px"] is None else f"{v['rms_px']:.3f}"
        lines.append(f"  {v['photo']:<24} {rms:>8} {v['points']:>7} {v['focal_mm']:>9.1f}")
    pts = sorted((p for p in report["points"] if p["rms_px"] is not None), key=lambda p: -p["rms_px"])
    lines.append(f"  worst points (of {len(report['points'])}):")
    for p in pts[:10]:
        tag = " (pose)" if p["pose"] else ""
        lines.append(f"    {p['feature']:<22} {p['rms_px']:7.3f} px in {p['views']} photos{tag}")
    for why in _grouped_reasons(dropped):
        lines.append(f"  not used: {why}")
    return "\n".join(lines)


def _grouped_reasons(reasons: list[str]) -> list[str]:
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


def cmd_new(args) -> int:
    """``facestudio new``: a project from a folder of photos, or from stills a clip's frames give
    (:mod:`photomodel.photos.stills`), with automatic landmarks."""
    target = Path(args.project)
    if target.exists():
        raise ProjectError(
            f"{target}: already exists; `facestudio new` does not overwrite a project "
            f"(choose another name, or add photos in the studio)"
        )
    if args.features_from is not None:
        source = load_project(args.features_from)
        features, curves = source.features, source.curves
    else:
        features, curves = default_features(load_generic_mesh())
    bar, progress = _progress_bar(not args.json or sys.stderr.isatty(), "new")
    try:
        if args.video is not None:
            project, warnings, from_video = new_project_from_video(
                args.video,
                target,
                features=features,
                curves=curves,
                count=args.stills,
                every=args.every,
                folder=args.stills_dir,
                expression=args.expression,
                camera_group=args.camera_group,
                progress=progress,
            )
        else:
            project, warnings = new_project_from_photos(
                args.photos,
                target,
                features=features,
                curves=curves,
                expression=args.expression,
                camera_group=args.camera_group,
                placer=place_landmarks,
                progress=progress,
            )
            save_project(project, target)
    finally:
        if bar is not None:
            bar.close()
    out = _intake_summary(target, args.expression, project.expression(args.expression).photos, warnings)
    if args.video is not None:
        out["video"] = from_video
    return _print_intake(args, out, f"created {target}", len(project.features))


def cmd_add_photos(args) -> int:
    """``facestudio add-photos``: photos added to an expression of a project, with automatic
    landmarks, as the studio's *Add photos with automatic landmarks…* adds them."""
    target = Path(args.project)
    project = load_project(target)
    paths, skipped = photo_files(args.photos)  # at least one photo, or a PhotoError naming the path
    dropped = any(e.name == args.expression and e.result is not None for e in project.expressions)
    bar, progress = _progress_bar(not args.json or sys.stderr.isatty(), "add-photos")
    try:
        warnings = add_photos(
            project, args.expression, paths, camera_group=args.camera_group, placer=place_landmarks, progress=progress
        )
    finally:
        if bar is not None:
            bar.close()
    expr = project.expression(args.expression)
    if dropped:  # a fit is of a set of photos (the studio drops it the same way)
        expr.result = None
        warnings.append(
            f"expression {args.expression!r}: its fit and texture were of the photos before; "
            f"fit it again (facestudio fit {target} --expression {args.expression})"
        )
        followers = [e.name for e in project.expressions if e.cameras_from == args.expression and e.result is not None]
        if followers:  # their fits keep the cameras they were made with, until fitted again
            warnings.append(
                f"{', '.join(map(repr, followers))} reuse the cameras of {args.expression!r}: "
                f"fit them again after it (facestudio fit {target} fits them in order)"
            )
    save_project(project, target)
    out = _intake_summary(target, args.expression, expr.photos[len(expr.photos) - len(paths) :], warnings + skipped)
    out["fit_dropped"] = dropped
    out["photos_in_expression"] = len(expr.photos)
    return _print_intake(args, out, f"added to {target}", len(project.features))


def _intake_summary(target: Path, expression: str, photos, warnings: list[str]) -> dict:
    """The JSON object of ``new`` and ``add-photos``: the photos taken in, with their automatic
    clicks, curves, view, focal guess and camera group."""
    views = [
        {
            "id": p.id,
            "file": Path(p.path).name,
            "width": p.width,
            "height": p.height,
            "preset": p.preset,
            "clicks_auto": len(p.auto_clicks()),
            "curves_auto": p.auto_curves(),
            "focal_mm_guess": p.focal_mm_guess,
            "camera_group": p.camera_group,
        }
        for p in photos
    ]
    return {
        "path": str(target),
        "expression": expression,
        "photos": len(views),
        "clicks_auto": sum(v["clicks_auto"] for v in views),
        "curves_auto": sum(len(v["curves_auto"]) for v in views),
        "warnings": warnings,
        "views": views,
    }


def _print_intake(args, out: dict, done: str, n_features: int) -> int:
    for w in out["warnings"]:
        print(f"facestudio: warning: {w}", file=sys.stderr)
    if args.json:
        print(json.dumps(out, indent=1))
    else:
        print(_format_intake(out, done, n_features))
    return 0


def _format_intake(out: dict, done: str, n_features: int) -> str:
    lines = [
        f"{done}: expression {out['expression']!r}, {out['photos']} photos, "
        f'{out["clicks_auto"]} automatic clicks and {out["curves_auto"]} automatic curves (source "auto"; '
        "check them in the studio)"
    ]
    if "video" in out:
        v = out["video"]
        lines.append(
            f"  stills of {Path(v['path']).name}: frames {', '.join(str(st['frame']) for st in v['stills'])} "
            f"(of {v['frames_looked_at']} frames looked at: {v['frames_with_face']} with a face, "
            f"{v['frames_occluded']} occluded; the least expressive clear frames across the head's turn)"
        )
    wid = max([len("photo")] + [len(v["id"]) for v in out["views"]])
    lines.append(f"  {'photo':<{wid}} {'view':<19} {'auto clicks':>11} {'focal mm':>9}  camera group")
    for v in out["views"]:
        focal = "-" if v["focal_mm_guess"] is None else f"{v['focal_mm_guess']:.1f}"
        lines.append(
            f"  {v['id']:<{wid}} {v['preset']:<19} {v['clicks_auto']:>4} of {n_features:<4} "
            f"{focal:>9}  {v['camera_group'] or '-'}"
        )
    lines.append(f"next: facestudio fit {out['path']}")
    return "\n".join(lines)


def cmd_fit(args) -> int:

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
    out = {"project": str(Path(args.project)), "expressions": []}
    bar, progress = _progress_bar(not args.json or sys.stderr.isatty(), "fit")
    try:
        results = []
        for i, name in enumerate(names):
            options = FitOptions(
                refine=not args.no_refine,
                weigh_auto_clicks=args.weigh_auto_clicks,
                person_prior=not args.no_person_prior,
            )

            def stage(label, frac, i=i, name=name):  # which expression, and the whole run's fraction
                progress(f"{name} ({i + 1}/{len(names)}): {label}", (i + frac) / len(names))

            result = fit_expression(project, name, mesh, options, progress=stage)
            results.append((name, result))
            # in memory at once: an expression fitted next may take its cameras from this one
            record_fit(project, name, result)
    finally:
        if bar is not None:
            bar.close()
    for name, result in results:
        entry = {"name": name, **result.report}
        entry["cameras"] = {pid: c.to_dict() for pid, c in zip(result.photo_ids, result.cameras, strict=True)}
        out["expressions"].append(entry)
        if not args.json:
            print(_format_report(name, result.report, result.report.get("dropped", [])))
    if not args.dry_run:
        # the meshes, then the project file; Ctrl-C waits until this is done
        with _sigint_deferred() as interrupted:
            save_results(project, fits={name: result.vertices for name, result in results}, faces=mesh.faces)
        if interrupted:
            print("facestudio: interrupted while saving; the results were saved completely", file=sys.stderr)
        if not args.json:
            print(f"saved results into {args.project}")
    if args.json:
        print(json.dumps(out, indent=1))
    return 0


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

    lo, hi = TEXTURE_SIZES
    if not lo <= args.size <= hi:
        raise FaceStudioError(f"--size {args.size}: the texture size must be between {lo} and {hi} texels")
    project = load_project(args.project)
    names = fitted_expressions(project, args.expression)
    generic = load_generic_mesh()
    bar, progress = _progress_bar(not args.json or sys.stderr.isatty(), "texture")
    prepared = []
    try:
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
    finally:
        if bar is not None:
            bar.close()

    # commit: every file atomically, then the project; Ctrl-C waits until this is done
    with _sigint_deferred() as interrupted:
        save_results(project, textures=[(job, files, rel) for _name, job, files, rel, _report in prepared])
    if interrupted:
        print("facestudio: interrupted while saving; the results were saved completely", file=sys.stderr)

    out = {"project": str(Path(args.project)), "expressions": []}
    for name, _job, _files, rel, report in prepared:
        entry = {
            "name": name,
            "size": args.size,
            **report,
            "files": {
                "texture": rel["image"],
                "weight_maps": rel["weight_maps"],
                "obj": rel["obj"],
                "mtl": rel["mtl"],
                "glb": rel["glb"],
                "ply": rel["ply"],
            },
        }
        out["expressions"].append(entry)
        if not args.json:
            print(
                f"expression {name!r}: {args.size}x{args.size} texture from {len(report['photos'])} photos "
                f"({', '.join(report['photos'])}), {report['coverage']:.1%} of the surface seen, "
                f"{report['extract_s']:.2f} s"
            )
            print(f"  texture  {rel['image']}")
            for pid, path in rel["weight_maps"].items():
                print(f"  weights  {path}  ({pid})")
            print(f"  exports  {rel['obj']} (+ .mtl), {rel['glb']}, {rel['ply']}")
    if args.json:
        print(json.dumps(out, indent=1))
    else:
        print(f"saved results into {args.project}")
    return 0


def _frames_saved(out_dir) -> int:
    """Frames listed in ``out_dir``'s track.json (0 if none or unreadable)."""

    try:
        doc = load_track_results(out_dir)
    except FaceStudioError:
        return 0
    return 0 if doc is None else len(doc["frames"])


def cmd_track(args) -> int:  # noqa: C901 - one branch per user-facing error of the command, each with its message

    if args.frames is not None and args.frames < 1:
        raise FaceStudioError(f"--frames {args.frames}: track at least one frame")
    if args.focal_px is not None and not args.focal_px > 0:
        raise FaceStudioError(f"--focal-px {args.focal_px}: the focal length must be a positive number of pixels")
    if (args.correct is None) != (args.pose is None):
        raise FaceStudioError(
            "--correct FRAME and --pose FILE go together: the frame to correct and its pose "
            "(clicks of frame FRAME in the first-pose format)"
        )
    bar, show = _progress_bar(not args.json or sys.stderr.isatty(), "track")
    stop = []

    def progress(done: int, total: int | None) -> None:  # the video, the frame, the fraction of the run
        of = f" of {total}" if total else ""
        show(f"{Path(args.video).name}", done / total if total else 0.0, f"frame {done}{of}")

    def on_sigint(signum, frame):  # first Ctrl-C: stop after this frame; a second one stops now
        stop.append(signum)
        signal.signal(signal.SIGINT, signal.default_int_handler)
        print("\nfacestudio: stopping after this frame (Ctrl-C again to stop at once)", file=sys.stderr)

    out_dir = args.out
    previous = signal.signal(signal.SIGINT, on_sigint)
    try:
        names = None if args.expressions is None else [n.strip() for n in args.expressions.split(",") if n.strip()]
        result = track_video(
            args.project,
            args.video,
            args.out,
            expressions=names,
            first_pose=args.first_pose,
            focal_px=args.focal_px,
            max_frames=args.frames,
            basis=args.basis,
            restart=args.restart,
            correct_frame=args.correct,
            correct_pose=args.pose,
            overlay=not args.no_overlay,
            progress=progress,
            cancel=lambda: bool(stop),
        )
    except KeyboardInterrupt:
        bar.close()
        if out_dir is None:
            out_dir = default_out_dir(args.project, args.video)
        print(
            f"facestudio: cancelled; {_frames_saved(out_dir)} frames saved in {out_dir}, rerun to continue",
            file=sys.stderr,
        )
        return 130
    finally:
        signal.signal(signal.SIGINT, previous)
        if bar is not None:
            bar.close()
    files = {k: str(v) for k, v in result.files.items()}
    rms = [f["rms"] for f in result.frames]
    summary = {
        "project": str(Path(args.project)),
        "video": str(Path(args.video)),
        "out_dir": str(result.out_dir),
        "frames": len(result.frames),
        "tracked": result.tracked,
        "resumed_from": result.resumed_from,
        "corrected": result.corrected,
        "complete": result.complete,
        "cancelled": result.cancelled,
        "fps": round(result.fps, 3),
        "diverged_frames": result.diverged,
        "mean_rms": float(sum(rms) / len(rms)) if rms else None,
        "files": files,
        "first_pose": result.first_pose,
        "redetected": sum(f.get("start") == "detected" for f in result.frames),
        "ignored_files": [str(p) for p in result.ignored],
    }
    if result.ignored:
        names = ", ".join(p.name for p in result.ignored[:5]) + (" …" if len(result.ignored) > 5 else "")
        print(
            f"facestudio: {len(result.ignored)} image(s) in the frame folder do not match its frame names and were "
            f"ignored: {names}",
            file=sys.stderr,
        )
    if args.json:
        print(json.dumps(summary, indent=1))
    else:
        resumed = f" (continuing after frame {result.resumed_from - 1})" if result.resumed_from else ""
        if result.corrected is not None:
            resumed = f" (from frame {result.corrected}, corrected to the given pose)"
        print(
            f"tracked {result.tracked} frames{resumed} at {result.fps:.2f} frames/s; {len(result.frames)} frames "
            f"in the results, {result.diverged} diverged, {summary['redetected']} fitted again from the landmark "
            f"detector, mean image RMS {summary['mean_rms'] or 0:.4f}"
        )
        print(f"  first pose: {result.first_pose}")
        for name, path in files.items():
            print(f"  {name:<12} {path}")
    if result.cancelled:
        print(
            f"facestudio: cancelled; {len(result.frames)} frames saved in {result.out_dir}, rerun to continue",
            file=sys.stderr,
        )
        return 130
    return 0


def _batch_display(show: bool):
    """``progress(BatchProgress)`` drawing a tqdm bar over the shots on stderr (frames/s overall,
    failures), each failed shot written above it with its cause; and the bar, to close."""
    bar = tqdm(total=None, unit="shot", file=sys.stderr, desc="shots", leave=False) if show else None
    told = []

    def progress(state: BatchProgress) -> None:
        if bar is None:
            return
        bar.total = state.shots
        for r in state.finished[len(told) :]:
            told.append(r)
            if r.status == "failed":
                tqdm.write(f"facestudio: {r.video} failed: {r.error}", file=sys.stderr)
        bar.set_postfix_str(f"{state.frames} frames, {state.fps:.2f} frames/s, {state.failed} failed", refresh=False)
        bar.update(state.ended - bar.n)

    return progress, bar


def _print_batch(result: BatchResult) -> None:
    """The human summary of ``track-many``: one line per shot, then the totals and the summary files."""
    for s in result.shots:
        what = {
            "tracked": f"{s.tracked} frames tracked at {s.fps:.2f} frames/s"
            + (f" (continuing after frame {s.resumed_from - 1})" if s.resumed_from else ""),
            "skipped": "already tracked, skipped",
            "cancelled": f"cancelled after {s.frames} frames",
            "failed": f"FAILED: {s.error}",
        }[s.status]
        print(f"{Path(s.video).name:<24} {what}; {s.frames} frames in {s.out_dir}")
    where = f"{result.workers} workers" + (f" of {result.scheduler}" if result.scheduler else "")
    print(
        f"{len(result.shots)} shots ({result.failed} failed), {result.tracked_frames} frames in "
        f"{result.seconds:.1f} s on {where} (start-up {result.startup_s:.1f} s)"
    )
    for name, path in result.files.items():
        print(f"  {name:<5} {path}")


def cmd_track_many(args) -> int:
    if args.frames is not None and args.frames < 1:
        raise FaceStudioError(f"--frames {args.frames}: track at least one frame")
    if args.workers is not None and args.workers < 1:
        raise FaceStudioError(f"--workers {args.workers}: at least one worker")
    progress, bar = _batch_display(not args.json or sys.stderr.isatty())
    stop = []

    def on_sigint(signum, frame):  # first Ctrl-C: every shot saves and stops; a second one stops now
        stop.append(signum)
        signal.signal(signal.SIGINT, signal.default_int_handler)
        print("\nfacestudio: stopping every shot after its frame (Ctrl-C again to stop at once)", file=sys.stderr)

    previous = signal.signal(signal.SIGINT, on_sigint)
    # an optional heavy library (Dask, ~1-2 s to import): only the command that needs it loads it
    from tracking.many_shots import track_many  # noqa: PLC0415

    try:
        names = None if args.expressions is None else [n.strip() for n in args.expressions.split(",") if n.strip()]
        result = track_many(
            args.project,
            args.videos,
            args.out,
            workers=args.workers,
            scheduler=args.scheduler,
            threads=args.threads,
            max_frames=args.frames,
            expressions=names,
            overlay=not args.no_overlay,
            progress=progress,
            stop=lambda: bool(stop),
        )
    except KeyboardInterrupt:
        print("facestudio: cancelled; every shot keeps the frames it saved, rerun to continue", file=sys.stderr)
        return 130
    finally:
        signal.signal(signal.SIGINT, previous)
        if bar is not None:
            bar.close()
    if args.json:
        print(json.dumps(result.summary() | {"files": {k: str(v) for k, v in result.files.items()}}, indent=1))
    else:
        _print_batch(result)
    if result.cancelled:
        print("facestudio: cancelled; the frames tracked so far are saved, rerun to continue", file=sys.stderr)
        return 130
    return 1 if result.failed else 0


def cmd_sample_data(args) -> int:

    print(sample_data_dir())
    return 0


def cmd_studio(args) -> int:
    try:  # Qt is imported here only
        from app.qt.qt_compat import check_pyside  # noqa: PLC0415 - the Qt stack loads only for the studio

        check_pyside()
        from app.qt.main_window import run_studio  # noqa: PLC0415 - as above
    except ImportError as exc:
        raise FaceStudioError(f"the studio cannot start: {exc}") from exc
    return run_studio(args.project)


def _positive_int(text: str) -> int:
    """An argument that must be a whole number of at least 1."""
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a whole number") from None
    if value < 1:
        raise argparse.ArgumentTypeError(f"{value} is not at least 1")
    return value


def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="facestudio", description="Face Studio: faces from photographs.")
    sub = p.add_subparsers(dest="command", required=True)
    n = sub.add_parser(
        "new",
        help="start a project from a folder of photos: photos checked, focal lengths "
        "from EXIF, landmarks placed automatically",
    )
    n.add_argument("project", type=Path, help="the project file to create (*.facestudio.json); never overwritten")
    source = n.add_mutually_exclusive_group(required=True)
    source.add_argument(
        "--photos",
        type=Path,
        metavar="DIR",
        help=f"folder of photos ({', '.join(x.lstrip('.') for x in PHOTO_SUFFIXES)}), added in name "
        "order; HEIC, camera raw and GIF files in it are named in a warning, not added",
    )
    source.add_argument(
        "--video",
        type=Path,
        metavar="CLIP",
        help="a video file or a folder of frames of the person: stills are picked where the face is "
        "clear and least expressive, spread over the head's turn, written as PNG and added as "
        "the photos (one camera group, the clip's name)",
    )
    n.add_argument(
        "--stills",
        type=_positive_int,
        default=5,
        metavar="N",
        help="with --video: at most N stills, fewer where the head turns less than 7.5 degrees "
        "between them (default 5)",
    )
    n.add_argument(
        "--every",
        type=_positive_int,
        metavar="K",
        help="with --video: look at every K-th frame (default: about 150 frames over the clip)",
    )
    n.add_argument(
        "--stills-dir",
        type=Path,
        metavar="DIR",
        help="with --video: where the stills are written (default: PROJECT_stills beside the project)",
    )
    n.add_argument("--expression", default="neutral", help="the expression the photos show (default: neutral)")
    n.add_argument(
        "--camera-group",
        metavar="NAME",
        help="one camera group for every photo (frames of one video); default: by camera and lens from EXIF",
    )
    n.add_argument(
        "--features-from",
        type=Path,
        metavar="PROJECT",
        help="copy the features and curves of this project (default: the sample project's "
        "13 pose features, the 68 landmarks and the generic mesh's curves)",
    )
    n.add_argument("--json", action="store_true", help="print one JSON object instead of the summary")
    n.set_defaults(func=cmd_new)
    a = sub.add_parser(
        "add-photos",
        help="add photos to an expression of a project (a new expression, or more "
        "views of one), with automatic landmarks as `new` places them",
    )
    a.add_argument("project", type=Path, help="the project file (*.facestudio.json); saved with a backup")
    a.add_argument(
        "--photos",
        type=Path,
        nargs="+",
        required=True,
        metavar="PATH",
        help="photo files and folders of photos (a folder's in name order)",
    )
    a.add_argument(
        "--expression",
        default="neutral",
        help="the expression the photos show, created when the project has none of that name "
        "(default: neutral); adding photos drops its fit, which is of the photos before",
    )
    a.add_argument(
        "--camera-group",
        metavar="NAME",
        help="one camera group for every new photo; default: by camera and lens from EXIF",
    )
    a.add_argument("--json", action="store_true", help="print one JSON object instead of the summary")
    a.set_defaults(func=cmd_add_photos)
    f = sub.add_parser("fit", help="recover cameras and fit the face mesh to the clicked photos")
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
    f.add_argument("--json", action="store_true", help="print one JSON object instead of the table")
    f.add_argument("--dry-run", action="store_true", help="report only; do not write into the project")
    f.set_defaults(func=cmd_fit)
    t = sub.add_parser(
        "texture",
        help="extract the texture of the fitted face from the photos and export it (OBJ+MTL+PNG, glb, coloured PLY)",
    )
    t.add_argument("project", help="project file (*.facestudio.json), fitted with `facestudio fit`")
    t.add_argument("--expression", help="texture only this expression (default: every fitted one)")
    t.add_argument("--size", type=int, default=1024, help="texture size in texels per side (default 1024)")
    t.add_argument("--json", action="store_true", help="print one JSON object instead of the summary")
    t.set_defaults(func=cmd_texture)
    k = sub.add_parser(
        "track", help="track head pose and expression through a video: JSON + CSV per frame, plots, overlay video"
    )
    k.add_argument(
        "project",
        help="project file (*.facestudio.json) with its expressions fitted and textured; "
        "a neutral one alone tracks head pose, more expressions add expression",
    )
    k.add_argument("--video", required=True, help="video file (anything OpenCV decodes) or folder of PNG/JPG frames")
    k.add_argument(
        "--out",
        type=Path,
        help="output folder (default: <project folder>/results/track_<video name>); a rerun continues what is there",
    )
    k.add_argument(
        "--first-pose",
        type=Path,
        help="first frame's pose or clicks, JSON (default: <video "
        "stem>.first_pose.json beside the video if there is one, else "
        "found by the landmark detector; see docs/tracking.md)",
    )
    k.add_argument(
        "--focal-px",
        type=float,
        help="the video camera's focal length in pixels (overrides the "
        "first-pose file's; default: the project's cameras of the "
        "video's size, else 0.9 x the frame width)",
    )
    k.add_argument("--frames", type=int, help="track only the first N frames (a later run may raise N)")
    k.add_argument(
        "--expressions",
        help="comma-separated expressions of the face model, neutral first (default: every expression of the project)",
    )
    k.add_argument(
        "--basis",
        choices=("arkit", "photographed", "both"),
        help="the expression basis: the rig's 51 ARKit shapes, the photographed expressions per region, or both "
        "(default: arkit when the project has a rig, else photographed)",
    )
    k.add_argument("--restart", action="store_true", help="discard earlier results in the output folder")
    k.add_argument(
        "--correct",
        type=int,
        metavar="FRAME",
        help="correct tracked frame FRAME (e.g. a diverged "
        "one) with --pose: keep frames 0..FRAME-1, fit "
        "FRAME from that pose, track on from there",
    )
    k.add_argument(
        "--pose",
        type=Path,
        metavar="FILE",
        help="frame FRAME's pose for --correct: JSON like the first-pose file (clicks of that frame, or R/t_mm)",
    )
    k.add_argument("--no-overlay", action="store_true", help="do not write the overlay video")
    k.add_argument("--json", action="store_true", help="print one JSON object instead of the summary")
    k.set_defaults(func=cmd_track)
    m = sub.add_parser(
        "track-many",
        help="track many shots in parallel on Dask (this machine's cores, or a "
        "cluster): each shot's results where `track` puts them, a summary",
    )
    m.add_argument("project", help="project file (*.facestudio.json); on a cluster, in a folder every worker reads")
    m.add_argument(
        "videos",
        nargs="+",
        help="video files or frame folders, one shot each (first pose of each: "
        "<video stem>.first_pose.json beside it, as for `track`)",
    )
    m.add_argument(
        "--workers", type=int, help="worker processes on this machine (default: one per core, at most one per shot)"
    )
    m.add_argument(
        "--scheduler",
        metavar="ADDR",
        help="a running Dask scheduler (tcp://host:8786): track on its workers instead of this machine's",
    )
    m.add_argument(
        "--threads",
        type=int,
        help="threads each worker's renderer and OpenCV may use (default: cores / workers; 1 on a cluster)",
    )
    m.add_argument(
        "--out",
        type=Path,
        help="folder of the shots' results folders and the summary (default: "
        "<project folder>/results); a rerun continues what is there",
    )
    m.add_argument("--frames", type=int, help="track only the first N frames of each shot")
    m.add_argument(
        "--expressions",
        help="comma-separated expressions of the face model, neutral first (default: every expression of the project)",
    )
    m.add_argument("--no-overlay", action="store_true", help="do not write the shots' overlay videos")
    m.add_argument("--json", action="store_true", help="print one JSON object (the summary) instead of the table")
    m.set_defaults(func=cmd_track_many)
    add_edit_parser(sub)
    add_rig_parsers(sub)
    add_auto_parser(sub)
    s = sub.add_parser("sample-data", help="fetch, verify and cache the sample data; print its folder")
    s.set_defaults(func=cmd_sample_data)
    g = sub.add_parser("studio", help="open the studio window (click points, draw curves, fit, look)")
    g.add_argument("project", nargs="?", help="project file to open (*.facestudio.json)")
    g.set_defaults(func=cmd_studio)
    return p


def error_json(exc: Exception, message: str | None = None) -> dict:
    """An error as ``--json`` prints it: its kind and message; a fit's missing clicks as a checklist
    (:class:`~photomodel.errors.MissingClicks`: one entry per feature or photo still to click)."""
    out = {"type": type(exc).__name__, "message": str(exc) if message is None else message}
    if isinstance(exc, MissingClicks):
        out.update(expression=exc.expression, checklist=exc.checklist)
    return out


def permission_message(exc: PermissionError) -> str:
    """What a user reads when the disk refuses a write: the folder, and what to do."""
    where = Path(exc.filename) if exc.filename else None
    if where is not None and not where.is_dir():
        where = where.parent
    folder = f"in {where}" if where is not None else "the results"
    return (
        f"could not write {folder}: {exc.strerror or exc}; make the folder writable (or copy the "
        f"project to a folder you can write to) and run the command again"
    )


def _report_error(args, exc: Exception, message: str | None = None) -> int:
    """Exit status 2 after printing ``exc`` on stderr (and as one JSON object with --json)."""
    print(f"facestudio: error: {exc if message is None else message}", file=sys.stderr)
    if getattr(args, "json", False):  # --json: one JSON object on stdout, the error too
        print(json.dumps({"error": error_json(exc, message)}, indent=1))
    return 2


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    signal.signal(signal.SIGINT, signal.default_int_handler)
    try:
        return args.func(args)
    except FaceStudioError as e:
        return _report_error(args, e)
    except PermissionError as e:  # a folder the user cannot write to, wherever a command writes
        return _report_error(args, e, permission_message(e))
    except KeyboardInterrupt:
        print("facestudio: cancelled; nothing was written", file=sys.stderr)
        return 130


if __name__ == "__main__":
    sys.exit(main())
