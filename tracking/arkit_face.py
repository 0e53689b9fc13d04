"""Tracking in ARKit terms: the rig's 51 shapes as the tracker's expression basis (beyond the paper).

Pighin et al. (2002, §6.1.1) track with the photographed expressions, blended per control region.
A project with a rig (``facestudio rig``: ICT-FaceKit's expressions moved onto the fitted neutral,
:mod:`photomodel.rig`) can be tracked in the shapes other tools speak — ARKit's — so that the
tracked weights *are* the glb's ARKit channels and the Live Link CSV's columns.

The bases (:data:`BASES`):

* ``"arkit"`` — the neutral and the rig's shapes: ``X = E_1 + Σ_k a_k D_k`` with ``a_k`` in
  [0, 1]. Every shape acts on the whole face at once (the rig's shapes are local already: the
  build keeps each where ICT's shape moves the skin), so they are a *shared* basis of the
  :class:`tracking.blendshape_face.FaceModel` (no control region has a parameter); the texture
  is the neutral's.
* ``"photographed"`` — the paper's model (:func:`tracking.face_from_project.project_face_model`).
* ``"both"`` — the photographed expressions per region *and* the rig's shapes on top: what a
  region's photographs show is explained by them, the rest by the shapes.

:func:`with_shared_shapes` adds shapes to any face model: each shape is one more expression of the
model whose geometry is its displacement (mm) and whose texture is black (a displacement moves
the surface and adds no colour), driven by a column of the shared basis scaled so that one unit
of ``α`` moves the face by at most 1 mm (the tracker's step tolerances are in mm); the shape's
weight is ``a_k = α_k / s_k`` (:func:`shape_weights`).

What the views cannot separate is decided by priors (:class:`tracking.frame_fit.TrackOptions`'s
``sparsity``, ``symmetry``, ``smoothness``) and the bounds (the penalty D of §6.1.2 on [0, 1];
the recorded weights are clipped to [0, 1]); docs/tracking.md says what was chosen and measured.
"""

from __future__ import annotations

import numpy as np

from photomodel.errors import FaceStudioError, ProjectError
from photomodel.project import load_rig_shapes
from tracking.blendshape_face import FaceModel
from tracking.face_from_project import face_model_from_project, model_expressions, project_face_model

__all__ = [
    "BASES",
    "MIN_SHAPE_MM",
    "default_basis",
    "basis_of",
    "with_shared_shapes",
    "shape_weights",
    "arkit_face_model",
    "tracking_face_model",
    "model_for_results",
]

#: The expression bases ``track`` can use.
BASES = ("arkit", "photographed", "both")
#: A shape whose largest displacement is under this (mm) is left out of the basis: the views
#: cannot see it, and its weight would be the priors' alone.
MIN_SHAPE_MM = 0.2
#: The displacement shapes' texture: black (they add no colour; see the module notes).
_BLACK = np.zeros((4, 4, 3), np.float32)


def default_basis(project) -> str:
    """``"arkit"`` when the project has a rig, else ``"photographed"``."""
    return "arkit" if getattr(project, "rig", None) is not None else "photographed"


def basis_of(model: FaceModel) -> str:
    """The basis a face model tracks with (:data:`BASES`): ``"photographed"`` without shared shapes,
    ``"arkit"`` with them and the neutral alone, else ``"both"``."""
    if not model.n_shared:
        return "photographed"
    return "arkit" if model.m - int(model.shared_expressions.sum()) == 1 else "both"


