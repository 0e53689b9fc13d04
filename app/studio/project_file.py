"""The life of the studio's project file: a new project, open, save (with its results), autosave, recovery.

Functions over a :class:`photomodel.project.Project` and the studio's fits and textures; the
:class:`app.studio_state.StudioModel` calls them and keeps the state (which project, modified or
not, the revision last autosaved) and the events. No Qt.

In memory a photo's path is absolute (relative on disk), so that a photo held by an undo command
stays valid whatever folder the project is saved to next. Fitted meshes and textures made in the
studio are written with the project (:func:`save_with_results`), never before the artist saves.
"""

from __future__ import annotations

import copy
import os
from pathlib import Path

from app.studio.fitting import FitState
from photomodel.errors import ProjectError
from photomodel.exchange.mesh import read_mesh
from photomodel.project import (
    CurveDef,
    Expression,
    Feature,
    Project,
    load_project,
    new_project,
    save_project,
    save_results,
)
from photomodel.texturing.job import encode_texture_outputs

#: Suffix of the autosave file written next to the project (``<file>.autosave``).
AUTOSAVE_SUFFIX = ".autosave"
#: Name of the first expression of a new project.
DEFAULT_EXPRESSION = "neutral"


class MissingPhotos(ProjectError):
    """A project opened fine but some of its photos are missing or unreadable."""


def blank_project(mesh, name: str) -> Project:
    """A new project with the generic mesh's initial (pose) features, its curves and one expression."""
    features = [Feature(n, mesh.features[n], pose=True) for n in mesh.initial_features]
    curves = [CurveDef(n, v) for n, v in mesh.curves.items()]
    p = new_project(name, features=features, curves=curves)
    p.expressions.append(Expression(name=DEFAULT_EXPRESSION))
    return p


def open_project(
    path: str | os.PathLike, mesh, *, recover: bool = False, allow_missing_photos: bool = False
) -> tuple[Project, dict[str, FitState]]:
    """``(project, fits)``: a project file read for the studio, with its fitted meshes.

    Parameters
    ----------
    path : the project file.
    mesh : the generic mesh (:class:`photomodel.modeling.generic_mesh.GenericMesh`) it must match.
    recover : read ``<path>.autosave`` instead (the project's file stays ``path``).
    allow_missing_photos : open even when photos are missing; otherwise :class:`MissingPhotos`
        names them.

    Raises
    ------
    ProjectError
        unreadable or malformed file (the message names the field), features outside the generic
        mesh, or (:class:`MissingPhotos`) missing photos.
    """
    path = Path(path).absolute()
    project = load_project(autosave_path(path) if recover else path)
    project.path = path
    for e in project.expressions:
        for photo in e.photos:
            photo.path = project.resolve(photo.path).as_posix()
    project.check_vertices(len(mesh.vertices))
    if not allow_missing_photos:
        try:
            project.check_photos()
        except ProjectError as exc:
            missing = MissingPhotos(str(exc))
            missing.problems = getattr(exc, "problems", [])
            raise missing from None
    fits = {e.name: loaded_fit(project, e, mesh) for e in project.expressions if e.result is not None}
    return project, fits


def open_recovery(path: str | os.PathLike, mesh) -> tuple[Project, dict[str, FitState]]:
    """``(project, fits)`` of the recovery file of a never-saved project (:func:`write_autosave`).

    The project comes back without a file (``path`` None); its photo and mesh paths are read
    relative to the recovery file's folder. Raises :class:`ProjectError` for an unreadable file.
    """
    path = Path(path).absolute()
    project = load_project(path)
    project.path = None
    for e in project.expressions:
        for photo in e.photos:
            photo.path = (path.parent / photo.path).absolute().as_posix()
    project.check_vertices(len(mesh.vertices))
    fits = {e.name: loaded_fit(project, e, mesh, path.parent) for e in project.expressions if e.result is not None}
    return project, fits


def loaded_fit(project: Project, e: Expression, mesh, folder: Path | None = None) -> FitState:
    """The :class:`FitState` of an expression's stored result; its mesh read from the result's
    files (relative to ``folder``, default the project's), ``vertices`` None when none can be read."""
    vertices = None
    for rel in (e.result.mesh_ply, e.result.mesh_obj):
        if rel is None:
            continue
        f = project.resolve(rel) if folder is None else (folder / rel).absolute()
        if f.is_file():
            try:
                v, _ = read_mesh(f)
            except Exception:  # a broken result mesh loses the overlay, not the project
                continue
            if v.shape == mesh.vertices.shape:
                vertices = v
                break
    return FitState(
        dict(e.result.cameras),
        dict(e.result.points_3d),
        vertices,
        e.result.report,
        None,
        None,
        saved=vertices is not None,
    )


