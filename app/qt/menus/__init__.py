"""The studio's menus, one module per menu (as napari keeps ``_qt/_qapp_model/qactions/_file.py``, ``_view.py`` …).

Each module holds one menu's :class:`QAction` objects, the menu built from them and the work
behind them (an object per menu, parented to the window); :class:`~app.qt.main_window.MainWindow`
only assembles them and keeps the ``act_*`` names on itself. A menu talks to the window through
its public API (``show_status``, ``show_error``, ``open_progress``, the docks and the photo tabs).
"""

from __future__ import annotations

from PySide6.QtGui import QAction, QKeySequence


def make_action(parent, text, slot=None, shortcut=None, checkable=False, checked=False, tip=None) -> QAction:
    """A :class:`QAction` of ``parent`` (the window: its shortcuts work wherever the window has the focus).

    ``slot`` is connected to ``toggled`` for a checkable action, else to ``triggered``; ``tip``
    is both the status tip and the tool tip.
    """
    a = QAction(text, parent)
    if shortcut is not None:
        a.setShortcut(QKeySequence(shortcut))
    if checkable:
        a.setCheckable(True)
        a.setChecked(checked)
    if tip:
        a.setStatusTip(tip)
        a.setToolTip(tip)
    if slot is not None:
        (a.toggled if checkable else a.triggered).connect(slot)
    return a


def actions_of(menu_object) -> dict[str, QAction]:
    """The ``act_*`` attributes of a menu object, by name (the window keeps them under the same names)."""
    return {k: v for k, v in vars(menu_object).items() if k.startswith("act_")}
