"""Tests of photomodel.project.io: load → save → load round trips, unreadable files, and atomic saving
with a backup (a failed save leaves the original intact)."""

from __future__ import annotations

import os
import stat
from pathlib import Path

import numpy as np
import pytest
from project_samples import load_text, sample_camera, sample_project, save_sample, temp_files

from photomodel.errors import ProjectError
from photomodel.project import load_project, new_project, save_project


@pytest.fixture
def saved(tmp_path):
    """(path, dict) of a valid saved project with its photos on disk."""
    return save_sample(tmp_path)


def test_round_trip_load_save_load_equal(tmp_path, saved):
    path, _ = saved
    original = sample_project()
    a = load_project(path)
    assert a == original  # all values are exactly representable at the file's precision
    assert a.path == path.absolute()
    # arrays come back as arrays of the documented shapes and dtypes
    ph = a.expression("neutral").photo("front")
    assert ph.points["nose_tip"].shape == (2,) and ph.points["nose_tip"].dtype == float
    assert ph.curves["brow_r"].shape == (3, 2)
    assert a.curves[0].vertices.dtype == np.int64
    assert ph.hidden == {"jaw_00"}
    cam = a.expression("neutral").result.cameras["left"]
    np.testing.assert_array_equal(cam.R, sample_camera(90.0).R)  # rotation stored at full precision

    b_path = save_project(a, tmp_path / "again.facestudio.json")
    b = load_project(b_path)
    assert b == a
    # deterministic: same project → byte-identical file
    assert b_path.read_bytes() == path.read_bytes()


def test_new_project_save_load(tmp_path):
    p = new_project("anna")
    assert p.expressions == [] and p.generic_mesh == "builtin:template-v1"
    with pytest.raises(ProjectError, match="not been saved yet"):
        save_project(p)
    path = save_project(p, tmp_path)  # a folder → <name>.facestudio.json inside it
    assert path == tmp_path / "anna.facestudio.json"
    assert load_project(path) == p
    with pytest.raises(ProjectError, match="non-empty name"):
        new_project("  ")


def test_other_unreadable_files(tmp_path):
    with pytest.raises(ProjectError, match="no such project file"):
        load_project(tmp_path / "nobody.facestudio.json")
    (tmp_path / "a.facestudio.json").write_bytes(b"\xff\xfe{}")
    with pytest.raises(ProjectError, match="not a text"):
        load_project(tmp_path / "a.facestudio.json")
    with pytest.raises(ProjectError, match="not a Face Studio project file"):
        load_text(tmp_path, "[1, 2]")


# ---------------------------------------------------------------------------------------
# saving: validated first, atomic, keeps a backup
# ---------------------------------------------------------------------------------------
def test_save_keeps_previous_version_as_bak(tmp_path, saved):
    path, _ = saved
    first = path.read_bytes()
    p = load_project(path)
    p.expressions[0].photos[0].points["nose_tip"] = np.array([1.0, 2.0])
    save_project(p)
    assert Path(str(path) + ".bak").read_bytes() == first
    assert load_project(path).expressions[0].photos[0].points["nose_tip"].tolist() == [1.0, 2.0]
    assert temp_files(tmp_path) == []


@pytest.mark.parametrize("target", ["os.replace", "final os.replace", "os.fsync", "write"])
def test_failed_save_leaves_original_intact(tmp_path, saved, monkeypatch, target):
    path, _ = saved
    before = path.read_bytes()
    p = load_project(path)
    p.name = "changed"

    def boom(*args, **kwargs):
        raise OSError(28, "No space left on device")

    real_replace = os.replace

    def fail_final_replace(src, dst):
        if Path(dst) == path:  # the backup copy succeeds, the move over the project fails
            boom()
        real_replace(src, dst)

    if target == "final os.replace":
        monkeypatch.setattr(os, "replace", fail_final_replace)
    elif target == "write":
        # the disk fills half-way through writing: the first half is on disk already
        real_fdopen = os.fdopen

        class HalfWriter:
            def __init__(self, *args, **kwargs):
                self.fh = real_fdopen(*args, **kwargs)

            def __enter__(self):
                return self

            def __exit__(self, *exc):
                self.fh.close()

            def write(self, text):
                self.fh.write(text[: len(text) // 2])
                self.fh.flush()
                boom()

        monkeypatch.setattr(os, "fdopen", HalfWriter)
    else:
        monkeypatch.setattr(os, target.split(".")[1], boom)
    with pytest.raises(ProjectError) as ei:
        save_project(p)
    assert "could not save the project: No space left on device" in str(ei.value)
    monkeypatch.undo()
    assert path.read_bytes() == before
    assert load_project(path).name == "james"
    assert temp_files(tmp_path) == []


def test_save_keeps_the_file_permissions_and_so_does_the_backup(tmp_path, saved):
    """A private project stays private: the new file and its .bak keep its mode; a new file is 0644."""
    path, _ = saved
    assert stat.S_IMODE(path.stat().st_mode) == 0o644
    path.chmod(0o600)
    save_project(load_project(path))
    assert stat.S_IMODE(path.stat().st_mode) == 0o600
    assert stat.S_IMODE(Path(str(path) + ".bak").stat().st_mode) == 0o600
    assert temp_files(tmp_path) == []


def _orphan(folder: Path, name: str, age_s: float) -> Path:
    folder.mkdir(parents=True, exist_ok=True)
    f = folder / name
    f.write_text("half a file")
    t = f.stat().st_mtime - age_s
    os.utime(f, (t, t))
    return f


@pytest.mark.parametrize("when", ["load", "save"])
def test_temporaries_of_a_killed_save_are_removed_on_the_next_load_or_save(tmp_path, saved, when):
    path, _ = saved
    results = path.parent / "results"
    old = [
        _orphan(path.parent, f".{path.name}.ab12cd_9.tmp", 3600),  # a killed project save
        _orphan(results, ".neutral.obj.x1y2z3w4.tmp", 3600),
    ]  # a killed mesh write
    kept = [
        _orphan(path.parent, f".{path.name}.qwertyui.tmp", 5),  # a save in progress elsewhere
        _orphan(path.parent, "notes.tmp", 3600),
        _orphan(path.parent, ".hidden.tmp", 3600),
        _orphan(results, ".neutral.obj.TOOLONGNAME.tmp", 3600),
    ]  # not our pattern
    project = load_project(path)
    if when == "save":
        for f in old:  # made again after the load: only the save removes them now
            _orphan(f.parent, f.name, 3600)
        save_project(project)
    assert not any(f.exists() for f in old)
    assert all(f.exists() for f in kept)
