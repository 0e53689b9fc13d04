"""Several expressions of one subject (photomodel/fit.py, ``cameras_from``), scored against the truth.

The sample project photographs the james scan in five expressions with one 5-camera rig: the
neutral (PNG) and four smooth deformations of the scan (tracking/expressions.py; JPEG, quality
92). The four reuse the neutral's fitted cameras (``cameras_from: "neutral"``), so their meshes
land in the neutral fit's frame, vertex for vertex comparable with it — what the blend-shape
model of §6.1.1 needs. Truth: ground_truth.json (true 3D features per expression) and the scan
deformed by the same field (surface distances).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from photomodel.alignment import similarity_transform
from photomodel.errors import FitError
from photomodel.modeling.fit import FitOptions, fit_expression, fit_order, source_cameras
from photomodel.project import ExpressionResult, load_project
from photomodel.samples.synthetic import deformed_scan, surface_distance
from tracking.synthetic_sequences.expressions import (
    deformed_scan_vertices,
    expression_displacement,
    true_expression_geometry,
)

SAMPLE_PROJECT = Path(__file__).resolve().parents[1] / "sample_projects" / "james"
PROJECT = SAMPLE_PROJECT / "james.facestudio.json"
EXPRESSIONS = ("smile", "open_mouth", "brows_raised", "frown")
#: iBUG-68 landmarks that each expression moves (mouth corners 48/54, chin 8, lower lip 57,
#: brows 17–26) and landmarks it leaves still (eye corners 36/39/42/45, nose tip 30).
MOVED = {
    "smile": [48, 54],
    "open_mouth": [8, 48, 54, 57],
    "brows_raised": list(range(17, 27)),
    "frown": list(range(17, 27)),
}
STILL = [30, 36, 39, 42, 45]


def _with_result(project, name, result):
    """Put a fit into the project in memory (what the CLI and the studio do before saving)."""
    project.expression(name).result = ExpressionResult(
        cameras=dict(zip(result.photo_ids, result.cameras, strict=True)),
        points_3d=dict(zip(result.feature_names, result.points_3d, strict=True)),
        report=result.report,
    )


@pytest.fixture(scope="module")
def neutral(mesh, sample_truth):
    """The sample project with its neutral fitted (once per module), the neutral's FitResult, and
    the similarity (s, R, t) taking the neutral fit's frame onto the true head frame."""
    project = load_project(PROJECT)
    result = fit_expression(project, "neutral", mesh)
    _with_result(project, "neutral", result)
    sim = similarity_transform(result.points_3d, sample_truth.true_points(result.feature_names))
    return project, result, sim


@pytest.fixture(scope="module")
def fits(neutral, mesh):
    """Each expression fitted with the neutral's cameras, fitted on first use."""
    project = neutral[0]
    cache = {}

    def get(name):
        if name not in cache:
            cache[name] = fit_expression(project, name, mesh)
        return cache[name]

    return get


def expression_scan(scan, name):
    """The james scan in expression ``name``: the true surface of that expression."""
    landmarks = scan.landmarks + expression_displacement(name, scan.landmarks, scan.landmarks)
    return deformed_scan(scan, deformed_scan_vertices(scan, [1.0], [name]), landmarks)


def test_sample_project_reuses_the_neutral_cameras():
    project = load_project(PROJECT)
    assert [e.name for e in project.expressions] == ["neutral", *EXPRESSIONS]
    assert [e.cameras_from for e in project.expressions] == [None] + ["neutral"] * 4
    assert fit_order(project) == ["neutral", *EXPRESSIONS]


