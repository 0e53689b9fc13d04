"""The studio's fit of an expression that reuses another's cameras (``cameras_from``), pytest-qt offscreen.

The sample project's smile was photographed by the neutral's rig: the studio fits it with the
neutral's fitted cameras, and says clearly when the neutral is not fitted yet.
"""

from __future__ import annotations

import numpy as np
import pytest

pytest.importorskip("PySide6")
pytest.importorskip("pytestqt")


def _fit(qtbot, studio_window) -> None:
    assert studio_window.run_fit()
    qtbot.waitUntil(lambda: not studio_window.fits.busy, timeout=60_000)


def test_studio_fits_an_expression_with_its_sources_cameras(qtbot, studio_window, project_copy, messages):
    assert studio_window.open_project(project_copy)
    model = studio_window.model
    studio_window.act_auto.setChecked(False)
    # the smile first: its cameras come from the neutral, which is not fitted — the artist is told
    model.set_expression("smile")
    _fit(qtbot, studio_window)
    assert model.fit("smile") is None
    assert messages and messages[-1][0] == "critical"
    assert "which is not fitted yet: fit 'neutral' first" in messages[-1][2] and "Traceback" not in messages[-1][2]
    # fit the neutral, then the smile: the smile's cameras are the neutral's
    model.set_expression("neutral")
    _fit(qtbot, studio_window)
    model.set_expression("smile")
    _fit(qtbot, studio_window)
    smile, neutral = model.fit("smile"), model.fit("neutral")
    assert smile is not None and smile.report["cameras_from"] == "neutral"
    np.testing.assert_array_equal(smile.cameras["front"].R, neutral.cameras["front"].R)
    assert smile.report["rms_px"] < 1.5  # the click noise (measured 1.14 px)
    assert len(messages) == 1, messages
