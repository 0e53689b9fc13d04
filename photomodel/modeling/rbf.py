"""Scattered-data interpolation with radial basis functions (Pighin et al. 2002, §5.1.2, Eq. 3).

Once the feature points ``m_i`` are known, the displacements ``u_i = m_i − m_i⁽⁰⁾`` of the
constrained vertices are spread to every vertex of the generic mesh by a smooth vector-valued
function of the *original* 3D position (the paper's embedding space)::

    f(m) = Σ_i c_i φ(‖m − m_i‖) + M m + t,        φ(r) = exp(−r / 64 in)          (3)

subject to ``u_i = f(m_i)`` and the side conditions ``Σ_i c_i = 0`` and ``Σ_i c_i m_iᵀ = 0``,
which keep the radial part free of affine contributions. The world is in millimetres, the
paper's kernel in inches, so ``r_in = r_mm / 25.4`` (the 64-inch length is the
``length_in`` parameter).

Numerics
--------
The kernel is very wide for a face (64 in ≈ 1.6 m against a ~0.2 m head), so every entry of
the kernel matrix is ≈ 1 and the information sits in the small differences ``φ(r) − 1 ≈ −r/L``.
Solved naively the block system has a condition number of ~10⁴ (13 centres) to ~10⁶
(250 centres). Two exact reformulations remove most of that (measured: ~10² and ~10⁴):

* Because ``Σ c_i = 0``, adding a constant to φ does not change ``f``, so the kernel is
  replaced by ``ψ(r) = (L/s) · expm1(−r/L) = (L/s)(φ(r) − 1)``: ``expm1`` keeps the small
  differences to full precision and ``L/s`` (``s`` the RMS radius of the centres) brings
  them to order one. The paper's coefficients are ``c_i = (L/s) c'_i``.
* The affine part is solved in centred, scaled coordinates ``(m − μ)/s`` so its block has
  entries of order one too.

The symmetric (n+4)×(n+4) block system is then solved directly with
:func:`scipy.linalg.solve` (``assume_a='sym'``, an LDLᵀ factorisation). It is nonsingular
whenever the centres are distinct (the exponential kernel is strictly positive definite) and
not coplanar (the affine block has full rank) — both are checked before solving — so an exact
solve gives exact interpolation; a least-squares solve would instead hide a degenerate set
of clicks behind a minimum-norm answer that no longer interpolates, which is the error we
want to report. The condition number is kept on the result (``condition_number``).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import scipy.linalg
from scipy.spatial.distance import cdist

from photomodel.errors import FitError

MM_PER_INCH = 25.4

#: Elements of one (query × centre) distance block evaluated at a time (~32 MB of float64).
_CHUNK_ELEMENTS = 4_000_000


def _as_points(a, name: str) -> np.ndarray:
    a = np.asarray(a, dtype=float)
    if a.ndim != 2 or a.shape[1] != 3:
        raise FitError(f"{name} must be an (n, 3) array of positions in mm, got shape {a.shape}")
    return a


@dataclass(frozen=True, eq=False)
class RBFInterpolant:
    """A fitted interpolant of Eq. (3); build it with :meth:`fit`, evaluate it by calling it.

    Attributes
    ----------
    centres : (n, 3) float mm
        The centres ``m_i`` (after merging coincident duplicates).
    coeffs : (n, d) float
        The paper's radial coefficients ``c_i`` (for the kernel ``φ`` itself, not ``ψ``).
    linear : (3, d) float
        ``Mᵀ``: the affine part is ``m @ linear + offset``.
    offset : (d,) float
        ``t``.
    length_in : float
        Kernel length in inches (64 in the paper).
    smoothing : float
        Ridge added to the diagonal of the kernel matrix ``Φ`` (``φ(0) = 1``); 0 interpolates.
    condition_number : float
        2-norm condition number of the (rescaled) block system that was solved.
    merged : list of (int, int)
        Pairs ``(kept, dropped)`` of input rows merged because they coincide.
    """

    centres: np.ndarray
    coeffs: np.ndarray
    linear: np.ndarray
    offset: np.ndarray
    length_in: float = 64.0
    smoothing: float = 0.0
    condition_number: float = float("nan")
    merged: list = field(default_factory=list)
    # solve-space representation used for evaluation (see module Notes)
    _mu: np.ndarray = field(default=None, repr=False)
    _scale: float = field(default=1.0, repr=False)
    _coeffs_scaled: np.ndarray = field(default=None, repr=False)
    _affine_scaled: np.ndarray = field(default=None, repr=False)
    _vector: bool = field(default=True, repr=False)

    @property
    def length_mm(self) -> float:
        return self.length_in * MM_PER_INCH

    @classmethod
    def fit(
        cls,
        centres,
        values,
        *,
        length_in: float = 64.0,
        smoothing: float = 0.0,
        min_separation_mm: float = 1e-3,
        coplanar_tol: float = 1e-3,
        labels=None,
    ) -> RBFInterpolant:
        """Fit Eq. (3) to values at centres.

        Parameters
        ----------
        centres : (n, 3) float mm
            Positions ``m_i`` (in the face-mesh frame; the paper uses the generic mesh's
            original vertex positions).
        values : (n, d) or (n,) float
            Values ``u_i`` to interpolate, e.g. (n, 3) displacements in mm; all ``d``
            columns share one factorisation.
        length_in : float
            Kernel length ``L`` of ``φ(r) = exp(−r/L)`` in inches (paper: 64).
        smoothing : float, >= 0
            Ridge ``λ`` on the kernel matrix, ``(Φ + λI) c + P a = u``. 0 (the paper) gives
            exact interpolation; since ``1 − φ(r) ≈ r/L`` a useful λ is tiny, around
            ``(noise_mm / L_mm)`` ≈ 1e-4 for millimetre noise.
        min_separation_mm : float
            Centres closer than this are coincident: merged when their values agree
            (to 1e-9 relative), otherwise a :class:`FitError` names them.
        coplanar_tol : float
            Centres whose thickness (smallest/largest singular value of the centred
            coordinates) is below this cannot determine the affine part: FitError.
        labels : sequence of str, optional
            How error messages name the rows (default ``"centre i"``).

        Raises
        ------
        FitError
            NaN/inf input, fewer than 4 centres, coplanar centres, coincident centres with
            different values.
        """
        X, U, vector, labels = _checked_inputs(centres, values, length_in, smoothing, labels)
        X, U, merged = _merge_coincident(X, U, min_separation_mm, labels)
        mu, s = _frame(X, coplanar_tol)
        L = length_in * MM_PER_INCH
        sol, cond = _solve_block_system(X, U, mu, s, L, smoothing)
        n = X.shape[0]
        c_scaled, a_scaled = sol[:n], sol[n:]
        linear = a_scaled[:3] / s
        offset = a_scaled[3] - mu @ linear
        return cls(
            centres=X,
            coeffs=c_scaled * (L / s),
            linear=linear,
            offset=offset,
            length_in=float(length_in),
            smoothing=float(smoothing),
            condition_number=cond,
            merged=merged,
            _mu=mu,
            _scale=s,
            _coeffs_scaled=c_scaled,
            _affine_scaled=a_scaled,
            _vector=vector,
        )

    def __call__(self, points) -> np.ndarray:
        """Evaluate ``f`` at points.

        Parameters
        ----------
        points : (m, 3) float mm

        Returns
        -------
        (m, d) float, or (m,) if the interpolant was fitted to (n,) values.
        """
        Q = _as_points(points, "points")
        L, s = self.length_mm, self._scale
        d = self._coeffs_scaled.shape[1]
        out = np.empty((Q.shape[0], d))
        chunk = max(1, _CHUNK_ELEMENTS // max(len(self.centres), 1))
        for start in range(0, Q.shape[0], chunk):
            q = Q[start : start + chunk]
            K = (L / s) * np.expm1(-cdist(q, self.centres) / L)
            out[start : start + chunk] = (
                K @ self._coeffs_scaled + ((q - self._mu) / s) @ self._affine_scaled[:3] + self._affine_scaled[3]
            )
        return out if self._vector else out[:, 0]


def _checked_inputs(centres, values, length_in, smoothing, labels):
    """:meth:`RBFInterpolant.fit`'s arguments checked: ``(X (n, 3), U (n, d), vector, labels)``
    (``vector``: the values came as (n, d)), or a FitError naming the row or argument."""
    X = _as_points(centres, "centres")
    U = np.asarray(values, dtype=float)
    vector = U.ndim == 2
    if U.ndim == 1:
        U = U[:, None]
    if U.ndim != 2 or U.shape[0] != X.shape[0]:
        raise FitError(f"values must have one row per centre: {X.shape[0]} centres, values shape {np.shape(values)}")
    if labels is None:
        labels = [f"centre {i}" for i in range(X.shape[0])]
    for arr, what in ((X, "position"), (U, "value")):
        bad = np.flatnonzero(~np.all(np.isfinite(arr), axis=1))
        if bad.size:
            names = ", ".join(labels[i] for i in bad[:10])
            raise FitError(f"{what} of {names} is not finite (NaN or inf); remove it")
    if not (np.isfinite(length_in) and length_in > 0):
        raise FitError(f"length_in must be a positive number of inches, got {length_in}")
    if not (np.isfinite(smoothing) and smoothing >= 0):
        raise FitError(f"smoothing must be >= 0, got {smoothing}")
    return X, U, vector, labels


def _frame(X: np.ndarray, coplanar_tol: float) -> tuple[np.ndarray, float]:
    """The centres' mean ``mu`` (3,) mm and RMS radius ``s`` mm, the frame the system is solved
    in (module Notes); a FitError when fewer than 4 centres or (nearly) coplanar ones cannot
    determine the affine part."""
    n = X.shape[0]
    if n < 4:
        raise FitError(f"the affine part of Eq. (3) needs at least 4 non-coplanar centres, got {n}")
    mu = X.mean(axis=0)
    Xc = X - mu
    sv = np.linalg.svd(Xc, compute_uv=False)
    if sv[0] == 0 or sv[2] / sv[0] < coplanar_tol:
        raise FitError(
            f"the {n} centres are (nearly) coplanar (thickness ratio "
            f"{sv[2] / max(sv[0], 1e-300):.2e} < {coplanar_tol:g}); the affine part of "
            "Eq. (3) needs points off one plane — add a feature with different depth"
        )
    return mu, float(np.sqrt((Xc**2).sum(axis=1).mean()))


def _solve_block_system(X, U, mu, s: float, L: float, smoothing: float) -> tuple[np.ndarray, float]:
    """Solve the rescaled block system of Eq. (3) (module Notes) for the values ``U`` (n, d):
    ``(n + 4, d)`` radial then affine coefficients in the solve's frame, and the system's
    2-norm condition number."""
    n = X.shape[0]
    A = np.zeros((n + 4, n + 4))
    A[:n, :n] = (L / s) * np.expm1(-cdist(X, X) / L)
    A[:n, :n][np.diag_indices(n)] += smoothing * L / s
    P = np.column_stack([(X - mu) / s, np.ones(n)])
    A[:n, n:] = P
    A[n:, :n] = P.T
    B = np.zeros((n + 4, U.shape[1]))
    B[:n] = U
    cond = float(np.linalg.cond(A))
    try:
        sol = scipy.linalg.solve(A, B, assume_a="sym", check_finite=False)
    except (np.linalg.LinAlgError, scipy.linalg.LinAlgError) as exc:  # pragma: no cover
        raise FitError(f"the RBF system is singular ({exc}); check for duplicate centres") from exc
    return sol, cond


def _merge_coincident(X: np.ndarray, U: np.ndarray, tol: float, labels):
    """Drop rows whose centre is within ``tol`` mm of an earlier one with the same value."""
    n = X.shape[0]
    if n < 2:
        return X, U, []
    D = cdist(X, X)
    ii, jj = np.nonzero(np.triu(D < tol, k=1))
    if ii.size == 0:
        return X, U, []
    scale = max(float(np.abs(U).max()), 1.0)
    drop = set()
    merged = []
    for i, j in zip(ii.tolist(), jj.tolist(), strict=True):
        if i in drop or j in drop:
            continue
        if np.max(np.abs(U[i] - U[j])) > 1e-9 * scale:
            raise FitError(
                f"{labels[i]} and {labels[j]} are {D[i, j]:.3g} mm apart but ask for different values "
                f"{U[i].tolist()} and {U[j].tolist()}; an interpolant cannot pass through both — "
                "remove one of the two constraints"
            )
        drop.add(j)
        merged.append((i, j))
    keep = np.setdiff1d(np.arange(n), sorted(drop))
    return X[keep], U[keep], merged


def deform_vertices(vertices, constrained, targets, **kw) -> np.ndarray:
    """Move a mesh so that constrained vertices land on targets and the rest follow (§5.1.2).

    Parameters
    ----------
    vertices : (N, 3) float mm
        Original (generic-mesh) vertex positions ``m⁽⁰⁾`` — the interpolation domain.
    constrained : (n,) int
        Indices of the constrained vertices (repeats allowed if their targets agree).
    targets : (n, 3) float mm
        New positions ``m_i`` of the constrained vertices.
    **kw
        Passed to :meth:`RBFInterpolant.fit` (``length_in``, ``smoothing``, ...).

    Returns
    -------
    (N, 3) float mm
        ``m⁽⁰⁾ + f(m⁽⁰⁾)`` with ``f`` interpolating the displacements ``u_i = m_i − m_i⁽⁰⁾``.
        With ``smoothing=0`` the constrained vertices are set exactly onto their targets
        (the interpolant already reaches them to ~1e-10 mm; the snap removes round-off).

    Raises
    ------
    FitError
        Bad indices or shapes, or any of :meth:`RBFInterpolant.fit`'s failures.
    """
    V = _as_points(vertices, "vertices")
    idx = np.asarray(constrained)
    if idx.ndim != 1 or (idx.size and not np.issubdtype(idx.dtype, np.integer)):
        raise FitError(f"constrained must be a 1-D array of vertex indices, got {idx.dtype} {idx.shape}")
    T = _as_points(targets, "targets")
    if T.shape[0] != idx.shape[0]:
        raise FitError(f"{idx.shape[0]} constrained vertices but {T.shape[0]} targets")
    out_of_range = idx[(idx < 0) | (idx >= V.shape[0])]
    if out_of_range.size:
        raise FitError(f"constrained vertex indices {out_of_range.tolist()} are outside the mesh (0..{V.shape[0] - 1})")
    kw.setdefault("labels", [f"vertex {v}" for v in idx.tolist()])
    interp = RBFInterpolant.fit(V[idx], T - V[idx], **kw)
    out = V + interp(V)
    if interp.smoothing == 0:
        out[idx] = T
    return out
