"""Nothing a user does crashes a command or the studio: the fuzzed project loader and the monkey.

    .venv/bin/python benchmarks/bench_fuzz.py [--json] [--mutants 10000] [--benign 1000] [--workers N]
                                              [--seed 0] [--only fuzz|benign|monkey|commands]
                                              [--commands fit,texture]

Sections (each a function of :data:`SECTIONS`, adding its keys to one JSON object):

* ``fuzz`` — ``--mutants`` seeded hypothesis mutants of the sample project
  (:mod:`photomodel.samples.project_mutants`: byte flips, truncation, deleted and renamed keys,
  type swaps, huge and tiny numbers, deep nesting, bad references, ``cameras_from`` cycles), an
  equal share of each kind. Each mutant must either load — and then save, reload and save to the
  same bytes — or raise :class:`~photomodel.errors.ProjectError`. Keys: ``mutants``, ``loaded``,
  ``project_errors``, ``other_exceptions`` (anything else, including a failed round trip; the
  bar is 0) and ``by_kind``; a few examples of other exceptions go to stderr.
* ``benign`` — ``--benign`` mutants that write the same project differently (whitespace, key
  order, number formatting, BOM and CRLF); ``loaded`` counts those that load equal to the
  original (the bar: all of them).
* ``monkey`` — seeded random artist actions on the studio, each seed in its own process
  (``benchmarks/fuzz_monkey.py``, ``monkey_section``; included when that file is there).
* ``commands`` — every ``facestudio`` command × {read-only output folder, missing input, a photo
  of the wrong size, an unknown name in an argument, a path with spaces and non-Latin letters},
  each in its own process (``benchmarks/fuzz_commands.py``, ``commands_section``). Keys:
  ``cases``, ``tracebacks``, ``partial_outputs``, ``unnamed``, ``exit_codes``, ``failures``; the
  bars: 0 tracebacks, 0 partial outputs, every failure exit 2 naming the path or name at fault.

Mutants are checked in ``--workers`` processes (default: every core), each running hypothesis
on its own seed; the figures do not depend on the number of workers' timing, only on the seeds.
"""

from __future__ import annotations

import math
import os
import sys
import tempfile
import time
import traceback
from collections import Counter
from functools import cache
from multiprocessing import Pool
from pathlib import Path

from fuzz_commands import COMMANDS, commands_section  # benchmarks/fuzz_commands.py
from hypothesis import HealthCheck, Phase, given, seed, settings
from sections import run_sections, section_parser  # benchmarks/sections.py

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # the repository, when not installed

from photomodel.project import load_project  # noqa: E402
from photomodel.samples.project_mutants import (  # noqa: E402
    MUTATIONS,
    benign_mutants,
    check_mutant,
    fuzz_base,
    mutants,
)

SAMPLE = Path(__file__).resolve().parents[1] / "sample_projects" / "james" / "james.facestudio.json"
#: Mutants per task given to a worker (one hypothesis run of one kind on one seed).
TASK = 50
#: ``cameras_from`` cycles have only a few hundred distinct forms: at most this many per run.
SMALL_KINDS = {"cameras_cycle": 300}
#: Examples of other exceptions kept per task.
EXAMPLES = 3


@cache
def _base():
    return fuzz_base(SAMPLE, photos_per_expression=2)


def _settings(n: int):
    return settings(
        max_examples=n, database=None, deadline=None, phases=[Phase.generate], suppress_health_check=list(HealthCheck)
    )


def _fuzz_task(task: tuple[str, int, int]) -> dict:
    """One worker task: ``n`` mutants of ``kind`` drawn with hypothesis seed ``s``; counts and
    examples of other exceptions."""
    kind, s, n = task
    counts: Counter = Counter()
    examples: list[str] = []
    with tempfile.TemporaryDirectory(prefix="fuzz") as folder:

        @seed(s)
        @_settings(n)
        @given(_strategy(kind))
        def run(data):
            try:
                counts[check_mutant(data, Path(folder))] += 1
            except Exception as exc:  # the thing being counted: anything but a ProjectError
                counts["other"] += 1
                if len(examples) < EXAMPLES:
                    examples.append(
                        f"{kind} (seed {s}): {type(exc).__name__}: {str(exc)[:300]}\n"
                        + "".join(traceback.format_tb(exc.__traceback__)[-3:])
                    )

        run()
    return {"kind": kind, "counts": dict(counts), "examples": examples}


def _strategy(kind: str):
    return mutants(_base(), kind)


def _fuzz_tasks(total: int, seed0: int, kinds=MUTATIONS) -> list[tuple[str, int, int]]:
    """Tasks of at most :data:`TASK` mutants, each of ``kinds`` its share of ``total`` (small
    kinds capped by :data:`SMALL_KINDS`, their rest shared by the others)."""
    small = [k for k in kinds if k in SMALL_KINDS]
    big = [k for k in kinds if k not in SMALL_KINDS]
    share = {k: min(SMALL_KINDS[k], math.ceil(total / len(kinds))) for k in small}
    rest = total - sum(share.values())
    share.update({k: math.ceil(rest / len(big)) for k in big})
    tasks = []
    for k in kinds:
        if k in SMALL_KINDS:  # one run: hypothesis does not repeat a mutant within a run
            tasks.append((k, seed0, share[k]))
            continue
        for i in range(math.ceil(share[k] / TASK)):
            tasks.append((k, seed0 + 1000 * MUTATIONS.index(k) + i, min(TASK, share[k] - i * TASK)))
    return tasks


