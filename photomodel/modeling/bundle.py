"""Robust joint polish of cameras and feature points (beyond the paper).

:func:`photomodel.modeling.pose.recover_poses` is the paper's alternation (§5.1.1, App. A) finished by a
least-squares polish. This module is the polish that :mod:`photomodel.modeling.camera_solve` runs on real
input, where three things the paper does not treat happen every day:

* **Wrong clicks.** The reprojection error of each click enters through the Huber loss
  ``ρ(e) = e²`` for ``e ≤ c``, ``2 c e − c²`` beyond (``e`` = length of the 2D residual, px), so a
  click placed 80 px off pulls like one placed ``c`` px off. The loss is minimised by
  Levenberg–Marquardt on iteratively re-weighted normal equations (weight ``min(1, c / e)``);
  ``c`` comes from the data (see :mod:`photomodel.modeling.camera_solve`). ``c = inf`` is plain least
  squares.
* **One camera, one lens.** Photos of a ``camera group`` share one focal length: the unknowns
  are, per photo, the incremental rotation ``v`` (3), ``t_x``, ``t_y`` and the image scale
  ``s = f η`` of the paper, and per group ``φ = ln f``; ``η = s / f`` follows. The image scale
  is what a photo measures well, the focal length (perspective strength) what it measures
  poorly, so the ill-determined direction is one unknown per group.
* **Narrow baselines.** When the views are close together the depth of the face trades against
  the focal length almost freely. An optional prior pulls each point towards the generic head's
  feature positions *up to a similarity* (re-aligned by Umeyama after every step, so the prior
  never fights the gauge): ``β Σ_i ‖m_i − (σ R g_i + t)‖²``. Its weight ``β`` (px² per mm²) is
  chosen by the caller (:data:`photomodel.modeling.camera_solve.PRIOR_SIGMA_MM`).

The point blocks are eliminated by a Schur complement, leaving one dense solve of size
``6 k + G`` (k photos, G free group focal lengths) per iteration. Projection and conventions are
those of :mod:`photomodel.camera` (image coordinates centred on the principal point,
``x = s (q_x + t_x) / (1 + η q_z)`` with ``q = R m``).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from photomodel.alignment import similarity_transform
from photomodel.camera import Camera
from photomodel.modeling.bundle_kernel import assemble
from photomodel.modeling.pose import rodrigues_batch

__all__ = ["BundleState", "BundleProblem"]


@dataclass
class BundleState:
    """Unknowns: ``R`` (k,3,3), ``t2`` = (t_x, t_y) (k,2) mm, ``s`` (k,) image scale px/mm,
    ``logf`` (G,) log focal length per group (px), ``m`` (n,3) mm."""

    R: np.ndarray
    t2: np.ndarray
    s: np.ndarray
    logf: np.ndarray
    m: np.ndarray

    def copy(self) -> BundleState:
        return BundleState(self.R.copy(), self.t2.copy(), self.s.copy(), self.logf.copy(), self.m.copy())


class BundleProblem:
    """Clicks, visibility, groups and the prior; :meth:`solve` minimises the robust cost.

    Parameters
    ----------
    obs : (k, n, 2) float, clicks in px (NaN where not clicked).
    valid : (k, n) bool, the clicks that take part (a dropped click is False here).
    principal_points : (k, 2) float px.
    groups : (k,) int, group index of each photo (0..G-1); photos of a group share a focal length.
    focal_free : bool, whether the group focal lengths are unknowns.
    prior_points : (n, 3) float mm or None, the generic head's feature positions.
    prior_weight : float, ``β`` in px² per mm² (0: no prior).
    weights : (k, n) float or None, each click's weight ``w > 0`` (its inverse variance relative to
        a click of weight 1; None: all 1). Residuals are taken as ``√w (P − O)``: a click of weight
        ``w`` pulls like a click of weight 1 that is ``√w`` times as far off, and the Huber loss,
        the noise scale and the suspect test see these scaled residuals (the lengths ``e`` of
        :meth:`evaluate` are scaled).
    """

    def __init__(
        self, obs, valid, principal_points, groups, focal_free=True, prior_points=None, prior_weight=0.0, weights=None
    ):
        k, n = valid.shape
        self.k, self.n = k, n
        self.valid = np.asarray(valid, bool)
        #: √ of each click's weight (None: every weight 1, and no multiplication at all)
        self.sqrt_w = None if weights is None else np.sqrt(np.where(self.valid, np.asarray(weights, float), 0.0))
        self.O = np.where(self.valid[..., None], obs - principal_points[:, None, :], 0.0)
        self.groups = np.asarray(groups, int)
        self.G = int(self.groups.max()) + 1
        self.focal_free = bool(focal_free)
        self.prior = None if prior_points is None or prior_weight <= 0 else np.asarray(prior_points, float)
        self.beta = float(prior_weight) if self.prior is not None else 0.0
        #: with a prior: a unit direction (in the points' frame) along which it is ``1 + depth_gain``
        #: times stiffer — the depth, where the views measure least (None: isotropic)
        self.depth_axis: np.ndarray | None = None
        self.depth_gain = 0.0
        nc = 7 if focal_free else 6
        self.C = 6 * k + (self.G if focal_free else 0)
        cols = np.arange(6 * k).reshape(k, 6)
        if focal_free:
            cols = np.column_stack([cols, 6 * k + self.groups])
        self.cols = cols  # (k, nc) global unknown index of each photo's local camera columns
        self.nc = nc

    # -- conversions ----------------------------------------------------------------------
    def state_from_cameras(self, cameras, points) -> BundleState:
        """State of ``cameras`` (one focal per group: the geometric mean of its photos')."""
        R = np.stack([c.R for c in cameras])
        t = np.stack([c.t for c in cameras])
        f = np.array([c.f for c in cameras], float)
        logf = np.array([np.mean(np.log(f[self.groups == g])) for g in range(self.G)])
        s = np.exp(logf[self.groups]) / t[:, 2]
        return BundleState(R, t[:, :2].copy(), s, logf, np.array(points, float))

    def cameras(self, st: BundleState, template) -> list[Camera]:
        f = np.exp(st.logf[self.groups])
        tz = f / st.s
        return [
            Camera(st.R[j], np.array([st.t2[j, 0], st.t2[j, 1], tz[j]]), float(f[j]), c.width, c.height)
            for j, c in enumerate(template)
        ]

    # -- residuals --------------------------------------------------------------------------
    def evaluate(self, st: BundleState, valid=None):
        """``(q, D, P, r, e)``: camera-frame points, depth factors ``1 + η q_z``, predictions,
        residuals (0 where not valid; times √w with weights) and their lengths (k, n) px."""
        valid = self.valid if valid is None else valid
        eta = st.s / np.exp(st.logf[self.groups])
        q = st.m @ st.R.transpose(0, 2, 1)
        D = 1.0 + eta[:, None] * q[..., 2]
        with np.errstate(divide="ignore", invalid="ignore"):
            P = (st.s[:, None] / D)[..., None] * (q[..., :2] + st.t2[:, None, :])
        r = np.where(valid[..., None], P - self.O, 0.0)
        if self.sqrt_w is not None:
            r = r * self.sqrt_w[..., None]
        e = np.sqrt((r * r).sum(2))
        return q, D, P, r, e

    def prior_target(self, m: np.ndarray) -> tuple[np.ndarray, float]:
        """``(ĝ, σ)``: ``m`` is aligned onto the generic head by the similarity ``σ R m + t``
        (Umeyama, so shrinking the scene does not shrink the prior); ``ĝ`` is the generic head
        mapped back into ``m``'s frame, so that the prior ``Σ ‖σ R m_i + t − g_i‖² = σ² Σ ‖m_i − ĝ_i‖²``."""
        s, R, t = similarity_transform(m, self.prior)
        return (self.prior - t) @ R / s, s

    def cost(self, st: BundleState, c: float, target=None) -> float:
        """Huber cost of the clicks (``Σ ρ(e)``) plus the prior; ``inf`` when a point is behind a
        camera that clicks it or a scale is not positive."""
        return self._cost(st, c, target)[0]

    def _cost(self, st: BundleState, c: float, target=None):
        """``(cost, evaluation, prior target)`` of :meth:`cost`."""
        ev = self.evaluate(st)
        D, e = ev[1], ev[4]  # e is 0 where not valid
        total = float(_huber(e, c).sum())
        if not (np.isfinite(total) and (st.s > 0).all() and not ((D <= 0) & self.valid).any()):
            return np.inf, ev, target
        if self.beta > 0:
            target = self.prior_target(st.m) if target is None else target
            g, sc = target
            total += self.beta * sc * sc * float((self._prior_metric(st.m - g) * (st.m - g)).sum())
        return total, ev, target

    def _prior_metric(self, d: np.ndarray) -> np.ndarray:
        """``A d`` per row: the prior's metric ``A = I + κ a aᵀ``, stiffer by ``1 + κ`` along the
        depth axis ``a`` (:attr:`depth_axis`, ``κ`` = :attr:`depth_gain`); ``A = I`` without one."""
        if self.depth_axis is None:
            return d
        a = self.depth_axis
        return d + self.depth_gain * (d @ a)[..., None] * a

    # -- Levenberg–Marquardt ------------------------------------------------------------------
    def solve(self, st: BundleState, c: float = np.inf, max_iter: int = 50, tol: float = 1e-7):
        """Minimise the cost from ``st``; return ``(state, iterations, converged)``.

        ``c`` is the Huber threshold in px (``inf``: least squares). Stops when an iteration
        lowers the cost by less than ``tol`` relative, or when no damping gives a descent.
        """
        cost, ev, target = self._cost(st, c)
        lam = 1e-3
        it = 0
        while it < max_iter:
            it += 1
            system = self._normal_equations(st, ev, c, target)
            while True:
                new = self._step(st, system, lam)
                new_cost, new_ev, new_target = self._cost(new, c)  # the prior re-aligned: the true cost
                if new_cost <= cost:
                    break
                lam *= 10.0
                if lam > 1e10:
                    return st, it - 1, True
            st, ev, target = new, new_ev, new_target
            lam = max(lam * 0.1, 1e-10)
            rel = (cost - new_cost) / cost if cost > 0 else 0.0
            cost = new_cost
            if rel < tol or cost < 1e-18:
                return st, it, True
        return st, it, False

    def _normal_equations(self, st: BundleState, ev, c: float, target):
        """The Gauss–Newton system with the point blocks apart: ``(U, gc, W2, Vp, gp)`` — camera
        block and gradient, camera–point coupling (unknowns, 3 n), 3 × 3 point blocks and gradients;
        with the prior, its similarity's 7 unknowns join the camera block. The clicks' part is
        assembled by the compiled loop of :mod:`~photomodel.modeling.bundle_kernel`."""
        n = self.n
        e = ev[4]
        with np.errstate(divide="ignore", invalid="ignore"):
            w = np.minimum(c / e, 1.0) if np.isfinite(c) else np.ones_like(e)
        sw = np.where(self.valid, np.sqrt(w), 0.0)
        if self.sqrt_w is not None:
            sw = sw * self.sqrt_w
        U, gc, W2, Vp, gp = assemble(
            st.m, st.R, st.t2, st.s, np.exp(st.logf[self.groups]), self.O, sw, self.cols, self.C
        )
        if self.beta > 0:
            # the prior's similarity (7 unknowns: translation, rotation, scale) joins the camera
            # block, so the prior never fights the gauge (variable projection in effect)
            ghat, sc = target
            beta = self.beta * sc * sc
            B2 = _similarity_basis(st.m).reshape(3 * n, 7)  # the similarity moves the points, not the target
            d = st.m - ghat
            Ad = self._prior_metric(d)
            AB2 = self._prior_metric(B2.reshape(n, 3, 7).transpose(0, 2, 1)).transpose(0, 2, 1).reshape(3 * n, 7)
            Vp = Vp + beta * self._prior_metric(np.eye(3))
            gp = gp + beta * Ad
            U = np.block([[U, np.zeros((self.C, 7))], [np.zeros((7, self.C)), beta * (B2.T @ AB2)]])
            gc = np.concatenate([gc, -beta * (B2.T @ Ad.reshape(-1))])
            W2 = np.concatenate([W2, -beta * AB2.T], axis=0)
        return U, gc, W2, Vp, gp

    def _step(self, st: BundleState, system, lam: float) -> BundleState:
        """The damped step (Marquardt: ``lam`` × the diagonal) from ``st``, points eliminated by
        the Schur complement: one dense solve for the cameras, 3 × 3 back-substitutions."""
        U, gc, W2, Vp, gp = system
        k, n = self.k, self.n
        Ct = U.shape[0]
        W3 = W2.reshape(Ct, n, 3)
        Vinv = _inv3(Vp + (lam * np.diagonal(Vp, 0, 1, 2) + 1e-12)[:, :, None] * np.eye(3))
        # Y = W V⁻¹ with V block-diagonal (3 × 3 per point), as three broadcast products
        Y2 = (
            W3[:, :, 0, None] * Vinv[None, :, 0, :]
            + W3[:, :, 1, None] * Vinv[None, :, 1, :]
            + W3[:, :, 2, None] * Vinv[None, :, 2, :]
        ).reshape(Ct, 3 * n)
        S = U - Y2 @ W2.T
        S.flat[:: Ct + 1] += lam * np.diagonal(U) + 1e-12
        rhs = Y2 @ gp.reshape(-1) - gc
        try:
            dc = np.linalg.solve(S, rhs)
        except np.linalg.LinAlgError:
            dc = np.linalg.lstsq(S, rhs, rcond=None)[0]
        gm = gp + (dc @ W2).reshape(n, 3)
        dm = -(Vinv * gm[:, None, :]).sum(2)
        dcam = dc[: 6 * k].reshape(k, 6)
        return BundleState(
            rodrigues_batch(dcam[:, :3]) @ st.R,
            st.t2 + dcam[:, 3:5],
            st.s + dcam[:, 5],
            st.logf + (dc[6 * k : self.C] if self.focal_free else 0.0),
            st.m + dm,
        )


def _inv3(A: np.ndarray) -> np.ndarray:
    """Inverses of a stack of 3 × 3 matrices (b, 3, 3) by the adjugate (symmetric positive
    definite here: damped normal matrices); ~5× faster than ``np.linalg.inv`` on small stacks."""
    a, b, c = A[:, 0, 0], A[:, 0, 1], A[:, 0, 2]
    d, e, f = A[:, 1, 0], A[:, 1, 1], A[:, 1, 2]
    g, h, i = A[:, 2, 0], A[:, 2, 1], A[:, 2, 2]
    C = np.empty_like(A)
    C[:, 0, 0] = e * i - f * h
    C[:, 0, 1] = c * h - b * i
    C[:, 0, 2] = b * f - c * e
    C[:, 1, 0] = f * g - d * i
    C[:, 1, 1] = a * i - c * g
    C[:, 1, 2] = c * d - a * f
    C[:, 2, 0] = d * h - e * g
    C[:, 2, 1] = b * g - a * h
    C[:, 2, 2] = a * e - b * d
    det = a * C[:, 0, 0] + b * C[:, 1, 0] + c * C[:, 2, 0]
    return C / det[:, None, None]


def _similarity_basis(g: np.ndarray) -> np.ndarray:
    """(n, 3, 7) first-order motion of points ``g`` under a similarity: translation (3),
    rotation ``ω × g`` (3), scale about the origin (1)."""
    n = len(g)
    B = np.zeros((n, 3, 7))
    B[:, :, :3] = np.eye(3)
    B[:, 0, 4], B[:, 0, 5] = g[:, 2], -g[:, 1]
    B[:, 1, 3], B[:, 1, 5] = -g[:, 2], g[:, 0]
    B[:, 2, 3], B[:, 2, 4] = g[:, 1], -g[:, 0]
    B[:, :, 6] = g
    return B


def _huber(e: np.ndarray, c: float) -> np.ndarray:
    """Huber cost of residual lengths ``e``: ``e²`` up to ``c``, ``2 c e − c²`` beyond."""
    if not np.isfinite(c):
        return e * e
    return np.where(e <= c, e * e, 2.0 * c * e - c * c)


def huber_weight(e: np.ndarray, c: float) -> np.ndarray:
    """The IRLS weight ``min(1, c / e)`` of residual lengths ``e`` (px)."""
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where(e > c, c / e, 1.0)
