"""Expression-editing benchmark (issue 16, Yang et al. 2012): the whole-clip smooth solve against
per-frame tracking, and the accuracy of the written edited frames, on synthetic sequences with truth.

**Smooth solve** (:func:`tracking.smooth.smooth_clip`, §3.1.4). The sequences of
``benchmarks/bench_track.py`` — ``b`` (the scan deformed per region and rendered, tracked with the
model fitted from the sample's photos) and ``d`` ((b) plus Gaussian noise σ = 0.03) — at
:data:`SMOOTH_FRAMES` frames: the same motion and expression bumps as the 40-frame sample, sampled
like a 25–30 fps clip (a smile rises over ~12 frames). Each is tracked per frame
(:func:`tracking.frame_fit.track_frames`), then smoothed. Metrics on the region weights of the
regions with parameters (non-neutral expressions, against the truth's):

* ``jitter`` — mean over the frames of ‖second difference‖ of the weights (the issue's measure;
  the truth's own curves have a jitter too, printed as ``jitter_truth``);
* ``rmse`` — RMS weight error over frames, regions and expressions;
* ``peak_err`` — mean absolute weight error at the peaks: over each true bump (truth ≥ 0.3 at its
  maximum), the frames where the truth is within 10 % of its maximum (a lagging or flattened
  curve shows there).

The ``smooth`` object of ``--json`` holds the means over the sequences; the table prints each.

**Edits** (:func:`tracking.edit_video.edit_frames`, §4–5): on the smoothed (b) track, the smile is
suppressed (×0) and magnified (×1.5) over the whole clip (Eq. 25); the written frames (float,
before any encoding) are compared with frames rendered from the truth with the same edit applied
to its weights (the scan deformed per region, :func:`tracking.synthetic_sequences.ground_truth.render_video_frame`
— not the tracker's model), at :data:`EDIT_FRAMES` frames across the smile. ``psnr_face_db``:
over the face — the pixels that the model's control regions (mouth with jaw, eyes, forehead:
membership over 0.5) cover at the tracked pose, with the tracked or the edited weights;
``psnr_outside_db``: the written frame against the input frame over the rest, less a margin of
:data:`OUTSIDE_MARGIN_PX` around the face (where the flow fades out); ``psnr_face_paste_db``: the
baseline of pasting the model's rendering at the edited weights over the frame, same face pixels.
PSNR with peak 1 (intensities in [0, 1]); pixels identical everywhere give 120 dB (capped).

Run::

    .venv/bin/python benchmarks/bench_edit.py [--frames 100] [--sequences bd] [--json] [--png strip.png]
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from dataclasses import replace
from pathlib import Path

import cv2
import numpy as np

REPO = Path(__file__).resolve().parents[1]
for p in (REPO, REPO / "benchmarks"):
    if str(p) not in sys.path:
        sys.path.insert(0, str(p))

from bench_track import first_pose  # noqa: E402

from photomodel.rendering.renderer import get_renderer  # noqa: E402
from tracking.blendshape_face import render_model  # noqa: E402
from tracking.edit import scale_expression, scale_factors  # noqa: E402
from tracking.edit_video import edit_frames  # noqa: E402
from tracking.frame_fit import FrameFitter, track_frames  # noqa: E402
from tracking.smooth import SmoothOptions, jitter, smooth_clip, weight_curves  # noqa: E402
from tracking.synthetic_sequences.expressions import EXPRESSION_NAMES  # noqa: E402
from tracking.synthetic_sequences.ground_truth import (  # noqa: E402
    fitted_sample_model,
    render_video_frame,
    sample_face_model,
    video_truth,
)

#: Frames of the smoothing sequences (the sample's motion sampled like a 25–30 fps clip).
SMOOTH_FRAMES = 100
#: Frames of the (b) sequence (of SMOOTH_FRAMES) at which the edits are compared with the truth:
#: across the smile's bump (its peak at 30 % of the clip, σ = 12 % of it).
EDIT_FRAMES = (18, 24, 30, 36, 42)
#: Margin (px) around the face excluded from the outside PSNR: the flow's falloff reaches
#: FALLOFF_CUT × FlowOptions.extend_px = 12 px beyond the moving skin.
OUTSIDE_MARGIN_PX = 15
#: The edits compared: the smile suppressed and magnified (Eq. 25).
EDITS = (("suppress", 0.0), ("magnify", 1.5))
PSNR_CAP_DB = 120.0


def psnr(a: np.ndarray, b: np.ndarray, mask: np.ndarray) -> float:
    """PSNR (dB, peak 1) of two (H, W, 3) images over ``mask`` (H, W), capped at :data:`PSNR_CAP_DB`."""
    e = float(((np.asarray(a, float) - np.asarray(b, float)) ** 2)[mask].mean()) if mask.any() else 0.0
    return PSNR_CAP_DB if e <= 10 ** (-PSNR_CAP_DB / 10) else float(10 * np.log10(1.0 / e))


def sequence_frames(truth, names: str) -> dict[str, list[np.ndarray]]:
    """Frames of sequences ``b`` and ``d`` (bench_track's: (d) is (b) plus the same seeded noise)."""
    b = [render_video_frame(truth, i) for i in range(truth.frames)]
    out = {"b": b}
    if "d" in names:
        rng = np.random.default_rng(1)
        out["d"] = [(img + rng.normal(0.0, 0.03, img.shape).astype(np.float32)) for img in b]
    return out


def weight_metrics(model, W: np.ndarray, truth) -> dict:
    """jitter, RMSE and peak error of weights (T, R, m) against the truth (module docstring)."""
    regs = [r for r, a in enumerate(model.n_alpha) if a]
    Wc, Tc = W[:, regs, 1:], truth.weights[:, regs, 1:]
    peaks = []
    for r in range(Tc.shape[1]):
        for k in range(Tc.shape[2]):
            top = Tc[:, r, k].max()
            if top >= 0.3:
                near = Tc[:, r, k] >= 0.9 * top
                peaks.append(np.abs(Wc[near, r, k] - Tc[near, r, k]).mean())
    return {
        "jitter": jitter(Wc),
        "rmse": float(np.sqrt(np.mean((Wc - Tc) ** 2))),
        "peak_err": float(np.mean(peaks)),
        "jitter_truth": jitter(Tc),
    }


def smooth_sequence(name: str, frames, truth, options: SmoothOptions) -> dict:
    """Track ``frames`` per frame, smooth, and measure both (module docstring)."""
    model = fitted_sample_model(EXPRESSION_NAMES)
    fitter = FrameFitter(model, truth.focal_px, truth.width, truth.height)
    t0 = time.perf_counter()
    results = track_frames(fitter, frames, first_pose(model, sample_face_model(EXPRESSION_NAMES), truth))
    t1 = time.perf_counter()
    states = [r.state for r in results]
    smoothed = smooth_clip(fitter, frames, states, options)
    t2 = time.perf_counter()
    per_frame = weight_metrics(model, weight_curves(model, [s.alpha for s in states]), truth)
    smooth = weight_metrics(model, smoothed.weights, truth)
    return {
        "name": name,
        "frames": len(frames),
        "track_s": t1 - t0,
        "smooth_s": t2 - t1,
        "frame": per_frame,
        "smooth": smooth,
        "states": smoothed.states,
        "fitter": fitter,
    }


def face_masks(renderer, fitter, states, alphas_new, t: int) -> tuple[np.ndarray, np.ndarray]:
    """(face, outside) (H, W) bool of frame ``t`` (module docstring)."""
    model = fitter.model
    ctrl = (1.0 - model.membership[:, 0]).astype(np.float32)[:, None]
    cam = fitter.camera(states[t])
    face = np.zeros(fitter.H * fitter.W, bool)
    for a in (states[t].alpha, alphas_new[t]):
        ras = renderer.rasterize_barycentric(cam, model.geometry_at(a), model.faces)
        face[ras.pixels[ras.interpolate(ctrl)[:, 0] > 0.5]] = True
    face = face.reshape(fitter.H, fitter.W)
    k = 2 * OUTSIDE_MARGIN_PX + 1
    near = cv2.dilate(face.astype(np.uint8), cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (k, k))).astype(bool)
    return face, ~near


