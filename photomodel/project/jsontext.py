"""The project file as JSON text: strict parsing and the readable, deterministic writer.

Parsing is step 1 of the checks of :func:`photomodel.project.io.load_project`: JSON syntax (line
and column), duplicate object keys, the ``NaN``/``Infinity`` literals that Python's :mod:`json`
accepts but JSON does not, numbers (integers too) beyond what a double holds, and nesting deeper
than :data:`MAX_DEPTH` (each reported with its JSON path). Whatever passes can be walked by the
recursive code downstream (the schema check, :func:`plain`, the writer) without a
``RecursionError`` and turned into floats without an ``OverflowError``. Writing puts a click on
one line (``"nose_tip": [512.3, 601.8]``) and a rotation on three, so the file diffs well.
"""

from __future__ import annotations

import json
import math

from photomodel.errors import ProjectError
from photomodel.project.problems import fmt_path, problems_error

_INLINE_DICT_WIDTH = 100
#: The deepest nesting of objects and lists a project file may have. The format itself is at
#: most 9 deep (a texture report's cylinder inside a result); free-form reports add a few more.
#: A limit far below Python's recursion limit keeps every recursive walk of the tree safe.
MAX_DEPTH = 64
#: Decimal digits beyond which an integer literal may exceed a double (~1.8e308); checked exactly.
_LONG_INT_DIGITS = 300


# ---------------------------------------------------------------------------------------
# parsing
# ---------------------------------------------------------------------------------------
class _NonFinite:
    """Placeholder for a NaN/Infinity literal (or an overflowing number) found while parsing."""

    def __init__(self, literal: str):
        self.literal = literal

    def message(self) -> str:
        if self.literal.lstrip("-") in ("NaN", "Infinity", "nan", "inf"):
            return (
                f"{self.literal} is not a finite number (JSON has no NaN or Infinity); remove the "
                f"value or use null where allowed"
            )
        return f"{_excerpt(self.literal)} is not a finite number: too large for a double (at most about 1.8e308)"


def _excerpt(literal: str, limit: int = 24) -> str:
    return literal if len(literal) <= limit else f"{literal[:12]}...{literal[-6:]} ({len(literal)} characters)"


class _KeyedDict(dict):
    """A JSON object that remembers keys it saw more than once."""

    duplicates: tuple = ()


def _object_pairs(pairs):
    d = _KeyedDict()
    dups = []
    for k, v in pairs:
        if k in d and k not in dups:
            dups.append(k)
        d[k] = v
    d.duplicates = tuple(dups)
    return d


def parse_json(text: str, source: str):
    """The parsed JSON of ``text``; ProjectError (naming ``source``) for invalid JSON, a
    repeated key or a non-finite number."""
    suspect = False  # set by the hooks, so that a clean file skips the tree scan

    def constant(literal: str):
        nonlocal suspect
        suspect = True
        return _NonFinite(literal)

    def number(literal: str):
        x = float(literal)
        return x if math.isfinite(x) else constant(literal)

    def integer(literal: str):
        x = int(literal)
        if len(literal) > _LONG_INT_DIGITS:
            try:
                float(x)
            except OverflowError:
                return constant(literal)
        return x

    def pairs(items):
        nonlocal suspect
        d = _object_pairs(items)
        suspect = suspect or bool(d.duplicates)
        return d

    try:
        data = json.loads(text, parse_constant=constant, parse_float=number, parse_int=integer, object_pairs_hook=pairs)
    except json.JSONDecodeError as exc:
        raise ProjectError(f"{source}: not valid JSON: {exc.msg} (line {exc.lineno}, column {exc.colno})") from None
    except RecursionError:  # the C parser's guard: thousands of nested [ or {
        raise ProjectError(
            f"{source}: objects or lists nested too deeply (more than {MAX_DEPTH} levels; "
            f"a project file is at most a dozen deep)"
        ) from None
    check_depth(data, source)
    if suspect:
        problems = scan_parsed(data)
        if problems:
            raise problems_error(source, problems)
    return data


