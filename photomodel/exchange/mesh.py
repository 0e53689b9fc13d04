"""Mesh files: OBJ and PLY written atomically with trimesh (a kept exporter, so
Blender/MeshLab read what we write). Textured exports (OBJ+MTL+PNG, coloured PLY, glTF) are in
:mod:`photomodel.exchange`, whose atomic writer this module shares."""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
import trimesh

from photomodel.exchange.files import atomic_write_bytes as _atomic_write_bytes


def write_mesh(path: str | os.PathLike, vertices: np.ndarray, faces: np.ndarray) -> Path:
    """Write ``(n, 3)`` mm vertices and ``(m, 3)`` faces as OBJ or PLY (by suffix), atomically."""
    path = Path(path)
    kind = path.suffix.lower().lstrip(".")
    if kind not in ("obj", "ply"):
        raise ValueError(f"{path}: mesh files must end in .obj or .ply")
    mesh = trimesh.Trimesh(np.asarray(vertices, float), np.asarray(faces, np.int64), process=False)
    data = mesh.export(file_type=kind)
    if isinstance(data, str):
        data = data.encode()
    _atomic_write_bytes(path, data)
    return path


def read_mesh(path: str | os.PathLike) -> tuple[np.ndarray, np.ndarray]:
    """``(vertices (n, 3), faces (m, 3))`` of an OBJ/PLY file, vertex order preserved."""
    mesh = trimesh.load(Path(path), process=False, force="mesh")
    return np.asarray(mesh.vertices, float), np.asarray(mesh.faces, np.int64)
