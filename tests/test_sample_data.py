"""Tests of photomodel.samples.sample_data: the james scan's units, frame and james → iBUG-68 landmark
order (checked against the template's geometry, not against itself), and its folder."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from scipy.optimize import linear_sum_assignment

from photomodel.data.menpo3d import menpo3d_dir
from photomodel.samples import sample_data
from photomodel.samples.sample_data import JAMES_TO_IBUG68, rigid_transform, sample_data_dir

# iBUG-68 indices on the subject's right side and their mirror images on the left
RIGHT = np.r_[0:8, 17:22, 36:42, 31, 48, 49, 59, 60, 67]
LEFT = np.r_[16:8:-1, 26:21:-1, 45, 44, 43, 42, 47, 46, 35, 54, 53, 55, 64, 65]


# ----------------------------------------------------------------------------- james


def test_permutation_is_a_permutation():
    assert sorted(JAMES_TO_IBUG68.tolist()) == list(range(68))


def test_james_landmarks_match_the_template_after_alignment(scan, template):
    d = np.linalg.norm(scan.landmarks - template.landmarks, axis=1)
    # Two different faces: jaw points at the ears and the outer brows differ by up to
    # ~22 mm; the eyes and mouth, better defined, agree within 10 mm.
    assert d.max() < 25.0
    assert d[36:68].max() < 10.0
    # the optimal one-to-one matching of the two point sets pairs each iBUG index with
    # itself: the order is right even where neighbours are close (lips, eyes)
    cost = np.linalg.norm(scan.landmarks[:, None] - template.landmarks[None], axis=2)
    _, match = linear_sum_assignment(cost)
    assert np.array_equal(match, np.arange(68))
    assert np.all(scan.landmarks[RIGHT, 0] < 0) and np.all(scan.landmarks[LEFT, 0] > 0)


def test_alignment_is_rigid_and_least_squares(scan, template):
    R, t = scan.rigid
    np.testing.assert_allclose(R @ R.T, np.eye(3), atol=1e-12)
    assert np.linalg.det(R) == pytest.approx(1.0)
    # the raw OBJ positions, read independently, map onto the scan's vertices
    raw = np.array(
        [
            [float(x) for x in line.split()[1:4]]
            for line in (sample_data_dir() / "james.obj").read_text().splitlines()
            if line.startswith("v ")
        ]
    )
    np.testing.assert_allclose(raw[scan.obj_vertex] @ R.T + t, scan.vertices, atol=1e-9)
    # least squares: no small rotation or shift reduces the landmark residual
    base = np.sum((scan.landmarks - template.landmarks) ** 2)
    for axis in np.eye(3):
        for sign in (-1, 1):
            c, s = np.cos(0.01), np.sin(0.01) * sign
            K = np.cross(np.eye(3), axis)
            Rs = np.eye(3) + s * K + (1 - c) * K @ K
            centre = scan.landmarks.mean(0)
            moved = (scan.landmarks - centre) @ Rs.T + centre
            assert np.sum((moved - template.landmarks) ** 2) > base
            assert np.sum((scan.landmarks + 0.1 * sign * axis - template.landmarks) ** 2) > base


def test_rigid_transform_recovers_a_known_motion():
    rng = np.random.default_rng(0)
    P = rng.normal(size=(20, 3))
    angle = 0.7
    R = np.array([[np.cos(angle), 0, np.sin(angle)], [0, 1, 0], [-np.sin(angle), 0, np.cos(angle)]])
    t = np.array([3.0, -2.0, 5.0])
    R_est, t_est = rigid_transform(P, P @ R.T + t)
    np.testing.assert_allclose(R_est, R, atol=1e-12)
    np.testing.assert_allclose(t_est, t, atol=1e-12)
    with pytest.raises(ValueError):
        rigid_transform(P[:2], P[:2])


def test_scan_mesh_arrays(scan):
    n = len(scan.vertices)
    assert scan.faces.shape == (12228, 3) and scan.faces.min() == 0 and scan.faces.max() == n - 1
    assert scan.uv.shape == (n, 2) and scan.uv.min() >= 0 and scan.uv.max() <= 1
    assert scan.texture.dtype == np.uint8 and scan.texture.shape == (1600, 2400, 3)
    assert scan.obj_vertex.shape == (n,) and len(np.unique(scan.obj_vertex)) == 6393
    # unwelding only splits texture seams: each (position, uv) pair is one vertex
    pairs = np.c_[scan.obj_vertex, scan.uv]
    assert len(np.unique(pairs, axis=0)) == n
    welded = scan.welded
    assert welded.vertices.shape == (6393, 3) and len(welded.faces) == 12228
    np.testing.assert_allclose(welded.vertices[scan.obj_vertex], scan.vertices)


def test_uv_v_is_measured_up_and_texture_is_rgb(scan):
    H, W = scan.texture.shape[:2]
    col = np.clip(np.round(scan.uv[:, 0] * W - 0.5), 0, W - 1).astype(int)
    row = np.clip(np.round((1 - scan.uv[:, 1]) * H - 0.5), 0, H - 1).astype(int)
    rgb = scan.texture[row, col].astype(float)
    y = scan.vertices[:, 1]
    hair = rgb[y > scan.landmarks[19, 1] + 60].mean(0)  # top of the head: dark hair
    L = scan.landmarks
    x, z = np.abs(scan.vertices[:, 0]), scan.vertices[:, 2]
    cheeks = (x > 25) & (x < 45) & (y > L[48, 1]) & (y < L[31, 1]) & (z > L[48, 2] - 25)
    assert cheeks.sum() > 20
    skin = rgb[cheeks].mean(0)
    assert skin.sum() > hair.sum() + 150  # with v measured down, the two swap places
    assert skin[0] > skin[2] + 20  # skin is red-ish: the channels are RGB, not BGR


def test_cli_prints_the_folder(capsys):
    """``python -m photomodel.samples.sample_data`` fetches the archive the scan comes in."""
    assert sample_data.main([]) == 0
    assert Path(capsys.readouterr().out.strip()) == sample_data_dir() == menpo3d_dir()


def test_the_cached_scan_is_the_parsed_file(scan):
    """load_james_scan serves ``james_scan-<key>.npz``; it holds what parsing the files gives now."""
    fresh = sample_data.james_arrays(sample_data_dir())
    np.testing.assert_array_equal(fresh["faces"], scan.faces)
    np.testing.assert_array_equal(fresh["uv"], scan.uv)
    np.testing.assert_array_equal(fresh["obj_vertex"], scan.obj_vertex)
    R, t = scan.rigid
    np.testing.assert_allclose(fresh["obj_positions"][fresh["obj_vertex"]] @ R.T + t, scan.vertices, atol=1e-12)
    np.testing.assert_allclose(fresh["obj_landmarks"] @ R.T + t, scan.landmarks, atol=1e-12)
