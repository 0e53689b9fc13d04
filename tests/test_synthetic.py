"""Tests of the ground-truth generator (photomodel/samples/synthetic.py) and of the sample project
it built (sample_projects/james). The generic→scan correspondence is built afresh once per run
(~9 s) and judged as the code stands; the cached one other tests read is compared with it."""

import json
from pathlib import Path

import numpy as np
import pytest
from trimesh.proximity import closest_point_naive

from photomodel.camera import PRESET_AZIMUTH_DEG, Camera, orbit_camera
from photomodel.data.cache import cache_dir
from photomodel.photos.reading import photo_size
from photomodel.project import load_project
from photomodel.samples import synthetic
from tracking.synthetic_sequences.expressions import (
    deformed_scan_vertices,
    expression_displacement,
    true_expression_geometry,
)

EXPRESSIONS = ("smile", "open_mouth", "brows_raised", "frown")
SAMPLE = Path(__file__).resolve().parents[1] / "sample_projects" / "james"

# How far regenerated 3D ground truth may be from the committed ground_truth.json. Not the file's
# rounding (1e-4 mm): the generator (closest points, smoothing, projection onto the scan) runs
# through numpy/scipy/trimesh, and other versions of those libraries, or another CPU's SIMD paths
# with the same versions, move its output: 0.0096 mm seen with other versions, 5e-6 mm with the
# versions in constraints.txt on the CPU that wrote the file, and on a CPU with AVX-512 (same
# versions, 2026-12-02) up to 0.066 mm on 4 of the 168 features (a closest point near a triangle
# edge of the scan), the median 5e-6 mm. The truth exists to score fits: their 3D feature errors
# are ~0.3 mm (1 px of click noise ≈ 0.3 mm; measured median 0.30 mm) and their bounds 1–2 mm. So
# a feature may move by 0.1 mm (3x below the smallest error the truth scores) and the median by
# 0.01 mm, while a real change of the generator is still caught (e.g. skipping the final
# projection onto the scan moves every point by 0.1–0.2 mm: the median).
GROUND_TRUTH_TOL_MM = 0.1
GROUND_TRUTH_MEDIAN_TOL_MM = 0.01


def assert_truth_current(stored: dict, regenerated: np.ndarray, features) -> None:
    """The committed 3D features ``stored`` (name → xyz) against ``regenerated`` (vertex rows)
    within the tolerances above."""
    d = np.array([np.linalg.norm(np.asarray(stored[f.name]) - regenerated[f.vertex]) for f in features])
    worst = features[int(np.argmax(d))].name
    assert d.max() <= GROUND_TRUTH_TOL_MM, f"{worst} moved {d.max():.4f} mm"
    assert np.median(d) <= GROUND_TRUTH_MEDIAN_TOL_MM, f"the features moved {np.median(d):.4f} mm (median)"


@pytest.fixture(scope="module")
def fresh(mesh, scan):
    """``(points, smooth_residual)`` of the correspondence made now, not read from the cache."""
    return synthetic.build_correspondence(mesh, scan)


@pytest.fixture(scope="module")
def truth(fresh):
    return fresh[0]


# ----------------------------------------------------------------------------- surface


def test_surface_distance_is_exact(scan):
    """Points pushed off the surface along the normal: our distance equals trimesh's
    brute-force closest point (exact to rounding) and is at most the push."""

    rng = np.random.default_rng(0)
    idx = rng.choice(len(scan.vertices), 300, replace=False)
    base = scan.vertices[idx]
    push = rng.uniform(-6.0, 6.0, size=(len(idx), 1))
    pts = base + push * synthetic.surface_normals(base, scan)
    d = synthetic.surface_distance(pts, scan)
    _, d_ref, _ = closest_point_naive(scan.welded, pts)
    np.testing.assert_allclose(d, d_ref, atol=1e-9)
    assert np.all(d <= np.abs(push[:, 0]) + 1e-9)


def test_surface_distance_rejects_bad_shape(scan):
    with pytest.raises(ValueError, match=r"\(n, 3\)"):
        synthetic.surface_distance(np.zeros((4, 2)), scan)


# ----------------------------------------------------------------------------- correspondence


