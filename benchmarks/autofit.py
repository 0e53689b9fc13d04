"""The landmark benchmark's fit sections: a fit from automatic landmarks alone, as a user makes it.

* ``auto_fit`` — the sample james project's five neutral photos copied to a new folder with no
  click at all (presets and focal unknown), then the two commands a user runs:
  ``facestudio new P --photos DIR`` and ``facestudio fit P`` (run as the CLI, in-process).
  ``rms_px``: the fit's reprojection RMS; ``mesh_mean_mm`` / ``mesh_p95_mm``: the refined mesh's face
  region to the scan surface after the similarity that maps the fit's 3-D features onto their true
  positions (as ``bench_pose.py``'s ``mesh``); ``clicks_auto``: automatic clicks placed;
  ``seconds``: wall time of new + fit; ``photos_used``: photos with a face found (the others are
  left out of the fit). The default fit weighs the automatic clicks by confidence² in the camera
  solve when the photos are of views ≥ 40° apart, as these are
  (:attr:`photomodel.modeling.fit.FitOptions.weigh_auto_clicks`); ``auto_fit_weighted``: the same
  project fitted again with ``facestudio fit --weigh-auto-clicks`` (always weighed: here the same
  as the default), ``auto_fit_unweighted`` with ``--no-weigh-auto-clicks`` (every click alike);
  their ``seconds`` are the fit's. ``auto_fit_no_prior``: weighed but fitted as they are
  (``facestudio fit --no-person-prior``), the peer of the default's most probable face under the
  person prior (:func:`photomodel.modeling.camera_solve._map_estimate`), in the same run.
* ``auto_fit_rigs`` — beyond the sample's five photos: renders of the scan (as ``one_photo``'s)
  from other sets of views, :data:`RIGS` (2 to 5 views, 30–140° apart), each fitted from
  automatic landmarks with and without the person prior and scored against the generic head
  moved onto the truth by the same features: per rig ``yaws``, ``photos_used``, ``mesh_mean_mm``,
  ``no_prior_mm``, ``generic_mm``, and the worst fitted camera's rotation error
  ``camera_worst_deg`` / ``no_prior_camera_worst_deg`` (-1 where the fit failed); over the rigs
  the default fit solved ``mean``, ``generic_mean``, ``worst``, ``camera_worst_deg`` (the largest
  of any rig) and ``better_than_generic``, over those the no-prior fit solved ``no_prior_mean``;
  ``failures`` and ``no_prior_failures``: rigs each fit failed (a rig is never left out of a
  figure without being counted there).
* ``auto_fit_draws`` — the same, over ``--draws`` jittered copies of the five photos (each photo
  scaled 0.92–1.08, turned ±4°, shifted ±30 px, edges replicated; seed 7, so the draws are the
  same every run): ``mesh_mean_mm`` per draw, their ``mean`` and ``worst``; ``failures``: draws
  whose ``new`` + ``fit`` did not give a mesh; ``over_bar``: draws above the 1.5 mm bar. One
  draw hides how a fit varies with where the detector's points land.
* ``real_sample`` — the real-footage sample (:mod:`photomodel.samples.real_clip`): frames of a
  real clip, ``facestudio new --camera-group clip`` + ``fit``. ``rms_px`` and ``depth_ratio``: the
  fitted face region's depth extent after the similarity onto the generic mesh, over the generic
  head's (1 = as deep as the generic head scaled to this face). The texture is made too
  (``facestudio texture``) and a picture written to ``<out>/real_sample.png``.
* ``stills`` — the real clip as a user with only footage would start: ``facestudio new P --video
  CLIP`` (:mod:`photomodel.photos.stills` picks the stills) + ``fit``, looking at every 3rd … 7th frame
  (five draws: which frames are looked at moves what is picked). Per draw ``every``, ``frames``
  (the stills), ``rms_px``, ``depth_ratio``, ``hand_stills`` (stills in the frames where a hand is
  over her mouth or nose, 60 and 69–226, labelled by looking); over the draws ``rms_mean_px``, ``rms_worst_px``,
  ``depth_ratio_min`` / ``_max``, ``hand_stills`` (total), ``failures``. Peers in the same run, the
  same fit of other frames: ``hand_picked`` (the real sample's frames, chosen by looking) and
  ``evenly_spaced`` (five frames evenly over the clip, what one gets without looking), each
  ``{"frames", "rms_px", "depth_ratio", "hand_stills"}``.
"""

from __future__ import annotations

