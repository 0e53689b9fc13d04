"""The studio's rig panel: the project's blend shapes with sliders posing the 3D view."""

import argparse
import os
import shutil
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("PySide6")

from PySide6.QtCore import Qt  # noqa: E402

from app.cli.rig import run as cmd_rig  # noqa: E402
from photomodel.project import load_project, load_rig_shapes, save_project  # noqa: E402

REPO_IMG = Path(__file__).resolve().parents[1] / "docs" / "img"


@pytest.fixture(scope="module")
def rigged(tmp_path_factory, fitted_sample):
    """A copy of the fitted sample project rigged by ``facestudio rig`` (made once for the module)."""
    dst = tmp_path_factory.mktemp("rigged") / "james"
    shutil.copytree(fitted_sample.parent, dst)
    path = dst / fitted_sample.name
    assert cmd_rig(argparse.Namespace(project=path, neutral=None, json=False, method="transfer")) == 0
    return path


def test_panel_hints_without_a_rig(studio_window):
    panel = studio_window.rig_panel
    assert studio_window.model.rig() is None and not panel.sliders
    assert not panel.hint.isHidden() and "facestudio rig PROJECT" in panel.hint.text()
    assert "Build rig" in panel.hint.text()


def test_sliders_pose_the_3d_view(studio_window, rigged, qtbot):
    w = studio_window
    w.open_project(rigged)
    project = load_project(rigged)
    names, deltas = load_rig_shapes(project)
    panel = w.rig_panel
    photographed = [e.name for e in project.expressions if e.name != project.rig.neutral]
    assert list(panel.sliders) == names + photographed and len(names) == 51
    assert panel.hint.isHidden()
    neutral, _ = w.view3d.vertices()
    np.testing.assert_array_equal(neutral, w.model.fit(project.rig.neutral).vertices)

    i = names.index("jawOpen")
    panel.sliders["jawOpen"].setValue(100)  # as a drag to the end
    posed, caption = w.view3d.vertices()
    assert "jawOpen" in caption
    np.testing.assert_allclose(posed - neutral, deltas[i], atol=1e-4)
    assert np.linalg.norm(deltas[i], axis=1).max() > 5.0  # the jaw moves millimetres
    panel.sliders["mouthSmileLeft"].setValue(50)
    posed, _ = w.view3d.vertices()
    np.testing.assert_allclose(posed - neutral, deltas[i] + 0.5 * deltas[names.index("mouthSmileLeft")], atol=1e-4)
    panel.sliders["smile"].setValue(100)  # a photographed expression moves the face too
    assert np.abs(w.view3d.vertices()[0] - posed).max() > 1.0
    assert not w.model.modified  # posing is the view's, not the project's

    w.rig_dock.show()
    w.rig_dock.raise_()
    w.view3d.view_from(30.0, 5.0)
    qtbot.wait(50)
    if os.environ.get("FACESTUDIO_SCREENSHOTS"):  # docs/img/rig_sliders.png on request (not in a plain run)
        REPO_IMG.mkdir(parents=True, exist_ok=True)
        w.grab().save(str(REPO_IMG / "rig_sliders.png"))

    qtbot.mouseClick(panel.reset_button, Qt.MouseButton.LeftButton)
    back, caption = w.view3d.vertices()
    np.testing.assert_array_equal(back, neutral)
    assert "rig" not in caption and all(s.value() == 0 for s in panel.sliders.values())


def test_build_rig_action_stores_and_shows_it(studio_window, rigged, tmp_path, qtbot):
    w = studio_window
    dst = tmp_path / "james"
    shutil.copytree(rigged.parent, dst)
    path = dst / rigged.name
    project = load_project(path)
    project.rig = None
    save_project(project, path)
    w.open_project(path)
    assert not w.rig_panel.sliders
    assert w.run_build_rig()
    qtbot.waitUntil(lambda: not w.rig_jobs.busy, timeout=60000)
    assert len(w.rig_panel.sliders) == 51 + 4 and w.model.modified
    w.save()
    assert load_project(path).rig.neutral == "neutral"
