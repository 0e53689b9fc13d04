"""Build the ``james`` sample project: synthetic photographs of a real head scan in five
expressions with an artist's clicks and curves, plus the ground truth that tests and benchmarks
compare the fit against.

Run from the repository root::

    .venv/bin/python sample_projects/make_james.py [--out sample_projects/james] [--overlays DIR]

It writes, into ``--out``:

* ``photos/neutral_<id>.png`` — the textured james scan (:mod:`photomodel.samples.sample_data`)
  rendered by :mod:`photomodel.rendering.renderer` from the 5-camera rig of
  :func:`photomodel.samples.synthetic.rig` at 1000×1000 on a light grey background;
* ``photos/<expression>_<id>.jpg`` for ``smile``, ``open_mouth``, ``brows_raised`` and
  ``frown`` — the scan deformed by that expression's smooth field (:mod:`tracking.synthetic_sequences.expressions`;
  ``frown`` is the extra expression the sample video never uses) and photographed by the same
  rig, the same cameras photo for photo. JPEG (quality :data:`JPEG_QUALITY`), as real cameras
  write, to keep the repository small (2.7 MB for the 20; the neutral's PNGs predate them and
  are kept byte for byte);
* ``james.facestudio.json`` — the project (:mod:`photomodel.project`): the 13 initial
  features (``pose: true``), the other 55 iBUG landmarks and 100 extra correspondences
  (``pose: false``), the generic mesh's curves, and five expressions whose photos carry the
  nearest preset as the artist's rough guess, no focal guess, noisy clicks (σ = 1 px) where
  visible and hand-drawn curves where (nearly) entirely visible. The four non-neutral
  expressions have ``cameras_from: "neutral"`` (one rig: the fit reuses the neutral's cameras);
* ``ground_truth.json`` — per expression: true cameras (the same rig), noise-free projections,
  visibility and true 3D feature positions (``features_3d``: the generic vertices' true positions
  on the neutral scan plus the expression's displacement, the rows of
  :func:`tracking.synthetic_sequences.expressions.true_expression_geometry`); the top-level ``features_3d`` is the
  neutral's; the seed and the scan alignment. The fit never reads it.

Everything is deterministic. The neutral's clicks and curves come from ``default_rng(SEED)``,
each other expression's from its own ``default_rng([SEED, i])`` (``i`` its index in
:data:`EXPRESSIONS`), so adding an expression changes no other. With ``--overlays DIR`` the
clicks and curves are also drawn over each photo to ``DIR/sample_overlay_<expression>_<id>.png``
for a visual check. :func:`expression_scan` gives the true surface of an expression.
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

from photomodel.exchange.files import atomic_write_bytes, encode_png  # noqa: E402
from photomodel.modeling.generic_mesh import IBUG68_NAMES, load_generic_mesh  # noqa: E402
from photomodel.project import CurveDef, Expression, Feature, Photo, new_project, save_project  # noqa: E402
from photomodel.samples import synthetic  # noqa: E402
from photomodel.samples.sample_data import load_james_scan  # noqa: E402
from tracking.synthetic_sequences.expressions import (  # noqa: E402
    deformed_scan_vertices,
    expression_displacement,
    true_expression_geometry,
)

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
#: The expressions photographed, neutral first; the others are the smooth deformations of the
#: scan of :mod:`tracking.synthetic_sequences.expressions` (its basic expressions and its extra one).
NEUTRAL = "neutral"
EXPRESSIONS = (NEUTRAL, "smile", "open_mouth", "brows_raised", "frown")
#: JPEG quality of the expression photos (the neutral's are PNG, kept as first published).
JPEG_QUALITY = 92
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


def expression_scan(scan, name: str):
    """The james scan in expression ``name`` (:mod:`tracking.synthetic_sequences.expressions`): a new
    :class:`~photomodel.samples.sample_data.Scan` with the deformed vertices and landmarks (its own
    welded surface for visibility and surface distances); the scan itself for ``neutral``."""
    if name == NEUTRAL:
        return scan
    vertices = deformed_scan_vertices(scan, [1.0], [name])
    landmarks = scan.landmarks + expression_displacement(name, scan.landmarks, scan.landmarks)
    return synthetic.deformed_scan(scan, vertices, landmarks)


def shoot(out: Path, expression: str, scan, cameras, ids, names, points3d, curve_points, rng, image_format: str):
    """Photograph one expression with the rig and play the artist on the photos.

    Parameters
    ----------
    scan : Scan, the head in this expression.
    cameras, ids : the rig's true cameras and photo ids.
    names, points3d : feature names and their true 3D positions (n, 3) mm in this expression.
    curve_points : dict curve name → (m, 3) mm, the curve's generic vertices' true positions.
    rng : the generator of this expression's clicks and curves.
    image_format : ``"png"`` (lossless) or ``"jpg"`` (quality :data:`JPEG_QUALITY`).

    Returns
    -------
    photos : list[Photo]; gt_photos : dict photo id → ground truth; vis : (k, n) bool.
    """
    dense_curves = {name: synthetic.dense_true_curve(pts, scan) for name, pts in curve_points.items()}
    depths, vis = [], []
    paths = []
    for cam, pid in zip(cameras, ids, strict=True):
        # supersampled: anti-aliased silhouettes, like a photograph
        result = synthetic.render_scan(cam, scan, background=BACKGROUND_RGB, supersample=3)
        rel = f"photos/{expression}_{pid}.{image_format}"
        if image_format == "png":
            atomic_write_bytes(out / rel, encode_png(result.color))
        else:
            atomic_write_bytes(out / rel, encode_jpeg(result.color, JPEG_QUALITY))
        paths.append(rel)
        depth = np.asarray(result.depth, float)
        depths.append(depth)
        vis.append(synthetic.visible(cam, points3d, scan, depth=depth, tol_mm=CLICK_TOL_MM, min_cos=CLICK_MIN_COS))
    vis = np.array(vis)
    clicks = synthetic.synthesize_clicks(cameras, points3d, vis, NOISE_PX, rng)

    photos, gt_photos = [], {}
    for i, (cam, pid) in enumerate(zip(cameras, ids, strict=True)):
        drawn = {}
        curve_visible = {}
        for name, dense in dense_curves.items():
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
                path=paths[i],
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
    return photos, gt_photos, vis


def encode_jpeg(image: np.ndarray, quality: int) -> bytes:
    """JPEG bytes of an RGB float image in [0, 1] (rounded to 8 bits like the PNGs)."""
    img = np.round(np.clip(np.asarray(image, float), 0.0, 1.0) * 255.0).astype(np.uint8)
    ok, buf = cv2.imencode(".jpg", cv2.cvtColor(img, cv2.COLOR_RGB2BGR), [cv2.IMWRITE_JPEG_QUALITY, int(quality)])
    if not ok:
        raise RuntimeError("OpenCV could not encode a JPEG")
    return buf.tobytes()


def build(out: Path, overlays: Path | None = None, expressions=EXPRESSIONS) -> dict:
    """Write the sample project into ``out``; returns a small summary dict.

    ``expressions`` (neutral first) picks which to shoot; each gets its own generator
    (``default_rng(SEED)`` for the neutral, ``default_rng([SEED, i])`` for the ``i``-th of
    :data:`EXPRESSIONS`), so adding one never changes another's clicks.
    """
    out = Path(out)
    if tuple(expressions[:1]) != (NEUTRAL,):
        raise ValueError(f"the neutral comes first (the others reuse its cameras), got {expressions}")
    (out / "photos").mkdir(parents=True, exist_ok=True)
    scan = load_james_scan()
    mesh = load_generic_mesh()

    extras = synthetic.extra_correspondences(mesh, N_EXTRAS, seed=SEED)
    features = feature_list(mesh, extras)
    names = [f.name for f in features]
    vertex_ids = [f.vertex for f in features]

    cameras = synthetic.rig("sample", IMAGE_SIZE, IMAGE_SIZE)
    ids = [synthetic.preset_for(c) for c in cameras]
    if len(set(ids)) != len(ids):
        raise RuntimeError(f"rig cameras map to repeated presets {ids}")

    curve_names = list(mesh.curves)
    # every expression's true geometry on the generic mesh: neutral = the scan correspondence
    geometry = true_expression_geometry(mesh, scan, tuple(expressions))
    project = new_project(
        "james",
        features=features,
        curves=[CurveDef(name, mesh.curves[name]) for name in curve_names],
    )
    gt_expressions = {}
    summary_clicks = {}
    for k, expression in enumerate(expressions):
        index = EXPRESSIONS.index(expression)
        rng = np.random.default_rng(SEED if index == 0 else [SEED, index])
        truth = geometry[k]
        points3d = truth[vertex_ids]
        photos, gt_photos, vis = shoot(
            out,
            expression,
            expression_scan(scan, expression),
            cameras,
            ids,
            names,
            points3d,
            {name: truth[mesh.curves[name]] for name in curve_names},
            rng,
            "png" if expression == NEUTRAL else "jpg",
        )
        if overlays is not None:
            for photo in photos:
                _overlay(out / photo.path, photo, features, overlays / f"sample_overlay_{expression}_{photo.id}.png")
        project.expressions.append(
            Expression(expression, photos, cameras_from=None if expression == NEUTRAL else NEUTRAL)
        )
        gt_expressions[expression] = {
            "deformation": "none"
            if expression == NEUTRAL
            else f"tracking.synthetic_sequences.expressions, {expression!r}",
            "features_3d": {n: np.round(points3d[j], 5).tolist() for j, n in enumerate(names)},
            "photos": gt_photos,
        }
        summary_clicks[expression] = {pid: int(vis[i].sum()) for i, pid in enumerate(ids)}

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
        "scan": "menpo3d 0.8.6 james.obj, see photomodel.samples.sample_data",
        "scan_alignment": {
            "description": "x_head = R @ x_obj + t (mm), rigid, james.obj coordinates -> head frame",
            "rotation": np.asarray(R).tolist(),
            "translation_mm": np.asarray(t).tolist(),
        },
        "correspondence_key": synthetic.correspondence_key(mesh, scan),
        "features_3d": gt_expressions[NEUTRAL]["features_3d"],
        "expressions": gt_expressions,
    }
    (out / GROUND_TRUTH_FILE).write_text(json.dumps(ground_truth, indent=1) + "\n")

    size = sum(p.stat().st_size for p in out.rglob("*") if p.is_file())
    photo_bytes = {e: sum((out / p.path).stat().st_size for p in project.expression(e).photos) for e in expressions}
    return {
        "photos": ids,
        "features": len(features),
        "clicks_per_photo": summary_clicks,
        "curves_per_photo": {e.name: {p.id: len(p.curves) for p in e.photos} for e in project.expressions},
        "photo_bytes": photo_bytes,
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