def with_shared_shapes(model: FaceModel, names, deltas: np.ndarray, min_mm: float = MIN_SHAPE_MM) -> FaceModel:
    """``model`` with the shapes ``names`` (k,) of displacements ``deltas`` (k, n, 3) mm (from
    ``model``'s E_1) added as a shared basis (see the module notes). Shapes moving no vertex by
    ``min_mm`` or more are left out."""
    D = np.asarray(deltas, float)
    names = list(names)
    if D.shape != (len(names), *model.geometry.shape[1:]):
        raise ValueError(f"deltas must be ({len(names)}, {model.geometry.shape[1]}, 3) mm, got {D.shape}")
    reach = np.linalg.norm(D, axis=2).max(axis=1)  # (k,) mm, each shape's largest motion
    keep = np.flatnonzero(reach >= min_mm)
    m, k = model.m, len(keep)
    shared = np.zeros((m + k, k))
    shared[m + np.arange(k), np.arange(k)] = 1.0 / reach[keep]
    bases = [np.vstack([Q, np.zeros((k, Q.shape[1]))]) for Q in model.bases]
    return FaceModel(
        names=tuple(model.names) + tuple(names[i] for i in keep),
        geometry=np.concatenate([model.geometry, D[keep]]),
        faces=model.faces,
        uv=np.concatenate([model.uv, np.zeros((k, *model.uv.shape[1:]))]),
        textures=list(model.textures) + [_BLACK] * k,
        regions=model.regions,
        membership=model.membership,
        bases=bases,
        centre=model.centre,
        face_mask=model.face_mask,
        shared=shared,
    )


def shape_weights(model: FaceModel, region_weights: np.ndarray) -> dict[str, float]:
    """{shape: weight in [0, 1]} of the shared shapes from a frame's :meth:`FaceModel.region_weights`
    (its last row); empty without a shared basis."""
    if not model.n_shared:
        return {}
    row = np.asarray(region_weights, float)[-1]
    return {model.names[i]: float(np.clip(row[i], 0.0, 1.0)) for i in np.flatnonzero(model.shared_expressions)}


def arkit_face_model(project, basis: str = "arkit", expressions=None) -> tuple[FaceModel, str]:
    """The face model of ``project`` with the rig's shapes: ``basis`` ``"arkit"`` (the neutral and the
    shapes) or ``"both"`` (the photographed ``expressions``, default all, and the shapes); and a
    sentence saying where it comes from.

    Raises
    ------
    ProjectError when the project has no rig or its rig was made on another neutral;
    what :func:`tracking.face_from_project.face_model_from_project` raises.
    """
    if basis not in ("arkit", "both"):
        raise ValueError(f"basis must be 'arkit' or 'both', got {basis!r}")
    if project.rig is None:
        where = project.path if project.path is not None else project.name
        raise ProjectError(
            f"{where}: tracking in ARKit terms needs the project's rig; run `facestudio rig {where}` "
            f"(or track with --basis photographed)"
        )
    names = model_expressions(project, expressions)
    if names[0] != project.rig.neutral:
        raise FaceStudioError(
            f"the rig was made on {project.rig.neutral!r} but the face model's neutral is {names[0]!r}; "
            f"run `facestudio rig` again"
        )
    base, _report = face_model_from_project(project, names[:1] if basis == "arkit" else names)
    rig_names, deltas = load_rig_shapes(project)
    model = with_shared_shapes(base, rig_names, deltas)
    kept = model.n_shared
    photographed = ", ".join(base.names[1:]) or "none"
    return model, (
        f"project: {base.names[0]} and the rig's {kept} ARKit shapes ({project.rig.source}, shared by the "
        f"whole face; weights in [0, 1]); photographed expressions per region: {photographed}"
    )


def tracking_face_model(project, basis: str | None = None, expressions=None) -> tuple[FaceModel, str, str]:
    """The face model ``track`` uses: ``(model, source sentence, basis)``; ``basis`` None chooses
    :func:`default_basis`."""
    basis = default_basis(project) if basis is None else basis
    if basis not in BASES:
        raise FaceStudioError(f"the expression basis must be one of {', '.join(BASES)}; got {basis!r}")
    if basis == "photographed":
        model, source = project_face_model(project, expressions)
        return model, source, basis
    model, source = arkit_face_model(project, basis, expressions)
    return model, source, basis


def model_for_results(project, doc: dict) -> FaceModel:
    """The face model a ``track.json`` document was tracked with, rebuilt from ``project`` (its
    ``model.basis``, default photographed, and ``model.expressions``)."""
    model = doc.get("model", {})
    basis = model.get("basis", "photographed")
    names = model.get("expressions")
    return tracking_face_model(project, basis, names)[0]
