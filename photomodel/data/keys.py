"""Cache keys made from the code that builds a result and from its inputs (:func:`code_key`).

A cached result is valid only for the code that made it. A hand-bumped version constant forgets
to change (and a test that reads the cache then passes with the builder broken), so the key is a
hash of the code itself:

* **the code**: the module file of each builder given, and transitively every first-party module
  (:data:`FIRST_PARTY`) it imports — at module top, inside functions or for type checking alike —
  with their parent packages. Each file counts as its syntax tree without docstrings
  (:func:`ast.dump`), so comments, docstrings and formatting do not change a key but any change of
  what the code does does. This is coarser than the functions themselves: an edit anywhere in a
  module the builder imports, even of a function it never calls, makes the result again.
* **the inputs** the caller names: arrays (dtype, shape, bytes), bytes, strings, numbers, files
  (by content) and lists, tuples and dicts of them;
* optionally the installed **versions of third-party packages** whose numerics move the result.

Keys are 16 hex digits (64 bits of SHA-256). Parsing is remembered per file (path, size and
modification time), so a key costs a ``stat`` per module after the first.
"""

from __future__ import annotations

import ast
import hashlib
import importlib.metadata
import sys
import types
from collections.abc import Iterable, Mapping
from functools import cache
from pathlib import Path

import numpy as np

#: Top-level packages whose modules count as the code of a result.
FIRST_PARTY = ("photomodel", "tracking", "app")
#: The folder holding the first-party packages.
ROOT = Path(__file__).resolve().parents[2]

_KEY_SALT = b"facestudio code key 1"
#: path -> (mtime_ns, size, digest of the docstring-free tree, first-party modules it imports)
_PARSED: dict[Path, tuple[int, int, str, frozenset[str]]] = {}


def code_key(*code, inputs: Iterable = (), packages: Iterable[str] = ()) -> str:
    """A 16-hex-digit key of the code that builds a result and of its inputs.

    Parameters
    ----------
    *code : functions, classes, modules or dotted module names
        the builders; each stands for its module and that module's first-party imports,
        transitively (see the module notes and :func:`code_modules`).
    inputs : iterable
        what the result is made from: numpy arrays, bytes, str, int, float, bool, None,
        :class:`~pathlib.Path` (the file's bytes), and lists, tuples and dicts of these.
    packages : iterable of str
        import names (``"numpy"``, ``"cv2"``) of third-party packages whose installed versions
        are part of the key.

    Returns
    -------
    str
        16 lowercase hex digits.
    """
    h = hashlib.sha256(_KEY_SALT)
    for name in code_modules(*code):
        h.update(f"\0module {name} ".encode())
        h.update(_parse(_file_of(name))[2].encode())
    for name in sorted(set(packages)):
        h.update(f"\0package {name}=={_version(name)}".encode())
    h.update(b"\0inputs")
    _feed(h, list(inputs))
    return h.hexdigest()[:16]


def code_modules(*code) -> list[str]:
    """The sorted dotted names of the modules whose source :func:`code_key` hashes for ``code``."""
    names = [_module_name(c) for c in code]
    todo = [".".join(n.split(".")[:i]) for n in names for i in range(1, n.count(".") + 2)]  # with parents
    seen: set[str] = set()
    while todo:
        name = todo.pop()
        if name in seen:
            continue
        if _file_of(name) is None:
            raise ValueError(f"{name!r} is not a module of {', '.join(FIRST_PARTY)} under {ROOT}")
        seen.add(name)
        todo.extend(_parse(_file_of(name))[3] - seen)
    return sorted(seen)


def _module_name(code) -> str:
    if isinstance(code, str):
        name = code
    elif isinstance(code, types.ModuleType):
        name = code.__name__
    else:
        name = getattr(code, "__module__", None)
        if not isinstance(name, str):
            raise TypeError(f"code_key takes functions, classes, modules or module names, got {code!r}")
    if name == "__main__":  # a module run with ``python -m``: its importable name
        spec = getattr(sys.modules.get("__main__"), "__spec__", None)
        name = spec.name if spec is not None else name
    return name


