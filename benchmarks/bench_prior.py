"""The localised face prior (issue 38, seed 004) against RBF-only and a global PCA prior, same run.

    .venv/bin/python benchmarks/bench_prior.py [--json] [--draws 10] [--sections lm,detector,full,scan]
        [--figures DIR] [--people 4] [--rigs 16]

Methods (all on the generic mesh, all through the same pipeline):

* ``rbf`` — today's fit: Pighin's RBF deformation of the generic mesh (§5.1.2–5.1.3);
* ``global`` — a global PCA prior: ICT's 100 identity modes as one model, fitted first, the RBF
  then honouring every click (:class:`photomodel.prior.face_prior.PriorDeformer`);
* ``local`` — the localised prior (:mod:`photomodel.prior.face_prior`), same way, with the global
  model fitted first as its coarsest level (as ``facestudio fit`` does).

Sections (mean surface distance, mm, from the fitted mesh's face region — bench_pose's
``face_mask`` — to the james scan, after the similarity that maps the fit's 3D feature points
onto their true positions):

* ``landmarks_only_mm`` — (i) the sample's five cameras, only the 68 landmark features (no other
  feature, no curve): the stored clicks plus ``--draws`` fresh draws of the true projections with
  σ = 1 px noise (seed 38); mean over the 1 + draws fits.
* ``detector_mm`` — (ii) the sample's photos with no click, ``facestudio new --photos`` (the
  detector's clicks and curves), then the fit.
* ``full_clicks_mm`` — (iii) the sample's ~170 hand clicks and curves as stored.
* ``scan`` — (iv) the james scan as a point cloud (40 000 points sampled on its surface, seed 38)
  with σ = 0.5 mm noise per axis, 5 % stray points 2–20 mm off the surface along its normal, and
  in turn one region removed (``nose_upper_lip``, ``cheek`` (the subject's right), ``chin``: the 30 %
  of the face's vertices nearest each region's centre; every scan point whose true generic-mesh
  correspondence lies in the region is dropped). The scan's 68 annotated landmarks are given.
  Per region: ``missing_mm`` (mean distance to the clean scan over the removed region's
  vertices), ``present_mm`` (over the rest of the face) and ``under_1mm_pct`` (of all the face's
  vertices, the removed region's included; the fraction over the rest alone is printed), per
  method; ``fit_s``: the local prior's mean fit time, CPU seconds of the process (all threads; wall
  clock on a shared machine is not comparable). The ``rbf`` peer here is the generic mesh
  warped by the landmarks and then non-rigid ICP without a prior
  (:func:`photomodel.prior.scan_fit.fit_scan_rbf`: an RBF with a ridge through a subsample of
  the paired vertices); all three get the same final detail step.

* ``ict_scan`` (only when asked for: ``--sections ict_scan``, not in the default run) — the scan
  section on ``--people`` ICT identities instead of james (seeded draws ``c ~ N(0, 1)`` of ICT's
  100 identity modes on the generic mesh, seed 37 001: people the sample is not), each made
  into the same kind of scan (40 000 points sampled on its mesh, noise, strays, each region in
  turn removed by the generic vertex it was sampled from), its 68 landmark vertices given; error
  against its own surface. Where the scan fit's settings are chosen (``SCAN_RIDGE``), since james
  must not be. Means over people and regions: ``missing_mm``, ``present_mm``, ``under_1mm_pct``.

* ``rigs`` (only when asked for: ``--sections rigs``) — (i) on other rigs than the sample's: ``--rigs``
  random rigs of the james scan (:func:`peers.rigs.synthetic_rig`, seed 38 000 + draw) cycling
  through :data:`RIG_SPECS` (3–6 cameras over yaw ranges from ±30° to ±80°, lenses 35–100 mm,
  1000 × 1333 px, the face half the image's width), each camera clicking the 68 landmarks it sees
  (depth-tested on the scan, :func:`photomodel.samples.synthetic.visible`) with σ = 1 px noise;
  per method the mean and worst over the rigs and how many are over 0.9 mm (issue 38's bar for
  held-back 68-landmark rigs). A rig whose clicks cannot be fitted (a pose feature in one photo
  only) counts in ``not_fitted`` and nowhere else.

``--figures DIR`` writes one PNG per scan region: the local prior's per-vertex error as colour.
"""