import contextlib
import io
import json
import shutil
import sys
import tempfile
import time
from functools import cache
from pathlib import Path

import cv2
import numpy as np

from app.cli import main as facestudio
from photomodel.alignment import align_to_truth, camera_errors, similarity_transform
from photomodel.camera import orbit_camera
from photomodel.exchange.mesh import read_mesh
from photomodel.modeling.generic_mesh import load_generic_mesh
from photomodel.photos.reading import read_photo
from photomodel.photos.stills import write_stills
from photomodel.photos.video import VideoFrames
from photomodel.project import load_project
from photomodel.samples import synthetic
from photomodel.samples.real_clip import FRAMES, clip_path, real_sample_project
from photomodel.samples.sample_data import load_james_scan
from photomodel.texturing.view_dependent import ViewDependentTexture

SAMPLE = Path(__file__).resolve().parents[1] / "sample_projects" / "james"


def run_cli(*argv: str) -> dict:
    """``facestudio ARGV --json`` in-process: its one JSON object (its stderr passes through)."""
    out = io.StringIO()
    with contextlib.redirect_stdout(out):
        code = facestudio([*argv, "--json"])
    result = json.loads(out.getvalue())
    if code != 0:
        raise RuntimeError(f"facestudio {' '.join(argv)} failed: {result}")
    return result


def auto_fit_section(args, log) -> dict:
    project = load_project(SAMPLE / "james.facestudio.json")
    expr = project.expression("neutral")
    with tempfile.TemporaryDirectory(prefix="autofit-") as tmp:
        photos = Path(tmp) / "photos"
        photos.mkdir()
        for p in expr.photos:
            shutil.copy(project.resolve(p.path), photos / Path(p.path).name)
        path = str(Path(tmp) / "auto.facestudio.json")
        t0 = time.perf_counter()
        made = run_cli("new", path, "--photos", str(photos))
        sections = {}
        for key, flags in (
            ("auto_fit", ()),
            ("auto_fit_weighted", ("--weigh-auto-clicks",)),
            ("auto_fit_unweighted", ("--no-weigh-auto-clicks",)),
            ("auto_fit_no_prior", ("--no-person-prior",)),
        ):
            t1 = time.perf_counter()
            fit = run_cli("fit", path, *flags)["expressions"][0]
            seconds = (t1 - t0 if key == "auto_fit" else 0.0) + time.perf_counter() - t1  # new + fit
            out = sections[key] = _scored(path, fit, made, seconds, len(expr.photos))
            log(
                f"{key.replace('_', ' ')} of the sample: {out['photos_used']}/{out['photos']} photos, "
                f"{out['clicks_auto']} automatic clicks, RMS {out['rms_px']:.2f} px, mesh → scan "
                f"{out['mesh_mean_mm']:.2f} mm mean (p95 {out['mesh_p95_mm']:.2f}), {seconds:.1f} s"
            )
    return sections


#: ``auto_fit_rigs``' sets of views (yaw, degrees) of the scan.
RIGS = (
    (-30.0, 0.0, 30.0),
    (-45.0, 0.0, 45.0),
    (-60.0, -20.0, 20.0, 60.0),
    (0.0, 30.0, 60.0),
    (-60.0, -30.0, 0.0),
    (-15.0, 15.0),
    (-40.0, -10.0, 20.0, 50.0),
    (-45.0, 45.0),
    (-70.0, -35.0, 0.0, 35.0, 70.0),
)


