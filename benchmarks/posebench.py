"""Benchmark harness for pose recovery: ours (accelerated and plain ALS) against the peer BA.

``benchmarks/bench_pose.py`` calls :func:`compare` with the real scan-derived feature points;
:func:`synthetic_rig` builds the photo rigs (true cameras, clicks, preset-like initial cameras).
Running this file directly does a quick run on a hand-made face-like point set::

    .venv/bin/python benchmarks/posebench.py

Accuracy is measured after a similarity alignment (Umeyama, with scale) of the recovered points
onto the true ones, applied to the recovered cameras too: structure from motion recovers the
scene only up to a similarity, so rotations, translations and points are compared in the true
frame, and focal lengths (which a similarity does not change) directly.
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np
from peer_bundle_adjust import bundle_adjust

from photomodel.alignment import align_to_truth
from photomodel.camera import (
    PRESET_AZIMUTH_DEG,
    Camera,
    focal_mm_to_px,
    look_at,
    preset_camera,
    rotation_angle_deg,
)
from photomodel.modeling.pose import recover_poses, reprojection_residuals


# ----------------------------------------------------------------------------------------------
# synthetic rigs
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
    """Cameras on an arc around a face, their clicks of ``points_true`` and preset initial cameras.

    Parameters
    ----------
    n_cameras : int, photos, evenly spread over ``azimuth_range_deg`` (±3° jitter).
    points_true : (n, 3) float mm, the true feature positions (head frame of
        :mod:`photomodel.camera`: +y up, +z out of the face).
    width, height : image size in px (height defaults to 4/3 · width, portrait).
    rng : random generator or seed.
    noise_px : float, standard deviation of Gaussian click noise per coordinate (px).
    focal_mm_range : lens range (mm, 36 mm sensor); each camera draws one uniformly.
    fill : fraction of the image width the face's extent should cover; the distance follows
        from the lens, clipped to 400–1200 mm.
    hide_back_facing : hide a feature in a photo when it faces away from the camera (normal
        approximated by the direction from a head centre 90 mm behind the face), keeping every
        feature visible in at least 2 photos.

    Returns
    -------
    Rig
    """
    rng = np.random.default_rng(rng)
    P = np.asarray(points_true, float)
    height = int(height or round(width * 4 / 3))
    centroid = P.mean(0)
    extent = float(np.ptp(P[:, 0]))
    az = np.linspace(*azimuth_range_deg, n_cameras) + rng.uniform(-3, 3, n_cameras)
    el = rng.uniform(-10, 10, n_cameras)
    cams = []
    for a, e in zip(az, el, strict=True):
        f_px = focal_mm_to_px(rng.uniform(*focal_mm_range), width)
        d = float(np.clip(f_px * extent / (fill * width), 400.0, 1200.0))
        ar, er = np.radians(a), np.radians(e)
        target = centroid + rng.uniform(-10, 10, 3)
        eye = target + d * np.array([np.sin(ar) * np.cos(er), np.sin(er), np.cos(ar) * np.cos(er)])
        roll = np.radians(rng.uniform(-3, 3))
        up = (np.sin(roll), np.cos(roll), 0.0)
        R, t = look_at(eye, target, up=up)
        cams.append(Camera(R, t, f_px, width, height))
    uv = np.stack([c.project(P) for c in cams])
    if noise_px > 0:
        uv = uv + rng.normal(0.0, noise_px, uv.shape)
    if hide_back_facing:
        centre = centroid - np.array([0.0, 0.0, 90.0])
        normal = P - centre
        normal /= np.linalg.norm(normal, axis=1, keepdims=True)
        to_cam = np.stack([c.center for c in cams])[:, None, :] - P[None]
        to_cam /= np.linalg.norm(to_cam, axis=2, keepdims=True)
        cos = np.einsum("kna,na->kn", to_cam, normal)
        visible = cos > 0.0
        # every feature in at least two photos: show it where it faces the camera best
        order = np.argsort(-cos, axis=0)
        for i in np.flatnonzero(visible.sum(0) < 2):
            visible[order[:2, i], i] = True
        uv[~visible] = np.nan
    names = list(PRESET_AZIMUTH_DEG)
    preset_az = np.array([PRESET_AZIMUTH_DEG[p] for p in names])
    presets = [names[int(np.argmin(np.abs(preset_az - a)))] for a in az]
    init = [preset_camera(p, width, height) for p in presets]
    return Rig(uv, cams, init, presets, az)


# ----------------------------------------------------------------------------------------------
# accuracy after similarity alignment
# ----------------------------------------------------------------------------------------------
def accuracy(cameras, points, observations, true_cameras, true_points) -> dict:
    """Reprojection RMS (px, length of the 2D error over all clicks) and errors against the truth."""
    res = reprojection_residuals(cameras, points, observations)
    ok = np.isfinite(res[..., 0])
    rms = float(np.sqrt(np.sum(res[ok] ** 2) / ok.sum()))
    cams, pts = align_to_truth(cameras, points, true_points)
    return {
        "reproj_rms_px": rms,
        "rot_err_deg": float(
            np.mean([rotation_angle_deg(a.R, b.R) for a, b in zip(cams, true_cameras, strict=True)])
        ),
        "focal_err_pct": float(
            np.mean([abs(a.f - b.f) / b.f * 100 for a, b in zip(cams, true_cameras, strict=True)])
        ),
        "point_err_mm": float(np.mean(np.linalg.norm(pts - true_points, axis=1))),
        "centre_err_mm": float(
            np.mean([np.linalg.norm(a.center - b.center) for a, b in zip(cams, true_cameras, strict=True)])
        ),
    }


# ----------------------------------------------------------------------------------------------
# the comparison
# ----------------------------------------------------------------------------------------------
METHODS = {
    "ours": "ALS (§5.1.1, 3 sweeps) + joint LM polish",
    "ours_als": "plain ALS (§5.1.1, App. A) to convergence",
    "peer": "full BA, scipy least_squares, analytic J",
}

#: Absolute RMS slack (px) of the "same minimum" test, for exact clicks where both RMS are ~0.
SAME_MINIMUM_SLACK_PX = 1e-6


def compare(
    observations,
    init_cameras,
    init_points,
    true_cameras,
    true_points,
    repeats: int = 5,
    als_tol: float = 1e-6,
    max_sweeps: int = 20000,
) -> dict:
    """Run ours (accelerated), ours (plain ALS) and the peer on the same data and score them.

    The three methods start from the same initial cameras and points; their timed runs are
    interleaved (ours, ALS, peer, ours, ...) so that a change in machine load hits all alike.

    Parameters
    ----------
    observations : (k, n, 2) float, clicks (NaN where not clicked).
    init_cameras : list[Camera], initial cameras (presets).
    init_points : (n, 3) float mm, initial points (generic head's features).
    true_cameras : list[Camera], ground truth.
    true_points : (n, 3) float mm, ground truth.
    repeats : int, timed runs per method; ``time_ms`` is their median.
    als_tol, max_sweeps : stopping test of the plain ALS (relative RMS change per sweep) and its
        sweep limit.

    Returns
    -------
    dict ``method -> row`` for ``ours``, ``ours_als``, ``peer``. Every row has ``reproj_rms_px``
    (RMS over clicks of the 2D reprojection error's length), ``rot_err_deg`` (mean over cameras),
    ``focal_err_pct`` (mean), ``point_err_mm`` (mean), ``centre_err_mm`` (mean camera-centre
    error) — all after similarity alignment onto the truth —, ``time_ms`` (median), ``iterations``
    (sweeps + polish iterations for ours, Jacobian evaluations for the peer) and ``label``.
    ``ours`` and ``ours_als`` add ``sweeps``, ``polish_iterations``, ``converged``,
    ``rms_ratio_to_peer``, ``same_minimum`` (RMS ≤ 1.02 × peer's + 1e-6 px) and
    ``speedup_vs_peer``; ``peer`` adds ``nfev`` and ``method``.
    """
    true_points = np.asarray(true_points, float)

    def run_ours(accelerate):
        r = recover_poses(
            observations,
            init_cameras,
            init_points,
            accelerate=accelerate,
            **({} if accelerate else {"tol": als_tol, "max_sweeps": max_sweeps}),
        )
        extra = {"sweeps": r.iterations, "polish_iterations": r.polish_iterations, "converged": r.converged}
        return r.cameras, r.points, r.iterations + r.polish_iterations, extra

    def run_peer():
        c, p, info = bundle_adjust(observations, init_cameras, init_points)
        return c, p, info["iterations"], {"nfev": info["nfev"], "method": info["method"]}

    runs = {"ours": lambda: run_ours(True), "ours_als": lambda: run_ours(False), "peer": run_peer}
    times: dict[str, list[float]] = {name: [] for name in runs}
    last = {}
    for _ in range(max(1, repeats)):
        for name, fn in runs.items():
            t0 = time.perf_counter()
            last[name] = fn()
            times[name].append((time.perf_counter() - t0) * 1e3)
    out = {}
    for name in runs:
        cams, pts, its, extra = last[name]
        row = accuracy(cams, pts, observations, true_cameras, true_points)
        row.update(time_ms=float(np.median(times[name])), iterations=int(its), label=METHODS[name], **extra)
        out[name] = row
    out["peer"]["label"] += f" ({out['peer']['method']})"
    peer_rms = out["peer"]["reproj_rms_px"]
    for name in ("ours", "ours_als"):
        rms = out[name]["reproj_rms_px"]
        out[name]["rms_ratio_to_peer"] = rms / max(peer_rms, 1e-300)
        out[name]["same_minimum"] = bool(rms <= 1.02 * peer_rms + SAME_MINIMUM_SLACK_PX)
        out[name]["speedup_vs_peer"] = out["peer"]["time_ms"] / out[name]["time_ms"]
    return out


def face_like_points(n: int = 13, rng: np.random.Generator | int | None = 0) -> np.ndarray:
    """A hand-made face-like point set (mm, head frame), for quick runs and tests only.

    The first 13 points are rough anthropometric landmarks (eye corners, nose, mouth, chin, jaw,
    brows); further points are drawn on an ellipsoidal face surface in front of the head centre.
    """
    base = np.array(
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
            [72.0, 10.0, 30.0],  # jaw / ear
        ]
    )
    if n <= len(base):
        return base[:n].copy()
    rng = np.random.default_rng(rng)
    m = n - len(base)
    az = rng.uniform(-1.3, 1.3, m)
    el = rng.uniform(-0.9, 0.7, m)
    r = np.array([75.0, 95.0, 115.0])
    extra = np.column_stack([np.sin(az) * np.cos(el), np.sin(el), np.cos(az) * np.cos(el)]) * r
    return np.vstack([base, extra + rng.normal(0, 3, (m, 3))])


def perturbed(points: np.ndarray, rng: np.random.Generator | int | None = 1, mm: float = 12.0) -> np.ndarray:
    """A "generic head" version of ``points``: other proportions (±8 % per axis) and ±``mm`` noise."""
    rng = np.random.default_rng(rng)
    c = points.mean(0)
    return (points - c) * rng.uniform(0.92, 1.08, 3) + c + rng.uniform(-mm, mm, points.shape)


def _main():
    rows = []
    for n in (13, 68):
        truth = face_like_points(n, rng=0)
        generic = perturbed(truth, rng=1)
        for k in (3, 5, 7):
            for noise in (0.0, 1.0):
                rig = synthetic_rig(k, truth, rng=100 + k, noise_px=noise)
                r = compare(rig.observations, rig.init_cameras, generic, rig.true_cameras, truth, repeats=3)
                rows.append((k, n, noise, r))
    hdr = (
        f"{'cams':>4} {'pts':>4} {'noise':>5} | {'method':<9} {'rms px':>9} {'rot°':>7} {'f %':>7} "
        f"{'pt mm':>7} {'ms':>8} {'iters':>6} {'same min':>9} {'speedup':>8}"
    )
    print(hdr)
    print("-" * len(hdr))
    for k, n, noise, r in rows:
        for name in ("ours", "ours_als", "peer"):
            x = r[name]
            extra = f"{x['same_minimum']!s:>9} {x['speedup_vs_peer']:8.2f}" if name != "peer" else ""
            print(
                f"{k:4d} {n:4d} {noise:5.1f} | {name:<9} {x['reproj_rms_px']:9.2e} {x['rot_err_deg']:7.3f} "
                f"{x['focal_err_pct']:7.3f} {x['point_err_mm']:7.3f} {x['time_ms']:8.2f} "
                f"{x['iterations']:6d} {extra}"
            )


if __name__ == "__main__":
    _main()