from __future__ import annotations

import argparse
import copy
import json
import shutil
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
from scipy.spatial import cKDTree

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # the repository, when not installed

from photomodel.alignment import similarity_transform  # noqa: E402
from photomodel.modeling.fit import fit_expression  # noqa: E402
from photomodel.modeling.generic_mesh import load_generic_mesh  # noqa: E402
from photomodel.modeling.rbf import deform_vertices  # noqa: E402
from photomodel.prior.face_prior import PriorDeformer, ScanData, load_face_prior  # noqa: E402
from photomodel.prior.scan_fit import fit_scan_prior_peer, fit_scan_rbf, scan_normals  # noqa: E402
from photomodel.project import load_project  # noqa: E402
from photomodel.samples import synthetic  # noqa: E402
from photomodel.samples.sample_data import load_james_scan  # noqa: E402

SAMPLE = Path(__file__).resolve().parents[1] / "sample_projects" / "james"
SEED = 38
METHODS = ("rbf", "global", "local")
REGIONS = ("nose_upper_lip", "cheek", "chin")


class Bench:
    def __init__(self):
        self.mesh = load_generic_mesh()
        self.scan = load_james_scan()
        self.truth = synthetic.load_ground_truth(SAMPLE / "ground_truth.json")
        self.priors = {"global": load_face_prior(self.mesh, "global"), "local": load_face_prior(self.mesh, "local")}

    def deformer(self, method):
        if method == "rbf":
            return deform_vertices
        outline = self.mesh.landmarks  # the face's outline for slide_onto's offset, as `fit`
        if method == "global":
            return PriorDeformer(self.priors["global"], deform_vertices, outline=outline)
        return PriorDeformer(self.priors["local"], deform_vertices, coarse=self.priors["global"], outline=outline)

    def score(self, result) -> float:
        s, R, t = similarity_transform(result.points_3d, self.truth.true_points(result.feature_names))
        V = result.vertices @ (s * R).T + t
        return float(synthetic.surface_distance(V[self.mesh.face_mask], self.scan).mean())

    def fit_scores(self, project) -> dict:
        return {m: self.score(fit_expression(project, "neutral", self.mesh, deform=self.deformer(m))) for m in METHODS}


def landmarks_only(project, landmark_vertices):
    """The project with only the 68 landmark features (no other feature, no curve)."""
    p = copy.deepcopy(project)
    keep = {f.name for f in p.features if f.vertex in landmark_vertices}
    p.features = [f for f in p.features if f.name in keep]
    p.curves = []
    for ph in p.expression("neutral").photos:
        ph.points = {k: v for k, v in ph.points.items() if k in keep}
        ph.hidden = {h for h in ph.hidden if h in keep}
        ph.curves = {}
    return p


def _mean(rows):
    return {m: float(np.mean([r[m] for r in rows])) for m in METHODS}


def landmarks_section(b: Bench, draws: int, log) -> dict:
    base = landmarks_only(load_project(SAMPLE / "james.facestudio.json"), set(b.mesh.landmarks.tolist()))
    rows = [b.fit_scores(base)]
    log(f"(i) stored clicks: {_fmt(rows[-1])}")
    rng = np.random.default_rng(SEED)
    photos = base.expression("neutral").photos
    names = [f.name for f in base.features]
    clean = b.truth.clean_observations("neutral", [ph.id for ph in photos], names)
    for d in range(draws):
        p = copy.deepcopy(base)
        for k, ph in enumerate(p.expression("neutral").photos):
            ph.points = {n: clean[k, i] + rng.normal(0.0, 1.0, 2) for i, n in enumerate(names) if n in photos[k].points}
        rows.append(b.fit_scores(p))
        log(f"(i) draw {d + 1}/{draws}: {_fmt(rows[-1])}")
    return _mean(rows)


