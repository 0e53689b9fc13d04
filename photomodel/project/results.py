"""Storing results into a project: a fit (its record and mesh files) and a texture (its files and record).

The one path shared by ``facestudio fit`` / ``facestudio texture`` (:mod:`app.cli`) and the studio
(:meth:`app.studio_state.StudioModel.save`):

* :func:`record_fit` puts a :class:`~photomodel.modeling.fit.FitResult` into the project in
  memory (:func:`expression_result`, the one place a fit becomes an
  :class:`~photomodel.project.datamodel.ExpressionResult`; no file yet). A new fit replaces the whole
  result, so a texture made for the previous mesh is dropped.
* :func:`save_results` stores the fitted meshes (``results/<expr>.obj|.ply``) and encoded
  textures (:func:`photomodel.texturing.job.encode_texture_outputs`, which texturing supplies:
  this module imports nothing of it) and then the project file:

  1. records the result files in the project (paths relative to the folder of the file being
     written);
  2. serialises and validates the project — if it is invalid nothing at all is written;
  3. writes the result files, each atomically (a reader never finds half a file); a re-fit's
     meshes go under new names (``results/<expr>.<fit id>.obj|.ply``, :func:`fit_mesh_paths`)
     when the earlier fit's are there, so the files the saved project names are never replaced;
  4. writes the project file, atomically and last, keeping the previous one as ``.bak``;
  5. removes the meshes of the replaced fits, which no expression names any more.

  The project file never names a result file that is not completely on disk, and its fitted
  result and mesh files always come from one fit: a crash, a kill or a full disk before step 4
  leaves the previous project file with its own meshes (the new files are removed by the next
  save of that expression).

:func:`store_fit_result` and :func:`store_texture_result` store one result without saving the
project file (the caller saves it, e.g. after several); :func:`store_rig` the rig (format version 4,
``results/rig.npz``) and :func:`load_rig_shapes` reads it back.
"""

from __future__ import annotations

import copy
import hashlib
import io
import re
from collections.abc import Mapping, Sequence
from pathlib import Path

import numpy as np

from photomodel.errors import FitError, ProjectError
from photomodel.exchange import files as exchange_files  # looked up at call time (tests replace it)
from photomodel.exchange.mesh import read_mesh, write_mesh
from photomodel.project.datamodel import ExpressionResult, Project, RigRecord, TextureResult
from photomodel.project.io import encode_project, target_file, write_project


# ---------------------------------------------------------------------------------------
# a fit
# ---------------------------------------------------------------------------------------
def expression_result(fit, *, mesh_obj: str | None = None, mesh_ply: str | None = None) -> ExpressionResult:
    """The project record of a :class:`~photomodel.modeling.fit.FitResult`: cameras by photo id,
    3-D points by feature name, the report, and the mesh files if already written."""
    return ExpressionResult(
        cameras=dict(zip(fit.photo_ids, fit.cameras, strict=True)),
        points_3d=dict(zip(fit.feature_names, fit.points_3d, strict=True)),
        mesh_obj=mesh_obj,
        mesh_ply=mesh_ply,
        report=fit.report,
    )


def record_fit(project: Project, expression_name: str, fit) -> ExpressionResult:
    """Make ``fit`` the expression's result, in memory only (no mesh file yet): what an expression
    fitted next with ``cameras_from`` reads. Drops a texture made for the previous fit."""
    result = project.expression(expression_name).result = expression_result(fit)
    return result


def fit_mesh_paths(
    project: Project, expression_name: str, folder: Path, vertices: np.ndarray | None = None
) -> dict[str, Path]:
    """``{"mesh_obj": <folder>/results/<expr>.obj, "mesh_ply": <folder>/results/<expr>.ply}``.

    With the fit's ``vertices``, and a mesh of that name already in ``folder`` (an earlier fit,
    which the project file on disk still names): ``results/<expr>.<fit id>.obj|.ply`` instead,
    the fit id the first 8 hex digits of the vertices' SHA-1. So a re-fit never overwrites the
    files the saved project names, and a kill before the project file is written leaves the old
    result with its own mesh (:func:`save_results` removes the replaced files afterwards)."""
    rel_obj, rel_ply = project.default_result_paths(expression_name)
    paths = {"mesh_obj": folder / rel_obj, "mesh_ply": folder / rel_ply}
    if vertices is not None and any(p.exists() for p in paths.values()):
        fit_id = hashlib.sha1(np.ascontiguousarray(vertices, dtype=np.float64).tobytes()).hexdigest()[:8]
        paths = {k: p.with_name(f"{p.stem}.{fit_id}{p.suffix}") for k, p in paths.items()}
    return paths


