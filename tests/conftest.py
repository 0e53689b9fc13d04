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


@pytest.fixture(scope="session")
def fitted_sample():
    """The sample project with every expression fitted and textured (made once, cached:
    :func:`tracking.samples.fitted_sample_project`); read it, do not change it."""
    from tracking.samples import fitted_sample_project

    return fitted_sample_project()


@pytest.fixture
def fitted_project_copy(tmp_path, fitted_sample):
    """A copy of the fitted sample project with the sample video, that a test may edit."""
    dst = tmp_path / "james"
    shutil.copytree(fitted_sample.parent, dst)
    shutil.copytree(SAMPLE_PROJECT / "video", dst / "video")
    return dst / fitted_sample.name
