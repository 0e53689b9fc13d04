"""A person's ARKit rig predicted by the multilinear model from their neutral and a few expressions.

Seed 000 (Vlasic et al. 2005, §5.1): with the expression weights ``w3`` of a face known, the model
``f = f̄ + Ǔ1 (C ×2 w2ᵀ ×3 w3ᵀ)`` is linear in the identity weights ``w2``, so the person's neutral and
photographed expressions place them in the model's identity space by linear least squares
(:func:`fit_rig_identity`: the expressions enter as displacements from the neutral, see
:data:`DISPLACEMENT_WEIGHT`); the model then gives every
ARKit shape of that identity, ``D_s = Ǔ1 (C ×2 w2ᵀ ×3 (u_{1+s} − u_0)ᵀ)`` (``u_e`` the rows of ``Ǔ3``: the
expression mode is linear, so a mix of shapes has the weights ``u_0 + Σ a_s (u_{1+s} − u_0)``).

An expression's weights are **known** when its name is an ARKit shape's (:data:`photomodel.rig.ict.RIG_SHAPES`:
the face photographed doing that shape fully). Any other expression (``smile``, ``frown``…) is a mix of
shapes the model solves for: the identity from the known faces first, then each other face's mix
``a`` in [0, 1] by bounded least squares with that identity, then the identity again from all faces,
:data:`ROUNDS` times (the alternation of seed 000 §5.1, with the expression mode in ARKit terms).

**Beyond the seed:** the shapes are displacements added to the person's own neutral (as the cloning does),
not the model's reconstruction of the whole face; a shape that was photographed on its own (an ARKit
name) keeps its photographed displacement.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy.optimize import lsq_linear

from photomodel.people.multilinear import MultilinearModel

__all__ = [
    "ROUNDS",
    "RIG_RIDGE",
    "DISPLACEMENT_WEIGHT",
    "PredictedRig",
    "shape_displacements",
    "fit_rig_identity",
    "predict_rig",
]

#: Rounds of (identity, mixes of the unnamed expressions).
ROUNDS = 3
#: Ridge of :func:`fit_rig_identity` (× the mean squared core entry per person) and the weight of the
#: expressions' displacement equations against the neutral's. Measured on 12 held-out ICT people (mean
#: error of the shapes not given, mm): given 5 shapes, ridge 1 and weight 1e5 gave 0.036 (weight 1: 0.064,
#: 1e4: 0.040, 1e6: 0.035; ridge 0.01 and weight 1e4: 0.036); given none, ridge 1 gave 0.067 (0.1: 0.079,
#: 0.01: 0.136). The neutral's equations are mm of identity over the whole head, the displacements
#: tenths of mm on part of the face: the weight makes the identity explain the expressions, with
#: the neutral and the ridge as its prior.
RIG_RIDGE = 1.0
DISPLACEMENT_WEIGHT = 1e5


@dataclass
class PredictedRig:
    """The rig of :func:`predict_rig`.

    Attributes
    ----------
    names : tuple of 51 str, the model's ARKit shapes (its expressions after the neutral).
    deltas : (51, n, 3) float mm, each shape's displacement of the person's neutral.
    identity : (r2,) float, the person's identity weights in the model.
    mixes : {expression name: {shape: weight}} the solved mixes of the unnamed expressions (weights > 0.01).
    report : dict, facts for the project's rig record.
    """

    names: tuple
    deltas: np.ndarray
    identity: np.ndarray
    mixes: dict = field(default_factory=dict)
    report: dict = field(default_factory=dict)


def shape_displacements(model: MultilinearModel, identity: np.ndarray) -> np.ndarray:
    """(E − 1, d) mm: the model's displacement of each expression after the neutral for ``identity`` (r2,)."""
    rows = model.expression_rows
    G = model.expression_space(identity) @ (rows[1:] - rows[0]).T  # (r1, E - 1)
    return (model.vertex_basis @ G).T


