"""The studio's state, apart from any widget: a project being edited, its fits, and events.

This is the napari pattern (``napari/components/viewer_model.py``): one model object holds
the :class:`~photomodel.project.Project`, the current expression, the active feature and curve,
and the fitted results, and announces every change through small :class:`Signal` objects. The
Qt widgets of :mod:`app` observe it and edit it through undoable commands
(:mod:`app.qt.commands`); scripts and tests drive the same object without any GUI. Nothing here
imports Qt.

Every edit goes through one primitive (``set_point``, ``set_hidden``, ``set_curve``,
``insert_photo`` …) that validates its input, changes the project, marks it modified and emits
one event; each returns what it replaced, which is what an undo needs.

The fitted result of an expression (:class:`FitState`) is kept in memory with the fitted
vertices; the mesh files (``results/<expr>.obj|.ply``) are written when the project is saved,
so a fit never writes next to a project the artist has not saved. A texture (:class:`TextureState`)
likewise; the texture stored with an opened project is read back from its files
(:func:`photomodel.texturing.job.load_stored_texture`) when its expression is first shown.
"""

from __future__ import annotations

import copy
import math
import os
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from photomodel.camera import PRESET_AZIMUTH_DEG, Camera
from photomodel.errors import FaceStudioError, FitError, ProjectError
from photomodel.exchange.mesh import read_mesh
from photomodel.modeling.checklist import ChecklistItem, click_checklist
from photomodel.modeling.generic_mesh import load_generic_mesh
from photomodel.modeling.refit import Refitter
from photomodel.modeling.wireframe import mesh_lines, photo_overlay
from photomodel.photos.exif import focal_mm_guess_from_exif
from photomodel.photos.reading import PHOTO_SUFFIXES, photo_size
from photomodel.project import (
    CurveDef,
    Expression,
    Feature,
    Photo,
    Project,
    load_project,
    load_rig_shapes,
    new_project,
    record_fit,
    save_project,
    save_results,
    store_rig,
)
from photomodel.rig.build import RigBuilder
from photomodel.texturing.job import (
    encode_texture_outputs,
    load_stored_texture,
    load_texture_photos,
    photo_side_for,
    texture_expression,
)
from photomodel.texturing.view_dependent import ViewDependentTexture
from tracking.face_from_project import register_expression

#: Suffix of the autosave file written next to the project (``<file>.autosave``).
AUTOSAVE_SUFFIX = ".autosave"
#: Name of the first expression of a new project.
DEFAULT_EXPRESSION = "neutral"
#: Image files a photo may be: the modeling core's one list (:mod:`photomodel.photos.reading`).
IMAGE_SUFFIXES = PHOTO_SUFFIXES


class Signal:
    """A minimal observer: ``connect(callback)``, ``disconnect(callback)``, ``emit(*args)``.

    Callbacks run synchronously, in connection order, on the emitting thread (the model is
    edited on the GUI thread only; workers hand results back through Qt signals).
    """

    def __init__(self):
        self._slots: list[Callable] = []

    def connect(self, callback: Callable) -> None:
        if callback not in self._slots:
            self._slots.append(callback)

    def disconnect(self, callback: Callable) -> None:
        if callback in self._slots:
            self._slots.remove(callback)

    def emit(self, *args) -> None:
        for slot in list(self._slots):
            slot(*args)


class MissingPhotos(ProjectError):
    """A project opened fine but some of its photos are missing or unreadable."""


@dataclass
class TextureState:
    """The texture extracted for one expression's fit (:mod:`photomodel.texturing.job`).

    Attributes
    ----------
    job : photomodel.texturing.job.TextureJob, the texture, its weight maps and inputs.
    vertices : (N, 3) float mm, the fitted mesh it was made for (a new fit drops it).
    saved : bool, its files (``results/<expr>_texture.png`` …) are written next to the project.
    photos_from : Project or None, where to read the photographs of a texture read back from its
        files (``job.inputs.photos`` None: :func:`photomodel.texturing.job.load_stored_texture`).
    """

    job: object
    vertices: np.ndarray
    saved: bool = False
    photos_from: object = None
    _view_dependent: object = None

    def view_dependent(self):
        """The :class:`photomodel.texturing.view_dependent.ViewDependentTexture` of the same photos (built once).

        A stored texture's photographs are read now (:class:`ProjectError` names a missing one).
        """
        if self._view_dependent is None:
            i = self.job.inputs
            if i.photos is None:
                if self.photos_from is None:
                    raise ProjectError(f"the photographs of the texture of {i.expression!r} are not known")
                load_texture_photos(self.photos_from, i, photo_side_for(self.job.size))
            self._view_dependent = ViewDependentTexture(
                i.vertices, i.faces, i.cameras, i.photos, single_view=self.job.single_view
            )
        return self._view_dependent


