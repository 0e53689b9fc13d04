"""No function over :data:`MAX_LINES` lines without the reason written beside it (issue 33, item 7).

A function's length runs from its ``def`` line to its last line, docstring included (how the issue
measured them). A long one is split into named steps; where it stays long for a reason (a long
numpy docstring over a short body, a table that reads better whole), a comment ``# long: <reason>``
on the ``def`` line or the line above says so.
"""

from __future__ import annotations

import ast
import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
#: The packages checked. tracking/ and app/ join when their long functions are split.
PACKAGES = ("photomodel", "tracking", "app")
MAX_LINES = 80
MARKER = re.compile(r"#\s*long:\s*\S")


def long_functions(packages=PACKAGES, max_lines: int = MAX_LINES, root: Path = ROOT) -> list[str]:
    """``"path:line name (n lines)"`` of every function over ``max_lines`` lines without a
    ``# long:`` reason, in ``packages`` (folders under ``root``)."""
    out = []
    for package in packages:
        for path in sorted((root / package).rglob("*.py")):
            text = path.read_text(encoding="utf-8")
            lines = text.splitlines()
            for node in ast.walk(ast.parse(text, filename=str(path))):
                if not isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
                    continue
                n = node.end_lineno - node.lineno + 1
                if n <= max_lines:
                    continue
                beside = lines[node.lineno - 1 : node.lineno] + lines[max(node.lineno - 2, 0) : node.lineno - 1]
                if not any(MARKER.search(line) for line in beside):
                    out.append(f"{path.relative_to(root).as_posix()}:{node.lineno} {node.name} ({n} lines)")
    return out


def test_no_long_function_without_a_reason():
    found = long_functions()
    assert not found, (
        f"functions over {MAX_LINES} lines: split them into named steps, or write why one stays long in a "
        "'# long: <reason>' comment on its def line or the line above:\n  " + "\n  ".join(found)
    )


def test_the_check_finds_a_long_function_and_honours_its_reason(tmp_path):
    body = "\n".join(f"    x = {i}" for i in range(MAX_LINES))  # with the def: one line over
    (tmp_path / "pkg").mkdir()
    (tmp_path / "pkg" / "mod.py").write_text(
        f"def unmarked():\n{body}\n\n\n"
        f"# long: a table that reads better whole\ndef marked_above():\n{body}\n\n\n"
        f"def marked_beside():  # long: one solve, its steps share ten arrays\n{body}\n\n\n"
        f"# long:\ndef no_reason():\n{body}\n\n\n"
        "def short():\n    return 1\n",
        encoding="utf-8",
    )
    found = long_functions(("pkg",), root=tmp_path)
    assert found == [
        f"pkg/mod.py:1 unmarked ({MAX_LINES + 1} lines)",
        f"pkg/mod.py:{3 * MAX_LINES + 12} no_reason ({MAX_LINES + 1} lines)",
    ]
