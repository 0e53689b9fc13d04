"""The command line's progress (app/cli/progress.py): a bar on a terminal, plain lines in a log, one style.

A log (stderr not a terminal) must not fill with carriage-return redraws: a line per stage and
per 10 % step instead. Fit, texture and track say the command and what they are on.
"""

from __future__ import annotations

import io

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