def fuzz_section(args, log) -> dict:
    """``{"fuzz": {"mutants", "loaded", "project_errors", "other_exceptions", "by_kind"}}``.

    A small kind may run out of distinct mutants before its share; the shortfall is then drawn
    from the other kinds on fresh seeds, so that at least ``args.mutants`` are checked."""
    by_kind: dict[str, Counter] = {k: Counter() for k in MUTATIONS}
    examples: list[str] = []
    t0 = time.perf_counter()
    tasks = _fuzz_tasks(args.mutants, args.seed)
    with Pool(args.workers) as pool:
        for attempt in range(1, 4):
            for i, r in enumerate(pool.imap_unordered(_fuzz_task, tasks), 1):
                by_kind[r["kind"]].update(r["counts"])
                examples += r["examples"]
                if i % 10 == 0 or i == len(tasks):
                    log(
                        f"fuzz: {_done(by_kind)} mutants, {sum(c['other'] for c in by_kind.values())} other "
                        f"exceptions, {time.perf_counter() - t0:.0f} s"
                    )
            missing = args.mutants - _done(by_kind)
            if missing <= 0:
                break
            big = [k for k in MUTATIONS if k not in SMALL_KINDS]
            tasks = _fuzz_tasks(missing, args.seed + 100_000 * attempt, big)
    for e in examples[:10]:
        log("other exception: " + e)
    total: Counter = Counter()
    for c in by_kind.values():
        total.update(c)
    return {
        "fuzz": {
            "mutants": sum(total.values()),
            "loaded": total["loaded"],
            "project_errors": total["project_error"],
            "other_exceptions": total["other"],
            "seconds": round(time.perf_counter() - t0, 1),
            "by_kind": {
                k: {"mutants": sum(c.values()), "loaded": c["loaded"], "other_exceptions": c["other"]}
                for k, c in by_kind.items()
            },
        }
    }


def _done(by_kind: dict) -> int:
    return sum(sum(c.values()) for c in by_kind.values())


def _benign_task(task: tuple[int, int]) -> dict:
    """``n`` benign mutants on hypothesis seed ``s``: how many load equal to the original."""
    s, n = task
    counts: Counter = Counter()
    failures: list[str] = []
    with tempfile.TemporaryDirectory(prefix="benign") as folder:
        path = Path(folder) / "o.facestudio.json"
        path.write_text(_base().text, encoding="utf-8")
        original = load_project(path)

        @seed(s)
        @_settings(n)
        @given(benign_mutants(_base()))
        def run(mutant):
            kind, text = mutant
            path.write_bytes(text if isinstance(text, bytes) else text.encode("utf-8"))
            try:
                ok = load_project(path) == original
            except Exception as exc:  # counted: a benign mutant must load
                ok = False
                failures.append(f"{kind}: {type(exc).__name__}: {str(exc)[:300]}")
            counts["loaded" if ok else "failed"] += 1

        run()
    return {"counts": dict(counts), "failures": failures[:EXAMPLES]}


def benign_section(args, log) -> dict:
    """``{"benign": {"mutants", "loaded"}}``."""
    tasks = [(args.seed + 500_000 + i, min(TASK, args.benign - i * TASK)) for i in range(math.ceil(args.benign / TASK))]
    total: Counter = Counter()
    with Pool(args.workers) as pool:
        for r in pool.imap_unordered(_benign_task, tasks):
            total.update(r["counts"])
            for f in r["failures"]:
                log("benign mutant not loaded equal: " + f)
    log(f"benign: {total['loaded']} of {sum(total.values())} loaded equal")
    return {"benign": {"mutants": sum(total.values()), "loaded": total["loaded"]}}


#: Benchmark sections in order; each takes ``(args, log)`` and returns the keys it adds.
SECTIONS = {"fuzz": fuzz_section, "benign": benign_section}
if (Path(__file__).with_name("fuzz_monkey.py")).exists():  # the studio's monkey section
    from fuzz_monkey import monkey_section  # noqa: E402

    SECTIONS["monkey"] = monkey_section
SECTIONS["commands"] = commands_section


def main(argv=None) -> int:
    ap = section_parser(__doc__.splitlines()[0])
    ap.add_argument("--mutants", type=int, default=10_000, help="harmful mutants (the bar: >= 10 000)")
    ap.add_argument("--benign", type=int, default=1000, help="benign mutants")
    ap.add_argument("--workers", type=int, default=os.cpu_count() or 1, help="processes checking mutants")
    ap.add_argument("--seed", type=int, default=0, help="first hypothesis seed")
    ap.add_argument("--monkey-seeds", type=int, help="the monkey section: seeds (default: fuzz_monkey.SEEDS)")
    ap.add_argument("--monkey-actions", type=int, help="the monkey section: actions per seed")
    ap.add_argument("--monkey-jobs", type=int, help="the monkey section: children at once")
    ap.add_argument(
        "--commands",
        metavar="A,B",
        help=f"the commands section: only these commands (default: all of {', '.join(COMMANDS)})",
    )
    return run_sections(ap, SECTIONS, argv)


if __name__ == "__main__":
    sys.exit(main())
