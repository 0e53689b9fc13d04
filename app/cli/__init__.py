"""The ``facestudio`` command: one module per sub-command.

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
    facestudio --version

Adding a command
----------------
A command is a module of this package with

* ``NAME`` — the sub-command's word (``"track-many"``);
* ``add_parser(subparsers) -> None`` — adds its parser with ``subparsers.add_parser(NAME, help=…)``
  and its arguments (``common.add_json_flag`` for ``--json``);
* ``run(args) -> int`` — does the work and returns the exit status. It checks its arguments and
  every folder it will write (:func:`app.cli.common.check_writable`) before the long work,
  reports through :func:`app.cli.progress.command_progress`, and raises
  :class:`~photomodel.errors.FaceStudioError` for anything the user must fix.

and one line in :data:`COMMANDS` (the order of ``facestudio --help``). :func:`main` sets
``func=module.run`` on each parser and turns every error into exit status 2: a
``FaceStudioError``'s message, or a refused write (read-only file system, full disk, permission)
named with its folder; ``--json`` prints the error as one JSON object too. Ctrl-C is exit 130.
Shared helpers live in :mod:`app.cli.common`, the progress style in :mod:`app.cli.progress`.

Qt is imported only by ``studio``; ``fit`` runs anywhere.
"""

from __future__ import annotations

import argparse
import json
import signal
import sys
from importlib import metadata

from app.cli import (
    add_photos,
    auto,
    clone,
    edit,
    export,
    fit,
    fit_scan,
    new,
    rig,
    sample_data,
    studio,
    texture,
    track,
    track_many,
)
from app.cli.common import WRITE_ERRNOS, write_error_message
from photomodel.errors import FaceStudioError, MissingClicks

#: The command modules, in the order ``facestudio --help`` lists them.
COMMANDS = (
    auto,
    new,
    add_photos,
    fit,
    fit_scan,
    texture,
    track,
    track_many,
    edit,
    clone,
    rig,
    export,
    sample_data,
    studio,
)


def version() -> str:
    """The installed distribution's version (``pyproject.toml``), or ``unknown`` from a bare checkout."""
    try:
        return metadata.version("facestudio")
    except metadata.PackageNotFoundError:
        return "unknown"


def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="facestudio", description="Face Studio: faces from photographs.")
    p.add_argument("--version", action="version", version=f"facestudio {version()}")
    sub = p.add_subparsers(dest="command", required=True)
    for module in COMMANDS:
        module.add_parser(sub)
        sub.choices[module.NAME].set_defaults(func=module.run)
    return p


def error_json(exc: Exception, message: str | None = None) -> dict:
    """An error as ``--json`` prints it: its kind and message; a fit's missing clicks as a checklist
    (:class:`~photomodel.errors.MissingClicks`: one entry per feature or photo still to click)."""
    out = {"type": type(exc).__name__, "message": str(exc) if message is None else message}
    if isinstance(exc, MissingClicks):
        out.update(expression=exc.expression, checklist=exc.checklist)
    return out


def permission_message(exc: OSError) -> str:
    """What a user reads when the disk refuses a write: the folder, and what to do."""
    return write_error_message(exc)


def report_error(args, exc: Exception, message: str | None = None) -> int:
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
        return report_error(args, e)
    except OSError as e:  # a folder the disk refuses to write to, wherever a command writes
        if not isinstance(e, PermissionError) and e.errno not in WRITE_ERRNOS:
            raise
        return report_error(args, e, write_error_message(e))
    except KeyboardInterrupt:
        print("facestudio: cancelled; nothing was written", file=sys.stderr)
        return 130


__all__ = ["COMMANDS", "build_parser", "error_json", "main", "version"]

if __name__ == "__main__":
    sys.exit(main())
