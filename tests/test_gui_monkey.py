"""A monkey test of the studio window (pytest-qt, offscreen): seeded random artist actions.

:class:`app.qt.monkey.Monkey` switches expressions and photo tabs, clicks, drags, deletes, hides,
draws curves, undoes, redoes, fits, cancels fits, extracts textures, and does *File → New*,
*Open…* (the sample, files saved meanwhile, damaged files), *Save*, add/remove photo and close —
through the real widgets — checking the window's invariants after every action and, before the
undo history is emptied and at the end, that undoing every edit gives the opened project back
(result records excepted). pytest-qt fails a test on any exception in a Qt virtual or slot.

A few seeds of :data:`ACTIONS_PER_SEED` actions keep this file near 40 s on the 2-core machine;
``benchmarks/fuzz_monkey.py`` runs thousands of actions, each seed in its own process.
"""

from __future__ import annotations

import pytest

pytest.importorskip("PySide6")
pytest.importorskip("pytestqt")

from PySide6.QtCore import QSettings  # noqa: E402

from app.qt.main_window import MainWindow  # noqa: E402
from app.qt.monkey import ACTIONS, Monkey  # noqa: E402

ACTIONS_PER_SEED = 50
#: Fits and textures take a second or two each: fewer of them in the suite than in the benchmark.
SUITE_WEIGHTS = {**ACTIONS, "fit": 1.5, "cancel": 1, "texture": 1.5}


@pytest.fixture
def make_window(qtbot, tmp_path):
    """Builds shown studio windows with their own settings and recovery folder (one more after
    each close); their workers are stopped when the test ends."""
    made = []

    def make():
        w = MainWindow(
            settings=QSettings(str(tmp_path / "settings.ini"), QSettings.Format.IniFormat),
            autosave_interval_ms=0,
            recovery_folder=tmp_path / "recovery",
        )
        qtbot.addWidget(w)
        w.resize(1300, 850)
        w.show()
        qtbot.waitExposed(w)
        made.append(w)
        return w

    yield make
    for w in made:
        w.fits.shutdown()
        w.jobs.shutdown()
        w.model.modified = False


def photos_of(project_copy):
    return sorted((project_copy.parent / "photos").glob("*_front.*"))[:3] + sorted(
        (project_copy.parent / "photos").glob("neutral_*.png")
    )


@pytest.mark.parametrize("seed", [11, 12])
def test_monkey_on_the_sample_project(qtbot, make_window, project_copy, tmp_path, messages, seed):
    monkey = Monkey(make_window, seed, tmp_path / "work", project_copy, photos_of(project_copy), SUITE_WEIGHTS)
    counts = monkey.run(ACTIONS_PER_SEED)
    assert sum(counts.values()) == ACTIONS_PER_SEED
    assert monkey.window.unexpected_errors == []
    # every message box the monkey met named its cause, none was a traceback
    assert not [m for m in monkey.messages if "Traceback" in m[2]], monkey.messages


def test_monkey_on_an_empty_project(qtbot, make_window, project_copy, tmp_path, messages):
    monkey = Monkey(
        make_window, 21, tmp_path / "work", None, photos_of(project_copy), {**SUITE_WEIGHTS, "add_photos": 6}
    )
    counts = monkey.run(ACTIONS_PER_SEED)
    assert sum(counts.values()) == ACTIONS_PER_SEED and counts["add_photos"] > 0
    assert monkey.window.unexpected_errors == []
    assert not [m for m in monkey.messages if "Traceback" in m[2]], monkey.messages