def auto_fit_rigs_section(args, log) -> dict:
    rows = []
    for yaws in RIGS:

        def fill(photos, yaws=yaws):
            for i, yaw in enumerate(yaws):
                cv2.imwrite(str(photos / f"view{i}.png"), _scan_render(yaw))

        row = {
            "yaws": list(yaws),
            "mesh_mean_mm": -1.0,
            "no_prior_mm": -1.0,
            "generic_mm": -1.0,
            "photos_used": 0,
            "camera_worst_deg": -1.0,
            "no_prior_camera_worst_deg": -1.0,
        }
        true = {f"view{i}": _scan_camera(yaw) for i, yaw in enumerate(yaws)}
        for key, flags in (("", ()), ("no_prior_", ("--no-person-prior",))):
            try:
                out = _fit_folder(fill, len(yaws), flags, true)
            except RuntimeError as exc:
                log(f"rig {yaws}{' ' + flags[0] if flags else ''}: failed ({str(exc)[:100]}…)")
                continue
            row["no_prior_mm" if key else "mesh_mean_mm"] = out["mesh_mean_mm"]
            row[key + "camera_worst_deg"] = out["camera_worst_deg"]
            row["generic_mm"] = out["generic_mm"]
            row["photos_used"] = row["photos_used"] or out["photos_used"]
        rows.append(row)
        log(
            f"rig {yaws}: {row['photos_used']} photos used, mesh → scan {row['mesh_mean_mm']:.2f} mm, worst camera "
            f"{row['camera_worst_deg']:.1f}° off (no prior {row['no_prior_mm']:.2f} mm, "
            f"{row['no_prior_camera_worst_deg']:.1f}°; the generic head {row['generic_mm']:.2f} mm)"
        )
    # each fit's figures over the rigs it solved; its failures counted beside them
    ok = [r for r in rows if r["mesh_mean_mm"] >= 0]
    ok_no_prior = [r for r in rows if r["no_prior_mm"] >= 0]

    def mean(key, solved):
        return float(np.mean([r[key] for r in solved])) if solved else -1.0

    return {
        "auto_fit_rigs": {
            "rigs": rows,
            "mean": mean("mesh_mean_mm", ok),
            "no_prior_mean": mean("no_prior_mm", ok_no_prior),
            "generic_mean": mean("generic_mm", ok),
            "worst": float(max((r["mesh_mean_mm"] for r in ok), default=-1.0)),
            "camera_worst_deg": float(max((r["camera_worst_deg"] for r in ok), default=-1.0)),
            "failures": sum(r["mesh_mean_mm"] < 0 for r in rows),
            "no_prior_failures": sum(r["no_prior_mm"] < 0 for r in rows),
            "better_than_generic": int(sum(r["mesh_mean_mm"] < r["generic_mm"] for r in ok)),
        }
    }


def _scan_camera(yaw: float):
    """The camera of :func:`_scan_render` at ``yaw``."""
    return orbit_camera(yaw, 1000, 1000, distance_mm=700.0, focal_mm=60.0, target=synthetic.HEAD_CENTRE_MM)


@cache
def _scan_render(yaw: float) -> np.ndarray:
    """BGR render of the scan at ``yaw`` (1000², a 60 mm lens at 700 mm, as the yaw bins); each yaw
    rendered once a run (a rig is fitted twice, and rigs share views). Read-only."""
    _, scan, _ = _truth()
    cam = _scan_camera(yaw)
    color = synthetic.render_scan(cam, scan, background=0.45, supersample=3).color
    rgb = (np.clip(color, 0.0, 1.0) * 255.0 + 0.5).astype(np.uint8)
    return cv2.cvtColor(rgb, cv2.COLOR_RGB2BGR)


#: The auto fit's bar (mm, refined mesh to the scan): ``over_bar`` counts the draws above it.
AUTO_FIT_BAR_MM = 1.5
#: Jitter of a draw's photos: scale range, rotation (degrees) and shift (px) bounds.
DRAW_SCALE, DRAW_TURN_DEG, DRAW_SHIFT_PX = (0.92, 1.08), 4.0, 30.0


def _jittered(src: Path, dst: Path, rng) -> None:
    """A copy of the photo ``src`` at ``dst`` scaled, turned and shifted within the draw bounds."""
    image = cv2.imread(str(src))
    h, w = image.shape[:2]
    m = cv2.getRotationMatrix2D((w / 2, h / 2), rng.uniform(-DRAW_TURN_DEG, DRAW_TURN_DEG), rng.uniform(*DRAW_SCALE))
    m[:, 2] += rng.uniform(-DRAW_SHIFT_PX, DRAW_SHIFT_PX, 2)
    cv2.imwrite(str(dst), cv2.warpAffine(image, m, (w, h), borderMode=cv2.BORDER_REPLICATE))


def auto_fit_draws_section(args, log) -> dict:
    project = load_project(SAMPLE / "james.facestudio.json")
    expr = project.expression("neutral")
    rng = np.random.default_rng(7)
    means, failures = [], 0
    for draw in range(max(0, int(getattr(args, "draws", 8)))):

        def fill(photos):
            for p in expr.photos:
                _jittered(project.resolve(p.path), photos / Path(p.path).name, rng)

        try:
            out = _fit_folder(fill, len(expr.photos))
        except RuntimeError as exc:
            failures += 1
            log(f"auto fit draw {draw}: failed ({exc})")
            continue
        means.append(out["mesh_mean_mm"])
        log(
            f"auto fit draw {draw}: {out['photos_used']}/{out['photos']} photos, mesh → scan "
            f"{out['mesh_mean_mm']:.2f} mm mean"
        )
    return {
        "auto_fit_draws": {
            "draws": len(means) + failures,
            "mesh_mean_mm": means,
            "mean": float(np.mean(means)) if means else -1.0,
            "worst": float(np.max(means)) if means else -1.0,
            "failures": failures,
            "over_bar": int(sum(m > AUTO_FIT_BAR_MM for m in means)),
        }
    }


