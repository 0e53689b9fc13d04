"""The *Expression* menu: a new expression (photographed with its own cameras or another
expression's), and every fitted expression side by side (:class:`~app.qt.texture_views.ExpressionsView`)."""

from __future__ import annotations

from functools import partial

from PySide6.QtCore import QObject
from PySide6.QtWidgets import QInputDialog, QMenu, QMenuBar

from app.qt.menus import make_action
from app.studio.commands import AddExpressionCommand
from photomodel.errors import FaceStudioError


class ExpressionMenu(QObject):
    """The *Expression* menu of ``window`` (a :class:`~app.qt.main_window.MainWindow`)."""

    def __init__(self, window):
        super().__init__(window)
        self.window = window
        A = partial(make_action, window)
        self.act_new_expr = A("New &expression…", self.new_expression_dialog)
        self.act_side_by_side = A(
            "Expressions &side by side",
            self.show_expressions,
            tip="every fitted expression from the same camera, with its RMS",
        )

    def build(self, menubar: QMenuBar) -> QMenu:
        x = menubar.addMenu("E&xpression")
        x.addAction(self.act_new_expr)
        x.addAction(self.act_side_by_side)
        return x

    def new_expression_dialog(self):
        window, model = self.window, self.window.model
        name, ok = QInputDialog.getText(window, "New expression", "Name of the expression (e.g. smile):")
        if not (ok and name.strip()):
            return
        # the paper photographs every expression with the same cameras: offer to reuse theirs
        cameras_from = None
        others = [e.name for e in model.project.expressions]
        if others:
            own = "its own cameras (recovered from its clicks)"
            choices = [f"the cameras of {o!r} (the same rig)" for o in others] + [own]
            choice, ok = QInputDialog.getItem(window, "New expression", "Photographed with:", choices, 0, False)
            if not ok:
                return
            cameras_from = None if choice == own else others[choices.index(choice)]
        try:
            window.undo_stack.push(AddExpressionCommand(model, name.strip(), cameras_from=cameras_from))
        except FaceStudioError as exc:
            window.show_error("Cannot add the expression", str(exc))

    def show_expressions(self) -> None:
        self.window.expressions_dock.show()
        self.window.expressions_dock.raise_()
        self.window.expressions_view.refresh()
