"""Shared test set-up: Qt runs offscreen, rendering is headless EGL."""

import json
import os
import shutil
import sys
from pathlib import Path

import exchange_data
import pytest

from photomodel.data.menpo3d import load_template
from photomodel.modeling.generic_mesh import load_generic_mesh
from photomodel.samples.fitted_sample import fitted_sample_project
from photomodel.samples.sample_data import load_james_scan
from photomodel.samples.synthetic import load_ground_truth
from tracking.run import track_video

os.environ.setdefault("QT_QPA_PLATFORM", "offscreen")

REPO = Path(__file__).resolve().parents[1]

SAMPLE_PROJECT = REPO / "sample_projects" / "james"


@pytest.fixture
def project_copy(tmp_path):
    """A copy of the sample project (without results) that a test may edit or damage."""
    shutil.copytree(SAMPLE_PROJECT, tmp_path / "james", ignore=shutil.ignore_patterns("results"))
    return tmp_path / "james" / "james.facestudio.json"


@pytest.fixture(scope="session")
def fitted_sample():
    """The sample project with every expression fitted and textured (made once, cached under a key of
    the code that makes it: :func:`photomodel.samples.fitted_sample.fitted_sample_project`; a change of
    the fit or texturing code makes it again, and tests/test_fitted_sample.py compares a fresh fit
    with it); read it, do not change it."""

    return fitted_sample_project()


@pytest.fixture
def fitted_project_copy(tmp_path, fitted_sample):
    """A copy of the fitted sample project with the sample video, that a test may edit."""
    dst = tmp_path / "james"
    shutil.copytree(fitted_sample.parent, dst)
    shutil.copytree(SAMPLE_PROJECT / "video", dst / "video")
    return dst / fitted_sample.name


@pytest.fixture(scope="session")
def straight(tmp_path_factory, fitted_sample):
    """One uninterrupted ``facestudio track`` run (:func:`tracking.run.track_video`) of the fitted
    sample over the first 6 frames of the sample video (``FRAMES`` in the tracking tests), with the
    plots and the overlay video: its :class:`tracking.run.TrackResult` (made once; read its folder,
    do not change it — a test that continues or corrects it works on a copy)."""

    out = tmp_path_factory.mktemp("straight")
    return track_video(fitted_sample, SAMPLE_PROJECT / "video" / "james_track.mp4", out, max_frames=6)


# ----------------------------------------------------------------------------- sample data
# Loaded once per run. The loaders build new objects from the on-disk cache on every call, so
# sharing one across modules is safe only while no test changes it: read them, do not change
# them (a test that must change one takes a copy or loads its own).


@pytest.fixture(scope="session")
def template():
    """The menpo3d template (:func:`photomodel.data.menpo3d.load_template`); read it, do not change it."""

    return load_template()


@pytest.fixture(scope="session")
def mesh():
    """The generic face mesh (:func:`photomodel.modeling.generic_mesh.load_generic_mesh`); read it, do not change it."""

    return load_generic_mesh()


@pytest.fixture(scope="session")
def scan():
    """The james scan in the head frame (:func:`photomodel.samples.sample_data.load_james_scan`); read it,
    do not change it."""

    return load_james_scan()


@pytest.fixture(scope="session")
def sample_truth():
    """The sample project's ``ground_truth.json`` as a :class:`photomodel.samples.synthetic.GroundTruth`;
    read it, do not change it."""

    return load_ground_truth(SAMPLE_PROJECT / "ground_truth.json")


@pytest.fixture(scope="session")
def sample_video_truth():
    """The sample video's ``video_truth.json`` (head pose and region weights per frame) as a
    :class:`tracking.synthetic_sequences.ground_truth.VideoTruth`; read it, do not change it."""
    from tracking.synthetic_sequences.ground_truth import VideoTruth

    return VideoTruth.from_dict(json.loads((SAMPLE_PROJECT / "video_truth.json").read_text()))


