"""The rig: ICT round trip, the tracked sample as an animated glb, and the Live Link CSV round trip.

    .venv/bin/python benchmarks/bench_rig.py [--json] [--identities 5] [--frames 8]

Sections of the one JSON object:

* ``rig`` — ``identities`` ICT identities sampled from its PCA (coefficients ~ N(0, 1) on all 100
  modes, seeded), each resampled onto the generic mesh through the registration and rigged by
  :class:`photomodel.rig.build.RigBuilder` (which fits only 50 of the modes before the
  deformation transfer); the truth is ICT's own identity + expression (the same ``Dᵉ`` for every
  identity in ICT's linear model) resampled the same way. Per shape and identity: the mean error
  over the face (generic face mask, covered by ICT) relative to the shape's mean displacement
  there. ``shapes``: the shapes that move the face ≥ 2 mm (the ones averaged);
  ``rel_err_pct_mean`` / ``_max`` over them and the identities; ``registration_landmark_mm``:
  the landmark RMS of ICT's registration onto the generic mesh (after the non-rigid fit).
* ``glb`` — the fitted sample project (:func:`tracking.synthetic_sequences.ground_truth.fitted_sample_project`,
  copied) rigged (``facestudio rig``), its sample video tracked for ``--frames`` frames and exported
  (``facestudio export --track --glb --csv``); read back with pygltflib: ``targets`` vs
  ``expected_targets`` (the rig's shapes + the photographed expressions × the 3 control regions),
  animated ``frames`` vs the tracked ones, and the Khronos validator's ``validator_errors`` (-1 when
  it is not installed).
* ``csv_roundtrip`` — the Live Link CSV that export wrote, read back, against the rig weights it was
  written from (recomputed): ``frames`` and ``max_abs_diff``.
"""

from __future__ import annotations

import argparse
import contextlib
import io
import json
import shutil
import sys
import tempfile
from pathlib import Path

import numpy as np
import pygltflib as gl

from app.cli import main as facestudio
from photomodel.exchange.livelink import read_livelink_csv
from photomodel.exchange.validator import validate_glb
from photomodel.modeling.generic_mesh import load_generic_mesh
from photomodel.project import load_project
from photomodel.rig.build import RigBuilder
from photomodel.rig.ict import ARKIT_SHAPES, load_ict
from tracking.blendshape_face import CONTROL_REGIONS
from tracking.performance import arkit_weights, blend_shapes, track_performance
from tracking.synthetic_sequences.ground_truth import fitted_sample_project
from tracking.track_result import load_track_results

REPO = Path(__file__).resolve().parents[1]
#: A shape counts in the round trip when it moves some face vertex at least this much (mm).
MOVES_MM = 2.0


def rig_section(identities: int, seed: int = 0, log=print) -> dict:
    builder = RigBuilder(load_generic_mesh())
    ict = load_ict()
    face = builder.face
    truth = builder.source_deltas[:, face]
    mag = np.linalg.norm(truth, axis=2)
    moving = mag.max(axis=1) >= MOVES_MM
    rng = np.random.default_rng(seed)
    rel = []
    for i in range(identities):
        P0 = builder.registration.positions(ict.identity(rng.standard_normal(len(ict.identities))))
        rig = builder.rig(P0)
        r = np.linalg.norm(rig.deltas[:, face] - truth, axis=2).mean(axis=1) / mag.mean(axis=1)
        rel.append(r[moving])
        log(f"identity {i}: rel. error mean {100 * r[moving].mean():.1f} %, max {100 * r[moving].max():.1f} %")
    rel = np.array(rel)
    return {
        "identities": identities,
        "shapes": int(moving.sum()),
        "rel_err_pct_mean": round(float(100 * rel.mean()), 2),
        "rel_err_pct_max": round(float(100 * rel.max()), 2),
        "registration_landmark_mm": round(builder.registration.landmark_rms_mm, 3),
    }


def _cli(*argv) -> dict:
    out = io.StringIO()
    with contextlib.redirect_stdout(out):
        rc = facestudio([*map(str, argv), "--json"])
    if rc != 0:
        raise RuntimeError(f"facestudio {' '.join(map(str, argv))} failed: {out.getvalue()}")
    return json.loads(out.getvalue())


def glb_and_csv_sections(frames: int, log=print) -> tuple[dict, dict]:
    with tempfile.TemporaryDirectory() as tmp:
        src = fitted_sample_project()
        folder = Path(tmp) / "james"
        shutil.copytree(src.parent, folder)
        shutil.copytree(REPO / "sample_projects" / "james" / "video", folder / "video")
        project_path = folder / src.name
        _cli("rig", project_path)
        track_dir = folder / "results" / "track"
        _cli(
            "track",
            project_path,
            "--video",
            folder / "video" / "james_track.mp4",
            "--frames",
            frames,
            "--out",
            track_dir,
            "--no-overlay",
            "--basis",
            "photographed",  # the CSV round trip measures the fit of the photographed weights
        )
        glb, csv = Path(tmp) / "james.glb", Path(tmp) / "james.csv"
        _cli("export", project_path, "--track", track_dir, "--glb", glb, "--csv", csv)
        log(f"exported {glb.stat().st_size / 1e6:.1f} MB")
        g = gl.GLTF2.load(str(glb))
        project = load_project(project_path)
        doc = load_track_results(track_dir)
        photographed = len(doc["model"]["expressions"]) - 1
        anim = g.animations[0] if g.animations else None
        report = validate_glb(glb)
        glb_out = {
            "targets": len(g.meshes[0].primitives[0].targets or []),
            "expected_targets": len(project.rig.shapes) + photographed * (len(CONTROL_REGIONS) - 1),
            "frames": 0 if anim is None else g.accessors[anim.samplers[0].input].count,
            "expected_frames": len(doc["frames"]),
            "validator_errors": -1 if report is None else int(report["issues"]["numErrors"]),
        }
        shapes, model = blend_shapes(project, doc["model"]["expressions"])
        written = arkit_weights(shapes, track_performance(doc, shapes.names).weights, model.face_mask)
        _codes, W, _rot = read_livelink_csv(csv)
        cols = [ARKIT_SHAPES.index(n) for n in shapes.names[: shapes.rig_shapes]]
        csv_out = {"frames": len(W), "max_abs_diff": float(np.abs(W[:, cols] - written).max())}
    return glb_out, csv_out


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--json", action="store_true", help="print one JSON object only")
    p.add_argument("--identities", type=int, default=5)
    p.add_argument("--frames", type=int, default=8, help="frames of the sample video to track")
    args = p.parse_args(argv)

    def log(msg):
        print(msg, file=sys.stderr if args.json else sys.stdout)

    out = {"rig": rig_section(args.identities, log=log)}
    out["glb"], out["csv_roundtrip"] = glb_and_csv_sections(args.frames, log=log)
    print(json.dumps(out, indent=None if args.json else 1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
