"""The monkey section of ``benchmarks/bench_fuzz.py``: thousands of random artist actions on the studio.

    .venv/bin/python benchmarks/fuzz_monkey.py [--seeds 20] [--actions 110] [--json]   # the section alone
    .venv/bin/python benchmarks/fuzz_monkey.py --seed N --actions K [--empty]          # one seed (a child)

:func:`monkey_section` runs each seed in its own process (this file with ``--seed``), so that a
crash — a signal such as a segmentation fault, a non-zero exit, a hang past the time limit — is
counted instead of ending the run. A child drives :class:`app.qt.monkey.Monkey` (offscreen) on a
fresh copy of the sample project (every fourth seed: an empty project that gets photos added),
prints one line per action before doing it (so a crash still counts the actions that came
before it) and one ``result`` line: unexpected exceptions (those reaching ``sys.excepthook``,
i.e. the studio's unexpected-error box, or escaping an action) and broken invariants
(:meth:`Monkey.check`, :meth:`Monkey.check_undo_all`).

The section's keys: ``actions`` (done, across seeds), ``seeds``, ``crashes`` (children ended by a
signal, a non-zero exit or the time limit), ``unexpected_exceptions`` and ``by_kind`` (actions per
kind), with the weights of :data:`app.qt.monkey.ACTIONS` (fit, texture and open ~4 % each: about 80
of each in the default run). Two children run at once (``--jobs``; the machine has two cores).
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import subprocess
import sys
import tempfile
import time
import traceback
from collections import Counter
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
SAMPLE = REPO / "sample_projects" / "james"
#: Seeds and actions per seed of the default run: 2 100 actions.
SEEDS, ACTIONS_PER_SEED = 10, 210
#: Children run at once.
JOBS = 2
#: A child taking longer than this is counted as a crash (hung).
CHILD_TIMEOUT_S = 900
#: Every EMPTY_EVERY-th seed starts from an empty project.
EMPTY_EVERY = 4


def run_child(seed: int, actions: int, empty: bool) -> int:
    """One seed in this process: prints ``step <kind>`` lines and a final ``result {json}``."""
    os.environ.setdefault("QT_QPA_PLATFORM", "offscreen")
    from PySide6.QtCore import QSettings  # noqa: PLC0415 - the Qt stack, loaded only in a child
    from PySide6.QtWidgets import QApplication  # noqa: PLC0415

    from app.qt.main_window import MainWindow  # noqa: PLC0415
    from app.qt.monkey import InvariantError, Monkey  # noqa: PLC0415

    app = QApplication.instance() or QApplication([])
    unexpected: list[str] = []
    work = Path(tempfile.mkdtemp(prefix=f"monkey{seed}_"))
    windows = []

    def make():
        w = MainWindow(
            settings=QSettings(str(work / "settings.ini"), QSettings.Format.IniFormat),
            autosave_interval_ms=0,
            recovery_folder=work / "recovery",
        )
        w.resize(1300, 850)
        w.show()
        windows.append(w)
        return w

    def hook(exc_type, exc, tb):  # what the studio's excepthook gets, recorded and shown
        unexpected.append(f"{exc_type.__name__}: {exc}")
        windows[-1].report_unexpected(exc_type, exc, tb)

    sys.excepthook = hook
    shutil.copytree(SAMPLE, work / "james", ignore=shutil.ignore_patterns("results", "video"))
    project = work / "james" / "james.facestudio.json"
    photos = sorted((work / "james" / "photos").glob("neutral_*.png"))
    try:
        monkey = Monkey(make, seed, work / "monkey", None if empty else project, photos)
        monkey.run(actions, on_step=lambda kind: print("step", kind, flush=True))
    except InvariantError as exc:
        unexpected.append(f"invariant: {exc}")
    except Exception as exc:
        unexpected.append(f"{type(exc).__name__}: {exc}")
        traceback.print_exc()
    for w in windows:
        w.fits.shutdown()
        w.jobs.shutdown()
    print("result", json.dumps({"seed": seed, "unexpected": unexpected}), flush=True)
    app.processEvents()
    shutil.rmtree(work, ignore_errors=True)
    return 0


def _run_seed(seed: int, actions: int, log) -> dict:
    empty = seed % EMPTY_EVERY == EMPTY_EVERY - 1
    cmd = [sys.executable, str(Path(__file__).resolve()), "--seed", str(seed), "--actions", str(actions)]
    cmd += ["--empty"] if empty else []
    env = {**os.environ, "QT_QPA_PLATFORM": "offscreen"}
    t0 = time.perf_counter()
    try:
        proc = subprocess.run(cmd, capture_output=True, text=True, timeout=CHILD_TIMEOUT_S, env=env, cwd=REPO)
        out, code = proc.stdout, proc.returncode
        err = proc.stderr
    except subprocess.TimeoutExpired as exc:
        out = exc.stdout.decode() if isinstance(exc.stdout, bytes) else (exc.stdout or "")
        err, code = "timed out", "timeout"
    kinds = Counter(line.split()[1] for line in out.splitlines() if line.startswith("step "))
    results = [json.loads(line[len("result ") :]) for line in out.splitlines() if line.startswith("result ")]
    crashed = code != 0 or not results
    unexpected = results[0]["unexpected"] if results else []
    log(
        f"seed {seed:3d} ({'empty' if empty else 'sample'}): {sum(kinds.values())} actions, "
        f"{time.perf_counter() - t0:.0f} s, exit {code}, {len(unexpected)} unexpected"
        + (f"\n  {unexpected}" if unexpected else "")
        + (f"\n  {err[-2000:]}" if crashed else "")
    )
    return {"kinds": kinds, "crashed": crashed, "unexpected": unexpected}


def monkey_section(args, log) -> dict:
    """``{"monkey": {"actions", "seeds", "crashes", "unexpected_exceptions", "by_kind"}}`` over
    ``args.monkey_seeds`` seeds (default :data:`SEEDS`) of ``args.monkey_actions`` actions each
    (default :data:`ACTIONS_PER_SEED`), ``args.monkey_jobs`` children at once; ``log(text)``
    gets one line per seed. ``args`` may lack these attributes (bench_fuzz's own)."""
    seeds = int(getattr(args, "monkey_seeds", None) or SEEDS)
    actions = int(getattr(args, "monkey_actions", None) or ACTIONS_PER_SEED)
    jobs = int(getattr(args, "monkey_jobs", None) or JOBS)
    by_kind, crashes, unexpected = Counter(), 0, 0
    with ThreadPoolExecutor(jobs) as pool:  # each child is a process: threads only wait for them
        for r in pool.map(lambda seed: _run_seed(seed, actions, log), range(seeds)):
            by_kind.update(r["kinds"])
            crashes += r["crashed"]
            unexpected += len(r["unexpected"])
    return {
        "monkey": {
            "actions": sum(by_kind.values()),
            "seeds": seeds,
            "crashes": crashes,
            "unexpected_exceptions": unexpected,
            "by_kind": dict(sorted(by_kind.items())),
        }
    }


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seed", type=int, help="run one seed in this process (the child)")
    ap.add_argument("--actions", type=int, default=ACTIONS_PER_SEED)
    ap.add_argument("--seeds", type=int, default=SEEDS)
    ap.add_argument("--jobs", type=int, default=JOBS, help="children at once")
    ap.add_argument("--empty", action="store_true", help="start from an empty project (with --seed)")
    ap.add_argument("--json", action="store_true", help="print the section as one JSON object")
    args = ap.parse_args(argv)
    if args.seed is not None:
        return run_child(args.seed, args.actions, args.empty)
    args.monkey_seeds, args.monkey_actions, args.monkey_jobs = args.seeds, args.actions, args.jobs

    def log(text):
        print(text, file=sys.stderr if args.json else sys.stdout, flush=True)

    section = monkey_section(args, log)
    print(json.dumps(section, indent=None if args.json else 1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
