"""Build the ``james`` sample project: synthetic photographs of a real head scan with
an artist's clicks and curves, plus the ground truth that tests and benchmarks compare
the fit against.

Run from the repository root::

    .venv/bin/python sample_projects/make_james.py [--out sample_projects/james] [--overlays DIR]

It writes, into ``--out``:

* ``photos/neutral_<id>.png`` — the textured james scan (:mod:`photomodel.sample_data`)
  rendered by :mod:`photomodel.render` from the 5-camera rig of
  :func:`photomodel.synthetic.rig` at 1000×1000 on a light grey background;
* ``james.facestudio.json`` — the project (:mod:`photomodel.project`): the 13 initial
  features (``pose: true``), the other 55 iBUG landmarks and 100 extra correspondences
  (``pose: false``), the generic mesh's curves, and one expression ``neutral`` whose
  photos carry the nearest preset as the artist's rough guess, no focal guess, noisy
  clicks (σ = 1 px) where visible and hand-drawn curves where (nearly) entirely visible;
* ``ground_truth.json`` — true cameras, noise-free projections, visibility, true 3D
  feature positions, the seed and the scan alignment. The fit never reads it.

Everything is deterministic (fixed seeds). With ``--overlays DIR`` the clicks and curves
are also drawn over each photo to ``DIR/sample_overlay_<id>.png`` for a visual check.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import cv2
import numpy as np

REPO = Path(__file__).resolve().parents[1]
if str(REPO) not in sys.path:
    sys.path.insert(0, str(REPO))

from photomodel import synthetic  # noqa: E402
from photomodel.generic_mesh import IBUG68_NAMES, load_generic_mesh  # noqa: E402
from photomodel.project import CurveDef, Expression, Feature, Photo, new_project, save_project  # noqa: E402
from photomodel.render import write_png  # noqa: E402
from photomodel.sample_data import load_james_scan  # noqa: E402

SEED = 20020601  # clicks, curves and extra correspondences all derive from it
NOISE_PX = 1.0  # σ of the click noise and RMS of the curve wobble (a careful artist)
IMAGE_SIZE = 1000
BACKGROUND_RGB = (0.86, 0.86, 0.85)  # light grey, as a studio backdrop
N_EXTRAS = 100
#: A curve is drawn in a photo only if at least this fraction of it is visible, and then
#: drawn whole: the fit binds a drawing to the whole mesh curve by arc length (§5.1.3),
#: so an artist outlines a curve end to end where it can (nearly) all be seen, following
#: the silhouette over a short hidden end, and leaves it out elsewhere.
MIN_CURVE_VISIBLE = 0.9
CLICK_MIN_COS = synthetic.CLICK_MIN_COS
CLICK_TOL_MM = synthetic.CLICK_TOL_MM
#: Curves are traced along silhouettes too (the jaw line in a front view), so their
#: visibility accepts surfaces seen edge-on (n·view > 0 rather than the clicks' 0.1).
CURVE_MIN_COS = 0.0
EXPRESSION = "neutral"
PROJECT_FILE = "james.facestudio.json"
GROUND_TRUTH_FILE = "ground_truth.json"


def feature_list(mesh, extras: dict[str, int]) -> list:
    """The project's features: initial (pose) ones, the other landmarks, the extras."""
    features = [Feature(name, mesh.features[name], True) for name in mesh.initial_features]
    used = {f.vertex for f in features}
    features += [
        Feature(name, int(mesh.landmarks[i]), False)
        for i, name in enumerate(IBUG68_NAMES)
        if int(mesh.landmarks[i]) not in used
    ]
    features += [Feature(name, v, False) for name, v in extras.items()]
    return features


