"""Tests of photomodel.samples.sample_data: checksums, the offline failure paths, units, frames and the
james → iBUG-68 landmark order (checked against the template's geometry, not against itself)."""

from __future__ import annotations

import hashlib
import io
import subprocess
import tarfile
from pathlib import Path

import numpy as np
import pytest
from scipy.optimize import linear_sum_assignment

from photomodel.errors import SampleDataError
from photomodel.samples import fetch, sample_data
from photomodel.samples.sample_data import (
    FILE_SHA256,
    JAMES_TO_IBUG68,
    rigid_transform,
    sample_data_dir,
)

# iBUG-68 indices on the subject's right side and their mirror images on the left
RIGHT = np.r_[0:8, 17:22, 36:42, 31, 48, 49, 59, 60, 67]
LEFT = np.r_[16:8:-1, 26:21:-1, 45, 44, 43, 42, 47, 46, 35, 54, 53, 55, 64, 65]


# ----------------------------------------------------------------------------- fetching


def test_cached_files_match_their_checksums():
    folder = sample_data_dir()
    for name, digest in FILE_SHA256.items():
        assert hashlib.sha256((folder / name).read_bytes()).hexdigest() == digest


def test_cache_folder_follows_environment(monkeypatch, tmp_path):
    monkeypatch.delenv("FACESTUDIO_CACHE", raising=False)
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "xdg"))
    assert fetch.cache_dir() == tmp_path / "xdg" / "facestudio"
    monkeypatch.setenv("FACESTUDIO_CACHE", str(tmp_path / "mine"))
    assert fetch.cache_dir() == tmp_path / "mine"


@pytest.fixture
def no_network(monkeypatch):
    """Fail the test if anything tries to run pip."""

    def refuse(*args, **kwargs):
        raise AssertionError(f"unexpected subprocess call {args}")

    monkeypatch.setattr(subprocess, "run", refuse)


def test_corrupt_cache_and_corrupt_sdist_raise(monkeypatch, tmp_path, no_network):
    data = tmp_path / "menpo3d-0.8.6"
    data.mkdir()
    for name in FILE_SHA256:
        (data / name).write_bytes(b"corrupt")
    bad_sdist = tmp_path / "menpo3d-0.8.6.tar.gz"
    bad_sdist.write_bytes(b"not the archive")
    monkeypatch.setenv("FACESTUDIO_CACHE", str(tmp_path))
    monkeypatch.setenv("FACESTUDIO_MENPO3D_SDIST", str(bad_sdist))
    with pytest.raises(SampleDataError, match="SHA-256") as err:
        sample_data_dir()
    assert "FACESTUDIO_MENPO3D_SDIST" in str(err.value)  # the message says what to do
    assert (data / "james.obj").read_bytes() == b"corrupt"  # nothing half-installed


def test_missing_local_sdist_raises(monkeypatch, tmp_path, no_network):
    monkeypatch.setenv("FACESTUDIO_CACHE", str(tmp_path))
    monkeypatch.setenv("FACESTUDIO_MENPO3D_SDIST", str(tmp_path / "nowhere.tar.gz"))
    with pytest.raises(SampleDataError, match="not a file"):
        sample_data_dir()


def test_pip_failure_raises_with_instructions(monkeypatch, tmp_path):
    calls = []

    def failing_pip(cmd, **kwargs):
        calls.append(cmd)
        return subprocess.CompletedProcess(cmd, 1, stdout="", stderr="ERROR: no network")

    monkeypatch.setattr(subprocess, "run", failing_pip)
    monkeypatch.setenv("FACESTUDIO_CACHE", str(tmp_path))
    monkeypatch.delenv("FACESTUDIO_MENPO3D_SDIST", raising=False)
    with pytest.raises(SampleDataError, match="setuptools wheel") as err:
        sample_data_dir()
    assert "no network" in str(err.value)
    assert calls and calls[0][1:4] == ["-m", "pip", "download"] and "menpo3d==0.8.6" in calls[0]


