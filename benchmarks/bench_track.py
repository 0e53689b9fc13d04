"""Tracking benchmark (issue 6, Pighin et al. 2002 §6.2): accuracy and speed of analysis-by-synthesis
tracking at 300×300 on synthetic sequences with known truth.

The tracked face model is the one a user of the sample gets: the sample project's expressions
fitted and textured from their photos (:func:`tracking.samples.ground_truth.fitted_sample_model`, built by
:func:`tracking.project_model.face_model_from_project`). Sequences (same head motion and region
weights, :func:`tracking.samples.ground_truth.video_truth`):

* ``a`` — frames rendered from that fitted face model itself (the paper's synthetic test);
* ``b`` — the sample video: the scan deformed per region and rendered (end to end);
* ``c`` — (b) with the colour channels scaled (×1.10, ×0.92, ×1.05) and offset (+0.04, −0.03, 0);
* ``d`` — (b) plus Gaussian noise (σ = 0.03 per channel, intensities in [0, 1]);
* ``e`` — (b) tracked with a model holding one expression more (``frown``) than the video uses.

The first frame starts from :func:`tracking.frame_fit.pose_from_clicks` on the 13 initial features clicked
with 0.5 px noise (the user's clicks), a neutral face. A model from photos has its own head frame
and scale (1/1.13 of the real head on the sample): for (b)–(e) the tracked pose is compared with the
truth through one fixed similarity (:func:`tracking.samples.ground_truth.model_gauge`: the model's neutral
registered onto the scan's surface) and camera-space positions are scaled by it. Metrics per
sequence (means over frames): rotation error (deg), translation error of the model centre (mm),
geometry error ``geom_err_mm`` (the issue's measure: mean surface distance from the tracked mesh's
face-region vertices, every :data:`GEOM_SUBSAMPLE`-th, to the frame's true surface — the model's
own mesh at the true weights for (a), the deformed scan the video shows for (b)–(e) — both in the
true head frame), and, as ``geom_vertex_err_mm``, the vertex-to-vertex distance to the generic
mesh's true positions (an upper bound: it also counts sliding along the surface), image RMS
(intensity in [0, 1]), frames flagged diverged (RMS over :data:`tracking.frame_fit.DIVERGED_RMS`, or
rotation error > 5°, or translation error > 20 mm), renderings per frame and frames per second of
the fitting alone (``fps``: all frames; ``fps_tracked``: after the first, which is fitted from the
user's pose in several rounds; rendering of the synthetic frames excluded). ``--outside-weight``
sets :attr:`tracking.frame_fit.TrackOptions.outside_weight` (1.0: the paper's ε).

``--jacobians`` tracks (b) with each combination of analytic / finite-difference Jacobians for the
pose and expression phases, and compares the two Jacobians directly at the true
parameters of 4 frames (cosine per column, norm ratio, time per Jacobian); with ``--json`` this is
the extra key ``"jacobians"``.

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

import cv2
import numpy as np

REPO = Path(__file__).resolve().parents[1]
if str(REPO) not in sys.path:
    sys.path.insert(0, str(REPO))

from photomodel.camera import rotation_angle_deg  # noqa: E402
from photomodel.modeling.generic_mesh import load_generic_mesh  # noqa: E402
from photomodel.rendering.renderer import get_renderer  # noqa: E402
from photomodel.samples.synthetic import ScanSurface  # noqa: E402
from tracking.facemodel import render_model  # noqa: E402
from tracking.frame_fit import FrameFitter, FrameState, TrackOptions, pose_from_clicks, track_frames  # noqa: E402
from tracking.samples.expressions import EXPRESSION_NAMES, EXTRA_EXPRESSIONS  # noqa: E402
from tracking.samples.ground_truth import (  # noqa: E402
    BACKGROUND_RGB,
    fitted_sample_model,
    model_gauge,
    render_video_frame,
    sample_face_model,
    true_scan_vertices,
    video_truth,
)


def _device() -> str:
    try:
        from photomodel.rendering.renderer import get_renderer

        r = get_renderer()
        return f"{platform.processor() or platform.machine()}; GL: {r.ctx.info.get('GL_RENDERER', '?')}"
    except Exception:  # noqa: BLE001 - the device string is informative only
        return platform.platform()


def frames_for(name: str, truth, model) -> list[np.ndarray]:

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


#: Every how many face-region vertices the surface distance is measured at (speed; the mean
#: over ~1000 of the ~4000 face vertices changes by under 0.01 mm).
GEOM_SUBSAMPLE = 4


def true_surface(name: str, truth, model, i: int):
    """ScanSurface of frame ``i``'s true geometry (head frame): the model's own mesh for (a), the
    deformed scan that the video shows for (b)–(e)."""

    if name == "a":
        return ScanSurface(model.blend_geometry(model.vertex_weights(truth.weights[i])), model.faces)
    return ScanSurface(*true_scan_vertices(truth, i))


def first_pose(model, true_model, truth):
    """The first frame's pose from the 13 initial features clicked with 0.5 px noise."""

    mesh = load_generic_mesh()
    ids = np.array([mesh.features[n] for n in mesh.initial_features])
    clicks = truth.camera(0).project(true_model.blend_geometry(true_model.vertex_weights(truth.weights[0]))[ids])
    clicks = clicks + np.random.default_rng(2).normal(0.0, 0.5, clicks.shape)
    return pose_from_clicks(model, ids, clicks, truth.focal_px, truth.width, truth.height)