def _remove_replaced_meshes(project: Project, folder: Path, names) -> None:
    """After the project file is written: the mesh files of expressions ``names`` (``<expr>.obj``,
    ``<expr>.<fit id>.obj``, and ``.ply``) in ``folder/results`` that no expression names any more."""
    named = {
        project.resolve(p)
        for e in project.expressions
        if e.result is not None
        for p in (e.result.mesh_obj, e.result.mesh_ply)
        if p is not None
    }
    for name in names:
        stem = re.escape(Path(project.default_result_paths(name)[0]).stem)
        pattern = re.compile(rf"^{stem}(\.[0-9a-f]{{8}})?\.(obj|ply)$")
        for f in (folder / "results").glob("*"):
            if pattern.match(f.name) and f.absolute() not in named:
                f.unlink(missing_ok=True)


def store_fit_meshes(
    project: Project, expression_name: str, vertices: np.ndarray, faces: np.ndarray, folder: Path | None = None
) -> dict[str, Path]:
    """Write the fitted mesh as OBJ and PLY (each atomically) into ``folder`` (default: the
    project's) and record them in the expression's result; returns the files written."""
    folder = _folder(project, folder)
    paths = fit_mesh_paths(project, expression_name, folder)
    _write_meshes(paths, vertices, faces)
    _record_meshes(project, expression_name, folder, paths)
    return paths


def store_fit_result(project: Project, expression_name: str, fit, faces: np.ndarray) -> None:
    """Put ``fit`` into ``project`` (in memory) and write the fitted mesh as OBJ and PLY next to the
    project file (``results/<expression>.obj|.ply``, atomically). The caller saves the project
    file (or uses :func:`save_results`, which does both)."""
    if project.path is None:
        raise FitError("save the project before storing results (the mesh files go next to it)")
    record_fit(project, expression_name, fit)
    store_fit_meshes(project, expression_name, fit.vertices, faces)


def _write_meshes(paths: dict[str, Path], vertices: np.ndarray, faces: np.ndarray) -> None:

    for path in paths.values():
        try:
            write_mesh(path, vertices, faces)
        except OSError as exc:
            raise ProjectError(f"{path}: could not write the fitted mesh: {exc.strerror or exc}") from exc


def _record_meshes(project: Project, expression_name: str, folder: Path, paths: dict[str, Path]) -> None:
    result = project.expression(expression_name).result
    if result is None:
        raise FitError(f"expression {expression_name!r} is not fitted; its mesh is not stored")
    result.mesh_obj = _recorded(project, folder, paths["mesh_obj"])
    result.mesh_ply = _recorded(project, folder, paths["mesh_ply"])


# ---------------------------------------------------------------------------------------
# a texture
# ---------------------------------------------------------------------------------------
def store_texture_result(project: Project, job, files: Mapping, rel: dict, folder: Path | None = None) -> None:
    """Write a texture's encoded files (each atomically, in order) and record the texture in the
    expression's result; ``files, rel`` are :func:`~photomodel.texturing.job.encode_texture_outputs`'
    for ``folder`` (default: the project's). The project file itself is not written: the caller saves it (or uses
    :func:`save_results`, which does both)."""
    _check_fitted(project, job)
    _write_texture(job, files)
    _record_texture(project, job, rel, _folder(project, folder))


def _check_fitted(project: Project, job) -> None:
    if project.expression(job.expression).result is None:
        raise FitError(f"expression {job.expression!r} is no longer fitted; its texture is not stored")


def _write_texture(job, files: Mapping) -> None:

    try:
        exchange_files.write_files(files)
    except OSError as exc:
        where = Path(next(iter(files))).parent if files else Path.cwd()
        raise ProjectError(
            f"{where}: could not write the texture of {job.expression!r}: {exc.strerror or exc}"
        ) from exc


def _record_texture(project: Project, job, rel: dict, folder: Path) -> None:
    def recorded(p: str) -> str:
        return _recorded(project, folder, folder / p)

    project.expression(job.expression).result.texture = TextureResult(
        size=job.size,
        image=recorded(rel["image"]),
        weight_maps={pid: recorded(p) for pid, p in rel["weight_maps"].items()},
        exports={k: recorded(rel[k]) for k in ("obj", "glb", "ply")},
        report=dict(job.report),
    )


# ---------------------------------------------------------------------------------------
# results and the project file, together
# ---------------------------------------------------------------------------------------
def save_results(
    project: Project,
    target=None,
    *,
    fits: Mapping[str, np.ndarray] | None = None,
    faces: np.ndarray | None = None,
    textures: Sequence[tuple] = (),
) -> Path:
    """Store result files, then the project file (see the module docstring); returns the file written.

    Parameters
    ----------
    project : Project, whose expressions in ``fits`` already hold their result (:func:`record_fit`).
    target : path of the project file to write (default ``project.path``; a folder means
        ``<folder>/<name>.facestudio.json``); result files go into its folder.
    fits : {expression name: (N, 3) fitted vertices}, meshes to write (with ``faces``).
    faces : (M, 3) int, the generic mesh's faces.
    textures : sequence of ``(job, files, rel)``, :func:`~photomodel.texturing.job.encode_texture_outputs`
        for the target's folder.

    Raises
    ------
    ProjectError
        the project is invalid (nothing is written), or a file could not be written (naming it;
        the project file is then not written).
    FitError
        an expression in ``fits`` or ``textures`` has no result.
    """
    target = target_file(project, target)
    folder = target.parent
    meshes = {name: fit_mesh_paths(project, name, folder, fits[name]) for name in (fits or {})}
    for name, paths in meshes.items():  # 1. record
        _record_meshes(project, name, folder, paths)
    for job, _files, rel in textures:
        _check_fitted(project, job)
        _record_texture(project, job, rel, folder)
    target, data = encode_project(project, target)  # 2. validate; nothing written if invalid
    for name, paths in meshes.items():  # 3. result files
        _write_meshes(paths, fits[name], faces)
    for job, files, _rel in textures:
        _write_texture(job, files)
    written = write_project(project, target, data)  # 4. the project file, last
    if project.path == written:  # 5. the meshes of the fits replaced, no longer named
        _remove_replaced_meshes(project, folder, meshes)
    return written


