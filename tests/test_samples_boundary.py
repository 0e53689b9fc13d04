"""The samples stay beside the program, not under it: ``photomodel/samples/`` (and tracking's own samples,
``tracking/synthetic_sequences/``) are imported by tests, benchmarks, the sample project and the
``sample-data`` command only; the data floor (``photomodel/data/``) imports nothing above it; no import
circle passes through the samples. Read from the source (every import, at module top or inside a
function), not from what a test run happened to import."""

from __future__ import annotations

import ast
from functools import cache
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
PACKAGES = ("photomodel", "tracking", "app")
SAMPLES = ("photomodel.samples", "tracking.synthetic_sequences")


def _module_name(path: Path) -> str:
    parts = path.relative_to(REPO).with_suffix("").parts
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def _is_module(name: str) -> bool:
    base = REPO.joinpath(*name.split("."))
    return base.with_suffix(".py").is_file() or (base / "__init__.py").is_file()


def _imports(path: Path) -> set[str]:
    """The first-party modules a file imports (``from pkg import mod`` names ``pkg.mod``)."""
    tree = ast.parse(path.read_text(encoding="utf-8"))
    package = _module_name(path) if path.name == "__init__.py" else _module_name(path).rpartition(".")[0]
    found = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            names = [a.name for a in node.names]
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                anchor = package.split(".")[: len(package.split(".")) - (node.level - 1)]
                base = ".".join([*anchor, *([node.module] if node.module else [])])
            names = [base, *(f"{base}.{a.name}" for a in node.names)]
        else:
            continue
        found.update(n for n in names if n.split(".")[0] in PACKAGES and _is_module(n))
    return found


@cache
def _graph() -> dict[str, set[str]]:
    """Module → the first-party modules it imports, for the whole tree (read once per run; do not change it)."""
    files = [p for pkg in PACKAGES for p in sorted((REPO / pkg).rglob("*.py"))]
    return {_module_name(p): _imports(p) for p in files}


def _in(name: str, packages) -> bool:
    return any(name == p or name.startswith(p + ".") for p in packages)


def _is_sample_data_command(module: str, target: str) -> bool:
    """The ``facestudio sample-data`` command may import the sample data module (its folder is what
    the command prints): a module of the CLI (``app/cli.py``, or the ``app/cli/`` package and its
    command modules once the CLI is split) or one whose name or source names the command."""
    if target not in ("photomodel.samples", "photomodel.samples.sample_data") or not module.startswith("app"):
        return False
    base = REPO.joinpath(*module.split("."))
    path = base.with_suffix(".py") if base.with_suffix(".py").is_file() else base / "__init__.py"
    return (
        module == "app.cli"
        or module.startswith("app.cli.")
        or "sample_data" in module
        or '"sample-data"' in path.read_text(encoding="utf-8")
    )


def test_only_the_samples_and_the_sample_data_command_import_the_samples():
    wrong = []
    for module, imported in _graph().items():
        for target in sorted(imported):
            if not _in(target, SAMPLES) or _in(module, SAMPLES):
                continue
            if _is_sample_data_command(module, target):
                continue
            wrong.append(f"{module} imports {target}")
    assert wrong == [], "the program imports the samples (move what it needs to photomodel/data):\n" + "\n".join(wrong)


def test_the_data_floor_imports_nothing_above_it():
    allowed = ("photomodel.data", "photomodel.errors")
    wrong = [
        f"{module} imports {target}"
        for module, imported in _graph().items()
        if _in(module, ("photomodel.data",))
        for target in sorted(imported)
        if not _in(target, allowed) and target != "photomodel"
    ]
    assert wrong == []


def _rooms(graph: dict[str, set[str]]) -> dict[str, set[str]]:
    """The import graph between rooms (``photomodel.modeling``, ``photomodel.samples``, ``tracking.run``
    …: a module's first two name parts): modeling → samples → modeling is a circle of rooms even
    when no single module closes it."""

    def room(name: str) -> str:
        return ".".join(name.split(".")[:2])

    rooms: dict[str, set[str]] = {}
    for module, imported in graph.items():
        rooms.setdefault(room(module), set()).update(room(t) for t in imported if room(t) != room(module))
    return rooms


def test_no_import_circle_passes_through_the_samples():
    for graph in (_graph(), _rooms(_graph())):
        circles = [c for c in _strongly_connected(graph) if len(c) > 1 and any(_in(m, SAMPLES) for m in c)]
        assert circles == [], f"import circles through the samples: {circles}"


def _strongly_connected(graph: dict[str, set[str]]) -> list[list[str]]:
    """Tarjan's strongly connected components, iteratively (the graph is a few hundred modules)."""
    index, low, on_stack, stack, out = {}, {}, set(), [], []
    for root in graph:
        if root in index:
            continue
        work = [(root, iter(sorted(graph[root])))]
        index[root] = low[root] = len(index)
        stack.append(root)
        on_stack.add(root)
        while work:
            node, children = work[-1]
            child = next(children, None)
            if child is None:
                work.pop()
                if work:
                    low[work[-1][0]] = min(low[work[-1][0]], low[node])
                if low[node] == index[node]:
                    component = []
                    while True:
                        m = stack.pop()
                        on_stack.discard(m)
                        component.append(m)
                        if m == node:
                            break
                    out.append(sorted(component))
            elif child not in index:
                index[child] = low[child] = len(index)
                stack.append(child)
                on_stack.add(child)
                work.append((child, iter(sorted(graph.get(child, ())))))
            elif child in on_stack:
                low[node] = min(low[node], index[child])
    return out


def test_the_circle_finder_finds_circles():
    graph = {"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}, "e": set()}
    assert sorted(c for c in _strongly_connected(graph) if len(c) > 1) == [["a", "b", "c"]]