def test_fit_takes_the_cameras_of_the_fitted_neutral(neutral, fits):
    project, n, _ = neutral
    r = fits("smile")
    assert r.cameras_from == r.report["cameras_from"] == "neutral"
    assert r.photo_ids == n.photo_ids
    for a, b in zip(r.cameras, n.cameras, strict=True):  # the very cameras, untouched
        np.testing.assert_array_equal(a.R, b.R)
        np.testing.assert_array_equal(a.t, b.t)
        assert a.f == b.f
    assert r.report["bundle"] is None and r.report["pose"]["sweeps"] == 0
    # triangulated with the neutral's cameras: residuals are the 1 px click noise (measured
    # 1.03–1.23 px RMS on the pose features, 1.11–1.14 px on all), not a camera mismatch
    assert r.report["pose"]["rms_px"] < 1.5 and r.report["rms_px"] < 1.5
    assert len(r.feature_names) > 150


@pytest.mark.parametrize("name", EXPRESSIONS)
def test_expression_mesh_is_close_to_its_true_surface(name, neutral, fits, mesh, scan):
    """Mean distance over the face from the fitted expression mesh to the deformed scan.

    The mesh is moved into the true head frame by the *neutral's* similarity: with shared
    cameras the expression has no gauge of its own. Measured 0.73 (smile), 0.74 (open_mouth),
    0.78 (brows_raised), 0.75 mm (frown) — the neutral's own 0.73 mm: the same clicks, noise and
    generic mesh. 1.0 mm leaves room for another noise draw; the issue's bar is 2 mm.
    """
    _, n, (s, R, t) = neutral
    face = mesh.face_mask
    surface = expression_scan(scan, name)
    fitted = surface_distance(fits(name).vertices[face] @ (s * R).T + t, surface)
    assert fitted.mean() < 1.0, fitted.mean()
    if name == "open_mouth":
        # the jaw drop is big enough to show in the whole-face mean: the neutral mesh is 1.18 mm
        # from the open-mouth surface, the fit 0.74 mm
        still = surface_distance(n.vertices[face] @ (s * R).T + t, surface)
        assert fitted.mean() < still.mean() - 0.25


@pytest.mark.parametrize("name", EXPRESSIONS)
def test_displacement_from_the_neutral_matches_the_truth(name, neutral, fits, mesh, scan):
    """What a blend-shape model uses: fitted expression − fitted neutral, per generic vertex.

    True displacements: 6.3 mm at the smile's mouth corners, 18.5 mm at the open mouth's chin,
    5.8 / 4.4 mm at the raised / frowning brows. The error at a vertex is the difference of two
    fits' errors (~0.3 mm per pixel of click noise each, smoothed by the RBF); measured: moved
    landmarks ≤ 1.21 mm (mean 0.43–0.79 mm), still ones ≤ 1.61 mm (smile's, 1.04 mm at most in
    the others). Bounds: 2 mm at a moved landmark, mean 1.2 mm, and 2.5 mm at a still one.
    """
    _, n, (s, R, t) = neutral
    geometry = true_expression_geometry(mesh, scan, ("neutral", name))
    true_disp = geometry[1] - geometry[0]
    fit_disp = (fits(name).vertices - n.vertices) @ (s * R).T  # in true-frame mm
    moved = mesh.landmarks[MOVED[name]]
    still = mesh.landmarks[STILL]
    err_moved = np.linalg.norm(fit_disp[moved] - true_disp[moved], axis=1)
    err_still = np.linalg.norm(fit_disp[still] - true_disp[still], axis=1)
    assert np.linalg.norm(true_disp[moved], axis=1).min() > 3.0  # the test sees a real motion
    assert err_moved.max() < 2.0, err_moved
    assert err_moved.mean() < 1.2, err_moved
    assert err_still.max() < 2.5, err_still


