"""The studio's state, apart from any widget: a project being edited, its fits, and events.

This is the napari pattern (``napari/components/viewer_model.py``): one model object holds
the :class:`~photomodel.project.Project`, the current expression, the active feature and curve,
and the fitted results, and announces every change through small :class:`Signal` objects. The
Qt widgets of :mod:`app` observe it and edit it through undoable commands
(:mod:`app.studio.commands`); scripts and tests drive the same object without any GUI. Nothing here
imports Qt.

Every edit goes through one primitive (``set_point``, ``set_hidden``, ``set_curve``,
``insert_photo`` …) that validates its input, changes the project, marks it modified and emits
one event; each returns what it replaced, which is what an undo needs. The primitives are the
model's base class :class:`app.studio.edits.ProjectEdits`; the model keeps the undo stack that
replays them (:attr:`StudioModel.undo_stack`, an :class:`app.studio.undo.UndoStack` of the
commands of :mod:`app.studio.commands`, one per primitive), cleared when the project is replaced
and marked clean when it is saved.

The work is done by Qt-free collaborators in :mod:`app.studio` that the model calls and whose
results it stores and announces: :mod:`~app.studio.fitting` (fits, overlays, click residuals),
:mod:`~app.studio.texturing`, :mod:`~app.studio.rig`, :mod:`~app.studio.tracking` and
:mod:`~app.studio.project_file` (open, save, autosave, recovery).

The fitted result of an expression (:class:`FitState`) is kept in memory with the fitted
vertices; the mesh files (``results/<expr>.obj|.ply``) are written when the project is saved,
so a fit never writes next to a project the artist has not saved. A texture (:class:`TextureState`)
likewise; the texture stored with an opened project is read back from its files
(:func:`photomodel.texturing.job.load_stored_texture`) when its expression is first shown.
"""

from __future__ import annotations

import copy
import os
from collections.abc import Callable
from pathlib import Path

import numpy as np

from app.studio import fitting, project_file, rig, texturing
from app.studio.cloning import CloneJob
from app.studio.edits import ProjectEdits
from app.studio.events import Signal
from app.studio.fitting import FitState, Fitting
from app.studio.identity import IdentityFace, load_identity_model, save_new_face
from app.studio.project_file import (
    AUTOSAVE_SUFFIX,
    DEFAULT_EXPRESSION,
    MissingPhotos,
    autosave_path,
    newer_autosave,
    remove_autosave,
)
from app.studio.rig import RigState
from app.studio.texturing import TextureState
from app.studio.tracking import TrackJob
from app.studio.undo import UndoStack
from photomodel.errors import FaceStudioError, ProjectError
from photomodel.modeling.checklist import ChecklistItem, click_checklist
from photomodel.modeling.generic_mesh import load_generic_mesh
from photomodel.photos.reading import PHOTO_SUFFIXES
from photomodel.project import Expression, Photo, Project, record_fit

#: Image files a photo may be: the modeling core's one list (:mod:`photomodel.photos.reading`).
IMAGE_SUFFIXES = PHOTO_SUFFIXES


def _copy_photo(photo: Photo) -> Photo:
    """A deep copy of a photo with its clicks and curves: its click positions copied into one new
    (n, 2) array whose rows become the copy's points (none shared with ``photo``)."""
    out = copy.copy(photo)
    names = list(photo.points)
    rows = np.array([photo.points[n] for n in names], dtype=float).reshape(-1, 2)
    out.points = dict(zip(names, rows, strict=True))
    out.curves = {k: np.array(v) for k, v in photo.curves.items()}
    out.hidden = set(photo.hidden)
    out.sources = dict(photo.sources)
    out.confidence = dict(photo.confidence)
    out.curve_sources = dict(photo.curve_sources)
    return out


