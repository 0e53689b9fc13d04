"""Refuse the one PySide6 build known to crash the studio, with a message that says what to do.

PySide6 6.12.0 on CPython ≤ 3.11 returns ``None`` from every C++ ``void`` method without taking
a reference to it (measured: 100 ``QPainter.setPen`` calls lower ``sys.getrefcount(None)`` by
100; 6.11.3 by 0). Since Python 3.12 ``None`` is immortal (PEP 683) and the bug is harmless,
but on 3.11 the count reaches zero after a few thousand paints and the interpreter aborts with
"Fatal Python error: none_dealloc". ``pyproject.toml`` therefore asks for ``PySide6<6.12``.
"""

from __future__ import annotations

import sys


def check_pyside() -> None:
    """Raise ImportError naming the fix when the installed PySide6 is the crashing build."""
    from PySide6 import QtCore  # noqa: PLC0415 - the Qt stack loads only when the studio opens

    text = getattr(QtCore, "__version__", "0.0")
    version = tuple(int(x) for x in text.split(".")[:2])
    if version == (6, 12) and sys.version_info < (3, 12):
        raise ImportError(
            f"PySide6 {text} crashes on Python {sys.version_info.major}.{sys.version_info.minor} "
            "(it releases None on every void call); install an earlier one: pip install 'PySide6>=6.6,<6.12'"
        )