def test_expression_features_match_their_true_positions(neutral, fits, sample_truth):
    """The triangulated 3D features against ground_truth.json's per-expression positions."""
    _, _, (s, R, t) = neutral
    r = fits("open_mouth")
    err = np.linalg.norm(r.points_3d @ (s * R).T + t - sample_truth.true_points(r.feature_names, "open_mouth"), axis=1)
    # triangulated from ≥ 2 photos with 1 px noise at ~0.3 mm/px: measured median 0.30 mm, mean
    # 0.34 mm (0.30–0.34 in every expression); bounds at about twice that
    assert np.median(err) < 0.75 and err.mean() < 1.0, (np.median(err), err.mean())
    # and they are not the neutral's: the chin moved 18 mm
    chin = r.feature_names.index("chin")
    assert np.linalg.norm(sample_truth.true_points(["chin"], "open_mouth") - sample_truth.true_points(["chin"])) > 15.0
    assert np.linalg.norm(r.points_3d[chin] @ (s * R).T + t - sample_truth.true_points(["chin"], "open_mouth")) < 2.0


def test_independent_fit_still_works(mesh, scan, sample_truth):
    """Without cameras_from, an expression recovers its own cameras (and gauge) like any other."""
    project = load_project(PROJECT)  # the neutral is not fitted: nothing to borrow
    r = fit_expression(project, "smile", mesh, FitOptions(independent_cameras=True))
    assert r.cameras_from is None and r.report["cameras_from"] is None
    assert r.report["bundle"] is not None and r.report["pose"]["sweeps"] > 0
    s, R, t = similarity_transform(r.points_3d, sample_truth.true_points(r.feature_names, "smile"))
    d = surface_distance(r.vertices[mesh.face_mask] @ (s * R).T + t, expression_scan(scan, "smile"))
    assert d.mean() < 1.0, d.mean()  # measured 0.746 mm (0.73 mm with the neutral's cameras)


def test_unfitted_source_is_a_clear_error(mesh):
    project = load_project(PROJECT)
    with pytest.raises(FitError, match="takes its cameras from expression 'neutral', which is not fitted yet"):
        fit_expression(project, "smile", mesh)


def test_photo_without_a_source_camera_is_a_clear_error(neutral, mesh):
    project = load_project(PROJECT)
    project.expression("neutral").result = neutral[0].expression("neutral").result
    photo = project.expression("frown").photo("front")
    photo.id = "frown_front"  # another id, the same view: matched by its view (preset)
    front = project.expression("neutral").result.cameras["front"]
    got = source_cameras(project, "frown", "neutral")[project.expression("frown").photos.index(photo)]
    np.testing.assert_array_equal(got.R, front.R)
    photo.preset = "left"  # two "left" photos: the view no longer names one camera
    with pytest.raises(FitError, match=r"no fitted camera for photo\(s\) 'frown_front' \(photos are matched by id"):
        fit_expression(project, "frown", mesh)
    photo.id, photo.preset = "front", "front"
    project.expression("frown").photos[2].width = 800
    with pytest.raises(FitError, match="photo 'front' is 800x1000 but the camera"):
        source_cameras(project, "frown", "neutral")


def test_options_override_the_project_setting(neutral, mesh):
    project = neutral[0]
    with pytest.raises(FitError, match="takes its cameras from 'grin'.*no expression 'grin'"):
        fit_expression(project, "smile", mesh, FitOptions(cameras_from="grin"))
    with pytest.raises(FitError, match="cannot take its cameras from itself"):
        fit_expression(project, "smile", mesh, FitOptions(cameras_from="smile"))


def test_fit_order_puts_sources_first():
    project = load_project(PROJECT)
    assert fit_order(project, ["smile", "neutral", "frown"]) == ["neutral", "smile", "frown"]
    assert fit_order(project, ["frown"]) == ["frown"]  # the source is not asked for: left to the fit
    project.expression("smile").cameras_from = "frown"  # a chain: neutral → frown → smile
    assert fit_order(project, ["smile", "frown", "neutral"]) == ["neutral", "frown", "smile"]
    project.expression("neutral").cameras_from = "smile"  # in memory only: files cannot hold a cycle
    with pytest.raises(FitError, match="cycle"):
        fit_order(project)
