"""The edit primitives of the studio's project: the one way the studio changes it.

:class:`ProjectEdits` is the base of :class:`app.studio_state.StudioModel` that holds its edits, so
that the model's file keeps its state and events. Each primitive (``set_point``, ``set_hidden``,
``set_curve``, ``insert_photo`` …) validates its input (a :class:`ProjectError` naming the
feature, photo or curve), changes the project, marks it modified, emits one event and returns what
it replaced — what an undo needs: :mod:`app.studio.commands` makes one undoable command of each.
No Qt.

The primitives use the model's ``project``, ``mesh``, ``photo``/``has_feature``/``has_curve``
look-ups, its events and its ``_expr``, ``_touch``, ``_drop_fit``, ``_drop_texture`` and
``load_stored_texture`` (adding or removing a photo invalidates the expression's fit; removing an
expression drops its fit and texture).
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from photomodel.camera import PRESET_AZIMUTH_DEG
from photomodel.errors import ProjectError
from photomodel.photos.exif import focal_mm_guess_from_exif
from photomodel.photos.reading import photo_size
from photomodel.project import CurveDef, Expression, Feature, Photo


class ProjectEdits:
    """The edit primitives of :class:`app.studio_state.StudioModel` (see the module docstring)."""

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


__all__ = ["ProjectEdits"]
