"""The docks around the photo tabs: features and fit, the 3D view, the weight maps, the expressions
side by side, tracking and the rig.

:func:`build_docks` makes each panel and its :class:`QDockWidget` and lays them out: the
:class:`~app.qt.feature_list.FeaturePanel` on the left (the *Rig* dock tabbed with it), the
:class:`~app.qt.view3d.View3D` on the right with the weight maps under it, the expressions and
tracking tabbed along the bottom. The weight maps, expressions and tracking start hidden (shown
by the first texture, *Expression → Side by side*, *Tracking → …*).
"""

from __future__ import annotations

from dataclasses import dataclass

from PySide6.QtCore import Qt
from PySide6.QtWidgets import QDockWidget, QMainWindow

from app.qt.feature_list import FeaturePanel
from app.qt.rig_panel import RigPanel
from app.qt.texture_views import ExpressionsView, WeightMapPanel
from app.qt.tracking_view import TrackingView
from app.qt.view3d import View3D
from app.studio_state import StudioModel


@dataclass
class Docks:
    """The window's panels and the docks holding them."""

    panel: FeaturePanel
    features_dock: QDockWidget
    view3d: View3D
    view3d_dock: QDockWidget
    weights_panel: WeightMapPanel
    weights_dock: QDockWidget
    expressions_view: ExpressionsView
    expressions_dock: QDockWidget
    tracking_view: TrackingView
    tracking_dock: QDockWidget
    rig_panel: RigPanel
    rig_dock: QDockWidget

    def toggle_actions(self) -> list:
        """The docks' show / hide actions, in the *View* menu's order."""
        docks = (
            self.features_dock,
            self.view3d_dock,
            self.weights_dock,
            self.expressions_dock,
            self.tracking_dock,
            self.rig_dock,
        )
        return [d.toggleViewAction() for d in docks]


def add_dock(window: QMainWindow, title: str, name: str, widget, area, *, closable: bool = True) -> QDockWidget:
    """A movable, floatable dock (closable unless told) holding ``widget``, added to ``window`` at ``area``."""
    dock = QDockWidget(title, window)
    dock.setObjectName(name)
    dock.setWidget(widget)
    features = QDockWidget.DockWidgetFeature.DockWidgetMovable | QDockWidget.DockWidgetFeature.DockWidgetFloatable
    if closable:
        features |= QDockWidget.DockWidgetFeature.DockWidgetClosable
    dock.setFeatures(features)
    window.addDockWidget(area, dock)
    return dock


def build_docks(window: QMainWindow, model: StudioModel, undo_stack) -> Docks:
    """Every panel of ``window`` in its dock, laid out (see the module docstring)."""
    left, right = Qt.DockWidgetArea.LeftDockWidgetArea, Qt.DockWidgetArea.RightDockWidgetArea
    bottom = Qt.DockWidgetArea.BottomDockWidgetArea
    panel = FeaturePanel(model, undo_stack=undo_stack)
    dock = add_dock(window, "Features and fit", "features", panel, left, closable=False)

    view3d = View3D(model)
    dock3 = add_dock(window, "3D view", "view3d", view3d, right, closable=False)
    window.resizeDocks([dock, dock3], [330, 400], Qt.Orientation.Horizontal)

    weights_panel = WeightMapPanel(model)
    dockw = add_dock(window, "Texture and weight maps", "weight_maps", weights_panel, right)
    window.splitDockWidget(dock3, dockw, Qt.Orientation.Vertical)  # under the 3D view
    dockw.hide()  # shown by the first texture

    expressions_view = ExpressionsView(model)
    docke = add_dock(window, "Expressions side by side", "expressions", expressions_view, bottom)
    docke.hide()

    tracking_view = TrackingView(model)
    dockt = add_dock(window, "Tracking", "tracking", tracking_view, bottom)
    window.tabifyDockWidget(docke, dockt)
    dockt.hide()

    rig_panel = RigPanel(model)
    rig_dock = add_dock(window, "Rig", "rig", rig_panel, left)
    window.tabifyDockWidget(dock, rig_dock)
    dock.raise_()
    return Docks(
        panel,
        dock,
        view3d,
        dock3,
        weights_panel,
        dockw,
        expressions_view,
        docke,
        tracking_view,
        dockt,
        rig_panel,
        rig_dock,
    )
