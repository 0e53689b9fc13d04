"""The *Edit* menu: undo and redo of the window's :class:`QUndoStack`, and the photo in front's
active click deleted or hidden (the ``Delete`` and ``H`` keys in a photo)."""

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
        stack = window.undo_stack
        self.act_undo = stack.createUndoAction(window, "&Undo")
        self.act_undo.setShortcut(QKeySequence.StandardKey.Undo)
        self.act_redo = stack.createRedoAction(window, "&Redo")
        # Ctrl+Y (Windows' and Qt's Redo on Linux) and Ctrl+Shift+Z (macOS, Blender, GIMP) both redo
        redo_keys = [*QKeySequence.keyBindings(QKeySequence.StandardKey.Redo)]
        for extra in (QKeySequence("Ctrl+Y"), QKeySequence("Ctrl+Shift+Z")):
            if extra not in redo_keys:
                redo_keys.append(extra)
        self.act_redo.setShortcuts(redo_keys)
        self.act_delete = A("Delete click of the active feature", self.delete_click, tip="Delete key in a photo")
        self.act_hide = A("Hide / show the active feature in this photo", self.toggle_hidden, tip="H in a photo")

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