#: Yaws (degrees) of the scan's renders in ``one_photo``, besides the sample's five photos.
ONE_PHOTO_YAWS = (-60.0, -45.0, -30.0, -15.0, 0.0, 15.0, 30.0, 45.0, 60.0)


def _one_photo_images():
    """``(label, write(path))`` of each single photo ``one_photo`` fits: the sample's five neutral
    photos, then renders of the scan (1000², a 60 mm lens at 700 mm, as the yaw bins) at
    :data:`ONE_PHOTO_YAWS`."""
    project = load_project(SAMPLE / "james.facestudio.json")
    for p in project.expression("neutral").photos:
        src = Path(project.resolve(p.path))
        yield p.id, lambda dst, src=src: shutil.copy(src, dst.with_suffix(src.suffix))
    for yaw in ONE_PHOTO_YAWS:

        def render(dst, yaw=yaw):
            cv2.imwrite(str(dst.with_suffix(".png")), _scan_render(yaw))

        yield f"render yaw {yaw:+.0f}", render


def one_photo_section(args, log) -> dict:
    """``one_photo``: a fit from one photo through ``facestudio new`` + ``fit`` from automatic
    landmarks (the camera placed against the generic head, the depth the generic head's), for each
    of :func:`_one_photo_images`. Per photo: ``mesh_mean_mm`` (``-1`` when it failed: no face
    found, or no fit) and ``generic_mm`` — the generic head itself scored the same way (moved onto
    the truth by the similarity of the same features): what a fit from one photo should beat.
    Over all: ``mean``, ``worst``, ``failures``, ``generic_mean_mm`` (over the fitted ones) and
    ``better_than_generic`` (fits nearer the scan than the generic head)."""
    rows, means, generic, failures = [], [], [], 0
    for label, write in _one_photo_images():
        try:
            out = _fit_folder(lambda photos, write=write: write(photos / "photo"), 1)
        except RuntimeError as exc:
            failures += 1
            rows.append({"photo": label, "mesh_mean_mm": -1.0, "generic_mm": -1.0})
            log(f"one photo, {label}: failed ({str(exc)[:100]}…)")
            continue
        rows.append({"photo": label, "mesh_mean_mm": out["mesh_mean_mm"], "generic_mm": out["generic_mm"]})
        means.append(out["mesh_mean_mm"])
        generic.append(out["generic_mm"])
        log(f"one photo, {label}: mesh → scan {means[-1]:.2f} mm (the generic head {generic[-1]:.2f} mm)")
    return {
        "one_photo": {
            "photos": rows,
            "mean": float(np.mean(means)) if means else -1.0,
            "worst": float(np.max(means)) if means else -1.0,
            "failures": failures,
            "generic_mean_mm": float(np.mean(generic)) if generic else -1.0,
            "better_than_generic": int(sum(m < g for m, g in zip(means, generic, strict=True))),
        }
    }


def _fit_folder(fill, n_photos: int, flags=(), true_cameras=None) -> dict:
    """``facestudio new`` + ``fit`` of the photos ``fill(folder)`` writes into a fresh folder, scored
    by :func:`_scored`; RuntimeError when either command fails."""
    with tempfile.TemporaryDirectory(prefix="autofit-") as tmp:
        photos = Path(tmp) / "photos"
        photos.mkdir()
        fill(photos)
        path = str(Path(tmp) / "auto.facestudio.json")
        made = run_cli("new", path, "--photos", str(photos))
        fit = run_cli("fit", path, *flags)["expressions"][0]
        return _scored(path, fit, made, 0.0, n_photos, true_cameras)


@cache
def _truth():
    """The generic mesh, the james scan and the sample's ground truth, read once."""
    return load_generic_mesh(), load_james_scan(), synthetic.load_ground_truth(SAMPLE / "ground_truth.json")


