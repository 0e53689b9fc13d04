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
Python loop over points or cameras. With ``fixed_focal`` step 1 is skipped and step 5 solves
for ``η`` with ``s = f η``.

Two properties of the alternation matter in practice:

* **Start.** A preset camera looks at the head's centre while a photo is framed on the face, so
  the presets' ``t_x, t_y`` can be off by tens of millimetres; step 1 then shrinks ``s`` to
  explain the offset and the next steps rotate the camera far away (side views ended behind
  the head in our tests). Before the first sweep each camera's image scale and offset are
  therefore fitted to its clicks (linear least squares in ``(s, s t_x, s t_y)``,
  :meth:`PoseProblem.register`, *beyond the paper*).
* **Limit.** Because ``w`` is frozen while ``m``, ``R`` and ``η`` are solved for, the
  alternation's limit satisfies the normal equations with the *clicked* ``x`` where the exact
  gradient has the *predicted* one (the ``x η r_z`` terms). With exact clicks both vanish; with
  noisy clicks the limit sits slightly off the reprojection minimum (≈ 0.02–0.2 % higher RMS
  with 1 px noise in our benchmarks) and creeps slowly. Convergence is linear: hundreds to
  thousands of sweeps.

Acceleration (``accelerate=True``, the default, *beyond the paper*)
--------------------------------------------------------------------
After three sweeps of the paper's method (which bring the presets into the right basin),
:func:`recover_poses` finishes with a joint Levenberg–Marquardt polish of the reprojection
error over all unknowns, in the same parameterisation (incremental rotation, ``t_x``, ``t_y``,
``s``, ``η`` per camera; ``m`` per point). The point blocks are eliminated by a Schur
complement, so an iteration is one dense solve of size ``7k`` (``k ≤ 10`` photos) plus batched
3×3 work per point; 4–6 iterations reach the minimum of the full bundle adjustment
(:mod:`peers.bundle_adjust`). ``accelerate=False`` runs the paper's alternation alone.

