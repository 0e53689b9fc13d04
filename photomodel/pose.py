"""Pose recovery by alternating weighted linear least squares (Pighin et al. 2002, §5.1.1, App. A).

Given the clicks of ``n`` features in ``k`` photographs, rough initial cameras (the presets an
artist picks: "front", "left", ...) and initial 3D feature positions (the generic head's
feature vertices), :func:`recover_poses` recovers every camera's rotation ``R_k``, translation
``t_k`` and focal length ``f_k`` together with the 3D feature positions ``m_i`` that minimise the
reprojection error of the clicks.

The paper's method
------------------
With image coordinates ``(x, y)`` measured from the optical centre (pixels, ``y`` down — the
conventions of :mod:`photomodel.camera`), the projection Eq. (1) is rewritten with the inverse
distance ``η_k = 1 / t_z`` and the world-to-image scale ``s_k = f_k η_k`` (Szeliski & Kang 1994):

    x = s (r_x·m + t_x) / (1 + η r_z·m),      y = s (r_y·m + t_y) / (1 + η r_z·m).

Multiplying by the denominator and by its inverse ``w_ik = 1 / (1 + η_k r_z·m_i)`` gives Eq. (2),

    w (x + x η (r_z·m) − s (r_x·m + t_x)) = 0,   w (y + y η (r_z·m) − s (r_y·m + t_y)) = 0,

which, with ``w`` held at its current value, is *linear* in each of ``s_k``, ``m_i``, ``t_x``,
``t_y`` and ``η_k`` (and its left-hand side *is* the pixel reprojection error when ``w`` is
current). Each sweep solves, in the paper's order, weighted linear least-squares problems for

1. ``s_k`` (one scalar per camera),
2. ``m_i`` (3×3 normal equations per point, Eq. 11 with the rows of App. A),
3. ``R_k`` through an incremental rotation ``R_k ← R̃(v_k) R_k``: the linearised rows of
   Eq. (14) give 3×3 normal equations in ``v = θ n̂``; the update uses the exact Rodrigues
   formula (Eq. 12),
4. ``t_x``, ``t_y`` per camera,
5. ``η_k`` per camera,

and ``f_k = s_k / η_k``, ``t_z = 1 / η_k``. The weights ``w`` are recomputed whenever a step has
changed what they depend on ("we consider that the scalars w are constant and update their
values as better estimates become available"). Every per-camera and per-point system is
independent of the others, so each step is a handful of batched numpy operations — there is no
Python loop over points or cameras.

Acceleration (``accelerate=True``, *beyond the paper*)
------------------------------------------------------
Alternation converges linearly and crawls along the weakly determined directions of the
problem (focal length against distance, the shape's depth against the cameras' spread), so
after a few sweeps of the paper's method :func:`recover_poses` finishes with a joint
Levenberg–Marquardt polish over all unknowns in the same parameterisation (``s, η, t_x, t_y``,
incremental rotation per camera; ``m`` per point). The point blocks are eliminated by a Schur
complement, so an iteration costs one dense solve of size ``7k`` (``k ≤ 10`` photos) plus
batched 3×3 work per point. ``accelerate=False`` runs the paper's alternation alone, to
convergence; both reach the same minimum (see ``tests/test_pose.py`` and
``benchmarks/posebench.py``).

Gauge
-----
Structure from motion recovers the scene only up to a similarity (the paper: "if we scale all of
the m's and t's up by the same amount, the answer is the same"). Every sub-problem above is
well posed with the other unknowns held fixed, so the alternation needs no gauge constraint:
the result lives near the frame and size of the initial guess. The damping of the polish keeps
its steps out of the gauge directions. Callers that need a fixed frame align the recovered
points onto a reference afterwards (``photomodel.fit`` does).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

import numpy as np

from .camera import Camera
from .errors import FitError

#: A photo needs this many clicked features: a camera with unknown focal length has 7 degrees
#: of freedom and each click gives 2 equations, so 4 non-collinear clicks determine it
#: (3 suffice with a fixed focal length, but 4 remove the P3P ambiguity).
MIN_POINTS_PER_VIEW = 4
#: The reconstruction needs at least this many features that are each seen in two photos.
MIN_POINTS = 6
#: A view whose clicks lie within this fraction of their spread from one straight line is
#: degenerate (a camera cannot be recovered from collinear points).
COLLINEAR_RATIO = 1e-2

__all__ = [
    "PoseResult",
    "recover_poses",
    "reprojection_residuals",
    "MIN_POINTS_PER_VIEW",
    "MIN_POINTS",
]


@dataclass
class PoseResult:
    """What :func:`recover_poses` returns.

    Attributes
    ----------
    cameras : list[Camera], the recovered camera of each photo (focal in pixels, mm).
    points : (n, 3) float, the recovered 3D feature positions in mm.
    iterations : int, sweeps of the paper's alternation that were run.
    converged : bool, whether the stopping test was met before ``max_sweeps``.
    rms_px : float, root mean square over all clicks of the reprojection error's length (px).
    per_view_rms_px : (k,) float, the same RMS per photo.
    per_point_rms_px : (n,) float, the same RMS per feature.
    residuals_px : (k, n, 2) float, projected minus clicked position (px); NaN where unclicked.
    polish_iterations : int, Levenberg–Marquardt iterations of the joint polish (0 without
        ``accelerate``).
    rms_history : (iterations + polish_iterations + 1,) float, RMS (px) at the start and after
        every sweep / polish iteration.
    """

    cameras: list[Camera]
    points: np.ndarray
    iterations: int
    converged: bool
    rms_px: float
    per_view_rms_px: np.ndarray
    per_point_rms_px: np.ndarray
    residuals_px: np.ndarray
    polish_iterations: int = 0
    rms_history: np.ndarray = field(default_factory=lambda: np.zeros(0))


# ----------------------------------------------------------------------------------------------
# residuals
# ----------------------------------------------------------------------------------------------
def reprojection_residuals(cameras: Sequence[Camera], points: np.ndarray, observations: np.ndarray) -> np.ndarray:
    """Projected minus clicked pixel positions.

    Parameters
    ----------
    cameras : sequence of k :class:`~photomodel.camera.Camera`.
    points : (n, 3) float, world mm.
    observations : (k, n, 2) float, clicked pixels (u right, v down); NaN where not clicked.

    Returns
    -------
    (k, n, 2) float, ``project(point) − click`` in pixels; NaN where not clicked.
    """
    obs = np.asarray(observations, dtype=float)
    pts = np.asarray(points, dtype=float)
    R = np.stack([c.R for c in cameras])
    t = np.stack([c.t for c in cameras])
    f = np.array([c.f for c in cameras])
    pp = np.stack([c.principal_point for c in cameras])
    Xc = pts @ R.transpose(0, 2, 1) + t[:, None, :]
    proj = f[:, None, None] * Xc[..., :2] / Xc[..., 2:3] + pp[:, None, :]
    return proj - obs


def _rms_summary(res: np.ndarray, valid: np.ndarray) -> tuple[float, np.ndarray, np.ndarray]:
    """Overall, per-view and per-point RMS (px) of residuals ``res`` (k, n, 2), zero where invalid."""
    sq = np.einsum("knj,knj->kn", res, res)
    cnt_v = valid.sum(1)
    cnt_p = valid.sum(0)
    with np.errstate(invalid="ignore", divide="ignore"):
        per_view = np.sqrt(sq.sum(1) / cnt_v)
        per_point = np.sqrt(sq.sum(0) / cnt_p)
    return float(np.sqrt(sq.sum() / valid.sum())), per_view, per_point


# ----------------------------------------------------------------------------------------------
# input validation (the boundary: errors name the photo / feature)
# ----------------------------------------------------------------------------------------------
def _validate(observations, cameras, points, names, view_names, fixed_focal):
    obs = np.asarray(observations, dtype=float)
    if obs.ndim != 3 or obs.shape[2] != 2:
        raise FitError(f"observations must be an array (photos, features, 2) of pixel clicks; got shape {obs.shape}")
    k, n, _ = obs.shape
    pts = np.asarray(points, dtype=float)
    if pts.shape != (n, 3):
        raise FitError(f"points must be ({n}, 3) to match {n} features in the observations; got shape {pts.shape}")
    cams = list(cameras)
    if len(cams) != k:
        raise FitError(f"got {len(cams)} camera(s) for {k} photo(s) of clicks; give one initial camera per photo")
    vname = list(view_names) if view_names is not None else [f"#{j}" for j in range(k)]
    pname = list(names) if names is not None else [f"#{i}" for i in range(n)]
    if len(vname) != k:
        raise FitError(f"view_names has {len(vname)} entries for {k} photos")
    if len(pname) != n:
        raise FitError(f"names has {len(pname)} entries for {n} features")
    if k < 2:
        raise FitError(f"pose recovery needs at least 2 photos; got {k}")

    nan = np.isnan(obs)
    half = nan[..., 0] != nan[..., 1]
    if half.any():
        j, i = np.argwhere(half)[0]
        raise FitError(
            f"photo {vname[j]!r}: feature {pname[i]!r} has one coordinate missing "
            f"({obs[j, i].tolist()}); a click needs both u and v (or neither)"
        )
    inf = np.isinf(obs).any(2)
    if inf.any():
        j, i = np.argwhere(inf)[0]
        raise FitError(f"photo {vname[j]!r}: feature {pname[i]!r} has an infinite coordinate ({obs[j, i].tolist()})")
    bad_pts = ~np.isfinite(pts).all(1)
    if bad_pts.any():
        i = int(np.flatnonzero(bad_pts)[0])
        raise FitError(f"initial 3D position of feature {pname[i]!r} is not finite ({pts[i].tolist()})")
    for j, c in enumerate(cams):
        if not isinstance(c, Camera):
            raise FitError(f"camera of photo {vname[j]!r} is a {type(c).__name__}, not a photomodel Camera")
        if not (np.isfinite(c.R).all() and np.isfinite(c.t).all() and np.isfinite(c.f)):
            raise FitError(f"initial camera of photo {vname[j]!r} has non-finite entries")
        if not c.f > 0:
            raise FitError(f"initial camera of photo {vname[j]!r} has focal length {c.f} px; it must be positive")
        if not np.allclose(c.R @ c.R.T, np.eye(3), atol=1e-6) or np.linalg.det(c.R) < 0:
            raise FitError(f"initial camera of photo {vname[j]!r}: R is not a rotation matrix")

    valid = ~nan[..., 0]
    seen = valid.sum(0)
    for i in np.flatnonzero(seen < 2):
        raise FitError(
            f"feature {pname[i]!r} is clicked in {seen[i]} photo(s) "
            f"({', '.join(repr(vname[j]) for j in np.flatnonzero(valid[:, i])) or 'none'}); "
            "pose recovery needs every feature in at least 2 photos — click it in another photo or leave it out"
        )
    per_view = valid.sum(1)
    for j in np.flatnonzero(per_view < MIN_POINTS_PER_VIEW):
        raise FitError(
            f"photo {vname[j]!r} has {per_view[j]} clicked feature(s); a camera needs at least "
            f"{MIN_POINTS_PER_VIEW} non-collinear clicks"
        )
    if n < MIN_POINTS:
        raise FitError(f"pose recovery needs at least {MIN_POINTS} features each clicked in 2 photos; got {n}")
    n_cam = 6 if fixed_focal else 7
    n_eq, n_unk = 2 * int(valid.sum()), n_cam * k + 3 * n - 7
    if n_eq < n_unk:
        raise FitError(
            f"{valid.sum()} clicks give {n_eq} equations for {n_unk} unknowns "
            f"({k} cameras × {n_cam} + {n} points × 3 − 7 for the similarity gauge); click more features"
        )
    # collinear clicks: second singular value of the centred clicks relative to the first
    for j in range(k):
        uv = obs[j, valid[j]]
        sv = np.linalg.svd(uv - uv.mean(0), compute_uv=False)
        if sv[1] <= COLLINEAR_RATIO * sv[0]:
            raise FitError(
                f"photo {vname[j]!r}: the {len(uv)} clicked features lie on one straight line; "
                "the camera cannot be recovered — click features off that line"
            )
    # the paper's η = 1/t_z and the weights 1/(1 + η r_z·m) need every clicked point in front
    for j, c in enumerate(cams):
        if not c.t[2] > 0:
            raise FitError(
                f"initial camera of photo {vname[j]!r} has t_z = {c.t[2]:.4g} mm; the world origin "
                "must lie in front of the camera (pick the preset that matches the photo)"
            )
        z = c.depth(pts)
        behind = valid[j] & ~(z > 0)
        if behind.any():
            i = int(np.flatnonzero(behind)[0])
            raise FitError(
                f"photo {vname[j]!r}: feature {pname[i]!r} is behind the initial camera (depth {z[i]:.4g} mm); "
                "pick the preset that matches the photo"
            )
    return obs, valid, pts, cams


# ----------------------------------------------------------------------------------------------
# the alternation (§5.1.1 + Appendix A), batched over cameras and points
# ----------------------------------------------------------------------------------------------
def _rodrigues_batch(v: np.ndarray) -> np.ndarray:
    """(k, 3) rotation vectors → (k, 3, 3) rotations by Rodrigues' formula, Eq. (12)."""
    theta = np.sqrt(np.einsum("ka,ka->k", v, v))
    small = theta < 1e-12
    th = np.where(small, 1.0, theta)
    a = np.where(small, 1.0, np.sin(th) / th)
    b = np.where(small, 0.5, (1.0 - np.cos(th)) / (th * th))
    K = np.zeros((len(v), 3, 3))
    K[:, 0, 1], K[:, 0, 2], K[:, 1, 2] = -v[:, 2], v[:, 1], -v[:, 0]
    K[:, 1, 0], K[:, 2, 0], K[:, 2, 1] = v[:, 2], -v[:, 1], v[:, 0]
    return np.eye(3) + a[:, None, None] * K + b[:, None, None] * (K @ K)


