"""Convert ICT-FaceKit's model files into the compact ``ict_facekit.npz`` Face Studio ships.

ICT-FaceKit (USC Institute for Creative Technologies, MIT licence; public repository
``ICT-VGL/ICT-FaceKit``) is not on a package registry, so its data were brought in once from a
snapshot of that repository and converted by this script; the result is committed
(``photomodel/rig/ict_facekit.npz``) and nothing needs the network afterwards. Only ICT's data are
used — the OBJ files of ``FaceXModel/`` and ``vertex_indices.json`` — none of its code.

What is kept (the *full face area*, ICT vertices 0–9408, polygons 0–9229: the face, forehead,
ears and the front of the neck; ICT's head back, mouth socket, eyes, teeth... are left out):

* ``neutral`` (9409, 3) float32, mm — ``generic_neutral_mesh.obj`` (ICT's unit is the cm), in
  ICT's frame (``+x`` subject's left, ``+y`` up, ``+z`` out of the face, like ours).
* ``faces`` (f, 3) int32 — the face area's quads and triangles split into triangles.
* ``expression_names`` (53,) str and ``expressions`` (53, 9409, 3) float16, mm — each expression
  OBJ minus the neutral (ARKit's names, ``_L``/``_R`` = the subject's left/right).
* ``identities`` (k, 9409, 3) float16, mm — ``identityNNN.obj`` minus the neutral: ICT's PCA modes
  at one standard deviation (ICT samples identities as standard normal coefficients).
* ``landmarks`` (68,) int32 — ``idx_to_landmark_verts``: the 68 Multi-PIE/iBUG points.

float16 keeps ~3 significant digits: 0.02 mm on a 20 mm expression, far below what the rig is
measured to (the round trip's bar is 10 %).

Usage::

    python -m photomodel.rig.make_ict_data --git-dir /path/to/ICT-FaceKit/.git [--identities 100]
    python -m photomodel.rig.make_ict_data --folder /path/to/ICT-FaceKit/FaceXModel
"""

from __future__ import annotations

import argparse
import io
import json
import subprocess
from collections.abc import Callable
from pathlib import Path

import numpy as np

#: ICT's full face area: vertices [0, 9408] and polygons [0, 9229] (ICT-FaceKit README).
FACE_VERTICES = 9409
FACE_POLYGONS = 9230
#: ICT's OBJ files are in centimetres.
MM_PER_ICT_UNIT = 10.0
#: Where the converted file lives (committed).
DATA_PATH = Path(__file__).with_name("ict_facekit.npz")


def _git_reader(git_dir: Path) -> Callable[[str], bytes]:
    def read(name: str) -> bytes:
        return subprocess.run(
            ["git", "--git-dir", str(git_dir), "show", f"HEAD:FaceXModel/{name}"], check=True, capture_output=True
        ).stdout

    return read


def _folder_reader(folder: Path) -> Callable[[str], bytes]:
    return lambda name: (folder / name).read_bytes()


def obj_vertices(text: bytes) -> np.ndarray:
    """(n, 3) float64 of the ``v`` lines of an OBJ file, in file order."""
    lines = [ln[2:] for ln in text.splitlines() if ln.startswith(b"v ")]
    return np.loadtxt(io.BytesIO(b"\n".join(lines)), dtype=np.float64).reshape(-1, 3)


def obj_triangles(text: bytes, n_polygons: int) -> np.ndarray:
    """(f, 3) int of the first ``n_polygons`` ``f`` lines of an OBJ file, fanned into triangles."""
    tris = []
    for ln in (ln for ln in text.splitlines() if ln.startswith(b"f ")):
        if n_polygons == 0:
            break
        n_polygons -= 1
        idx = [int(tok.split(b"/")[0]) - 1 for tok in ln.split()[1:]]
        tris += [(idx[0], idx[i], idx[i + 1]) for i in range(1, len(idx) - 1)]
    return np.array(tris, dtype=np.int32)


def convert(read: Callable[[str], bytes], n_identities: int = 100) -> dict[str, np.ndarray]:
    """The arrays of ``ict_facekit.npz`` (see the module notes) from ICT's files read by ``read``."""
    config = json.loads(read("vertex_indices.json"))
    neutral_obj = read("generic_neutral_mesh.obj")
    neutral = obj_vertices(neutral_obj)[:FACE_VERTICES] * MM_PER_ICT_UNIT
    faces = obj_triangles(neutral_obj, FACE_POLYGONS)
    if faces.max() >= FACE_VERTICES:
        raise ValueError("the face area's polygons reach beyond its vertices")

    def deltas(name: str) -> np.ndarray:
        return (obj_vertices(read(f"{name}.obj"))[:FACE_VERTICES] * MM_PER_ICT_UNIT - neutral).astype(np.float16)

    names = list(config["expressions"])
    return {
        "neutral": neutral.astype(np.float32),
        "faces": faces,
        "expression_names": np.array(names),
        "expressions": np.stack([deltas(n) for n in names]),
        "identities": np.stack([deltas(f"identity{i:03d}") for i in range(n_identities)]),
        "landmarks": np.array(config["idx_to_landmark_verts"], dtype=np.int32),
    }


def main(argv: list[str] | None = None) -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    src = p.add_mutually_exclusive_group(required=True)
    src.add_argument("--git-dir", type=Path, help="the git directory of an ICT-FaceKit snapshot")
    src.add_argument("--folder", type=Path, help="an ICT-FaceKit FaceXModel folder")
    p.add_argument("--identities", type=int, default=100, help="identity PCA modes kept (default 100)")
    p.add_argument("--out", type=Path, default=DATA_PATH)
    args = p.parse_args(argv)
    read = _git_reader(args.git_dir) if args.git_dir else _folder_reader(args.folder)
    arrays = convert(read, args.identities)
    np.savez_compressed(args.out, **arrays)
    print(
        f"{args.out}: {args.out.stat().st_size / 1e6:.1f} MB, "
        f"{len(arrays['expression_names'])} expressions, {len(arrays['identities'])} identities"
    )


if __name__ == "__main__":
    main()