def test_correspondence_lands_on_the_scan(mesh, scan, truth):
    assert truth.shape == mesh.vertices.shape
    d = synthetic.surface_distance(truth, scan)
    # after the final projection every vertex is on the surface up to rounding; the
    # landmarks sit on the scan's own landmarks, which are within 0.15 mm of it
    assert d.mean() < 0.5
    assert d.max() < 0.2
    np.testing.assert_array_equal(truth[mesh.landmarks], scan.landmarks)


def test_smooth_warp_already_fits_the_face(mesh, fresh):
    """The projection at the end must not do the work: before it, the smooth warp is
    already within a fraction of a millimetre of the scan over the face."""
    r = fresh[1]
    assert r[mesh.face_mask].mean() < 0.3
    assert np.median(r[mesh.face_mask]) < 0.1


def test_the_cached_correspondence_is_a_fresh_build(mesh, scan, fresh):
    """What true_correspondence serves (the cache, keyed on the code, the meshes and the libraries'
    versions) is what the code makes now, and it is kept under that key."""
    np.testing.assert_allclose(synthetic.true_correspondence(mesh, scan), fresh[0], atol=1e-9)
    np.testing.assert_allclose(synthetic.correspondence_residual(mesh, scan), fresh[1], atol=1e-9)
    assert (cache_dir() / f"true_correspondence-{synthetic.correspondence_key(mesh, scan)}.npz").is_file()


def test_correspondence_keeps_the_mesh_layout(mesh, truth):
    """Triangles keep their orientation (no fold-over) except in the few places where the
    template has geometry the scan lacks (nostrils, lip slit, eye sockets): < 2 %."""

    def normals(V):
        t = V[mesh.faces]
        c = np.cross(t[:, 1] - t[:, 0], t[:, 2] - t[:, 0])
        return c / np.maximum(np.linalg.norm(c, axis=1, keepdims=True), 1e-12)

    inside = mesh.face_mask[mesh.faces].all(axis=1)
    flipped = (normals(mesh.vertices) * normals(truth)).sum(1) < 0
    assert flipped[inside].mean() < 0.02


def test_extra_correspondences(mesh):
    extras = synthetic.extra_correspondences(mesh, 100, seed=3)
    assert list(extras) == [f"extra_{i:03d}" for i in range(100)]
    v = np.array(list(extras.values()))
    assert len(set(v)) == 100 and mesh.face_mask[v].all()
    lm = mesh.vertices[mesh.landmarks]
    assert np.linalg.norm(mesh.vertices[v][:, None] - lm[None], axis=2).min() >= 6.0
    assert extras == synthetic.extra_correspondences(mesh, 100, seed=3)  # deterministic
    # spread: no two extras closer than 4 mm (farthest-point sampling on a ~150 mm face)
    d = np.linalg.norm(mesh.vertices[v][:, None] - mesh.vertices[v][None], axis=2)
    assert d[~np.eye(100, dtype=bool)].min() > 4.0


# ----------------------------------------------------------------------------- rigs


def test_sample_rig(scan):
    cams = synthetic.rig("sample", 1000, 1000)
    assert len(cams) == 5
    az = [synthetic.azimuth_deg(c) for c in cams]
    np.testing.assert_allclose(az, [-75, -35, 0, 40, 80], atol=1.0)
    assert [round(c.focal_mm) for c in cams] == [35, 50, 85, 100, 70]
    assert [synthetic.preset_for(c) for c in cams] == [
        "right",
        "three_quarter_right",
        "front",
        "three_quarter_left",
        "left",
    ]
    for c in cams:
        uv = c.project(scan.landmarks)
        assert np.all((uv > 50) & (uv < 950)), "the face must be well inside every photo"
        face_height = np.ptp(uv[:, 1])
        assert face_height > 350, "the face should fill a good part of the frame"
    assert [len(synthetic.rig(n)) for n in (3, 5, 7)] == [3, 5, 7]
    assert synthetic.rig(3)[0].width == 1000
    with pytest.raises(ValueError, match="no rig with 4 cameras"):
        synthetic.rig(4)
    with pytest.raises(ValueError, match="unknown rig"):
        synthetic.rig("five")


