"""The studio's *Fit → Add scan…*: a noisy, holed scan of the head becomes the neutral's fit, undoably."""

import shutil

import numpy as np
import pytest
import trimesh

pytest.importorskip("PySide6")

from PySide6.QtWidgets import QFileDialog  # noqa: E402
from scan_data import chin_hole, scanned  # noqa: E402
from scipy.spatial.transform import Rotation  # noqa: E402
from studio_window import close_studio, open_studio  # noqa: E402

from photomodel.alignment import similarity_transform  # noqa: E402
from photomodel.samples import synthetic  # noqa: E402

#: Where the scan file lies: in metres, turned and 2 m from the origin (as a scanner's own frame might).
TURN = Rotation.from_euler("yxz", [35.0, -10.0, 5.0], degrees=True).as_matrix()
OFFSET_M = np.array([1.2, -0.4, 2.0])


@pytest.fixture
def studio(qtbot, tmp_path, fitted_sample, messages):
    dst = tmp_path / "james"
    shutil.copytree(fitted_sample.parent, dst)
    w = open_studio(qtbot, tmp_path, dst / fitted_sample.name)
    w.messages = messages
    yield w
    close_studio(w)


@pytest.fixture(scope="module")
def scan_file(tmp_path_factory, scan):
    """The james scan as a PLY point cloud in metres, far from the origin: noise, 5 % strays, no chin."""
    centre, radius = chin_hole(scan)
    pts = scanned(scan, centre, radius)
    path = tmp_path_factory.mktemp("scan") / "james_scan.ply"
    trimesh.PointCloud(pts @ TURN.T / 1000.0 + OFFSET_M).export(path)
    return path


def _choose(monkeypatch, path):
    monkeypatch.setattr(QFileDialog, "getOpenFileName", staticmethod(lambda *a, **k: (str(path), "")))


def _clicks(model):
    return [(p.id, dict(p.points), dict(p.curves)) for e in model.project.expressions for p in e.photos]


def test_add_scan_fits_the_neutral_undoably(studio, scan_file, scan, sample_truth, monkeypatch, qtbot):
    w, model = studio, studio.model
    before = model.fit("neutral")
    clicks = _clicks(model)
    _choose(monkeypatch, scan_file)
    w.act_add_scan.trigger()
    assert w.fit_menu.scan.progress_dialog is not None  # the fit runs in the worker, cancellable
    qtbot.waitUntil(lambda: not w.scan_jobs.busy, timeout=180_000)
    assert w.messages == [] and w.fit_menu.scan.progress_dialog is None
    fit = model.fit("neutral")
    assert fit is not before and fit.from_scan
    assert "unit taken as m" in w.fit_menu.scan.last_message  # metres, said so
    assert "scan" in w.fit_label.text()
    np.testing.assert_array_equal(w.view3d.vertices()[0], fit.vertices)  # shown in the 3D view
    assert fit.cameras.keys() == before.cameras.keys()  # the photo fit's cameras kept (texturing)

    # against the true surface: into the scan's own frame by the similarity that maps the photo
    # fit's triangulated feature points onto their true positions (the sample's ground truth; the
    # scan fit was laid onto the photo fit's surface, so the same similarity applies)
    names = sorted(before.points_3d)
    s, R, t = similarity_transform(np.array([before.points_3d[n] for n in names]), sample_truth.true_points(names))
    face = model.mesh.face_mask
    V = (fit.vertices @ (s * R).T + t)[face]
    d = synthetic.surface_distance(V, scan)
    d_photos = synthetic.surface_distance((before.vertices @ (s * R).T + t)[face], scan)
    centre, radius = chin_hole(scan)
    hole = np.linalg.norm(V - centre, axis=1) < radius
    assert hole.sum() > 200  # the hole covers part of the face (~340 of its 4200 vertices)
    # measured 0.48 mm outside the hole and 1.9 in it (the shape alone, laid on the clean scan:
    # 0.38 / 1.95). Outside: bench_prior's bar is 0.5 mm in the scan's frame; this frame comes from
    # the clicks (the photo fit scores 0.73 mm the same way), hence 0.7, and better than the photo
    # fit there. In the hole: the bar is 2 mm with the scan's landmarks given; here they come from
    # the photo fit laid on the scan (the chin's own clicks fall in the hole), hence 2.5.
    assert d[~hole].mean() < 0.7 and d[~hole].mean() < d_photos[~hole].mean(), (d[~hole].mean(), d_photos.mean())
    assert d[hole].mean() < 2.5, d[hole].mean()

    # undo: the previous fit back, no click or curve changed; redo: the scan's again
    assert _clicks(model) == clicks
    w.act_undo.trigger()
    assert model.fit("neutral") is before
    w.act_redo.trigger()
    np.testing.assert_array_equal(model.fit("neutral").vertices, fit.vertices)
    assert model.modified


def test_a_scan_without_a_face_is_said_and_nothing_changes(studio, tmp_path, monkeypatch, qtbot):
    w, model = studio, studio.model
    ball = tmp_path / "ball.stl"
    trimesh.creation.icosphere(subdivisions=4, radius=0.1).export(ball)
    before, depth = model.fit("neutral"), len(model.undo_stack)
    _choose(monkeypatch, ball)
    w.act_add_scan.trigger()
    qtbot.waitUntil(lambda: not w.scan_jobs.busy, timeout=60_000)
    assert [(kind, title) for kind, title, _ in w.messages] == [("critical", "Cannot fit the scan")]
    assert "no face found on the scan" in w.messages[0][2]
    assert model.fit("neutral") is before and len(model.undo_stack) == depth and not model.modified


def test_add_scan_can_be_cancelled(studio, scan_file, monkeypatch, qtbot):
    w, model = studio, studio.model
    before = model.fit("neutral")
    _choose(monkeypatch, scan_file)
    w.act_add_scan.trigger()
    w.fit_menu.scan.progress_dialog.canceled.emit()  # what the dialog's Cancel button sends
    qtbot.waitUntil(lambda: not w.scan_jobs.busy, timeout=60_000)
    assert "cancelled" in w.fit_menu.scan.last_message and w.messages == []
    assert model.fit("neutral") is before and not model.modified
