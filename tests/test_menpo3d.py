"""Tests of photomodel.data.menpo3d: checksums, the offline failure paths, and the template's units,
frame and landmark order."""

from __future__ import annotations

import hashlib
import io
import shutil
import subprocess
import tarfile
from pathlib import Path

import numpy as np
import pytest

from photomodel.data import menpo3d
from photomodel.data.menpo3d import FILE_SHA256, menpo3d_dir
from photomodel.errors import SampleDataError

# iBUG-68 indices on the subject's right side and their mirror images on the left
RIGHT = np.r_[0:8, 17:22, 36:42, 31, 48, 49, 59, 60, 67]
LEFT = np.r_[16:8:-1, 26:21:-1, 45, 44, 43, 42, 47, 46, 35, 54, 53, 55, 64, 65]


# ----------------------------------------------------------------------------- fetching


def test_cached_files_match_their_checksums():
    folder = menpo3d_dir()
    for name, digest in FILE_SHA256.items():
        assert hashlib.sha256((folder / name).read_bytes()).hexdigest() == digest


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
        menpo3d_dir()
    assert "FACESTUDIO_MENPO3D_SDIST" in str(err.value)  # the message says what to do
    assert (data / "james.obj").read_bytes() == b"corrupt"  # nothing half-installed


def test_missing_local_sdist_raises(monkeypatch, tmp_path, no_network):
    monkeypatch.setenv("FACESTUDIO_CACHE", str(tmp_path))
    monkeypatch.setenv("FACESTUDIO_MENPO3D_SDIST", str(tmp_path / "nowhere.tar.gz"))
    with pytest.raises(SampleDataError, match="not a file"):
        menpo3d_dir()


def test_pip_failure_raises_with_instructions(monkeypatch, tmp_path):
    calls = []

    def failing_pip(cmd, **kwargs):
        calls.append(cmd)
        return subprocess.CompletedProcess(cmd, 1, stdout="", stderr="ERROR: no network")

    monkeypatch.setattr(subprocess, "run", failing_pip)
    monkeypatch.setenv("FACESTUDIO_CACHE", str(tmp_path))
    monkeypatch.delenv("FACESTUDIO_MENPO3D_SDIST", raising=False)
    with pytest.raises(SampleDataError, match="setuptools wheel") as err:
        menpo3d_dir()
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
    monkeypatch.setattr(menpo3d, "SDIST_SHA256", hashlib.sha256(sdist.read_bytes()).hexdigest())
    monkeypatch.setattr(menpo3d, "FILE_SHA256", {n: hashlib.sha256(d).hexdigest() for n, d in contents.items()})
    cache = tmp_path / "cache"
    (cache / "menpo3d-0.8.6").mkdir(parents=True)
    (cache / "menpo3d-0.8.6" / "james.obj").write_bytes(b"corrupt")
    monkeypatch.setenv("FACESTUDIO_CACHE", str(cache))
    monkeypatch.setenv("FACESTUDIO_MENPO3D_SDIST", str(sdist))

    folder = menpo3d_dir()

    assert folder == cache / "menpo3d-0.8.6"
    assert sorted(p.name for p in folder.iterdir()) == sorted(contents)  # only the six files
    for name, data in contents.items():
        assert (folder / name).read_bytes() == data
    assert [p.name for p in cache.iterdir()] == ["menpo3d-0.8.6"]  # no temporary left over


def test_archive_member_with_wrong_checksum_raises(monkeypatch, tmp_path, no_network):
    contents = {name: b"x" for name in FILE_SHA256}
    sdist = tmp_path / "fake.tar.gz"
    _fake_sdist(sdist, contents)
    monkeypatch.setattr(menpo3d, "SDIST_SHA256", hashlib.sha256(sdist.read_bytes()).hexdigest())
    monkeypatch.setenv("FACESTUDIO_CACHE", str(tmp_path / "cache"))
    monkeypatch.setenv("FACESTUDIO_MENPO3D_SDIST", str(sdist))
    with pytest.raises(SampleDataError, match="fails its SHA-256 check"):
        menpo3d_dir()
    assert not (tmp_path / "cache" / "menpo3d-0.8.6").exists()


def test_cli_prints_the_folder(capsys):
    assert menpo3d.main([]) == 0
    assert Path(capsys.readouterr().out.strip()) == menpo3d_dir()


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


def test_the_cached_template_is_the_parsed_file(template, tmp_path, monkeypatch):
    """load_template serves ``template-<key>.npz``; it holds what parsing the files gives now, and
    an empty cache is filled under that key (the file of the earlier scheme removed)."""
    fresh = menpo3d.template_arrays(menpo3d_dir())
    np.testing.assert_array_equal(fresh["vertices"], template.vertices)
    np.testing.assert_array_equal(fresh["faces"], template.faces)
    np.testing.assert_array_equal(fresh["landmarks"], template.landmarks)
    folder = tmp_path / "menpo3d-0.8.6"
    folder.mkdir()
    for name in ("template.ply", "template.ljson"):
        shutil.copy2(menpo3d_dir() / name, folder / name)
    (folder / "template.npz").write_bytes(b"the earlier scheme's file")
    monkeypatch.setattr(menpo3d, "menpo3d_dir", lambda: folder)
    np.testing.assert_array_equal(menpo3d.load_template().vertices, template.vertices)
    made = f"template-{menpo3d.code_key(menpo3d.template_arrays)}.npz"
    assert sorted(p.name for p in folder.iterdir()) == [made, "template.ljson", "template.ply"]
