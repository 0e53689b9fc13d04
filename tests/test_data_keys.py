"""Tests of photomodel.data.keys: a cache key follows the code that builds a result (transitively) and
its inputs, and nothing else."""

from __future__ import annotations

import importlib.machinery
import os
import sys
import types
from pathlib import Path

import numpy as np
import pytest

from photomodel.data import keys
from photomodel.data.keys import code_key, code_modules
from photomodel.modeling.generic_mesh import build_generic_mesh_arrays


@pytest.fixture
def package(tmp_path, monkeypatch):
    """A first-party package ``fakepkg`` in a temporary root: ``a`` imports ``b`` (inside a
    function), ``b`` imports ``c`` relatively; ``d`` stands alone. Returns ``write(name, text)``."""
    root = tmp_path / "root"
    (root / "fakepkg").mkdir(parents=True)
    monkeypatch.setattr(keys, "ROOT", root)
    monkeypatch.setattr(keys, "FIRST_PARTY", ("fakepkg",))
    stamp = [1_000_000_000]

    def write(name: str, text: str) -> Path:
        path = root / "fakepkg" / f"{name}.py"
        path.write_text(text)
        stamp[0] += 1_000_000_000  # a new modification time for every write, as an editor gives
        os.utime(path, ns=(stamp[0], stamp[0]))
        return path

    write("__init__", "")
    write("a", "import numpy\n\ndef build():\n    from fakepkg import b\n    return b.f()\n")
    write("b", "from . import c\n\ndef f():\n    return c.g() + 1\n")
    write("c", '"""C."""\n\ndef g():\n    return 1\n')
    write("d", "X = 1\n")
    return write


def test_the_code_is_the_builders_module_and_what_it_imports(package):
    assert code_modules("fakepkg.a") == ["fakepkg", "fakepkg.a", "fakepkg.b", "fakepkg.c"]
    assert code_modules("fakepkg.d") == ["fakepkg", "fakepkg.d"]
    with pytest.raises(ValueError, match="not a module"):
        code_modules("fakepkg.nowhere")


def test_a_change_of_an_imported_module_changes_the_key(package):
    before, other = code_key("fakepkg.a"), code_key("fakepkg.d")
    package("c", '"""C."""\n\ndef g():\n    return 2\n')  # two modules away
    assert code_key("fakepkg.a") != before
    assert code_key("fakepkg.d") == other  # a module that does not import it keeps its key


def test_comments_docstrings_and_layout_do_not_change_the_key(package):
    before = code_key("fakepkg.a")
    package(
        "c", '"""Another docstring,\n\nlonger."""\n\n\ndef g():  # a comment\n    """And here."""\n    return (1)\n'
    )
    assert code_key("fakepkg.a") == before


def test_inputs_and_package_versions_are_part_of_the_key(package, tmp_path):
    a = np.arange(6, dtype=np.int64)
    base = code_key("fakepkg.a", inputs=(a,))
    assert code_key("fakepkg.a", inputs=(a.copy(),)) == base
    assert code_key("fakepkg.a", inputs=(a.reshape(2, 3),)) != base  # same bytes, other shape
    assert code_key("fakepkg.a", inputs=(a.view(np.float64),)) != base  # same bytes, other dtype
    assert code_key("fakepkg.a", inputs=(a + 1,)) != base
    assert code_key("fakepkg.a", inputs=({"x": 1, "y": "2"},)) == code_key("fakepkg.a", inputs=({"y": "2", "x": 1},))
    assert code_key("fakepkg.a", inputs=("1",)) != code_key("fakepkg.a", inputs=(1,))
    f = tmp_path / "input.bin"
    f.write_bytes(b"one")
    one = code_key("fakepkg.a", inputs=(f,))
    f.write_bytes(b"two")
    assert code_key("fakepkg.a", inputs=(f,)) != one  # a file counts by its content
    assert code_key("fakepkg.a", packages=("numpy",)) != code_key("fakepkg.a")
    with pytest.raises(TypeError, match="cannot key"):
        code_key("fakepkg.a", inputs=(object(),))


def test_functions_stand_for_their_modules():
    """A builder of the real tree: the generic mesh's key covers its module, the template's loader
    (whose checksums fix the input files) and what they import, not the fit or tracking."""
    modules = code_modules(build_generic_mesh_arrays)
    assert {"photomodel.modeling.generic_mesh", "photomodel.data.menpo3d", "photomodel.data.keys"} <= set(modules)
    assert "photomodel.modeling.fit" not in modules and not any(m.startswith("tracking") for m in modules)
    assert code_key(build_generic_mesh_arrays) == code_key("photomodel.modeling.generic_mesh")
    assert len(code_key(build_generic_mesh_arrays)) == 16


def test_a_builder_run_as_a_script_keys_as_its_module(package, monkeypatch):
    """``python -m fakepkg.a`` runs the module as ``__main__``; its functions key as ``fakepkg.a``."""
    main = types.ModuleType("__main__")
    main.__spec__ = importlib.machinery.ModuleSpec("fakepkg.a", None)
    monkeypatch.setitem(sys.modules, "__main__", main)

    def build():
        pass

    build.__module__ = "__main__"
    assert code_key(build) == code_key("fakepkg.a")
