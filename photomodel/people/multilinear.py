"""Seed 000's multilinear face model: N-mode SVD of a vertices × people × expressions tensor, imputation.

Vlasic, Brand, Pfister, Popović, *Face Transfer with Multilinear Models* (SIGGRAPH 2005), §4.

Tensor algebra (§3)
-------------------
A data tensor ``T`` (d, p, E) holds ``d = 3n`` vertex coordinates (mode 1), ``p`` people (mode 2, identity)
and ``E`` expressions (mode 3). The mode-``k`` product ``T ×_k M`` transforms the mode-``k`` vectors by ``M``
(:func:`mode_product`); the **N-mode SVD** (Eq. 1–2, :func:`n_mode_svd`)

    T ×1 U1ᵀ ×2 U2ᵀ ×3 U3ᵀ = C        ⇔        T = C ×1 U1 ×2 U2 ×3 U3

takes each ``U_k`` from the left singular vectors of the mode-``k`` unfolding; truncating columns gives
the reduced model ``T ≈ C_r ×1 Ǔ1 ×2 Ǔ2 ×3 Ǔ3`` (Eq. 3). A face of identity weights ``w2`` (r2,) and
expression weights ``w3`` (r3,) is (Eq. 5)

    f = f̄ + Ǔ1 (C_r ×2 w2ᵀ ×3 w3ᵀ)

:class:`MultilinearModel` keeps the vertex mode factored (Eq. 3) rather than folded into ``M`` (Eq. 4):
the same faces, but ``Ǔ1`` (d, r1) and a small core are a few MB where ``M`` (d, r2, r3) would be
a hundred. **Beyond the seed:** the tensor is centred on the mean face ``f̄`` (d,) first (the seed
decomposes raw positions), so the truncation spends its components on variation, not on the
average head.

Imputation (§4.3)
-----------------
:func:`impute` fills the missing (person, expression) cells of an incomplete tensor. Following §4.3,
every mode's vectors — mode 2: ``x_(v,e) = T[v, :, e]`` (p,), mode 3: ``y_(v,i) = T[v, i, :]`` (E,) —
get a low-rank subspace estimated from the current fill (the top ``q_k`` left singular vectors of the
mode's unfolding: ISVD-style imputation, one of the seed's three named options and the one of its
reported trilinear experiments), each mode predicts the missing entries as the projection of its vectors
onto its subspace, and the constraints of both modes are solved **together**: every missing value takes
the least-squares value of its two equations (the mean of the two predictions), the subspaces are
estimated again and the two steps repeated (:data:`IMPUTE_ROUNDS`). Mode 1 gives no constraint on its
own (a missing cell's mode-1 vector, the whole face, is missing); the missing faces are sought in the
span of the known ones (the top :data:`VERTEX_RANK` left singular vectors: Eq. 3's mode-1 truncation).

**Beyond the seed:** the modes are fitted to the *residual* of seed 000's own "average displacement"
predictor (§4.4, :func:`average_displacement`): every person's neutral (expression 0, which must be
known) plus the expression's mean displacement over the people who have it. The ICT-derived data are
nearly additive (person + expression), a structure that per-mode subspaces of the raw tensor cannot use
when every identity is independent (the people mode is full rank). We tried, and dropped, seed 000's
PPCA formulation with a joint Mahalanobis solve (worse than this on the same data) and an ALS
factorisation of the people mode fed by the neutrals (worse than the baseline at 70 % missing).
"""

from __future__ import annotations

import io
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from photomodel.exchange.files import atomic_write_bytes

__all__ = [
    "mode_product",
    "unfold",
    "fold",
    "n_mode_svd",
    "MultilinearModel",
    "build_model",
    "average_displacement",
    "impute",
    "IMPUTE_ROUNDS",
    "IDENTITY_RIDGE",
    "IMPUTE_RANKS",
    "MODEL_FORMAT",
]

