"""Renders of the sample's rigged face driven by known ARKit weight curves: ground truth for ARKit tracking.

The fitted sample project (:func:`tracking.synthetic_sequences.ground_truth.fitted_sample_project`)
is rigged (:class:`photomodel.rig.build.RigBuilder` on its fitted neutral, as ``facestudio rig``
does) and its neutral mesh, moved by the rig's shapes with weights that follow known curves —
talking (``jawOpen`` with ``mouthFunnel``/``mouthPucker``/``mouthClose``), blinking (both eyes, and
one wink), smiling (``mouthSmile*``, ``cheekSquint*``), brows (``browInnerUp``, ``browOuterUp*``,
``browDown*``) — is rendered with the neutral's texture under head motion turning ±``yaw_deg``
(:func:`arkit_truth`, :func:`render_arkit_frame`). Tests and ``benchmarks/bench_auto.py`` track it
with :func:`tracking.arkit_face.arkit_face_model` and compare the weights; the tracker never
imports this module.
"""

from __future__ import annotations

import shutil
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from photomodel.camera import rodrigues
from photomodel.modeling.generic_mesh import load_generic_mesh
from photomodel.project import load_project, read_fitted_mesh, save_project, store_rig
from photomodel.rendering.renderer import get_renderer
from photomodel.rig.build import RigBuilder
from tracking.blendshape_face import FaceModel
from tracking.face_from_project import model_expressions
from tracking.synthetic_sequences.ground_truth import (
    BACKGROUND_RGB,
    VIDEO_DISTANCE_MM,
    VideoTruth,
    fitted_sample_project,
)

__all__ = ["ArkitTruth", "arkit_truth", "rigged_sample_project", "render_arkit_frame", "CURVES"]

#: Shapes the curves drive, and how (the rest stay at 0).
CURVES = (
    "jawOpen",
    "mouthFunnel",
    "mouthPucker",
    "mouthClose",
    "eyeBlinkLeft",
    "eyeBlinkRight",
    "mouthSmileLeft",
    "mouthSmileRight",
    "cheekSquintLeft",
    "cheekSquintRight",
    "browInnerUp",
    "browOuterUpLeft",
    "browOuterUpRight",
    "browDownLeft",
    "browDownRight",
)


@dataclass
class ArkitTruth(VideoTruth):
    """Ground truth of a rendered ARKit sequence: ``R`` (T, 3, 3), ``t`` (T, 3) mm (``X_cam = R X +
    t``), ``weights`` (T, k) in [0, 1] over ``names`` (the rig's shapes), the camera."""


def rigged_sample_project(folder: str | Path) -> Path:
    """A copy of the fitted sample project in ``folder`` with its rig built as ``facestudio rig``
    builds it: the project file's path."""

    src = fitted_sample_project()
    dst = Path(folder) / "james"
    if not (dst / src.name).is_file():
        shutil.copytree(src.parent, dst, dirs_exist_ok=True)
    path = dst / src.name
    project = load_project(path)
    if project.rig is None:  # the recipe of `facestudio rig` (app/cli/rig.py) on the neutral
        neutral = model_expressions(project)[0]
        vertices, _faces = read_fitted_mesh(project, neutral)
        rig = RigBuilder(load_generic_mesh()).rig(vertices)
        store_rig(project, neutral=neutral, names=rig.names, deltas=rig.deltas, report=rig.report)
        save_project(project)
    return path


