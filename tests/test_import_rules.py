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

from import_graph import LAYERS, REPO, Import, cycles, graph, imports, modules

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


def test_cycle_finder_finds_a_circle_of_three_and_no_more():
    edges = {"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}, "e": set()}
    assert cycles(edges) == [["a", "b", "c"]]


def test_no_import_circles():
    edges = graph()
    lines = []
    for comp in cycles(edges):
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