Gauge
-----
Structure from motion recovers the scene only up to a similarity (the paper: "if we scale all of
the m's and t's up by the same amount, the answer is the same"). Every sub-problem of the
alternation is well posed with the other unknowns held fixed, so it needs no gauge constraint;
the polish's damping keeps its normal equations regular along the 7 flat gauge directions. The
result lives near the frame and size of the initial guess; callers that need a fixed frame
align the recovered points onto a reference afterwards (``photomodel.modeling.fit`` does).

Input rules (:class:`~photomodel.errors.FitError` otherwise, naming the photo or feature):
at least 2 photos; every feature clicked in at least 2 photos; every photo with at least
:data:`MIN_POINTS_PER_VIEW` clicks, not all on one line; at least :data:`MIN_POINTS` features and
at least as many equations (2 per click) as unknowns (7 per camera, 6 with a fixed focal
length, 3 per feature, less the 7 of the gauge); finite numbers, a click has both coordinates or
neither; every clicked feature in front of its initial camera.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

import numpy as np
from numpy.lib.stride_tricks import as_strided

from photomodel.camera import Camera
from photomodel.errors import FitError

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
    "PoseProblem",
    "validate_pose_inputs",
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
    return project_all(cameras, points)[0] - obs


def project_all(cameras: Sequence[Camera], points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Pixel positions (k, n, 2) and depths ``Z_cam`` (k, n) mm of ``points`` (n, 3) in every camera,
    batched over cameras (the one-camera version is :meth:`photomodel.camera.Camera.project`)."""
    pts = np.asarray(points, dtype=float)
    R = np.stack([c.R for c in cameras])
    t = np.stack([c.t for c in cameras])
    f = np.array([c.f for c in cameras])
    pp = np.stack([c.principal_point for c in cameras])
    Xc = pts @ R.transpose(0, 2, 1) + t[:, None, :]
    with np.errstate(divide="ignore", invalid="ignore"):
        uv = f[:, None, None] * Xc[..., :2] / Xc[..., 2:3] + pp[:, None, :]
    return uv, Xc[..., 2]


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
def validate_pose_inputs(observations, cameras, points, names, view_names, fixed_focal):
    """Check the inputs of :func:`recover_poses`; return ``obs (k,n,2)``, ``valid (k,n)``, points, cameras."""
    obs, pts, cams, vname, pname = _check_shapes(observations, cameras, points, names, view_names)
    nan, R, t = _check_values(obs, pts, cams, vname, pname)
    valid, per_view = _check_counts(nan, vname, pname, fixed_focal)
    _check_geometry(obs, pts, valid, per_view, R, t, vname, pname)
    return obs, valid, pts, cams


def _check_shapes(observations, cameras, points, names, view_names):
    """Arrays of the right shapes, one camera and one name per photo, a name per feature, ≥ 2 photos."""
    try:
        obs = np.asarray(observations, dtype=float)
        pts = np.asarray(points, dtype=float)
    except (TypeError, ValueError) as e:
        raise FitError(f"observations and points must be numeric arrays: {e}") from None
    if obs.ndim != 3 or obs.shape[2] != 2:
        raise FitError(f"observations must be an array (photos, features, 2) of pixel clicks; got shape {obs.shape}")
    k, n, _ = obs.shape
    if pts.shape != (n, 3):
        raise FitError(f"points must be ({n}, 3) to match the {n} features of the observations; got shape {pts.shape}")
    cams = list(cameras)
    if len(cams) != k:
        raise FitError(f"got {len(cams)} camera(s) for {k} photo(s) of clicks; give one initial camera per photo")
    vname = [str(v) for v in view_names] if view_names is not None else [f"#{j}" for j in range(k)]
    pname = [str(v) for v in names] if names is not None else [f"#{i}" for i in range(n)]
    if len(vname) != k:
        raise FitError(f"view_names has {len(vname)} entries for {k} photos")
    if len(pname) != n:
        raise FitError(f"names has {len(pname)} entries for {n} features")
    if k < 2:
        raise FitError(f"pose recovery needs at least 2 photos; got {k}")
    return obs, pts, cams, vname, pname


def _check_values(obs, pts, cams, vname, pname):
    """Clicks with both coordinates and finite; finite initial points and valid initial cameras."""
    k, n, _ = obs.shape
    nan = np.isnan(obs)
    half = nan[..., 0] != nan[..., 1]
    if half.any():
        j, i = np.argwhere(half)[0]
        raise FitError(
            f"photo {vname[j]!r}: feature {pname[i]!r} has one coordinate missing ({obs[j, i].tolist()}); "
            "a click needs both u and v (or neither)"
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
    R = np.stack([c.R for c in cams])
    t = np.stack([c.t for c in cams])
    f = np.array([c.f for c in cams])
    bad = ~(np.isfinite(R).all((1, 2)) & np.isfinite(t).all(1) & np.isfinite(f))
    bad |= ~(f > 0)
    bad |= ~(np.abs(R @ R.transpose(0, 2, 1) - np.eye(3)).max((1, 2)) < 1e-6)
    bad |= ~(np.linalg.det(R) > 0)
    if bad.any():
        j = int(np.flatnonzero(bad)[0])
        raise FitError(
            f"initial camera of photo {vname[j]!r} is invalid (focal {f[j]:.4g} px, det R "
            f"{np.linalg.det(R[j]):.4g}): it needs a finite rotation matrix, translation and a "
            "positive focal length"
        )

    return nan, R, t


def _check_counts(nan, vname, pname, fixed_focal):
    """Each feature in ≥ 2 photos, each photo with enough clicks, enough features and equations."""
    k, n = nan.shape[:2]
    valid = ~nan[..., 0]
    seen = valid.sum(0)
    for i in np.flatnonzero(seen < 2)[:1]:
        where = ", ".join(repr(vname[j]) for j in np.flatnonzero(valid[:, i])) or "none"
        raise FitError(
            f"feature {pname[i]!r} is clicked in {seen[i]} photo(s) ({where}); pose recovery needs every "
            "feature in at least 2 photos — click it in another photo or leave it out"
        )
    per_view = valid.sum(1)
    for j in np.flatnonzero(per_view < MIN_POINTS_PER_VIEW)[:1]:
        raise FitError(
            f"photo {vname[j]!r} has {per_view[j]} clicked feature(s); a camera needs at least "
            f"{MIN_POINTS_PER_VIEW} clicks that are not on one line"
        )
    if n < MIN_POINTS:
        raise FitError(f"pose recovery needs at least {MIN_POINTS} features each clicked in 2 photos; got {n}")
    n_cam = 6 if fixed_focal else 7
    n_eq, n_unk = 2 * int(valid.sum()), n_cam * k + 3 * n - 7
    if n_eq < n_unk:
        raise FitError(
            f"{valid.sum()} clicks give {n_eq} equations for {n_unk} unknowns ({k} cameras × {n_cam} + "
            f"{n} features × 3 − 7 for the similarity gauge); click more features in more photos"
        )
    # collinear clicks: the smaller principal axis of a view's clicks against the larger
    return valid, per_view


def _check_geometry(obs, pts, valid, per_view, R, t, vname, pname):
    """No photo with collinear clicks; the head and every clicked feature in front of its initial camera."""
    vf = valid.astype(float)
    uv = np.where(valid[..., None], obs, 0.0)
    mu = uv.sum(1) / per_view[:, None]
    d = (uv - mu[:, None, :]) * vf[..., None]
    cov = d.transpose(0, 2, 1) @ d  # (k, 2, 2)
    tr = cov[:, 0, 0] + cov[:, 1, 1]
    disc = np.sqrt(np.maximum(tr * tr / 4 - (cov[:, 0, 0] * cov[:, 1, 1] - cov[:, 0, 1] ** 2), 0.0))
    lo, hi = tr / 2 - disc, tr / 2 + disc
    flat = ~(lo > (COLLINEAR_RATIO**2) * hi)
    for j in np.flatnonzero(flat)[:1]:
        raise FitError(
            f"photo {vname[j]!r}: its {per_view[j]} clicked features lie on one straight line; the camera "
            "cannot be recovered from them — click features off that line"
        )
    # η = 1/t_z and the weights 1/(1 + η r_z·m) need the origin and every clicked point in front
    for j in np.flatnonzero(~(t[:, 2] > 0))[:1]:
        raise FitError(
            f"initial camera of photo {vname[j]!r} has t_z = {t[j, 2]:.4g} mm: the head is not in front of "
            "it — pick the preset that matches the photo"
        )
    depth = pts @ R[:, 2, :].T + t[:, 2]  # (n, k)
    behind = valid & ~(depth.T > 0)
    if behind.any():
        j, i = np.argwhere(behind)[0]
        raise FitError(
            f"photo {vname[j]!r}: feature {pname[i]!r} is behind the initial camera "
            f"(depth {depth[i, j]:.4g} mm); "
            "pick the preset that matches the photo"
        )


# ----------------------------------------------------------------------------------------------
# the alternation (§5.1.1 + Appendix A), batched over cameras and points
# ----------------------------------------------------------------------------------------------
# X(v) = Σ_c v_c E[c] (Eq. 13) as a (3, 9) matrix, so that cross matrices of many vectors are one product
_EPS = np.zeros((3, 3, 3))
_EPS[0, 2, 1], _EPS[0, 1, 2] = 1.0, -1.0
_EPS[1, 0, 2], _EPS[1, 2, 0] = 1.0, -1.0
_EPS[2, 1, 0], _EPS[2, 0, 1] = 1.0, -1.0
_EPS = _EPS.reshape(3, 9)
_EYE9 = np.eye(3).reshape(9)


def rodrigues_batch(v: np.ndarray) -> np.ndarray:
    """(k, 3) rotation vectors → (k, 3, 3) rotations, Eq. (12):
    ``I + sin θ X(n̂) + (1 − cos θ) X(n̂)² = cos θ I + sin θ X(n̂) + (1 − cos θ) n̂ n̂ᵀ``.

    Written with ``sin θ / θ`` and ``(1 − cos θ) / θ² = 2 (sin(θ/2) / θ)²`` so that no branch is
    needed at ``θ → 0`` (both stay accurate down to the clamp at 1e-30).
    """
    theta = np.maximum(np.sqrt((v * v).sum(1)), 1e-30)
    sinc = np.sin(theta) / theta
    cosc = 2.0 * (np.sin(0.5 * theta) / theta) ** 2
    out = np.cos(theta)[:, None] * _EYE9 + (sinc[:, None] * v) @ _EPS
    out += ((cosc[:, None] * v)[:, :, None] * v[:, None, :]).reshape(-1, 9)
    return out.reshape(-1, 3, 3)


class _State:
    """Unknowns of §5.1.1 as arrays: R (k,3,3), t2 = (t_x, t_y) (k,2), eta (k,), s (k,), m (n,3)."""

    __slots__ = ("R", "t2", "eta", "s", "m")

    def __init__(self, R, t2, eta, s, m):
        self.R, self.t2, self.eta, self.s, self.m = R, t2, eta, s, m

    def copy(self) -> _State:
        return _State(self.R.copy(), self.t2.copy(), self.eta.copy(), self.s.copy(), self.m.copy())


def _gram(M: np.ndarray) -> np.ndarray:
    """``Mᵀ M`` of a stack of row blocks ``M`` (b, rows, c) → (b, c, c)."""
    return M.transpose(0, 2, 1) @ M


class PoseProblem:
    """The clicks in the paper's image coordinates and the operations on a :class:`_State`.

    Everything is dense over (camera, point) with weight 0 where a feature is not clicked, so a
    step is a few array operations whatever the visibility pattern.
    """

    def __init__(self, obs_px, valid, cameras, fixed_focal):
        k, n = valid.shape
        pp = np.stack([c.principal_point for c in cameras])
        self.k, self.n = k, n
        self.valid = valid
        self.V = valid.astype(float)  # (k, n) 1 where clicked
        self.O = np.where(valid[..., None], obs_px - pp[:, None, :], 0.0)  # (k, n, 2) centred, 0 if unclicked
        self.n_obs = float(valid.sum())
        self.fixed_focal = fixed_focal
        self.f_fixed = np.array([c.f for c in cameras])
        # work arrays whose zero entries never change
        self._H = np.zeros((k, n, 2, 4))  # point step: camera-frame rows (h | b)
        self._R4 = np.zeros((k, 4, 4))
        self._R4[:, 3, 3] = 1.0
        self._G = np.zeros((k, n, 2, 4))  # rotation step: rows (a | e0)
        nc = 6 if fixed_focal else 7
        self.nc = nc
        self._J = np.zeros((k, n, 2, nc + 4))  # polish: (J_cam | J_point | r)
        self._g = np.zeros((k, n, 2, 3))  # polish: dP/dq

    # -- paper parameterisation <-> cameras ---------------------------------------------------
    def state_from(self, cameras, points) -> _State:
        R = np.stack([c.R for c in cameras])
        t = np.stack([c.t for c in cameras])
        f = np.array([c.f for c in cameras])
        eta = 1.0 / t[:, 2]
        return _State(R, t[:, :2].copy(), eta, f * eta, np.array(points, dtype=float))

    def cameras_from(self, st: _State, template: Sequence[Camera]) -> list[Camera]:
        tz = 1.0 / st.eta
        f = self.f_fixed if self.fixed_focal else st.s * tz
        t = np.column_stack([st.t2, tz])
        return [Camera(st.R[j], t[j], f[j], c.width, c.height) for j, c in enumerate(template)]

    def evaluate(self, st: _State):
        """Camera-frame points ``q`` (k,n,3), weights ``w`` (k,n), ``p = q_xy + t`` (k,n,2),
        predictions ``P`` (k,n,2), residuals ``r = P − x`` (0 where unclicked) and the cost ``Σ r²``;
        the cost is ``inf`` when a clicked point is not in front of its camera."""
        q = st.m @ st.R.transpose(0, 2, 1)
        D = 1.0 + st.eta[:, None] * q[..., 2]
        w = self.V / D
        p = q[..., :2] + st.t2[:, None, :]
        P = (st.s[:, None] * w)[..., None] * p
        r = P - self.O
        cost = float((r * r).sum())
        if not (D > 0).all() and (self.valid & ~(D > 0)).any():
            cost = np.inf
        return q, w, p, P, r, cost

    def register(self, st: _State) -> None:
        """Fit each camera's image scale and offset to its clicks (beyond the paper).

        A preset camera looks at the head's centre while a photo is framed on the face, so the
        preset's ``t_x, t_y`` can be far off, and step (1) would then shrink ``s`` to explain the
        offset. Least squares in ``(s, s t_x, s t_y)`` (linear) with R, η and the points held
        fixes both before the first sweep.
        """
        q = st.m @ st.R.transpose(0, 2, 1)
        w = self.V / (1.0 + st.eta[:, None] * q[..., 2])
        k, n = w.shape
        M = np.zeros((k, n, 2, 4))  # columns: s, s t_x, s t_y | x
        M[..., 0] = w[..., None] * q[..., :2]
        M[..., 0, 1] = w
        M[..., 1, 2] = w
        M[..., 3] = self.O
        G = _gram(M.reshape(k, 2 * n, 4))
        if self.fixed_focal:  # s = f η is known: fit the offset only
            st.t2 = (G[:, 1:3, 3] / st.s[:, None] - G[:, 0, 1:3]) / G[:, 1:3, 1:3].diagonal(0, 1, 2)
            return
        x = np.linalg.solve(G[:, :3, :3], G[:, :3, 3:])[..., 0]
        st.s = x[:, 0]
        st.t2 = x[:, 1:] / x[:, :1]

    # -- one sweep of the paper's five weighted linear least-squares steps ----------------------
    def sweep(self, st: _State) -> float:
        """Update ``st`` in place by one sweep (§5.1.1 order: s, m, R, t_x/t_y, η); return the RMS (px)."""
        k, n = self.k, self.n
        V, O = self.V, self.O
        R, eta, t2 = st.R, st.eta, st.t2
        ek = eta[:, None]
        q = st.m @ R.transpose(0, 2, 1)  # (k, n, 3): R_k m_i
        w = V / (1.0 + ek * q[..., 2])  # w_ik of Eq. (2)

        # (1) s_k — rows a = w (r·m + t), b = w x (1 + η r_z·m) = x  (w (1 + η r_z·m) = 1 where clicked)
        if not self.fixed_focal:
            a = w[..., None] * (q[..., :2] + t2[:, None, :])
            st.s = (a * O).sum((1, 2)) / (a * a).sum((1, 2))
        s = st.s
        sk = s[:, None]

        # (2) m_i — rows a_j = w (x_j η r_z − s r_j) = h_j R with h_x = w (−s, 0, x η), h_y = w (0, −s, y η),
        #     b_j = w (s t_j − x_j); 3×3 normal equations (Eq. 11) per point
        H = self._H
        sw = sk * w
        H[..., 0, 0] = H[..., 1, 1] = -sw
        H[..., 2] = (w * ek)[..., None] * O
        H[..., 3] = w[..., None] * (sk[..., None] * t2[:, None, :] - O)
        R4 = self._R4
        R4[:, :3, :3] = R
        M = (H.reshape(k, 2 * n, 4) @ R4).reshape(k, n, 2, 4).transpose(1, 0, 2, 3).reshape(n, 2 * k, 4)
        G = _gram(M)
        st.m = np.linalg.solve(G[:, :3, :3], G[:, :3, 3:])[..., 0]

        # (3) R_k ← R̃(v) R_k — Eq. (14) linearised in v (r̃·q = r·q + (v × q)_r): with
        #     g_j = s e_j − x_j η e_z the residual is e0_j + w (g_j × q)·v, 3×3 normal equations per camera
        q = st.m @ R.transpose(0, 2, 1)
        w = V / (1.0 + ek * q[..., 2])
        sw = sk * w
        cw = (w * ek)[..., None] * O  # w x_j η
        qx, qy, qz = q[..., 0], q[..., 1], q[..., 2]
        Gm = self._G
        Gm[..., 0, 0] = cw[..., 0] * qy
        Gm[..., 0, 1] = -sw * qz - cw[..., 0] * qx
        Gm[..., 0, 2] = sw * qy
        Gm[..., 1, 0] = sw * qz + cw[..., 1] * qy
        Gm[..., 1, 1] = -cw[..., 1] * qx
        Gm[..., 1, 2] = -sw * qx
        Gm[..., 3] = O - sw[..., None] * (q[..., :2] + t2[:, None, :])  # e0 = x − prediction
        G = _gram(Gm.reshape(k, 2 * n, 4))
        v = np.linalg.solve(G[:, :3, :3], -G[:, :3, 3:])[..., 0]
        st.R = R = rodrigues_batch(v) @ R

        # (4) t_x, t_y — minimise Σ (x_j − w s q_j − w s t_j)²:  t_j = (Σ w x_j − s Σ w² q_j) / (s Σ w²)
        q = st.m @ R.transpose(0, 2, 1)
        w = V / (1.0 + ek * q[..., 2])
        w2 = w * w
        sum_wx = (w[:, None, :] @ O)[:, 0]
        sum_w2q = (w2[:, None, :] @ q[..., :2])[:, 0]
        st.t2 = t2 = (sum_wx / sk - sum_w2q) / w2.sum(1)[:, None]

        # (5) η_k — rows a = w x_j q_z, b = w (s (q_j + t_j) − x_j)
        #     (fixed focal length: s = f η, so a = w (x_j q_z − f (q_j + t_j)), b = −w x_j)
        p = q[..., :2] + t2[:, None, :]
        wO = w[..., None] * O
        if self.fixed_focal:
            a = wO * q[..., 2:3] - (self.f_fixed[:, None] * w)[..., None] * p
            st.eta = -(a * wO).sum((1, 2)) / (a * a).sum((1, 2))
            st.s = self.f_fixed * st.eta
        else:
            a = wO * q[..., 2:3]
            st.eta = (a * (w[..., None] * (sk[..., None] * p - O))).sum((1, 2)) / (a * a).sum((1, 2))

        # reprojection error of the new estimate (q is current: R and m did not change since (4))
        r = (st.s[:, None] * V / (1.0 + st.eta[:, None] * q[..., 2]))[..., None] * p - O
        return float(np.sqrt((r * r).sum() / self.n_obs))

    # -- joint Levenberg–Marquardt polish (beyond the paper) ------------------------------------
    def polish(self, st: _State, max_iter: int, tol: float, history: list, callback, sweeps: int):
        """Joint damped Gauss–Newton over all unknowns; the point blocks are eliminated by a Schur
        complement, leaving one dense ``(nc k) × (nc k)`` solve per iteration.

        Camera unknowns per photo: incremental rotation ``v`` (3), ``t_x``, ``t_y``, ``s``, ``η``
        (``nc = 7``; 6 with a fixed focal length, where ``s = f η``). Returns
        ``(state, iterations, converged, stopped)``.
        """
        q, w, p, P, r, cost = self.evaluate(st)
        lam = _LM_LAMBDA0
        it = 0
        converged = stopped = False
        while it < max_iter:
            it += 1
            normal = self._normal_blocks(st, q, w, p, P, r)
            step = self._damped_step(st, normal, cost, lam)
            if step is None:  # no descent direction left: at the minimum to working precision
                return st, it - 1, True, False
            st, (q, w, p, P, r, cost_new), lam = step
            lam = max(lam * 0.1, 1e-10)
            rms = float(np.sqrt(cost_new / self.n_obs))
            history.append(rms)
            rel = 1.0 - np.sqrt(cost_new / cost) if cost > 0 else 0.0  # relative RMS change
            cost = cost_new
            if callback is not None and callback(sweeps + it, rms):
                stopped = True
                break
            if rel < tol or rms < _RMS_FLOOR:
                converged = True
                break
        return st, it, converged, stopped

    def _normal_blocks(self, st: _State, q, w, p, P, r):
        """The polish's normal equations at ``st`` (with :meth:`evaluate`'s ``q, w, p, P, r``) in
        blocks: the cameras' ``U`` (k, nc, nc) and gradient ``gc``, the points' ``Vp`` (n, 3, 3) and
        ``gp``, the camera–point coupling ``Wt`` (n, k nc, 3) and ``W2`` (k nc, 3 n), and the
        diagonals ``dU``, ``dV`` the damping scales."""
        k, n, nc = self.k, self.n, self.nc
        J = self._J
        g = self._g
        R, eta, s = st.R, st.eta, st.s
        sw = s[:, None] * w
        c = -(w * eta[:, None])[..., None] * P  # dP_j/dq_z
        # dP/dq rows g_x = (s w, 0, c_x), g_y = (0, s w, c_y)
        g[..., 0, 0] = g[..., 1, 1] = sw
        g[..., 2] = c
        qx, qy, qz = q[..., 0:1], q[..., 1:2], q[..., 2:3]
        # d/dv = q × g_j (rotation q → q + v × q)
        J[..., 0] = qy * c
        J[..., 0, 1] = qz[..., 0] * sw - qx[..., 0] * c[..., 0]
        J[..., 1, 1] = -qx[..., 0] * c[..., 1]
        J[..., 0, 2] = -qy[..., 0] * sw
        J[..., 1, 2] = qx[..., 0] * sw
        J[..., 1, 0] -= qz[..., 0] * sw
        J[..., 0, 3] = J[..., 1, 4] = sw  # d/dt_x, d/dt_y
        dEta = -(w[..., None] * qz) * P
        if self.fixed_focal:
            J[..., 5] = dEta + (self.f_fixed[:, None] * w)[..., None] * p
        else:
            J[..., 5] = w[..., None] * p  # d/ds
            J[..., 6] = dEta
        J[..., nc : nc + 3] = (g.reshape(k, 2 * n, 3) @ R).reshape(k, n, 2, 3)  # dP/dm = g R
        J[..., nc + 3] = r
        Gc = _gram(J.reshape(k, 2 * n, nc + 4))  # U (cameras) and their gradients
        U, gc = Gc[:, :nc, :nc], Gc[:, :nc, nc + 3]
        Jp = np.ascontiguousarray(J[..., nc:].transpose(1, 0, 2, 3)).reshape(n, 2 * k, 4)
        Gp = _gram(Jp)
        Vp, gp = Gp[:, :3, :3], Gp[:, :3, 3]
        Jc, Jm = J[..., :nc], J[..., nc : nc + 3]
        W = Jc[..., 0, :, None] * Jm[..., 0, None, :] + Jc[..., 1, :, None] * Jm[..., 1, None, :]
        Wt = np.ascontiguousarray(W.transpose(1, 0, 2, 3)).reshape(n, k * nc, 3)  # (n, k nc, 3)
        W2 = Wt.transpose(1, 0, 2).reshape(k * nc, 3 * n)
        return U, gc, Vp, gp, Wt, W2, U.diagonal(0, 1, 2), Vp.diagonal(0, 1, 2)

    def _damped_step(self, st: _State, normal, cost: float, lam: float):
        """One Levenberg–Marquardt step from ``st``: the point blocks eliminated by a Schur
        complement, the damping ``lam`` raised tenfold until the cost does not rise. Returns
        ``(new state, its evaluate(), lam)``, or None when ``lam`` passes 1e10."""
        k, n, nc = self.k, self.n, self.nc
        U, gc, Vp, gp, Wt, W2, dU, dV = normal
        R, eta, s = st.R, st.eta, st.s
        eye_c = np.eye(nc)
        while True:
            Vd = Vp + (lam * dV + 1e-12)[:, :, None] * np.eye(3)
            Vinv = np.linalg.inv(Vd)
            Y2 = (Wt @ Vinv).transpose(1, 0, 2).reshape(k * nc, 3 * n)
            S = np.ascontiguousarray(Y2 @ W2.T)
            np.negative(S, out=S)
            s0, s1 = S.strides
            blocks = as_strided(S, (k, nc, nc), ((s0 + s1) * nc, s0, s1))  # view of S's camera blocks
            blocks += U + (lam * dU + 1e-12)[:, :, None] * eye_c
            rhs = Y2 @ gp.reshape(-1) - gc.reshape(-1)
            dc = np.linalg.solve(S, rhs).reshape(k, nc)
            dm = -(Vinv @ (gp + (dc.reshape(-1) @ W2).reshape(n, 3))[..., None])[..., 0]
            new = _State(rodrigues_batch(dc[:, :3]) @ R, st.t2 + dc[:, 3:5], eta + dc[:, -1], s, st.m + dm)
            new.s = self.f_fixed * new.eta if self.fixed_focal else s + dc[:, 5]
            ev = self.evaluate(new)
            if ev[5] <= cost:
                return new, ev, lam
            lam *= 10.0
            if lam > 1e10:
                return None


#: Below this RMS (px) the clicks are reproduced exactly for every practical purpose (exact synthetic clicks).
_RMS_FLOOR = 1e-6
#: With ``accelerate``: sweeps of the alternation before the joint polish takes over. From the presets
#: (after :meth:`PoseProblem.register`) one to ten sweeps all led the polish to the peer's minimum on 72
#: synthetic rigs; the alternation's progress per sweep is small after the first few.
_ALS_SWEEPS_BEFORE_POLISH = 3
#: Initial Levenberg–Marquardt damping of the polish (relative to the normal matrix' diagonal).
_LM_LAMBDA0 = 1e-3


# long: a 46-line numpy docstring for 10 parameters; the body is 32 lines of named steps
def recover_poses(
    observations: np.ndarray,
    cameras: Sequence[Camera],
    points: np.ndarray,
    *,
    fixed_focal: bool = False,
    max_sweeps: int = 2000,
    tol: float = 1e-6,
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
        Maximum number of sweeps of the alternation (and, with ``accelerate``, of polish iterations).
    tol : float
        Stop when a sweep (or polish iteration) changes the RMS by less than ``tol`` relative, or
        when the RMS drops below 1e-6 px. The polish converges quadratically, so its result is then
        at the minimum to many more digits; the alternation converges linearly and stops short of
        its limit by roughly ``tol`` over its rate.
    callback : callable ``(iteration, rms_px) -> bool | None``, optional
        Called after every sweep and polish iteration; returning True stops early (the result is
        then marked not converged).
    accelerate : bool
        After a few sweeps, finish with a joint Levenberg–Marquardt polish (beyond the paper;
        reaches the same minimum much faster). ``False`` runs the paper's alternation alone.
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
        :data:`MIN_POINTS_PER_VIEW` clicks or with collinear clicks; fewer than :data:`MIN_POINTS`
        features or fewer equations than unknowns; a camera or point that is not finite; a clicked
        feature behind its initial camera; or a solve that diverged.
    """
    obs, valid, pts, cams = validate_pose_inputs(observations, cameras, points, names, view_names, fixed_focal)
    prob = PoseProblem(obs, valid, cams, fixed_focal)
    st = prob.state_from(cams, pts)
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        prob.register(st)
        n_sweeps = min(max_sweeps, _ALS_SWEEPS_BEFORE_POLISH) if accelerate else max_sweeps
        st, rms, history, sweeps, converged, stopped = _alternate(prob, st, n_sweeps, tol, callback, accelerate)
        polish_it = 0
        if accelerate and not (stopped or converged) and np.isfinite(rms):
            try:
                st, polish_it, converged, stopped = prob.polish(st, max_sweeps, tol, history, callback, sweeps)
            except np.linalg.LinAlgError:  # the last estimate stands; the checks below judge it
                pass
        q, w, p, P, r, cost = prob.evaluate(st)
    if not (np.isfinite(cost) and np.all(np.isfinite(st.m)) and np.all(st.eta > 0)):
        raise FitError(
            "pose recovery diverged (a camera passed behind the head); check that each photo's preset "
            "matches its view and that no feature is clicked in the wrong place"
        )
    rms_all, per_view, per_point = _rms_summary(r, valid)
    return PoseResult(
        cameras=prob.cameras_from(st, cams),
        points=st.m,
        iterations=sweeps,
        converged=converged,
        rms_px=rms_all,
        per_view_rms_px=per_view,
        per_point_rms_px=per_point,
        residuals_px=np.where(valid[..., None], r, np.nan),
        polish_iterations=polish_it,
        rms_history=np.asarray(history),
    )


def _alternate(prob: PoseProblem, st: _State, n_sweeps: int, tol: float, callback, accelerate: bool):
    """Up to ``n_sweeps`` sweeps of the paper's alternation (§5.1.1) from ``st``. With
    ``accelerate`` a sweep that goes non-finite hands the last finite estimate on (the polish
    that follows only descends). Returns ``(state, rms, history, sweeps, converged, stopped)``."""
    rms = float(np.sqrt(prob.evaluate(st)[5] / prob.n_obs))
    history = [rms]
    converged = stopped = False
    sweeps = 0
    last_good = st.copy()
    while sweeps < n_sweeps:
        prev = rms
        if accelerate:
            last_good = st.copy()
        try:
            rms = prob.sweep(st)
        except np.linalg.LinAlgError:
            rms = np.nan
        sweeps += 1
        history.append(rms)
        if not np.isfinite(rms):
            if accelerate:  # let the (descent-only) polish start from the last finite estimate
                st, rms = last_good, prev
            break
        if callback is not None and callback(sweeps, rms):
            stopped = True
            break
        if rms < _RMS_FLOOR:
            converged = True
            break
        if not accelerate and abs(prev - rms) <= tol * prev:
            converged = True
            break
    return st, rms, history, sweeps, converged, stopped
