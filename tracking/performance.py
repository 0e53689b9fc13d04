"""A project's blend shapes and a tracked performance, gathered for an animated glTF export.

The targets of ``facestudio export --glb`` are

* the rig's shapes (ARKit's names, :mod:`photomodel.rig`, stored by ``facestudio rig``), and
* the **photographed expressions, one target per control region**: the tracking model blends
  each region with its own weights (Pighin et al. 2002, §6.1.1, Eq. 4), ``X_i = Σ_r μ_ir Σ_k
  w_rk E_k,i`` with ``Σ_k w_rk = 1`` in every region (:func:`tracking.blendshape_face.expression_basis`)
  and the rest region neutral, so

      X = E_1 + Σ_(r ≠ rest) Σ_(k ≥ 2) w_rk · μ_r (E_k − E_1)

  exactly: target ``<expression>_<region>`` is ``μ_r (E_k − E_1)`` and a tracked frame's weight
  ``w_rk`` (``track.json``'s ``weights[region][expression]``) is its weight, unchanged.

A track in ARKit terms (:mod:`tracking.arkit_face`: ``track.json`` frames carry ``arkit``
{shape: weight}) animates the rig's targets with those weights themselves
(:func:`track_performance`), and its Live Link CSV carries them (:func:`tracked_arkit_weights`);
a track of the photographed expressions alone is said in ARKit's shapes by fitting
(:func:`arkit_weights`).

The base mesh is the model's ``E_1`` (the neutral fit), with the neutral's texture and its
cylindrical coordinates; triangles crossing the texture's seam are left out, as in tracking.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.optimize import lsq_linear

from photomodel.errors import FaceStudioError
from photomodel.exchange.files import write_files
from photomodel.exchange.gltf_animation import Performance, encode_rigged_glb
from photomodel.exchange.livelink import ROTATION_COLUMNS, livelink_csv_bytes
from photomodel.project import load_rig_shapes
from photomodel.rig.ict import ARKIT_SHAPES
from tracking.blendshape_face import CONTROL_REGIONS, FaceModel
from tracking.face_from_project import face_model_from_project

__all__ = [
    "BlendShapes",
    "arkit_weights",
    "blend_shapes",
    "track_performance",
    "tracked_arkit_weights",
    "export_track",
    "rigged_glb_bytes",
    "track_livelink_bytes",
    "region_targets",
]


@dataclass
class BlendShapes:
    """What a rigged glb holds: the neutral (n, 3) mm, faces (m, 3), deltas (k, n, 3) mm, k names,
    uv (n, 2) (v up) and the texture PNG bytes (or None)."""

    neutral: np.ndarray
    faces: np.ndarray
    deltas: np.ndarray
    names: list
    uv: np.ndarray | None
    texture_png: bytes | None
    rig_shapes: int
    photographed: int


def region_targets(model: FaceModel) -> tuple[list[str], np.ndarray]:
    """``<expression>_<region>`` names and ``μ_r (E_k − E_1)`` (mm) of every controlled region and
    expression after the neutral (see the module notes)."""
    names, deltas = [], []
    for r, region in enumerate(CONTROL_REGIONS):
        if r == 0:
            continue
        for k in range(1, model.m):
            names.append(f"{model.names[k]}_{region}")
            deltas.append(model.membership[:, r, None] * (model.geometry[k] - model.geometry[0]))
    return names, np.array(deltas).reshape(len(names), *model.geometry.shape[1:])


def blend_shapes(project, expressions=None) -> tuple[BlendShapes, FaceModel]:
    """The glb's targets of ``project`` (rig first, if it has one; then the photographed expressions
    per region) on the face model of ``expressions`` (default: as tracking chooses)."""
    model, _report = face_model_from_project(project, expressions)
    names, deltas = region_targets(model)
    rig_names, rig_deltas = ([], np.zeros((0, *model.geometry.shape[1:])))
    if project.rig is not None:
        if project.rig.neutral != model.names[0]:
            raise FaceStudioError(
                f"the rig was made on {project.rig.neutral!r} but the face model's neutral is "
                f"{model.names[0]!r}; run `facestudio rig` again"
            )
        rig_names, rig_deltas = load_rig_shapes(project)
    texture = project.expression(model.names[0]).result.texture
    png = project.resolve(texture.image).read_bytes() if texture is not None else None
    shapes = BlendShapes(
        neutral=model.geometry[0],
        faces=model.faces,
        deltas=np.concatenate([rig_deltas, deltas]),
        names=list(rig_names) + names,
        uv=model.uv[0] if png is not None else None,
        texture_png=png,
        rig_shapes=len(rig_names),
        photographed=len(names),
    )
    return shapes, model


def track_performance(doc: dict, names: list[str]) -> Performance:
    """The ``track.json`` document ``doc`` as a :class:`Performance` over the targets ``names``:
    each tracked ``weights[region][expression]`` on target ``<expression>_<region>``, each tracked
    ARKit weight (``arkit[shape]``) on the rig's target ``shape``, the others 0."""
    frames = doc["frames"]
    fps = float(doc["video"].get("fps") or 0.0)
    if not frames:
        raise FaceStudioError("the tracking results hold no frame yet; run `facestudio track` first")
    if fps <= 0:
        raise FaceStudioError("the tracking results do not say the video's frame rate")
    index = {n: i for i, n in enumerate(names)}
    W = np.zeros((len(frames), len(names)))
    for f, rec in enumerate(frames):
        for region, weights in rec["weights"].items():
            for expr, w in weights.items():
                i = index.get(f"{expr}_{region}")
                if i is not None:
                    W[f, i] = w
        for shape, w in rec.get("arkit", {}).items():
            i = index.get(shape)
            if i is not None:
                W[f, i] = w
    cam = doc["camera"]
    return Performance(
        times_s=np.array([r["frame"] for r in frames], float) / fps,
        weights=W,
        rotation=np.array([r["R"] for r in frames], float),
        translation_mm=np.array([r["t_mm"] for r in frames], float),
        focal_px=float(cam["focal_px"]),
        width=int(cam["width"]),
        height=int(cam["height"]),
    )


