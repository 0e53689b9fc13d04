"""Synthetic heads and photo rigs with known truth, and accuracy against that truth.

Not part of the product: the camera-recovery benchmarks (``benchmarks/bench_pose.py``,
``benchmarks/posebench.py``) and tests (``tests/test_bundle.py``, ``tests/test_camera_solve.py``)
make their ground truth here and score ours and :mod:`peers.bundle_adjust` against it. Nothing in
``app``, ``photomodel`` or ``tracking`` imports it.

The truth is made independently of the solvers under test: a hand-made face-like point set
(:func:`face_points`), true cameras on an arc around it placed with
:func:`photomodel.camera.look_at` (the camera convention itself), their clicks as exact
projections (:meth:`~photomodel.camera.Camera.project`) plus Gaussian noise, and a "generic head"
(:func:`generic_head`) that is the truth with other proportions and a few mm of noise per point —
what an artist starts from. The initial cameras are the nearest presets (600 mm, 50 mm lens).

Two ways to draw a rig share one geometry (:func:`arc_cameras`, :func:`rig_clicks`) and differ
only in the order of their random draws, each kept so that its seeds keep giving the same rigs:

* :func:`synthetic_rig` — ``n`` cameras spread over an azimuth range, ±3° jitter, ±10°
  elevation, one lens per camera from a range (the benchmarks' draws; the figures in README and
  docs/modeling.md come from them);
* :func:`make_rig` — cameras at given azimuths, ±8° elevation, a given lens or one drawn from
  35–100 mm (the tests' draws).

Accuracy is measured after a similarity alignment (Umeyama, with scale) of the recovered points
onto the true ones, applied to the recovered cameras too (:func:`aligned`): structure from motion
recovers the scene only up to a similarity, so rotations, translations and points are compared in
the true frame, and focal lengths (which a similarity does not change) directly.
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
        [-45.0, 33.0, 86.0],
        [-18.0, 32.0, 94.0],
        [18.0, 32.0, 94.0],
        [45.0, 33.0, 86.0],  # eye corners
        [0.0, 12.0, 127.0],
        [0.0, 40.0, 104.0],  # nose tip, bridge
        [-16.0, 0.0, 108.0],
        [16.0, 0.0, 108.0],  # nostrils
        [-24.0, -33.0, 99.0],
        [24.0, -33.0, 99.0],  # mouth corners
        [0.0, -75.0, 102.0],  # chin
        [-72.0, 10.0, 30.0],
        [72.0, 10.0, 30.0],  # jaw below the ears
    ]
)
N_POSE = len(LANDMARKS)
NAMES = [f"f{i:02d}" for i in range(100)]


# ----------------------------------------------------------------------------------------------
# heads
# ----------------------------------------------------------------------------------------------
def face_points(n: int = 68, seed: np.random.Generator | int | None = 0, noise_mm: float = 3.0) -> np.ndarray:
    """``n`` face-like points (mm, head frame): the 13 :data:`LANDMARKS`, then points on an
    ellipsoidal face surface in front of the head centre, each moved by Gaussian noise of
    ``noise_mm`` per axis."""
    if n <= N_POSE:
        return LANDMARKS[:n].copy()
    rng = np.random.default_rng(seed)
    m = n - N_POSE
    az, el = rng.uniform(-1.3, 1.3, m), rng.uniform(-0.9, 0.7, m)
    d = np.column_stack([np.sin(az) * np.cos(el), np.sin(el), np.cos(az) * np.cos(el)]) * [75.0, 95.0, 115.0]
    return np.vstack([LANDMARKS, d + rng.normal(0.0, noise_mm, (m, 3)) if noise_mm else d])


def generic_head(
    points: np.ndarray, seed: np.random.Generator | int | None = 1, mm: float = 4.0, scale: float = 0.05
) -> np.ndarray:
    """Another head: up to ±``scale`` other proportions per axis and ±``mm`` per point."""
    rng = np.random.default_rng(seed)
    c = points.mean(0)
    return (points - c) * rng.uniform(1.0 - scale, 1.0 + scale, 3) + c + rng.uniform(-mm, mm, points.shape)


def nearest_preset(az: float) -> str:
    """The camera preset whose azimuth is nearest ``az`` (degrees); the first in
    :data:`~photomodel.camera.PRESET_AZIMUTH_DEG` on a tie."""
    return min(PRESET_AZIMUTH_DEG, key=lambda p: abs(PRESET_AZIMUTH_DEG[p] - az))


# ----------------------------------------------------------------------------------------------
# rigs
# ----------------------------------------------------------------------------------------------
@dataclass
class Rig:
    """A synthetic photo rig.

    Attributes
    ----------
    observations : (k, n, 2) float, clicks in px (NaN where hidden), with the requested noise.
    true_cameras : list[Camera]
    init_cameras : list[Camera], the nearest preset (600 mm, 50 mm lens) of each photo.
    presets : list[str], the preset names of ``init_cameras``.
    azimuth_deg : (k,) float, true azimuths.
    """

    observations: np.ndarray
    true_cameras: list[Camera]
    init_cameras: list[Camera]
    presets: list[str]
    azimuth_deg: np.ndarray


def arc_cameras(
    points,
    azimuth_deg,
    elevation_deg,
    focal_mm,
    target_offset_mm,
    roll_deg,
    width: int = W,
    height: int = H,
    fill: float = 0.5,
) -> list[Camera]:
    """Cameras on an arc around ``points``, one per entry of the per-camera arrays.

    Camera ``j`` looks at the centroid moved by ``target_offset_mm[j]`` from azimuth
    ``azimuth_deg[j]`` about +y and elevation ``elevation_deg[j]``, rolled by ``roll_deg[j]``, with
    a ``focal_mm[j]`` lens (36 mm sensor), at the distance where the points' x extent covers
    ``fill`` of the image width (clipped to 400–1200 mm).
    """
    P = np.asarray(points, float)
    c0 = P.mean(0)
    extent = float(np.ptp(P[:, 0]))
    cams = []
    for a, e, fm, off, rl in zip(azimuth_deg, elevation_deg, focal_mm, target_offset_mm, roll_deg, strict=True):
        f = focal_mm_to_px(fm, width)
        d = float(np.clip(f * extent / (fill * width), 400.0, 1200.0))
        ar, er = np.radians(a), np.radians(e)
        target = c0 + off
        eye = target + d * np.array([np.sin(ar) * np.cos(er), np.sin(er), np.cos(ar) * np.cos(er)])
        roll = np.radians(rl)
        R, t = look_at(eye, target, up=(np.sin(roll), np.cos(roll), 0.0))
        cams.append(Camera(R, t, f, width, height))
    return cams


def rig_clicks(cameras, points, rng: np.random.Generator, noise_px: float = 0.0, hide: bool = True) -> np.ndarray:
    """(k, n, 2) clicks: exact projections plus Gaussian noise of ``noise_px`` per axis (none drawn
    when 0). With ``hide`` a feature is hidden (NaN) where it faces away from the camera (normal
    from a head centre 90 mm behind the centroid), keeping each feature in ≥ 2 photos (those it
    faces best)."""
    P = np.asarray(points, float)
    uv = np.stack([c.project(P) for c in cameras])
    if noise_px > 0:
        uv = uv + rng.normal(0.0, noise_px, uv.shape)
    if hide:
        normal = P - (P.mean(0) - [0.0, 0.0, 90.0])
        normal /= np.linalg.norm(normal, axis=1, keepdims=True)
        to_cam = np.stack([c.center for c in cameras])[:, None] - P
        to_cam /= np.linalg.norm(to_cam, axis=2, keepdims=True)
        cos = np.einsum("kna,na->kn", to_cam, normal)
        visible = cos > 0.0
        order = np.argsort(-cos, axis=0)
        for i in np.flatnonzero(visible.sum(0) < 2):
            visible[order[:2, i], i] = True
        uv[~visible] = np.nan
    return uv


def _rig(cameras, points, azimuth_deg, rng, noise_px, hide) -> Rig:
    presets = [nearest_preset(a) for a in azimuth_deg]
    w, h = cameras[0].width, cameras[0].height
    return Rig(
        rig_clicks(cameras, points, rng, noise_px, hide),
        cameras,
        [preset_camera(p, w, h) for p in presets],
        presets,
        np.asarray(azimuth_deg, float),
    )


def synthetic_rig(
    n_cameras: int,
    points_true: np.ndarray,
    width: int = 1000,
    height: int | None = None,
    *,
    rng: np.random.Generator | int | None = None,
    noise_px: float = 0.0,
    azimuth_range_deg: tuple[float, float] = (-70.0, 70.0),
    focal_mm_range: tuple[float, float] = (35.0, 100.0),
    fill: float = 0.5,
    hide_back_facing: bool = True,
) -> Rig:
    """Cameras on an arc around a face, their clicks of ``points_true`` and preset initial cameras
    (the benchmarks' draws).

    Parameters
    ----------
    n_cameras : int, photos, evenly spread over ``azimuth_range_deg`` (±3° jitter), ±10° elevation,
        ±3° roll, aimed within 10 mm of the centroid.
    points_true : (n, 3) float mm, the true feature positions (head frame of
        :mod:`photomodel.camera`: +y up, +z out of the face).
    width, height : image size in px (height defaults to 4/3 · width, portrait).
    rng : random generator or seed.
    noise_px : float, standard deviation of Gaussian click noise per coordinate (px).
    focal_mm_range : lens range (mm, 36 mm sensor); each camera draws one uniformly.
    fill : fraction of the image width the face's extent should cover; the distance follows
        from the lens, clipped to 400–1200 mm.
    hide_back_facing : hide a feature in a photo when it faces away from the camera
        (:func:`rig_clicks`).

    Returns
    -------
    Rig
    """
    rng = np.random.default_rng(rng)
    height = int(height or round(width * 4 / 3))
    az = np.linspace(*azimuth_range_deg, n_cameras) + rng.uniform(-3, 3, n_cameras)
    el = rng.uniform(-10, 10, n_cameras)
    fmm, off, roll = [], [], []
    for _ in range(n_cameras):  # per camera: lens, aim, roll (this order keeps the seeds' rigs)
        fmm.append(rng.uniform(*focal_mm_range))
        off.append(rng.uniform(-10, 10, 3))
        roll.append(rng.uniform(-3, 3))
    cams = arc_cameras(points_true, az, el, fmm, off, roll, width, height, fill)
    return _rig(cams, points_true, az, rng, noise_px, hide_back_facing)


def make_rig(points, azimuths, seed, *, noise_px=1.0, focal_mm=None, hide=True, jitter_deg=0.0) -> Rig:
    """True cameras at ``azimuths`` (±``jitter_deg``) around ``points``, ±8° elevation, ±3° roll,
    aimed within 10 mm of the centroid, lens ``focal_mm`` (one value or per photo; default drawn
    from 35–100 mm), :data:`W` × :data:`H` photos, at the distance where the face fills half the
    image width (clipped to 400–1200 mm); Gaussian clicks of ``noise_px`` per axis, hidden with
    ``hide`` where a feature faces away (:func:`rig_clicks`) — the tests' draws."""
    rng = np.random.default_rng(seed)
    az = np.asarray(azimuths, float) + rng.uniform(-jitter_deg, jitter_deg, len(azimuths))
    k = len(az)
    fmm = rng.uniform(35.0, 100.0, k) if focal_mm is None else np.broadcast_to(np.asarray(focal_mm, float), (k,))
    el, off, roll = [], [], []
    for _ in range(k):  # per camera: elevation, aim, roll (this order keeps the seeds' rigs)
        el.append(rng.uniform(-8.0, 8.0))
        off.append(rng.uniform(-10.0, 10.0, 3))
        roll.append(rng.uniform(-3.0, 3.0))
    cams = arc_cameras(points, az, el, fmm, off, roll, W, H)
    return _rig(cams, points, az, rng, noise_px, hide)


def perturbed_start(cameras, points, seed, *, deg=2.0, mm=10.0, focal=0.05, point_mm=3.0):
    """The truth moved off: each camera turned by ``deg``, shifted up to ``mm``, focal off by up to
    ``focal`` relative; each point moved up to ``point_mm``."""
    rng = np.random.default_rng(seed)
    out = []
    for c in cameras:
        w = rng.normal(size=3)
        w *= np.radians(deg) / np.linalg.norm(w)
        out.append(
            Camera(
                rodrigues(w) @ c.R,
                c.t + rng.uniform(-mm, mm, 3),
                c.f * (1.0 + rng.uniform(-focal, focal)),
                c.width,
                c.height,
            )
        )
    return out, points + rng.uniform(-point_mm, point_mm, points.shape)


# ----------------------------------------------------------------------------------------------
# accuracy
# ----------------------------------------------------------------------------------------------
def click_rms(cameras, points, obs) -> float:
    """RMS over the clicks (finite rows of ``obs``) of the 2D reprojection error's length (px)."""
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
    """Per camera, the angle (deg) between its rotation and the true one."""
    return np.array([rotation_angle_deg(a.R, b.R) for a, b in zip(cameras, true_cameras, strict=True)])


def focal_errors(cameras, true_cameras) -> np.ndarray:
    """Relative focal-length errors (a similarity does not change focal lengths)."""
    return np.array([abs(a.f - b.f) / b.f for a, b in zip(cameras, true_cameras, strict=True)])


def accuracy(cameras, points, observations, true_cameras, true_points) -> dict:
    """Reprojection RMS and errors against the truth, means over cameras / points after
    :func:`aligned`: ``reproj_rms_px`` (:func:`click_rms`), ``rot_err_deg``, ``focal_err_pct``,
    ``point_err_mm``, ``centre_err_mm`` (camera centres)."""
    true_points = np.asarray(true_points, float)
    cams, pts = aligned(cameras, points, true_points)
    return {
        "reproj_rms_px": click_rms(cameras, points, observations),
        "rot_err_deg": float(np.mean(rotation_errors_deg(cams, true_cameras))),
        "focal_err_pct": float(np.mean(focal_errors(cams, true_cameras)) * 100),
        "point_err_mm": float(np.mean(np.linalg.norm(pts - true_points, axis=1))),
        "centre_err_mm": float(
            np.mean([np.linalg.norm(a.center - b.center) for a, b in zip(cams, true_cameras, strict=True)])
        ),
    }