def detector_section(b: Bench, log) -> dict:
    from benchmarks.autofit import run_cli

    project = load_project(SAMPLE / "james.facestudio.json")
    with tempfile.TemporaryDirectory(prefix="bench-prior-") as tmp:
        photos = Path(tmp) / "photos"
        photos.mkdir()
        for p in project.expression("neutral").photos:
            shutil.copy(project.resolve(p.path), photos / Path(p.path).name)
        path = Path(tmp) / "auto.facestudio.json"
        run_cli("new", str(path), "--photos", str(photos))
        out = b.fit_scores(load_project(path))
    log(f"(ii) detector clicks: {_fmt(out)}")
    return out


def full_section(b: Bench, log) -> dict:
    out = b.fit_scores(load_project(SAMPLE / "james.facestudio.json"))
    log(f"(iii) full hand clicks: {_fmt(out)}")
    return out


def regions(mesh) -> dict[str, np.ndarray]:
    """(N,) bool per removed region: the 30 % of face vertices nearest its centre (module notes)."""
    V, L = mesh.vertices, mesh.vertices[mesh.landmarks]
    face = np.flatnonzero(mesh.face_mask)
    centres = {
        "nose_upper_lip": (L[30] + L[51]) / 2,
        "cheek": (L[2] + L[31] + L[41]) / 3,  # the subject's right (x < 0)
        "chin": (L[8] + L[57]) / 2,
    }
    stretch = {"nose_upper_lip": np.array([1.6, 0.8, 1.0]), "cheek": np.ones(3), "chin": np.array([0.8, 1.2, 1.0])}
    out = {}
    for name, c in centres.items():
        d = np.linalg.norm((V[face] - c) * stretch[name], axis=1)
        mask = np.zeros(len(V), bool)
        mask[face[np.argsort(d)[: int(0.3 * len(face))]]] = True
        out[name] = mask
    return out


def noisy_scan(b: Bench, removed: np.ndarray, rng) -> tuple[np.ndarray, np.ndarray]:
    """(points, true correspondence's generic vertex) of the corrupted james scan (module notes)."""
    import trimesh

    welded = b.scan.welded
    pts, fidx = trimesh.sample.sample_surface(welded, 40000, seed=SEED)
    normals = np.asarray(welded.face_normals)[fidx]
    truth = synthetic.true_correspondence(b.mesh, b.scan)
    nearest = cKDTree(truth).query(pts)[1]
    keep = ~removed[nearest]
    pts = pts + rng.normal(0.0, 0.5, pts.shape)
    stray = rng.random(len(pts)) < 0.05
    off = rng.uniform(2.0, 20.0, stray.sum()) * rng.choice([-1.0, 1.0], stray.sum())
    pts[stray] += normals[stray] * off[:, None]
    return pts[keep], normals[keep]


def scan_section(b: Bench, log, figures: Path | None) -> dict:
    rng = np.random.default_rng(SEED)
    lm = np.asarray(b.scan.landmarks, float)
    face = b.mesh.face_mask
    rows, times, present_under, missing_under = [], [], {}, {}
    for name, removed in regions(b.mesh).items():
        pts, _ = noisy_scan(b, removed, rng)
        data = ScanData(pts, scan_normals(pts))
        row = {"region": name, "missing_mm": {}, "present_mm": {}, "under_1mm_pct": {}}
        for m in METHODS:
            t0 = time.process_time()
            if m == "rbf":
                V = fit_scan_rbf(b.mesh, data, lm)
            else:
                V = fit_scan_prior_peer(b.priors[m], b.mesh, data, lm)
            if m == "local":
                times.append(time.process_time() - t0)
            d = synthetic.surface_distance(V, b.scan)
            miss, rest = removed & face, face & ~removed
            row["missing_mm"][m] = float(d[miss].mean())
            row["present_mm"][m] = float(d[rest].mean())
            row["under_1mm_pct"][m] = float(100.0 * (d[face] < 1.0).mean())
            present_under.setdefault(m, []).append(float(100.0 * (d[rest] < 1.0).mean()))
            missing_under.setdefault(m, []).append(float(100.0 * (d[miss] < 1.0).mean()))
            if figures is not None and m == "local":
                _figure(b, V, d, figures / f"scan_{name}.png")
        rows.append(row)
        log(
            f"(iv) {name}: missing {_fmt(row['missing_mm'])}; present {_fmt(row['present_mm'])}; "
            f"<1 mm {_fmt(row['under_1mm_pct'], '.0f')} %"
        )
    log(
        f"(iv) fit time (local) {np.mean(times):.1f} s CPU; under 1 mm outside the removed regions, %: "
        + " ".join(f"{m} {min(v):.0f}–{max(v):.0f}" for m, v in present_under.items())
        + "; inside them: "
        + " ".join(f"{m} {min(v):.0f}–{max(v):.0f}" for m, v in missing_under.items())
    )
    return {"regions": rows, "fit_s": float(np.mean(times))}


