"""``facestudio studio [PROJECT]`` (and ``python -m app [PROJECT]``): the studio window.

Qt is imported here only, when the command runs; every other command runs without it.
"""

from __future__ import annotations

from pathlib import Path

from photomodel.errors import FaceStudioError, ProjectError

NAME = "studio"


def run(args) -> int:
    if args.project is not None and not Path(args.project).is_file():
        raise ProjectError(f"{args.project} does not exist (give a project file, *.facestudio.json)")
    try:  # Qt is imported here only
        from app.qt.qt_compat import check_pyside  # noqa: PLC0415 - the Qt stack loads only for the studio

        check_pyside()
        from app.qt.main_window import run_studio  # noqa: PLC0415 - as above
    except ImportError as exc:
        raise FaceStudioError(f"the studio cannot start: {exc}") from exc
    return run_studio(args.project)


def add_parser(sub) -> None:
    g = sub.add_parser(NAME, help="open the studio window (click points, draw curves, fit, look)")
    g.add_argument("project", nargs="?", help="project file to open (*.facestudio.json)")