class _State:
    """Unknowns of §5.1.1 as arrays: R (k,3,3), t2 = (t_x, t_y) (k,2), eta (k,), s (k,), m (n,3)."""

    __slots__ = ("R", "t2", "eta", "s", "m")

    def __init__(self, R, t2, eta, s, m):
        self.R, self.t2, self.eta, self.s, self.m = R, t2, eta, s, m

    def copy(self) -> _State:
        return _State(self.R.copy(), self.t2.copy(), self.eta.copy(), self.s.copy(), self.m.copy())


class _Problem:
    """The clicks in the paper's image coordinates and the operations on a :class:`_State`."""

    def __init__(self, obs_px, valid, cameras, fixed_focal):
        pp = np.stack([c.principal_point for c in cameras])
        self.V = valid.astype(float)  # (k, n) 1 where clicked
        self.O = np.where(valid[..., None], obs_px - pp[:, None, :], 0.0)  # (k, n, 2) centred, 0 if unclicked
        self.n_obs = float(valid.sum())
        self.fixed_focal = fixed_focal
        self.f_fixed = np.array([c.f for c in cameras])
        k = len(cameras)
        self.eye_k = np.broadcast_to(np.eye(3), (k, 3, 3))

    # -- paper parameterisation <-> cameras ---------------------------------------------------
    def state_from(self, cameras, points) -> _State:
        R = np.stack([c.R for c in cameras])
        t = np.stack([c.t for c in cameras])
        f = np.array([c.f for c in cameras])
        eta = 1.0 / t[:, 2]
        return _State(R, t[:, :2].copy(), eta, f * eta, np.array(points, dtype=float))

    def cameras_from(self, st: _State, template: Sequence[Camera]) -> list[Camera]:
        out = []
        for j, c in enumerate(template):
            tz = 1.0 / st.eta[j]
            f = self.f_fixed[j] if self.fixed_focal else st.s[j] * tz
            out.append(Camera(st.R[j], np.array([st.t2[j, 0], st.t2[j, 1], tz]), f, c.width, c.height))
        return out

    def residuals(self, st: _State) -> np.ndarray:
        """(k, n, 2) projected − clicked in px (0 where unclicked)."""
        q = st.m @ st.R.transpose(0, 2, 1)
        w = self.V / (1.0 + st.eta[:, None] * q[..., 2])
        return (st.s[:, None] * w)[..., None] * (q[..., :2] + st.t2[:, None, :]) - self.O

    def rms(self, st: _State) -> float:
        r = self.residuals(st)
        return float(np.sqrt(np.einsum("knj,knj->", r, r) / self.n_obs))

    def register(self, st: _State) -> None:
        """Fit each camera's image scale and offset to its clicks: least squares in
        ``(s, s t_x, s t_y)`` (linear) with R, η and the points held. Beyond the paper."""
        V, O = self.V, self.O
        q = st.m @ st.R.transpose(0, 2, 1)
        w = V / (1.0 + st.eta[:, None] * q[..., 2])
        k = len(w)
        # rows for x: [w q_x, w, 0], for y: [w q_y, 0, w]
        A = np.zeros((k, 3, 3))
        wq = w[..., None] * q[..., :2]
        A[:, 0, 0] = np.einsum("knj,knj->k", wq, wq)
        A[:, 0, 1:] = A[:, 1:, 0] = wq.sum(1)
        w2 = (w * w).sum(1)
        A[:, 1, 1] = A[:, 2, 2] = w2
        rhs = np.empty((k, 3))
        rhs[:, 0] = np.einsum("knj,knj->k", wq, O)
        rhs[:, 1:] = np.einsum("kn,knj->kj", w, O)
        if self.fixed_focal:
            # s is tied to η: fit only the offset
            st.t2 = (rhs[:, 1:] / st.s[:, None] - A[:, 0, 1:]) / w2[:, None]
            return
        x = np.linalg.solve(A, rhs[..., None])[..., 0]
        st.s = x[:, 0]
        st.t2 = x[:, 1:] / x[:, :1]

    # -- one sweep of the paper's five weighted linear least-squares steps ----------------------
    def sweep(self, st: _State, solve_points: bool = True) -> float:
        """Update ``st`` in place by one sweep (§5.1.1 order: s, m, R, t_x/t_y, η); return the RMS (px)."""
        V, O = self.V, self.O
        R, eta = st.R, st.eta
        eta_kn = eta[:, None]
        # weights of the current estimate
        q = st.m @ R.transpose(0, 2, 1)  # (k, n, 3) = R_k m_i
        w = V / (1.0 + eta_kn * q[..., 2])

        # (1) s_k: rows a = w (r·m + t), b = w x (1 + η r_z·m) = x   (w (1+η r_z·m) = 1 where clicked)
        if not self.fixed_focal:
            a = w[..., None] * (q[..., :2] + st.t2[:, None, :])
            st.s = np.einsum("knj,knj->k", a, O) / np.einsum("knj,knj->k", a, a)
        s = st.s

        # (2) m_i: rows a_j = w (x_j η r_z − s r_j),  b_j = w (s t_j − x_j)   (App. A)
        c = O * eta[:, None, None]  # x_j η
        rows = c[..., None] * R[:, None, None, 2, :] - (s[:, None, None] * R[:, :2, :])[:, None]  # (k,n,2,3)
        rows *= w[..., None, None]
        b = w[..., None] * (s[:, None, None] * st.t2[:, None, :] - O)
        A = np.einsum("knja,knjb->nab", rows, rows)
        rhs = np.einsum("knja,knj->na", rows, b)
        if solve_points:
            st.m = np.linalg.solve(A, rhs[..., None])[..., 0]

        # (3) R_k ← R̃(v) R_k with the rows of Eq. (14) linearised in v; with q = R m and
        #     g_j = (s e_j − x_j η e_z) the residual is e0_j + w (g_j × q)·v.
        q = st.m @ R.transpose(0, 2, 1)
        w = V / (1.0 + eta_kn * q[..., 2])
        sw = s[:, None] * w
        e0 = O - sw[..., None] * (q[..., :2] + st.t2[:, None, :])
        # g_j × q for g_x = (s, 0, −c_x), g_y = (0, s, −c_y), times w
        qx, qy, qz = q[..., 0], q[..., 1], q[..., 2]
        cw = c * w[..., None]
        J = np.empty(rows.shape)
        J[..., 0, 0] = cw[..., 0] * qy
        J[..., 0, 1] = -sw * qz - cw[..., 0] * qx
        J[..., 0, 2] = sw * qy
        J[..., 1, 0] = sw * qz + cw[..., 1] * qy
        J[..., 1, 1] = -cw[..., 1] * qx
        J[..., 1, 2] = -sw * qx
        A = np.einsum("knja,knjb->kab", J, J)
        rhs = -np.einsum("knja,knj->ka", J, e0)
        v = np.linalg.solve(A, rhs[..., None])[..., 0]
        st.R = R = _rodrigues_batch(v) @ R

        # (4) t_x, t_y: minimise Σ (x_j − w s q_j − w s t_j)²  →  t_j = (Σ w x_j − s Σ w² q_j) / (s Σ w²)
        q = st.m @ R.transpose(0, 2, 1)
        w = V / (1.0 + eta_kn * q[..., 2])
        w2 = w * w
        st.t2 = (np.einsum("kn,knj->kj", w, O) / s[:, None] - np.einsum("kn,knj->kj", w2, q[..., :2])) / w2.sum(1)[
            :, None
        ]

        # (5) η_k: rows a = w x_j q_z, b = w (s (q_j + t_j) − x_j)
        #     (fixed focal length: s = f η, so a = w (x_j q_z − f (q_j + t_j)), b = −w x_j)
        p = q[..., :2] + st.t2[:, None, :]
        if self.fixed_focal:
            a = w[..., None] * (O * q[..., 2:3] - self.f_fixed[:, None, None] * p)
            b = -w[..., None] * O
            st.eta = np.einsum("knj,knj->k", a, b) / np.einsum("knj,knj->k", a, a)
            st.s = self.f_fixed * st.eta
        else:
            a = w[..., None] * O * q[..., 2:3]
            b = w[..., None] * (s[:, None, None] * p - O)
            st.eta = np.einsum("knj,knj->k", a, b) / np.einsum("knj,knj->k", a, a)

        # reprojection error of the new estimate (q is current: R and m did not change since (4))
        r = (st.s[:, None] * V / (1.0 + st.eta[:, None] * q[..., 2]))[..., None] * p - O
        return float(np.sqrt(np.einsum("knj,knj->", r, r) / self.n_obs))

    # -- joint Levenberg–Marquardt polish (beyond the paper) ------------------------------------
    def polish(self, st: _State, rms0: float, max_iter: int, tol: float, history: list) -> tuple[_State, int, bool]:
        """Joint damped Gauss–Newton over all unknowns, points eliminated by a Schur complement.

        Camera unknowns per photo: incremental rotation v (3), t_x, t_y, s, η (7; 6 with a fixed
        focal length, where s = f η). Returns the new state, the iterations run and convergence.
        """
        V, O = self.V, self.O
        k, n = V.shape
        nc = 6 if self.fixed_focal else 7
        cost = rms0 * rms0 * self.n_obs
        lam = 1e-3
        eye_c = np.eye(nc)
        eye_p = np.eye(3)
        it = 0
        converged = False
        while it < max_iter:
            it += 1
            R, eta, s, t2, m = st.R, st.eta, st.s, st.t2, st.m
            q = m @ R.transpose(0, 2, 1)
            D = 1.0 + eta[:, None] * q[..., 2]
            w = V / D
            p = q[..., :2] + t2[:, None, :]
            sw = s[:, None] * w
            P = sw[..., None] * p  # predicted image coords (k, n, 2)
            r = P - O
            # dP_j/dq = w (s e_j − P_j η e_z)  (k, n, 2, 3)
            g = np.zeros((k, n, 2, 3))
            g[..., 0, 0] = sw
            g[..., 1, 1] = sw
            g[..., 2] = -(w * eta[:, None])[..., None] * P
            # cameras: d/dv = q × g (q → q + v × q), d/dt_j = s w, d/ds = w p_j, d/dη = −w P_j q_z
            Jc = np.empty((k, n, 2, nc))
            Jc[..., :3] = np.cross(q[:, :, None, :], g)
            Jc[..., 3] = 0.0
            Jc[..., 4] = 0.0
            Jc[..., 0, 3] = sw
            Jc[..., 1, 4] = sw
            dEta = -(w * q[..., 2])[..., None] * P
            if self.fixed_focal:
                Jc[..., 5] = dEta + self.f_fixed[:, None, None] * w[..., None] * p
            else:
                Jc[..., 5] = w[..., None] * p
                Jc[..., 6] = dEta
            Jp = g @ R[:, None]  # (k, n, 2, 3): dP/dm = g R
            # normal equations blocks
            U = np.einsum("knja,knjb->kab", Jc, Jc)
            Vp = np.einsum("knja,knjb->nab", Jp, Jp)
            W = np.einsum("knja,knjb->knab", Jc, Jp)
            gc = np.einsum("knja,knj->ka", Jc, r)
            gp = np.einsum("knja,knj->na", Jp, r)
            while True:
                Ud = U + lam * (U * eye_c + 1e-9 * eye_c)  # Marquardt scaling of the diagonal
                Vd = Vp + lam * (Vp * eye_p + 1e-9 * eye_p)
                Vinv = np.linalg.inv(Vd)
                Y = W @ Vinv[None]  # (k, n, nc, 3)
                S = -np.einsum("knab,lncb->kalc", Y, W)
                S[np.arange(k), :, np.arange(k), :] += Ud
                rhs = -gc + np.einsum("knab,nb->ka", Y, gp)
                dc = np.linalg.solve(S.reshape(k * nc, k * nc), rhs.reshape(-1)).reshape(k, nc)
                dp = -np.einsum("nab,nb->na", Vinv, gp + np.einsum("knab,ka->nb", W, dc))
                new = _State(_rodrigues_batch(dc[:, :3]) @ R, t2 + dc[:, 3:5], eta + dc[:, -1], s, m + dp)
                new.s = self.f_fixed * new.eta if self.fixed_focal else s + dc[:, 5]
                rms_new = self.rms(new)
                cost_new = rms_new * rms_new * self.n_obs
                if np.isfinite(cost_new) and cost_new <= cost:
                    break
                lam *= 10.0
                if lam > 1e8:
                    return st, it, True  # no descent possible: at the minimum to working precision
            st = new
            lam = max(lam / 10.0, 1e-9)
            history.append(rms_new)
            rel = (cost - cost_new) / max(cost, 1e-300)
            cost = cost_new
            if rel < tol or rms_new < 1e-9:
                converged = True
                break
        return st, it, converged