@dataclass
class RigState:
    """The project's rig as the studio shows it: blend shapes on the fitted neutral, with weights.

    Attributes
    ----------
    neutral : str, the expression the rig was made on (``project.rig.neutral``).
    vertices : (N, 3) float mm, that expression's fitted mesh.
    names : list of str, the rig's ARKit shapes, then the photographed expressions.
    deltas : (k, N, 3) float mm, each shape's displacement from ``vertices``; a photographed
        expression's is its fitted mesh registered onto the neutral
        (:func:`tracking.face_from_project.register_expression`) minus the neutral.
    arkit : int, how many of ``names`` are the rig's (ARKit) shapes; the rest are photographed.
    weights : (k,) float in [0, 1].
    """

    neutral: str
    vertices: np.ndarray
    names: list
    deltas: np.ndarray
    arkit: int
    weights: np.ndarray

    def posed(self) -> np.ndarray:
        """The neutral plus Σ wᵢ·Δᵢ."""
        used = np.flatnonzero(self.weights)
        if not len(used):
            return self.vertices
        return self.vertices + np.tensordot(self.weights[used], self.deltas[used], axes=1)


@dataclass
class FitState:
    """The last fit of one expression as the studio holds it.

    Attributes
    ----------
    cameras : dict photo id → Camera
    points_3d : dict feature → (3,) float mm
    vertices : (N, 3) float mm or None
        The fitted mesh (None when a loaded project's mesh file is missing).
    report : dict, the fit report (:func:`photomodel.modeling.fit.build_report`).
    result : photomodel.modeling.fit.FitResult or None
        The in-memory result (warm start of the next refit); None for a loaded result.
    elapsed_s : float or None, wall time of the fit.
    saved : bool, the mesh files on disk hold ``vertices``.
    overlays : dict photo id → photomodel.modeling.wireframe.PhotoOverlay
        The wireframe overlays of this fit computed so far (by the fit's worker for the photo on
        screen, by :meth:`StudioModel.overlay` for the others when they are shown).
    """

    cameras: dict
    points_3d: dict
    vertices: np.ndarray | None
    report: dict
    result: object = None
    elapsed_s: float | None = None
    saved: bool = False
    overlays: dict = field(default_factory=dict)


