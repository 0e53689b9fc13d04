"""The command line's progress: one style for every command, plain lines in logs.

On a terminal it is a tqdm bar (the kept library for progress bars) redrawn in place, saying the
command, what it is on, how far it is and how long the current phase has taken, e.g.
``fit neutral (1/5): refining: points and curves  |██████████          |  55% 00:12`` or
``track james_track.mp4: frame 12 of 40  |██████              |  30% 00:04``. The elapsed time
starts again at each new phase (a stage), so a later phase never carries an earlier one's time.
When stderr is not a terminal (a log file, CI, a pipe) carriage-return redraws would pile up in
the file as one long line, so a plain line is written instead each time the stage changes or the
percentage reaches the next :data:`PERCENT_STEP` — e.g. ``fit neutral (1/5): pose recovery 0%``.

Every command reports through :class:`StageProgress` (made by :func:`command_progress`):
``new``, ``add-photos``, ``fit``, ``texture``, ``track``, ``track-many``, ``edit``, ``rig`` and
``export``. :meth:`StageProgress.write` puts a message above the bar (a line in a log).
"""

from __future__ import annotations

import io
import os
import sys
import time
from typing import TextIO

from tqdm import tqdm

#: Without a terminal, a line each time the percentage passes a multiple of this.
PERCENT_STEP = 10
#: The one bar style: what it is on (cut to 56 characters), the bar, the percentage, the phase's time.
BAR_FORMAT = "{desc:<56.56} |{bar:20}| {percentage:3.0f}% {elapsed}"


class StageProgress:
    """``progress(stage, fraction, detail="")`` for one command, on ``stream`` (default stderr).

    Parameters
    ----------
    task : the command's word in front of every stage (``"fit"``, ``"texture"``, ``"track"``).
    enabled : False: silent (``--json`` output without a terminal).
    stream : where to write (default ``sys.stderr``).
    tty : whether ``stream`` is a terminal (default: ``stream.isatty()``): a bar, else lines.

    ``stage`` says what is being done and on which expression (a new stage is a new line in a
    log, and restarts the bar's clock); ``detail`` changes often (a frame number) and is shown
    without starting a line; ``fraction`` is the whole command's, in [0, 1].
    """

    def __init__(self, task: str, *, enabled: bool = True, stream: TextIO | None = None, tty: bool | None = None):
        self.task = task
        self.enabled = enabled
        self.stream = stream if stream is not None else sys.stderr
        self.tty = bool(tty if tty is not None else _is_terminal(self.stream))
        self.bar = None
        self._stage: str | None = None
        self._next_percent = 0
        self.stage_started = time.monotonic()

    def __call__(self, stage: str, fraction: float, detail: str = "") -> None:
        if not self.enabled:
            return
        percent = int(round(100 * min(max(float(fraction), 0.0), 1.0)))
        text = f"{self.task} {stage}" + (f": {detail}" if detail else "")
        new_stage = stage != self._stage
        if new_stage:
            self.stage_started = time.monotonic()
        if self.tty:
            if self.bar is None:
                self.bar = tqdm(
                    total=100, file=self.stream, bar_format=BAR_FORMAT, leave=False, desc=text, initial=percent
                )
            elif new_stage:  # the elapsed time is the phase's
                self.bar.start_t = self.bar._time()
            self._stage = stage
            self.bar.set_description_str(text, refresh=False)
            self.bar.n = percent
            self.bar.refresh()
            return
        if new_stage or percent >= self._next_percent:
            self._stage = stage
            self._next_percent = (percent // PERCENT_STEP + 1) * PERCENT_STEP
            self.stream.write(f"{text} {percent}%\n")
            self.stream.flush()

    def counter(self, stage: str, done: int, total: int | None, unit: str = "frame") -> None:
        """A stage counted in items: ``stage: frame 3 of 40`` at fraction ``done / total``."""
        of = f" of {total}" if total else ""
        self(stage, done / total if total else 0.0, f"{unit} {done}{of}")

    def write(self, message: str) -> None:
        """``message`` on a line of its own, above the bar on a terminal (always shown)."""
        if self.bar is not None:
            tqdm.write(message, file=self.stream)
        else:
            self.stream.write(message + "\n")
            self.stream.flush()

    def close(self) -> None:
        """Take the bar off the terminal (nothing to do for lines)."""
        if self.bar is not None:
            self.bar.close()
            self.bar = None

    def __enter__(self) -> StageProgress:
        return self

    def __exit__(self, *exc) -> None:
        self.close()


def _is_terminal(stream) -> bool:
    """Whether ``stream`` is a terminal a bar can be drawn on: a TTY that reports a width (a
    pseudo-terminal of width 0, as some CI runners open, would show an empty bar: lines there)."""
    if not getattr(stream, "isatty", lambda: False)():
        return False
    try:
        return os.get_terminal_size(stream.fileno()).columns > 0
    except (AttributeError, OSError, ValueError, io.UnsupportedOperation):
        return True  # a terminal-like stream without a descriptor (tests): a bar


def command_progress(args, task: str, stream: TextIO | None = None) -> StageProgress:
    """The progress of command ``task``: on stderr, silent with ``--json`` unless stderr is a terminal."""
    stream = stream if stream is not None else sys.stderr
    tty = _is_terminal(stream)
    return StageProgress(task, enabled=not getattr(args, "json", False) or tty, stream=stream, tty=tty)


__all__ = ["BAR_FORMAT", "PERCENT_STEP", "StageProgress", "command_progress"]
