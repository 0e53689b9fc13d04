"""The first-party import graph read from the source (every import, at module top or inside a
function, ``TYPE_CHECKING`` ones too), for the tests of the import rules
(``tests/test_import_rules.py``) and of the samples' boundary (``tests/test_samples_boundary.py``)."""

from __future__ import annotations

import ast
from dataclasses import dataclass
from functools import cache
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
#: The packages, lowest first: each may import only those before it and itself.
LAYERS = ("photomodel", "tracking", "app")


@dataclass(frozen=True)
class Import:
    """One imported module (``target``) of ``module``, at ``line``; ``name`` the name taken from it
    (``from target import name``, or ``target.name`` on the module), None for the module itself."""

    module: str
    target: str
    line: int
    name: str | None = None


@cache
def modules() -> dict[str, tuple[Path, bool]]:
    """{dotted module name: (file, is a package's ``__init__``)} of the three packages."""
    out = {}
    for pkg in LAYERS:
        for path in sorted((REPO / pkg).rglob("*.py")):
            parts = list(path.relative_to(REPO).with_suffix("").parts)
            is_init = parts[-1] == "__init__"
            out[".".join(parts[:-1] if is_init else parts)] = (path, is_init)
    return out


def known_module(name: str) -> str | None:
    """The longest prefix of dotted ``name`` that is one of our modules (None: not ours)."""
    mods = modules()
    while name and name not in mods:
        name = name.rpartition(".")[0]
    return name or None


def _absolute(module: str, is_init: bool, node: ast.ImportFrom) -> str:
    if not node.level:
        return node.module or ""
    base = module.split(".") if is_init else module.split(".")[:-1]
    base = base[: len(base) - (node.level - 1)]
    return ".".join(base + ([node.module] if node.module else []))


@cache
def imports(module: str) -> tuple[Import, ...]:
    """Everything ``module`` imports from the three packages, and every ``_name`` it takes from them."""
    path, is_init = modules()[module]
    tree = ast.parse(path.read_text(encoding="utf-8"), str(path))
    out: list[Import] = []
    bound: dict[str, str] = {}  # local name or dotted chain → our module it stands for
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            for alias in node.names:
                target = known_module(alias.name)
                if target is None:
                    continue
                out.append(Import(module, target, node.lineno))
                if alias.asname:
                    bound[alias.asname] = target
                else:
                    parts = alias.name.split(".")
                    for i in range(1, len(parts) + 1):
                        if (m := known_module(".".join(parts[:i]))) == ".".join(parts[:i]):
                            bound[m] = m
        elif isinstance(node, ast.ImportFrom):
            base = _absolute(module, is_init, node)
            for alias in node.names:
                full = f"{base}.{alias.name}"
                if full in modules():  # a submodule
                    out.append(Import(module, full, node.lineno))
                    bound[alias.asname or alias.name] = full
                elif (target := known_module(base)) is not None:
                    out.append(Import(module, target, node.lineno, alias.name))
    for node in ast.walk(tree):  # m._x on an imported module m
        if isinstance(node, ast.Attribute) and node.attr.startswith("_"):
            target = bound.get(ast.unparse(node.value))
            if target is not None:
                out.append(Import(module, target, node.lineno, node.attr))
    return tuple(out)


def graph() -> dict[str, set[str]]:
    """Module → the other first-party modules it imports."""
    return {m: {i.target for i in imports(m) if i.target != m} for m in modules()}


def cycles(edges: dict[str, set[str]]) -> list[list[str]]:
    """The strongly connected components of more than one module (Tarjan, iterative)."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    found = []
    for root in sorted(edges):
        if root in index:
            continue
        work = [(root, iter(sorted(edges[root])))]
        index[root] = low[root] = len(index)
        stack.append(root)
        on_stack.add(root)
        while work:
            v, it = work[-1]
            w = next(it, None)
            if w is not None:
                if w not in index:
                    index[w] = low[w] = len(index)
                    stack.append(w)
                    on_stack.add(w)
                    work.append((w, iter(sorted(edges[w]))))
                elif w in on_stack:
                    low[v] = min(low[v], index[w])
                continue
            work.pop()
            if work:
                low[work[-1][0]] = min(low[work[-1][0]], low[v])
            if low[v] == index[v]:
                comp = []
                while True:
                    w = stack.pop()
                    on_stack.discard(w)
                    comp.append(w)
                    if w == v:
                        break
                if len(comp) > 1:
                    found.append(sorted(comp))
    return found