def _file_of(name: str) -> Path | None:
    """The source file of first-party module ``name`` (a package's ``__init__.py``), or None."""
    parts = name.split(".")
    if parts[0] not in FIRST_PARTY:
        return None
    base = ROOT.joinpath(*parts)
    for path in (base.with_suffix(".py"), base / "__init__.py"):
        if path.is_file():
            return path
    return None


def _parse(path: Path) -> tuple[int, int, str, frozenset[str]]:
    stat = path.stat()
    known = _PARSED.get(path)
    if known is not None and known[:2] == (stat.st_mtime_ns, stat.st_size):
        return known
    tree = ast.parse(path.read_bytes(), filename=str(path))
    imports = _first_party_imports(tree, _package_of(path))
    _strip_docstrings(tree)
    digest = hashlib.sha256(ast.dump(tree).encode()).hexdigest()
    _PARSED[path] = (stat.st_mtime_ns, stat.st_size, digest, frozenset(imports))
    return _PARSED[path]


def _package_of(path: Path) -> str:
    """The dotted package a file's relative imports start from."""
    parts = path.relative_to(ROOT).with_suffix("").parts
    return ".".join(parts[:-1])


def _first_party_imports(tree: ast.Module, package: str) -> set[str]:
    """First-party modules a file imports, with their parent packages (which the import runs)."""
    named: set[str] = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            named.update(alias.name for alias in node.names)
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                anchor = package.split(".")[: len(package.split(".")) - (node.level - 1)]
                base = ".".join(anchor + ([node.module] if node.module else []))
            else:
                base = node.module or ""
            named.add(base)
            named.update(f"{base}.{alias.name}" for alias in node.names)  # submodules imported by name
    found = set()
    for name in named:
        parts = name.split(".")
        for i in range(1, len(parts) + 1):
            prefix = ".".join(parts[:i])
            if _file_of(prefix) is not None:
                found.add(prefix)
    return found


def _strip_docstrings(tree: ast.Module) -> None:
    for node in ast.walk(tree):
        if isinstance(node, (ast.Module, ast.ClassDef, ast.FunctionDef, ast.AsyncFunctionDef)):
            body = node.body
            if body and isinstance(body[0], ast.Expr) and isinstance(body[0].value, ast.Constant):
                if isinstance(body[0].value.value, str):
                    node.body = body[1:] or [ast.Pass()]


@cache
def _version(import_name: str) -> str:
    dists = importlib.metadata.packages_distributions().get(import_name, [import_name])
    versions = []
    for dist in sorted(set(dists)):
        try:
            versions.append(f"{dist} {importlib.metadata.version(dist)}")
        except importlib.metadata.PackageNotFoundError:
            versions.append(f"{dist} absent")
    return ", ".join(versions)


def _feed(h, value) -> None:
    """Add ``value`` to hash ``h``, tagged by kind so that different values never feed alike."""
    if isinstance(value, np.ndarray | np.generic):
        a = np.ascontiguousarray(value)
        h.update(f"\0array {a.dtype.str} {a.shape}\0".encode())
        h.update(a.tobytes())
    elif isinstance(value, bytes | bytearray | memoryview):
        h.update(f"\0bytes {len(value)}\0".encode())
        h.update(value)
    elif isinstance(value, str):
        h.update(f"\0str {len(value)}\0".encode())
        h.update(value.encode())
    elif value is None or isinstance(value, bool | int | float):
        h.update(f"\0{type(value).__name__} {value!r}".encode())
    elif isinstance(value, Path):
        h.update(f"\0file {value.stat().st_size}\0".encode())
        with open(value, "rb") as f:
            for block in iter(lambda: f.read(1 << 20), b""):
                h.update(block)
    elif isinstance(value, Mapping):
        h.update(f"\0dict {len(value)}".encode())
        for k in sorted(value, key=repr):
            _feed(h, k)
            _feed(h, value[k])
    elif isinstance(value, list | tuple):
        h.update(f"\0{type(value).__name__} {len(value)}".encode())
        for v in value:
            _feed(h, v)
    else:
        raise TypeError(
            f"cannot key an input of type {type(value).__name__}: pass arrays, bytes, str, numbers or paths"
        )
