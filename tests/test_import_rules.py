"""The import rules of ``photomodel/``, ``tracking/`` and ``app/``, read from the source with :mod:`ast`.

(a) Seams are public: no module imports another module's ``_private`` name (``from m import _x``,
    or ``m._x`` on an imported module).
(b) No import circles among the modules. Every import counts — at the top, inside a function, or
    under ``if TYPE_CHECKING:`` — so an import moved into a function to dodge a circle is still
    the circle it was.
(c) Imports run one way, ``app`` → ``tracking`` → ``photomodel``, and nothing below ``app/``
    imports Qt.
(d) Inside ``photomodel/`` the subpackages (and top-level modules) stand in the order
    :data:`PHOTOMODEL_ORDER`: each imports only those on lower levels — no import circle between
    two subpackages even when their modules form none.
"""

from __future__ import annotations

import ast
from dataclasses import dataclass
from functools import cache
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
#: The packages, lowest first: each may import only those before it and itself.
LAYERS = ("photomodel", "tracking", "app")
#: ``photomodel``'s subpackages and top-level modules in levels, lowest first: each may import only
#: those on lower levels (and itself), not those on its own level. Written out in
#: ``docs/architecture.md``.
PHOTOMODEL_ORDER = (
    ("camera", "errors"),  # conventions and exceptions
    ("data", "alignment", "rendering"),  # cache, fetch, array files; similarity transforms; the one renderer
    ("exchange", "closest_points"),  # file formats (a format per module, one atomic writer); closest points
    ("project", "modeling"),  # the project's data model and file; cameras, RBF, refinement
    ("rig", "landmarks"),  # the ARKit rig from ICT-FaceKit; automatic landmarks
    ("photos", "prior", "people"),  # photos and stills into a project; the face prior; the multilinear people model
    ("texturing",),  # the texture of a fitted expression, stored with the project
)
#: Left out of the order: ``samples`` (tests, benchmarks, the sample project and the ``sample-data``
#: command only: tests/test_samples_boundary.py keeps runtime code from importing it).
UNORDERED = ("samples",)
QT_PACKAGES = ("PySide6", "PySide2", "PyQt5", "PyQt6", "shiboken6", "qtpy")


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


def _known(name: str) -> str | None:
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
                target = _known(alias.name)
                if target is None:
                    continue
                out.append(Import(module, target, node.lineno))
                if alias.asname:
                    bound[alias.asname] = target
                else:
                    parts = alias.name.split(".")
                    for i in range(1, len(parts) + 1):
                        if (m := _known(".".join(parts[:i]))) == ".".join(parts[:i]):
                            bound[m] = m
        elif isinstance(node, ast.ImportFrom):
            base = _absolute(module, is_init, node)
            for alias in node.names:
                full = f"{base}.{alias.name}"
                if full in modules():  # a submodule
                    out.append(Import(module, full, node.lineno))
                    bound[alias.asname or alias.name] = full
                elif (target := _known(base)) is not None:
                    out.append(Import(module, target, node.lineno, alias.name))
    for node in ast.walk(tree):  # m._x on an imported module m
        if isinstance(node, ast.Attribute) and node.attr.startswith("_"):
            target = bound.get(ast.unparse(node.value))
            if target is not None:
                out.append(Import(module, target, node.lineno, node.attr))
    return tuple(out)


def _private(name: str | None) -> bool:
    return name is not None and name.startswith("_") and not name.startswith("__")


def _where(imp: Import) -> str:
    return f"{modules()[imp.module][0].relative_to(REPO)}:{imp.line}"


def test_the_modules_are_found():
    mods = modules()
    assert {"photomodel.camera", "tracking.frame_fit", "app.studio_state"} <= set(mods)
    assert any(i.target == "photomodel.camera" for i in imports("tracking.frame_fit"))


def test_no_module_imports_another_modules_private_name():
    bad = [
        f"{_where(i)}: {i.module} takes {i.name} from {i.target}"
        for m in modules()
        for i in imports(m)
        if _private(i.name) and i.target != m
    ]
    assert bad == [], "private names imported across modules (give them a public name):\n" + "\n".join(bad)


def _cycles(edges: dict[str, set[str]]) -> list[list[str]]:
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


def test_cycle_finder_finds_a_circle_of_three_and_no_more():
    edges = {"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}, "e": set()}
    assert _cycles(edges) == [["a", "b", "c"]]


def test_no_import_circles():
    edges = {m: {i.target for i in imports(m) if i.target != m} for m in modules()}
    lines = []
    for comp in _cycles(edges):
        inside = set(comp)
        links = [f"    {_where(i)}: {i.module} → {i.target}" for m in comp for i in imports(m) if i.target in inside]
        lines.append(f"circle of {len(comp)}: {', '.join(comp)}\n" + "\n".join(sorted(set(links))))
    assert lines == [], "import circles:\n" + "\n".join(lines)


def test_imports_run_app_tracking_photomodel_and_no_qt_below_app():
    rank = {pkg: k for k, pkg in enumerate(LAYERS)}
    upward = [
        f"{_where(i)}: {i.module} imports {i.target}"
        for m in modules()
        for i in imports(m)
        if rank[i.target.split(".")[0]] > rank[m.split(".")[0]]
    ]
    assert upward == [], "imports against app → tracking → photomodel:\n" + "\n".join(upward)
    qt = []
    for m, (path, _) in modules().items():
        if m.split(".")[0] == "app":
            continue
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            names = (
                [a.name for a in node.names]
                if isinstance(node, ast.Import)
                else [node.module or ""]
                if isinstance(node, ast.ImportFrom) and not node.level
                else []
            )
            qt += [f"{path.relative_to(REPO)}:{node.lineno}: {n}" for n in names if n.split(".")[0] in QT_PACKAGES]
    assert qt == [], "Qt imported below app/:\n" + "\n".join(qt)


def _photomodel_part(module: str) -> str | None:
    """The subpackage or top-level module of ``photomodel`` that ``module`` is in (None: the root)."""
    parts = module.split(".")
    return parts[1] if parts[0] == "photomodel" and len(parts) > 1 else None


def test_photomodel_subpackages_stand_in_their_order():
    level = {part: k for k, parts in enumerate(PHOTOMODEL_ORDER) for part in parts}
    found = {_photomodel_part(m) for m in modules()} - {None, *UNORDERED}
    assert found == set(level), f"photomodel's parts not in PHOTOMODEL_ORDER: {sorted(found ^ set(level))}"
    back = []
    for m in modules():
        a = _photomodel_part(m)
        if a is None or a in UNORDERED:
            continue
        for i in imports(m):
            b = _photomodel_part(i.target)
            if b is None or b == a or b in UNORDERED:
                continue
            if level[b] >= level[a]:
                back.append(f"{_where(i)}: {i.module} ({a}, level {level[a]}) imports {i.target} (level {level[b]})")
    assert back == [], "imports against photomodel's order (PHOTOMODEL_ORDER):\n" + "\n".join(sorted(set(back)))
