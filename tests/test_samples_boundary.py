"""The samples stay beside the program, not under it: ``photomodel/samples/`` (and tracking's own samples,
``tracking/synthetic_sequences/``) are imported by tests, benchmarks, the sample project and the
``sample-data`` command only; the data floor (``photomodel/data/``) imports nothing above it; no import
circle passes through the samples. Read from the source (every import, at module top or inside a
function), not from what a test run happened to import."""

from __future__ import annotations

from import_graph import REPO, cycles, graph

SAMPLES = ("photomodel.samples", "tracking.synthetic_sequences")


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
    for module, imported in graph().items():
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
        for module, imported in graph().items()
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
    for edges in (graph(), _rooms(graph())):
        circles = [c for c in cycles(edges) if len(c) > 1 and any(_in(m, SAMPLES) for m in c)]
        assert circles == [], f"import circles through the samples: {circles}"
