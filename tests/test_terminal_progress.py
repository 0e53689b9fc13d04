"""The command line's progress (app/cli/progress.py): a bar on a terminal, plain lines in a log, one style.

A log (stderr not a terminal) must not fill with carriage-return redraws: a line per stage and
per 10 % step instead. Fit, texture and track say the command and what they are on.
"""

from __future__ import annotations

import fcntl
import io
import os
import pty
import shutil
import struct
import subprocess
import sys
import termios
from pathlib import Path

import pytest

from app.cli import main
from app.cli.progress import PERCENT_STEP, StageProgress


class Terminal(io.StringIO):
    def isatty(self) -> bool:
        return True


def test_lines_in_a_log_one_per_stage_and_ten_percent_step():
    log = io.StringIO()
    progress = StageProgress("fit", stream=log)
    assert not progress.tty
    for i in range(101):  # one stage reported at every percent
        progress("neutral (1/2): refining", i / 100)
    progress("smile (2/2): pose recovery", 1.0)
    progress.close()
    lines = log.getvalue().splitlines()
    assert "\r" not in log.getvalue()
    assert len(lines) == 100 // PERCENT_STEP + 1 + 1
    assert lines[0] == "fit neutral (1/2): refining 0%" and lines[1] == "fit neutral (1/2): refining 10%"
    assert lines[-1] == "fit smile (2/2): pose recovery 100%"


def test_a_detail_changes_the_bar_not_the_log():
    log = io.StringIO()
    progress = StageProgress("track", stream=log)
    for done in range(1, 41):
        progress("james_track.mp4", done / 40, f"frame {done} of 40")
    lines = log.getvalue().splitlines()
    assert len(lines) == 11 and lines[0] == "track james_track.mp4: frame 1 of 40 2%"
    assert lines[-1] == "track james_track.mp4: frame 40 of 40 100%"


def test_a_bar_on_a_terminal_and_silence_when_disabled():
    term = Terminal()
    progress = StageProgress("texture", stream=term)
    progress("neutral (1/1): blending", 0.5)
    assert "\r" in term.getvalue() and "texture neutral (1/1): blending" in term.getvalue()
    assert "50%" in term.getvalue()
    progress.close()
    quiet = io.StringIO()
    StageProgress("fit", stream=quiet, enabled=False)("neutral", 0.5)
    assert quiet.getvalue() == ""


def test_fit_command_writes_lines_naming_the_expression_into_a_log(project_copy, capsys):
    assert main(["fit", str(project_copy), "--expression", "neutral", "--dry-run"]) == 0
    err = capsys.readouterr().err  # captured: not a terminal
    assert "\r" not in err
    lines = [line for line in err.splitlines() if line.startswith("fit ")]
    assert lines[0] == "fit neutral (1/1): pose recovery 0%" and lines[-1] == "fit neutral (1/1): done 100%"
    assert len(lines) <= 2 * (100 // PERCENT_STEP + 1)


def test_a_new_phase_starts_its_own_clock_on_the_bar():
    """Issue 35: a later phase must not carry an earlier one's elapsed time ("[00:26<16:58]" on a 30 s job)."""
    term = Terminal()
    progress = StageProgress("edit", stream=term)
    progress("smoothing (round 1)", 0.5)
    progress.bar.start_t -= 100  # the first phase took 100 s
    progress("smoothing (round 1)", 0.6)
    assert "01:40" in term.getvalue()
    progress("editing", 0.1)
    assert progress.bar.format_dict["elapsed"] < 5 and term.getvalue().rstrip().endswith("00:00")
    progress.close()


@pytest.fixture
def track_copy(straight, tmp_path):
    out = tmp_path / "track"
    shutil.copytree(straight.out_dir, out)
    return out


def _commands(fitted, track, tmp):
    video = Path(__file__).resolve().parents[1] / "sample_projects" / "james" / "video" / "james_track.mp4"
    clip = tmp / "clip.mp4"
    shutil.copy(video, clip)
    shutil.copy(video.with_name("james_track.first_pose.json"), tmp / "clip.first_pose.json")
    return {
        "edit": [
            "edit",
            str(fitted),
            "--track",
            str(track),
            "--scale",
            "smile=0.5",
            "--no-smooth",
            "--out",
            str(tmp / "e"),
        ],
        "export": ["export", str(fitted), "--track", str(track), "--glb", str(tmp / "x.glb")],
        "track-many": [
            "track-many",
            str(fitted),
            str(clip),
            "--out",
            str(tmp / "many"),
            "--frames",
            "2",
            "--no-overlay",
        ],
    }


def test_edit_export_and_track_many_write_lines_into_a_log(fitted_sample, track_copy, tmp_path, capsys):
    """Issue 35: every command reports in the one style; in a log (stderr not a terminal) as plain
    lines: no carriage-return redraws (edit and track-many wrote them), no silence (export)."""
    for word, argv in _commands(fitted_sample, track_copy, tmp_path).items():
        assert main(argv) == 0, word
        err = capsys.readouterr().err
        lines = [line for line in err.splitlines() if line.startswith(f"{word} ")]
        assert "\r" not in err and lines and lines[-1].endswith("100%"), (word, err)


@pytest.mark.parametrize("word", ["edit", "export", "track-many"])
def test_on_a_terminal_each_command_draws_one_bar(word, fitted_sample, track_copy, tmp_path):
    """stderr a pty: the bar, redrawn in place, with the command's word and the phase's time."""
    argv = _commands(fitted_sample, track_copy, tmp_path)[word]
    master, slave = pty.openpty()
    fcntl.ioctl(slave, termios.TIOCSWINSZ, struct.pack("HHHH", 24, 120, 0, 0))  # a terminal 120 columns wide
    env = {**os.environ, "PYTHONPATH": str(Path(__file__).resolve().parents[1])}
    code = "import sys; from app.cli import main; sys.exit(main(sys.argv[1:]))"
    proc = subprocess.Popen([sys.executable, "-c", code, *argv], stderr=slave, stdout=subprocess.PIPE, env=env)
    os.close(slave)
    chunks = []
    while True:
        try:
            data = os.read(master, 4096)
        except OSError:  # EIO: the child closed the terminal
            break
        if not data:
            break
        chunks.append(data)
    os.close(master)
    assert proc.wait(timeout=300) == 0
    text = b"".join(chunks).decode("utf-8", "replace")
    assert "\r" in text and f"\r{word} " in text and "00:0" in text, text[-500:]
