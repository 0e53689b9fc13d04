"""Fitting a scan (photomodel.prior.scan_fit) and ``facestudio fit-scan``: units, pose, no face."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh
from scipy.spatial.transform import Rotation

from app.cli import main as facestudio
from photomodel.prior import scan_fit


def test_unit_guessed_from_the_head_size():
    head = np.random.default_rng(0).uniform(-1.0, 1.0, (500, 3)) * [80.0, 110.0, 90.0]  # mm
    for name, per in scan_fit.UNITS.items():
        assert scan_fit.guess_unit(head / per) == (name, per)


def test_a_moved_scan_is_brought_back(mesh):
    """The generic head in metres, turned 150° and 40 cm away: its face is found and the similarity
    undone (template and scan share the surface, so to a fraction of a millimetre)."""
    R = Rotation.from_euler("yxz", [150.0, 15.0, -10.0], degrees=True).as_matrix()
    t = np.array([400.0, -250.0, 900.0])
    scan_m = (mesh.vertices @ R.T + t) / 1000.0
    unit, per = scan_fit.guess_unit(scan_m)
    assert unit == "m"
    (s, R_fit, t_fit), inliers = scan_fit.align_template(mesh.vertices, mesh.face_mask, scan_m * per)
    moved = mesh.vertices @ (s * R_fit).T + t_fit
    assert inliers > 0.95
    assert s == pytest.approx(1.0, abs=0.01)
    assert np.abs(moved - (mesh.vertices @ R.T + t)).max() < 1.0  # mm


def test_fit_scan_without_a_face_exits_2(project_copy, tmp_path, capsys):
    ball = tmp_path / "ball.stl"
    trimesh.creation.icosphere(subdivisions=4, radius=0.1).export(ball)
    project = str(project_copy)
    before = open(project, encoding="utf-8").read()
    assert facestudio(["fit-scan", project, str(ball)]) == 2
    assert "no face found on the scan" in capsys.readouterr().err
    assert open(project, encoding="utf-8").read() == before  # nothing written


def test_unit_from_landmarks_snaps_to_a_unit():
    # a head 6 % smaller than the generic one, in metres: the landmarks' scale says 946 mm per unit
    assert scan_fit._snapped_unit(946.0) == 1000.0
    assert scan_fit._snapped_unit(10.9) == 10.0
    assert scan_fit._snapped_unit(3.0) == 3.0  # no unit near: the measured scale is kept
