"""How a project problem is worded: JSON paths, value excerpts, listings, "did you mean".

Every :class:`~photomodel.errors.ProjectError` about a project names the file and the JSON path
of the culprit, e.g. ``james.facestudio.json: expressions[0].photos[2].points.nose_tip: expected
[u, v] of two finite numbers, got [12.0]``; a check that finds several problems reports them
together (:func:`problems_error`).
"""

from __future__ import annotations

import difflib
import json
import re
from collections.abc import Iterable, Sequence

from photomodel.errors import ProjectError

#: At most this many problems are listed in one message (the rest are counted).
MAX_LISTED_PROBLEMS = 10

_IDENT = re.compile(r"^[A-Za-z_][A-Za-z0-9_-]*$")


def fmt_key(k) -> str:
    """One step of a JSON path: ``[3]``, ``.name`` or ``["left eye"]``."""
    if isinstance(k, int):
        return f"[{k}]"
    return f".{k}" if _IDENT.match(k) else f"[{json.dumps(k, ensure_ascii=False)}]"


def fmt_path(path) -> str:
    """``("expressions", 0, "photos")`` → ``expressions[0].photos`` ("(top level)" if empty)."""
    s = "".join(fmt_key(k) for k in path).lstrip(".")
    return s or "(top level)"


def short(value, limit: int = 80) -> str:
    """``value`` as JSON text, cut to ``limit`` characters (its repr if it is not JSON-able)."""
    try:
        s = json.dumps(value, ensure_ascii=False)
    except (TypeError, ValueError):
        s = repr(value)
    return s if len(s) <= limit else s[: limit - 3] + "..."


def listing(names: Iterable[str]) -> str:
    """``'a', 'b'`` (``(none)`` for no names)."""
    names = list(names)
    return ", ".join(repr(n) for n in names) if names else "(none)"


def did_you_mean(name: str, candidates: Sequence[str]) -> str:
    """`` (did you mean 'x'?)`` for the closest candidate, or ``""``."""
    close = difflib.get_close_matches(name, list(candidates), n=1, cutoff=0.6)
    return f" (did you mean {close[0]!r}?)" if close else ""


def problems_error(source: str, problems: list[tuple[str, str]]) -> ProjectError:
    """One ProjectError for a list of (path, message); ``.problems`` keeps the list."""
    if len(problems) == 1:
        msg = f"{source}: {problems[0][0]}: {problems[0][1]}"
    else:
        lines = [f"  {p}: {m}" for p, m in problems[:MAX_LISTED_PROBLEMS]]
        if len(problems) > MAX_LISTED_PROBLEMS:
            lines.append(f"  ... and {len(problems) - MAX_LISTED_PROBLEMS} more")
        msg = f"{source}: {len(problems)} problems:\n" + "\n".join(lines)
    exc = ProjectError(msg)
    exc.problems = list(problems)
    return exc
