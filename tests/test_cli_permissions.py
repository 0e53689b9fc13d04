"""``fit``, ``texture`` and ``track`` in a project folder the user cannot write to: a clear error
naming the folder (one JSON error object with ``--json``), no traceback, the project untouched.

Root ignores permission bits, so as root the folder is made immutable (``chattr +i``, which
refuses even root with EPERM, a PermissionError too); the tests skip where neither works."""

from __future__ import annotations

import json
import os
import shutil
import subprocess
from pathlib import Path

import pytest

from app.cli import main


def _lock(folder: Path) -> bool:
    """Make ``folder`` unwritable; False if this machine cannot."""
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


@pytest.fixture
def locked(fitted_project_copy):
    """The fitted sample project whose folder and results folder cannot be written to."""
    folders = [fitted_project_copy.parent / "results", fitted_project_copy.parent]
    locked = [f for f in folders if _lock(f)]
    if len(locked) < len(folders):
        for f in locked:
            _unlock(f)
        pytest.skip("cannot make a folder unwritable here (root without chattr)")
    probe = fitted_project_copy.parent / "probe"
    try:
        probe.write_text("x")
    except PermissionError:
        pass
    else:
        probe.unlink()
        for f in folders:
            _unlock(f)
        pytest.skip("the folder stays writable (a filesystem without permissions)")
    yield fitted_project_copy
    for f in folders:
        _unlock(f)


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
        assert error["type"] in ("ProjectError", "PermissionError") and str(locked.parent) in error["message"]
    assert locked.read_bytes() == before
