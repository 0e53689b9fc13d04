"""``fit``, ``texture`` and ``track`` in a project folder the user cannot write to: a clear error
naming the folder (one JSON error object with ``--json``), no traceback, the project untouched.

Two ways a folder refuses writes, each a parameter of the tests:

* ``permissions`` — its permission bits (``chmod 555``). Root ignores them, so as root the folder
  is made immutable (``chattr +i``, which refuses even root with EPERM, a PermissionError too);
  skipped where root cannot ``chattr`` (a filesystem without the attribute);
* ``read-only`` — a read-only disk (EROFS): as root the folder is bind-mounted read-only onto itself
  (``mount --bind D D; mount -o remount,bind,ro D``); where that is refused (not root, or a
  container without the capability) every write under the folder fails with ``OSError(EROFS)``
  injected at the writers (``os.open``, ``open``, ``os.mkdir``). This one always runs.
"""

from __future__ import annotations

import json
import os
import shutil
import subprocess
from contextlib import contextmanager
from pathlib import Path

import pytest
from refused_writes import bind_read_only, refuse_writes, unmount

from app.cli import main


def _lock(folder: Path) -> bool:
    """Make ``folder`` unwritable by its permissions; False if this machine cannot."""
    if os.geteuid() != 0:
        folder.chmod(0o555)
        return True
    return (
        shutil.which("chattr") is not None
        and subprocess.run(["chattr", "+i", str(folder)], capture_output=True).returncode == 0
    )


def _unlock(folder: Path) -> None:
    if os.geteuid() != 0:
        folder.chmod(0o755)
    else:
        subprocess.run(["chattr", "-i", str(folder)], capture_output=True)


def _writable(folder: Path) -> bool:
    probe = folder / "probe"
    try:
        probe.write_text("x")
    except OSError:
        return False
    probe.unlink()
    return True


@contextmanager
def _permissions_refused(folders: list[Path]):
    locked = [f for f in folders if _lock(f)]
    try:
        if len(locked) < len(folders):
            pytest.skip("cannot make a folder unwritable by its permissions here (root without chattr)")
        if _writable(folders[-1]):
            pytest.skip("the folder stays writable (a filesystem without permissions)")
        yield
    finally:
        for f in locked:
            _unlock(f)


@contextmanager
def _read_only(folder: Path, monkeypatch):
    if bind_read_only(folder):
        try:
            assert not _writable(folder)
            yield
        finally:
            unmount(folder, check=True)
    else:
        refuse_writes(monkeypatch, folder)
        assert not _writable(folder)
        yield


@pytest.fixture(params=["permissions", "read-only"])
def locked(request, fitted_project_copy, monkeypatch):
    """The fitted sample project whose folder and results folder cannot be written to."""
    folder = fitted_project_copy.parent
    if request.param == "permissions":
        refused = _permissions_refused([folder / "results", folder])
    else:
        refused = _read_only(folder, monkeypatch)
    with refused:
        yield fitted_project_copy


COMMANDS = {
    "fit": ["fit", "{p}", "--expression", "neutral", "--no-refine"],
    "texture": ["texture", "{p}", "--expression", "neutral", "--size", "64"],
    "track": ["track", "{p}", "--video", "{video}", "--frames", "1", "--no-overlay"],
}


@pytest.mark.parametrize("command", list(COMMANDS))
@pytest.mark.parametrize("as_json", [False, True])
def test_unwritable_project_folder_is_a_clear_error(locked, capsys, command, as_json):
    before = locked.read_bytes()
    video = locked.parent / "video" / "james_track.mp4"
    argv = [a.format(p=locked, video=video) for a in COMMANDS[command]] + (["--json"] if as_json else [])
    assert main(argv) == 2
    out, err = capsys.readouterr()
    assert "Traceback" not in err and "could not write" in err and str(locked.parent) in err, err
    if as_json:  # one JSON object on stdout: the error
        error = json.loads(out)["error"]
        assert (
            error["type"] in ("ProjectError", "PermissionError", "OSError") and str(locked.parent) in error["message"]
        )
    assert locked.read_bytes() == before
