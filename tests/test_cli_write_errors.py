"""Every command in an output folder the disk refuses (issue 35, item 1): exit status 2, a message
naming the folder, no traceback, nothing written there — checked before the long work.

CI runs as root, which ignores permission bits, and the failures of interest are not permission
errors anyway: as root the folder is made a read-only bind mount (``mount --bind D D; mount -o
remount,bind,ro D``; skipped where that is refused), and everywhere the writers are made to
fail with ``OSError(errno.EROFS)`` / ``OSError(errno.ENOSPC)`` for paths in that folder
(:func:`refused_writes.refuse_writes`: ``os.open``, ``os.mkdir``, ``open``, ``os.replace``)."""

from __future__ import annotations

import errno
import json
import os
import shutil
from pathlib import Path

import cv2
import numpy as np
import pytest
from refused_writes import bind_read_only, refuse_writes, unmount

import app.cli.common as common
import app.cli.export
from app.cli import main
from photomodel.exchange import files
from photomodel.exchange.files import atomic_write_bytes
from photomodel.project import io as project_io
from tracking.performance import BlendShapes, arkit_weights

SAMPLE = Path(__file__).resolve().parents[1] / "sample_projects" / "james"
VIDEO = SAMPLE / "video" / "james_track.mp4"


@pytest.fixture(params=["mount", "EROFS", "ENOSPC"])
def refused(request, monkeypatch):
    """``refuse(folder)``: make ``folder`` refuse writes the way the parameter says."""
    mounted = []

    def refuse(folder: Path) -> None:
        folder.mkdir(parents=True, exist_ok=True)
        if request.param == "mount":
            if not bind_read_only(folder):
                pytest.skip("a read-only bind mount is refused here (not root, or no mount permission)")
            mounted.append(folder)
        else:
            refuse_writes(monkeypatch, folder, getattr(errno, request.param))

    yield refuse
    for folder in mounted:
        unmount(folder)


def _listing(folder: Path) -> dict:
    return {str(p.relative_to(folder)): p.stat().st_mtime_ns for p in sorted(folder.rglob("*"))}


@pytest.fixture
def tracked(straight, tmp_path):
    out = tmp_path / "track"
    shutil.copytree(straight.out_dir, out)
    return out


#: command → (argv with {p} the project, {ro} the refused folder, {t} a track folder, {w} a writable folder;
#: which folder is refused: the project's ("project") or a fresh one ("ro")).
CASES = {
    "new": (["new", "{ro}/x.facestudio.json", "--photos", "{photos}"], "ro"),
    "add-photos": (["add-photos", "{p}", "--photos", "{photos}/neutral_front.png"], "project"),
    "fit": (["fit", "{p}", "--expression", "neutral", "--no-refine"], "project"),
    "texture": (["texture", "{p}", "--expression", "neutral", "--size", "64"], "project"),
    "rig": (["rig", "{p}"], "project"),
    "track": (["track", "{p}", "--video", str(VIDEO), "--out", "{ro}/t", "--frames", "1", "--no-overlay"], "ro"),
    "track-many": (["track-many", "{p}", str(VIDEO), "--out", "{ro}", "--frames", "1", "--no-overlay"], "ro"),
    "edit": (["edit", "{p}", "--track", "{t}", "--scale", "smile=0.5", "--no-smooth", "--out", "{ro}/e.mp4"], "ro"),
    "export": (["export", "{p}", "--glb", "{ro}/x.glb"], "ro"),
    "export-csv": (["export", "{p}", "--track", "{t}", "--glb", "{w}/x.glb", "--csv", "{ro}/x.csv"], "ro"),
}


@pytest.mark.parametrize("as_json", [False, True], ids=["text", "json"])
@pytest.mark.parametrize("command", list(CASES))
def test_a_refused_output_folder_is_named_before_any_work(
    command, as_json, refused, fitted_project_copy, tracked, tmp_path, capsys
):
    argv, which = CASES[command]
    folder = fitted_project_copy.parent if which == "project" else tmp_path / "refused"
    writable = tmp_path / "writable"
    writable.mkdir()
    refused(folder)
    before = _listing(folder)
    names = dict(p=fitted_project_copy, ro=folder, t=tracked, w=writable, photos=SAMPLE / "photos")
    code = main([a.format(**names) for a in argv] + (["--json"] if as_json else []))
    out, err = capsys.readouterr()
    assert code == 2 and "Traceback" not in err, err
    assert "could not write" in err and str(folder) in err, err
    assert _listing(folder) == before and not any(writable.iterdir())  # nothing written, the glb neither
    if as_json:
        assert str(folder) in json.loads(out)["error"]["message"]


def test_a_full_disk_is_named_before_any_work(fitted_project_copy, monkeypatch, capsys):
    real = shutil.disk_usage
    monkeypatch.setattr(common.shutil, "disk_usage", lambda p: real(p)._replace(free=0))
    assert main(["fit", str(fitted_project_copy), "--no-refine"]) == 2
    err = capsys.readouterr().err
    assert "disk is full" in err and str(fitted_project_copy.parent) in err


