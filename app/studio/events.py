"""The studio's events: :class:`Signal`, a minimal observer the Qt-free state announces its changes with.

:class:`app.studio_state.StudioModel` holds one :class:`Signal` per kind of change; the widgets of
:mod:`app.qt` connect to them (napari's event emitters, without Qt, so tests and scripts observe
the same state).
"""

from __future__ import annotations

from collections.abc import Callable


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


__all__ = ["Signal"]
