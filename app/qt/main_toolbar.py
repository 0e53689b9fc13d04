"""The window's toolbar: the expression, the editing mode, the fit and overlay switches, and the
current photo's starting view and camera group.

The photo fields show the photo in front (:meth:`MainToolBar.sync_photo`); what the artist sets
in them is pushed as an undoable command for the photo it was set for — a camera group typed
while another tab comes forward still goes to the photo it was typed for.
"""

from __future__ import annotations

from PySide6.QtCore import QTimer
from PySide6.QtWidgets import QComboBox, QLabel, QLineEdit, QToolBar

from app.qt.photo_tabs import PhotoTabs
from app.studio.commands import SetCameraGroupCommand, SetPresetCommand
from app.studio_state import StudioModel
from photomodel.camera import PRESET_AZIMUTH_DEG
from photomodel.errors import FaceStudioError


class MainToolBar(QToolBar):
    """The toolbar of the window ``parent``; ``actions`` are the window's ``act_*`` actions by name."""

    def __init__(self, model: StudioModel, undo_stack, tabs: PhotoTabs, actions: dict, parent=None):
        super().__init__("Main", parent)
        self.setObjectName("main")
        self.model, self.undo_stack, self.tabs = model, undo_stack, tabs
        self.addWidget(QLabel(" Expression "))
        self.expr_combo = QComboBox()
        self.expr_combo.setMinimumContentsLength(10)
        self.expr_combo.activated.connect(self._on_expr_combo)
        self.addWidget(self.expr_combo)
        self.addAction(actions["act_new_expr"])
        self.addSeparator()
        self.addAction(actions["act_mode_points"])
        self.addAction(actions["act_mode_curve"])
        self.addSeparator()
        for name in ("act_fit", "act_auto", "act_overlay", "act_texture"):
            self.addAction(actions[name])
        self.addSeparator()
        self.addWidget(QLabel(" Photo view "))
        self.preset_combo = QComboBox()
        for p in PRESET_AZIMUTH_DEG:
            self.preset_combo.addItem(p.replace("_", " "), p)
        self.preset_combo.setToolTip("the rough direction the current photo was taken from (starts the pose recovery)")
        self.preset_combo.activated.connect(self._on_preset_combo)
        self.addWidget(self.preset_combo)
        self.addWidget(QLabel(" Camera group "))
        self.camera_group_edit = QLineEdit()
        self._camera_group_target = None  # (expression, photo id) whose group the field shows
        self.camera_group_edit.setPlaceholderText("own camera")
        self.camera_group_edit.setMaximumWidth(140)
        self.camera_group_edit.setToolTip(
            "photos with the same camera group were taken with one camera and lens (frames of a video, "
            "a fixed lens) and share one focal length; empty: a camera of its own"
        )
        self.camera_group_edit.editingFinished.connect(self._on_camera_group_edited)
        self.addWidget(self.camera_group_edit)
        self.addAction(actions["act_add_photos"])

    # ------------------------------------------------------------------ the expression
    def sync_expressions(self) -> None:
        """The expression box lists the project's expressions and shows the current one."""
        self.expr_combo.clear()
        for e in self.model.project.expressions:
            self.expr_combo.addItem(f"{e.name} ({len(e.photos)} photos)", e.name)
        i = self.expr_combo.findData(self.model.expression_name)
        self.expr_combo.setCurrentIndex(i)

    def _on_expr_combo(self, index: int):
        name = self.expr_combo.itemData(index)
        if name is not None and name != self.model.expression_name:
            self.model.set_expression(name)

    # ------------------------------------------------------------------ the photo in front
    def _on_preset_combo(self, index: int):
        view = self.tabs.current_view()
        preset = self.preset_combo.itemData(index)
        if view is not None and preset != view.photo.preset:
            self.undo_stack.push(SetPresetCommand(self.model, view.expression, view.photo_id, preset))

    def _on_camera_group_edited(self):
        """Enter or leaving the field: apply the camera group typed to the photo it was typed for."""
        pending = self._take_camera_group_edit()
        if pending is not None:
            self._apply_camera_group(*pending)

    def _take_camera_group_edit(self) -> tuple | None:
        """(project, expression, photo id, group) of a camera group typed but not yet applied, or None."""
        edit, target = self.camera_group_edit, self._camera_group_target
        if target is None or not edit.isModified():
            return None
        edit.setModified(False)
        return (self.model.project, *target, edit.text().strip() or None)

    def _apply_camera_group(self, project, expression: str, photo_id: str, group: str | None) -> None:
        if project is not self.model.project:  # typed in a project since closed
            return
        try:
            photo = self.model.photo(photo_id, expression)
        except FaceStudioError:  # the photo went away meanwhile
            return
        if group != photo.camera_group:
            self.undo_stack.push(SetCameraGroupCommand(self.model, expression, photo_id, group))

    def sync_photo(self) -> None:
        """The toolbar's photo properties (starting view, camera group) show the current photo's."""
        # a group still being typed belongs to the photo shown until now; applied once the edit
        # that brought us here (a tab change, an undo) has finished: never push inside an undo
        pending = self._take_camera_group_edit()
        if pending is not None:
            QTimer.singleShot(0, self, lambda: self._apply_camera_group(*pending))
        view = self.tabs.current_view()
        self.preset_combo.setEnabled(view is not None)
        self.camera_group_edit.setEnabled(view is not None)
        if view is not None:
            i = self.preset_combo.findData(view.photo.preset)
            self.preset_combo.setCurrentIndex(i)
            self._camera_group_target = (view.expression, view.photo_id)
            self.camera_group_edit.setText(view.photo.camera_group or "")  # also clears isModified
        else:
            self._camera_group_target = None
            self.camera_group_edit.clear()
