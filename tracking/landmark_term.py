"""The detector's landmarks as a soft term of a frame's ε (beyond the paper).

Pighin's tracker (§6) is analysis by synthesis alone: the model's rendering against the frame. With
the robust error (:meth:`tracking.frame_fit.FrameFitter._robust`) that is what keeps a hand over the
mouth from dragging the fit, but it also treats a large expression the model's texture does not show
— a wide open smile whose teeth meet the model's closed lips — as outliers, so the mouth stays
where the prediction put it (on the real-clip sample the tracked mouth corner sat 17–21 px inside
the detected one on frames 420–444). Trackers since (Face2Face, Thies et al. 2016) add a sparse
term: the model's feature vertices projected against a landmark detector's positions. This module
is that term for :class:`tracking.frame_fit.FrameFitter`:

    E_L = c_L Σ_j ½ ‖d_j‖² / (τ² + ‖d_j‖²),    d_j = π(R (X_j(α) − c) + t) − u_j

a Geman–McClure kernel of scale ``τ`` (:attr:`TrackOptions.landmark_scale_px`) on each landmark's
distance in pixels — a detection that is wrong (a landmark under a hand) weighs at most ``½ c_L``
— with ``c_L = κ σ² N / k`` (``κ`` :attr:`TrackOptions.landmarks`, ``σ²`` the frame's robust scale,
``N`` the covered pixels, ``k`` the landmarks): every landmark an outlier costs ``κ`` × what every
pixel an outlier costs, so ``κ`` is the landmarks' weight against the whole image. ``X_j(α)`` is
affine in α (the model's geometry is: :meth:`FaceModel.geometry_at`), so the term's Jacobian is
exact: the projection's derivative times ``−[R(X − c)]×`` (rotation, as the tracker's
``R ← R̂(ω) R`` update), the identity (translation) and ``R ∂X/∂α``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["LandmarkTerm"]


@dataclass
class LandmarkTerm:
    """Landmarks of one frame for one fitter.

    Attributes
    ----------
    X0 : (k, 3) mm, the feature vertices at α = 0 (model space).
    dX : (k, A, 3) mm per unit α, their derivatives (affine in α).
    uv : (k, 2) px, the detected positions in the fitter's frame.
    centre : (3,) mm, the model's centre ``c``.
    f : float, focal length (px); ``principal`` (2,) px.
    scale_px : float, the kernel's ``τ``.
    """

    X0: np.ndarray
    dX: np.ndarray
    uv: np.ndarray
    centre: np.ndarray
    f: float
    principal: np.ndarray
    scale_px: float

    def _camera_points(self, state) -> tuple[np.ndarray, np.ndarray]:
        X = self.X0 + np.einsum("kad,a->kd", self.dX, np.asarray(state.alpha, float))
        Y = (X - self.centre) @ state.R.T  # R (X − c)
        return Y, Y + state.t

    def residuals(self, state) -> np.ndarray:
        """(k, 2) px: projected feature vertices minus the detections."""
        _, Xc = self._camera_points(state)
        return self.f * Xc[:, :2] / Xc[:, 2:3] + self.principal - self.uv

    def value(self, state) -> float:
        """``Σ_j ½ n_j / (τ² + n_j)`` with ``n_j = ‖d_j‖²`` (without ``c_L``): in [0, k/2)."""
        n = (self.residuals(state) ** 2).sum(axis=1)
        t2 = self.scale_px**2
        return float(0.5 * (n / (t2 + n)).sum())

    def jacobian(self, state) -> np.ndarray:
        """(k, 2, 6 + A): ∂d_j/∂(ω, t, α) at ``state``."""
        Y, Xc = self._camera_points(state)
        k, A = self.dX.shape[:2]
        z = Xc[:, 2]
        # ∂π/∂X_cam: f/z [[1, 0, −x/z], [0, 1, −y/z]]
        P = np.zeros((k, 2, 3))
        P[:, 0, 0] = P[:, 1, 1] = self.f / z
        P[:, 0, 2] = -self.f * Xc[:, 0] / z**2
        P[:, 1, 2] = -self.f * Xc[:, 1] / z**2
        D = np.zeros((k, 3, 6 + A))
        # ∂(R̂(ω) Y)/∂ω at 0 = −[Y]×
        D[:, 0, 1], D[:, 0, 2] = Y[:, 2], -Y[:, 1]
        D[:, 1, 0], D[:, 1, 2] = -Y[:, 2], Y[:, 0]
        D[:, 2, 0], D[:, 2, 1] = Y[:, 1], -Y[:, 0]
        D[:, :, 3:6] = np.eye(3)
        D[:, :, 6:] = np.einsum("ij,kaj->kia", state.R, self.dX)
        return np.einsum("kij,kjp->kip", P, D)

    def gauss_newton(self, state) -> tuple[np.ndarray, np.ndarray]:
        """``(H, g)`` over all 6 + A parameters (without ``c_L``): the Gauss–Newton matrix of the
        re-weighted term and the term's gradient, ``g = Σ_j w_j J_jᵀ d_j``, ``H = Σ_j w_j J_jᵀ J_j``
        with ``w_j = τ² / (τ² + n_j)²`` (the kernel's derivative)."""
        d = self.residuals(state)
        J = self.jacobian(state)
        t2 = self.scale_px**2
        w = t2 / (t2 + (d * d).sum(axis=1)) ** 2
        g = np.einsum("k,kip,ki->p", w, J, d)
        H = np.einsum("k,kip,kiq->pq", w, J, J)
        return H, g