def arkit_truth(
    names,
    centre: np.ndarray,
    frames: int = 120,
    *,
    seed: int = 3,
    yaw_deg: float = 20.0,
    focal_px: float = 560.0,
    size: int = 300,
) -> ArkitTruth:
    """Head motion turning ±``yaw_deg`` (pitch ±6°, roll ±4°, ±10 mm sideways, ±12 mm in depth) and
    the weight curves of :data:`CURVES` over ``frames`` frames, for a model whose centre (mm, head
    frame) is ``centre``: the head centre ``VIDEO_DISTANCE_MM`` in front of the camera."""
    rng = np.random.default_rng(seed)
    T = int(frames)
    s = np.arange(T) / max(T - 1, 1)
    ph = rng.uniform(0, 2 * np.pi, 6)
    yaw = np.radians(yaw_deg) * np.sin(2 * np.pi * 1.0 * s + ph[0])
    pitch = np.radians(6.0) * np.sin(2 * np.pi * 1.3 * s + ph[1])
    roll = np.radians(4.0) * np.sin(2 * np.pi * 0.7 * s + ph[2])
    facing = np.diag([1.0, -1.0, -1.0])
    R = np.array([rodrigues(np.array([p, y, r])) @ facing for p, y, r in zip(pitch, yaw, roll, strict=True)])
    centre_cam = np.column_stack(
        [
            10.0 * np.sin(2 * np.pi * 0.6 * s + ph[3]),
            6.0 * np.sin(2 * np.pi * 0.8 * s + ph[4]),
            VIDEO_DISTANCE_MM + 12.0 * np.sin(2 * np.pi * 0.5 * s + ph[5]),
        ]
    )
    t = centre_cam - np.einsum("tij,j->ti", R, np.asarray(centre, float))
    index = {n: i for i, n in enumerate(names)}
    W = np.zeros((T, len(names)))

    def bump(c, width, height):
        return height * np.exp(-0.5 * ((s - c) / width) ** 2)

    def put(name, curve):
        if name in index:
            W[:, index[name]] = np.clip(curve, 0.0, 1.0)

    # talking: the jaw opens and closes ~6 times over the clip, rounding the lips now and then
    talk = np.clip(np.sin(2 * np.pi * 6.0 * s), 0.0, None) * (0.35 + 0.35 * np.sin(2 * np.pi * 1.1 * s + 1.0) ** 2)
    put("jawOpen", talk)
    put("mouthFunnel", 0.6 * bump(0.15, 0.04, 1.0))
    put("mouthPucker", 0.7 * bump(0.85, 0.04, 1.0))
    put("mouthClose", 0.3 * bump(0.85, 0.04, 1.0))
    # blinking: both eyes at four moments (2–3 frames closed), the left alone once (a wink)
    blink = sum(bump(c, 0.012, 1.0) for c in (0.1, 0.37, 0.62, 0.9))
    put("eyeBlinkLeft", blink + bump(0.5, 0.015, 0.9))
    put("eyeBlinkRight", blink)
    # smiling: a broad smile early, a lop-sided one late
    put("mouthSmileLeft", bump(0.3, 0.08, 0.8) + bump(0.75, 0.05, 0.6))
    put("mouthSmileRight", bump(0.3, 0.08, 0.8))
    put("cheekSquintLeft", bump(0.3, 0.08, 0.4))
    put("cheekSquintRight", bump(0.3, 0.08, 0.4))
    # brows: raised in the middle of the clip, knitted near the end
    put("browInnerUp", bump(0.45, 0.07, 0.8))
    put("browOuterUpLeft", bump(0.45, 0.07, 0.6))
    put("browOuterUpRight", bump(0.45, 0.07, 0.6))
    put("browDownLeft", bump(0.8, 0.05, 0.7))
    put("browDownRight", bump(0.8, 0.05, 0.7))
    return ArkitTruth(R, t, W, tuple(names), float(focal_px), int(size), int(size))


def true_geometry(model: FaceModel, truth: ArkitTruth, i: int) -> np.ndarray:
    """(n, 3) mm, head frame: the rigged neutral moved by frame ``i``'s weights (``model``: an
    ARKit model, :func:`tracking.arkit_face.arkit_face_model`, whose shared shapes include ``truth.names``)."""
    index = {n: k for k, n in enumerate(model.names)}
    X = model.geometry[0].copy()
    for j, n in enumerate(truth.names):
        if n in index and truth.weights[i, j]:
            X += truth.weights[i, j] * model.geometry[index[n]]
    return X


_HANDLES: dict = {}


def render_arkit_frame(model: FaceModel, truth: ArkitTruth, i: int, *, supersample: int = 3) -> np.ndarray:
    """(H, W, 3) float32 in [0, 1]: frame ``i`` — the rigged face (:func:`true_geometry`) textured
    with the neutral's texture, seen by the camera at the frame's pose, on a plain background,
    ``supersample``-times supersampled (a rendering the tracker's own Eq. 5 does not reproduce
    exactly)."""
    r = get_renderer()
    key = (id(r), id(model.textures[0]))
    if key not in _HANDLES:
        _HANDLES[key] = r.upload_texture(model.textures[0])
    res = r.render(
        truth.camera(i),
        true_geometry(model, truth, i),
        model.faces,
        uv=model.uv[0],
        texture=_HANDLES[key],
        background=BACKGROUND_RGB,
        supersample=supersample,
    )
    return res.color
