"""scikit-image's photograph of a face: one more real portrait the benchmarks were not made on.

The ``scikit-image==0.24.0`` wheel (code BSD-3-Clause) ships ``skimage/data/astronaut.png``, the
astronaut Eileen Collins's NASA portrait (512×512, "no known copyright restrictions, released into
the public domain" says ``skimage.data.astronaut``'s docstring): a smiling face, a dark collar under
the chin. It is fetched like every sample file (:mod:`photomodel.data.fetch`: pip by package name,
archive and file checksums, cache in ``<cache>/scikit-image-0.24.0/``; offline, set
``FACESTUDIO_SKIMAGE_WHEEL`` to a local copy of the wheel) and never redistributed.

It carries no landmarks: :data:`ASTRONAUT_MARKS` are points marked by eye on it for
``benchmarks/bench_real.py`` (the eyes' centres, the visible jaw line from ear to ear through the
lowest point of the chin), with :func:`load_astronaut` giving them in the 68-point layout of
:func:`photomodel.samples.menpo_images.load_annotated` (the others NaN).
"""

from __future__ import annotations

import cv2
import numpy as np

from photomodel.data.fetch import PackageFiles, package_files
from photomodel.errors import SampleDataError

SKIMAGE = PackageFiles(
    package="scikit-image",
    version="0.24.0",
    archive_name="scikit_image-0.24.0-cp311-cp311-manylinux_2_17_x86_64.manylinux2014_x86_64.whl",
    archive_sha256="fa27b3a0dbad807b966b8db2d78da734cb812ca4787f7fbb143764800ce2fa9c",
    members={
        "astronaut.png": (
            "skimage/data/astronaut.png",
            "88431cd9653ccd539741b555fb0a46b61558b301d4110412b5bc28b5e3ea6cb5",
        ),
        "LICENSE.txt": (
            "scikit_image-0.24.0.dist-info/LICENSE.txt",
            "51f15344f59759ed5d8ddb6dad48e8b994bdd45b050a80fe58a419bd0f98aed0",
        ),
    },
    pip_args=("--only-binary=:all:", "--python-version", "3.11", "--platform", "manylinux_2_17_x86_64"),
    env_archive="FACESTUDIO_SKIMAGE_WHEEL",
)

#: Marked by eye on ``astronaut.png`` at 10× (u, v px): the eyes' centres (image left, right) and
#: the visible outline of the face from beside the image-left ear, through the chin's lowest point
#: (220, 177), to beside the other ear — where the skin meets the backdrop, and under the cheeks
#: the shading line of the jaw over the neck.
ASTRONAUT_MARKS = {
    "eyes": ((204.0, 102.0), (246.0, 103.0)),
    "jaw": (
        (183.0, 130.0),
        (184.0, 145.0),
        (187.0, 154.0),
        (192.0, 162.0),
        (199.0, 168.0),
        (207.0, 173.0),
        (214.0, 176.0),
        (220.0, 177.0),
        (232.0, 175.0),
        (242.0, 171.0),
        (250.0, 166.0),
        (257.0, 161.0),
        (261.0, 154.0),
        (265.0, 145.0),
        (267.5, 135.0),
    ),
}


def _jaw17(jaw: np.ndarray) -> np.ndarray:
    """17 points along the polyline ``jaw``, evenly by arc length, the middle one on its middle point."""
    mid = len(jaw) // 2
    halves = []
    for part in (jaw[: mid + 1], jaw[mid:]):
        s = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(part, axis=0), axis=1))])
        t = np.linspace(0.0, s[-1], 9)
        halves.append(np.stack([np.interp(t, s, part[:, 0]), np.interp(t, s, part[:, 1])], axis=1))
    return np.vstack([halves[0], halves[1][1:]])


def load_astronaut() -> tuple[np.ndarray, np.ndarray]:
    """``(image, points)``: the RGB uint8 photo and (68, 2) float points in the iBUG layout, only
    the jaw (0–16, from :data:`ASTRONAUT_MARKS`) and the eyes (36–47, each eye's six at its
    centre) known, the others NaN.

    Raises
    ------
    SampleDataError
        when the wheel cannot be fetched or the file cannot be read.
    """
    path = package_files(SKIMAGE) / "astronaut.png"
    bgr = cv2.imread(str(path), cv2.IMREAD_COLOR)
    if bgr is None:
        raise SampleDataError(f"cannot read {path}; delete it and try again. {SKIMAGE.how_to_fix()}")
    points = np.full((68, 2), np.nan)
    points[:17] = _jaw17(np.asarray(ASTRONAUT_MARKS["jaw"], float))
    points[36:42] = ASTRONAUT_MARKS["eyes"][0]
    points[42:48] = ASTRONAUT_MARKS["eyes"][1]
    return np.ascontiguousarray(bgr[:, :, ::-1]), points
