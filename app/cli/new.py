"""``facestudio new``: a project from a folder of photos, or from stills a clip's frames give
(:mod:`photomodel.photos.stills`), with automatic landmarks.

    facestudio new PROJECT (--photos DIR | --video CLIP [--stills 5] [--every K] [--stills-dir DIR])
                   [--expression neutral] [--camera-group NAME] [--features-from PROJECT] [--json]

The summary (:func:`intake_summary`, :func:`print_intake`) is shared with ``add-photos``.
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

from app.cli.common import add_json_flag, check_file_writable, check_writable, column_width, positive_int, quoted
from app.cli.progress import command_progress
from photomodel.errors import ProjectError
from photomodel.landmarks import place_landmarks
from photomodel.modeling.generic_mesh import load_generic_mesh
from photomodel.photos.intake import default_features, new_project_from_photos
from photomodel.photos.reading import PHOTO_SUFFIXES
from photomodel.photos.stills import new_project_from_video
from photomodel.project import load_project, save_project

NAME = "new"


def run(args) -> int:
    target = Path(args.project)
    if target.exists():
        raise ProjectError(
            f"{target}: already exists; `facestudio new` does not overwrite a project "
            f"(choose another name, or add photos in the studio)"
        )
    check_file_writable(target)
    if args.video is not None:
        check_writable(args.stills_dir)
    if args.features_from is not None:
        source = load_project(args.features_from)
        features, curves = source.features, source.curves
    else:
        features, curves = default_features(load_generic_mesh())
    with command_progress(args, NAME) as progress:
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
    out = intake_summary(target, args.expression, project.expression(args.expression).photos, warnings)
    if args.video is not None:
        out["video"] = from_video
    return print_intake(args, out, f"created {target}", len(project.features))


def intake_summary(target: Path, expression: str, photos, warnings: list[str]) -> dict:
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


def print_intake(args, out: dict, done: str, n_features: int) -> int:
    """The warnings on stderr, then the summary (or its JSON) on stdout; exit status 0."""
    for w in out["warnings"]:
        print(f"facestudio: warning: {w}", file=sys.stderr)
    if args.json:
        print(json.dumps(out, indent=1))
    else:
        print(format_intake(out, done, n_features))
    return 0


def view_label(view: dict) -> str:
    """The table's view of a photo: its preset, or that no face was found in it (no automatic
    click or curve: the project's default preset says nothing about the photo)."""
    if view["clicks_auto"] == 0 and not view["curves_auto"]:
        return "- (no face found)"
    return view["preset"]


def format_intake(out: dict, done: str, n_features: int) -> str:
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
    wid = column_width((v["id"] for v in out["views"]), "photo")
    vwid = column_width((view_label(v) for v in out["views"]), "view")
    lines.append(f"  {'photo':<{wid}} {'view':<{vwid}} {'auto clicks':>11} {'focal mm':>9}  camera group")
    for v in out["views"]:
        focal = "-" if v["focal_mm_guess"] is None else f"{v['focal_mm_guess']:.1f}"
        lines.append(
            f"  {v['id']:<{wid}} {view_label(v):<{vwid}} {v['clicks_auto']:>4} of {n_features:<4} "
            f"{focal:>9}  {v['camera_group'] or '-'}"
        )
    lines.append(f"next: {quoted('facestudio', 'fit', out['path'])}")
    return "\n".join(lines)


def add_parser(sub) -> None:
    n = sub.add_parser(
        NAME,
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
        type=positive_int,
        default=5,
        metavar="N",
        help="with --video: at most N stills, fewer where the head turns less than 7.5 degrees "
        "between them (default 5)",
    )
    n.add_argument(
        "--every",
        type=positive_int,
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
    add_json_flag(n)
