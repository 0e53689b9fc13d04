"""The cancellable progress dialog shared by the fit, texture and tracking actions."""

from __future__ import annotations

from collections.abc import Callable

from PySide6.QtCore import Qt
from PySide6.QtWidgets import QProgressDialog, QWidget


def open_progress(
    parent: QWidget, title: str, label: str, on_cancel: Callable[[], None], min_duration_ms: int = 300
) -> QProgressDialog:
    """A window-modal 0–100 % dialog whose Cancel button calls ``on_cancel``; it stays open until
    :func:`close_progress` (no auto close/reset, so a late progress report cannot reopen it)."""
    dlg = QProgressDialog(label, "Cancel", 0, 100, parent)
    dlg.setWindowTitle(title)
    dlg.setWindowModality(Qt.WindowModality.WindowModal)
    dlg.setMinimumDuration(min_duration_ms)
    dlg.setAutoClose(False)
    dlg.setAutoReset(False)
    dlg.canceled.connect(on_cancel)
    return dlg


def update_progress(dlg: QProgressDialog | None, stage: str, fraction: float) -> None:
    if dlg is not None:
        dlg.setLabelText(stage)
        dlg.setValue(int(round(100 * fraction)))


def close_progress(dlg: QProgressDialog | None, on_cancel: Callable[[], None]) -> None:
    """Close and delete ``dlg`` (if any) without firing ``on_cancel``; the caller drops its reference."""
    if dlg is not None:
        dlg.canceled.disconnect(on_cancel)
        dlg.close()
        dlg.deleteLater()