class StudioModel:
    """The project being edited in the studio, with its fits, as an observable object.

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

        self._rig: RigState | None = None
        self._rig_read = False
        self.rig_problem: str | None = None  # why the project's rig is not shown
        self.fit_changed.connect(self._drop_rig)  # a new neutral or expression: read the rig again
        self._mesh_loader = mesh_loader
        self._mesh = None
        self._lines = None
        self._refitter = None
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
        self._set_project(project if project is not None else self._blank_project("untitled"))

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
    def overlay_lines(self):
        """The wireframe overlay's lines on the generic mesh (:func:`photomodel.modeling.wireframe.mesh_lines`)."""
        if self._lines is None:
            self._lines = mesh_lines(self.mesh.vertices, self.mesh.faces, curves=self.mesh.curves)
        return self._lines

    @property
    def refitter(self):
        """The :class:`photomodel.modeling.refit.Refitter` shared by every fit of this model."""
        if self._refitter is None:
            self._refitter = Refitter(self.mesh)
        return self._refitter

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
        fit = self.fit(expression)
        if fit is None or photo_id not in fit.cameras:
            return None
        vertex = self.project.feature(feature).vertex if self.has_feature(feature) else self.mesh.features.get(feature)
        if fit.vertices is not None and vertex is not None:
            X = np.asarray(fit.vertices)[int(vertex)]
        elif feature in fit.points_3d:
            X = np.asarray(fit.points_3d[feature])
        else:
            return None
        return fit.cameras[photo_id].project(X[None])[0]

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

    # ------------------------------------------------------------------ edit primitives
    def set_point(
        self, expression: str, photo_id: str, feature: str, uv, *, source: str = "user", confidence: float | None = None
    ) -> np.ndarray | None:
        """Place (``uv`` (2,) px), move, or delete (``uv=None``) a click; returns the old one.

        ``source``: ``"user"`` (the artist's edit: an automatic click placed or dragged becomes
        the artist's) or ``"auto"`` with the landmark detector's ``confidence`` (automatic
        landmarks, or an undo putting an automatic click back); see :meth:`Photo.set_click`.
        """
        photo = self.photo(photo_id, expression)
        if not self.has_feature(feature):
            raise ProjectError(f"no feature named {feature!r} is defined in the project")
        old = photo.points.get(feature)
        if uv is None:
            photo.remove_click(feature)
        else:
            try:
                photo.set_click(feature, uv, source=source, confidence=confidence)
            except ValueError as exc:
                raise ProjectError(str(exc)) from None
        self._touch()
        self.points_changed.emit(expression, photo_id, feature)
        return None if old is None else old.copy()

    def curve_source(self, expression: str, photo_id: str, curve: str) -> str:
        """``"auto"`` or ``"user"``: who drew a curve in a photo."""
        return self.photo(photo_id, expression).curve_source(curve)

    def click_source(self, expression: str, photo_id: str, feature: str) -> tuple[str, float | None]:
        """Where a click came from: ``("user", None)`` or ``("auto", confidence or None)``."""
        photo = self.photo(photo_id, expression)
        return photo.click_source(feature), photo.confidence.get(feature)

    def set_hidden(self, expression: str, photo_id: str, feature: str, hidden: bool) -> bool:
        """Mark a feature (in)visible in one photo; returns the old state."""
        photo = self.photo(photo_id, expression)
        if not self.has_feature(feature):
            raise ProjectError(f"no feature named {feature!r} is defined in the project")
        old = feature in photo.hidden
        if hidden:
            photo.hidden.add(feature)
        else:
            photo.hidden.discard(feature)
        self._touch()
        self.points_changed.emit(expression, photo_id, feature)
        return old

    def set_feature_pose(self, name: str, pose: bool) -> bool:
        """Flag a feature as a pose feature (§5.1.1) or unflag it (then only refinement uses it,
        e.g. one the views cannot see twice); returns the old flag."""
        if not self.has_feature(name):
            raise ProjectError(f"no feature named {name!r} is defined in the project")
        f = self.project.feature(name)
        old, f.pose = f.pose, bool(pose)
        self._touch()
        self.features_changed.emit()
        return old

    def set_curve(
        self, expression: str, photo_id: str, curve: str, polyline, source: str = "user"
    ) -> np.ndarray | None:
        """Draw (``polyline`` (m, 2) px, m >= 2) or delete (None) a curve in a photo; returns the old.
        ``source``: who drew it — the artist (default; redrawing an automatic curve makes it
        the artist's) or ``"auto"`` (undoing an edit of an automatic curve)."""
        photo = self.photo(photo_id, expression)
        if not self.has_curve(curve):
            raise ProjectError(f"no curve named {curve!r} is defined in the project")
        old = photo.curves.get(curve)
        try:
            photo.set_curve(curve, polyline, source=source)
        except ValueError as exc:
            raise ProjectError(str(exc)) from None
        self._touch()
        self.curves_changed.emit(expression, photo_id, curve)
        return None if old is None else old.copy()

    def add_feature(self, feature: Feature, index: int | None = None) -> None:
        if self.has_feature(feature.name):
            raise ProjectError(f"feature {feature.name!r} is already defined")
        if not 0 <= feature.vertex < len(self.mesh.vertices):
            raise ProjectError(f"feature {feature.name!r}: vertex {feature.vertex} is not a generic-mesh vertex")
        feats = self.project.features
        feats.insert(len(feats) if index is None else index, feature)
        self._touch()
        self.features_changed.emit()

    def remove_feature(self, name: str) -> tuple[Feature, int]:
        """Remove an unused feature definition; returns it and its index (for undo)."""
        for e in self.project.expressions:
            for p in e.photos:
                if name in p.points or name in p.hidden:
                    raise ProjectError(f"feature {name!r} is still clicked in photo {p.id!r} of {e.name!r}")
        i = self.project.feature_names().index(name)
        f = self.project.features.pop(i)
        self._touch()
        self.features_changed.emit()
        return f, i

    def add_curve_def(self, curve: CurveDef, index: int | None = None) -> None:
        if self.has_curve(curve.name):
            raise ProjectError(f"curve {curve.name!r} is already defined")
        curves = self.project.curves
        curves.insert(len(curves) if index is None else index, curve)
        self._touch()
        self.features_changed.emit()

    def remove_curve_def(self, name: str) -> tuple[CurveDef, int]:
        for e in self.project.expressions:
            for p in e.photos:
                if name in p.curves:
                    raise ProjectError(f"curve {name!r} is still drawn in photo {p.id!r} of {e.name!r}")
        i = [c.name for c in self.project.curves].index(name)
        c = self.project.curves.pop(i)
        self._touch()
        self.features_changed.emit()
        return c, i

    def insert_photo(self, expression: str, photo: Photo, index: int | None = None) -> None:
        e = self._expr(expression)
        if any(p.id == photo.id for p in e.photos):
            raise ProjectError(f"expression {expression!r} already has a photo {photo.id!r}")
        if photo.preset not in PRESET_AZIMUTH_DEG:
            raise ProjectError(
                f"unknown camera preset {photo.preset!r}; choose one of {', '.join(sorted(PRESET_AZIMUTH_DEG))}"
            )
        e.photos.insert(len(e.photos) if index is None else index, photo)
        self._drop_fit(expression)
        self._touch()
        self.photos_changed.emit(expression)

    def remove_photo(self, expression: str, photo_id: str) -> tuple[Photo, int]:
        e = self._expr(expression)
        photo = e.photo(photo_id)
        i = e.photos.index(photo)
        e.photos.pop(i)
        self._drop_fit(expression)
        self._touch()
        self.photos_changed.emit(expression)
        return photo, i

    def set_photo_preset(self, expression: str, photo_id: str, preset: str) -> str:
        if preset not in PRESET_AZIMUTH_DEG:
            raise ProjectError(
                f"unknown camera preset {preset!r}; choose one of {', '.join(sorted(PRESET_AZIMUTH_DEG))}"
            )
        photo = self.photo(photo_id, expression)
        old, photo.preset = photo.preset, preset
        self._touch()
        self.photo_changed.emit(expression, photo_id)
        return old

    def set_photo_camera_group(self, expression: str, photo_id: str, group: str | None) -> str | None:
        """Name the camera (and lens) a photo was taken with: photos of one group share one focal
        length (``Photo.camera_group``); ``None``: a camera of its own. Returns the old group."""
        if group is not None and (not isinstance(group, str) or not group):
            raise ProjectError(f"a camera group is a non-empty name or none, got {group!r}")
        photo = self.photo(photo_id, expression)
        old, photo.camera_group = photo.camera_group, group
        self._touch()
        self.photo_changed.emit(expression, photo_id)
        return old

    def add_expression(self, name: str, index: int | None = None, expression: Expression | None = None) -> None:
        if not isinstance(name, str) or not name.strip():
            raise ProjectError("an expression needs a non-empty name")
        if any(e.name == name for e in self.project.expressions):
            raise ProjectError(f"an expression called {name!r} already exists")
        expr = expression if expression is not None else Expression(name=name)
        exprs = self.project.expressions
        exprs.insert(len(exprs) if index is None else index, expr)
        self._touch()
        self.expression_name = name
        self.expression_changed.emit(name)

    def remove_expression(self, name: str) -> tuple[Expression, int]:
        e = self.project.expression(name)
        i = self.project.expressions.index(e)
        self.project.expressions.pop(i)
        self.fits.pop(name, None)
        self._drop_texture(name)
        self._touch()
        if self.expression_name == name:
            exprs = self.project.expressions
            self.expression_name = exprs[min(i, len(exprs) - 1)].name if exprs else None
            self.load_stored_texture(self.expression_name)
            self.expression_changed.emit(self.expression_name)
        return e, i

    def photo_from_file(
        self,
        path: str | os.PathLike,
        expression: str | None = None,
        preset: str = "front",
        focal_mm_guess: float | None = None,
    ) -> Photo:
        """A :class:`Photo` for an image file, with an unused id.

        The file is checked and its size read by :func:`photomodel.photos.reading.photo_size`
        (EXIF orientation applied: the oriented size). ``focal_mm_guess`` (mm on a 36 mm-wide
        sensor) when given, else the focal length the file's EXIF records
        (:func:`photomodel.photos.exif.focal_mm_guess_from_exif`), else none. Raises
        :class:`~photomodel.errors.PhotoError` (a :class:`ProjectError`) naming the file when it
        is missing, truncated or not an image.
        """

        path = Path(path).absolute()
        w, h = photo_size(path)
        e = self._expr(expression)
        ids = {p.id for p in e.photos}
        stem = path.stem.split(".")[0] or "photo"
        pid, k = stem, 2
        while pid in ids:
            pid, k = f"{stem}_{k}", k + 1
        if focal_mm_guess is None:
            focal_mm_guess = focal_mm_guess_from_exif(path, w, h)
        return Photo(id=pid, path=str(path), width=w, height=h, preset=preset, focal_mm_guess=focal_mm_guess)

    # ------------------------------------------------------------------ fits
    def click_residuals(self, expression: str | None = None) -> dict[str, dict[str, float]]:
        """Reprojection error (px) of every click with a fitted 3D point: photo id → feature → px.

        ``|project(camera, X) − click|`` with the fitted camera of the photo and the fitted
        position of the feature; clicks edited after the fit are measured against that fit.
        """
        fit = self.fit(expression)
        out: dict[str, dict[str, float]] = {}
        if fit is None:
            return out
        # every view and the panel ask after each edit and fit: computed once per state
        key = (expression or self.expression_name, id(fit), self.revision, self.generation)
        if self._residual_cache is not None and self._residual_cache[0] == key:
            return self._residual_cache[1]
        self._residual_cache = (key, out)
        for photo in self._expr(expression).photos:
            cam = fit.cameras.get(photo.id)
            if cam is None:
                continue
            names = [n for n in photo.points if n in fit.points_3d and n not in photo.hidden]
            if not names:
                continue
            X = np.array([fit.points_3d[n] for n in names])
            uv = np.array([photo.points[n] for n in names])
            err = np.linalg.norm(cam.project(X) - uv, axis=1)
            out[photo.id] = {n: float(e) for n, e in zip(names, err, strict=True)}
        return out

    def worst_clicks(self, count: int = 20, expression: str | None = None) -> list[tuple[float, str, str]]:
        """The ``count`` largest click residuals, ``(px, photo id, feature)``, largest first."""
        rows = [(px, pid, n) for pid, d in self.click_residuals(expression).items() for n, px in d.items()]
        rows.sort(key=lambda r: (-r[0], r[1], r[2]))
        return rows[:count]

    def fit_snapshot(self) -> Project:
        """A deep copy of the project for a worker thread (edits go on while it fits)."""
        return copy.deepcopy(self.project)

    def warm_start(self, expression: str):
        """What the next refit of ``expression`` starts from: the last fit's result or vertices (or None)."""
        prev = self.fits.get(expression)
        if prev is None:
            return None
        return prev.result if prev.result is not None else prev.vertices

    def compute_fit(self, snapshot: Project, expression: str, *, previous=None, progress=None, cancel=None):
        """Fit ``expression`` of a snapshot; safe to call from a worker thread.

        With ``previous`` (:meth:`warm_start`, taken on the GUI thread) the refinement is
        warm-started from the last fit (:class:`photomodel.modeling.refit.Refitter`); otherwise this is the
        full pipeline of :func:`photomodel.modeling.fit.fit_expression`. Returns ``(FitResult, elapsed_s,
        cold)`` where ``cold`` says the fit had to build cached RBF solves (a new set of
        constrained vertices).
        """
        refitter = self.refitter
        misses = refitter.deformer.misses
        t0 = time.perf_counter()
        result = refitter.fit(snapshot, expression, previous=previous, progress=progress, cancel=cancel)
        return result, time.perf_counter() - t0, refitter.deformer.misses != misses

    def compute_overlays(self, result, photo_ids, lines) -> dict:
        """The wireframe overlays of a fit in some of its photos; safe to call from a worker thread.

        Parameters
        ----------
        result : photomodel.modeling.fit.FitResult, the fit (cameras and vertices).
        photo_ids : iterable of str; ids the fit has no camera for are skipped.
        lines : photomodel.modeling.wireframe.MeshLines, :attr:`overlay_lines` read on the GUI thread.

        Returns
        -------
        dict photo id → photomodel.modeling.wireframe.PhotoOverlay, for :meth:`apply_fit` ``overlays``.
        """

        cams = dict(zip(result.photo_ids, result.cameras, strict=True))
        faces = self.mesh.faces
        return {pid: photo_overlay(cams[pid], result.vertices, faces, lines) for pid in photo_ids if pid in cams}

    def overlay(self, photo_id: str, expression: str | None = None):
        """The wireframe overlay (:class:`photomodel.modeling.wireframe.PhotoOverlay`) of a fit in one photo, or None.

        Taken from the fit's cache (filled by the fit's worker); computed here, on the calling
        thread, and cached when missing (a photo that was not on screen when the fit ran).
        """
        fit = self.fit(expression)
        if fit is None or fit.vertices is None or photo_id not in fit.cameras:
            return None
        found = fit.overlays.get(photo_id)
        if found is None:
            found = fit.overlays[photo_id] = photo_overlay(
                fit.cameras[photo_id], fit.vertices, self.mesh.faces, self.overlay_lines
            )
        return found

    def apply_fit(self, expression: str, result, elapsed_s: float | None = None, overlays: dict | None = None) -> None:
        """Store a :class:`photomodel.modeling.fit.FitResult` as the expression's fit (GUI thread).

        ``overlays`` (:meth:`compute_overlays` of this result) fill the fit's overlay cache.
        """
        e = record_fit(self.project, self._expr(expression).name, result)
        self.fits[expression] = FitState(
            e.cameras,
            e.points_3d,
            np.asarray(result.vertices),
            result.report,
            result,
            elapsed_s,
            saved=False,
            overlays=dict(overlays or {}),
        )
        self._drop_texture(expression)  # it was made for the previous mesh
        self._touch()
        self.fit_changed.emit(expression)

    def _drop_fit(self, expression: str) -> None:
        # a fit is of a set of photos; adding or removing one invalidates it
        if self.fits.pop(expression, None) is not None:
            self._expr(expression).result = None
            self._drop_texture(expression)
            self.fit_changed.emit(expression)

    # ------------------------------------------------------------------ textures
    def texture_inputs(self, expression: str | None = None):
        """What texturing the expression's fit needs, read on the GUI thread (no pixels yet).

        Returns ``(snapshot Project, expression name, vertices (N, 3), faces, face_mask)``;
        :class:`ProjectError` / :class:`FitError` when the expression is not fitted with a mesh.
        """

        name = expression or self.expression_name
        fit = self.fit(name)
        if name is None or fit is None:
            raise FitError(f"expression {name!r} is not fitted yet: fit it first (Fit → Fit)")
        if fit.vertices is None:
            raise FitError(f"expression {name!r}: its fitted mesh is missing; fit it again")
        return self.fit_snapshot(), name, fit.vertices, self.mesh.faces, self.mesh.face_mask

    @staticmethod
    def compute_texture(inputs, size: int, *, progress=None, cancel=None):
        """Extract the texture of :meth:`texture_inputs` (worker thread): a TextureJob."""

        snapshot, name, vertices, faces, face_mask = inputs
        return texture_expression(
            snapshot, name, size, face_mask=face_mask, vertices=vertices, faces=faces, progress=progress, cancel=cancel
        )

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
        if name in self._stored_tried or self.project.path is None:
            return None
        try:
            e = self.project.expression(name)
        except ProjectError:
            return None
        fit = self.fits.get(name)
        if e.result is None or e.result.texture is None or fit is None:
            return None
        self._stored_tried.add(name)
        try:
            if fit.vertices is None:
                raise ProjectError(f"expression {name!r}: its fitted mesh {e.result.mesh_obj} could not be read")

            job = load_stored_texture(self.project, name, fit.vertices, self.mesh.faces, face_mask=self.mesh.face_mask)
        except (FaceStudioError, OSError, ValueError) as exc:
            message = f"the stored texture of {name!r} is not shown: {exc}"
            self.texture_problems[name] = message
            self.texture_load_failed.emit(name, message)
            return None
        tex = self.textures[name] = TextureState(job, fit.vertices, saved=True, photos_from=self.project)
        self.texture_changed.emit(name)
        return tex

    # ------------------------------------------------------------------ files
    # ------------------------------------------------------------------ the rig
    def rig(self) -> RigState | None:
        """The project's rig with its weights (read once per project and fit), or None: no rig
        (``facestudio rig``, :meth:`set_rig`), or it cannot be shown (:attr:`rig_problem` says why)."""
        if self._rig_read:
            return self._rig
        self._rig_read, self._rig, self.rig_problem = True, None, None
        record = self.project.rig
        if record is None:
            return None
        fit = self.fits.get(record.neutral)
        if fit is None or fit.vertices is None:
            self.rig_problem = f"the rig's neutral {record.neutral!r} has no fitted mesh"
            return None
        try:
            names, deltas = load_rig_shapes(self.project)
        except ProjectError as exc:
            self.rig_problem = str(exc)
            return None
        if deltas.shape[1:] != fit.vertices.shape:
            self.rig_problem = f"the rig has {deltas.shape[1]} vertices, the fitted mesh {len(fit.vertices)}"
            return None
        extra_names, extra = self._photographed_deltas(record.neutral, fit.vertices)
        D = np.concatenate([deltas, np.reshape(extra, (-1, *fit.vertices.shape))])
        self._rig = RigState(record.neutral, fit.vertices, list(names) + extra_names, D, len(names), np.zeros(len(D)))
        return self._rig

    def _photographed_deltas(self, neutral: str, N: np.ndarray) -> tuple[list[str], list[np.ndarray]]:
        """The other fitted expressions as shapes on the neutral: registered onto it as tracking's
        face model does (rigid when fitted with its cameras, else a similarity), minus it."""
        names, deltas = [], []
        weight = self.mesh.face_mask.astype(float)
        for e in self.project.expressions:
            fit = self.fits.get(e.name)
            if e.name == neutral or fit is None or fit.vertices is None or fit.vertices.shape != N.shape:
                continue
            try:
                shared = getattr(e, "cameras_from", None) == neutral
                moved, _ = register_expression(fit.vertices, N, weight, scale=not shared)
            except FitError:
                continue
            names.append(e.name)
            deltas.append(moved - N)
        return names, deltas

    def rig_vertices(self) -> np.ndarray | None:
        """The rig's neutral + Σ wᵢ·Δᵢ while any weight is not 0, else None."""
        rig = self.rig()
        if rig is None or not np.any(rig.weights):
            return None
        return rig.posed()

    def set_rig_weight(self, name: str, weight: float) -> None:
        """Set one shape's weight (clipped to [0, 1]); the project is not changed."""
        rig = self.rig()
        if rig is None:
            raise ProjectError("the project has no rig to pose")
        if name not in rig.names:
            raise ProjectError(f"the rig has no shape {name!r}")
        w = float(np.clip(weight, 0.0, 1.0))
        i = rig.names.index(name)
        if rig.weights[i] != w:
            rig.weights[i] = w
            self.rig_weights_changed.emit()

    def reset_rig_weights(self) -> None:
        """Every weight back to 0: the neutral."""
        rig = self.rig()
        if rig is not None and np.any(rig.weights):
            rig.weights[:] = 0.0
            self.rig_weights_changed.emit()

    def compute_rig(self, neutral: str | None = None):
        """``(neutral, RigResult)``: the rig of a fitted expression (default: the rig's, else the
        first), as ``facestudio rig`` makes it (:class:`photomodel.rig.build.RigBuilder`); a few
        seconds, for a worker. Reads only the fitted mesh, taken now."""
        name = neutral or (self.project.rig.neutral if self.project.rig is not None else None)
        name = name or (self.project.expressions[0].name if self.project.expressions else None)
        fit = self.fits.get(name) if name is not None else None
        if fit is None or fit.vertices is None:
            raise FitError(f"expression {name!r} is not fitted; fit it first")
        vertices = fit.vertices.copy()
        return lambda: (name, RigBuilder(self.mesh).rig(vertices))

    def set_rig(self, neutral: str, rig) -> None:
        """Store a rig (:meth:`compute_rig`'s result) in the project (``results/rig.npz`` written
        now next to the project file; the project is then modified) and show it."""
        if self.project.path is None:
            raise ProjectError("save the project first: the rig is written next to the project file")
        store_rig(self.project, neutral=neutral, names=rig.names, deltas=rig.deltas, report=dict(rig.report))
        self._touch()
        self._drop_rig()

    def _drop_rig(self, *args) -> None:
        self._rig, self._rig_read, self.rig_problem = None, False, None
        self.rig_changed.emit()

    def new(self, name: str = "untitled") -> None:
        """Replace the project by a new one with the default features and curves."""
        self._set_project(self._blank_project(name))

    def _blank_project(self, name: str) -> Project:
        m = self.mesh
        features = [Feature(n, m.features[n], pose=True) for n in m.initial_features]
        curves = [CurveDef(n, v) for n, v in m.curves.items()]
        p = new_project(name, features=features, curves=curves)
        p.expressions.append(Expression(name=DEFAULT_EXPRESSION))
        return p

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

        Raises
        ------
        ProjectError
            unreadable or malformed file (the message names the field), features outside the
            generic mesh, or (:class:`MissingPhotos`) missing photos.
        """
        path = Path(path).absolute()
        source = autosave_path(path) if recover else path
        project = load_project(source)
        project.path = path
        # absolute in memory (relative on disk): a photo held by an undo command stays valid
        # whatever folder the project is saved to next
        for e in project.expressions:
            for photo in e.photos:
                photo.path = project.resolve(photo.path).as_posix()
        project.check_vertices(len(self.mesh.vertices))
        if not allow_missing_photos:
            try:
                project.check_photos()
            except ProjectError as exc:
                missing = MissingPhotos(str(exc))
                missing.problems = getattr(exc, "problems", [])
                raise missing from None
        fits = {}
        for e in project.expressions:
            if e.result is not None:
                fits[e.name] = self._loaded_fit(project, e)
        self._set_project(project, fits)
        if recover:
            self._touch()

    def recover(self, path: str | os.PathLike) -> None:
        """Open the recovery file of a never-saved project (:meth:`autosave` ``recovery``).

        The project comes back without a file (save asks where) and marked modified; missing
        photos show as placeholders. Raises :class:`ProjectError` for an unreadable file.
        """
        path = Path(path).absolute()
        project = load_project(path)
        project.path = None
        for e in project.expressions:
            for photo in e.photos:
                photo.path = (path.parent / photo.path).absolute().as_posix()
        project.check_vertices(len(self.mesh.vertices))
        fits = {e.name: self._loaded_fit(project, e, path.parent) for e in project.expressions if e.result is not None}
        self._set_project(project, fits)
        self._touch()

    def _loaded_fit(self, project: Project, e: Expression, folder: Path | None = None) -> FitState:
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
                if v.shape == self.mesh.vertices.shape:
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

    def save(self, path: str | os.PathLike | None = None) -> Path:
        """Save (atomically) to ``path`` (default: the project's file), with the fitted meshes and
        textures not yet saved there written first (:func:`photomodel.project.results.save_results`,
        as ``facestudio fit`` and ``facestudio texture`` do).

        Relative paths are rewritten for the new folder on "save as"; the autosave file is
        removed afterwards.
        """
        if path is None:
            if self.project.path is None:
                raise ProjectError("the project has no file yet; choose where to save it")
            path = self.project.path
        target = Path(path).absolute()
        old_path = self.project.path
        moved = old_path is None or target.parent != old_path.parent
        fits, textures = self._results_to_write(target.parent, moved)
        written = save_results(self.project, target, fits=fits, faces=self.mesh.faces, textures=textures)
        for fit in self.fits.values():
            fit.saved = fit.vertices is not None
        for tex in self.textures.values():
            tex.saved = True
        if moved:
            self._take_written_paths(written)
        self.project.path = written
        remove_autosave(written)
        self._autosaved_revision = self.revision
        self._set_modified(False)
        if written != old_path:
            self.path_changed.emit(written)
        return written

    def _results_to_write(self, folder: Path, moved: bool) -> tuple[dict, list]:
        """``(fits, textures)`` for :func:`~photomodel.project.results.save_results` into ``folder``:
        the fitted meshes and textures held in memory and not yet saved there."""
        fits = {
            name: fit.vertices
            for name, fit in self.fits.items()
            if fit.vertices is not None
            and self.project.expression(name).result is not None
            and (moved or not fit.saved or not self._meshes_on_disk(name))
        }
        textures = [
            (tex.job, *encode_texture_outputs(self.project, tex.job, folder))
            for tex in self.textures.values()
            if moved or not tex.saved
        ]
        return fits, textures

    def _meshes_on_disk(self, name: str) -> bool:
        """Whether the mesh files the expression's result names are there: a fit put back by an
        undo names the files of the fit it replaced, which a save since has removed
        (:func:`photomodel.project.results.save_results`), so it is written again."""
        r = self.project.expression(name).result
        return all(p is not None and self.project.resolve(p).is_file() for p in (r.mesh_obj, r.mesh_ply))

    def _take_written_paths(self, written: Path) -> None:
        """After "save as": result and generic-mesh paths as written, relative to the new folder
        (photo paths are absolute in memory, see :meth:`open`)."""
        fresh = load_project(written)
        for e_old, e_new in zip(self.project.expressions, fresh.expressions, strict=True):
            if e_old.result is not None and e_new.result is not None:
                e_old.result.mesh_obj, e_old.result.mesh_ply = e_new.result.mesh_obj, e_new.result.mesh_ply
                e_old.result.texture = e_new.result.texture
        self.project.generic_mesh = fresh.generic_mesh

    def autosave(self, recovery: str | os.PathLike | None = None) -> Path | None:
        """Write ``<file>.autosave`` if there are changes since the last save or autosave.

        A project that has never been saved goes to ``recovery`` instead (the studio passes a
        file in the user's data folder, offered at the next start by :meth:`recover`); without
        ``recovery`` such a project is not autosaved. The project itself and its ``.bak`` are
        untouched. Returns the file written, or None.
        """
        if not self.modified or self.revision == self._autosaved_revision:
            return None
        if self.project.path is None:
            if recovery is None:
                return None
            target = Path(recovery).absolute()
        else:
            target = autosave_path(self.project.path)
        snapshot = copy.copy(self.project)  # save_project sets .path on what it saves
        save_project(snapshot, target)
        bak = target.with_name(target.name + ".bak")
        if bak.exists():  # save_project keeps the previous autosave as a backup; one file is enough
            bak.unlink()
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
        self.project_replaced.emit()
        self.modified_changed.emit(False)
        self.path_changed.emit(project.path)
        self._drop_rig()
        self.load_stored_texture(self.expression_name)


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
    for f in (autosave_path(path), autosave_path(path).with_name(autosave_path(path).name + ".bak")):
        try:
            f.unlink()
        except FileNotFoundError:
            pass


def camera_summary(camera: Camera) -> str:
    """``"f 85.2 mm, 612 mm away"``: a fitted camera in words for tool tips."""
    return f"f {camera.focal_mm:.1f} mm, {float(np.linalg.norm(camera.center)):.0f} mm away"


def format_px(value: float | None) -> str:
    return "–" if value is None or not math.isfinite(value) else f"{value:.2f} px"


__all__ = [
    "AUTOSAVE_SUFFIX",
    "FaceStudioError",
    "FitState",
    "MissingPhotos",
    "RigState",
    "Signal",
    "StudioModel",
    "autosave_path",
    "newer_autosave",
    "remove_autosave",
]
