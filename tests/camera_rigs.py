"""Synthetic heads and photo rigs for the camera-recovery tests (test_bundle, test_camera_solve).

The ground truth is made here, independently of the solvers under test: a hand-made face-like
point set, true cameras placed on an arc around it with :func:`photomodel.camera.look_at` (the
camera convention itself), their clicks as exact projections (:meth:`Camera.project`) plus
Gaussian noise, and a "generic head" that is the truth with other proportions (a few %) and a
few mm of noise per point — what an artist starts from. (A small copy of the idea of
``benchmarks/posebench.py``, so that these tests do not depend on the benchmarks.)
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from photomodel.alignment import similarity_transform, transform_cameras
from photomodel.camera import (
    PRESET_AZIMUTH_DEG,
    Camera,
    focal_mm_to_px,
    look_at,
    preset_camera,
    rodrigues,
    rotation_angle_deg,
)

W, H = 1000, 1333  # portrait photos

# rough facial landmarks in mm, head frame (+y up, +z out of the face): the 13 "pose" features
LANDMARKS = np.array(
    [
        [-45.0, 33.0, 86.0], [-18.0, 32.0, 94.0], [18.0, 32.0, 94.0], [45.0, 33.0, 86.0],  # eye corners
        [0.0, 12.0, 127.0], [0.0, 40.0, 104.0],  # nose tip, bridge
        [-16.0, 0.0, 108.0], [16.0, 0.0, 108.0],  # nostrils
        [-24.0, -33.0, 99.0], [24.0, -33.0, 99.0],  # mouth corners
        [0.0, -75.0, 102.0],  # chin
        [-72.0, 10.0, 30.0], [72.0, 10.0, 30.0],  # jaw below the ears
    ]
)  # fmt: skip
N_POSE = len(LANDMARKS)
NAMES = [f"f{i:02d}" for i in range(100)]


def face_points(n: int = 68, seed: int = 0) -> np.ndarray:
    """``n`` face-like points (mm): the 13 landmarks, then points on an ellipsoidal face surface."""
    if n <= N_POSE:
        return LANDMARKS[:n].copy()
    rng = np.random.default_rng(seed)
    m = n - N_POSE
    az, el = rng.uniform(-1.3, 1.3, m), rng.uniform(-0.9, 0.7, m)
    d = np.column_stack([np.sin(az) * np.cos(el), np.sin(el), np.cos(az) * np.cos(el)])
    return np.vstack([LANDMARKS, d * [75.0, 95.0, 115.0] + rng.normal(0.0, 3.0, (m, 3))])


def generic_head(points: np.ndarray, seed: int = 1, mm: float = 4.0, scale: float = 0.05) -> np.ndarray:
    """Another head: up to ±``scale`` other proportions per axis and ±``mm`` per point."""
    rng = np.random.default_rng(seed)
    c = points.mean(0)
    return (points - c) * rng.uniform(1.0 - scale, 1.0 + scale, 3) + c + rng.uniform(-mm, mm, points.shape)


def nearest_preset(az: float) -> str:
    return min(PRESET_AZIMUTH_DEG, key=lambda p: abs(PRESET_AZIMUTH_DEG[p] - az))


@dataclass
class Rig:
    obs: np.ndarray  # (k, n, 2) clicks, NaN where hidden
    cameras: list[Camera]  # the truth
    presets: list[Camera]  # nearest preset of each photo (600 mm, 50 mm lens)


def make_rig(points, azimuths, seed, *, noise_px=1.0, focal_mm=None, hide=True, jitter_deg=0.0) -> Rig:
    """True cameras on an arc around ``points`` (±8° elevation, ±3° roll, aimed within 10 mm of the
    centroid), lens ``focal_mm`` (one value or per photo; default drawn from 35–100 mm), at the
    distance where the face fills half the image width (clipped to 400–1200 mm); Gaussian clicks of
    ``noise_px`` per axis; with ``hide`` a feature is hidden where it faces away from the camera
    (normal from a head centre 90 mm behind the face), keeping each feature in ≥ 2 photos."""
    rng = np.random.default_rng(seed)
    P = np.asarray(points, float)
    az = np.asarray(azimuths, float) + rng.uniform(-jitter_deg, jitter_deg, len(azimuths))
    k = len(az)
    fmm = rng.uniform(35.0, 100.0, k) if focal_mm is None else np.broadcast_to(np.asarray(focal_mm, float), (k,))
    c0 = P.mean(0)
    extent = float(np.ptp(P[:, 0]))
    cams = []
    for a, fm in zip(az, fmm, strict=True):
        f = focal_mm_to_px(fm, W)
        d = float(np.clip(f * extent / (0.5 * W), 400.0, 1200.0))
        ar, er = np.radians(a), np.radians(rng.uniform(-8.0, 8.0))
        target = c0 + rng.uniform(-10.0, 10.0, 3)
        eye = target + d * np.array([np.sin(ar) * np.cos(er), np.sin(er), np.cos(ar) * np.cos(er)])
        roll = np.radians(rng.uniform(-3.0, 3.0))
        R, t = look_at(eye, target, up=(np.sin(roll), np.cos(roll), 0.0))
        cams.append(Camera(R, t, f, W, H))
    obs = np.stack([c.project(P) for c in cams]) + rng.normal(0.0, noise_px, (k, len(P), 2))
    if hide:
        normal = P - (c0 - [0.0, 0.0, 90.0])
        normal /= np.linalg.norm(normal, axis=1, keepdims=True)
        to_cam = np.stack([c.center for c in cams])[:, None] - P
        to_cam /= np.linalg.norm(to_cam, axis=2, keepdims=True)
        cos = np.einsum("kna,na->kn", to_cam, normal)
        visible = cos > 0.0
        order = np.argsort(-cos, axis=0)
        for i in np.flatnonzero(visible.sum(0) < 2):
            visible[order[:2, i], i] = True
        obs[~visible] = np.nan
    return Rig(obs, cams, [preset_camera(nearest_preset(a), W, H) for a in az])


def perturbed_start(cameras, points, seed, *, deg=2.0, mm=10.0, focal=0.05, point_mm=3.0):
    """The truth moved off: each camera turned by ``deg``, shifted up to ``mm``, focal off by up to
    ``focal`` relative; each point moved up to ``point_mm``."""
    rng = np.random.default_rng(seed)
    out = []
    for c in cameras:
        w = rng.normal(size=3)
        w *= np.radians(deg) / np.linalg.norm(w)
        out.append(Camera(rodrigues(w) @ c.R, c.t + rng.uniform(-mm, mm, 3),
                          c.f * (1.0 + rng.uniform(-focal, focal)), c.width, c.height))  # fmt: skip
    return out, points + rng.uniform(-point_mm, point_mm, points.shape)


def click_rms(cameras, points, obs) -> float:
    """RMS over the clicks of the 2D reprojection error's length (px)."""
    proj = np.stack([c.project(points) for c in cameras])
    e2 = ((proj - obs) ** 2).sum(2)
    ok = np.isfinite(e2)
    return float(np.sqrt(e2[ok].sum() / ok.sum()))


def aligned(cameras, points, true_points, used=None):
    """(cameras, points) moved onto ``true_points`` by the similarity of the points (structure from
    motion is defined up to one); ``used``: the point rows that define it (default all finite)."""
    pts = np.asarray(points, float)
    used = np.isfinite(pts[:, 0]) if used is None else used
    s, R, t = similarity_transform(pts[used], np.asarray(true_points, float)[used])
    return transform_cameras(cameras, s, R, t), pts @ (s * R).T + t


def rotation_errors_deg(cameras, true_cameras) -> np.ndarray:
    return np.array([rotation_angle_deg(a.R, b.R) for a, b in zip(cameras, true_cameras, strict=True)])


def focal_errors(cameras, true_cameras) -> np.ndarray:
    """Relative focal-length errors (a similarity does not change focal lengths)."""
    return np.array([abs(a.f - b.f) / b.f for a, b in zip(cameras, true_cameras, strict=True)])
