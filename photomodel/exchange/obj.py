"""Wavefront OBJ with a material (MTL) and a PNG texture — the textured face for any 3-D package.

Three files: ``<name>.obj`` (geometry, ``vt`` texture coordinates, ``vn`` normals, ``mtllib``),
``<name>.mtl`` (one material whose ``map_Kd`` names the PNG) and the PNG. Every reference is a
bare or relative file name, so the three files can be moved together.

* Positions are written in the caller's units (Face Studio: millimetres, head frame of
  :mod:`photomodel.camera`: ``+y`` up, ``+z`` out of the face — also OBJ's usual orientation),
  to 1e-6 units.
* ``vt`` has ``v`` up (OBJ convention, and ours: :mod:`photomodel.exchange.uv`). OBJ indexes
  positions and texture coordinates separately, so the vertex list is written *unchanged*
  (vertex ``i`` of the file is vertex ``i`` of the mesh, which later blend shapes rely on) and
  a seam is expressed by corners of the same vertex using different ``vt`` rows. (Importers
  with one index per vertex — trimesh, game engines — duplicate those vertices on load.)
* ``vn`` are area-weighted vertex normals (:func:`photomodel.rendering.renderer.vertex_normals`), one per
  vertex, so importers that use them shade the face smoothly across texture seams.

Written by hand rather than with trimesh's exporter: the format is a few lines of text, and
this keeps the vertex order, the texture file name and the seam representation under our
control (trimesh merges and reorders vertices by ``uv``).
"""

from __future__ import annotations

import os
import re
from dataclasses import dataclass
from pathlib import Path, PurePosixPath

import numpy as np

from photomodel.exchange.files import encode_png, write_files
from photomodel.exchange.uv import check_mesh, check_texture, check_uv
from photomodel.rendering.renderer import vertex_normals

#: Name of the single material.
MATERIAL_NAME = "face"


@dataclass
class TexturedObj:
    """An encoded OBJ + MTL (+ PNG) set, ready for :meth:`write`.

    Attributes
    ----------
    obj_path, mtl_path : Path
    png_path : Path, the texture the MTL refers to.
    files : dict[Path, bytes], what :meth:`write` writes, texture first, OBJ last (so a reader
        never meets a reference to a file not yet written). Holds no PNG when the texture is
        an existing file.
    n_texcoords : int, number of ``vt`` rows.
    """

    obj_path: Path
    mtl_path: Path
    png_path: Path
    files: dict
    n_texcoords: int

    def write(self) -> list[Path]:
        """Write every file atomically; return their paths."""
        return write_files(self.files)


def encode_textured_obj(
    path: str | os.PathLike,
    vertices,
    faces,
    uv,
    texture,
    *,
    texture_path: str | os.PathLike | None = None,
    check_exists: bool = True,
) -> TexturedObj:
    """Encode a textured mesh as OBJ + MTL (+ PNG) without touching the disk.

    Parameters
    ----------
    path : str or Path
        the ``.obj`` file; the MTL is ``path`` with suffix ``.mtl``.
    vertices : (n, 3) float, positions (mm in Face Studio).
    faces : (m, 3) int, counter-clockwise seen from outside.
    uv : (n, 2) per-vertex or (m, 3, 2) per-corner float, ``v`` up (see
        :mod:`photomodel.exchange.uv`).
    texture : (H, W, 3|4) uint8 or float in [0, 1] image, or None
        with an image, the PNG is encoded too; with None, ``texture_path`` must name an
        existing PNG that the MTL refers to.
    texture_path : str or Path, optional
        where the PNG is (default: ``path`` with suffix ``.png``). It must be in the OBJ's
        folder or below it, since MTL references are relative; no whitespace in its name
        (MTL readers split on it).
    check_exists : bool
        with ``texture=None``, require the PNG at ``texture_path`` to exist (set False when
        the caller writes it in the same batch, before these files).

    Returns
    -------
    TexturedObj
    """
    obj_path = Path(path)
    if obj_path.suffix.lower() != ".obj":
        raise ValueError(f"{obj_path}: an OBJ file name must end in .obj")
    v, f = check_mesh(vertices, faces)
    t = check_uv(uv, len(v), len(f))
    png_path = Path(texture_path) if texture_path is not None else obj_path.with_suffix(".png")
    rel = _relative_reference(png_path, obj_path.parent)
    mtl_path = obj_path.with_suffix(".mtl")
    if re.search(r"\s", mtl_path.name):
        raise ValueError(f"{obj_path}: OBJ/MTL file names must not contain whitespace (mtllib splits on it)")

    files: dict[Path, bytes] = {}
    if texture is not None:
        files[png_path] = encode_png(check_texture(texture))
    elif check_exists and not png_path.is_file():
        raise ValueError(f"{png_path}: no texture image given and no such file to refer to")

    text, n_texcoords = _obj_text(v, f, t, mtl_path.name)
    files[mtl_path] = _mtl_text(rel).encode()
    files[obj_path] = text.encode()
    return TexturedObj(obj_path=obj_path, mtl_path=mtl_path, png_path=png_path, files=files, n_texcoords=n_texcoords)