def save_with_results(project: Project, path: str | os.PathLike, fits: dict, textures: dict, faces) -> Path:
    """Save ``project`` (atomically) to ``path`` with the fitted meshes and textures not yet saved
    there written first (:func:`photomodel.project.results.save_results`, as ``facestudio fit`` and
    ``facestudio texture`` do); returns the file written.

    ``fits`` and ``textures`` (expression → :class:`FitState` / :class:`~app.studio.texturing.TextureState`)
    are marked saved. On "save as" into another folder the result paths are rewritten for it;
    ``project.path`` becomes the file written and its autosave is removed.
    """
    target = Path(path).absolute()
    old_path = project.path
    moved = old_path is None or target.parent != old_path.parent
    meshes = {
        name: fit.vertices
        for name, fit in fits.items()
        if fit.vertices is not None
        and project.expression(name).result is not None
        and (moved or not fit.saved or not meshes_on_disk(project, name))
    }
    texts = [
        (tex.job, *encode_texture_outputs(project, tex.job, target.parent))
        for tex in textures.values()
        if moved or not tex.saved
    ]
    written = save_results(project, target, fits=meshes, faces=faces, textures=texts)
    for fit in fits.values():
        fit.saved = fit.vertices is not None
    for tex in textures.values():
        tex.saved = True
    if moved:
        take_written_paths(project, written)
    project.path = written
    remove_autosave(written)
    return written


def meshes_on_disk(project: Project, name: str) -> bool:
    """Whether the mesh files the expression's result names are there: a fit put back by an undo
    names the files of the fit it replaced, which a save since has removed
    (:func:`photomodel.project.results.save_results`), so it is written again."""
    r = project.expression(name).result
    return all(p is not None and project.resolve(p).is_file() for p in (r.mesh_obj, r.mesh_ply))


def take_written_paths(project: Project, written: Path) -> None:
    """After "save as": result and generic-mesh paths as written, relative to the new folder
    (photo paths are absolute in memory)."""
    fresh = load_project(written)
    for e_old, e_new in zip(project.expressions, fresh.expressions, strict=True):
        if e_old.result is not None and e_new.result is not None:
            e_old.result.mesh_obj, e_old.result.mesh_ply = e_new.result.mesh_obj, e_new.result.mesh_ply
            e_old.result.texture = e_new.result.texture
    project.generic_mesh = fresh.generic_mesh


def autosave_target(project: Project, recovery: str | os.PathLike | None = None) -> Path | None:
    """Where ``project`` autosaves: ``<file>.autosave``; a never-saved project to ``recovery``
    (a file in the user's data folder), or nowhere (None) without one."""
    if project.path is not None:
        return autosave_path(project.path)
    return None if recovery is None else Path(recovery).absolute()


def write_autosave(project: Project, target: Path) -> Path:
    """Write a copy of ``project`` to ``target`` (the project itself and its ``.bak`` untouched); returns ``target``."""
    snapshot = copy.copy(project)  # save_project sets .path on what it saves
    save_project(snapshot, target)
    bak = target.with_name(target.name + ".bak")
    if bak.exists():  # save_project keeps the previous autosave as a backup; one file is enough
        bak.unlink()
    return target


def autosave_path(path: str | os.PathLike) -> Path:
    """``<path>.autosave``: where the studio autosaves the project stored at ``path``."""
    path = Path(path)
    return path.with_name(path.name + AUTOSAVE_SUFFIX)


def newer_autosave(path: str | os.PathLike) -> Path | None:
    """The autosave of ``path`` if it exists and is newer than the project file, else None."""
    a = autosave_path(path)
    try:
        if a.stat().st_mtime > Path(path).stat().st_mtime:
            return a
    except OSError:
        return None
    return None


def remove_autosave(path: str | os.PathLike) -> None:
    """Remove ``<path>.autosave`` and its ``.bak`` where they exist."""
    for f in (autosave_path(path), autosave_path(path).with_name(autosave_path(path).name + ".bak")):
        try:
            f.unlink()
        except FileNotFoundError:
            pass


__all__ = [
    "AUTOSAVE_SUFFIX",
    "DEFAULT_EXPRESSION",
    "MissingPhotos",
    "autosave_path",
    "autosave_target",
    "blank_project",
    "newer_autosave",
    "open_project",
    "open_recovery",
    "remove_autosave",
    "save_with_results",
    "write_autosave",
]