#: Rounds of (per-mode factorisation, joint fill) of :func:`impute`.
IMPUTE_ROUNDS = 50
#: Subspace sizes (people mode, expression mode) of the imputation (int, or float: a fraction of
#: the mode's size). Chosen on the model's own people, never the benchmark's held-out ones: 30 of
#: the 100 with half their cells hidden, imputed beside the other 70 complete (2026-12-05): people
#: rank 3 / 10 / 30 → 7.65 / 6.81 / 7.93 % (expression rank 0.5 with 3: 7.61 %).
IMPUTE_RANKS = (10, 1.0)
#: Vertex-mode subspace the imputation works in.
VERTEX_RANK = 400
#: ``format`` of a saved model file.
MODEL_FORMAT = "facestudio-multilinear-1"
#: Ridge of :meth:`MultilinearModel.fit_identity` (× the mean squared core entry per person): pulls a
#: person seen in few faces towards the training people's mean identity (0.1 measured best of 1e-6–10 on
#: held-out cloning).
IDENTITY_RIDGE = 0.1


def unfold(T: np.ndarray, mode: int) -> np.ndarray:
    """The mode-``mode`` unfolding (T.shape[mode], prod(others)): its columns are the mode vectors."""
    return np.moveaxis(T, mode, 0).reshape(T.shape[mode], -1)


def fold(M: np.ndarray, mode: int, shape: tuple) -> np.ndarray:
    """The inverse of :func:`unfold` for a tensor of ``shape`` (with ``shape[mode] = len(M)``)."""
    rest = [s for k, s in enumerate(shape) if k != mode]
    return np.moveaxis(M.reshape(M.shape[0], *rest), 0, mode)


def mode_product(T: np.ndarray, M: np.ndarray, mode: int) -> np.ndarray:
    """``T ×_mode M``: every mode-``mode`` vector ``v`` of ``T`` replaced by ``M v`` (seed 000, §3)."""
    shape = list(T.shape)
    shape[mode] = M.shape[0]
    return fold(M @ unfold(T, mode), mode, tuple(shape))


def _left_singular(A: np.ndarray, rank: int | None) -> np.ndarray:
    """The first ``rank`` left singular vectors of ``A`` (via the smaller Gram matrix when ``A`` is tall)."""
    r = min(A.shape) if rank is None else min(rank, min(A.shape))
    if A.shape[0] <= A.shape[1]:
        w, U = np.linalg.eigh(A @ A.T)
        return U[:, np.argsort(w)[::-1][:r]]
    w, V = np.linalg.eigh(A.T @ A)
    order = np.argsort(w)[::-1][:r]
    U = A @ V[:, order]
    return U / np.maximum(np.linalg.norm(U, axis=0), 1e-300)


def n_mode_svd(T: np.ndarray, ranks=None) -> tuple[np.ndarray, list[np.ndarray]]:
    """Seed 000's N-mode SVD (Eq. 1–3) with truncation per mode.

    Parameters
    ----------
    T : (d1, …, dN) float, the data tensor.
    ranks : sequence of N int or None, columns kept of each ``U_k`` (None: all).

    Returns
    -------
    core : (r1, …, rN) float, ``C = T ×1 U1ᵀ ×2 … ×N UNᵀ``.
    factors : list of (d_k, r_k) float, orthonormal columns.
    """
    T = np.asarray(T, float)
    ranks = [None] * T.ndim if ranks is None else list(ranks)
    if len(ranks) != T.ndim:
        raise ValueError(f"one rank per mode expected ({T.ndim}), got {len(ranks)}")
    factors = [_left_singular(unfold(T, k), r) for k, r in enumerate(ranks)]
    core = T
    for k, U in enumerate(factors):
        core = mode_product(core, U.T, k)
    return core, factors


