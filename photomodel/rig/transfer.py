"""Deformation transfer (Sumner & Popović 2004): ICT's expressions moved onto a person's neutral.

Source and target share the generic mesh's triangles: the source is ICT's neutral ``S⁰`` and its
expressions ``Sᵉ = S⁰ + Dᵉ`` resampled onto the generic mesh (:mod:`photomodel.rig.registration`),
the target is the person's fitted neutral ``P⁰`` (n, 3). For every triangle ``j = (a, b, c)`` the
source's *deformation gradient* (S&P §3, Eq. 3–4, with their fourth vertex along the normal)

    V(X) = [x_b − x_a,  x_c − x_a,  (x_b − x_a) × (x_c − x_a) / √|(x_b − x_a) × (x_c − x_a)|]
    T_j  = V(Sᵉ) V(S⁰)⁻¹                                                     (3, 3)

says how the expression stretches and turns that piece of skin. The person's expression ``Pᵉ``
takes the same gradients on *its own* triangles: in S&P's vertex formulation (§4, Eq. 5), solved
for the displacement ``d = Pᵉ − P⁰`` as one sparse linear least-squares problem over the three
edges ``(p, q)`` of every triangle,

    min_d  Σ_j Σ_(p,q)∈j ‖(d_q − d_p) − (T_j − I)(P⁰_q − P⁰_p)‖²  +  μ Σ_i∈A ‖d_i − Dᵉ_i‖²

i.e. ``(GᵀWG + μ Π_A) d = GᵀW r + μ Π_A Dᵉ`` with ``G`` (3m, n) the edge-difference matrix
(``scipy.sparse``) and ``W`` the edge weights, factorised once (:class:`DeformationTransfer`) for
every shape, coordinate and person. Triangles with a corner ICT does not cover take
``T_j = I`` with a small weight (they follow their neighbours). The anchors ``A`` fix the
translation the edges leave free (S&P fix one vertex): they take the source's own displacement
``Dᵉ_i``, with weight :data:`ANCHOR_WEIGHT`; the rig passes the vertices away from the face
(the back of the head, the neck; where ICT's face area ends, ``Dᵉ`` there is that of the nearest
ICT point).

With ``P⁰ = S⁰`` the transfer gives back ``Sᵉ`` exactly (the edges are then consistent).
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sparse
from scipy.sparse.linalg import splu

__all__ = [
    "DeformationTransfer",
    "deformation_gradients",
    "soft_triangles",
    "transfer_deformations",
    "ANCHOR_WEIGHT",
    "SOFT_WEIGHT",
    "MIN_DET",
]

#: ``|det V(S⁰)|`` (mm^1.5·mm) below which a source triangle is degenerate: several generic
#: vertices resampled onto one ICT point (outside ICT's face area).
MIN_DET = 1e-6
#: Weight of the edges of a triangle the source says nothing about (it keeps its shape).
SOFT_WEIGHT = 1e-3
#: Weight μ of the anchors against the unit-weight edges.
ANCHOR_WEIGHT = 10.0
#: The three edges of a triangle as corner pairs.
_EDGES = ((0, 1), (0, 2), (1, 2))


def _frames(X: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """(…, m, 3, 3) ``V(X)`` of every triangle, columns: the two edges and the scaled normal."""
    a, b, c = (X[..., faces[:, k], :] for k in range(3))
    e1, e2 = b - a, c - a
    n = np.cross(e1, e2)
    n = n / np.sqrt(np.maximum(np.linalg.norm(n, axis=-1, keepdims=True), 1e-12))
    return np.stack([e1, e2, n], axis=-1)


def deformation_gradients(neutral: np.ndarray, deformed: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """``T_j = V(deformed) V(neutral)⁻¹`` of every triangle (S&P Eq. 4).

    Parameters
    ----------
    neutral : (n, 3) float, deformed : (n, 3) or (k, n, 3) float, faces : (m, 3) int.

    Returns
    -------
    (m, 3, 3) or (k, m, 3, 3) float
    """
    V0 = _frames(np.asarray(neutral, float), faces)
    V1 = _frames(np.asarray(deformed, float), faces)
    flat = np.abs(np.linalg.det(V0)) < MIN_DET
    V0[flat] = np.eye(3)  # degenerate: reported as no deformation
    T = V1 @ np.linalg.inv(V0)
    T[..., flat, :, :] = np.eye(3)
    return T


def _edge_matrix(faces: np.ndarray, n: int) -> sparse.csr_matrix:
    """``G`` (3m, n): row ``3j + k`` is ``x_q − x_p`` of edge ``k`` of triangle ``j``."""
    p = np.stack([faces[:, i] for i, _ in _EDGES], axis=1).ravel()
    q = np.stack([faces[:, k] for _, k in _EDGES], axis=1).ravel()
    rows = np.arange(len(p))
    return sparse.csr_matrix(
        (np.r_[-np.ones(len(p)), np.ones(len(q))], (np.r_[rows, rows], np.r_[p, q])), shape=(len(p), n)
    )


class DeformationTransfer:
    """The transfer's normal equations for one triangle mesh, factorised once (see the module notes).

    Parameters
    ----------
    faces : (m, 3) int, n : int (vertices).
    soft : (m,) bool, triangles the source says nothing about (they keep their shape, weight
        :data:`SOFT_WEIGHT`).
    anchors : (n,) bool, vertices that take the source's displacement (weight :data:`ANCHOR_WEIGHT`);
        at least one.
    """

    def __init__(self, faces: np.ndarray, n: int, soft: np.ndarray, anchors: np.ndarray):
        self.faces = np.asarray(faces, np.int64)
        self.soft = np.asarray(soft, bool)
        self.anchors = np.asarray(anchors, bool)
        if not self.anchors.any():
            raise ValueError("deformation transfer needs at least one anchor vertex (it fixes the translation)")
        self._G = _edge_matrix(self.faces, n)
        self._GtW = self._G.T @ sparse.diags(np.repeat(np.where(self.soft, SOFT_WEIGHT, 1.0), 3))
        K = self._GtW @ self._G + sparse.diags(ANCHOR_WEIGHT * self.anchors.astype(float))
        self._lu = splu(K.tocsc())

    def __call__(self, source_neutral: np.ndarray, source_deltas: np.ndarray, target_neutral: np.ndarray) -> np.ndarray:
        """(k, n, 3) mm, ``Pᵉ − P⁰`` for source ``S⁰`` (n, 3), ``Dᵉ`` (k, n, 3), target ``P⁰`` (n, 3)."""
        S0 = np.asarray(source_neutral, float)
        D = np.asarray(source_deltas, float)
        P0 = np.asarray(target_neutral, float)
        n, m = self._G.shape[1], len(self.faces)
        if S0.shape != (n, 3) or P0.shape != (n, 3) or D.ndim != 3 or D.shape[1:] != (n, 3):
            raise ValueError(
                f"neutrals (n, 3) and deltas (k, n, 3) with n = {n} expected, got {S0.shape}, {P0.shape} and {D.shape}"
            )
        T = deformation_gradients(S0, S0 + D, self.faces)  # (k, m, 3, 3)
        T[:, self.soft] = np.eye(3)
        edges = (self._G @ P0).reshape(m, 3, 3)  # (m, 3 edges, xyz)
        r = np.einsum("kmij,mej->kmei", T - np.eye(3), edges).reshape(len(D), -1, 3)  # (k, 3m, 3)
        pin = ANCHOR_WEIGHT * self.anchors[:, None] * D  # anchors follow the source's displacement
        rhs = np.concatenate([self._GtW @ r[e] + pin[e] for e in range(len(D))], axis=1)  # (n, 3k)
        return self._lu.solve(rhs).reshape(n, len(D), 3).transpose(1, 0, 2)


def soft_triangles(source_neutral: np.ndarray, faces: np.ndarray, covered: np.ndarray) -> np.ndarray:
    """(m,) bool: triangles with a corner the source does not cover, or degenerate in the source."""
    F = np.asarray(faces, np.int64)
    degenerate = np.abs(np.linalg.det(_frames(np.asarray(source_neutral, float), F))) < MIN_DET
    return ~np.asarray(covered, bool)[F].all(axis=1) | degenerate


def transfer_deformations(
    source_neutral: np.ndarray,
    source_deltas: np.ndarray,
    target_neutral: np.ndarray,
    faces: np.ndarray,
    covered: np.ndarray | None = None,
    anchors: np.ndarray | None = None,
) -> np.ndarray:
    """The target's displacements for every source shape (see the module notes): one
    :class:`DeformationTransfer` built and applied.

    Parameters
    ----------
    source_neutral : (n, 3) float mm, ``S⁰`` on the target's triangles.
    source_deltas : (k, n, 3) float mm, ``Dᵉ`` (``Sᵉ = S⁰ + Dᵉ``).
    target_neutral : (n, 3) float mm, ``P⁰`` (same vertices and triangles).
    faces : (m, 3) int.
    covered : (n,) bool, optional, vertices the source says something about (default all).
        A triangle with a corner not covered, or degenerate in the source (``|det V| <``
        :data:`MIN_DET`), keeps its shape (``T = I``) with the small weight :data:`SOFT_WEIGHT`:
        it follows its neighbours.
    anchors : (n,) bool, optional, vertices that take the source's displacement ``Dᵉ``
        (default: those not covered; when there are none, the vertex the source moves least).

    Returns
    -------
    (k, n, 3) float mm, ``Pᵉ − P⁰``.
    """
    S0 = np.asarray(source_neutral, float)
    D = np.asarray(source_deltas, float)
    n = len(S0)
    cov = np.ones(n, bool) if covered is None else np.asarray(covered, bool)
    anchor = ~cov if anchors is None else np.asarray(anchors, bool).copy()
    if not anchor.any():
        anchor[np.argmin(np.abs(D).max(axis=(0, 2)))] = True  # the stillest vertex fixes the translation
    return DeformationTransfer(faces, n, soft_triangles(S0, faces, cov), anchor)(S0, D, target_neutral)