def _folder(project: Project, folder: Path | None) -> Path:
    if folder is not None:
        return Path(folder).absolute()
    if project.path is None:
        raise FitError("save the project before storing results (the result files go next to it)")
    return project.path.parent


def _recorded(project: Project, folder: Path, path: Path) -> str:
    """How a result file written at ``path`` (in ``folder``) is recorded in the project: relative
    to the project's folder when ``folder`` is it, else absolute (saving to ``folder`` then stores
    it relative to the file written)."""
    if project.path is not None and folder == project.path.parent:
        return path.relative_to(folder).as_posix()
    return path.as_posix()


#: Where ``facestudio rig`` stores the rig's displacements, relative to the project folder.
RIG_FILE = "results/rig.npz"


def store_rig(
    project: Project,
    *,
    neutral: str,
    names: Sequence[str],
    deltas: np.ndarray,
    report: dict,
    folder: Path | None = None,
    source: str = "ict-facekit",
) -> None:
    """Write the rig's displacements (``results/rig.npz``: ``names`` (k,), ``deltas`` (k, n, 3)
    float32 mm) atomically and record it in ``project.rig`` (format version 4); the caller saves
    the project file afterwards, as with :func:`store_fit_result`. ``source``: ``"ict-facekit"``
    (``facestudio rig``) or ``"multilinear"`` (the people model's shapes, format version 6)."""
    names = [str(n) for n in names]
    D = np.asarray(deltas, np.float32)
    if D.ndim != 3 or D.shape[0] != len(names) or D.shape[2] != 3:
        raise ValueError(f"deltas must be (k, n, 3) with k = {len(names)} names, got {D.shape}")
    folder = _folder(project, folder)
    path = folder / RIG_FILE
    buf = io.BytesIO()
    np.savez_compressed(buf, names=np.array(names), deltas=D)
    try:
        exchange_files.atomic_write_bytes(path, buf.getvalue())
    except OSError as exc:
        raise ProjectError(f"cannot write the rig file {path}: {exc}") from exc
    project.rig = RigRecord(
        source=source,
        neutral=neutral,
        shapes=names,
        file=_recorded(project, folder, path),
        report=copy.deepcopy(report),
    )


def read_fitted_mesh(project: Project, name: str) -> tuple[np.ndarray, np.ndarray]:
    """``(vertices (N, 3) mm, faces (F, 3))`` of expression ``name``'s fitted mesh as stored.

    Raises FitError when no fitted mesh is recorded, ProjectError naming the file when it is
    missing, unreadable or holds non-finite positions."""
    result = project.expression(name).result
    rel = None if result is None else result.mesh_obj
    if rel is None:
        raise FitError(f"expression {name!r} has no fitted mesh recorded: run `facestudio fit {project.path}`")
    path = project.resolve(rel)
    if not path.is_file():
        raise ProjectError(
            f"expression {name!r}: the fitted mesh {rel} does not exist (looked for {path}); "
            f"run `facestudio fit {project.path}` again"
        )
    try:
        V, F = read_mesh(path)
    except Exception as exc:  # trimesh raises many kinds on a damaged file
        raise ProjectError(f"expression {name!r}: cannot read the fitted mesh {rel}: {exc}") from exc
    if not np.all(np.isfinite(V)):
        raise ProjectError(f"expression {name!r}: the fitted mesh {rel} has non-finite vertex positions")
    return V, F


def load_rig_shapes(project: Project) -> tuple[list[str], np.ndarray]:
    """The project's rig: shape names and (k, n, 3) float mm displacements; ProjectError when it has
    none or its file is missing or does not match the record."""
    if project.rig is None:
        raise ProjectError(f"project {project.name!r} has no rig; run `facestudio rig` first")
    path = project.resolve(project.rig.file)
    try:
        with np.load(path, allow_pickle=False) as z:
            names, deltas = [str(n) for n in z["names"]], z["deltas"].astype(float)
    except (OSError, ValueError, KeyError) as exc:
        raise ProjectError(f"cannot read the rig file {path}: {exc}; run `facestudio rig` again") from exc
    if names != list(project.rig.shapes):
        raise ProjectError(f"{path}: its shapes differ from the project's rig record; run `facestudio rig` again")
    return names, deltas