@dataclass
class MultilinearModel:
    """A face model of identity and expression (seed 000 Eq. 3 and 5, centred; see the module notes).

    Attributes
    ----------
    mean : (d,) float mm, the mean face ``f̄`` (d = 3n, vertex-major xyz).
    vertex_basis : (d, r1) float, ``Ǔ1``.
    core : (r1, r2, r3) float, ``C_r``.
    identity_rows : (p, r2) float, ``Ǔ2``: row ``i`` is the identity weights of training person ``i``.
    expression_rows : (E, r3) float, ``Ǔ3``: row ``e`` is the weights of expression ``e``.
    expression_names : tuple of E str (expression 0 the neutral).
    people : tuple of p str, the training people.
    """

    mean: np.ndarray
    vertex_basis: np.ndarray
    core: np.ndarray
    identity_rows: np.ndarray
    expression_rows: np.ndarray
    expression_names: tuple
    people: tuple

    @property
    def ranks(self) -> tuple[int, int, int]:
        return tuple(int(s) for s in self.core.shape)

    def face(self, identity: np.ndarray, expression: np.ndarray) -> np.ndarray:
        """(d,) mm, Eq. 5: ``f̄ + Ǔ1 (C ×2 w2ᵀ ×3 w3ᵀ)`` for weights (r2,) and (r3,)."""
        g = np.einsum("abc,b,c->a", self.core, np.asarray(identity, float), np.asarray(expression, float))
        return self.mean + self.vertex_basis @ g

    def expression_space(self, identity: np.ndarray) -> np.ndarray:
        """(r1, r3): ``C ×2 w2ᵀ``, the expression basis of one identity in ``Ǔ1``'s coordinates."""
        return np.einsum("abc,b->ac", self.core, np.asarray(identity, float))

    def coordinates(self, faces: np.ndarray) -> np.ndarray:
        """(…, r1): faces (…, d) mm as ``Ǔ1ᵀ (f − f̄)``."""
        return (np.asarray(faces, float) - self.mean) @ self.vertex_basis

    def fit_identity(self, faces: np.ndarray, expressions, ridge: float = IDENTITY_RIDGE) -> np.ndarray:
        """(r2,) identity weights of a person seen in ``faces`` (k, d) mm, of the model's expressions
        ``expressions`` (k indices into :attr:`expression_names`): :meth:`fit_identity_weights` with
        those expressions' weights (rows of :attr:`expression_rows`)."""
        return self.fit_identity_weights(faces, self.expression_rows[np.asarray(expressions, int)], ridge)

    def fit_identity_weights(
        self, faces: np.ndarray, expression_weights: np.ndarray, ridge: float = IDENTITY_RIDGE
    ) -> np.ndarray:
        """(r2,) identity weights of a person seen in ``faces`` (k, d) mm whose expression weights
        ``expression_weights`` (k, r3) are known: linear least squares (the model is linear in ``w2``
        with ``w3`` fixed, seed 000 §5.1), ridge ``ridge`` × the mean squared training weight towards
        the training people's mean identity."""
        g = self.coordinates(np.atleast_2d(faces))  # (k, r1)
        A = np.einsum("abc,kc->kab", self.core, np.atleast_2d(np.asarray(expression_weights, float)))  # (k, r1, r2)
        A = A.reshape(-1, A.shape[-1])
        prior = self.identity_rows.mean(axis=0)
        lam = ridge * np.sum(self.core**2) / max(len(self.identity_rows), 1)
        lhs = A.T @ A + lam * np.eye(A.shape[1])
        return np.linalg.solve(lhs, A.T @ g.ravel() + lam * prior)

    def to_bytes(self) -> bytes:
        """The model as an ``.npz`` file's bytes (float32 arrays)."""
        buf = io.BytesIO()
        np.savez(
            buf,
            format=np.array(MODEL_FORMAT),
            mean=self.mean.astype(np.float32),
            vertex_basis=self.vertex_basis.astype(np.float32),
            core=self.core.astype(np.float32),
            identity_rows=self.identity_rows.astype(np.float32),
            expression_rows=self.expression_rows.astype(np.float32),
            expression_names=np.array(self.expression_names),
            people=np.array(self.people),
        )
        return buf.getvalue()

    def save(self, path: str | Path) -> Path:
        """Write the model to ``path`` (atomically)."""
        return atomic_write_bytes(path, self.to_bytes())

    @classmethod
    def load(cls, path: str | Path) -> MultilinearModel:
        """A model written by :meth:`save`; ``ValueError`` naming the file if it is not one."""
        try:
            with np.load(path, allow_pickle=False) as z:
                if str(z["format"]) != MODEL_FORMAT:
                    raise ValueError(f"{path}: not a {MODEL_FORMAT} file (format {z['format']})")
                return cls(
                    mean=z["mean"].astype(float),
                    vertex_basis=z["vertex_basis"].astype(float),
                    core=z["core"].astype(float),
                    identity_rows=z["identity_rows"].astype(float),
                    expression_rows=z["expression_rows"].astype(float),
                    expression_names=tuple(str(s) for s in z["expression_names"]),
                    people=tuple(str(s) for s in z["people"]),
                )
        except (OSError, KeyError, EOFError) as exc:
            raise ValueError(f"{path}: cannot read the multilinear model ({exc}); rebuild it") from exc


