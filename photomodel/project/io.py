"""Reading and writing project files: load with every check, save atomically with a backup.

Loading is the boundary where user data enters, so it is checked thoroughly and every
:class:`~photomodel.errors.ProjectError` names the file and the JSON path of the culprit
(:mod:`photomodel.project.problems`): the bytes must be UTF-8 text, the text strict JSON
(:func:`photomodel.project.jsontext.parse_json`), the dict a valid project
(:func:`photomodel.project.validate.validate`).

Saving validates first, so a file that could not be loaded back is never written. It is atomic
(:func:`photomodel.exchange.files.atomic_write_bytes`, the one atomic writer of the code base):
the text is written to a temporary file in the same folder, flushed and fsynced, then moved over
the project with :func:`os.replace`, so a crash leaves either the old or the new file, never half
of one. The previous version is kept as ``<file>.bak``. Saving to another folder ("save as")
rewrites relative paths so they still reach the same files.

:func:`encode_project` and :func:`write_project` are the two halves of :func:`save_project`, for
a caller that writes other files between them (:func:`photomodel.project.results.save_results`).
"""

from __future__ import annotations

import json
import os
import re
from pathlib import Path

from photomodel.errors import ProjectError
from photomodel.exchange.files import atomic_write_bytes, remove_stale_temp_files
from photomodel.project.codec import project_from_dict, project_to_dict
from photomodel.project.datamodel import Project
from photomodel.project.format import FILE_SUFFIX
from photomodel.project.jsontext import dumps, parse_json, scan_parsed
from photomodel.project.problems import problems_error
from photomodel.project.validate import validate


def default_filename(name: str) -> str:
    """``<name>.facestudio.json`` with characters unsafe in file names replaced by ``_``."""
    return re.sub(r"[^\w.-]", "_", name).lstrip(".") + FILE_SUFFIX


def load_project(path: str | os.PathLike) -> Project:
    """Read and validate a project file; raises :class:`ProjectError` naming the problem."""
    path = Path(path)
    data = parse_json(_read_text(path), path.name)
    project = project_from_dict(data, path)
    remove_orphan_temp_files(path.parent)
    return project


def load_person(project: Project, reference: str) -> Project:
    """The project that ``project.people`` entry ``reference`` names, loaded; :class:`ProjectError`
    naming the entry and the path looked for when the file is missing (``project`` is unchanged:
    the reference stays, so a project moved back into place is found again)."""
    if reference not in project.people:
        raise ProjectError(f"project {project.name!r} refers to no person {reference!r}")
    path = project.person_path(reference)
    if not path.is_file():
        i = project.people.index(reference)
        raise ProjectError(
            f"{project.path.name if project.path else project.name}: people[{i}]: the referenced project "
            f"{reference} does not exist (looked for {path}); move it back or remove the reference"
        )
    return load_project(path)


def remove_orphan_temp_files(folder: Path) -> list[Path]:
    """Temporary files left in a project folder and its ``results/`` by a save that was killed
    (:func:`photomodel.exchange.files.remove_stale_temp_files`: our own names, older than ten
    minutes), removed when the project is next loaded or saved; returns them."""
    return remove_stale_temp_files(folder) + remove_stale_temp_files(Path(folder) / "results")


def _read_text(path: Path) -> str:
    try:
        raw = path.read_bytes()
    except FileNotFoundError:
        raise ProjectError(f"{path}: no such project file") from None
    except OSError as exc:
        raise ProjectError(f"{path}: cannot read the project file: {exc.strerror or exc}") from exc
    try:
        return raw.decode("utf-8-sig")
    except UnicodeDecodeError as exc:
        raise ProjectError(f"{path.name}: not a text (UTF-8) file: {exc.reason} at byte {exc.start}") from None


def save_project(project: Project, path: str | os.PathLike | None = None) -> Path:
    """Write ``project`` atomically and return the absolute path written.

    ``path`` defaults to ``project.path``; an existing directory means
    ``<dir>/<name>.facestudio.json``. The project is validated first, so a file that could not
    be loaded back is never written. The text goes to a temporary file in the target folder,
    is flushed and fsynced, and replaces the target with :func:`os.replace`; a previous
    version of the target is kept as ``<file>.bak``. On failure the target is untouched and
    the temporary file removed. ``project.path`` is set to the written file on success.
    """
    target, data = encode_project(project, path)
    return write_project(project, target, data)


def encode_project(project: Project, path: str | os.PathLike | None = None) -> tuple[Path, bytes]:
    """``(absolute target, file bytes)`` of :func:`save_project`, serialised (paths relative to
    the target's folder) and validated; nothing is written. ProjectError if it is invalid."""
    target = target_file(project, path)
    d = project_to_dict(project, target)
    try:
        json.dumps(d, allow_nan=False)  # fast C check for NaN/inf clicks or results ...
    except ValueError:
        raise problems_error(target.name, scan_parsed(d)) from None  # ... then find where they are
    validate(d, target.name)
    return target, (dumps(d) + "\n").encode("utf-8")


def write_project(project: Project, target: Path, data: bytes) -> Path:
    """Write :func:`encode_project`'s bytes to ``target`` atomically, keeping the previous file as
    ``<file>.bak``; sets ``project.path``. ProjectError if the disk refuses."""
    try:
        atomic_write_bytes(target, data, backup=True)
    except OSError as exc:
        raise ProjectError(f"{target}: could not save the project: {exc.strerror or exc}") from exc
    project.path = target
    remove_orphan_temp_files(target.parent)
    return target


def target_file(project: Project, path: str | os.PathLike | None = None) -> Path:
    """The absolute file :func:`save_project` writes: ``path``, else ``project.path``; an existing
    folder means the default file name inside it."""
    if path is None:
        if project.path is None:
            raise ProjectError(
                f"project {project.name!r} has not been saved yet: give a file name "
                f"(e.g. {default_filename(project.name)})"
            )
        path = project.path
    path = Path(path).absolute()
    if path.is_dir():
        path = path / default_filename(project.name)
    return path
