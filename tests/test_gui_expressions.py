"""The studio's fit of an expression that reuses another's cameras (``cameras_from``), pytest-qt offscreen.

The sample project's smile was photographed by the neutral's rig: the studio fits it with the
neutral's fitted cameras, and says clearly when the neutral is not fitted yet.
"""

from __future__ import annotations

import numpy as np
import pytest

pytest.importorskip("PySide6")
pytest.importorskip("pytestqt")

from PySide6.QtCore import QSettings  # noqa: E402
from PySide6.QtWidgets import QMessageBox  # noqa: E402

from app.main_window import MainWindow  # noqa: E402


@pytest.fixture
def messages(monkeypatch):
    """Every message box shown, as (kind, title, text)."""
    shown = []

    def fake(kind):
        def box(parent, title, text, *args, **kwargs):
            shown.append((kind, title, text))
            return QMessageBox.StandardButton.No if kind == "question" else QMessageBox.StandardButton.Ok

        return box

    for kind in ("critical", "warning", "information", "question"):
        monkeypatch.setattr(QMessageBox, kind, fake(kind))
    return shown


@pytest.fixture
def window(qtbot, tmp_path, messages):
    w = MainWindow(settings=QSettings(str(tmp_path / "settings.ini"), QSettings.Format.IniFormat),
                   autosave_interval_ms=0)  # fmt: skip
    qtbot.addWidget(w)
    w.resize(1300, 850)
    w.show()
    qtbot.waitExposed(w)
    yield w
    w.fits.shutdown()
    w.model.modified = False  # no unsaved-changes prompt when the test ends


def _fit(qtbot, window) -> None:
    assert window.run_fit()
    qtbot.waitUntil(lambda: not window.fits.busy, timeout=60_000)


def test_studio_fits_an_expression_with_its_sources_cameras(qtbot, window, project_copy, messages):
    assert window.open_project(project_copy)
    model = window.model
    window.act_auto.setChecked(False)
    # the smile first: its cameras come from the neutral, which is not fitted — the artist is told
    model.set_expression("smile")
    _fit(qtbot, window)
    assert model.fit("smile") is None
    assert messages and messages[-1][0] == "critical"
    assert "which is not fitted yet: fit 'neutral' first" in messages[-1][2] and "Traceback" not in messages[-1][2]
    # fit the neutral, then the smile: the smile's cameras are the neutral's
    model.set_expression("neutral")
    _fit(qtbot, window)
    model.set_expression("smile")
    _fit(qtbot, window)
    smile, neutral = model.fit("smile"), model.fit("neutral")
    assert smile is not None and smile.report["cameras_from"] == "neutral"
    np.testing.assert_array_equal(smile.cameras["front"].R, neutral.cameras["front"].R)
    assert smile.report["rms_px"] < 1.5  # the click noise (measured 1.14 px)
    assert len(messages) == 1, messages