def _fake_sdist(path: Path, contents: dict[str, bytes]) -> None:
    with tarfile.open(path, "w:gz") as tar:
        for name, data in contents.items():
            info = tarfile.TarInfo("menpo3d-0.8.6/menpo3d/data/" + name)
            info.size = len(data)
            tar.addfile(info, io.BytesIO(data))


def test_install_from_local_sdist_replaces_corrupt_cache(monkeypatch, tmp_path, no_network):
    # a stand-in archive whose checksums we declare, to run the whole install offline
    contents = {name: f"payload of {name}".encode() for name in FILE_SHA256}
    sdist = tmp_path / "fake.tar.gz"
    _fake_sdist(sdist, {**contents, "bunny.obj": b"not extracted"})
    monkeypatch.setattr(sample_data, "SDIST_SHA256", hashlib.sha256(sdist.read_bytes()).hexdigest())
    monkeypatch.setattr(sample_data, "FILE_SHA256", {n: hashlib.sha256(d).hexdigest() for n, d in contents.items()})
    cache = tmp_path / "cache"
    (cache / "menpo3d-0.8.6").mkdir(parents=True)
    (cache / "menpo3d-0.8.6" / "james.obj").write_bytes(b"corrupt")
    monkeypatch.setenv("FACESTUDIO_CACHE", str(cache))
    monkeypatch.setenv("FACESTUDIO_MENPO3D_SDIST", str(sdist))

    folder = sample_data_dir()

    assert folder == cache / "menpo3d-0.8.6"
    assert sorted(p.name for p in folder.iterdir()) == sorted(contents)  # only the six files
    for name, data in contents.items():
        assert (folder / name).read_bytes() == data
    assert [p.name for p in cache.iterdir()] == ["menpo3d-0.8.6"]  # no temporary left over


def test_archive_member_with_wrong_checksum_raises(monkeypatch, tmp_path, no_network):
    contents = {name: b"x" for name in FILE_SHA256}
    sdist = tmp_path / "fake.tar.gz"
    _fake_sdist(sdist, contents)
    monkeypatch.setattr(sample_data, "SDIST_SHA256", hashlib.sha256(sdist.read_bytes()).hexdigest())
    monkeypatch.setenv("FACESTUDIO_CACHE", str(tmp_path / "cache"))
    monkeypatch.setenv("FACESTUDIO_MENPO3D_SDIST", str(sdist))
    with pytest.raises(SampleDataError, match="fails its SHA-256 check"):
        sample_data_dir()
    assert not (tmp_path / "cache" / "menpo3d-0.8.6").exists()


def test_cli_prints_the_folder(capsys):
    assert sample_data.main([]) == 0
    assert Path(capsys.readouterr().out.strip()) == sample_data_dir()


# ----------------------------------------------------------------------------- template


def test_template_is_in_millimetres_in_the_head_frame(template):
    assert template.vertices.shape == (53349, 3) and template.faces.shape[1] == 3
    width = np.ptp(template.vertices[:, 0])
    assert 150 < width < 250  # a head is ~15–20 cm wide: micrometres were converted
    # landmarks lie on the surface: the mesh is ~1.2 mm between vertices
    d = np.linalg.norm(template.vertices[None] - template.landmarks[:, None], axis=2).min(axis=1)
    assert d.max() < 1.5
    L = template.landmarks
    assert L[30, 2] > L[[36, 45, 48, 54], 2].max()  # the nose points along +z
    assert L[19, 1] > L[37, 1] > L[30, 1] > L[51, 1] > L[8, 1]  # +y is up: brow, eye, nose, lip, chin


def test_template_landmarks_are_in_ibug_order(template):
    L = template.landmarks
    assert np.all(L[RIGHT, 0] < 0) and np.all(L[LEFT, 0] > 0)  # subject's right is -x
    assert np.all(np.diff(L[0:17, 0]) > 0)  # jaw runs from the right ear to the left
    assert L[36, 0] < L[39, 0] and L[42, 0] < L[45, 0]  # eye corners
    assert L[37:39, 1].min() > L[[40, 41], 1].max()  # 37, 38 on the upper lid
    assert L[49:54, 1].min() > L[55:60, 1].max()  # outer lip: the top first


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