def check_depth(node, source: str) -> None:
    """ProjectError naming the path where ``node`` nests objects/lists deeper than :data:`MAX_DEPTH`.

    Level by level, without recursion, so that it is itself safe on any depth (4 ms on the
    sample project)."""
    level, depth = [node], 0
    while level:
        depth += 1
        if depth > MAX_DEPTH:
            raise ProjectError(
                f"{source}: {fmt_path(_deep_path(node))}: objects or lists nested too "
                f"deeply (more than {MAX_DEPTH} levels; a project file is at most a dozen deep)"
            )
        nested = []
        for item in level:
            for v in item if type(item) is list else item.values():
                if type(v) is list or isinstance(v, dict):
                    nested.append(v)
        level = nested


def _deep_path(node) -> tuple:
    """The first :data:`MAX_DEPTH` steps of a path into ``node`` that goes deepest."""
    path: list = []
    while isinstance(node, (dict, list)) and node and len(path) < MAX_DEPTH:
        keys = node.keys() if isinstance(node, dict) else range(len(node))
        key = max(keys, key=lambda k: _depth_at_most(node[k], MAX_DEPTH - len(path)))
        path.append(key)
        node = node[key]
    return tuple(path)


def _depth_at_most(node, limit: int) -> int:
    """min(nesting depth of ``node``, ``limit``), iteratively."""
    best, stack = 0, [(node, 0)]
    while stack and best < limit:
        item, depth = stack.pop()
        if isinstance(item, (dict, list)):
            best = max(best, depth + 1)
            stack.extend((v, depth + 1) for v in (item.values() if isinstance(item, dict) else item))
    return best


def scan_parsed(node, path: tuple = ()) -> list[tuple[str, str]]:
    """NaN/Infinity literals (or non-finite floats) and repeated keys in a JSON tree; (path,
    message) each."""
    problems: list[tuple[str, str]] = []
    _scan(node, path, problems)
    return problems


def _scan(node, path: tuple, problems: list) -> None:
    if isinstance(node, float) and not math.isfinite(node):
        node = _NonFinite(repr(node))
    if isinstance(node, _NonFinite):
        problems.append((fmt_path(path), node.message()))
    elif isinstance(node, dict):
        for k in getattr(node, "duplicates", ()):
            problems.append((fmt_path(path), f"key {k!r} appears more than once"))
        for k, v in node.items():
            _scan(v, (*path, k), problems)
    elif isinstance(node, list):
        for i, v in enumerate(node):
            _scan(v, (*path, i), problems)


def plain(node):
    """Parsed JSON with the parse-time helper types replaced by plain dicts."""
    if isinstance(node, dict):
        return {k: plain(v) for k, v in node.items()}
    if isinstance(node, list):
        return [plain(v) for v in node]
    return node


# ---------------------------------------------------------------------------------------
# writing
# ---------------------------------------------------------------------------------------
def dumps(node, level: int = 0) -> str:
    """Readable, deterministic JSON: 2-space indent, lists of numbers and small flat objects on
    one line (a click is ``"nose_tip": [512.3, 601.8]``, a rotation is three rows)."""
    pad, pad1 = "  " * level, "  " * (level + 1)
    if isinstance(node, dict):
        if not node:
            return "{}"
        if all(not isinstance(v, (dict, list)) for v in node.values()):
            inline = (
                "{" + ", ".join(f"{json.dumps(k, ensure_ascii=False)}: {_scalar(v)}" for k, v in node.items()) + "}"
            )
            if len(inline) + len(pad1) <= _INLINE_DICT_WIDTH:
                return inline
        items = [f"{pad1}{json.dumps(k, ensure_ascii=False)}: {dumps(v, level + 1)}" for k, v in node.items()]
        return "{\n" + ",\n".join(items) + "\n" + pad + "}"
    if isinstance(node, list):
        if not node:
            return "[]"
        if all(not isinstance(v, (dict, list)) for v in node):
            return "[" + ", ".join(_scalar(v) for v in node) + "]"
        return "[\n" + ",\n".join(pad1 + dumps(v, level + 1) for v in node) + "\n" + pad + "]"
    return _scalar(node)


def _scalar(v) -> str:
    # same text as json.dumps (floats use repr, the shortest round-tripping form), but ~5x faster
    if type(v) is float:
        if not math.isfinite(v):
            raise ValueError(f"non-finite number {v!r} cannot be written to JSON")
        return repr(v)
    if v is True:
        return "true"
    if v is False:
        return "false"
    if v is None:
        return "null"
    if type(v) is int:
        return str(v)
    return json.dumps(v, ensure_ascii=False, allow_nan=False)
