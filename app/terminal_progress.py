"""The command line's progress: one style for ``new``, ``fit``, ``texture`` and ``track``, lines in logs.

On a terminal it is a tqdm bar (the kept library for progress bars) redrawn in place, saying the
command, what it is on and how far it is, e.g.
``fit neutral (1/5): refining: points and curves  |██████████          |  55%`` or
``track james_track.mp4: frame 12 of 40  |██████              |  30%``.
When stderr is not a terminal (a log file, CI, a pipe) carriage-return redraws would pile up in
the file as one long line, so a plain line is written instead each time the stage changes or the
percentage reaches the next :data:`PERCENT_STEP` — e.g. ``fit neutral (1/5): pose recovery 0%``.
"""

from __future__ import annotations

import sys
from typing import TextIO

from tqdm import tqdm

#: Without a terminal, a line each time the percentage passes a multiple of this.
PERCENT_STEP = 10
#: The one bar style: what it is on (cut to 56 characters), the bar, the percentage.
BAR_FORMAT = "{desc:<56.56} |{bar:20}| {percentage:3.0f}%"


class StageProgress:
    """``progress(stage, fraction, detail="")`` for one command, on ``stream`` (default stderr).

    Parameters
    ----------
    task : the command's word in front of every stage (``"fit"``, ``"texture"``, ``"track"``).
    enabled : False: silent (``--json`` output without a terminal).
    stream : where to write (default ``sys.stderr``).
    tty : whether ``stream`` is a terminal (default: ``stream.isatty()``): a bar, else lines.

    ``stage`` says what is being done and on which expression (a new stage is a new line in a
    log); ``detail`` changes often (a frame number) and is shown without starting a line;
    ``fraction`` is the whole command's, in [0, 1].
    """

    def __init__(self, task: str, *, enabled: bool = True, stream: TextIO | None = None, tty: bool | None = None):
        self.task = task
        self.enabled = enabled
        self.stream = stream if stream is not None else sys.stderr
        self.tty = bool(tty if tty is not None else getattr(self.stream, "isatty", lambda: False)())
        self.bar = None
        self._stage: str | None = None
        self._next_percent = 0

    def __call__(self, stage: str, fraction: float, detail: str = "") -> None:
        if not self.enabled:
            return
        percent = int(round(100 * min(max(float(fraction), 0.0), 1.0)))
        text = f"{self.task} {stage}" + (f": {detail}" if detail else "")
        if self.tty:
            if self.bar is None:
                self.bar = tqdm(total=100, file=self.stream, bar_format=BAR_FORMAT, leave=False)
            self.bar.set_description_str(text, refresh=False)
            self.bar.n = percent
            self.bar.refresh()
            return
        if stage != self._stage or percent >= self._next_percent:
            self._stage = stage
            self._next_percent = (percent // PERCENT_STEP + 1) * PERCENT_STEP
            self.stream.write(f"{text} {percent}%\n")
            self.stream.flush()

    def close(self) -> None:
        """Take the bar off the terminal (nothing to do for lines)."""
        if self.bar is not None:
            self.bar.close()
            self.bar = None


__all__ = ["BAR_FORMAT", "PERCENT_STEP", "StageProgress"]
