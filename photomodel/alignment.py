"""Similarity transforms between reconstructions (structure from motion is defined up to one).

Used to fix the gauge of a fit (:mod:`photomodel.modeling.fit`) and to compare a reconstruction with
ground truth (tests, benchmarks).
"""

from __future__ import annotations

import numpy as np

from photomodel.camera import Camera, rotation_angle_deg


def similarity_transform(src: np.ndarray, dst: np.ndarray) -> tuple[float, np.ndarray, np.ndarray]:
    """Least-squares similarity ``dst ≈ s R src + t`` (Umeyama 1991).

    Parameters
    ----------
    src, dst : (n, 3) float, corresponding points (n ≥ 3, not collinear).

    Returns
    -------
    s : float, R : (3, 3) rotation, t : (3,)
    """
    src = np.asarray(src, float)
    dst = np.asarray(dst, float)
    mu_s, mu_d = src.mean(0), dst.mean(0)
    a, b = src - mu_s, dst - mu_d
    U, S, Vt = np.linalg.svd(b.T @ a / len(src))
    D = np.eye(3)
    if np.linalg.det(U) * np.linalg.det(Vt) < 0:
        D[2, 2] = -1.0
    R = U @ D @ Vt
    s = float(np.trace(np.diag(S) @ D) / ((a**2).sum() / len(src)))
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