class StudioModel(ProjectEdits):
    """The project being edited in the studio, with its fits, as an observable object.

    The model holds the state and announces its changes; its edit primitives are its base
    :class:`app.studio.edits.ProjectEdits` (what the commands of :mod:`app.studio.commands` on
    :attr:`undo_stack` undo and redo), and the work —
    fitting, texturing, the rig, tracking, the project file — is done by the collaborators of
    :mod:`app.studio`, whose results it stores.

    Parameters
    ----------
    project : Project, optional
        Default: a new, empty project (:meth:`new`).
    mesh_loader : callable returning a GenericMesh
        Default :func:`photomodel.modeling.generic_mesh.load_generic_mesh` (loaded on first use).

    Events (:class:`Signal`, arguments in brackets)
    ------------------------------------------------
    project_replaced () — new/open; everything may have changed.
    expression_changed (name) — the current expression.
    photos_changed (expression) — photos added, removed or re-ordered.
    photo_changed (expression, photo_id) — a photo's preset / lens guess.
    points_changed (expression, photo_id, feature) — a click added, moved, deleted, hidden.
    curves_changed (expression, photo_id, curve) — a drawn curve added, replaced or deleted.
    features_changed () — the project's feature or curve definitions.
    fit_changed (expression) — a new fit (or none).
    texture_changed (expression) — a new texture (or none; a new fit drops the texture), or the
        stored texture read back when its expression is first shown after opening the project.
    texture_load_failed (expression, message) — the stored texture of an expression could not be
        read (the message names the file); it is not shown, the project stays open.
    active_feature_changed (name or None), active_curve_changed (name or None).
    modified_changed (bool), path_changed (Path or None).
    rig_changed () — the rig shown (:meth:`rig`) may have changed: another project, a new fit of
        an expression, or a rig built (:meth:`set_rig`); its weights are back to 0.
    rig_weights_changed () — a rig weight moved (:meth:`set_rig_weight`, :meth:`reset_rig_weights`).
    identity_changed () — the people model loaded, an identity slider moved, the new face shown or hidden
    (:meth:`load_identity`, :meth:`set_identity_value`, :meth:`show_identity`).

    The undo history is :attr:`undo_stack` (:class:`app.studio.undo.UndoStack`, with its own
    ``index_changed`` and ``changed`` events): emptied when the project is replaced (new, open,
    recover), clean after :meth:`save`.
    """

    def __init__(self, project: Project | None = None, mesh_loader: Callable | None = None):
        self.project_replaced = Signal()
        self.expression_changed = Signal()
        self.photos_changed = Signal()
        self.photo_changed = Signal()
        self.points_changed = Signal()
        self.curves_changed = Signal()
        self.features_changed = Signal()
        self.fit_changed = Signal()
        self.texture_changed = Signal()
        self.texture_load_failed = Signal()
        self.active_feature_changed = Signal()
        self.active_curve_changed = Signal()
        self.modified_changed = Signal()
        self.path_changed = Signal()
        self.rig_changed = Signal()
        self.rig_weights_changed = Signal()
        self.identity_changed = Signal()
        self.undo_stack = UndoStack()  # the edits of the project, as commands (app.studio.commands)

        self._rig: RigState | None = None
        self._rig_read = False
        self.rig_problem: str | None = None  # why the project's rig is not shown
        self.identity: IdentityFace | None = None  # the people model's identity sliders, once loaded
        self.identity_shown = False  # the new face shown in the 3D view
        self.fit_changed.connect(self._drop_rig)  # a new neutral or expression: read the rig again
        self._mesh_loader = mesh_loader
        self._mesh = None
        self._fitting: Fitting | None = None
        self._residual_cache = None
        self.generation = 0  # bumped whenever the project object is replaced (stale fits are dropped)
        self.fits: dict[str, FitState] = {}
        self.textures: dict[str, TextureState] = {}
        self.texture_problems: dict[str, str] = {}  # expression → why its stored texture is not shown
        self._stored_tried: set[str] = set()
        self.modified = False
        self._autosaved_revision = self.revision = 0
        self.active_feature: str | None = None
        self.active_curve: str | None = None
        self.expression_name: str | None = None
        self.project: Project
        self._set_project(project if project is not None else project_file.blank_project(self.mesh, "untitled"))

    # ------------------------------------------------------------------ generic mesh
    @property
    def mesh(self):
        """The generic face mesh (:class:`photomodel.modeling.generic_mesh.GenericMesh`), loaded once."""
        if self._mesh is None:
            if self._mesh_loader is None:
                self._mesh_loader = load_generic_mesh
            self._mesh = self._mesh_loader()
        return self._mesh

    @property
    def fitting(self) -> Fitting:
        """The :class:`app.studio.fitting.Fitting` of the generic mesh that runs this model's fits."""
        if self._fitting is None:
            self._fitting = Fitting(self.mesh)
        return self._fitting

    @property
    def overlay_lines(self):
        """The wireframe overlay's lines on the generic mesh (:func:`photomodel.modeling.wireframe.mesh_lines`)."""
        return self.fitting.overlay_lines

    @property
    def refitter(self):
        """The :class:`photomodel.modeling.refit.Refitter` shared by every fit of this model."""
        return self.fitting.refitter

    # ------------------------------------------------------------------ look-ups
    @property
    def path(self) -> Path | None:
        return self.project.path

    @property
    def expression(self) -> Expression | None:
        """The current expression (None in a project without expressions)."""
        if self.expression_name is None:
            return None
        return self.project.expression(self.expression_name)

    @property
    def photos(self) -> list[Photo]:
        e = self.expression
        return [] if e is None else list(e.photos)

    def photo(self, photo_id: str, expression: str | None = None) -> Photo:
        return self._expr(expression).photo(photo_id)

    def fit(self, expression: str | None = None) -> FitState | None:
        """The last fit of an expression (default: the current one), or None."""
        name = expression or self.expression_name
        return self.fits.get(name) if name is not None else None

    def texture(self, expression: str | None = None) -> TextureState | None:
        """The texture of an expression's current fit (default: the current expression), or None."""
        name = expression or self.expression_name
        return self.textures.get(name) if name is not None else None

    def feature_names(self) -> list[str]:
        return self.project.feature_names()

    def has_feature(self, name: str) -> bool:
        return any(f.name == name for f in self.project.features)

    def has_curve(self, name: str) -> bool:
        return any(c.name == name for c in self.project.curves)

    def catalogue(self) -> list[tuple[str, int, bool, bool]]:
        """Every feature an artist can click: ``(name, vertex, in_project, pose)``.

        The project's features first (definition order), then the generic mesh's named
        features whose vertex no project feature uses yet (an alias and its iBUG name share a
        vertex; only one of them is offered).
        """
        out = [(f.name, f.vertex, True, f.pose) for f in self.project.features]
        used = {f.vertex for f in self.project.features}
        for name, v in self.mesh.features.items():
            if v not in used:
                used.add(v)
                out.append((name, int(v), False, False))
        return out

    def curve_catalogue(self) -> list[tuple[str, bool]]:
        """Every curve an artist can draw: ``(name, in_project)``; the project's first."""
        out = [(c.name, True) for c in self.project.curves]
        have = {c.name for c in self.project.curves}
        out += [(n, False) for n in self.mesh.curves if n not in have]
        return out

    def click_count(self, feature: str, expression: str | None = None) -> int:
        """In how many photos of the expression the feature is clicked and not hidden."""
        e = self._expr(expression)
        return sum(1 for p in e.photos if feature in p.points and feature not in p.hidden)

    def checklist(self, expression: str | None = None) -> list[ChecklistItem]:
        """What the expression's clicks still lack for a fit (:func:`photomodel.modeling.checklist.click_checklist`):
        under-clicked pose features, then photos short of shared clicks; empty when nothing is missing."""
        e = self._expr(expression)
        return click_checklist(self.project, e.name)

    def next_feature(self, expression: str | None = None) -> str | None:
        """The pose feature to click next: the first one of the checklist, or None."""
        e = self.expression if expression is None else self._expr(expression)
        if e is None:
            return None
        return next((it.feature for it in self.checklist(e.name) if it.feature is not None), None)

    def predicted_uv(self, photo_id: str, feature: str, expression: str | None = None) -> np.ndarray | None:
        """Where the current fit puts a feature in a photo: (2,) px, or None before a fit.

        The fitted mesh's vertex of the feature (the project's, or the generic mesh's named
        feature) projected with the photo's fitted camera — the ghost marker of the photo view.
        """
        vertex = self.project.feature(feature).vertex if self.has_feature(feature) else self.mesh.features.get(feature)
        return fitting.predicted_uv(self.fit(expression), photo_id, feature, vertex)

    # ------------------------------------------------------------------ selection
    def set_expression(self, name: str) -> None:
        self.project.expression(name)  # raises ProjectError naming the expressions
        if name != self.expression_name:
            self.expression_name = name
            self.load_stored_texture(name)
            self.expression_changed.emit(name)

    def set_active_feature(self, name: str | None) -> None:
        if name is not None and not self.has_feature(name) and name not in self.mesh.features:
            raise ProjectError(f"no feature named {name!r} in the project or the generic mesh")
        if name != self.active_feature:
            self.active_feature = name
            self.active_feature_changed.emit(name)

    def set_active_curve(self, name: str | None) -> None:
        if name is not None and not self.has_curve(name) and name not in self.mesh.curves:
            raise ProjectError(f"no curve named {name!r} in the project or the generic mesh")
        if name != self.active_curve:
            self.active_curve = name
            self.active_curve_changed.emit(name)

    # ------------------------------------------------------------------ where a click or curve came from
    def curve_source(self, expression: str, photo_id: str, curve: str) -> str:
        """``"auto"`` or ``"user"``: who drew a curve in a photo."""
        return self.photo(photo_id, expression).curve_source(curve)

    def click_source(self, expression: str, photo_id: str, feature: str) -> tuple[str, float | None]:
        """Where a click came from: ``("user", None)`` or ``("auto", confidence or None)``."""
        photo = self.photo(photo_id, expression)
        return photo.click_source(feature), photo.confidence.get(feature)

    # ------------------------------------------------------------------ fits (app.studio.fitting)
    def click_residuals(self, expression: str | None = None) -> dict[str, dict[str, float]]:
        """Reprojection error (px) of every click with a fitted 3D point: photo id → feature → px
        (:func:`app.studio.fitting.click_residuals`); clicks edited after the fit are measured
        against that fit."""
        fit = self.fit(expression)
        if fit is None:
            return {}
        # every view and the panel ask after each edit and fit: computed once per state
        key = (expression or self.expression_name, id(fit), self.revision, self.generation)
        if self._residual_cache is None or self._residual_cache[0] != key:
            self._residual_cache = (key, fitting.click_residuals(fit, self._expr(expression).photos))
        return self._residual_cache[1]

    def worst_clicks(self, count: int = 20, expression: str | None = None) -> list[tuple[float, str, str]]:
        """The ``count`` largest click residuals, ``(px, photo id, feature)``, largest first."""
        return fitting.worst_clicks(self.click_residuals(expression), count)

    def fit_snapshot(self) -> Project:
        """A deep copy of the project for a worker thread (edits go on while it fits).

        Taken on the GUI thread at every refit, so the photos — ~3000 clicks on the sample, one
        small array each — are copied by :func:`_copy_photo` (~1 ms) rather than by
        ``copy.deepcopy`` (~4 ms); the rest is deep-copied as before.
        """
        memo = {id(photo): _copy_photo(photo) for e in self.project.expressions for photo in e.photos}
        return copy.deepcopy(self.project, memo)

    def warm_start(self, expression: str):
        """What the next refit of ``expression`` starts from: the last fit's result or vertices (or None)."""
        prev = self.fits.get(expression)
        return None if prev is None else prev.warm_start()

    def compute_fit(self, snapshot: Project, expression: str, *, previous=None, progress=None, cancel=None):
        """Fit ``expression`` of a snapshot (worker thread): ``(FitResult, elapsed_s, cold)``,
        :meth:`app.studio.fitting.Fitting.compute`; ``previous`` is :meth:`warm_start`."""
        return self.fitting.compute(snapshot, expression, previous=previous, progress=progress, cancel=cancel)

    def compute_overlays(self, result, photo_ids, lines) -> dict:
        """The wireframe overlays of a fit in some of its photos (worker thread), for :meth:`apply_fit`
        ``overlays``: :meth:`app.studio.fitting.Fitting.overlays`."""
        return self.fitting.overlays(result, photo_ids, lines)

    def overlay(self, photo_id: str, expression: str | None = None):
        """The wireframe overlay of a fit in one photo, or None: from the fit's cache, else computed
        on the calling thread and cached (:meth:`app.studio.fitting.Fitting.overlay`)."""
        return self.fitting.overlay(self.fit(expression), photo_id)

    def apply_fit(self, expression: str, result, elapsed_s: float | None = None, overlays: dict | None = None) -> None:
        """Store a :class:`photomodel.modeling.fit.FitResult` as the expression's fit (GUI thread).

        ``overlays`` (:meth:`compute_overlays` of this result) fill the fit's overlay cache.
        """
        record = record_fit(self.project, self._expr(expression).name, result)
        self.fits[expression] = FitState.of_result(record, result, elapsed_s, overlays)
        self._drop_texture(expression)  # it was made for the previous mesh
        self._touch()
        self.fit_changed.emit(expression)

    def scan_fit_job(self, path: str | os.PathLike, expression: str | None = None):
        """A job ``(progress=, cancel=) → ScanExpressionFit`` for a worker: the scan file ``path``
        fitted as an expression's fit (default: the first, the neutral), as ``facestudio fit-scan``
        does (:func:`app.studio.fitting.scan_fit_job`); the project and the expression's fit are
        read now. Store its result with :class:`app.studio.commands.ScanFitCommand`."""
        name = expression or (self.project.expressions[0].name if self.project.expressions else None)
        if name is None:
            raise ProjectError("the project has no expression to fit the scan to; add one first")
        return fitting.scan_fit_job(self.project, self._expr(name).name, self.fits.get(name), self.mesh, path)

    def replace_fit(self, expression: str, fit: FitState | None, result, texture: TextureState | None = None):
        """Make ``fit`` the expression's fit, ``result`` its project result and ``texture`` its
        texture (None: none); returns what it replaced, ``(fit, result, texture)`` — the edit
        primitive of :class:`app.studio.commands.ScanFitCommand` and its undo."""
        e = self._expr(expression)
        old = self.fits.get(expression), e.result, self.textures.get(expression)
        if fit is None:
            self.fits.pop(expression, None)
        else:
            self.fits[expression] = fit
        e.result = result
        if texture is None:
            self.textures.pop(expression, None)
        else:
            self.textures[expression] = texture
        self._touch()
        self.fit_changed.emit(expression)
        self.texture_changed.emit(expression)
        return old

    def _drop_fit(self, expression: str) -> None:
        # a fit is of a set of photos; adding or removing one invalidates it
        if self.fits.pop(expression, None) is not None:
            self._expr(expression).result = None
            self._drop_texture(expression)
            self.fit_changed.emit(expression)

    # ------------------------------------------------------------------ textures (app.studio.texturing)
    def texture_inputs(self, expression: str | None = None):
        """What texturing the expression's fit needs, read on the GUI thread (no pixels yet):
        :func:`app.studio.texturing.texture_inputs`."""
        name = expression or self.expression_name
        return texturing.texture_inputs(self.project, name, self.fit(name), self.mesh)

    compute_texture = staticmethod(texturing.compute_texture)

    def apply_texture(self, job, vertices: np.ndarray) -> bool:
        """Store a texture (GUI thread) if the expression's fit is still the mesh it was made for.

        Its files are written with the project (:meth:`save`). Returns False (nothing stored)
        when the expression was refitted or removed meanwhile.
        """
        fit = self.fits.get(job.expression)
        if fit is None or fit.vertices is None or fit.vertices is not vertices:
            return False
        self.textures[job.expression] = TextureState(job, vertices, saved=False)
        self._touch()
        self.texture_changed.emit(job.expression)
        return True

    def _drop_texture(self, expression: str) -> None:
        if self.textures.pop(expression, None) is not None:
            self.texture_changed.emit(expression)

    def load_stored_texture(self, expression: str | None = None) -> TextureState | None:
        """Show the texture stored with the expression's fit (``result.texture``): read it back once.

        Called when the project is opened (for its first expression) and whenever another
        expression becomes current; ~0.15 s for a 1024² texture with five weight maps. Nothing
        happens when the expression has a texture in memory already, no stored texture, no fit in
        the studio, or a project without a file. When a file is missing or unreadable the texture
        is not shown: :attr:`texture_problems` holds why (naming the file) and
        ``texture_load_failed`` is emitted; each expression is tried once per opening.

        Returns the texture now held for the expression, or None.
        """
        name = expression or self.expression_name
        if name is None or name in self.textures:
            return self.textures.get(name) if name is not None else None
        fit = self.fits.get(name)
        if name in self._stored_tried or not texturing.stored_texture_wanted(self.project, name, fit):
            return None
        self._stored_tried.add(name)
        try:
            tex = texturing.read_stored_texture(self.project, name, fit, self.mesh)
        except (FaceStudioError, OSError, ValueError) as exc:
            message = f"the stored texture of {name!r} is not shown: {exc}"
            self.texture_problems[name] = message
            self.texture_load_failed.emit(name, message)
            return None
        self.textures[name] = tex
        self.texture_changed.emit(name)
        return tex

    # ------------------------------------------------------------------ the rig (app.studio.rig)
    def rig(self) -> RigState | None:
        """The project's rig with its weights (read once per project and fit), or None: no rig
        (``facestudio rig``, :meth:`set_rig`), or it cannot be shown (:attr:`rig_problem` says why)."""
        if not self._rig_read:
            self._rig, self.rig_problem = rig.read_rig(self.project, self.fits, self.mesh.face_mask)
            self._rig_read = True
        return self._rig

    def rig_vertices(self) -> np.ndarray | None:
        """The rig's neutral + Σ wᵢ·Δᵢ while any weight is not 0, else None."""
        shown = self.rig()
        if shown is None or not np.any(shown.weights):
            return None
        return shown.posed()

    def set_rig_weight(self, name: str, weight: float) -> None:
        """Set one shape's weight (clipped to [0, 1]); the project is not changed."""
        shown = self.rig()
        if shown is None:
            raise ProjectError("the project has no rig to pose")
        if shown.set_weight(name, weight):
            self.rig_weights_changed.emit()

    def reset_rig_weights(self) -> None:
        """Every weight back to 0: the neutral."""
        shown = self.rig()
        if shown is not None and shown.reset():
            self.rig_weights_changed.emit()

    def compute_rig(self, neutral: str | None = None):
        """A job returning ``(neutral, RigResult)``: the rig of a fitted expression (default: the
        rig's, else the first) as ``facestudio rig`` makes it, for a worker
        (:func:`app.studio.rig.rig_job`). Reads only the fitted mesh, taken now."""
        return rig.rig_job(self.project, self.fits, self.mesh, neutral)

    def set_rig(self, neutral: str, made) -> None:
        """Store a rig (:meth:`compute_rig`'s result) in the project (``results/rig.npz`` written
        now next to the project file; the project is then modified) and show it."""
        rig.store_new_rig(self.project, neutral, made)
        self._touch()
        self._drop_rig()

    def _drop_rig(self, *args) -> None:
        self._rig, self._rig_read, self.rig_problem = None, False, None
        self.rig_changed.emit()

    # ------------------------------------------------------------------ new faces (app.studio.identity)
    def load_identity(self, path: str | os.PathLike | None = None) -> IdentityFace:
        """The people model's identity sliders (:class:`app.studio.identity.IdentityFace`), the model read
        from ``path`` (default: its file) once; :class:`FaceStudioError` saying how to build a missing one."""
        if self.identity is None:
            self.identity = IdentityFace(load_identity_model(path))
            self.identity_changed.emit()
        return self.identity

    def identity_vertices(self) -> np.ndarray | None:
        """The new face's neutral (n, 3) mm while it is shown (:attr:`identity_shown`), else None."""
        if self.identity is None or not self.identity_shown:
            return None
        return self.identity.neutral()

    def show_identity(self, shown: bool) -> None:
        """Show the new face in the 3D view (instead of the fit or the posed rig) or not."""
        if bool(shown) != self.identity_shown:
            self.identity_shown = bool(shown)
            self.identity_changed.emit()

    def set_identity_value(self, mode: int, value: float) -> None:
        """Set identity slider ``mode`` (standard deviations); the face is then shown. The project is not changed."""
        face = self.identity
        if face is None:
            raise FaceStudioError("the people model is not loaded")
        changed = face.set_value(mode, value)
        if changed or not self.identity_shown:
            self.identity_shown = True
            self.identity_changed.emit()

    def reset_identity(self) -> None:
        """Every identity slider back to 0: the mean face."""
        if self.identity is not None and self.identity.reset():
            self.identity_changed.emit()

    def save_identity(self, target: str | os.PathLike) -> Path:
        """Write the new face as a project at ``target`` (:func:`app.studio.identity.save_new_face`: its
        neutral fitted, the model's 51 shapes as its rig, this project's texture borrowed) and return
        the file; this project is not changed."""
        if self.identity is None:
            raise FaceStudioError("the people model is not loaded")
        source = self.project if self.project.path is not None else None
        return save_new_face(self.identity, target, self.mesh, texture_from=source)

    # ------------------------------------------------------------------ tracking (app.studio.tracking)
    def track_job(self, video: str | os.PathLike, out_dir=None, max_frames: int | None = None, **settings) -> TrackJob:
        """A :class:`app.studio.tracking.TrackJob` tracking ``video`` with the saved project file
        (results in ``out_dir``, default ``<project folder>/results/track_<video stem>``), to run in
        a worker; ``settings`` are :func:`tracking.run.track_video`'s (``correct_frame``,
        ``correct_pose`` …). :class:`ProjectError` when the project has no file yet."""
        return TrackJob.prepare(self.project.path, video, out_dir, max_frames, **settings)

    # ------------------------------------------------------------------ other people (app.studio.cloning)
    def clone_job(self, project_a: str | os.PathLike, track: str | os.PathLike, method: str, out_dir=None) -> CloneJob:
        """A :class:`app.studio.cloning.CloneJob` putting ``track`` (results of project file ``project_a``)
        on this project's saved face by ``method``, to run in a worker; :class:`ProjectError` when the
        project has no file yet or A or its track is not one."""
        return CloneJob.prepare(self.project.path, project_a, track, method, out_dir)

    def add_person(self, path: str | os.PathLike) -> str | None:
        """Refer to another project file in the project's ``people`` (format version 6; the project is
        then modified); returns the entry, None when it was there already."""
        entry = self.project.add_person(path)
        if entry is not None:
            self._touch()
        return entry

    # ------------------------------------------------------------------ the file (app.studio.project_file)
    def new(self, name: str = "untitled") -> None:
        """Replace the project by a new one with the default features and curves."""
        self._set_project(project_file.blank_project(self.mesh, name))

    def open(self, path: str | os.PathLike, *, recover: bool = False, allow_missing_photos: bool = False) -> None:
        """Open a project file; the current project is kept when anything is wrong.

        Parameters
        ----------
        path : the project file.
        recover : read ``<path>.autosave`` instead (the file stays ``path``; the project is
            then marked modified).
        allow_missing_photos : open even when photos are missing (they show as placeholders);
            otherwise :class:`MissingPhotos` names them.

        The fitted meshes are read (:class:`FitState`) and the first expression's stored texture
        (:meth:`load_stored_texture`); a texture file that cannot be read does not stop the opening.
        Raises :class:`ProjectError` as :func:`app.studio.project_file.open_project` does.
        """
        opened = project_file.open_project(path, self.mesh, recover=recover, allow_missing_photos=allow_missing_photos)
        self._set_project(*opened)
        if recover:
            self._touch()

    def recover(self, path: str | os.PathLike) -> None:
        """Open the recovery file of a never-saved project (:meth:`autosave` ``recovery``).

        The project comes back without a file (save asks where) and marked modified; missing
        photos show as placeholders. Raises :class:`ProjectError` for an unreadable file.
        """
        self._set_project(*project_file.open_recovery(path, self.mesh))
        self._touch()

    def save(self, path: str | os.PathLike | None = None) -> Path:
        """Save (atomically) to ``path`` (default: the project's file), with the fitted meshes and
        textures not yet saved there written first (:func:`app.studio.project_file.save_with_results`).

        Relative paths are rewritten for the new folder on "save as"; the autosave file is
        removed afterwards.
        """
        if path is None:
            if self.project.path is None:
                raise ProjectError("the project has no file yet; choose where to save it")
            path = self.project.path
        old_path = self.project.path
        written = project_file.save_with_results(self.project, path, self.fits, self.textures, self.mesh.faces)
        self._autosaved_revision = self.revision
        self._set_modified(False)
        self.undo_stack.set_clean()
        if written != old_path:
            self.path_changed.emit(written)
        return written

    def autosave(self, recovery: str | os.PathLike | None = None) -> Path | None:
        """Write ``<file>.autosave`` if there are changes since the last save or autosave.

        A project that has never been saved goes to ``recovery`` instead (the studio passes a
        file in the user's data folder, offered at the next start by :meth:`recover`); without
        ``recovery`` such a project is not autosaved. The project itself and its ``.bak`` are
        untouched. Returns the file written, or None.
        """
        if not self.modified or self.revision == self._autosaved_revision:
            return None
        target = project_file.autosave_target(self.project, recovery)
        if target is None:
            return None
        project_file.write_autosave(self.project, target)
        self._autosaved_revision = self.revision
        return target

    # ------------------------------------------------------------------ internals
    def _expr(self, expression: str | None) -> Expression:
        name = expression or self.expression_name
        if name is None:
            raise ProjectError("the project has no expression yet")
        return self.project.expression(name)

    def _touch(self) -> None:
        self.revision += 1
        self._set_modified(True)

    def _set_modified(self, value: bool) -> None:
        if value != self.modified:
            self.modified = value
            self.modified_changed.emit(value)

    def _set_project(self, project: Project, fits: dict | None = None) -> None:
        self.project = project
        self.fits = dict(fits or {})
        self.textures = {}
        self.texture_problems = {}
        self._stored_tried = set()
        self.generation += 1
        self.expression_name = project.expressions[0].name if project.expressions else None
        names = project.feature_names()
        self.active_feature = names[0] if names else None
        self.active_curve = project.curves[0].name if project.curves else None
        self.revision = self._autosaved_revision = 0
        self.modified = False
        self.undo_stack.clear()  # the history was the previous project's
        self.project_replaced.emit()
        self.modified_changed.emit(False)
        self.path_changed.emit(project.path)
        self._drop_rig()
        self.load_stored_texture(self.expression_name)


__all__ = [
    "AUTOSAVE_SUFFIX",
    "DEFAULT_EXPRESSION",
    "IMAGE_SUFFIXES",
    "FaceStudioError",
    "FitState",
    "MissingPhotos",
    "RigState",
    "Signal",
    "StudioModel",
    "TextureState",
    "autosave_path",
    "newer_autosave",
    "remove_autosave",
]
