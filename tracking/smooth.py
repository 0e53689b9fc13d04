"""The whole-clip smooth solve of the expression weights (Yang et al. 2012, §3.1.4, Eq. 15–23).

After per-frame tracking (:mod:`tracking.frame_fit`) every frame ``t`` has a pose ``(R_t, t_t)``
and expression parameters ``α_t`` (the paper's ``β_t``). The per-frame fits are independent, so the
weight curves jitter from frame to frame. Here the expression parameters of all ``T`` frames are
re-estimated jointly, as in Eq. (15):

    Σ_t ε_t(α_t) + ½ λ₁ ‖K₁ α‖² + ½ λ₂ ‖K₂ α‖²,

with ``K₁`` / ``K₂`` the first / second differences over the frames (Eq. 22–23). The paper's data
term is quadratic in ``β_t`` (landmarks of a linear model); ours is the tracker's image error ε_t
(analysis by synthesis, bandpassed), so it is *linearised at the tracked solution*: with ``J_t``
the Jacobian of the frame's (filtered, face-weighted, robust-weighted) rendering with respect to
``α`` (the tracker's own analytic Jacobian, Eq. 7 of Pighin et al. 2002) and ``r_t`` the residual
there,

    ε_t(α_t⁰ + δ) ≈ ε_t(α_t⁰) − r_tᵀ J_t δ + ½ δᵀ J_tᵀ J_t δ   (Gauss–Newton),

which is the paper's ``A_t = M_tᵀ W M_t`` (Eq. 12) and ``B_t`` (Eq. 14) with ``A_t = J_tᵀJ_t`` and
``B_t = A_t α_t⁰ + J_tᵀ r_t``. Stacking the frames gives one sparse banded system (Eq. 17–21),

    [diag(A_t) + λ_β I + λ₁ (K₁ᵀK₁ ⊗ I_a) + λ₂ (K₂ᵀK₂ ⊗ I_a)] α = B,

bandwidth ``2a`` (``a`` parameters per frame), solved with :mod:`scipy.sparse` (SuperLU) — no loop
over frames in the solve. The λ's are given relative to the data term (``λ = κ · median_t
trace(A_t) / a``), so that one setting serves any image size and texture contrast.

**Alternating with pose** (the paper's coordinate descent, Algorithm 1): after each expression
solve every frame's pose is refitted with its new ``α`` held (a few LM steps of the tracker's pose
phase, on the bandpassed images as the tracker's last phase), then the data terms are linearised
again at the new pose and weights. Two rounds are the default.

**The convex range.** The model's weights of each region sum to 1 by construction (Eq. 4 of
Pighin et al.); the tracker keeps them in ``[0, 1]`` with its piecewise-quadratic penalty ``D``
(``c (w − bound)²`` outside, ``c`` = :attr:`tracking.frame_fit.TrackOptions.penalty` × covered
pixels) and never beyond :data:`tracking.blendshape_face.WEIGHT_RANGE`. The clip solve uses the same
``D``, which is convex and piecewise quadratic: the system is solved with the pieces of ``D`` that
the weights of the last solution are on, until those pieces stop changing (Newton's method on the
pieces, an active set; at most :data:`ACTIVE_SET_PASSES` passes, starting with none — a weight
out of range only at the tracked start is not held at its bound);
a frame whose weights would still leave ``WEIGHT_RANGE`` has its change from the tracked ``α``
shortened until they do not.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import scipy.sparse as sparse
import scipy.sparse.linalg as splinalg

from tracking.blendshape_face import WEIGHT_RANGE, FaceModel
from tracking.frame_fit import FrameFitter, FrameState, Phase

__all__ = [
    "ACTIVE_SET_PASSES",
    "SmoothOptions",
    "SmoothResult",
    "difference_operator",
    "smoothness_matrix",
    "solve_clip",
    "linearise_frame",
    "smooth_clip",
    "weight_curves",
    "jitter",
]

#: Passes of the active set of the penalty D in one clip solve.
ACTIVE_SET_PASSES = 5


@dataclass
class SmoothOptions:
    """Settings of :func:`smooth_clip`.

    ``first_difference`` / ``second_difference`` are the paper's λ₁ / λ₂ (Eq. 18) in units of one
    frame's data term (the median over the clip of ``trace(A_t) / a``): ``κ₂ = 1`` weighs a unit
    second difference of ``α`` (mm RMS of surface motion) like a unit deviation of an average
    parameter in one frame. Defaults measured by ``benchmarks/bench_edit.py`` on the synthetic
    sequences (jitter halved or better with the peaks' error not above the per-frame one).
    """

    first_difference: float = 0.0
    second_difference: float = 2.0
    #: λ_β of Eq. (18), relative as above: a pull of every α towards 0 (the neutral face).
    ridge: float = 0.0
    #: expression-solve / pose-refit rounds (Algorithm 1's loop).
    rounds: int = 2
    #: most LM iterations of each frame's pose refit.
    pose_iterations: int = 3

    def __post_init__(self):
        for name in ("first_difference", "second_difference", "ridge"):
            if getattr(self, name) < 0:
                raise ValueError(f"{name} must be ≥ 0, got {getattr(self, name)}")
        if self.rounds < 1:
            raise ValueError(f"rounds must be ≥ 1, got {self.rounds}")


@dataclass
class SmoothResult:
    """What :func:`smooth_clip` returns.

    Attributes
    ----------
    states : list of T FrameState, the smoothed parameters (pose refitted, ``α`` jointly solved).
    weights : (T, R, m) float, region blending weights at the smoothed ``α``.
    energies : list of float, the clip's linearised energy after each round's expression solve.
    """

    states: list
    weights: np.ndarray
    energies: list = field(default_factory=list)


def difference_operator(frames: int, order: int) -> sparse.csr_matrix:
    """``K₁`` (Eq. 22, ``order=1``: (T−1, T)) or ``K₂`` (Eq. 23, ``order=2``: (T−2, T)), sparse.

    Rows are ``[−1, 1]`` and ``[−1, 2, −1]`` (the paper's signs; only ``KᵀK`` is used)."""
    if order not in (1, 2):
        raise ValueError(f"order must be 1 or 2, got {order}")
    n = max(frames - order, 0)
    stencil = [-1.0, 1.0] if order == 1 else [-1.0, 2.0, -1.0]
    return sparse.diags([np.full(n, s) for s in stencil], list(range(order + 1)), shape=(n, frames), format="csr")


def smoothness_matrix(frames: int, a: int, first: float, second: float) -> sparse.csr_matrix:
    """``λ₁ H₁ + λ₂ H₂`` (Eq. 20–21) for ``frames`` frames of ``a`` parameters: (T a, T a) sparse,
    frame-major (``α`` of frame ``t`` at rows ``t a … t a + a − 1``)."""
    H = sparse.csr_matrix((frames * a, frames * a))
    I = sparse.identity(a, format="csr")
    for lam, order in ((first, 1), (second, 2)):
        if lam > 0 and frames > order:
            K = difference_operator(frames, order)
            H = H + lam * sparse.kron((K.T @ K).tocsr(), I, format="csr")
    return H.tocsr()


def solve_clip(A: np.ndarray, B: np.ndarray, first: float, second: float, ridge: float = 0.0) -> np.ndarray:
    """The joint solve of Eq. (17): ``α = [diag(A_t) + λ_β I + λ₁H₁ + λ₂H₂]⁻¹ B``.

    Parameters
    ----------
    A : (T, a, a) float, the frames' data-term Hessians (Eq. 12).
    B : (T, a) float, their right-hand sides (Eq. 14).
    first, second, ridge : float, λ₁, λ₂, λ_β (absolute).

    Returns
    -------
    (T, a) float
    """
    A = np.asarray(A, float)
    B = np.asarray(B, float)
    T, a = B.shape
    if A.shape != (T, a, a):
        raise ValueError(f"A must be ({T}, {a}, {a}) for B of shape {B.shape}, got {A.shape}")
    if a == 0:
        return np.zeros((T, 0))
    M = sparse.block_diag(list(A), format="csr") + smoothness_matrix(T, a, first, second)
    if ridge > 0:
        M = M + ridge * sparse.identity(T * a, format="csr")
    return splinalg.spsolve(M.tocsc(), B.reshape(-1)).reshape(T, a)


def linearise_frame(fitter: FrameFitter, frame: np.ndarray, state: FrameState) -> tuple[np.ndarray, np.ndarray, int]:
    """One frame's data term linearised at ``state``: ``(A_t, g_t, pixels)``.

    ``A_t = J_tᵀJ_t`` (a, a) and ``g_t = J_tᵀ r_t`` (a,) of the tracker's expression phase — its
    bandpassed, face- and robust-weighted residual and analytic Jacobian with respect to ``α``
    (:class:`tracking.frame_fit.FrameFitter`, Eq. 7 of Pighin et al.) — without the penalty ``D``
    (the clip solve adds it, see the module docstring); ``pixels``: covered pixels (``D``'s scale).
    """
    system = fitter.linearise_expression(frame, state)
    return system.JtJ, system.Jtr, system.pixels


def _penalty_terms(model: FaceModel, alpha: np.ndarray, c: np.ndarray, sides: np.ndarray):
    """Block Hessians (T, a, a) and right-hand sides (T, a) of the pieces of ``D`` chosen by
    ``sides`` (T, R−1, m: −1 below 0, +1 above 1): ``c_t (w − b)²`` with ``w = q·α_r + w*``."""
    T, a = alpha.shape
    H = np.zeros((T, a, a))
    rhs = np.zeros((T, a))
    for r, (Q, s) in enumerate(zip(model.bases, model.alpha_slices, strict=True)):
        if r == 0 or Q.shape[1] == 0:
            continue
        on = (sides[:, r - 1] != 0).astype(float)  # (T, m)
        bound = (sides[:, r - 1] > 0).astype(float)
        # Σ_k on_k 2c q_k q_kᵀ and 2c q_k (b_k − w*_k)
        H[:, s, s] += 2 * c[:, None, None] * np.einsum("tk,kl,kj->tlj", on, Q, Q)
        rhs[:, s] += 2 * c[:, None] * np.einsum("tk,kl->tl", on * (bound - model.w_star), Q)
    return H, rhs


def _sides(W: np.ndarray) -> np.ndarray:
    """(T, R−1, m) int: −1 below 0, +1 above 1, else 0 (control regions only)."""
    return (W[:, 1:] > 1.0).astype(int) - (W[:, 1:] < 0.0).astype(int)


def weight_curves(model: FaceModel, alpha: np.ndarray) -> np.ndarray:
    """(T, R, m) region blending weights of the parameters ``alpha`` (T, a) (Eq. 4 of Pighin et al.)."""
    return np.array([model.region_weights(a) for a in np.asarray(alpha, float)])


def _within_range(model: FaceModel, before: np.ndarray, after: np.ndarray) -> np.ndarray:
    """``after`` (T, a) with each frame's change from ``before`` shortened so that its weights stay
    in :data:`WEIGHT_RANGE` (the weights are affine in α, so the limit is a line search)."""
    lo, hi = WEIGHT_RANGE
    w0, w1 = weight_curves(model, before)[:, 1:], weight_curves(model, after)[:, 1:]
    dw = w1 - w0
    with np.errstate(divide="ignore", invalid="ignore"):
        up = np.where(dw > 1e-12, (hi - w0) / dw, np.inf)
        down = np.where(dw < -1e-12, (lo - w0) / dw, np.inf)
    s = np.clip(np.minimum(up, down).reshape(len(dw), -1).min(axis=1), 0.0, 1.0)
    return before + s[:, None] * (after - before)


def _solve_in_range(model, A, B, alpha0, pixels, penalty, lams) -> np.ndarray:
    """Eq. (17) with the active set of ``D`` (module docstring)."""
    c = penalty * np.maximum(pixels, 1).astype(float)
    sides = np.zeros_like(_sides(weight_curves(model, alpha0)))
    for _ in range(ACTIVE_SET_PASSES):
        H, rhs = _penalty_terms(model, alpha0, c, sides)
        alpha = solve_clip(A + H, B + rhs, *lams)
        now = _sides(weight_curves(model, alpha))
        if np.array_equal(now, sides):
            break
        sides = now
    return _within_range(model, alpha0, alpha)


def _refit_pose(fitter: FrameFitter, frame: np.ndarray, state: FrameState, iterations: int) -> FrameState:
    """The frame's pose refitted with its ``α`` held: LM on the 6 pose parameters (the tracker's,
    on the bandpassed ε of its last phase)."""
    o = fitter.options
    pose = Phase(np.arange(6), iterations, o.pose_jacobian, o.bandpass is not None, o.step_tolerance_mm, reuse=False)
    return fitter.refine(frame, state, pose)


def smooth_clip(
    fitter: FrameFitter, frames, states, options: SmoothOptions | None = None, progress=None
) -> SmoothResult:
    """Re-estimate the expression parameters of a tracked clip jointly (§3.1.4, Eq. 15–23),
    alternating with the frames' poses (module docstring).

    Parameters
    ----------
    fitter : FrameFitter, the tracker's (its model, camera and options).
    frames : sequence of T (H, W, 3) float images in [0, 1] (indexable: each is read once a round).
    states : sequence of T FrameState, the per-frame tracking results.
    options : SmoothOptions, optional.
    progress : callable ``(round, frame)``, optional.

    Returns
    -------
    SmoothResult
    """
    o = options or SmoothOptions()
    states = [s.copy() for s in states]
    T = len(states)
    if len(frames) != T:
        raise ValueError(f"need one frame per state: {len(frames)} frames, {T} states")
    model = fitter.model
    a = fitter.n_alpha
    energies = []
    if T == 0 or a == 0:
        return SmoothResult(states, weight_curves(model, np.zeros((T, a))), energies)
    for k in range(o.rounds):
        A = np.zeros((T, a, a))
        B = np.zeros((T, a))
        pixels = np.zeros(T)
        alpha0 = np.array([s.alpha for s in states])
        for t in range(T):
            A[t], g, pixels[t] = linearise_frame(fitter, frames[t], states[t])
            B[t] = A[t] @ alpha0[t] + g
            if progress is not None:
                progress(k, t)
        scale = float(np.median(np.trace(A, axis1=1, axis2=2))) / a
        lams = (o.first_difference * scale, o.second_difference * scale, o.ridge * scale)
        alpha = _solve_in_range(model, A, B, alpha0, pixels, fitter.options.penalty, lams)
        energies.append(_energy(A, B, alpha, lams))
        for t in range(T):
            states[t].alpha = alpha[t]
            states[t] = _refit_pose(fitter, frames[t], states[t], o.pose_iterations)
    alpha = np.array([s.alpha for s in states])
    return SmoothResult(states, weight_curves(model, alpha), energies)


def _energy(A, B, alpha, lams) -> float:
    """The linearised clip energy ``Σ_t (½ αᵀA_tα − B_tᵀα) + ½ αᵀ(λ₁H₁ + λ₂H₂ + λ_β I)α`` (up to a constant)."""
    T, a = alpha.shape
    data = 0.5 * np.einsum("ti,tij,tj->", alpha, A, alpha) - float((B * alpha).sum())
    H = smoothness_matrix(T, a, lams[0], lams[1])
    x = alpha.reshape(-1)
    return float(data + 0.5 * x @ (H @ x) + 0.5 * lams[2] * x @ x)


def jitter(weights: np.ndarray) -> float:
    """Mean over the frames of ‖second difference‖ of the weights (T, ...) — the issue's jitter."""
    W = np.asarray(weights, float).reshape(len(weights), -1)
    if len(W) < 3:
        return 0.0
    return float(np.linalg.norm(W[2:] - 2 * W[1:-1] + W[:-2], axis=1).mean())