def test_a_write_failing_later_names_the_file_and_leaves_no_glb(
    fitted_project_copy, tracked, tmp_path, monkeypatch, capsys
):
    """The CSV's write fails after the checks passed (the disk filled meanwhile): the glb asked
    for with it is not left behind, and the message names the CSV."""
    glb, csv = tmp_path / "x.glb", tmp_path / "x.csv"
    real = files.atomic_write_bytes

    def full(path, data, **kw):
        if Path(path).suffix == ".csv":
            raise files._named(OSError(errno.ENOSPC, "No space left on device"), Path(path))
        return real(path, data, **kw)

    monkeypatch.setattr(files, "atomic_write_bytes", full)
    monkeypatch.setattr(app.cli.export, "_livelink_csv", lambda *a: b"csv")  # no rig needed: the writes matter
    monkeypatch.setattr(app.cli.export, "check_csv_rig", lambda shapes: None)
    args = ["export", str(fitted_project_copy), "--track", str(tracked), "--glb", str(glb), "--csv", str(csv)]
    assert main(args) == 2
    err = capsys.readouterr().err
    assert "Traceback" not in err and "disk is full" in err and str(tmp_path) in err, err
    assert not glb.exists() and not csv.exists()


def test_the_atomic_writer_names_the_file_a_full_disk_refuses(tmp_path, monkeypatch):
    real_fsync = os.fsync

    def full(fd):
        raise OSError(errno.ENOSPC, "No space left on device")

    monkeypatch.setattr(os, "fsync", full)
    with pytest.raises(OSError) as err:
        atomic_write_bytes(tmp_path / "a.bin", b"x")
    monkeypatch.setattr(os, "fsync", real_fsync)
    assert err.value.errno == errno.ENOSPC and err.value.filename == str(tmp_path / "a.bin")
    assert list(tmp_path.iterdir()) == []  # no temporary file left


def test_edit_frames_failing_half_way_leave_no_frames(tracked, fitted_sample, tmp_path, monkeypatch, capsys):
    real, calls = cv2.imwrite, []

    def imwrite(path, img, *a):
        calls.append(path)
        return False if len(calls) == 3 else real(path, img, *a)

    monkeypatch.setattr(cv2, "imwrite", imwrite)
    out = tmp_path / "frames"
    args = ["edit", str(fitted_sample), "--track", str(tracked), "--scale", "smile=0.5", "--no-smooth"]
    assert main([*args, "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert "frame_00002.png" in err and "Traceback" not in err
    assert not out.exists()  # the two frames written before are gone with their folder


def test_live_link_weights_of_a_neutral_only_model_are_zero():
    """A track of the neutral alone (head pose only) exported as Live Link CSV: every weight 0
    (it was a ValueError reshaping no photographed target)."""
    n, r = 5, 3
    shapes = BlendShapes(np.zeros((n, 3)), np.zeros((1, 3), int), np.ones((r, n, 3)), ["a", "b", "c"], None, None, r, 0)
    assert np.array_equal(arkit_weights(shapes, np.zeros((4, r)), None), np.zeros((4, r)))


def test_texture_files_written_before_a_refused_one_are_removed(fitted_project_copy, monkeypatch, capsys):
    """The disk fills while the texture's files are written: the new ones written before are
    removed, the project file is untouched, and the message names the file's folder."""
    results = fitted_project_copy.parent / "results"
    for f in results.glob("neutral*"):  # as if never textured: every texture file would be new
        if f.name not in ("neutral.obj", "neutral.ply"):  # the fitted mesh stays
            f.unlink()
    before, project = _listing(results), fitted_project_copy.read_bytes()
    real = files.atomic_write_bytes

    def full(path, data, **kw):
        if Path(path).suffix == ".ply":
            raise files._named(OSError(errno.ENOSPC, "No space left on device"), Path(path))
        return real(path, data, **kw)

    monkeypatch.setattr(files, "atomic_write_bytes", full)
    assert main(["texture", str(fitted_project_copy), "--expression", "neutral", "--size", "64"]) == 2
    err = capsys.readouterr().err
    assert "Traceback" not in err and "No space left on device" in err and str(results) in err, err
    assert _listing(results) == before and fitted_project_copy.read_bytes() == project


def test_fit_meshes_written_before_a_refused_project_file_are_removed(project_copy, monkeypatch, capsys):
    """The project file's write fails after the meshes were written: no new mesh is left in results/."""
    results = project_copy.parent / "results"
    real = files.atomic_write_bytes

    def full(path, data, **kw):
        if Path(path).name.endswith(".facestudio.json"):
            raise files._named(OSError(errno.ENOSPC, "No space left on device"), Path(path))
        return real(path, data, **kw)

    monkeypatch.setattr(project_io, "atomic_write_bytes", full)  # the project file's writer
    before = project_copy.read_bytes()
    assert main(["fit", str(project_copy), "--expression", "neutral", "--no-refine"]) == 2
    err = capsys.readouterr().err
    assert "Traceback" not in err and str(project_copy.parent) in err, err
    assert not results.exists() or not any(results.iterdir())
    assert project_copy.read_bytes() == before