def build(out: Path, overlays: Path | None = None) -> dict:
    """Write the sample project into ``out``; returns a small summary dict."""
    out = Path(out)
    (out / "photos").mkdir(parents=True, exist_ok=True)
    rng = np.random.default_rng(SEED)
    scan = load_james_scan()
    mesh = load_generic_mesh()
    truth = synthetic.true_correspondence(mesh, scan)

    extras = synthetic.extra_correspondences(mesh, N_EXTRAS, seed=SEED)
    features = feature_list(mesh, extras)
    names = [f.name for f in features]
    points3d = truth[[f.vertex for f in features]]

    cameras = synthetic.rig("sample", IMAGE_SIZE, IMAGE_SIZE)
    ids = [synthetic.preset_for(c) for c in cameras]
    if len(set(ids)) != len(ids):
        raise RuntimeError(f"rig cameras map to repeated presets {ids}")

    curve_names = list(mesh.curves)
    dense_curves = {name: synthetic.dense_true_curve(truth[mesh.curves[name]], scan) for name in curve_names}
    depths, vis = [], []
    gt_photos = {}
    photos = []
    for cam, pid in zip(cameras, ids, strict=True):
        # supersampled: anti-aliased silhouettes, like a photograph
        result = synthetic.render_scan(cam, scan, background=BACKGROUND_RGB, supersample=3)
        write_png(out / "photos" / f"{EXPRESSION}_{pid}.png", result.color)
        depth = np.asarray(result.depth, float)
        depths.append(depth)
        vis.append(
            synthetic.visible(cam, points3d, scan, depth=depth, tol_mm=CLICK_TOL_MM, min_cos=CLICK_MIN_COS)
        )
    vis = np.array(vis)
    clicks = synthetic.synthesize_clicks(cameras, points3d, vis, NOISE_PX, rng)

    for i, (cam, pid) in enumerate(zip(cameras, ids, strict=True)):
        drawn = {}
        curve_visible = {}
        for name in curve_names:
            dense = dense_curves[name]
            v = synthetic.visible(cam, dense, scan, depth=depths[i], min_cos=CURVE_MIN_COS)
            curve_visible[name] = round(float(v.mean()), 4)
            if v.mean() < MIN_CURVE_VISIBLE:
                continue
            stroke = synthetic.synthesize_curve(cam, dense, NOISE_PX, rng)
            if stroke is not None:
                drawn[name] = stroke
        points = {n: clicks[i, j] for j, n in enumerate(names) if vis[i, j]}
        photos.append(
            Photo(
                id=pid,
                path=f"photos/{EXPRESSION}_{pid}.png",
                width=IMAGE_SIZE,
                height=IMAGE_SIZE,
                preset=pid,
                focal_mm_guess=None,
                points=points,
                hidden=set(),
                curves=drawn,
            )
        )
        exact = cam.project(points3d)
        gt_photos[pid] = {
            "camera": cam.to_dict(),
            "azimuth_deg": round(synthetic.azimuth_deg(cam), 3),
            "focal_mm": round(cam.focal_mm, 3),
            "visible": [n for j, n in enumerate(names) if vis[i, j]],
            "points": {n: np.round(exact[j], 4).tolist() for j, n in enumerate(names)},
            "curve_visible_fraction": curve_visible,
            "curves_drawn": sorted(drawn),
        }
        if overlays is not None:
            _overlay(out / photos[-1].path, photos[-1], features, overlays / f"sample_overlay_{pid}.png")

    project = new_project(
        "james",
        features=features,
        curves=[CurveDef(name, mesh.curves[name]) for name in curve_names],
    )
    project.expressions.append(Expression(EXPRESSION, photos))
    project_path = out / PROJECT_FILE
    project_path.unlink(missing_ok=True)  # a fresh build: no .bak of an older one
    save_project(project, project_path)
    Path(str(project_path) + ".bak").unlink(missing_ok=True)

    R, t = scan.rigid
    ground_truth = {
        "format": "facestudio-ground-truth",
        "version": 1,
        "project": PROJECT_FILE,
        "note": "Ground truth of the synthetic sample project; the fit never reads this file.",
        "seed": SEED,
        "noise_px": NOISE_PX,
        "rig": "sample",
        "scan": "menpo3d 0.8.6 james.obj, see photomodel.sample_data",
        "scan_alignment": {
            "description": "x_head = R @ x_obj + t (mm), rigid, james.obj coordinates -> head frame",
            "rotation": np.asarray(R).tolist(),
            "translation_mm": np.asarray(t).tolist(),
        },
        "correspondence_version": synthetic.CORRESPONDENCE_VERSION,
        "features_3d": {n: np.round(points3d[j], 5).tolist() for j, n in enumerate(names)},
        "expressions": {EXPRESSION: {"photos": gt_photos}},
    }
    (out / GROUND_TRUTH_FILE).write_text(json.dumps(ground_truth, indent=1) + "\n")

    size = sum(p.stat().st_size for p in out.rglob("*") if p.is_file())
    return {
        "photos": ids,
        "features": len(features),
        "clicks_per_photo": {pid: int(vis[i].sum()) for i, pid in enumerate(ids)},
        "curves_per_photo": {p.id: sorted(p.curves) for p in photos},
        "folder_bytes": size,
    }


def _overlay(photo_path: Path, photo: Photo, features, target: Path) -> None:
    """Draw clicks (pose features large and labelled, landmarks small, extras dots) and
    curves (red) over a photo."""
    img = cv2.imread(str(photo_path), cv2.IMREAD_COLOR)
    pose = {f.name for f in features if f.pose}
    extra = {f.name for f in features if f.name.startswith("extra_")}
    for stroke in photo.curves.values():
        pts = np.round(stroke).astype(np.int32)
        cv2.polylines(img, [pts], False, (0, 0, 255), 1, cv2.LINE_AA)
        cv2.circle(img, tuple(int(x) for x in pts[0]), 3, (0, 0, 255), -1)  # stroke start
    for name, (u, v) in photo.points.items():
        c = (int(round(u)), int(round(v)))
        if name in pose:
            cv2.circle(img, c, 5, (0, 200, 0), 2, cv2.LINE_AA)
            cv2.putText(img, name, (c[0] + 6, c[1] - 6), cv2.FONT_HERSHEY_SIMPLEX, 0.4, (0, 120, 0), 1)
        elif name in extra:
            cv2.circle(img, c, 2, (255, 160, 0), -1)
        else:
            cv2.circle(img, c, 3, (0, 220, 255), 1, cv2.LINE_AA)
    target.parent.mkdir(parents=True, exist_ok=True)
    cv2.imwrite(str(target), img)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--out", type=Path, default=REPO / "sample_projects" / "james")
    parser.add_argument(
        "--overlays",
        type=Path,
        default=None,
        help="also write sample_overlay_<id>.png debug overlays into this folder",
    )
    args = parser.parse_args(argv)
    summary = build(args.out, args.overlays)
    print(json.dumps(summary, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