def edit_accuracy(run: dict, frames, truth, png: Path | None = None) -> list[dict]:
    """The edits of :data:`EDITS` on the smoothed (b) track against the truth (module docstring);
    ``png``: a strip of the middle compared frame — input, then per edit the written frame, the
    truth and 4× their absolute difference."""
    fitter, states = run["fitter"], run["states"]
    model = fitter.model
    renderer = get_renderer()
    k = EXPRESSION_NAMES.index("smile")
    sel = [t for t in EDIT_FRAMES if t < len(frames)]
    rows, strip = [], [frames[sel[len(sel) // 2]]]
    for op, factor in EDITS:
        edit = {"op": "scale", "expression": "smile", "factor": factor}
        images, new, counts = edit_frames(fitter, frames, states, [edit], only=sel)
        edited_truth = replace(truth, weights=scale_expression(truth.weights, k, scale_factors(edit, truth.frames)))
        face_db, out_db, paste_db = [], [], []
        for j, t in enumerate(sel):
            gt = render_video_frame(edited_truth, t)
            face, outside = face_masks(renderer, fitter, states, new, t)
            Wv = model.vertex_weights(model.region_weights(new[t]))
            paste = render_model(
                renderer, fitter.camera(states[t]), model, model.blend_geometry(Wv), Wv, background=frames[t]
            ).image
            face_db.append(psnr(images[j], gt, face))
            out_db.append(psnr(images[j], frames[t], outside))
            paste_db.append(psnr(paste, gt, face))
            if j == len(sel) // 2:
                strip += [images[j], gt, np.minimum(4 * np.abs(images[j] - gt), 1.0)]
        rows.append(
            {
                "op": op,
                "factor": factor,
                "psnr_face_db": float(np.mean(face_db)),
                "psnr_outside_db": float(np.min(out_db)),
                "psnr_face_paste_db": float(np.mean(paste_db)),
                "frames": sel,
                "psnr_face_min_db": float(np.min(face_db)),
                **counts,
            }
        )
    if png is not None:
        rgb = np.clip(np.rint(np.hstack(strip) * 255), 0, 255).astype(np.uint8)
        cv2.imwrite(str(png), cv2.cvtColor(rgb, cv2.COLOR_RGB2BGR))
    return rows


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description="expression-editing benchmark (issue 16)")
    ap.add_argument("--frames", type=int, default=SMOOTH_FRAMES)
    ap.add_argument("--sequences", default="bd", help="smoothing sequences among b, d (the edits use b)")
    ap.add_argument("--second-difference", type=float, default=SmoothOptions.second_difference)
    ap.add_argument("--json", action="store_true")
    ap.add_argument(
        "--png", type=Path, help="write the middle compared frame: input | per edit: written, truth, 4x |difference|"
    )
    args = ap.parse_args(argv)
    truth = video_truth(args.frames)
    seqs = sequence_frames(truth, args.sequences)
    options = SmoothOptions(second_difference=args.second_difference)
    runs = {s: smooth_sequence(s, seqs[s], truth, options) for s in dict.fromkeys("b" + args.sequences) if s in seqs}
    edits = edit_accuracy(runs["b"], seqs["b"], truth, args.png)
    used = [runs[s] for s in args.sequences if s in runs]
    smooth = {
        f"{key}_{kind}": float(np.mean([r[kind][key] for r in used]))
        for key in ("jitter", "rmse", "peak_err")
        for kind in ("frame", "smooth")
    }
    if args.json:
        print(
            json.dumps(
                {
                    "smooth": smooth,
                    "edits": [
                        {k: e[k] for k in ("op", "factor", "psnr_face_db", "psnr_outside_db", "psnr_face_paste_db")}
                        for e in edits
                    ],
                }
            )
        )
        return 0
    print(f"smooth solve ({options}), {args.frames} frames:")
    print(f"{'seq':4s} {'':7s} {'jitter':>8s} {'rmse':>8s} {'peak':>8s}   (truth jitter)")
    for r in used:
        for kind in ("frame", "smooth"):
            m = r[kind]
            print(
                f"{r['name']:4s} {kind:7s} {m['jitter']:8.4f} {m['rmse']:8.4f} {m['peak_err']:8.4f}   "
                f"({m['jitter_truth']:.4f})"
            )
        print(f"     tracked in {r['track_s']:.0f} s, smoothed in {r['smooth_s']:.0f} s")
    print("mean:", {k: round(v, 4) for k, v in smooth.items()})
    print(
        f"bars: jitter_smooth ≤ ½ jitter_frame: {smooth['jitter_smooth'] <= 0.5 * smooth['jitter_frame']}; "
        f"rmse ≤ 1.02×: {smooth['rmse_smooth'] <= 1.02 * smooth['rmse_frame']}; "
        f"peaks ≤ 1.1×: {smooth['peak_err_smooth'] <= 1.1 * smooth['peak_err_frame']}"
    )
    print("\nedits of the smile on the smoothed (b) track, frames", edits[0]["frames"])
    for e in edits:
        print(
            f"{e['op']:9s} ×{e['factor']:<4} face {e['psnr_face_db']:6.2f} dB (min {e['psnr_face_min_db']:.2f}, "
            f"paste {e['psnr_face_paste_db']:6.2f} dB), outside {e['psnr_outside_db']:6.2f} dB; "
            f"filled from a similar frame {e['filled_similar']} px, texture {e['filled_texture']} px"
        )
    return 0


if __name__ == "__main__":
    sys.exit(main())
