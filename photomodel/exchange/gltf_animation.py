"""Binary glTF 2.0 with blend shapes and an animation: a rigged face and a tracked performance.

The face is :func:`photomodel.exchange.gltf.add_face_mesh`'s (metres, texture embedded, seams
split); on top of it:

* **Morph targets.** Each blend shape is a ``POSITION`` displacement accessor (metres, with the
  ``min``/``max`` glTF requires) in ``Primitive.targets``; the mesh's default ``weights`` are 0 and
  its names go into ``mesh.extras.targetNames`` — the convention Blender, three.js and Babylon
  read (three.js ignores the names when their count differs from the targets').
* **Animation** (optional, :class:`Performance`): a ``weights`` channel on the face's node at the
  video's frame times (``LINEAR``; one output row of all weights per frame), and the head pose as
  the node's ``rotation`` (unit quaternions ``x, y, z, w``) and ``translation`` (metres).

Frame of the pose
-----------------
The pose is the tracked ``X_cam = R X + t`` (:mod:`photomodel.camera`: camera looks along
``+z``, ``y`` down) turned into glTF's camera convention (looks along ``−Z``, ``+Y`` up) by
``C = diag(1, −1, −1)``: the node's transform is ``(C R, C t)``, i.e. the head placed in the
**video camera's frame**. A camera node at the origin with the video's vertical field of view
(``yfov = 2 atan(H / 2f)``, aspect ``W / H``) is added, so looking through it shows the head where
the video showed it.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pygltflib as gl

from photomodel.exchange.files import atomic_write_bytes
from photomodel.exchange.gltf import METRES_PER_MM, GlbDocument, add_face_mesh

__all__ = [
    "Performance",
    "encode_rigged_glb",
    "read_animated_weights",
    "write_rigged_glb",
    "GLTF_FROM_CAMERA",
    "quaternion_xyzw",
]

#: Our camera frame (y down, looking along +z) → glTF's camera frame (y up, looking along −z).
GLTF_FROM_CAMERA = np.diag([1.0, -1.0, -1.0])


@dataclass
class Performance:
    """A tracked performance to animate the rigged face with.

    Attributes
    ----------
    times_s : (f,) float, increasing frame times (frame / fps).
    weights : (f, k) float, each target's weight per frame (the targets' order).
    rotation : (f, 3, 3) float, ``R`` of ``X_cam = R X + t`` per frame.
    translation_mm : (f, 3) float, ``t``.
    focal_px : float, width, height : int — the video camera (for the camera node).
    """

    times_s: np.ndarray
    weights: np.ndarray
    rotation: np.ndarray
    translation_mm: np.ndarray
    focal_px: float
    width: int
    height: int


def quaternion_xyzw(R: np.ndarray) -> np.ndarray:
    """(f, 4) unit quaternions ``(x, y, z, w)`` of rotations (f, 3, 3), ``w ≥ 0``, sign-continuous."""
    R = np.asarray(R, float).reshape(-1, 3, 3)
    w = np.sqrt(np.maximum(0.0, 1.0 + R[:, 0, 0] + R[:, 1, 1] + R[:, 2, 2])) / 2
    x = np.sqrt(np.maximum(0.0, 1.0 + R[:, 0, 0] - R[:, 1, 1] - R[:, 2, 2])) / 2
    y = np.sqrt(np.maximum(0.0, 1.0 - R[:, 0, 0] + R[:, 1, 1] - R[:, 2, 2])) / 2
    z = np.sqrt(np.maximum(0.0, 1.0 - R[:, 0, 0] - R[:, 1, 1] + R[:, 2, 2])) / 2
    x = np.copysign(x, R[:, 2, 1] - R[:, 1, 2])
    y = np.copysign(y, R[:, 0, 2] - R[:, 2, 0])
    z = np.copysign(z, R[:, 1, 0] - R[:, 0, 1])
    q = np.column_stack([x, y, z, w])
    q /= np.linalg.norm(q, axis=1, keepdims=True)
    for i in range(1, len(q)):  # the shorter way between frames (q and −q are one rotation)
        if q[i] @ q[i - 1] < 0:
            q[i] = -q[i]
    return q


def _add_targets(doc: GlbDocument, primitive: gl.Primitive, source: np.ndarray, deltas: np.ndarray) -> None:
    primitive.targets = []
    for d in deltas:
        acc = doc.add_accessor((d[source] * METRES_PER_MM).astype(np.float32), bounds=True)
        primitive.targets.append({"POSITION": acc})


def _add_animation(doc: GlbDocument, node: int, perf: Performance, k: int) -> None:
    t = np.asarray(perf.times_s, np.float32)
    W = np.asarray(perf.weights, np.float32)
    if t.ndim != 1 or len(t) == 0 or W.shape != (len(t), k) or np.any(np.diff(t) <= 0):
        raise ValueError(f"a performance needs increasing times (f,) and weights (f, {k}); got {t.shape}, {W.shape}")
    R = GLTF_FROM_CAMERA @ np.asarray(perf.rotation, float)
    tr = np.asarray(perf.translation_mm, float) @ GLTF_FROM_CAMERA.T * METRES_PER_MM
    times = doc.add_accessor(t, target=None, bounds=True)
    outputs = [
        (W.reshape(-1), "weights"),
        (quaternion_xyzw(R).astype(np.float32), "rotation"),
        (tr.astype(np.float32), "translation"),
    ]
    anim = gl.Animation(name="performance")
    for i, (data, path) in enumerate(outputs):
        anim.samplers.append(
            gl.AnimationSampler(input=times, output=doc.add_accessor(data, target=None), interpolation="LINEAR")
        )
        anim.channels.append(gl.AnimationChannel(sampler=i, target=gl.AnimationChannelTarget(node=node, path=path)))
    doc.gltf.animations.append(anim)
    yfov = 2.0 * np.arctan(perf.height / (2.0 * perf.focal_px))
    doc.gltf.cameras.append(
        gl.Camera(
            type="perspective",
            name="video_camera",
            perspective=gl.Perspective(yfov=float(yfov), aspectRatio=perf.width / perf.height, znear=0.01),
        )
    )
    doc.gltf.nodes.append(gl.Node(name="video_camera", camera=len(doc.gltf.cameras) - 1))


def encode_rigged_glb(
    vertices, faces, deltas, names, *, uv=None, texture=None, performance: Performance | None = None, name: str = "face"
) -> bytes:
    """Encode a face with blend shapes (and a performance) as a binary glTF file.

    Parameters
    ----------
    vertices : (n, 3) float mm, the neutral. faces : (m, 3) int.
    deltas : (k, n, 3) float mm, each blend shape's displacement. names : k str (``targetNames``).
    uv, texture : as :func:`photomodel.exchange.gltf.encode_glb` (both or neither).
    performance : Performance, optional, the animation (weights in the targets' order).
    name : str, the mesh's and node's name.

    Returns
    -------
    bytes, the ``.glb`` file.
    """
    D = np.asarray(deltas, float)
    names = [str(s) for s in names]
    if D.ndim != 3 or D.shape[0] != len(names) or D.shape[1:] != np.shape(vertices):
        raise ValueError(f"deltas must be (k, n, 3) with one name each, got {D.shape} and {len(names)} names")
    doc = GlbDocument()
    primitive, source = add_face_mesh(doc, vertices, faces, uv=uv, texture=texture, name=name)
    node = len(doc.gltf.nodes) - 1
    mesh = doc.gltf.meshes[-1]
    if len(names):
        _add_targets(doc, primitive, source, D)
        mesh.weights = [0.0] * len(names)
        mesh.extras = {"targetNames": names}
    if performance is not None:
        _add_animation(doc, node, performance, len(names))
    doc.gltf.scenes.append(gl.Scene(nodes=list(range(len(doc.gltf.nodes)))))
    doc.gltf.scene = 0
    return doc.to_bytes()


def read_animated_weights(path) -> tuple[list[str], int, np.ndarray]:
    """A rigged glb read back: its morph targets' names (``extras.targetNames``), their count and
    the animated weights (frames, k) float32 of its first animation's ``weights`` channel (0 rows
    when it has no animation)."""
    g = gl.GLTF2.load(str(path))
    mesh = g.meshes[0]
    names = list((mesh.extras or {}).get("targetNames", []))
    k = len(mesh.primitives[0].targets or [])
    if not g.animations:
        return names, k, np.zeros((0, k), np.float32)
    anim = g.animations[0]
    chan = next(c for c in anim.channels if c.target.path == "weights")
    sampler = anim.samplers[chan.sampler]
    frames = g.accessors[sampler.input].count
    acc = g.accessors[sampler.output]
    view = g.bufferViews[acc.bufferView]
    blob = g.binary_blob()
    W = np.frombuffer(blob, np.float32, acc.count, view.byteOffset + (acc.byteOffset or 0)).reshape(frames, k)
    return names, k, W


def write_rigged_glb(path, vertices, faces, deltas, names, **kw):
    """:func:`encode_rigged_glb` written atomically to ``path`` (``*.glb``); returns the path."""
    path = Path(path)
    if path.suffix.lower() != ".glb":
        raise ValueError(f"{path}: a binary glTF file name must end in .glb")
    return atomic_write_bytes(path, encode_rigged_glb(vertices, faces, deltas, names, **kw))
