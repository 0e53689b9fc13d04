"""Quick comparison for pose recovery: ours (accelerated and plain ALS) against the peer BA.

:func:`compare` runs :func:`photomodel.modeling.pose.recover_poses` (accelerated and plain ALS)
and the peer :func:`peers.bundle_adjust.bundle_adjust` on the same data and scores them with
:func:`peers.rigs.accuracy`; the rigs (true cameras, clicks, preset initial cameras) come from
:func:`peers.rigs.synthetic_rig`. ``benchmarks/bench_pose.py`` is the full benchmark (many draws,
the robust solver); running this file does a quick run on the hand-made face-like point set of
:func:`peers.rigs.face_points`::

    .venv/bin/python benchmarks/posebench.py
"""

from __future__ import annotations

import time

import numpy as np

from peers.bundle_adjust import bundle_adjust
from peers.rigs import accuracy, face_points, generic_head, synthetic_rig
from photomodel.modeling.pose import recover_poses

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


def _main():
    rows = []
    for n in (13, 68):
        truth = face_points(n, seed=0)
        generic = generic_head(truth, seed=1, mm=12.0, scale=0.08)  # other proportions (±8 %), ±12 mm
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