def recover_poses(
    observations: np.ndarray,
    cameras: Sequence[Camera],
    points: np.ndarray,
    *,
    fixed_focal: bool = False,
    max_sweeps: int = 2000,
    tol: float = 1e-10,
    callback: Callable[[int, float], bool | None] | None = None,
    accelerate: bool = True,
    names: Sequence[str] | None = None,
    view_names: Sequence[str] | None = None,
) -> PoseResult:
    """Recover cameras (rotation, translation, focal length) and 3D feature points from clicks.

    Implements the pose recovery of Pighin et al. 2002, §5.1.1 and Appendix A (see the module
    docstring); with ``accelerate`` the alternation is finished by a joint polish.

    Parameters
    ----------
    observations : (k, n, 2) float
        Clicked pixel positions (u right, v down, pixel centres at integers) of ``n`` features in
        ``k`` photos; NaN (both coordinates) where a feature is not clicked in a photo.
    cameras : sequence of k :class:`~photomodel.camera.Camera`
        Initial cameras, e.g. :func:`~photomodel.camera.preset_camera`. Their image sizes fix the
        principal points; with ``fixed_focal`` their focal lengths are kept.
    points : (n, 3) float
        Initial 3D feature positions in mm (the generic head's feature vertices).
    fixed_focal : bool
        Keep every camera's focal length (known lens) and solve for pose and points only.
    max_sweeps : int
        Maximum number of sweeps of the alternation.
    tol : float
        Stop when a sweep changes the squared RMS by less than ``tol`` relative (or the RMS
        drops below 1e-9 px). Without ``accelerate`` the alternation converges linearly, so a
        small ``tol`` is needed to be close to the minimum.
    callback : callable ``(sweep, rms_px) -> bool | None``, optional
        Called after every sweep (and polish iteration); returning True stops early (the result
        is then marked not converged).
    accelerate : bool
        Finish with a joint Levenberg–Marquardt polish (beyond the paper, much faster to reach
        the same minimum). ``False`` runs the paper's alternation alone.
    names, view_names : sequence of str, optional
        Feature and photo names used in error messages (default ``#i``).

    Returns
    -------
    PoseResult

    Raises
    ------
    FitError
        Wrong shapes; a click with one coordinate NaN or an infinite coordinate; fewer than 2
        photos; a feature clicked in fewer than 2 photos; a photo with fewer than
        :data:`MIN_POINTS_PER_VIEW` clicks or with collinear clicks; fewer than
        :data:`MIN_POINTS` features or fewer equations than unknowns; a clicked feature behind
        its initial camera; or a divergent solve.
    """
    obs, valid, pts, cams = _validate(observations, cameras, points, names, view_names, fixed_focal)
    prob = _Problem(obs, valid, cams, fixed_focal)
    st = prob.state_from(cams, pts)
    prob.register(st)
    rms = prob.rms(st)
    history = [rms]
    converged = False
    sweeps = 0
    polish_it = 0
    stopped = False
    # with the polish, the alternation only has to bring the estimate into the polish's basin
    als_tol = max(tol, 1e-4) if accelerate else tol
    min_sweeps = 3 if accelerate else 1
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        while sweeps < max_sweeps:
            prev = rms
            rms = prob.sweep(st)
            sweeps += 1
            history.append(rms)
            if not np.isfinite(rms):
                break
            if callback is not None and callback(sweeps, rms):
                stopped = True
                break
            if rms < 1e-9 or (sweeps >= min_sweeps and abs(prev * prev - rms * rms) <= als_tol * prev * prev):
                converged = True
                break
        if accelerate and not stopped and np.isfinite(rms) and rms >= 1e-9:
            st, polish_it, converged = prob.polish(st, rms, max_iter=50, tol=tol, history=history)
            rms = history[-1]
            if callback is not None:
                callback(sweeps + polish_it, rms)
    if not (np.isfinite(rms) and np.all(np.isfinite(st.m)) and np.all(st.eta > 0)):
        raise FitError(
            "pose recovery diverged (a camera passed behind the head); check that each photo's preset "
            "matches its view and that no feature is clicked in the wrong place"
        )
    out_cams = prob.cameras_from(st, cams)
    res = prob.residuals(st)
    rms_all, per_view, per_point = _rms_summary(res, valid)
    res_px = np.where(valid[..., None], res, np.nan)
    return PoseResult(
        cameras=out_cams,
        points=st.m,
        iterations=sweeps,
        converged=converged,
        rms_px=rms_all,
        per_view_rms_px=per_view,
        per_point_rms_px=per_point,
        residuals_px=res_px,
        polish_iterations=polish_it,
        rms_history=np.asarray(history),
    )