def fit_rig_identity(
    model: MultilinearModel,
    neutral: np.ndarray,
    displacements: np.ndarray | None = None,
    expression_steps: np.ndarray | None = None,
    ridge: float = RIG_RIDGE,
    weight: float = DISPLACEMENT_WEIGHT,
) -> np.ndarray:
    """(r2,) identity weights of a person from their neutral (n, 3) mm and the displacements (k, d) mm of
    faces whose expression weights differ from the neutral's by ``expression_steps`` (k, r3).

    Linear least squares over ``Ǔ1ᵀ(P⁰ − f̄) = (C ×3 u_0) w2`` and ``weight`` × ``Ǔ1ᵀ Δ_j = (C ×3 Δu_j) w2``
    (the model is linear in ``w2`` with ``w3`` known, seed 000 §5.1), ridge ``ridge`` × the mean squared
    core entry per person towards the training people's mean identity."""
    C, U1 = model.core, model.vertex_basis
    A0 = np.einsum("abc,c->ab", C, model.expression_rows[0])
    lhs = A0.T @ A0
    rhs = A0.T @ model.coordinates(np.asarray(neutral, float).ravel())
    if displacements is not None and len(displacements):
        Ad = np.einsum("abc,kc->kab", C, np.asarray(expression_steps, float))  # (k, r1, r2)
        gd = np.asarray(displacements, float).reshape(len(Ad), -1) @ U1  # (k, r1)
        lhs = lhs + weight * np.einsum("kab,kac->bc", Ad, Ad)
        rhs = rhs + weight * np.einsum("kab,ka->b", Ad, gd)
    lam = ridge * np.sum(C**2) / max(len(model.identity_rows), 1)
    return np.linalg.solve(lhs + lam * np.eye(len(lhs)), rhs + lam * model.identity_rows.mean(axis=0))


def predict_rig(
    model: MultilinearModel, neutral: np.ndarray, expressions: dict | None = None, rounds: int = ROUNDS
) -> PredictedRig:
    """The person's 51 ARKit shapes predicted by ``model`` (see the module notes).

    Parameters
    ----------
    model : the multilinear model (:mod:`photomodel.people.model_file`), of the same mesh.
    neutral : (n, 3) float mm, the person's neutral.
    expressions : {name: (n, 3) float mm} the person's other photographed faces, in the neutral's head
        frame; a name among the model's expressions is that shape done fully, any other a mix to solve.
    rounds : rounds of (identity, mixes) when some expression is unnamed.

    Returns
    -------
    :class:`PredictedRig`.
    """
    P0 = np.asarray(neutral, float)
    if P0.ndim != 2 or P0.shape[1] != 3 or model.mean.shape != (P0.size,):
        raise ValueError(f"the neutral must be the model's mesh ({model.mean.size // 3}, 3) mm, got {P0.shape}")
    expressions = dict(expressions or {})
    index = {name: e for e, name in enumerate(model.expression_names)}
    named = {k: v for k, v in expressions.items() if k in index and index[k] > 0}
    unnamed = {k: v for k, v in expressions.items() if k not in named}
    shapes = len(model.expression_names) - 1
    rows = model.expression_rows
    steps = rows[1:] - rows[0]  # (51, r3): a shape's expression weights less the neutral's
    disp = [np.asarray(v, float).ravel() - P0.ravel() for v in named.values()]
    known = [steps[index[k] - 1] for k in named]
    identity = fit_rig_identity(model, P0, np.array(disp), np.array(known))
    mixes = {}
    if unnamed:
        U1 = model.vertex_basis
        extra = [np.asarray(v, float).ravel() - P0.ravel() for v in unnamed.values()]
        targets = [d @ U1 for d in extra]
        for _ in range(max(rounds, 1)):
            D = shape_displacements(model, identity) @ U1  # (51, r1) the shapes in Ǔ1's coordinates
            mixes = dict(zip(unnamed, (lsq_linear(D.T, g, bounds=(0.0, 1.0)).x for g in targets), strict=True))
            solved_steps = [a @ steps for a in mixes.values()]
            identity = fit_rig_identity(model, P0, np.array(disp + extra), np.array(known + solved_steps))
    deltas = shape_displacements(model, identity).reshape(shapes, *P0.shape)
    for k, v in named.items():  # photographed on its own: the photograph is the shape
        deltas[index[k] - 1] = np.asarray(v, float) - P0
    names = tuple(model.expression_names[1:])
    solved = {k: {names[s]: round(float(a[s]), 3) for s in np.flatnonzero(a > 0.01)} for k, a in mixes.items()}
    report = {
        "method": "multilinear",
        "model_people": len(model.people),
        "model_ranks": list(model.ranks),
        "given_shapes": list(named),
        "given_mixes": solved,
    }
    return PredictedRig(names, deltas, identity, solved, report)
