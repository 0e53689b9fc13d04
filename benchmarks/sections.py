"""A benchmark made of sections: each ``section(args, log) -> dict`` adds its keys to one JSON object.

``bench_landmarks.py`` and ``bench_fuzz.py`` are built this way: :func:`section_parser` gives the
shared flags (``--json``, ``--quiet``), the benchmark adds its own, and :func:`run_sections` adds
``--only``, runs the sections in order (progress to stderr unless ``--quiet``) and prints exactly
one JSON object with ``--json`` (a line per key without).
"""

from __future__ import annotations

import argparse
import json
import sys
from collections.abc import Callable

Section = Callable[[argparse.Namespace, Callable[[str], None]], dict]


def section_parser(description: str) -> argparse.ArgumentParser:
    """An argument parser with the flags every sectioned benchmark has."""
    ap = argparse.ArgumentParser(description=description)
    ap.add_argument("--json", action="store_true", help="print one JSON object on stdout")
    ap.add_argument("--quiet", action="store_true", help="no progress on stderr")
    return ap


def run_sections(ap: argparse.ArgumentParser, sections: dict[str, Section], argv=None) -> int:
    """Parse ``argv`` (``--only`` added), run the chosen ``sections`` in order, print the result."""
    ap.add_argument("--only", choices=list(sections), action="append", help="run only these sections")
    args = ap.parse_args(argv)
    log = (lambda s: None) if args.quiet else (lambda s: print(s, file=sys.stderr, flush=True))
    out: dict = {}
    for key, section in sections.items():
        if args.only and key not in args.only:
            continue
        out.update(section(args, log))
    if args.json:
        print(json.dumps(out, indent=1))
    else:
        for key, value in out.items():
            print(f"{key}: {json.dumps(value)}")
    return 0