def arkit_weights(
    shapes: BlendShapes, weights: np.ndarray, mask: np.ndarray | None = None, progress=None
) -> np.ndarray:
    """(f, r) the rig's weights in [0, 1] closest to the frames posed by the photographed targets'
    ``weights`` (f, k) (bounded least squares over the vertices of ``mask``, default all): a tracked
    performance said in ARKit's shapes, for other tools (Live Link CSV). A model of the neutral
    alone (k = 0: head pose only) poses no expression: every weight is 0. ``progress(done, f)``,
    optional, after each frame."""
    r = shapes.rig_shapes
    if r == 0:
        raise FaceStudioError("the project has no rig; run `facestudio rig` first")
    W = np.asarray(weights, float).reshape(len(weights), -1)
    W = W[:, r:] if W.shape[1] == len(shapes.names) else W
    k = len(shapes.deltas) - r
    if k == 0 or W.shape[1] == 0:
        return np.zeros((len(W), r))
    sel = slice(None) if mask is None else np.asarray(mask, bool)
    A = shapes.deltas[:r, sel].reshape(r, -1).T  # (3n', r)
    B = shapes.deltas[r:, sel].reshape(k, -1).T  # (3n', k)
    # |A x - B w|² = |R x - Qᵀ B w|² + a constant (A = QR): each frame's bounded solve is then
    # r × r instead of 3n' × r, the same minimum (1e-9 apart) ~20× faster
    Q, R = np.linalg.qr(A)
    QB = Q.T @ B  # (r, k)
    out = np.zeros((len(W), r))
    for i, w in enumerate(W):
        out[i] = lsq_linear(R, QB @ w, bounds=(0.0, 1.0)).x
        if progress is not None:
            progress(i + 1, len(W))
    return out


def tracked_arkit_weights(doc: dict, shapes: list[str]) -> np.ndarray | None:
    """(f, k) the tracked ARKit weights of ``doc``'s frames over ``shapes`` (0 for a shape the track
    did not have), or None when the track is not in ARKit terms (``model.arkit`` empty)."""
    if not doc.get("model", {}).get("arkit"):
        return None
    return np.array([[rec.get("arkit", {}).get(n, 0.0) for n in shapes] for rec in doc["frames"]], float)


def rigged_glb_bytes(shapes: BlendShapes, perf: Performance | None = None) -> bytes:
    """The glb of ``shapes`` (every blend shape a morph target, textured), animated by ``perf``."""
    return encode_rigged_glb(
        shapes.neutral,
        shapes.faces,
        shapes.deltas,
        shapes.names,
        uv=shapes.uv,
        texture=shapes.texture_png,
        performance=perf,
    )


def track_livelink_bytes(doc: dict, shapes: BlendShapes, perf: Performance, face_mask=None, progress=None) -> bytes:
    """The Live Link Face CSV of a tracked performance: the tracked ARKit weights themselves
    (:func:`tracked_arkit_weights`) where the track is in ARKit terms, else the rig's weights fitted
    to each frame (:func:`arkit_weights`, ``progress(done, f)``); head yaw/pitch/roll."""
    rig_names = shapes.names[: shapes.rig_shapes]
    arkit = tracked_arkit_weights(doc, rig_names)
    if arkit is None:  # a track of the photographed expressions: said in ARKit's shapes by fitting
        arkit = arkit_weights(shapes, perf.weights, face_mask, progress=progress)
    full = np.zeros((len(arkit), len(ARKIT_SHAPES)))
    full[:, [ARKIT_SHAPES.index(n) for n in rig_names]] = arkit
    head = np.radians([r["head_rotation_deg"] for r in doc["frames"]])  # pitch, yaw, roll
    rot = np.zeros((len(full), len(ROTATION_COLUMNS)))
    rot[:, :3] = head[:, [1, 0, 2]]
    return livelink_csv_bytes(full, float(doc["video"]["fps"]), rot)


def export_track(project, doc: dict, glb, csv=None) -> dict:
    """Write the animated glb of a ``track.json`` document ``doc`` (the targets of
    :func:`blend_shapes` on the tracked expressions, animated by :func:`track_performance`) and,
    with ``csv``, its Live Link Face CSV (:func:`track_livelink_bytes`). Both are encoded before
    either is written. What ``facestudio export --track`` writes. Returns
    ``{"targets", "rig_names", "frames"}``.

    Raises FaceStudioError when ``csv`` is asked of a project without a rig (before anything is
    written), or the track holds no frame."""
    shapes, model = blend_shapes(project, doc["model"]["expressions"])
    if csv is not None and shapes.rig_shapes == 0:
        raise FaceStudioError("the Live Link CSV carries the rig's ARKit weights: the project has no rig")
    perf = track_performance(doc, shapes.names)
    files = {glb: rigged_glb_bytes(shapes, perf)}
    if csv is not None:
        files[csv] = track_livelink_bytes(doc, shapes, perf, model.face_mask)
    write_files(files)
    rig_names = shapes.names[: shapes.rig_shapes]
    return {"targets": len(shapes.names), "rig_names": list(rig_names), "frames": len(perf.times_s)}
