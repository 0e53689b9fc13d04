"""Exporting the textured face: one module per file format, every file written atomically.

| module | writes |
|---|---|
| :mod:`~photomodel.exchange.obj` | OBJ + MTL + PNG texture (``write_textured_obj``) |
| :mod:`~photomodel.exchange.ply` | PLY with per-vertex RGB colours (``write_colored_ply``) |
| :mod:`~photomodel.exchange.gltf` | binary glTF ``.glb`` with the texture embedded (``write_glb``) |
| :mod:`~photomodel.exchange.uv` | texture-coordinate checks, the cylindrical seam, sampling |
| :mod:`~photomodel.exchange.files` | atomic writes, PNG encoding |

Every writer has an ``encode_*`` twin that returns bytes without touching the disk, so a command
can prepare all its outputs first and write them only once nothing can fail any more. Plain
(untextured) OBJ/PLY files of a fitted mesh are :mod:`photomodel.exchange.mesh`'s job.
"""
