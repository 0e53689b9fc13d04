"""A scanner's view of the james scan for the scan-fitting tests: noise, stray points and a hole.

Like ``benchmarks/bench_prior.py``'s scan section (σ = 0.5 mm noise, 5 % of the points moved
2–20 mm off the surface along its normal), but with the hole cut by distance from a landmark of
the scan itself, so that the tests need nothing from the benchmark.
"""

from __future__ import annotations

import numpy as np
import trimesh

#: Points sampled on the scan's surface (the benchmark's count).
POINTS = 40_000
#: Scanner noise per axis (mm), the fraction of stray points and how far off they lie (mm).
NOISE_MM = 0.5
STRAY_FRACTION = 0.05
STRAY_MM = (2.0, 20.0)


def scanned(scan, hole_centre: np.ndarray, hole_radius_mm: float, seed: int = 38) -> np.ndarray:
    """(n, 3) mm points of the james ``scan`` (:class:`photomodel.samples.sample_data.Scan`, head
    frame) as a scanner might give them: sampled on its surface, noisy, 5 % strays, and no point
    within ``hole_radius_mm`` of ``hole_centre`` (3,) mm."""
    rng = np.random.default_rng(seed)
    welded = scan.welded
    pts, fidx = trimesh.sample.sample_surface(welded, POINTS, seed=seed)
    normals = np.asarray(welded.face_normals)[fidx]
    keep = np.linalg.norm(pts - hole_centre, axis=1) > hole_radius_mm
    pts = pts + rng.normal(0.0, NOISE_MM, pts.shape)
    stray = rng.random(len(pts)) < STRAY_FRACTION
    off = rng.uniform(*STRAY_MM, stray.sum()) * rng.choice([-1.0, 1.0], stray.sum())
    pts[stray] += normals[stray] * off[:, None]
    return pts[keep]


def chin_hole(scan) -> tuple[np.ndarray, float]:
    """The centre and radius (mm) of a hole over the chin: between iBUG landmarks 8 (chin) and 57
    (lower lip), 30 mm across every way (about a fifth of the face)."""
    L = np.asarray(scan.landmarks, float)
    return (L[8] + L[57]) / 2.0, 30.0