def _scored(path: str, fit: dict, made: dict, seconds: float, photos: int, true_cameras=None) -> dict:
    """The auto fit's figures (module docstring) of the fitted project at ``path`` against the
    sample's ground truth (``fit``, ``made``: the fit's and ``new``'s JSON); with ``true_cameras``
    (photo id → Camera) also ``camera_worst_deg``, the largest rotation error of a fitted camera
    after the similarity that maps the fit's 3-D features onto their true positions."""
    fitted = load_project(path)
    result = fitted.expression("neutral").result
    vertices = read_mesh(fitted.resolve(result.mesh_obj))[0]
    mesh, scan, truth = _truth()
    names = [n for n in result.points_3d if n in truth.features_3d]
    X = np.array([result.points_3d[n] for n in names])
    s, R, t = similarity_transform(X, truth.true_points(names))
    d = synthetic.surface_distance((vertices @ (s * R).T + t)[mesh.face_mask], scan)
    # the generic head moved onto the truth by the same features: what the fit improves on
    vertex = {f.name: f.vertex for f in fitted.features}
    sg, Rg, tg = similarity_transform(mesh.vertices[[vertex[n] for n in names]], truth.true_points(names))
    dg = synthetic.surface_distance((mesh.vertices @ (sg * Rg).T + tg)[mesh.face_mask], scan)
    out = {}
    if true_cameras is not None:
        ids = list(result.cameras)
        cams, _ = align_to_truth([result.cameras[i] for i in ids], X, truth.true_points(names))
        out["camera_worst_deg"] = float(camera_errors(cams, [true_cameras[i] for i in ids])["rot_err_deg"].max())
    return out | {
        "rms_px": float(fit["rms_px"]),
        "mesh_mean_mm": float(d.mean()),
        "mesh_p95_mm": float(np.percentile(d, 95)),
        "clicks_auto": int(made["clicks_auto"]),
        "seconds": seconds,
        "photos_used": len(result.cameras),
        "photos": photos,
        "generic_mm": float(dg.mean()),
    }


def depth_ratio(vertices: np.ndarray, mesh) -> float:
    """Depth extent of the fitted face region after the similarity onto the generic mesh, over the
    generic mesh's (the generic head scaled to this face)."""
    face = mesh.face_mask
    s, R, t = similarity_transform(vertices[face], mesh.vertices[face])
    return float(np.ptp((vertices[face] @ (s * R).T + t)[:, 2]) / np.ptp(mesh.vertices[face][:, 2]))


def figure(project, vertices: np.ndarray, size: int = 360) -> np.ndarray:
    """BGR picture of the real sample: a frame with its automatic clicks and curves (violet), the fitted
    model drawn view-dependently from the frames at −35°, 0° and 35°, and the texture."""
    expr = project.expression("neutral")
    result = expr.result
    photos, cams = [], []
    for p in expr.photos:
        if p.id in result.cameras:
            photos.append(read_photo(project.resolve(p.path)).image)
            cams.append(result.cameras[p.id])
    mesh = load_generic_mesh()
    vdt = ViewDependentTexture(vertices, mesh.faces, cams, photos)
    centre = vertices[mesh.face_mask].mean(0)
    views = [
        vdt.render(orbit_camera(a, size, size, distance_mm=300.0, focal_mm=50.0, target=centre), background=0.85).color
        for a in (-35.0, 0.0, 35.0)
    ]
    views = [cv2.cvtColor((np.clip(v, 0, 1) * 255).astype(np.uint8), cv2.COLOR_RGB2BGR) for v in views]
    first = expr.photos[0]
    frame = cv2.imread(str(project.resolve(first.path)))
    for line in first.curves.values():  # the automatic eyelid and lip curves
        cv2.polylines(frame, [np.round(line).astype(np.int32)], False, (230, 60, 170), 1, cv2.LINE_AA)
    for uv in first.points.values():
        cv2.circle(frame, (int(round(uv[0])), int(round(uv[1]))), 2, (230, 60, 170), -1, cv2.LINE_AA)
    h, w = frame.shape[:2]
    side = min(h, w)
    x0 = int(np.clip(np.mean([uv[0] for uv in first.points.values()]) - side / 2, 0, w - side))
    frame = cv2.resize(frame[:, x0 : x0 + side], (size, size))
    texture = cv2.resize(cv2.imread(str(project.resolve(result.texture.image))), (size, size))
    return np.hstack([frame, *views, texture])


