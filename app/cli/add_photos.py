"""``facestudio add-photos``: photos added to an expression of a project, with automatic
landmarks, as the studio's *Add photos with automatic landmarks…* adds them.

    facestudio add-photos PROJECT --photos PATH... [--expression neutral] [--camera-group NAME] [--json]
"""

from __future__ import annotations

from pathlib import Path

from app.cli.common import add_json_flag, check_file_writable, quoted
from app.cli.new import intake_summary, print_intake
from app.cli.progress import command_progress
from photomodel.landmarks import place_landmarks
from photomodel.photos.intake import add_photos, photo_files
from photomodel.project import load_project, save_project

NAME = "add-photos"


def run(args) -> int:
    target = Path(args.project)
    project = load_project(target)
    paths, skipped = photo_files(args.photos)  # at least one photo, or a PhotoError naming the path
    check_file_writable(target)
    dropped = any(e.name == args.expression and e.result is not None for e in project.expressions)
    with command_progress(args, NAME) as progress:
        warnings = add_photos(
            project, args.expression, paths, camera_group=args.camera_group, placer=place_landmarks, progress=progress
        )
    expr = project.expression(args.expression)
    if dropped:  # a fit is of a set of photos (the studio drops it the same way)
        expr.result = None
        warnings.append(
            f"expression {args.expression!r}: its fit and texture were of the photos before; "
            f"fit it again ({quoted('facestudio', 'fit', target, '--expression', args.expression)})"
        )
        followers = [e.name for e in project.expressions if e.cameras_from == args.expression and e.result is not None]
        if followers:  # their fits keep the cameras they were made with, until fitted again
            warnings.append(
                f"{', '.join(map(repr, followers))} reuse the cameras of {args.expression!r}: "
                f"fit them again after it ({quoted('facestudio', 'fit', target)} fits them in order)"
            )
    save_project(project, target)
    out = intake_summary(target, args.expression, expr.photos[len(expr.photos) - len(paths) :], warnings + skipped)
    out["fit_dropped"] = dropped
    out["photos_in_expression"] = len(expr.photos)
    return print_intake(args, out, f"added to {target}", len(project.features))


def add_parser(sub) -> None:
    a = sub.add_parser(
        NAME,
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
    add_json_flag(a)
