"""menpo3d 0.8.6's data files, and its generic head ``template`` that the generic mesh is made from.

Face Studio does not ship third-party meshes. It asks ``pip`` (:mod:`photomodel.data.fetch`) for
the *source distribution* of ``menpo3d==0.8.6``, checks the archive's SHA-256, and extracts only
the six files it needs into ``<cache>/menpo3d-0.8.6/`` (:func:`menpo3d_dir`):

* ``template.ply`` / ``template.ljson`` — a 53k-vertex generic head surface (face, ears, neck;
  open at the back) in *micrometres* with the 68 iBUG landmarks;
  :mod:`photomodel.modeling.generic_mesh` simplifies it into the generic mesh that the fit of
  Pighin et al. (2002), §5.1, deforms (:func:`load_template`).
* ``james.obj`` / ``james.obj.mtl`` / ``james.jpg`` / ``james.ljson`` — a real textured head scan,
  the ground truth of tests and benchmarks, read by :mod:`photomodel.samples.sample_data`.

Offline, set ``FACESTUDIO_MENPO3D_SDIST`` to a local copy of ``menpo3d-0.8.6.tar.gz``.
``python -m photomodel.data.menpo3d`` fetches the files ahead of time (install.sh runs it) and
prints the folder.

The template is returned in millimetres in the *head frame* of :mod:`photomodel.camera`
(``+x`` subject's left, ``+y`` up, ``+z`` out of the face), which is the frame of
``template.ply`` after scaling µm → mm.
"""

from __future__ import annotations

import json
import sys
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import trimesh  # only the first load parses the PLY

from photomodel.data.cache import cached_arrays
from photomodel.data.fetch import PackageFiles, package_files, print_folder
from photomodel.data.keys import code_key
from photomodel.errors import SampleDataError

PACKAGE = "menpo3d"
VERSION = "0.8.6"
SDIST_NAME = f"{PACKAGE}-{VERSION}.tar.gz"
SDIST_SHA256 = "96ad2c8b55b74e026cdc190cf6b1564ad7c8e6c53976cf897d6a1bf4940f084a"
#: SHA-256 of every file extracted into the cache.
FILE_SHA256 = {
    "james.jpg": "829589c076a9cb7b8904b08cc0b301a01e75d6096bf2ca01ed7a8e9d4a615a77",
    "james.ljson": "02a9e32271c47db90ec51ec0027eb302b68e52f974d6b2856a3f7e55b13b0ee2",
    "james.obj": "80cb729b6a751b25794d9d571668ff3c022f111119b307dd93dc8fbed6eed110",
    "james.obj.mtl": "90aa99e8d939fa6e9849e15c7b39a3364b8814a494a7fe59baca0484104c9ca4",
    "template.ljson": "15d5af3e496d10a71306d9a5d41b3ef0bbf1d603a2aee0fc723a17c9284395fd",
    "template.ply": "2c9898e9582ac2fd76131e5757f063315cbe8781ffbd036e2bb5f1bd1fa8215e",
}
_ARCHIVE_DATA = f"{PACKAGE}-{VERSION}/{PACKAGE}/data/"
ENV_SDIST = "FACESTUDIO_MENPO3D_SDIST"


def menpo3d_files() -> PackageFiles:
    """The six files of the menpo3d source distribution (built at each call from the module's
    constants, so tests can swap the checksums)."""
    return PackageFiles(
        package=PACKAGE,
        version=VERSION,
        archive_name=SDIST_NAME,
        archive_sha256=SDIST_SHA256,
        members={name: (_ARCHIVE_DATA + name, digest) for name, digest in FILE_SHA256.items()},
        pip_args=("--no-build-isolation", "--no-binary", ":all:"),
        env_archive=ENV_SDIST,
        note="pip prepares a source distribution's metadata itself: `python -m pip install setuptools wheel` first.",
    )


def menpo3d_dir() -> Path:
    """Folder holding the verified menpo3d 0.8.6 files; fetch them if needed
    (:func:`photomodel.data.fetch.package_files`: pip, checksums, cache, atomic install).

    Returns
    -------
    Path
        ``<cache>/menpo3d-0.8.6`` containing the files of :data:`FILE_SHA256`, each with
        a verified SHA-256.

    Raises
    ------
    SampleDataError
        when the source distribution cannot be obtained (pip fails, no network) or
        a checksum does not match; the message says what to do.
    """
    return package_files(menpo3d_files())


def ljson_points(path: Path) -> np.ndarray:
    """(68, 3) float landmark points of a menpo ``.ljson`` file."""
    doc = json.loads(Path(path).read_text())
    points = np.asarray(doc["groups"]["LJSON"]["landmarks"]["points"], dtype=float)
    if points.shape != (68, 3):
        raise SampleDataError(f"{path} holds {points.shape} landmarks, expected (68, 3)")
    return points


@dataclass
class Template:
    """menpo3d's generic head surface (``template.ply``), in mm in the head frame.

    Attributes
    ----------
    vertices : (n, 3) float
        mm (the file stores micrometres; divided by 1000). n = 53349.
    faces : (m, 3) int64
        triangles, counter-clockwise seen from outside.
    landmarks : (68, 3) float
        mm, iBUG-68 order (``template.ljson`` is already in that order: index 0 is the
        jaw at the subject's right ear, x < 0). They are not vertices: each lies within
        ~1.2 mm of the nearest vertex.
    """

    vertices: np.ndarray
    faces: np.ndarray
    landmarks: np.ndarray


def template_arrays(folder: Path) -> dict[str, np.ndarray]:
    """The arrays of :class:`Template` read from the files in ``folder`` (the uncached path)."""
    mesh = trimesh.load(Path(folder) / "template.ply", process=False, force="mesh")
    return {
        "vertices": np.asarray(mesh.vertices, float) / 1000.0,  # µm → mm
        "faces": np.asarray(mesh.faces, np.int64),
        "landmarks": ljson_points(Path(folder) / "template.ljson") / 1000.0,
    }


def load_template() -> Template:
    """The generic face mask of menpo3d in mm (see :class:`Template`), parsed once and kept as
    ``template-<key>.npz`` beside the files (the key: :func:`template_arrays`' code; the files are
    fixed by their checksums, which are part of that code)."""
    folder = menpo3d_dir()
    arrays = cached_arrays(
        "template",
        code_key(template_arrays),
        lambda: template_arrays(folder),
        folder=folder,
        legacy=("template.npz",),
    )
    return Template(vertices=arrays["vertices"], faces=arrays["faces"], landmarks=arrays["landmarks"])


def main(argv: list[str] | None = None) -> int:
    """``python -m photomodel.data.menpo3d``: fetch and verify menpo3d's files, print their folder."""
    del argv
    return print_folder(menpo3d_dir)


if __name__ == "__main__":
    sys.exit(main())
