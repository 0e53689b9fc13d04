"""Texture extraction and view-dependent rendering, leave-one-photo-out (Pighin et al. 2002, §5.2).

    .venv/bin/python benchmarks/bench_texture.py [--json] [--size 1024] [--out benchmarks/out]
                                                 [--feather-sweep] [--repeats 3]

For every photo of the sample project (``sample_projects/james``, five 1000×1000 renders of
the real james scan), the model is textured from the *other four* photos and rendered from
the held-out photo's camera; the render is compared with the held-out photo inside the face:

* ``fitted``        — the fitted generic mesh and the recovered cameras
  (:func:`photomodel.modeling.fit.fit_expression`; the held-out camera is the recovered one);
* ``true_geometry`` — the scan's own (welded) surface and the true cameras, textured with
  the same cylindrical method (the scan's own UVs and texture are not used). This separates
  texturing error from modeling error.

Methods: ``cyl`` — the view-independent cylindrical texture (§5.2.2, 1024² by default);
``vd`` — view-dependent rendering from the two nearest photos as
:class:`ViewDependentTexture` does by default (§5.2.3, per-pixel weights and blend in a
fragment shader, the two photos registered by optical flow before blending — beyond the
paper); ``vd_numpy`` — the same per pixel in numpy/OpenCV (``method="numpy"``, the reference
the shader path must match: ``psnr_vd_numpy_db``); ``vd_plain`` — the shader path without the
registration (the paper's blend, ``align=False``); ``vd_per_vertex`` — the paper's multi-pass
variant (per-vertex weights and texture coordinates).

Comparison region: the generic mesh's face mask (``GenericMesh.face_mask``) placed on the scan
by the true correspondence, rendered from the held-out camera, intersected with the fitted
mesh's face mask rendered from the recovered camera, and kept 3 px away from the scan's
silhouette in that photo (the photos are anti-aliased there, the renders are not). The same
pixels are compared for every method and geometry. Pixels the model does not cover count
(they show the background, as a user would see them).

Metrics: PSNR (dB, RGB in [0, 1]) and SSIM (Wang et al. 2004: Gaussian window σ = 1.5 px,
``C1 = 0.01²``, ``C2 = 0.03²``, per RGB channel, averaged over the region), each averaged
over the five held-out views; ``psnr_vd_shader_vs_numpy_db``: the shader frame against the
numpy frame over the same region. Times: extraction of a 1024² texture from all five photos of
the fitted model (median of ``--repeats``; wall clock on whatever this machine is doing,
``load_1min`` says how busy it was), and one view-dependent frame (1000×1000, a new view 20°
from the front photo) from a prepared :class:`ViewDependentTexture`, after a warm-up frame:
``vd_frame_ms`` the shader path's median of ``--frames`` (everything of a frame: the GL passes,
read-back and the CPU fallback pixels; ``vd_frame_runs_ms`` each frame) of a **moving** view —
each frame's camera turned a further 0.25° about the head, as an orbit in the studio draws
them; ``vd_frame_same_view_ms`` (and ``_runs_ms``) redraws one view (a repaint); the other
methods' medians of 5; ``vd_numpy_over_shader`` the numpy path's frame time over the shader
path's, measured in the same run (this machine's speed drifts by ±20 % within an hour; the
ratio of two paths timed minutes apart drifts less). The registration of the two photographs (see
:mod:`photomodel.texturing.view_dependent`) depends on the pair, not on the view: it is
computed once per pair, outside these frames, and timed on its own as ``vd_pair_setup_ms``
(what the pair's first frame adds: the reprojection, two DIS flows and the shift maps).
The studio's orbit (:func:`studio_orbit`): ``vd_orbit_{on_demand,ahead}_{median_ms,max_ms,stalls}``
over ``vd_orbit_frames`` frames of its 400×780 view turning −120°…120° in 5° steps, each pair's
registration computed by the frame that first needs it or ahead on a worker thread as the studio
does (``vd_orbit_pairs`` pairs in ``vd_register_ahead_s``); a stall is a frame over 100 ms.

Images: ``<out>/texture_<geometry>_<held-out>.png`` — held-out photo | cylindrical |
view-dependent | |error|×4 of each (inside the comparison region); ``<out>/texture_fitted.png``
and ``<out>/texture_true_geometry.png`` — the textures from all five photos, and
``<out>/weights_fitted.png`` — their weight maps; ``<out>/vd_new_view_*.png`` — a new view
20° from the front photo; with ``--feather-sweep``, ``<out>/feather_<w>mm.png`` — the texture
around the nose and the new view for each feathering width.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import sys
import threading
import time
from pathlib import Path

import cv2
import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from photomodel.camera import orbit_camera, rodrigues
from photomodel.exchange.files import atomic_write_bytes, encode_png  # noqa: E402
from photomodel.modeling.fit import fit_expression  # noqa: E402
from photomodel.modeling.generic_mesh import load_generic_mesh  # noqa: E402
from photomodel.project import load_project  # noqa: E402
from photomodel.rendering.renderer import get_renderer  # noqa: E402
from photomodel.samples.sample_data import load_james_scan  # noqa: E402
from photomodel.samples.synthetic import load_ground_truth, true_correspondence  # noqa: E402
from photomodel.texturing.cylindrical import cylindrical_texture, render_cylindrical, single_view_weights  # noqa: E402
from photomodel.texturing.view_dependent import ViewDependentTexture  # noqa: E402
from photomodel.texturing.weights import FEATHER_WIDTH_MM  # noqa: E402


def write_png(path, image):
    """Write an image as PNG, atomically (photomodel.exchange.files)."""
    return atomic_write_bytes(path, encode_png(image))


SAMPLE = Path(__file__).resolve().parents[1] / "sample_projects" / "james"
BACKGROUND = (0.86, 0.86, 0.85)  # the sample photos' backdrop
SILHOUETTE_MARGIN_PX = 3


def psnr(a: np.ndarray, b: np.ndarray, mask: np.ndarray) -> float:
    """PSNR (dB) of RGB images in [0, 1] over ``mask``."""
    mse = float(((a - b) ** 2)[mask].mean())
    return 10.0 * np.log10(1.0 / max(mse, 1e-12))


def ssim(a: np.ndarray, b: np.ndarray, mask: np.ndarray) -> float:
    """Mean SSIM (Wang et al. 2004) over ``mask`` of RGB images in [0, 1], per channel."""
    C1, C2 = 0.01**2, 0.03**2

    def g(x):
        return cv2.GaussianBlur(x, (11, 11), 1.5, borderType=cv2.BORDER_REFLECT)

    a = a.astype(np.float32)
    b = b.astype(np.float32)
    mu_a, mu_b = g(a), g(b)
    va = g(a * a) - mu_a**2
    vb = g(b * b) - mu_b**2
    cov = g(a * b) - mu_a * mu_b
    s = ((2 * mu_a * mu_b + C1) * (2 * cov + C2)) / ((mu_a**2 + mu_b**2 + C1) * (va + vb + C2))
    return float(s.mean(axis=2)[mask].mean())


def load_photos(project) -> tuple[list[str], list[np.ndarray]]:
    expr = project.expression("neutral")
    photos = []
    for p in expr.photos:
        img = cv2.imread(str(project.photo_path(p)), cv2.IMREAD_COLOR)
        photos.append(cv2.cvtColor(img, cv2.COLOR_BGR2RGB))
    return [p.id for p in expr.photos], photos


def comparison_masks(mesh, truth_vertices, fit_vertices, true_cams, fit_cams, scan) -> list[np.ndarray]:
    """Per photo: the face region compared (see the module notes)."""
    r = get_renderer()
    fm = mesh.face_mask.astype(np.float32)
    masks = []
    kernel = np.ones((2 * SILHOUETTE_MARGIN_PX + 1,) * 2, np.uint8)
    for tc, fc in zip(true_cams, fit_cams, strict=True):
        a = r.render(tc, truth_vertices, mesh.faces, colors=fm).color[..., 0] > 0.5
        b = r.render(fc, fit_vertices, mesh.faces, colors=fm).color[..., 0] > 0.5
        head = r.render(tc, scan.vertices, scan.faces).mask.astype(np.uint8)
        masks.append(a & b & (cv2.erode(head, kernel) > 0))
    return masks


def leave_one_out(
    vertices,
    faces,
    cams,
    photos,
    masks,
    size,
    single,
    *,
    feather_mm=FEATHER_WIDTH_MM,
    per_vertex=True,
    images=None,
    label="",
):
    """Per held-out view: PSNR/SSIM of cylindrical, view-dependent (and per-vertex VD)."""
    rows = []
    for j in range(len(photos)):
        keep = [i for i in range(len(photos)) if i != j]
        cs = [cams[i] for i in keep]
        ps = [photos[i] for i in keep]
        tex = cylindrical_texture(vertices, faces, cs, ps, size, single_view=single, feather_mm=feather_mm)
        Vr, Fr, uvr = tex.render_mesh(vertices)
        cyl = render_cylindrical(cams[j], Vr, Fr, uvr, tex.image, background=BACKGROUND).color
        vdt = ViewDependentTexture(vertices, faces, cs, ps, single_view=single, feather_mm=feather_mm)
        vd = vdt.render(cams[j], background=BACKGROUND)  # default: fragment shader, aligned
        vdn = vdt.render(cams[j], background=BACKGROUND, method="numpy")  # the same in numpy
        ref = photos[j].astype(np.float32) / 255.0
        m = masks[j]
        row = {
            "psnr_cyl_db": psnr(cyl, ref, m),
            "psnr_vd_db": psnr(vd.color, ref, m),
            "psnr_vd_numpy_db": psnr(vdn.color, ref, m),
            "psnr_vd_shader_vs_numpy_db": psnr(vd.color, vdn.color, m),
            "ssim_cyl": ssim(cyl, ref, m),
            "ssim_vd": ssim(vd.color, ref, m),
            "ssim_vd_numpy": ssim(vdn.color, ref, m),
            "vd_views": [keep[vd.views[0]], keep[vd.views[1]]],
        }
        if per_vertex:
            pv = vdt.render(cams[j], background=BACKGROUND, method="per_vertex").color
            row["psnr_vd_per_vertex_db"] = psnr(pv, ref, m)
            row["ssim_vd_per_vertex"] = ssim(pv, ref, m)
            plain = vdt.render(cams[j], background=BACKGROUND, align=False).color
            row["psnr_vd_plain_db"] = psnr(plain, ref, m)
            row["ssim_vd_plain"] = ssim(plain, ref, m)
        rows.append(row)
        if images is not None:

            def err(x, m=m, ref=ref):
                return np.where(m[..., None], np.abs(x - ref) * 4.0, 0.0)

            panel = np.hstack([ref, cyl, vd.color, err(cyl), err(vd.color)])
            write_png(
                Path(images) / f"texture_{label}_{j}.png",
                cv2.resize(panel, (panel.shape[1] // 2, panel.shape[0] // 2), interpolation=cv2.INTER_AREA),
            )
    return rows


def turned(camera, centre, degrees: float):
    """A copy of ``camera`` turned ``degrees`` about the vertical axis through ``centre``."""
    view = camera.copy()
    Rz = rodrigues(np.array([0.0, np.radians(degrees), 0.0]))
    view.R = camera.R @ Rz.T
    view.t = camera.R @ centre + camera.t - view.R @ centre
    return view


def studio_orbit(V, F, cams, photos, single, width=400, height=780, step_deg=5.0) -> dict:
    """Frames of an orbit as the studio's 3D view draws them (its default 400×780 dock, 450 mm
    away, azimuth −120°…120° in ``step_deg`` steps), with each pair's registration computed on
    the frame that first needs it (``on_demand``) and computed ahead on a worker thread as the
    studio does (``ahead``: ``prepare_surfaces`` then ``register_pairs``, timed as
    ``vd_register_ahead_s``). A frame over 100 ms counts as a stall."""
    out = {}
    for mode in ("on_demand", "ahead"):
        vdt = ViewDependentTexture(V, F, cams, photos, single_view=single)
        vdt.render(orbit_camera(0.0, width, height, distance_mm=450.0, target=vdt.centre))  # warm: GL state
        vdt.forget_registration()
        if mode == "ahead":
            t = time.perf_counter()
            vdt.prepare_surfaces()
            worker = threading.Thread(target=vdt.register_pairs)
            worker.start()
            worker.join()
            out["vd_register_ahead_s"] = time.perf_counter() - t
            out["vd_orbit_pairs"] = len(vdt.orbit_pairs())
        ts = []
        for az in np.arange(-120.0, 120.0 + 1e-9, step_deg):
            cam = orbit_camera(float(az), width, height, distance_mm=450.0, target=vdt.centre)
            t = time.perf_counter()
            vdt.render(cam, background=BACKGROUND)
            ts.append((time.perf_counter() - t) * 1000.0)
        out[f"vd_orbit_{mode}_median_ms"] = statistics.median(ts)
        out[f"vd_orbit_{mode}_max_ms"] = max(ts)
        out[f"vd_orbit_{mode}_stalls"] = sum(x > 100.0 for x in ts)
        out["vd_orbit_frames"] = len(ts)
    return out


def mean_of(rows, key):
    return float(np.mean([r[key] for r in rows]))


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--json", action="store_true", help="print one JSON object")
    ap.add_argument("--size", type=int, default=1024, help="cylindrical texture size (texels per side)")
    ap.add_argument("--out", default=str(Path(__file__).resolve().parent / "out"), help="folder for the PNGs")
    ap.add_argument("--repeats", type=int, default=3, help="runs of the timed extraction (median)")
    ap.add_argument("--frames", type=int, default=9, help="timed shader view-dependent frames (median)")
    ap.add_argument("--feather-sweep", action="store_true", help="held-out PSNR of the fit vs feather width")
    args = ap.parse_args(argv)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)

    project = load_project(SAMPLE / "james.facestudio.json")
    truth = load_ground_truth(SAMPLE / "ground_truth.json")
    ids, photos = load_photos(project)
    mesh = load_generic_mesh()
    scan = load_james_scan()
    welded = scan.welded
    true_cams = [truth.cameras["neutral"][i] for i in ids]

    t0 = time.perf_counter()
    fit = fit_expression(project, "neutral", mesh)
    fit_s = time.perf_counter() - t0
    fit_cams = [fit.camera(i) for i in ids]
    Vf, F = fit.vertices, mesh.faces
    single = single_view_weights(Vf, mesh.face_mask)
    masks = comparison_masks(mesh, true_correspondence(mesh, scan), Vf, true_cams, fit_cams, scan)

    fitted = leave_one_out(Vf, F, fit_cams, photos, masks, args.size, single, images=out, label="fitted")
    true_rows = leave_one_out(
        welded.vertices, welded.faces, true_cams, photos, masks, args.size, None, images=out, label="true_geometry"
    )

    # timings on the full set of five photos
    renderer = get_renderer()
    ext = []
    for _ in range(max(1, args.repeats)):
        t = time.perf_counter()
        tex = cylindrical_texture(Vf, F, fit_cams, photos, 1024, single_view=single)
        ext.append(time.perf_counter() - t)
    write_png(out / "texture_fitted.png", tex.image)
    write_png(out / "weights_fitted.png", np.hstack(list(tex.weight_maps)))
    write_png(
        out / "texture_true_geometry.png",
        cylindrical_texture(welded.vertices, welded.faces, true_cams, photos, 1024).image,
    )
    vdt = ViewDependentTexture(Vf, F, fit_cams, photos, single_view=single)

    c = vdt.centre
    new_view = turned(fit_cams[2], c, 20.0)  # a frame between the photos: the front camera turned 20°
    timings, runs = {}, {}
    load_1min = os.getloadavg()[0]
    vdt.gl_state()
    t = time.perf_counter()
    vdt.registration_shift(*sorted(vdt.view_weights(new_view)[0]))  # what a pair's first frame adds
    pair_ms = (time.perf_counter() - t) * 1000.0
    for label, kw, n in (
        ("default", {}, max(1, args.frames)),
        ("same_view", {}, max(1, args.frames)),
        ("plain", {"align": False}, 5),
        ("numpy", {"method": "numpy"}, 5),
        ("numpy_plain", {"method": "numpy", "align": False}, 5),
        ("per_vertex", {"method": "per_vertex"}, 5),
    ):
        vdt.render(new_view, background=BACKGROUND, **kw)  # warm: shader compilation, texture uploads
        ts = []
        for i in range(n):
            view = new_view
            if label == "default":  # a moving view: a new camera every frame
                view = turned(new_view, c, 0.25 * (i + 1))
            t = time.perf_counter()
            frame = vdt.render(view, background=BACKGROUND, **kw)
            ts.append(time.perf_counter() - t)
        timings[label] = statistics.median(ts) * 1000.0
        runs[label] = [x * 1000.0 for x in ts]
        if label == "default":  # the picture of the nominal view, as the other methods'
            frame = vdt.render(new_view, background=BACKGROUND)
        write_png(out / f"vd_new_view_{label}.png", frame.color)
    t = time.perf_counter()
    render_cylindrical(new_view, Vf, F, tex.uv, tex.image, background=BACKGROUND)
    cyl_frame_ms = (time.perf_counter() - t) * 1000.0
    orbit = studio_orbit(Vf, F, fit_cams, photos, single)
    del renderer

    result = {
        "fitted": {
            "psnr_cyl_db": mean_of(fitted, "psnr_cyl_db"),
            "psnr_vd_db": mean_of(fitted, "psnr_vd_db"),
            "psnr_vd_numpy_db": mean_of(fitted, "psnr_vd_numpy_db"),
            "psnr_vd_shader_vs_numpy_db": mean_of(fitted, "psnr_vd_shader_vs_numpy_db"),
            "ssim_cyl": mean_of(fitted, "ssim_cyl"),
            "ssim_vd": mean_of(fitted, "ssim_vd"),
            "ssim_vd_numpy": mean_of(fitted, "ssim_vd_numpy"),
            "psnr_vd_per_vertex_db": mean_of(fitted, "psnr_vd_per_vertex_db"),
            "psnr_vd_plain_db": mean_of(fitted, "psnr_vd_plain_db"),
            "ssim_vd_plain": mean_of(fitted, "ssim_vd_plain"),
            "per_view": dict(zip(ids, fitted, strict=True)),
        },
        "true_geometry": {
            "psnr_cyl_db": mean_of(true_rows, "psnr_cyl_db"),
            "psnr_vd_db": mean_of(true_rows, "psnr_vd_db"),
            "psnr_vd_numpy_db": mean_of(true_rows, "psnr_vd_numpy_db"),
            "psnr_vd_shader_vs_numpy_db": mean_of(true_rows, "psnr_vd_shader_vs_numpy_db"),
            "ssim_cyl": mean_of(true_rows, "ssim_cyl"),
            "ssim_vd": mean_of(true_rows, "ssim_vd"),
            "ssim_vd_numpy": mean_of(true_rows, "ssim_vd_numpy"),
            "psnr_vd_per_vertex_db": mean_of(true_rows, "psnr_vd_per_vertex_db"),
            "psnr_vd_plain_db": mean_of(true_rows, "psnr_vd_plain_db"),
            "ssim_vd_plain": mean_of(true_rows, "ssim_vd_plain"),
            "per_view": dict(zip(ids, true_rows, strict=True)),
        },
        "extract_s": statistics.median(ext),
        "extract_runs_s": ext,
        "psnr_vd_numpy_db": mean_of(fitted, "psnr_vd_numpy_db"),
        "vd_frame_ms": timings["default"],
        "vd_frame_runs_ms": runs["default"],
        "vd_frame_same_view_ms": timings["same_view"],
        "vd_frame_same_view_runs_ms": runs["same_view"],
        "vd_pair_setup_ms": pair_ms,
        "vd_plain_frame_ms": timings["plain"],
        "vd_numpy_frame_ms": timings["numpy"],
        "vd_numpy_over_shader": timings["numpy"] / timings["default"],
        "vd_numpy_plain_frame_ms": timings["numpy_plain"],
        "vd_per_vertex_frame_ms": timings["per_vertex"],
        "vd_frame_size": [new_view.width, new_view.height],
        "load_1min": load_1min,
        "cyl_frame_ms": cyl_frame_ms,
        **orbit,
        "fit_s": fit_s,
        "texture_size": args.size,
        "feather_mm": FEATHER_WIDTH_MM,
    }
    if args.feather_sweep:
        sweep = {}
        for w in (0.0, 2.0, 4.0, 6.0, 8.0, 12.0, 16.0):
            rows = leave_one_out(Vf, F, fit_cams, photos, masks, args.size, single, feather_mm=w, per_vertex=False)
            sweep[str(w)] = {"psnr_cyl_db": mean_of(rows, "psnr_cyl_db"), "psnr_vd_db": mean_of(rows, "psnr_vd_db")}
            # what the width does to seams: the texture around the nose and a new view
            t = cylindrical_texture(Vf, F, fit_cams, photos, 1024, single_view=single, feather_mm=w)
            v = ViewDependentTexture(Vf, F, fit_cams, photos, single_view=single, feather_mm=w)
            frame = v.render(new_view, background=BACKGROUND).color
            write_png(
                out / f"feather_{w:g}mm.png", np.hstack([t.image[250:650, 300:700] / 255.0, frame[250:650, 300:700]])
            )
        result["feather_sweep"] = sweep

    if args.json:
        print(json.dumps(result, indent=1, default=float))
        return 0
    print(f"fit {fit_s:.2f} s; comparison region: face mask, {SILHOUETTE_MARGIN_PX} px inside the silhouette")
    print(
        f"{'held out':20s} {'geometry':14s} {'PSNR cyl':>9s} {'PSNR vd':>8s} {'vd/numpy':>9s} {'vd/vertex':>9s} "
        f"{'vd/plain':>9s} {'SSIM cyl':>9s} {'SSIM vd':>8s}  vd views"
    )
    for label, rows in (("fitted", fitted), ("true_geometry", true_rows)):
        for pid, r in zip(ids, rows, strict=True):
            print(
                f"{pid:20s} {label:14s} {r['psnr_cyl_db']:9.2f} {r['psnr_vd_db']:8.2f} "
                f"{r['psnr_vd_numpy_db']:9.2f} {r['psnr_vd_per_vertex_db']:9.2f} {r['psnr_vd_plain_db']:9.2f} "
                f"{r['ssim_cyl']:9.4f} {r['ssim_vd']:8.4f}  {ids[r['vd_views'][0]]}, {ids[r['vd_views'][1]]}"
            )
        g = result[label]
        print(
            f"{'mean':20s} {label:14s} {g['psnr_cyl_db']:9.2f} {g['psnr_vd_db']:8.2f} "
            f"{g['psnr_vd_numpy_db']:9.2f} {g['psnr_vd_per_vertex_db']:9.2f} {g['psnr_vd_plain_db']:9.2f} "
            f"{g['ssim_cyl']:9.4f} {g['ssim_vd']:8.4f}"
        )
        print(f"{'':20s} {label:14s} shader vs numpy frame: {g['psnr_vd_shader_vs_numpy_db']:.1f} dB")
    print(
        f"extraction 1024² from 5 photos: {result['extract_s']:.2f} s (median of {len(ext)}: "
        + ", ".join(f"{x:.2f}" for x in ext)
        + ")"
    )
    print(
        f"view-dependent frame 1000×1000 (load {load_1min:.1f}): {timings['default']:.0f} ms shader, aligned "
        f"(median of {len(runs['default'])}; {timings['same_view']:.0f} ms redrawing the same view, its flow "
        f"kept), {timings['plain']:.0f} ms shader plain; "
        f"numpy {timings['numpy']:.0f} ms aligned, {timings['numpy_plain']:.0f} ms plain; "
        f"{timings['per_vertex']:.0f} ms per-vertex multi-pass; cylindrical frame {cyl_frame_ms:.0f} ms"
    )
    print(
        f"studio orbit 400×780, {orbit['vd_orbit_frames']} frames: pairs registered on demand "
        f"{orbit['vd_orbit_on_demand_median_ms']:.0f} ms median, {orbit['vd_orbit_on_demand_max_ms']:.0f} ms max, "
        f"{orbit['vd_orbit_on_demand_stalls']} over 100 ms; {orbit['vd_orbit_pairs']} pairs registered ahead in "
        f"{orbit['vd_register_ahead_s']:.1f} s: {orbit['vd_orbit_ahead_median_ms']:.0f} ms median, "
        f"{orbit['vd_orbit_ahead_max_ms']:.0f} ms max, {orbit['vd_orbit_ahead_stalls']} over 100 ms"
    )
    if args.feather_sweep:
        for w, r in result["feather_sweep"].items():
            print(f"feather {float(w):5.1f} mm: PSNR cyl {r['psnr_cyl_db']:.2f} dB, vd {r['psnr_vd_db']:.2f} dB")
    print(f"images in {out}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