def test_preset_for_is_nearest_azimuth():
    for name, az in PRESET_AZIMUTH_DEG.items():
        for jitter in (-20.0, 0.0, 20.0):
            cam = orbit_camera(az + jitter, 100, 100, target=synthetic.HEAD_CENTRE_MM)
            assert synthetic.preset_for(cam) == name


# ----------------------------------------------------------------------------- visibility


def test_visibility(mesh, scan, truth):
    cams = synthetic.rig("sample", 500, 500)
    front, left = cams[2], cams[4]  # left: +80°, at the subject's left
    names = ["nose_tip", "eye_r_outer", "eye_l_outer", "eye_l_inner"]
    pts = truth[[mesh.features[n] for n in names]]
    vf = dict(zip(names, synthetic.visible(front, pts, scan), strict=True))
    vl = dict(zip(names, synthetic.visible(left, pts, scan), strict=True))
    assert vf["nose_tip"] and vf["eye_r_outer"] and vf["eye_l_outer"]
    assert not vl["eye_r_outer"], "the far-side eye corner is hidden in an 80° side view"
    assert vl["eye_l_outer"]
    # the back of the skull, seen from the front: hidden (faces away)
    top = scan.vertices[scan.vertices[:, 1] > 100]
    back = top[np.argmin(top[:, 2])][None]
    assert not synthetic.visible(front, back, scan)[0]


def test_visibility_needs_a_matching_depth_map(scan):
    cam = synthetic.rig("sample", 100, 100)[2]
    with pytest.raises(ValueError, match="depth map"):
        synthetic.visible(cam, scan.landmarks, scan, depth=np.zeros((10, 10)))


# ----------------------------------------------------------------------------- the artist


def _random_camera_and_points(n=4000):
    cam = synthetic.rig("sample", 1000, 1000)[2]
    rng = np.random.default_rng(1)
    pts = synthetic.HEAD_CENTRE_MM + rng.uniform(-80, 80, size=(n, 3)) * [1, 1, 0.3] + [0, 0, 40]
    return cam, pts


def test_clicks_are_projections_plus_noise():
    cam, pts = _random_camera_and_points()
    vis = np.ones((2, len(pts)), bool)
    vis[1, ::3] = False
    clicks = synthetic.synthesize_clicks([cam, cam], pts, vis, noise_px=1.0, rng=5)
    assert clicks.shape == (2, len(pts), 2)
    assert np.isnan(clicks[1, ::3]).all() and not np.isnan(clicks[0]).any()
    err = clicks[0] - cam.project(pts)
    # 4000 samples per axis: the sample σ is within 5 % of 1 px with overwhelming odds
    np.testing.assert_allclose(err.std(axis=0), 1.0, atol=0.05)
    np.testing.assert_allclose(err.mean(axis=0), 0.0, atol=0.06)
    exact = synthetic.synthesize_clicks([cam], pts, vis[:1], noise_px=0.0)
    np.testing.assert_allclose(exact[0], cam.project(pts), atol=1e-9)
    # points outside the frame are clipped to it
    far = synthetic.synthesize_clicks([cam], np.array([[500.0, 0.0, 60.0]]), [[True]], 0.0)
    assert far[0, 0, 0] == cam.width - 1


