"""The *Edit* menu: undo and redo of the model's undo stack (:class:`app.studio.undo.UndoStack`), and
the photo in front's active click deleted or hidden (the ``Delete`` and ``H`` keys in a photo).

The *Undo* and *Redo* actions follow the stack's ``changed`` event: enabled when there is something
to undo or redo, their text naming it (``"&Undo Move chin in front"``), as Qt's undo actions do."""

from __future__ import annotations

from functools import partial

from PySide6.QtCore import QObject
from PySide6.QtGui import QKeySequence
from PySide6.QtWidgets import QMenu, QMenuBar

from app.qt.menus import make_action


class EditMenu(QObject):
    """The *Edit* menu of ``window`` (a :class:`~app.qt.main_window.MainWindow`)."""

    def __init__(self, window):
        super().__init__(window)
        self.window = window
        A = partial(make_action, window)
        self.stack = stack = window.model.undo_stack
        self.act_undo = A("&Undo", lambda *_: stack.undo())
        self.act_undo.setShortcut(QKeySequence.StandardKey.Undo)
        self.act_redo = A("&Redo", lambda *_: stack.redo())
        # Ctrl+Y (Windows' and Qt's Redo on Linux) and Ctrl+Shift+Z (macOS, Blender, GIMP) both redo
        redo_keys = [*QKeySequence.keyBindings(QKeySequence.StandardKey.Redo)]
        for extra in (QKeySequence("Ctrl+Y"), QKeySequence("Ctrl+Shift+Z")):
            if extra not in redo_keys:
                redo_keys.append(extra)
        self.act_redo.setShortcuts(redo_keys)
        self.act_delete = A("Delete click of the active feature", self.delete_click, tip="Delete key in a photo")
        self.act_hide = A("Hide / show the active feature in this photo", self.toggle_hidden, tip="H in a photo")
        stack.changed.connect(self.sync_undo_actions)
        self.sync_undo_actions()

    def sync_undo_actions(self) -> None:
        """Enable *Undo*/*Redo* when the stack can, each naming the command it would undo or redo."""
        for action, prefix, can, text in (
            (self.act_undo, "&Undo", self.stack.can_undo, self.stack.undo_text),
            (self.act_redo, "&Redo", self.stack.can_redo, self.stack.redo_text),
        ):
            action.setEnabled(can)
            action.setText(f"{prefix} {text}" if text else prefix)

    def build(self, menubar: QMenuBar) -> QMenu:
        e = menubar.addMenu("&Edit")
        for a in (self.act_undo, self.act_redo):
            e.addAction(a)
        e.addSeparator()
        e.addAction(self.act_delete)
        e.addAction(self.act_hide)
        return e

    def delete_click(self):
        view = self.window.current_view()
        if view is not None:
            view.delete_active_click()

    def toggle_hidden(self):
        view = self.window.current_view()
        if view is not None:
            view.toggle_active_hidden()