def run_sequence(name: str, frames: int, options: TrackOptions | None = None) -> dict:
    truth = video_truth(frames)
    fitted = fitted_sample_model(EXPRESSION_NAMES)
    model = fitted_sample_model(EXPRESSION_NAMES + EXTRA_EXPRESSIONS) if name == "e" else fitted
    # the truth: (a) the fitted model itself (its frame is the true one); (b)–(e) the james scan
    true_model = fitted if name == "a" else sample_face_model(EXPRESSION_NAMES)
    s_g, R_g, t_g = (1.0, np.eye(3), np.zeros(3)) if name == "a" else model_gauge(model)
    imgs = frames_for(name, truth, fitted)
    first = first_pose(model, true_model, truth)
    fitter = FrameFitter(model, truth.focal_px, truth.width, truth.height, options)
    stamps = [time.perf_counter()]
    results = track_frames(fitter, imgs, first, callback=lambda i, r: stamps.append(time.perf_counter()))
    elapsed = stamps[-1] - stamps[0]
    # the first frame is fitted from the user's pose in several rounds (a few times a tracked
    # frame's cost); frames/s of the tracked frames alone is the steady rate
    tracked_s = stamps[-1] - stamps[1]
    c = model.centre
    c_true = s_g * R_g @ c + t_g  # the model's centre in the true head frame
    face = np.flatnonzero(model.face_mask)
    rot, trans, geom, v2v, rms, diverged = [], [], [], [], [], 0
    for i, res in enumerate(results):
        R = truth.R[i]
        rot.append(rotation_angle_deg(res.state.R, R @ R_g))
        trans.append(float(np.linalg.norm(s_g * res.state.t - (R @ c_true + truth.t[i]))))
        Pe = s_g * ((model.geometry_at(res.state.alpha) - c) @ res.state.R.T + res.state.t)  # tracked, camera mm
        head = (Pe - truth.t[i]) @ R  # ... in the true head frame
        Xt = true_model.blend_geometry(true_model.vertex_weights(truth.weights[i]))
        v2v.append(float(np.linalg.norm(head - Xt, axis=1)[face].mean()))
        geom.append(float(true_surface(name, truth, true_model, i).closest(head[face[::GEOM_SUBSAMPLE]])[1].mean()))
        rms.append(res.rms)
        diverged += int(res.diverged or rot[-1] > 5.0 or trans[-1] > 20.0)
    return {
        "name": name, "frames": len(results), "fps": len(results) / elapsed,
        "fps_tracked": (len(results) - 1) / tracked_s if len(results) > 1 else float("nan"),
        "rot_err_deg": float(np.mean(rot)), "trans_err_mm": float(np.mean(trans)),
        "geom_err_mm": float(np.mean(geom)), "image_rms": float(np.mean(rms)), "diverged_frames": diverged,
        "geom_vertex_err_mm": float(np.mean(v2v)), "model_scale": float(s_g),
        "evaluations_per_frame": float(np.mean([r.evaluations for r in results])),
    }  # fmt: skip


