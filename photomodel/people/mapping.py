"""Seed 001's expression cloning: a linear map between two person-specific expression spaces.

Theobald, Matthews, Cohn, Baker? — *Real-time expression cloning using appearance models* (ICMI 2007), §3.
Each person has their own linear model of shape, the PCA of *their own* expression set (the
expressions photographed of them: different people, different sets; the neutral included):

    s = s̄ + S p,        S (d, r) orthonormal columns, variances γ (r,)       (seed 001 Eq. 1)

A performance of the source person (parameters ``p_s = Sᵀ(x − s̄)``) maps to the target through the
inner products of the two bases, ``R = S*ᵀ S`` (q, r) (Eq. 3),

    s* = s̄* + S* clip(R p_s, ±3 √γ*)                                           (Eq. 3 + §3.1's limits)

and the part of each source vector the target space cannot represent is added back (§3.2, Eq. 4):

    δ_i = (S_i − S* R_i) √γ_i     (per +1σ of source component i),     s* += Σ_i δ_i p_i / √γ_i

**Sign:** the seed writes the residual as ``δ_t − δ_s`` (target's reconstruction minus the source
perturbation); adding that would *subtract* the lost component, so we use ``δ_s − δ_t``, which is what its
text describes ("the component of the i-th source vector that cannot be reconstructed by the target").
Without the ±3σ clipping, Eq. 4 reduces to ``s̄* + S p_s``: the source's projected displacement from its
own mean, copied.

**Beyond the seed:** the two people's meshes share vertices (the generic mesh), and the source's vectors
are first brought into the target's head frame by the similarity (Umeyama, :func:`photomodel.alignment.
similarity_transform`) of the source's neutral onto the target's over the face, so that "same dimension
Euclidean space" holds; :func:`displacement_copy` is the baseline the seed compares against (§4):
the source's displacement from its neutral, aligned the same way, added to the target's neutral.

**The base** (seed 001 §3 assumes the two bases are similar expressions; §5 allows any reference
expression): :func:`expression_space` takes the mean by default (Eq. 1) or a reference shape; the
studio and the benchmark take each person's **neutral**. The seed's people are filmed in similar
performances, whose means converge (its Fig. 2); ours are photographed in different expression sets,
whose means are different expressions, and mapping about them added the difference of the two sets'
mean expressions to every frame (measured, 2026-12-05, on 3 × 50 pairs of the model's people, not the
benchmark's: mapping / its floor 1.15–1.29× about the means, 1.02–1.15× about the neutrals).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from photomodel.alignment import similarity_transform

__all__ = [
    "ExpressionSpace",
    "ExpressionMapping",
    "expression_space",
    "align_similarity",
    "displacement_copy",
    "LIMIT_SIGMA",
    "MIN_VARIANCE",
]

#: Mapped parameters are kept within this many standard deviations of the target's own data (§3.1).
LIMIT_SIGMA = 3.0
#: Components with a variance below this fraction of the largest are dropped (numerically null).
MIN_VARIANCE = 1e-10


@dataclass
class ExpressionSpace:
    """One person's expression model (seed 001 Eq. 1).

    Attributes
    ----------
    mean : (d,) float mm, ``s̄`` (d = 3n).
    basis : (d, r) float, ``S`` (orthonormal columns).
    variances : (r,) float mm², ``γ``.
    """

    mean: np.ndarray
    basis: np.ndarray
    variances: np.ndarray

    def parameters(self, shapes: np.ndarray) -> np.ndarray:
        """(…, r): ``Sᵀ (x − s̄)`` of shapes (…, d)."""
        return (np.asarray(shapes, float) - self.mean) @ self.basis

    def project(self, shapes: np.ndarray) -> np.ndarray:
        """(…, d): shapes projected into the space (the best this person's model can show)."""
        return self.mean + self.parameters(shapes) @ self.basis.T


def expression_space(shapes: np.ndarray, reference: int | None = None) -> ExpressionSpace:
    """The PCA of a person's own expressions ``shapes`` (k, d) mm (all components of nonzero variance).

    ``reference``: None, the base ``s̄`` is the shapes' mean (seed 001 Eq. 1); an index, the base is that
    shape (seed 001 §5: "no reason the base vectors need be their respective means"; the reference
    expression, with the basis and the variances ``γ`` taken about it). The space (the affine span of the
    shapes) is the same either way; the base is what Eq. 3 maps parameters about, so two people's bases must
    be the same expression (§3): with different expression sets their means are different expressions,
    their neutrals are not.
    """
    X = np.asarray(shapes, float)
    if X.ndim != 2 or len(X) < 2:
        raise ValueError(f"an expression space needs at least two shapes (k, d), got {X.shape}")
    if reference is not None and not -len(X) <= reference < len(X):
        raise ValueError(f"reference {reference} is not one of the {len(X)} shapes")
    mean = X.mean(axis=0) if reference is None else X[reference].copy()
    # γ: the shapes' mean squared parameter about the base (k − 1 degrees of freedom: the mean, or the
    # reference whose parameters are zero)
    _, sv, Vt = np.linalg.svd(X - mean, full_matrices=False)
    var = sv**2 / (len(X) - 1)
    keep = var > MIN_VARIANCE * max(var[0], 1e-300)
    return ExpressionSpace(mean, Vt[keep].T, var[keep])


def align_similarity(source_neutral: np.ndarray, target_neutral: np.ndarray, mask=None):
    """``(s, R, t)`` taking the source's neutral (n, 3) onto the target's over ``mask`` (n,) bool
    (default all): ``x ↦ s R x + t``."""
    m = slice(None) if mask is None else np.asarray(mask, bool)
    return similarity_transform(np.asarray(source_neutral, float)[m], np.asarray(target_neutral, float)[m])


def _rotate(vectors: np.ndarray, s: float, R: np.ndarray) -> np.ndarray:
    """(…, d) vectors of (n, 3) displacements turned and scaled: ``s R v`` per vertex."""
    v = np.asarray(vectors, float)
    return (s * v.reshape(*v.shape[:-1], -1, 3) @ R.T).reshape(v.shape)


def displacement_copy(frames: np.ndarray, source_neutral: np.ndarray, target_neutral: np.ndarray, mask=None):
    """(f, d): the source frames' displacements (f, d) from its neutral (n, 3), similarity-aligned onto
    the target (seed 001 §4's baseline), added to the target's neutral (n, 3)."""
    s, R, _ = align_similarity(source_neutral, target_neutral, mask)
    disp = np.asarray(frames, float) - np.asarray(source_neutral, float).ravel()
    return np.asarray(target_neutral, float).ravel() + _rotate(disp, s, R)


@dataclass
class ExpressionMapping:
    """Seed 001's map from a source person's expression space to a target's (Eq. 3–4).

    Built by :meth:`between`; :meth:`__call__` maps frames. ``residual`` adds Eq. 4's term.
    """

    source: ExpressionSpace
    target: ExpressionSpace
    inner: np.ndarray  # (q, r) R = S*ᵀ S (aligned)
    residual_vectors: np.ndarray  # (d, r) (S − S* R) per unit source parameter, aligned
    aligned_source_basis: np.ndarray  # (d, r)
    limits: np.ndarray  # (q,) ± LIMIT_SIGMA √γ*
    residual: bool = True
    _stacked: np.ndarray | None = None

    @classmethod
    def between(
        cls,
        source: ExpressionSpace,
        target: ExpressionSpace,
        similarity=None,
        residual: bool = True,
    ) -> ExpressionMapping:
        """The map of ``source`` onto ``target``; ``similarity`` ``(s, R)`` turns the source's vectors
        into the target's frame (:func:`align_similarity`; default none)."""
        s, Rot = (1.0, np.eye(3)) if similarity is None else (similarity[0], similarity[1])
        S = _rotate(source.basis.T, s, Rot).T  # (d, r) aligned, scaled by s
        inner = target.basis.T @ S  # (q, r) Eq. 3's R
        res = S - target.basis @ inner  # §3.2 per unit parameter (sign: δ_s − δ_t)
        return cls(source, target, inner, res, S, LIMIT_SIGMA * np.sqrt(target.variances), residual)

    def map_parameters(self, p_source: np.ndarray) -> np.ndarray:
        """(…, q): the target parameters of source parameters (…, r), within ±3σ."""
        return np.clip(np.asarray(p_source, float) @ self.inner.T, -self.limits, self.limits)

    def __call__(self, frames: np.ndarray) -> np.ndarray:
        """(f, d) target shapes of source frames (f, d) mm (Eq. 3, plus Eq. 4 when ``residual``)."""
        p = self.source.parameters(frames)
        if not self.residual:
            return self.target.mean + self.map_parameters(p) @ self.target.basis.T
        if self._stacked is None:  # one product for Eq. 3's and Eq. 4's terms
            self._stacked = np.concatenate([self.target.basis, self.residual_vectors], axis=1).T
        return self.target.mean + np.concatenate([self.map_parameters(p), p], axis=1) @ self._stacked