def _obj_text(v: np.ndarray, f: np.ndarray, t: np.ndarray, mtl_name: str) -> tuple[str, int]:
    """The OBJ's text for the checked mesh ``v``, ``f`` with texture coordinates ``t`` (per vertex
    or per corner) and the number of ``vt`` lines."""
    if t.ndim == 2:  # one vt per vertex, indexed like the positions
        vt, corner_vt = t, f
    else:
        vt, inverse = np.unique(t.reshape(-1, 2), axis=0, return_inverse=True)
        corner_vt = inverse.reshape(f.shape)
    normals = vertex_normals(v, f)

    idx = np.stack([f + 1, corner_vt + 1, f + 1], axis=2).reshape(len(f), 9)  # v/vt/vn, 1-based
    text = "".join(
        [
            "# Face Studio textured mesh\n",
            f"# {len(v)} vertices, {len(f)} triangles, {len(vt)} texture coordinates (v up)\n",
            f"mtllib {mtl_name}\n",
            ("v %.6f %.6f %.6f\n" * len(v)) % tuple(v.ravel()),
            ("vt %.7f %.7f\n" * len(vt)) % tuple(vt.ravel()),
            ("vn %.6f %.6f %.6f\n" * len(v)) % tuple(normals.ravel()),
            f"usemtl {MATERIAL_NAME}\n",
            ("f %d/%d/%d %d/%d/%d %d/%d/%d\n" * len(f)) % tuple(idx.ravel().tolist()),
        ]
    )
    return text, len(vt)


def _mtl_text(texture_reference: str) -> str:
    """The MTL's text: one material whose colour is the texture at ``texture_reference``."""
    return "".join(
        [
            "# Face Studio material: colour from the texture only (no specular: the photographs' shading\n",
            "# is already in the texture)\n",
            f"newmtl {MATERIAL_NAME}\n",
            "Ka 1.000000 1.000000 1.000000\n",
            "Kd 1.000000 1.000000 1.000000\n",
            "Ks 0.000000 0.000000 0.000000\n",
            "d 1.0\n",
            "illum 1\n",
            f"map_Kd {texture_reference}\n",
        ]
    )


def write_textured_obj(
    path: str | os.PathLike, vertices, faces, uv, texture, *, texture_path: str | os.PathLike | None = None
) -> TexturedObj:
    """:func:`encode_textured_obj` then write the files atomically (PNG, MTL, OBJ in that order)."""
    out = encode_textured_obj(path, vertices, faces, uv, texture, texture_path=texture_path)
    out.write()
    return out


def _relative_reference(target: Path, folder: Path) -> str:
    """``target`` relative to ``folder``, with ``/``; ValueError if outside it or with whitespace."""
    try:
        rel = Path(os.path.abspath(target)).relative_to(os.path.abspath(folder))
    except ValueError:
        raise ValueError(
            f"{target}: the texture must be in the OBJ's folder ({folder}) or below it, "
            f"since the MTL refers to it by a relative name"
        ) from None
    name = PurePosixPath(*rel.parts).as_posix()
    if re.search(r"\s", name):
        raise ValueError(f"{target}: texture file names must not contain whitespace (MTL splits on it)")
    return name
