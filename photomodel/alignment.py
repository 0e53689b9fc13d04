"""Similarity transforms between reconstructions (structure from motion is defined up to one).

Used to fix the gauge of a fit (:mod:`photomodel.modeling.fit`) and to compare a reconstruction with
ground truth (tests, benchmarks).
"""

from __future__ import annotations

import numpy as np

from photomodel.camera import Camera, rotation_angle_deg


def similarity_transform(
    src: np.ndarray, dst: np.ndarray, weights: np.ndarray | None = None, *, scale: bool = True
) -> tuple[float, np.ndarray, np.ndarray]:
    """Least-squares similarity ``dst ≈ s R src + t`` (Umeyama 1991), optionally weighted.

    Minimises ``Σ_i w_i |dst_i − (s R src_i + t)|²`` over rotations ``R`` (det +1), ``t`` and, when
    ``scale``, ``s``: with ``w``-weighted means ``μ``, deviations ``a = src − μ_src``,
    ``b = dst − μ_dst``, covariance ``Σ = Σ_i w_i b_i a_iᵀ / Σ w = U S Vᵀ`` and ``D = diag(1, 1,
    ±1)`` (−1 when ``det U det V < 0``, a reflection otherwise): ``R = U D Vᵀ``,
    ``s = tr(S D) / (Σ_i w_i |a_i|² / Σ w)``, ``t = μ_dst − s R μ_src``.

    Parameters
    ----------
    src, dst : (n, 3) float, corresponding points (n ≥ 3 with non-zero weight, not collinear).
    weights : (n,) float ≥ 0, optional
        each pair's weight (default: all equal, the plain Umeyama).
    scale : bool
        estimate ``s``; ``False`` keeps ``s = 1`` (a rigid motion, weighted Kabsch).

    Returns
    -------
    s : float, R : (3, 3) rotation, t : (3,)
    """
    src = np.asarray(src, float)
    dst = np.asarray(dst, float)
    if weights is None:
        mu_s, mu_d = src.mean(0), dst.mean(0)
        a, b = src - mu_s, dst - mu_d
        cov = b.T @ a / len(src)
    else:
        w = np.asarray(weights, float)
        w = w / w.sum()
        mu_s, mu_d = w @ src, w @ dst
        a, b = src - mu_s, dst - mu_d
        cov = (b * w[:, None]).T @ a
    U, S, Vt = np.linalg.svd(cov)
    D = np.eye(3)
    if np.linalg.det(U) * np.linalg.det(Vt) < 0:
        D[2, 2] = -1.0
    R = U @ D @ Vt
    if not scale:
        return 1.0, R, mu_d - R @ mu_s
    var = (a**2).sum() / len(src) if weights is None else w @ (a**2).sum(1)
    s = float(np.trace(np.diag(S) @ D) / var)
    return s, R, mu_d - s * R @ mu_s


def transform_cameras(cameras: list[Camera], s: float, R: np.ndarray, t: np.ndarray) -> list[Camera]:
    """The cameras that see the moved scene ``X' = s R X + t`` exactly as before.

    ``X_cam = R_c X + t_c`` becomes ``s X_cam = (R_c Rᵀ) X' + (s t_c − R_c Rᵀ t)``; scaling
    camera coordinates does not change the projection, so the images are unchanged.
    """
    out = []
    for c in cameras:
        Rn = c.R @ R.T
        out.append(Camera(Rn, s * c.t - Rn @ t, c.f, c.width, c.height))
    return out


def align_to_truth(cameras, points, true_points):
    """Move a reconstruction onto the truth by the similarity of its points; returns
    ``(cameras, points)`` in the true frame."""
    s, R, t = similarity_transform(points, true_points)
    return transform_cameras(cameras, s, R, t), np.asarray(points) @ (s * R).T + t


def camera_errors(cameras, true_cameras) -> dict:
    """Per-camera rotation error (deg), focal error (%), centre error (mm) of aligned cameras."""
    pairs = list(zip(cameras, true_cameras, strict=True))
    return {
        "rot_err_deg": np.array([rotation_angle_deg(a.R, b.R) for a, b in pairs]),
        "focal_err_pct": np.array([abs(a.f - b.f) / b.f * 100 for a, b in pairs]),
        "centre_err_mm": np.array([np.linalg.norm(a.center - b.center) for a, b in pairs]),
    }