def test_curve_follows_the_projection(mesh, scan, truth):
    cam = synthetic.rig("sample", 1000, 1000)[2]
    dense = synthetic.dense_true_curve(truth[mesh.curves["brow_r"]], scan)
    assert synthetic.surface_distance(dense, scan).max() < 1e-6
    proj = cam.project(dense)
    reversed_count = 0
    for seed in range(8):
        stroke = synthetic.synthesize_curve(cam, dense, 1.0, seed)
        assert 15 <= len(stroke) <= 40
        # every stroke point within 4 px of the projected curve (wobble RMS 1 px per axis)
        gap = np.linalg.norm(stroke[:, None] - proj[None], axis=2).min(axis=1)
        assert gap.max() < 4.0
        ends = np.linalg.norm(stroke[[0, -1]] - proj[[0, -1]], axis=1)
        if ends.max() > 10:
            reversed_count += 1
            ends = np.linalg.norm(stroke[[-1, 0]] - proj[[0, -1]], axis=1)
        assert ends.max() < 4.0  # drawn end to end
    assert 0 < reversed_count < 8  # some strokes are drawn backwards
    # clipped to the longest visible run
    vis = np.ones(len(dense), bool)
    vis[: len(dense) // 3] = False
    stroke = synthetic.synthesize_curve(cam, dense, 0.0, 0, visible=vis)
    hit = np.linalg.norm(stroke[:, None] - proj[None], axis=2).argmin(axis=1)
    assert hit.min() >= len(dense) // 3 - 1
    assert synthetic.synthesize_curve(cam, dense, 1.0, 0, visible=np.zeros(len(dense), bool)) is None


# ----------------------------------------------------------------------------- sample project


@pytest.fixture(scope="module")
def sample():
    project = load_project(SAMPLE / "james.facestudio.json")
    gt = json.loads((SAMPLE / "ground_truth.json").read_text())
    return project, gt


def test_sample_project_loads(sample, mesh):
    project, gt = sample
    project.check_vertices(len(mesh.vertices))
    project.check_photos(read_size=photo_size)
    assert len(project.feature_names(pose_only=True)) == 13
    assert len(project.features) == 13 + 55 + 100
    expr = project.expression("neutral")
    ids = ["right", "three_quarter_right", "front", "three_quarter_left", "left"]
    assert [p.id for p in expr.photos] == ids
    assert all(p.focal_mm_guess is None and p.preset == p.id for p in expr.photos)
    assert {c.name for c in project.curves} == set(mesh.curves)
    assert "chin" in expr.photo("front").curves
    # the other expressions: same rig (photo ids), JPEG photos, the neutral's cameras reused
    assert [e.name for e in project.expressions] == ["neutral", *EXPRESSIONS]
    for e in project.expressions[1:]:
        assert [p.id for p in e.photos] == ids and e.cameras_from == "neutral"
        assert all(p.path == f"photos/{e.name}_{p.id}.jpg" for p in e.photos)
    size = sum(p.stat().st_size for p in SAMPLE.rglob("*") if p.is_file())
    # measured: 4.2 MB of neutral PNGs, 2.7 MB for the 20 expression JPEGs (quality 92), 0.7 MB
    # of JSON, 0.15 MB of video
    jpeg = sum(project.photo_path(p).stat().st_size for e in project.expressions[1:] for p in e.photos)
    assert jpeg < 4e6 and size < 9e6, "the sample project must stay small"


def test_sample_clicks_agree_with_ground_truth(sample):
    for expression in ["neutral", *EXPRESSIONS]:
        _clicks_agree_with_ground_truth(*sample, expression)


def _clicks_agree_with_ground_truth(project, gt, expression):
    names = project.feature_names()
    obs = project.observations(expression)
    errors = []
    for i, photo in enumerate(project.expression(expression).photos):
        g = gt["expressions"][expression]["photos"][photo.id]
        clicked = [n for n in names if n in photo.points]
        assert clicked == [n for n in names if n in g["visible"]]
        cam = Camera.from_dict(g["camera"])
        true3d = np.array([gt["expressions"][expression]["features_3d"][n] for n in names])
        exact = np.array([g["points"][n] for n in names])
        np.testing.assert_allclose(cam.project(true3d), exact, atol=1e-3)  # file rounding
        seen = ~np.isnan(obs[i, :, 0])
        errors.append(obs[i, seen] - exact[seen])
    err = np.concatenate(errors)
    # σ = 1 px Gaussian noise: no click beyond 5σ, and ~600 samples give the RMS to ±10 %
    assert np.abs(err).max() < 5.0
    np.testing.assert_allclose(np.sqrt((err**2).mean(axis=0)), 1.0, atol=0.1)


def test_sample_ground_truth_is_current(sample, mesh, scan, truth):
    """The committed sample project matches what the current code would generate."""
    project, gt = sample
    photos = gt["expressions"]["neutral"]["photos"]
    for cam, (pid, g) in zip(synthetic.rig("sample"), photos.items(), strict=True):
        ref = Camera.from_dict(g["camera"])
        assert synthetic.preset_for(cam) == pid
        np.testing.assert_allclose(ref.R, cam.R, atol=1e-12)
        np.testing.assert_allclose(ref.t, cam.t, atol=1e-9)
    assert_truth_current(gt["features_3d"], truth, project.features)
    # every expression: the same rig, and the features where the expression field moves them
    geometry = true_expression_geometry(mesh, scan, ("neutral", *EXPRESSIONS))
    for k, expression in enumerate(("neutral", *EXPRESSIONS)):
        g = gt["expressions"][expression]
        for cam, (pid, p) in zip(synthetic.rig("sample"), g["photos"].items(), strict=True):
            assert synthetic.preset_for(cam) == pid
            np.testing.assert_allclose(Camera.from_dict(p["camera"]).R, cam.R, atol=1e-12)
        assert_truth_current(g["features_3d"], geometry[k], project.features)


@pytest.mark.parametrize("expression", ["neutral", "open_mouth"])
def test_sample_curves_follow_the_true_curves(expression, sample, mesh, scan):
    project, gt = sample
    k = 0 if expression == "neutral" else 1
    truth = true_expression_geometry(mesh, scan, ("neutral", expression))[k]
    surface = _expression_scan(scan, expression)
    for photo in project.expression(expression).photos:
        cam = Camera.from_dict(gt["expressions"][expression]["photos"][photo.id]["camera"])
        for name, stroke in photo.curves.items():
            proj = cam.project(synthetic.dense_true_curve(truth[mesh.curves[name]], surface))
            gap = np.linalg.norm(stroke[:, None] - proj[None], axis=2).min(axis=1)
            assert gap.max() < 4.5, f"{photo.id}/{name}"  # wobble RMS 1 px per axis


def _expression_scan(scan, name):
    if name == "neutral":
        return scan
    landmarks = scan.landmarks + expression_displacement(name, scan.landmarks, scan.landmarks)
    return synthetic.deformed_scan(scan, deformed_scan_vertices(scan, [1.0], [name]), landmarks)


def test_deformed_scan_has_its_own_surface(scan):
    """A scan in another expression: new vertices, its own welded surface, the original intact."""
    before = scan.vertices.copy()
    assert synthetic.surface_distance(scan.vertices[:50], scan).max() < 1e-9  # builds the neutral's surface
    moved = _expression_scan(scan, "open_mouth")
    assert moved is not scan
    np.testing.assert_array_equal(moved.faces, scan.faces)
    np.testing.assert_array_equal(scan.vertices, before)
    chin = np.argmin(np.linalg.norm(scan.vertices - scan.landmarks[8], axis=1))  # iBUG 8: the chin
    assert np.linalg.norm(moved.vertices[chin] - scan.vertices[chin]) > 5.0  # the jaw dropped
    # distances are measured to the moved surface, not to the cached neutral one
    assert synthetic.surface_distance(moved.vertices, moved).max() < 1e-9
    assert synthetic.surface_distance(moved.vertices[[chin]], scan)[0] > 3.0
    with pytest.raises(ValueError, match="vertices must be"):
        synthetic.deformed_scan(scan, scan.vertices[:10])


def test_ground_truth_per_expression():
    gt = synthetic.load_ground_truth(SAMPLE / "ground_truth.json")
    assert gt.expressions == ["neutral", *EXPRESSIONS]
    names = ["chin", "nose_tip", "brow_r_mid"]
    np.testing.assert_array_equal(gt.true_points(names), gt.true_points(names, "neutral"))  # old API: neutral
    drop = gt.true_points(["chin"], "open_mouth") - gt.true_points(["chin"])
    assert drop[0, 1] < -10.0  # the chin moves ~17 mm down (tracking.synthetic_sequences.expressions.JAW_ANGLE_DEG)
    # the smile's Gaussian falloff (σ 11 mm about the mouth corners) leaves the nose tip in place
    np.testing.assert_allclose(gt.true_points(["nose_tip"], "smile"), gt.true_points(["nose_tip"]), atol=1e-3)
    assert gt.visible["smile"]["front"] and gt.cameras["frown"].keys() == gt.cameras["neutral"].keys()
    with pytest.raises(KeyError, match="no ground truth for expression 'grin'"):
        gt.true_points(["chin"], "grin")
