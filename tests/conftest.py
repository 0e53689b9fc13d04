"""Shared test set-up: Qt runs offscreen, rendering is headless EGL."""

import os
import shutil
import sys
from pathlib import Path

import pytest

os.environ.setdefault("QT_QPA_PLATFORM", "offscreen")

REPO = Path(__file__).resolve().parents[1]
# benchmarks/ holds the peer implementations that some tests compare against
if str(REPO / "benchmarks") not in sys.path:
    sys.path.insert(0, str(REPO / "benchmarks"))

SAMPLE_PROJECT = REPO / "sample_projects" / "james"


@pytest.fixture
def project_copy(tmp_path):
    """A copy of the sample project (without results) that a test may edit or damage."""
    shutil.copytree(SAMPLE_PROJECT, tmp_path / "james", ignore=shutil.ignore_patterns("results"))
    return tmp_path / "james" / "james.facestudio.json"