def build_model(T: np.ndarray, ranks, expression_names, people, known: np.ndarray | None = None) -> MultilinearModel:
    """The model of data tensor ``T`` (d, p, E) with ``ranks`` (r1, r2, r3) (None: full) — missing
    cells (``known`` (p, E) False) imputed first (:func:`impute`)."""
    T = np.asarray(T, float)
    if known is not None and not np.all(known):
        T = impute(T, known)
    mean = T.mean(axis=(1, 2))
    core, (U1, U2, U3) = n_mode_svd(T - mean[:, None, None], ranks)
    return MultilinearModel(mean, U1, core, U2, U3, tuple(expression_names), tuple(people))


def _mean_displacements(T: np.ndarray, known: np.ndarray) -> np.ndarray:
    """(d, E): each expression's mean displacement from the neutral over the people who have it."""
    disp = np.zeros((T.shape[0], T.shape[2]))
    for e in range(1, T.shape[2]):
        have = known[:, e]
        if have.any():
            disp[:, e] = (T[:, have, e] - T[:, have, 0]).mean(axis=1)
    return disp


def average_displacement(T: np.ndarray, known: np.ndarray) -> np.ndarray:
    """Seed 000's baseline (§4.4, "copy their average"): each missing cell ``(i, e)`` is person ``i``'s
    neutral ``T[:, i, 0]`` plus the mean of ``T[:, j, e] − T[:, j, 0]`` over the people ``j`` who have
    expression ``e``. Known cells are kept. ``T`` (d, p, E), ``known`` (p, E) bool; the neutrals must
    be known."""
    T = np.asarray(T, float)
    known = _check_known(T, known)
    predicted = T[:, :, :1] + _mean_displacements(T, known)[:, None, :]
    return np.where(known[None], T, predicted)


def _check_known(T: np.ndarray, known: np.ndarray) -> np.ndarray:
    known = np.asarray(known, bool)
    if known.shape != T.shape[1:]:
        raise ValueError(f"known must be (people, expressions) = {T.shape[1:]}, got {known.shape}")
    if not known[:, 0].all():
        raise ValueError("every person's neutral (expression 0) must be known")
    return known


def _project_mode(X: np.ndarray, mode: int, rank: int) -> np.ndarray:
    """``X`` with its mode-``mode`` vectors projected onto their top-``rank`` left singular subspace."""
    U = _left_singular(unfold(X, mode), rank)
    return mode_product(X, U @ U.T, mode)


def _rank(r, size: int) -> int:
    return int(min(max(round(r * size) if isinstance(r, float) else r, 1), size))


def impute(
    T: np.ndarray, known: np.ndarray, ranks=IMPUTE_RANKS, rounds: int = IMPUTE_ROUNDS, vertex_rank: int = VERTEX_RANK
) -> np.ndarray:
    """Seed 000 §4.3's imputation of the missing cells (see the module notes).

    Parameters
    ----------
    T : (d, p, E) float, the data (values of missing cells are ignored).
    known : (p, E) bool, the known cells; every person's neutral (expression 0) must be known.
    ranks : (q2, q3), subspace sizes of the people and expression modes (int, or float: a fraction
        of the mode's size).
    rounds : int, rounds of (per-mode factorisation, joint fill).
    vertex_rank : int, size of the vertex-mode subspace the missing cells are sought in.

    Returns
    -------
    (d, p, E) float, ``T`` with the missing cells filled.
    """
    T = np.asarray(T, float)
    known = _check_known(T, known)
    hidden = ~known[:, 1:]
    if not hidden.any():
        return T.copy()
    # the residual from the average-displacement predictor, over the expressions after the neutral
    base = T[:, :, :1] + _mean_displacements(T, known)[:, None, :]
    R = (T - base)[:, :, 1:]
    R[:, hidden] = 0.0
    # vertex mode: the span of the known residuals (Eq. 3's truncation of mode 1)
    U1 = _left_singular(R[:, ~hidden], vertex_rank)
    X = mode_product(R, U1.T, 0)  # (r1, p, E - 1)
    q2, q3 = _rank(ranks[0], X.shape[1]), _rank(ranks[1], X.shape[2])
    for _ in range(rounds):
        fill = 0.5 * (_project_mode(X, 1, q2) + _project_mode(X, 2, q3))
        X[:, hidden] = fill[:, hidden]
    out = base.copy()
    out[:, :, 1:] += mode_product(X, U1, 0)
    return np.where(known[None], T, out)
