"""Check that no cache stands in for the code: break each builder whose output the suite caches and run
the test file that claims to test it, with the cache as it is (warm, as on a developer's machine).

``python tools/break_builders.py [NAME ...]`` makes the builder's first statement
``raise RuntimeError(...)`` in the source, runs its test file, puts the source back and prints the
tests that failed; a builder whose test file still passes is reported as ``NOT CAUGHT`` and the exit
status is 1. The results are written up in docs/testing.md. Run it with the cache warm (run the test
files once first) and a clean work tree: it edits the files in place (and restores them).
"""

from __future__ import annotations

import ast
import os
import re
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
#: (source file, builder, the test file that claims to test it)
CASES = (
    ("photomodel/data/menpo3d.py", "template_arrays", "tests/test_menpo3d.py"),
    ("photomodel/samples/sample_data.py", "james_arrays", "tests/test_sample_data.py"),
    ("photomodel/modeling/generic_mesh.py", "build_generic_mesh_arrays", "tests/test_generic_mesh.py"),
    ("photomodel/samples/synthetic.py", "build_correspondence", "tests/test_synthetic.py"),
    ("photomodel/rig/registration.py", "register_ict", "tests/test_rig.py"),
    ("photomodel/samples/fitted_sample.py", "make_fitted_sample", "tests/test_fitted_sample.py"),
    ("photomodel/modeling/fit.py", "fit_expression", "tests/test_face_from_project.py"),
    ("photomodel/modeling/fit.py", "fit_expression", "tests/test_fitted_sample.py"),
    ("photomodel/samples/real_clip.py", "real_sample_project", "tests/test_real_clip.py"),
)


def broken_source(source: str, name: str) -> str:
    """``source`` with ``raise RuntimeError`` as the first statement of function ``name``."""
    node = next(n for n in ast.walk(ast.parse(source)) if isinstance(n, ast.FunctionDef) and n.name == name)
    first = node.body[0]
    lines = source.splitlines(keepends=True)
    lines.insert(first.lineno - 1, " " * first.col_offset + f'raise RuntimeError("{name} broken on purpose")\n')
    return "".join(lines)


def main(argv: list[str]) -> int:
    env = dict(os.environ, PYTHONPATH=str(ROOT), QT_QPA_PLATFORM="offscreen")
    missed = 0
    for path, name, test in CASES:
        if argv and name not in argv:
            continue
        file = ROOT / path
        original = file.read_text()
        file.write_text(broken_source(original, name))
        try:
            run = subprocess.run(
                [sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider", "-rfE", test],
                cwd=ROOT,
                env=env,
                capture_output=True,
                text=True,
            )
        finally:
            file.write_text(original)
        failing = re.findall(r"^(?:FAILED|ERROR) (\S+)", run.stdout, flags=re.M)
        missed += not failing
        print(f"{name} ({path}) -> {test}: {'NOT CAUGHT' if not failing else f'{len(failing)} failing'}")
        for t in failing:
            print(f"    {t}")
    return 1 if missed else 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
