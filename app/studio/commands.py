"""Undoable edits of a :class:`~app.studio_state.StudioModel`: one :class:`~app.studio.undo.UndoCommand` per action.

Each command calls the model's edit primitives in ``redo`` and restores what they returned in
``undo``, so the model's undo stack (:class:`~app.studio.undo.UndoStack`, ``model.undo_stack``,
undone and redone by the Edit menu) covers every change of the clicks, curves, photos, features
and expressions, and a scan's fit (*Fit → Add scan…*). A click on a generic-mesh feature that the
project does not define yet adds the definition in the same command (and undo removes it).
Commands name their photo and feature, never hold widgets, and are pushed by the views.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from app.studio.fitting import FitState
from app.studio.undo import UndoCommand
from app.studio_state import StudioModel
from photomodel.project import CurveDef, Expression, Feature, Photo


def _fmt_uv(uv) -> str:
    return "–" if uv is None else f"({uv[0]:.1f}, {uv[1]:.1f})"


class SetPointCommand(UndoCommand):
    """Place, move or delete (``uv=None``) the click of a feature in one photo.

    Placing a click also shows the feature again in that photo if it was hidden there. The click
    is the artist's (``source="user"``), also when it moves an automatic one; undo restores the
    automatic click with its confidence.
    """

    def __init__(
        self, model: StudioModel, expression: str, photo_id: str, feature: str, uv, old_uv=None, text: str | None = None
    ):
        photo = model.photo(photo_id, expression)
        self.model, self.expression, self.photo_id, self.feature = model, expression, photo_id, feature
        self.new = None if uv is None else np.asarray(uv, dtype=float).reshape(2).copy()
        # a drag moves the marker before the command exists: its start is passed in
        current = photo.points.get(feature)
        self.old = (
            np.asarray(old_uv, float).reshape(2).copy()
            if old_uv is not None
            else (None if current is None else current.copy())
        )
        self.was_hidden = feature in photo.hidden
        # an automatic click the artist moves becomes theirs; undo makes it automatic again
        self.old_source = (photo.click_source(feature), photo.confidence.get(feature))
        self.define = None
        if not model.has_feature(feature):
            self.define = Feature(feature, model.mesh.features[feature], pose=False)
        if text is None:
            if self.new is None:
                text = f"Delete {feature} in {photo_id}"
            elif self.old is None:
                text = f"Click {feature} in {photo_id}"
            else:
                text = f"Move {feature} in {photo_id}"
        super().__init__(text)

    def redo(self):
        if self.define is not None and not self.model.has_feature(self.define.name):
            self.model.add_feature(Feature(self.define.name, self.define.vertex, self.define.pose))
        if self.new is not None and self.was_hidden:
            self.model.set_hidden(self.expression, self.photo_id, self.feature, False)
        self.model.set_point(self.expression, self.photo_id, self.feature, self.new)

    def undo(self):
        source, confidence = self.old_source
        self.model.set_point(
            self.expression, self.photo_id, self.feature, self.old, source=source, confidence=confidence
        )
        if self.new is not None and self.was_hidden:
            self.model.set_hidden(self.expression, self.photo_id, self.feature, True)
        if self.define is not None:
            self.model.remove_feature(self.define.name)


class DefineFeaturesCommand(UndoCommand):
    """Add feature definitions the project lacks (e.g. those automatic landmarks of new photos
    use); pushed with the photos in one macro, so one undo takes both back."""

    def __init__(self, model: StudioModel, features: list[Feature]):
        super().__init__(f"Define {', '.join(f.name for f in features)}")
        self.model = model
        self.features = [Feature(f.name, f.vertex, f.pose) for f in features]

    def redo(self):
        for f in self.features:
            if not self.model.has_feature(f.name):
                self.model.add_feature(Feature(f.name, f.vertex, f.pose))

    def undo(self):
        for f in reversed(self.features):
            self.model.remove_feature(f.name)


class SetHiddenCommand(UndoCommand):
    """Mark a feature as not visible (or visible again) in one photo."""

    def __init__(self, model: StudioModel, expression: str, photo_id: str, feature: str, hidden: bool):
        super().__init__(f"{'Hide' if hidden else 'Show'} {feature} in {photo_id}")
        self.model, self.expression, self.photo_id, self.feature = model, expression, photo_id, feature
        self.hidden = bool(hidden)
        self.old = feature in model.photo(photo_id, expression).hidden

    def redo(self):
        self.model.set_hidden(self.expression, self.photo_id, self.feature, self.hidden)

    def undo(self):
        self.model.set_hidden(self.expression, self.photo_id, self.feature, self.old)


class SetPoseCommand(UndoCommand):
    """Flag a feature as a pose feature or unflag it: one the views cannot see twice is left out
    of the camera solve (and so of the fit's checklist) but still refines the mesh."""

    def __init__(self, model: StudioModel, feature: str, pose: bool):
        super().__init__(f"{'Flag' if pose else 'Unflag'} {feature} as a pose feature")
        self.model, self.feature, self.pose = model, feature, bool(pose)
        self.old = model.project.feature(feature).pose

    def redo(self):
        self.model.set_feature_pose(self.feature, self.pose)

    def undo(self):
        self.model.set_feature_pose(self.feature, self.old)


class SetCurveCommand(UndoCommand):
    """Draw, replace or delete (``polyline=None``) a curve in one photo (§5.1.3)."""

    def __init__(self, model: StudioModel, expression: str, photo_id: str, curve: str, polyline):
        self.model, self.expression, self.photo_id, self.curve = model, expression, photo_id, curve
        self.new = None if polyline is None else np.asarray(polyline, dtype=float).reshape(-1, 2).copy()
        old = model.photo(photo_id, expression).curves.get(curve)
        self.old = None if old is None else old.copy()
        self.old_source = model.curve_source(expression, photo_id, curve)  # an automatic curve stays one on undo
        self.define = None
        if not model.has_curve(curve):
            self.define = CurveDef(curve, model.mesh.curves[curve])
        verb = "Delete" if self.new is None else ("Draw" if self.old is None else "Redraw")
        super().__init__(f"{verb} curve {curve} in {photo_id}")

    def redo(self):
        if self.define is not None and not self.model.has_curve(self.define.name):
            self.model.add_curve_def(CurveDef(self.define.name, self.define.vertices))
        self.model.set_curve(self.expression, self.photo_id, self.curve, self.new)

    def undo(self):
        self.model.set_curve(self.expression, self.photo_id, self.curve, self.old, source=self.old_source)
        if self.define is not None:
            self.model.remove_curve_def(self.define.name)


class AddPhotosCommand(UndoCommand):
    """Add photos to an expression."""

    def __init__(self, model: StudioModel, expression: str, photos: list[Photo]):
        names = ", ".join(p.id for p in photos)
        super().__init__(f"Add photo{'s' if len(photos) > 1 else ''} {names}")
        self.model, self.expression, self.photos = model, expression, list(photos)
        self.saved_fit = None

    def redo(self):
        self.saved_fit = self.model.fits.get(self.expression), self.model.project.expression(self.expression).result
        for p in self.photos:
            self.model.insert_photo(self.expression, p)

    def undo(self):
        for p in reversed(self.photos):
            self.model.remove_photo(self.expression, p.id)
        _restore_fit(self.model, self.expression, self.saved_fit)


class RemovePhotoCommand(UndoCommand):
    """Remove one photo (with its clicks and curves) from an expression."""

    def __init__(self, model: StudioModel, expression: str, photo_id: str):
        super().__init__(f"Remove photo {photo_id}")
        self.model, self.expression, self.photo_id = model, expression, photo_id
        self.photo, self.index, self.saved_fit = None, None, None

    def redo(self):
        self.saved_fit = self.model.fits.get(self.expression), self.model.project.expression(self.expression).result
        self.photo, self.index = self.model.remove_photo(self.expression, self.photo_id)

    def undo(self):
        self.model.insert_photo(self.expression, self.photo, self.index)
        _restore_fit(self.model, self.expression, self.saved_fit)


def _restore_fit(model: StudioModel, expression: str, saved) -> None:
    """Put back the fit an add/remove of photos dropped (it is valid again for the old photos)."""
    if saved is None or saved[0] is None:
        return
    model.fits[expression] = saved[0]
    model.project.expression(expression).result = saved[1]
    model.fit_changed.emit(expression)


class SetPresetCommand(UndoCommand):
    """Change a photo's rough starting view (front, three-quarter, profile)."""

    def __init__(self, model: StudioModel, expression: str, photo_id: str, preset: str):
        super().__init__(f"Set {photo_id} to {preset.replace('_', ' ')}")
        self.model, self.expression, self.photo_id, self.preset = model, expression, photo_id, preset
        self.old = model.photo(photo_id, expression).preset

    def redo(self):
        self.model.set_photo_preset(self.expression, self.photo_id, self.preset)

    def undo(self):
        self.model.set_photo_preset(self.expression, self.photo_id, self.old)


class SetCameraGroupCommand(UndoCommand):
    """Name the camera a photo was taken with (photos of one group share one focal length);
    ``None`` clears it."""

    def __init__(self, model: StudioModel, expression: str, photo_id: str, group: str | None):
        super().__init__(
            f"Set camera group of {photo_id} to {group}" if group is not None else f"Clear camera group of {photo_id}"
        )
        self.model, self.expression, self.photo_id, self.group = model, expression, photo_id, group
        self.old = model.photo(photo_id, expression).camera_group

    def redo(self):
        self.model.set_photo_camera_group(self.expression, self.photo_id, self.group)

    def undo(self):
        self.model.set_photo_camera_group(self.expression, self.photo_id, self.old)


class AddExpressionCommand(UndoCommand):
    """Add an (empty) expression and make it current; ``cameras_from``: the expression whose
    fitted cameras it reuses (photographed by the same rig), or None."""

    def __init__(self, model: StudioModel, name: str, cameras_from: str | None = None):
        super().__init__(f"Add expression {name}")
        self.model, self.name = model, name
        self.previous = model.expression_name
        self.expression = Expression(name=name, cameras_from=cameras_from)

    def redo(self):
        self.model.add_expression(self.name, expression=self.expression)

    def undo(self):
        self.model.remove_expression(self.name)
        if self.previous is not None:
            self.model.set_expression(self.previous)


class ScanFitCommand(UndoCommand):
    """Make a scan's fit (:meth:`app.studio_state.StudioModel.scan_fit_job`'s result) an expression's
    fit; undo puts back the fit, result and texture it replaced. The clicks and curves are not touched."""

    def __init__(self, model: StudioModel, made):
        super().__init__(f"Fit {made.expression} to {Path(made.report.get('scan', 'the scan')).name}")
        self.model, self.made = model, made
        self.saved = None

    def redo(self):
        self.saved = self.model.replace_fit(self.made.expression, FitState.of_scan(self.made), self.made.result)

    def undo(self):
        self.model.replace_fit(self.made.expression, *self.saved)
