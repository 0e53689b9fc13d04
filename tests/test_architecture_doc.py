"""docs/architecture.md lists every module of every package by its path, and nothing else."""

from __future__ import annotations

import re
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
PACKAGES = ("photomodel", "tracking", "app", "peers")


def test_every_module_is_listed_by_path_and_every_listed_path_exists():
    doc = (REPO / "docs" / "architecture.md").read_text(encoding="utf-8")
    listed = set(re.findall(r"^- `([\w/]+\.py)` — \S", doc, flags=re.M))
    tree = {p.relative_to(REPO).as_posix() for pkg in PACKAGES for p in (REPO / pkg).rglob("*.py")}
    assert tree - listed == set(), f"modules missing from docs/architecture.md: {sorted(tree - listed)}"
    assert listed - tree == set(), f"docs/architecture.md lists modules that do not exist: {sorted(listed - tree)}"