def ict_scan_section(b: Bench, people: int, log) -> dict:
    """The ``ict_scan`` section (module notes): ICT people as noisy, holed scans."""
    import trimesh

    from photomodel.closest_points import TriangleSurface
    from photomodel.prior.face_prior import ict_modes_on_mesh

    modes, _ = ict_modes_on_mesh(b.mesh)
    rng = np.random.default_rng(37_001)
    face, rows = b.mesh.face_mask, []
    for person in range(people):
        P = b.mesh.vertices + np.tensordot(rng.normal(0.0, 1.0, len(modes)), modes, 1)
        head, surface = trimesh.Trimesh(P, b.mesh.faces, process=False), TriangleSurface(P, b.mesh.faces)
        for name, removed in regions(b.mesh).items():
            pts, fidx = trimesh.sample.sample_surface(head, 40000, seed=int(rng.integers(1 << 30)))
            normals = np.asarray(head.face_normals)[fidx]
            keep = ~removed[b.mesh.faces[fidx, 0]]
            pts = pts + rng.normal(0.0, 0.5, pts.shape)
            stray = rng.random(len(pts)) < 0.05
            off = rng.uniform(2.0, 20.0, stray.sum()) * rng.choice([-1.0, 1.0], stray.sum())
            pts[stray] += normals[stray] * off[:, None]
            data = ScanData(pts[keep], scan_normals(pts[keep]))
            lm = P[b.mesh.landmarks]
            row = {}
            for m in METHODS:
                V = fit_scan_rbf(b.mesh, data, lm) if m == "rbf" else fit_scan_prior_peer(b.priors[m], b.mesh, data, lm)
                d = surface.closest(V)[1]
                row[m] = (d[removed & face].mean(), d[face & ~removed].mean(), 100.0 * (d[face] < 1.0).mean())
            rows.append(row)
            log(
                f"ict_scan person {person + 1}/{people} {name}: <1 mm "
                + " ".join(f"{m} {row[m][2]:.1f}" for m in METHODS)
            )
    keys = ("missing_mm", "present_mm", "under_1mm_pct")
    return {k: {m: float(np.mean([r[m][i] for r in rows])) for m in METHODS} for i, k in enumerate(keys)} | {
        "people": people
    }


#: σ (px) of the ``rigs`` section's click noise per axis.
RIG_NOISE_PX = 1.0
#: (cameras, yaw range °) of the ``rigs`` section's draws, in turn.
RIG_SPECS = (
    (3, (-45.0, 45.0)),
    (4, (-60.0, 60.0)),
    (5, (-70.0, 70.0)),
    (3, (-30.0, 30.0)),
    (6, (-80.0, 80.0)),
    (4, (-20.0, 50.0)),
    (5, (-60.0, 30.0)),
    (4, (-35.0, 35.0)),
)