def real_sample_section(args, log) -> dict:
    with tempfile.TemporaryDirectory(prefix="realsample-") as tmp:
        path = real_sample_project(Path(tmp), rebuild=True)
        fit = run_cli("fit", str(path))["expressions"][0]
        run_cli("texture", str(path))
        project = load_project(path)
        result = project.expression("neutral").result
        vertices = read_mesh(project.resolve(result.mesh_obj))[0]
        ratio = depth_ratio(vertices, load_generic_mesh())
        out_dir = Path(getattr(args, "out", None) or Path(__file__).resolve().parent / "out")
        out_dir.mkdir(parents=True, exist_ok=True)
        cv2.imwrite(str(out_dir / "real_sample.png"), figure(project, vertices))
    out = {
        "photos": len(result.cameras),
        "rms_px": float(fit["rms_px"]),
        "depth_ratio": ratio,
        "start": fit.get("camera_solve", {}).get("start", ""),
    }
    log(f"real sample: {out['photos']} frames, RMS {out['rms_px']:.2f} px, depth ratio {ratio:.2f} ({out['start']})")
    return {"real_sample": out}


#: The real clip's frames with a hand over the mouth or nose, looked at frame by frame (61–68:
#: the hand under the lips, which are seen).
REAL_HAND_FRAMES = frozenset({60, *range(69, 227)})


def _fit_stills(folder: Path, photos: Path | None, video: Path | None, every: int | None = None) -> dict:
    """``new`` (from ``photos`` or ``video``) + ``fit`` in ``folder``: the fit's figures."""
    project = folder / "p.facestudio.json"
    source = ["--photos", str(photos)] if photos is not None else ["--video", str(video)]
    if every is not None:
        source += ["--every", str(every)]
    new = run_cli("new", str(project), *source, "--camera-group", "clip")
    fit = run_cli("fit", str(project))["expressions"][0]
    loaded = load_project(project)
    result = loaded.expression("neutral").result
    vertices = read_mesh(loaded.resolve(result.mesh_obj))[0]
    frames = [s["frame"] for s in new["video"]["stills"]] if "video" in new else []
    return {
        "frames": frames,
        "photos": len(result.cameras),
        "rms_px": round(float(fit["rms_px"]), 3),
        "depth_ratio": round(depth_ratio(vertices, load_generic_mesh()), 3),
        "hand_stills": sum(f in REAL_HAND_FRAMES for f in frames),
    }


def _fit_frames(frames: list[int]) -> dict:
    """The real clip's ``frames`` written as PNG and fitted as ``_fit_stills`` fits a folder."""
    with tempfile.TemporaryDirectory(prefix="stills-") as tmp:
        write_stills(VideoFrames(clip_path()), frames, Path(tmp) / "frames")
        out = _fit_stills(Path(tmp), Path(tmp) / "frames", None)
    return {**out, "frames": frames, "hand_stills": sum(f in REAL_HAND_FRAMES for f in frames)}


def stills_section(args, log) -> dict:
    draws, failures = [], 0
    for every in (3, 4, 5, 6, 7):
        with tempfile.TemporaryDirectory(prefix="stills-") as tmp:
            try:
                draws.append({"every": every, **_fit_stills(Path(tmp), None, clip_path(), every)})
            except (RuntimeError, KeyError) as exc:
                failures += 1
                log(f"stills every {every}: failed ({exc})")
                continue
        d = draws[-1]
        log(
            f"stills every {every}: frames {d['frames']}, RMS {d['rms_px']:.2f} px, depth {d['depth_ratio']:.2f}, "
            f"{d['hand_stills']} with the hand"
        )
    hand = _fit_frames(list(FRAMES))
    even = _fit_frames([int(round(x)) for x in np.linspace(0, 471, 5)])
    log(
        f"peers: hand-picked RMS {hand['rms_px']:.2f} px, depth {hand['depth_ratio']:.2f}; evenly spaced "
        f"{even['frames']} RMS {even['rms_px']:.2f} px, depth {even['depth_ratio']:.2f}, "
        f"{even['hand_stills']} with the hand"
    )
    rms = [d["rms_px"] for d in draws] or [-1.0]
    depth = [d["depth_ratio"] for d in draws] or [-1.0]
    return {
        "stills": {
            "draws": draws,
            "rms_mean_px": round(float(np.mean(rms)), 3),
            "rms_worst_px": max(rms),
            "depth_ratio_min": min(depth),
            "depth_ratio_max": max(depth),
            "hand_stills": sum(d["hand_stills"] for d in draws),
            "failures": failures,
            "hand_picked": hand,
            "evenly_spaced": even,
        }
    }


if __name__ == "__main__":
    log = lambda s: print(s, file=sys.stderr, flush=True)  # noqa: E731
    print(json.dumps({**auto_fit_section(None, log), **real_sample_section(None, log)}, indent=1))