def jacobian_accuracy(frames: int = 4) -> list[dict]:
    """Analytic vs central-difference Jacobians on frames of sequence (b) at the true parameters:
    per phase (pose: unfiltered ω, t; expression: bandpassed α), the cosine between each analytic
    column and its finite-difference counterpart over the pixels 3 px inside the silhouette, the
    norm ratio, and the time to compute the Jacobian once."""

    truth = video_truth(max(frames, 2))
    model = sample_face_model(EXPRESSION_NAMES)  # at the true parameters: the true model
    fitter = FrameFitter(model, truth.focal_px, truth.width, truth.height)
    rows = []
    for phase, filtered in (("pose", False), ("expression", True)):
        params = np.arange(6) if phase == "pose" else 6 + np.arange(fitter.n_alpha)
        cos, ratio, times = [], [], {"analytic": 0.0, "fd": 0.0}
        for i in range(frames):
            frame = render_video_frame(truth, i)
            R = truth.R[i]
            st = FrameState(R, truth.t[i] + R @ model.centre, model.alpha_of_weights(truth.weights[i]))
            ev = fitter._evaluate(frame, st, filtered)
            J = {}
            for method in ("analytic", "fd"):
                t0 = time.perf_counter()
                J[method] = fitter.jacobian(frame, ev, params, method, filtered)
                times[method] += time.perf_counter() - t0
            y0, y1, x0, x1 = ev.box
            inner = cv2.erode(ev.render.mask.astype(np.uint8), np.ones((7, 7), np.uint8))[y0:y1, x0:x1]
            sel = np.repeat(inner.reshape(-1).astype(bool), 3)
            a, f = J["analytic"][sel].astype(float), J["fd"][sel].astype(float)
            na, nf = np.linalg.norm(a, axis=0), np.linalg.norm(f, axis=0)
            cos.append((a * f).sum(0) / na / nf)
            ratio.append(na / nf)
        rows.append({
            "phase": phase, "columns": len(params), "cosine_mean": float(np.mean(cos)),
            "cosine_min": float(np.min(cos)), "norm_ratio_mean": float(np.mean(ratio)),
            "ms_analytic": 1e3 * times["analytic"] / frames, "ms_fd": 1e3 * times["fd"] / frames,
        })  # fmt: skip
    return rows


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description="tracking benchmark (issue 6)")
    ap.add_argument("--frames", type=int, default=20)
    ap.add_argument("--sequences", default="abcde")
    ap.add_argument("--json", action="store_true")
    ap.add_argument("--outside-weight", type=float, default=None,
                    help="TrackOptions.outside_weight (default: the tracker's; 1.0 = the paper's ε)")
    ap.add_argument("--jacobians", action="store_true",
                    help="compare analytic and finite-difference Jacobians per phase on sequence b")  # fmt: skip
    args = ap.parse_args(argv)
    extra = {}
    if args.jacobians:
        frames = args.frames
        rows = []
        for pose in ("analytic", "fd"):
            for expr in ("analytic", "fd"):
                r = run_sequence("b", frames, TrackOptions(pose_jacobian=pose, expression_jacobian=expr))
                r["name"] = f"b pose={pose} expression={expr}"
                rows.append(r)
        extra["jacobians"] = jacobian_accuracy()
    else:
        options = None if args.outside_weight is None else TrackOptions(outside_weight=args.outside_weight)
        rows = [run_sequence(s, args.frames, options) for s in args.sequences]
    if args.json:
        print(json.dumps({"device": _device(), "sequences": rows, **extra}))
        return 0
    print(f"device: {_device()}")
    head = ("sequence", "frames", "fps", "fps≥1", "rot°", "t mm", "geom mm", "v2v mm", "rms", "div", "renders")
    print(f"{head[0]:34s} " + " ".join(f"{h:>7s}" for h in head[1:]))
    for r in rows:
        print(f"{r['name']:34s} {r['frames']:7d} {r['fps']:7.2f} {r['fps_tracked']:7.2f} {r['rot_err_deg']:7.3f} "
              f"{r['trans_err_mm']:7.2f} "
              f"{r['geom_err_mm']:7.3f} {r['geom_vertex_err_mm']:7.3f} {r['image_rms']:7.4f} {r['diverged_frames']:7d} "
              f"{r['evaluations_per_frame']:7.1f}")  # fmt: skip
    print("fps: all frames; fps≥1: frames after the first (fitted from the user's pose in 3 rounds); "
          "geom: mean surface distance (mm) of the tracked face-region vertices to the frame's true surface; "
          "v2v: vertex-to-vertex distance (upper bound); renders: model renderings per frame")  # fmt: skip
    if "jacobians" in extra:
        print("\nJacobians at the true parameters of sequence b (analytic vs central differences):")
        head = ("cols", "cos mean", "cos min", "|a|/|fd|", "ms analytic", "ms fd")
        print(f"{'phase':12s} " + " ".join(f"{h:>11s}" for h in head))
        for j in extra["jacobians"]:
            print(f"{j['phase']:12s} {j['columns']:11d} {j['cosine_mean']:11.3f} {j['cosine_min']:11.3f} "
                  f"{j['norm_ratio_mean']:11.3f} {j['ms_analytic']:11.1f} {j['ms_fd']:11.1f}")  # fmt: skip
    return 0


if __name__ == "__main__":
    sys.exit(main())