def rigs_section(b: Bench, rigs: int, log) -> dict:
    """The ``rigs`` section (module notes): 68 landmarks on random rigs of the scan."""
    from peers.rigs import synthetic_rig
    from photomodel.errors import FitError
    from photomodel.project.datamodel import Photo

    base = landmarks_only(load_project(SAMPLE / "james.facestudio.json"), set(b.mesh.landmarks.tolist()))
    names = [f.name for f in base.features]
    P = b.truth.true_points(names)
    rows, not_fitted = [], 0
    for d in range(rigs):
        k, yaws = RIG_SPECS[d % len(RIG_SPECS)]
        rig = synthetic_rig(k, P, width=1000, rng=38_000 + d, noise_px=0.0, azimuth_range_deg=yaws)
        rng = np.random.default_rng(38_500 + d)
        p = copy.deepcopy(base)
        photos = []
        for i, cam in enumerate(rig.true_cameras):
            seen = synthetic.visible(cam, P, b.scan, tol_mm=synthetic.CLICK_TOL_MM, min_cos=synthetic.CLICK_MIN_COS)
            uv = cam.project(P) + rng.normal(0.0, RIG_NOISE_PX, (len(P), 2))
            seen &= np.all((uv >= 0) & (uv < [cam.width, cam.height]), axis=1)
            points = {n: uv[j] for j, n in enumerate(names) if seen[j]}
            photos.append(Photo(f"v{i}", f"v{i}.png", cam.width, cam.height, rig.presets[i], points=points))
        p.expression("neutral").photos = photos
        try:
            row = b.fit_scores(p)
        except FitError as exc:
            not_fitted += 1
            why = str(exc).splitlines()[0]
            log(f"rig {d + 1}/{rigs} ({k} cameras, {yaws[0]:.0f}…{yaws[1]:.0f}°): not fitted ({why})")
            continue
        rows.append(row)
        log(f"rig {d + 1}/{rigs} ({k} cameras, {yaws[0]:.0f}…{yaws[1]:.0f}°): {_fmt(row)}")

    def figures(m):
        v = np.array([r[m] for r in rows]) if rows else np.array([-1.0])
        return {"mean": float(v.mean()), "worst": float(v.max()), "over_0_9": int((v > 0.9).sum()) if rows else 0}

    return {m: figures(m) for m in METHODS} | {"rigs": rigs, "not_fitted": not_fitted}


def _figure(b: Bench, V, d, path: Path) -> None:
    """A front view of the fitted mesh's vertices coloured by error (0 green … 3 mm red)."""
    import cv2

    path.parent.mkdir(parents=True, exist_ok=True)
    img = np.full((600, 500, 3), 255, np.uint8)
    x = ((V[:, 0] + 100) * 2.5).astype(int)
    y = ((120 - V[:, 1]) * 2.5).astype(int)
    order = np.argsort(V[:, 2])
    for i in order:
        if 0 <= x[i] < 500 and 0 <= y[i] < 600:
            e = min(d[i] / 3.0, 1.0)
            cv2.circle(img, (int(x[i]), int(y[i])), 2, (0, int(255 * (1 - e)), int(255 * e)), -1)
    cv2.imwrite(str(path), img)


def _fmt(row: dict, spec: str = ".3f") -> str:
    return " ".join(f"{m} {row[m]:{spec}}" for m in METHODS)


def run(draws: int, sections: set, figures: Path | None, log, people: int = 4, rigs: int = 16) -> dict:
    b = Bench()
    out = {"draws": draws}
    if "lm" in sections:
        out["landmarks_only_mm"] = landmarks_section(b, draws, log)
    if "detector" in sections:
        out["detector_mm"] = detector_section(b, log)
    if "full" in sections:
        out["full_clicks_mm"] = full_section(b, log)
    if "scan" in sections:
        out["scan"] = scan_section(b, log, figures)
    if "ict_scan" in sections:
        out["ict_scan"] = ict_scan_section(b, people, log)
    if "rigs" in sections:
        out["rigs"] = rigs_section(b, rigs, log)
    return {"prior": out}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--json", action="store_true", help="print one JSON object")
    ap.add_argument("--draws", type=int, default=10, help="fresh σ = 1 px draws of section (i)")
    ap.add_argument("--sections", default="lm,detector,full,scan")
    ap.add_argument("--figures", type=Path, default=None, help="folder for the scan sections' PNGs")
    ap.add_argument("--people", type=int, default=4, help="ICT people of the ict_scan section (only run when asked)")
    ap.add_argument("--rigs", type=int, default=16, help="random rigs of the rigs section (only run when asked)")
    args = ap.parse_args(argv)

    def log(msg):
        print(msg, file=sys.stderr if args.json else sys.stdout, flush=True)

    out = run(args.draws, set(args.sections.split(",")), args.figures, log, args.people, args.rigs)
    if args.json:
        print(json.dumps(out, indent=2))
    return 0


if __name__ == "__main__":
    sys.exit(main())
