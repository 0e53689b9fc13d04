"""The *View* menu: the editing mode of the photos (click points / draw curve), what they show
(the fitted wireframe, the drawn curves), the photo fitted to the window, and each dock shown or
hidden."""

from __future__ import annotations

from functools import partial

from PySide6.QtCore import QObject
from PySide6.QtGui import QActionGroup
from PySide6.QtWidgets import QMenu, QMenuBar

from app.qt.menus import make_action
from app.qt.photo_view import CURVE, POINTS


class ViewMenu(QObject):
    """The *View* menu of ``window`` (a :class:`~app.qt.main_window.MainWindow`)."""

    def __init__(self, window):
        super().__init__(window)
        self.window = window
        A = partial(make_action, window)
        self.act_overlay = A("Fitted &wireframe overlay", self.set_overlay, "W", checkable=True, checked=True)
        self.act_curves = A("Drawn &curves", self.set_curves, checkable=True, checked=True)
        self.act_fit_view = A("Fit photo to window", self.fit_photo_view, "F")
        self.act_mode_points = A(
            "Click &points",
            lambda on: on and self.set_mode(POINTS),
            "P",
            checkable=True,
            checked=True,
            tip="left-click places the active feature; drag a marker to move it",
        )
        self.act_mode_curve = A(
            "Draw &curve",
            lambda on: on and self.set_mode(CURVE),
            "C",
            checkable=True,
            tip="click successive points (or drag) along a brow, lid or lip; Enter finishes",
        )
        group = QActionGroup(window)
        group.addAction(self.act_mode_points)
        group.addAction(self.act_mode_curve)

    def build(self, menubar: QMenuBar, dock_toggles) -> QMenu:
        """The menu, ending with ``dock_toggles`` (the docks' show / hide actions)."""
        v = menubar.addMenu("&View")
        for a in (self.act_mode_points, self.act_mode_curve):
            v.addAction(a)
        v.addSeparator()
        for a in (self.act_overlay, self.act_curves, self.act_fit_view):
            v.addAction(a)
        v.addSeparator()
        for a in dock_toggles:
            v.addAction(a)
        return v

    def set_mode(self, mode: str):
        """Every photo in ``mode`` (:data:`~app.qt.photo_view.POINTS` or :data:`~app.qt.photo_view.CURVE`)."""
        self.window.tabs.set_mode(mode)
        (self.act_mode_curve if mode == CURVE else self.act_mode_points).setChecked(True)
        if mode == CURVE:
            self.window.show_status(
                f"draw curve {self.window.model.active_curve}: click points along it, Enter to finish"
            )

    def set_overlay(self, on: bool):
        self.window.tabs.set_overlay_visible(on)

    def set_curves(self, on: bool):
        self.window.tabs.set_curves_visible(on)

    def fit_photo_view(self):
        view = self.window.current_view()
        if view is not None:
            view.user_zoomed = False
            view.fit_photo()
