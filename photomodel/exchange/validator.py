"""The Khronos glTF validator on an exported ``.glb``, when it is installed.

``install.sh`` installs the npm package ``gltf-validator`` (pinned in
``tools/gltf-validator/package.json``) where npm exists; :func:`validate_glb` runs it through
``tools/gltf-validator/validate.js`` with Node and returns its report (``issues.numErrors`` …), or
``None`` when Node or the package is missing — callers then check the file with pygltflib alone.
"""

from __future__ import annotations

import json
import shutil
import subprocess
from pathlib import Path

__all__ = ["VALIDATOR_DIR", "validator_available", "validate_glb"]

VALIDATOR_DIR = Path(__file__).resolve().parents[2] / "tools" / "gltf-validator"


def validator_available() -> bool:
    """Node and the installed ``gltf-validator`` package are both there."""
    return shutil.which("node") is not None and (VALIDATOR_DIR / "node_modules" / "gltf-validator").is_dir()


def validate_glb(path: str | Path, timeout_s: float = 120.0) -> dict | None:
    """The validator's JSON report of ``path``, or None when the validator is not installed."""
    if not validator_available():
        return None
    run = subprocess.run(
        ["node", str(VALIDATOR_DIR / "validate.js"), str(Path(path).absolute())],
        capture_output=True,
        text=True,
        timeout=timeout_s,
        check=False,
    )
    if run.returncode != 0:
        raise RuntimeError(f"the glTF validator failed on {path}: {run.stderr.strip()}")
    return json.loads(run.stdout)
