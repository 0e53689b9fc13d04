"""Tracking benchmark (issue 6, Pighin et al. 2002 §6.2): accuracy and speed of analysis-by-synthesis
tracking at 300×300 on synthetic sequences with known truth.

Sequences (all from :mod:`tracking.samples`, same head motion and region weights):

* ``a`` — frames rendered from the fitted face model itself (the paper's synthetic test);
* ``b`` — the sample video: the scan deformed per region and rendered (end to end);
* ``c`` — (b) with the colour channels scaled (×1.10, ×0.92, ×1.05) and offset (+0.04, −0.03, 0);
* ``d`` — (b) plus Gaussian noise (σ = 0.03 per channel, intensities in [0, 1]);
* ``e`` — (b) tracked with a model holding one expression more (``frown``) than the video uses.

The first frame starts from :func:`tracking.fit.pose_from_clicks` on the 13 initial features clicked
with 0.5 px noise (the user's clicks), a neutral face. Metrics per sequence (means over frames):
rotation error (deg), translation error of the model centre (mm), geometry error (mean over the face
mask of the distance, in camera space, between each tracked vertex and its true position in that
frame — vertex-to-vertex, an upper bound of the surface distance), image RMS (intensity in [0, 1]),
frames flagged diverged (RMS over :data:`tracking.fit.DIVERGED_RMS`, or rotation error > 5°, or
translation error > 20 mm) and frames per second of the fitting alone (rendering of the
synthetic frames excluded).

Run::

    .venv/bin/python benchmarks/bench_track.py [--frames 20] [--sequences abcde] [--json]
    .venv/bin/python benchmarks/bench_track.py --jacobians   # analytic vs finite differences
"""

from __future__ import annotations

import argparse
import json
import platform
import sys
import time
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
if str(REPO) not in sys.path:
    sys.path.insert(0, str(REPO))

from photomodel.camera import rotation_angle_deg  # noqa: E402
from tracking.expressions import EXPRESSION_NAMES, EXTRA_EXPRESSIONS  # noqa: E402
from tracking.facemodel import render_model  # noqa: E402
from tracking.fit import FrameFitter, TrackOptions, pose_from_clicks, track_frames  # noqa: E402
from tracking.samples import BACKGROUND_RGB, render_video_frame, sample_face_model, video_truth  # noqa: E402


def _device() -> str:
    try:
        from photomodel.render import get_renderer

        r = get_renderer()
        return f"{platform.processor() or platform.machine()}; GL: {r.ctx.info.get('GL_RENDERER', '?')}"
    except Exception:  # noqa: BLE001 - the device string is informative only
        return platform.platform()


def frames_for(name: str, truth, model) -> list[np.ndarray]:
    from photomodel.render import get_renderer

    out = []
    rng = np.random.default_rng(1)
    for i in range(truth.frames):
        if name == "a":
            Wv = model.vertex_weights(truth.weights[i])
            bg = np.broadcast_to(np.asarray(BACKGROUND_RGB, np.float32), (truth.height, truth.width, 3))
            img = render_model(get_renderer(), truth.camera(i), model, model.blend_geometry(Wv), Wv, bg).image
        else:
            img = render_video_frame(truth, i)
            if name == "c":
                img = img * np.float32([1.10, 0.92, 1.05]) + np.float32([0.04, -0.03, 0.0])
            elif name == "d":
                img = img + rng.normal(0.0, 0.03, img.shape).astype(np.float32)
        out.append(np.asarray(img, np.float32))
    return out


def run_sequence(name: str, frames: int, options: TrackOptions | None = None) -> dict:
    from photomodel.generic_mesh import load_generic_mesh

    truth = video_truth(frames)
    true_model = sample_face_model(EXPRESSION_NAMES)
    model = sample_face_model(EXPRESSION_NAMES + EXTRA_EXPRESSIONS) if name == "e" else true_model
    imgs = frames_for(name, truth, true_model)
    mesh = load_generic_mesh()
    ids = np.array([mesh.features[n] for n in mesh.initial_features])
    cam0 = truth.camera(0)
    clicks = cam0.project(true_model.blend_geometry(true_model.vertex_weights(truth.weights[0]))[ids])
    clicks = clicks + np.random.default_rng(2).normal(0.0, 0.5, clicks.shape)
    first = pose_from_clicks(model, ids, clicks, truth.focal_px, truth.width, truth.height)
    fitter = FrameFitter(model, truth.focal_px, truth.width, truth.height, options)
    t0 = time.perf_counter()
    results = track_frames(fitter, imgs, first)
    elapsed = time.perf_counter() - t0
    c = true_model.centre
    rot, trans, geom, rms, diverged = [], [], [], [], 0
    for i, res in enumerate(results):
        R, t = truth.R[i], truth.t[i] + truth.R[i] @ c
        rot.append(rotation_angle_deg(res.state.R, R))
        trans.append(float(np.linalg.norm(res.state.t - t)))
        Xt = true_model.blend_geometry(true_model.vertex_weights(truth.weights[i]))
        Xe = model.geometry_at(res.state.alpha)
        Pt = (Xt - c) @ R.T + t
        Pe = (Xe - model.centre) @ res.state.R.T + res.state.t
        geom.append(float(np.linalg.norm(Pt - Pe, axis=1)[true_model.face_mask].mean()))
        rms.append(res.rms)
        diverged += int(res.diverged or rot[-1] > 5.0 or trans[-1] > 20.0)
    return {
        "name": name, "frames": len(results), "fps": len(results) / elapsed,
        "rot_err_deg": float(np.mean(rot)), "trans_err_mm": float(np.mean(trans)),
        "geom_err_mm": float(np.mean(geom)), "image_rms": float(np.mean(rms)), "diverged_frames": diverged,
    }  # fmt: skip


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description="tracking benchmark (issue 6)")
    ap.add_argument("--frames", type=int, default=20)
    ap.add_argument("--sequences", default="abcde")
    ap.add_argument("--json", action="store_true")
    ap.add_argument("--jacobians", action="store_true",
                    help="compare analytic and finite-difference Jacobians per phase on sequence b")  # fmt: skip
    args = ap.parse_args(argv)
    if args.jacobians:
        rows = []
        for pose in ("analytic", "fd"):
            for expr in ("analytic", "fd"):
                r = run_sequence("b", args.frames, TrackOptions(pose_jacobian=pose, expression_jacobian=expr))
                r["name"] = f"b pose={pose} expression={expr}"
                rows.append(r)
    else:
        rows = [run_sequence(s, args.frames) for s in args.sequences]
    if args.json:
        print(json.dumps({"device": _device(), "sequences": rows}))
    else:
        print(f"device: {_device()}")
        head = ("sequence", "frames", "fps", "rot°", "t mm", "geom mm", "rms", "div")
        print(f"{head[0]:34s} " + " ".join(f"{h:>6s}" for h in head[1:]))
        for r in rows:
            print(f"{r['name']:34s} {r['frames']:6d} {r['fps']:6.2f} {r['rot_err_deg']:6.3f} {r['trans_err_mm']:6.2f} "
                  f"{r['geom_err_mm']:8.3f} {r['image_rms']:6.4f} {r['diverged_frames']:4d}")  # fmt: skip
    return 0


if __name__ == "__main__":
    sys.exit(main())
