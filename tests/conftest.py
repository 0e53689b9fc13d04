"""Shared test set-up: Qt runs offscreen, rendering is headless EGL."""

import os
import sys
from pathlib import Path

os.environ.setdefault("QT_QPA_PLATFORM", "offscreen")

REPO = Path(__file__).resolve().parents[1]
# benchmarks/ holds the peer implementations that some tests compare against
if str(REPO / "benchmarks") not in sys.path:
    sys.path.insert(0, str(REPO / "benchmarks"))