@pytest.fixture
def errors(monkeypatch):
    """The studio's error dialogs, recorded instead of shown: a list of (title, text)."""
    from PySide6.QtWidgets import QMessageBox

    shown = []
    monkeypatch.setattr(QMessageBox, "critical", lambda parent, title, text, *a, **k: shown.append((title, text)))
    return shown


# ----------------------------------------------------------------------------- studio (Qt)
# Qt is imported inside the fixtures: a GUI test file calls ``pytest.importorskip("PySide6")``
# first, so the rest of the suite runs where PySide6 is missing.


class MessageLog(list):
    """The message boxes shown, as ``(kind, title, text)``; ``answers`` maps a kind to the button
    its box returns (default ``Ok``)."""

    answers: dict


@pytest.fixture
def messages(monkeypatch):
    """Every message box the window shows (a :class:`MessageLog`) instead of showing it;
    questions answer ``messages.answers["question"]``, ``No`` unless a test sets it."""
    from PySide6.QtWidgets import QMessageBox

    shown = MessageLog()
    shown.answers = {"question": QMessageBox.StandardButton.No}

    def fake(kind):
        def box(parent, title, text, *args, **kwargs):
            shown.append((kind, title, text))
            return shown.answers.get(kind, QMessageBox.StandardButton.Ok)

        return box

    for kind in ("critical", "warning", "information", "question"):
        monkeypatch.setattr(QMessageBox, kind, fake(kind))
    return shown


@pytest.fixture
def studio_window(qtbot, tmp_path, messages):
    """A shown studio :class:`app.qt.main_window.MainWindow` with its own settings file and no
    autosave timer, no project open; its message boxes go to ``messages``."""
    from PySide6.QtCore import QSettings

    from app.qt.main_window import MainWindow

    w = MainWindow(
        settings=QSettings(str(tmp_path / "settings.ini"), QSettings.Format.IniFormat), autosave_interval_ms=0
    )
    qtbot.addWidget(w)
    w.resize(1300, 850)
    w.show()
    qtbot.waitExposed(w)
    yield w
    w.fits.shutdown()
    w.model.modified = False  # no unsaved-changes prompt when the test ends


# -- the exchange tests' data (tests/exchange_data.py), one copy per test module ---------------------
@pytest.fixture(scope="module", name="sphere")
def sphere_fixture():
    """The seamed test sphere of :func:`exchange_data.sphere`."""
    return exchange_data.sphere()


@pytest.fixture(scope="module", name="texture")
def texture_fixture():
    """The every-texel-unique texture of :func:`exchange_data.texture`."""
    return exchange_data.texture()


@pytest.fixture
def studio_run_loop(monkeypatch, project_copy):
    """For tests of ``facestudio studio``: run_studio's excepthook and settings kept to the test,
    and its event loop replaced by a local one that calls ``inspect()`` after 200 ms and quits (after
    the application's own loop has been quit, Qt refuses the nested loops pytest-qt's waits use).
    Returns ``use(inspect)``, which installs that loop."""
    from PySide6.QtCore import QEventLoop, QSettings, QTimer
    from PySide6.QtWidgets import QApplication

    monkeypatch.setattr(sys, "excepthook", sys.excepthook)  # run_studio installs the window's
    monkeypatch.setattr(
        "app.qt.main_window.QSettings",
        lambda *a: QSettings(str(project_copy.parent / "s.ini"), QSettings.Format.IniFormat),
    )

    def use(inspect):
        def exec_():
            loop = QEventLoop()
            QTimer.singleShot(200, lambda: (inspect(), loop.quit()))
            loop.exec()
            return 0

        monkeypatch.setattr(QApplication, "exec", staticmethod(exec_))

    return use


@pytest.fixture(scope="module")
def people():
    """A model of 30 ICT people (vertex rank 300) and 4 held-out people (tests/test_personal_rig.py,
    tests/test_rig_clone.py)."""
    from photomodel.people.dataset import EXPRESSIONS, load_people
    from photomodel.people.multilinear import build_model

    data = load_people("model", 30)
    model = build_model(data.tensor(), (300, None, None), EXPRESSIONS, data.names)
    return model, load_people("held_out", 30).subset(range(4))
