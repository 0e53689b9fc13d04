"""A fit from automatic landmarks on views close together (photomodel.modeling.fit with
camera_solve.person_depth_prior): renders of the james scan from near the front, whose depth is
known — the scan itself, matched vertex for vertex onto the generic mesh
(:func:`photomodel.samples.synthetic.true_correspondence`) — and whose lens is known."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from photomodel.alignment import similarity_transform
from photomodel.camera import orbit_camera
from photomodel.modeling.camera_solve import DEPTH_ONLY, PERSON_PRIOR
from photomodel.modeling.fit import FitOptions, fit_expression, views_apart_deg
from photomodel.modeling.generic_mesh import load_generic_mesh
from photomodel.photos.intake import default_features, new_project_from_photos
from photomodel.samples import synthetic
from photomodel.samples.sample_data import load_james_scan
from tracking.auto_pipeline import depth_ratio

#: Views of the scan, degrees of yaw: 30° from one side to the other, as frames of a clip turning
#: a little (the real sample's clip: ±13° by the detector).
YAWS = (-15.0, 0.0, 15.0)
#: The renders: 1000², a 60 mm lens (36 mm wide sensor) at 700 mm, as benchmarks/autofit.py's.
SIZE, FOCAL_MM, DISTANCE_MM = 1000, 60.0, 700.0


@pytest.fixture(scope="module")
def near_frontal(tmp_path_factory):
    """A project of the renders with automatic landmarks only, the generic mesh, the scan."""
    folder = tmp_path_factory.mktemp("narrow")
    mesh, scan = load_generic_mesh(), load_james_scan()
    paths = []
    for i, yaw in enumerate(YAWS):
        cam = orbit_camera(yaw, SIZE, SIZE, distance_mm=DISTANCE_MM, focal_mm=FOCAL_MM, target=synthetic.HEAD_CENTRE_MM)
        color = synthetic.render_scan(cam, scan, background=0.45, supersample=3).color
        rgb = (np.clip(color, 0.0, 1.0) * 255.0 + 0.5).astype(np.uint8)
        paths.append(folder / f"view{i}.png")
        cv2.imwrite(str(paths[-1]), cv2.cvtColor(rgb, cv2.COLOR_RGB2BGR))
    features, curves = default_features(mesh)
    project, _ = new_project_from_photos(paths, folder / "p.facestudio.json", features=features, curves=curves)
    return project, mesh, scan


def _mesh_to_scan_mm(vertices, points, names, mesh, scan, truth) -> float:
    """Mean distance (mm) of the face region of ``vertices`` (N, 3) to the scan after the similarity
    that maps ``points`` (n, 3), the features ``names``, onto their true positions (as
    benchmarks/autofit.py scores a fit)."""
    s, R, t = similarity_transform(points, truth.true_points(names))
    return float(synthetic.surface_distance((vertices @ (s * R).T + t)[mesh.face_mask], scan).mean())


def _scored(fit, mesh, scan, truth) -> float:
    names = [n for n in fit.feature_names if n in truth.features_3d]
    points = fit.points_3d[[fit.feature_names.index(n) for n in names]]
    return _mesh_to_scan_mm(fit.vertices, points, names, mesh, scan, truth)


@pytest.mark.slow
def test_views_close_together_take_the_depth_from_the_person_prior(near_frontal, sample_truth):
    project, mesh, scan = near_frontal
    true_depth = depth_ratio(synthetic.true_correspondence(mesh, scan), mesh)  # the scan's: 0.91x
    true_focal = SIZE * FOCAL_MM / 36.0

    fit = fit_expression(project, "neutral", mesh, FitOptions())
    alone = fit_expression(project, "neutral", mesh, FitOptions(person_prior=False))
    assert views_apart_deg(fit.cameras) < 40.0  # the rule's "close together"
    assert f"{PERSON_PRIOR} ({DEPTH_ONLY})" in fit.report["camera_solve"]["start"]
    assert PERSON_PRIOR not in alone.report["camera_solve"]["start"]

    # measured 2026-12-04: the clicks alone 1.11x (0.20 over the scan's 0.91x), focal 828 px (half
    # the true 1667), 1.87 mm from the scan; with the prior (2.1 mm along the front axis) 0.98x,
    # 1397 px, 1.34 mm; the generic head 1.46 mm. 2026-12-05, the prior's 8 mm
    # (DEPTH_ONLY_SIGMA_MM): 1.04x (0.13 over the scan's). Bounds with room for the detector's
    # wobble, each one the clicks alone fail.
    depth, depth_alone = depth_ratio(fit.vertices, mesh), depth_ratio(alone.vertices, mesh)
    assert abs(depth - true_depth) < 0.16
    assert abs(depth - true_depth) < abs(depth_alone - true_depth)
    assert abs(fit.cameras[0].f / true_focal - 1.0) < 0.3
    fit_mm, alone_mm = _scored(fit, mesh, scan, sample_truth), _scored(alone, mesh, scan, sample_truth)
    names = [n for n in fit.feature_names if n in sample_truth.features_3d]  # moved by the same features
    vertex = {f.name: f.vertex for f in project.features}
    generic_mm = _mesh_to_scan_mm(
        mesh.vertices, mesh.vertices[[vertex[n] for n in names]], names, mesh, scan, sample_truth
    )
    assert fit_mm < alone_mm
    assert fit_mm < generic_mm  # a fit nearer the scan than the generic head, which the clicks alone are not
    assert fit.report["rms_px"] < 3.0
