"""The modeling pipeline of §5.1: pose recovery → scattered-data interpolation → refinement.

``fit_expression`` takes a project, the name of one expression (a set of photos of one
facial expression taken with one rig) and the generic face mesh, and returns the
recovered cameras, the 3D feature points and the fitted mesh:

1. **Pose recovery** (§5.1.1, Appendix A) from the ``pose`` features (the initial ~13
   clicks), starting from each photo's rough preset camera and the generic mesh's
   feature vertices (:func:`photomodel.modeling.pose.recover_poses`).
2. **Gauge.** Structure from motion recovers the scene only up to a similarity; we fix
   it by aligning the recovered feature points onto the generic mesh's (Umeyama,
   with scale), so results live in the generic head's frame and at its size
   (photographs alone carry no absolute scale). *Beyond the paper*, which leaves the
   gauge to the initial guess.
3. **Scattered-data interpolation** (§5.1.2, Eq. 3): the generic mesh is deformed so
   the feature vertices land on the recovered points (:mod:`photomodel.modeling.rbf`).
4. **Refinement** (§5.1.3): with the cameras fixed, the other clicked correspondences
   are triangulated, hand-drawn curves are converted into per-vertex observations by
   arc length and triangulated too (:mod:`photomodel.modeling.refine`), and the RBF is re-run
   from the generic mesh with every constraint. Curves are re-parameterised on the
   refined mesh and the step repeated ``curve_passes`` times.

**Several expressions** (§5.1 photographs every expression with the same cameras). An
expression whose ``cameras_from`` names another, already fitted, expression (or
``FitOptions.cameras_from``) skips steps 1–2: it takes that expression's fitted cameras photo
by photo id, triangulates its pose features with them (:func:`photomodel.modeling.refine.triangulate`)
and keeps their frame — no gauge onto the generic mesh — so its mesh lies in the source
expression's head frame, vertex for vertex comparable with it (what a blend-shape model,
§6.1.1, needs). Steps 3–4 are as usual; the cameras stay fixed (no ``bundle_all``).
:func:`fit_order` sorts expressions so that sources are fitted first.

**One photo** (beyond the paper): steps 1–2 place its camera against the generic head
(:func:`photomodel.modeling.camera_solve.solve_cameras`), every clicked feature it is sure of
deforms the mesh at the generic head's depth, and the features the photo does not show are held
where the generic head has them (:attr:`_CameraStage.anchor_idx`); docs/modeling.md, "One photo".

No file I/O happens here; :func:`photomodel.project.results.store_fit_result` stores a result in a project.
"""

from __future__ import annotations

import re
from collections.abc import Callable
from dataclasses import dataclass, field, replace

import numpy as np

from photomodel.alignment import similarity_transform, transform_cameras
from photomodel.camera import PRESET_AZIMUTH_DEG, Camera, focal_mm_to_px, preset_camera
from photomodel.errors import FitError, ProjectError
from photomodel.modeling.camera_solve import (
    DEPTH_HELD,
    DETECTOR_SIGMA_MM,
    PERSON_PRIOR,
    PERSON_SIGMA_MM,
    solve_cameras,
)
from photomodel.modeling.checklist import require_clicks
from photomodel.modeling.pose import PoseResult, recover_poses, reprojection_residuals
from photomodel.modeling.rbf import deform_vertices
from photomodel.modeling.refine import refine_points, triangulate

#: Default distance of a preset camera from the head (mm) when the project gives none.
PRESET_DISTANCE_MM = 600.0
#: Default lens of a preset camera (mm, 36 mm-wide sensor) when the photo gives no guess.
PRESET_FOCAL_MM = 50.0


class Cancelled(Exception):
    """Raised inside :func:`fit_expression` when the caller's ``cancel()`` returns True."""


@dataclass
class FitOptions:
    refine: bool = True
    curve_passes: int = 2
    fixed_focal: bool = False
    max_sweeps: int = 500
    #: Beyond the paper: after refinement, re-estimate the cameras (and points) with every
    #: triangulated correspondence, not only the pose features, then refine once more. The
    #: paper keeps the cameras from the ~13 pose features because extra correspondences may
    #: be less precise; on the sample project the extra ~150 clicks cut the worst camera
    #: rotation error from 1.6° to 0.4° and the focal error from ≤ 14 % to ≤ 4 %.
    bundle_all: bool = True
    #: Fit with the cameras of this (fitted) expression instead of the project's
    #: ``Expression.cameras_from`` setting; None: use the project's setting.
    cameras_from: str | None = None
    #: Recover this expression's own cameras even if the project gives it ``cameras_from``.
    independent_cameras: bool = False
    #: Weigh each automatic click in the camera solve by the detector's confidence squared
    #: (:func:`click_weights`; the artist's clicks 1): True, False, or None (the default) for
    #: :func:`weigh_auto_clicks`'s rule — on when the photos with automatic clicks are of views
    #: at least :data:`WEIGH_FROM_SPREAD_DEG` apart. Measured both ways: on
    #: the james sample's five photos (three-quarter views at ±35–40°, profiles) the outline
    #: points, silhouette rather than skin points, pulled the three-quarter cameras 7–9° towards
    #: the front and weighing them down took the auto fit's mesh from 2.32 to 2.07 mm mean over 8
    #: jittered copies of the photos (every copy better); on the real-footage sample (frames of one
    #: clip at ±13°) it made the face shallower (depth 1.08× → 0.90× of the generic head's, focal
    #: 585 → 469 px) and tracking the clip with that model was worse on all three figures the
    #: footage gives (projected features vs the detector 3.91 → 4.02 px, rotation jitter 0.39° →
    #: 0.49°, image RMS 0.102 → 0.105). Photo sets of wide yaw gain; footage frames near the front
    #: lose. With the automatic eyelid and lip curves (2026-12) the same: the sample 2.10 → 1.76 mm
    #: (8 jittered draws 2.18 → 1.89 mean, every draw better), the real clip's tracking 3.98 →
    #: 4.07 px, jitter 0.41° → 0.48°. ``facestudio fit --weigh-auto-clicks`` /
    #: ``--no-weigh-auto-clicks`` overrule the rule. Weighed, the answer is also the most probable
    #: face under the person prior (:attr:`person_prior`).
    weigh_auto_clicks: bool | None = None
    #: Where the automatic clicks are weighed (and always with one photo), the answer is the most
    #: probable face under the person prior: the camera solve's
    #: :func:`~photomodel.modeling.camera_solve._map_estimate` and the refinement's
    #: :func:`_weigh_auto_targets`. False: the weighed clicks are fitted as they are (maximum
    #: likelihood), as before 2026-12; the sample's auto fit then follows the detector's error
    #: (1.69 against 1.31 mm from the scan). ``facestudio fit --no-person-prior``.
    person_prior: bool = True


@dataclass
class FitResult:
    """What the modeling pipeline recovers for one expression.

    Attributes
    ----------
    photo_ids : list[str], order of ``cameras``.
    cameras : list[Camera], one per photo.
    feature_names : list[str], the features with a 3D position.
    points_3d : (n, 3) float mm, recovered/triangulated feature positions.
    initial_vertices : (N, 3) float mm, the generic mesh deformed by the pose features only.
    vertices : (N, 3) float mm, the fitted mesh after refinement.
    pose : PoseResult of the pose-recovery stage (in the fixed gauge); with ``cameras_from``,
        the triangulation of the pose features with the fixed cameras (0 sweeps).
    report : dict, reprojection report (JSON-serialisable); ``report["cameras_from"]`` names
        the expression whose cameras were reused (None when they were recovered).
    cameras_from : str or None, the expression whose fitted cameras this fit reused.
    """

    photo_ids: list[str]
    cameras: list[Camera]
    feature_names: list[str]
    points_3d: np.ndarray
    initial_vertices: np.ndarray
    vertices: np.ndarray
    pose: PoseResult
    report: dict = field(default_factory=dict)
    cameras_from: str | None = None

    def camera(self, photo_id: str) -> Camera:
        return self.cameras[self.photo_ids.index(photo_id)]


def initial_cameras(photos) -> list[Camera]:
    """The artist's rough starting cameras: each photo's preset at a default distance/lens."""
    cams = []
    for p in photos:
        focal = p.focal_mm_guess or PRESET_FOCAL_MM
        c = preset_camera(p.preset, p.width, p.height, distance_mm=PRESET_DISTANCE_MM, focal_mm=focal)
        # keep the lens guess as a focal in pixels of this photo
        c.f = focal_mm_to_px(focal, p.width)
        cams.append(c)
    return cams


def cameras_source(project, expression_name: str, options: FitOptions | None = None) -> str | None:
    """The expression whose fitted cameras ``expression_name`` is fitted with, or None.

    ``options.cameras_from`` wins over the project's ``Expression.cameras_from``;
    ``options.independent_cameras`` turns both off.
    """
    opt = options or FitOptions()
    if opt.independent_cameras:
        return None
    if opt.cameras_from is not None:
        return opt.cameras_from
    return project.expression(expression_name).cameras_from


def fit_order(project, names=None) -> list[str]:
    """``names`` (default: every expression) ordered so that an expression comes after the
    expression it takes its cameras from (``cameras_from``) when both are to be fitted;
    otherwise the project's order is kept (a stable topological sort).

    Raises
    ------
    FitError
        if ``cameras_from`` goes round in a cycle (a loaded project cannot have one).
    """
    names = [e.name for e in project.expressions] if names is None else list(names)
    wanted = set(names)
    order: list[str] = []
    state: dict[str, int] = {}  # 1 = being placed, 2 = placed

    def place(name: str, path: list[str]) -> None:
        if state.get(name) == 2:
            return
        if state.get(name) == 1:
            raise FitError("cameras_from goes round in a cycle: " + " → ".join(path + [name]))
        state[name] = 1
        src = project.expression(name).cameras_from
        if src is not None and src in wanted:
            place(src, path + [name])
        state[name] = 2
        order.append(name)

    for n in names:
        place(n, [])
    return order


def source_cameras(project, expression_name: str, source: str) -> list[Camera]:
    """The fitted cameras of expression ``source`` for the photos of ``expression_name``,
    matched by photo id, else by the view (``preset``) when each expression has one photo of it.

    Raises
    ------
    FitError
        naming the problem: ``source`` is the expression itself, does not exist, is not
        fitted yet, or lacks a camera for one of the photos (or has one of another image size).
    """

    if source == expression_name:
        raise FitError(f"expression {expression_name!r} cannot take its cameras from itself")
    try:
        src = project.expression(source)
    except ProjectError as exc:
        raise FitError(f"expression {expression_name!r} takes its cameras from {source!r}: {exc}") from None
    if src.result is None or not src.result.cameras:
        raise FitError(
            f"expression {expression_name!r} takes its cameras from expression {source!r}, which is not "
            f"fitted yet: fit {source!r} first"
        )
    # a rig position is a photo id, or else the view the artist gave both photos (its preset)
    # when that view is unique in both expressions: photos added from files named after their
    # expression ("smile_front.jpg") get their own ids
    photos = project.expression(expression_name).photos
    by_preset = {}
    for view in {q.preset for q in src.photos}:
        theirs = [q.id for q in src.photos if q.preset == view and q.id in src.result.cameras]
        if len(theirs) == 1 and sum(q.preset == view for q in photos) == 1:
            by_preset[view] = theirs[0]
    cams, missing = [], []
    for p in photos:
        cam = src.result.cameras.get(p.id)
        if cam is None and p.preset in by_preset:
            cam = src.result.cameras[by_preset[p.preset]]
        if cam is None:
            missing.append(p.id)
            continue
        if (cam.width, cam.height) != (p.width, p.height):
            raise FitError(
                f"expression {expression_name!r}, photo {p.id!r} is {p.width}x{p.height} but the camera of "
                f"photo {p.id!r} of expression {source!r} is {cam.width}x{cam.height}: not the same camera"
            )
        cams.append(Camera(np.array(cam.R, float), np.array(cam.t, float), float(cam.f), cam.width, cam.height))
    if missing:
        raise FitError(
            f"expression {expression_name!r} takes its cameras from expression {source!r}, which has no "
            f"fitted camera for photo(s) {', '.join(repr(m) for m in missing)} (photos are matched by id, or by "
            f"view when each expression has one photo of that view; "
            f"{source!r} has {', '.join(repr(k) for k in src.result.cameras)})"
        )
    return cams


def _fixed_camera_pose(cameras, obs_pose, pose_names, photo_ids):
    """Pose stage with known cameras: triangulate the pose features (§5.1.3 with the cameras
    fixed). Returns ``(PoseResult, kept (n,) bool, dropped messages)``."""

    tri = triangulate(cameras, obs_pose)
    kept = tri.ok
    problems = tri.problems(pose_names)
    dropped = [f"pose feature {why}" for why in problems.values()]
    if kept.sum() < 4:
        raise FitError(
            f"only {int(kept.sum())} pose feature(s) could be triangulated with the fixed cameras (need 4): "
            + "; ".join(problems.values())
        )
    res = reprojection_residuals(cameras, tri.points[kept], obs_pose[:, kept])
    per_view, per_point, rms = _rms(res, axis=1), _rms(res, axis=0), _rms(res)
    pose = PoseResult(
        cameras=list(cameras),
        points=tri.points[kept],
        iterations=0,
        converged=True,
        rms_px=float(rms),
        per_view_rms_px=per_view,
        per_point_rms_px=per_point,
        residuals_px=res,
    )
    return pose, kept, dropped


def _rms(res: np.ndarray, axis=None) -> np.ndarray:
    sq = np.nansum(res**2, axis=-1)
    cnt = np.sum(np.isfinite(res[..., 0]), axis=axis)
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.sqrt(np.nansum(sq, axis=axis) / cnt)


def _reproject(cameras: list[Camera], points: np.ndarray, obs: np.ndarray) -> np.ndarray:
    proj = np.stack([c.project(points) for c in cameras])
    return proj - obs


@dataclass
class _CameraStage:
    """What the camera stage hands on: cameras and the pose features' 3D points in the fit's
    frame, plus what the report says about them."""

    cameras: list[Camera]
    pose: PoseResult
    pose_names: list[str]
    pose_idx: np.ndarray
    pose_points: np.ndarray
    dropped: list[str] = field(default_factory=list)
    suspects: list[dict] = field(default_factory=list)
    excluded: np.ndarray | None = None  # (k, features) clicks left out, project.features order
    camera_report: dict = field(default_factory=dict)
    bundle_report: dict | None = None
    #: one photo: vertices of the features it does not show (the far side of a profile), held
    #: where the generic head has them after the similarity onto the clicked ones — without
    #: them the deformation extrapolates from one side (a profile's mesh came out 6 mm from the
    #: scan, the far side sheared)
    anchor_idx: np.ndarray | None = None
    anchor_points: np.ndarray | None = None

    def constraints(self, idx=None, points=None) -> tuple[np.ndarray, np.ndarray]:
        """The deformation's centres and targets: the pose features', then ``idx`` / ``points``
        (refinement targets), then the anchors no target replaces."""
        idx_all = self.pose_idx if idx is None else np.concatenate([self.pose_idx, idx])
        pts_all = self.pose_points if points is None else np.concatenate([self.pose_points, points])
        if self.anchor_idx is None:
            return idx_all, pts_all
        free = ~np.isin(self.anchor_idx, idx_all)
        return (np.concatenate([idx_all, self.anchor_idx[free]]), np.concatenate([pts_all, self.anchor_points[free]]))


def _check_inputs(project, expr, mesh, curve_mesh) -> tuple[dict, np.ndarray | None]:
    """Feature → vertex map and the curve mesh as an array, or a FitError naming the problem."""
    if not expr.photos:
        raise FitError(f"expression {expr.name!r} has no photo; add photos of it to fit it")
    n_vertices = len(mesh.vertices)
    if curve_mesh is not None:
        curve_mesh = np.asarray(curve_mesh, dtype=float)
        if curve_mesh.shape != mesh.vertices.shape:
            raise FitError(f"curve_mesh has shape {curve_mesh.shape}, the generic mesh {mesh.vertices.shape}")
    feat_vertex = {f.name: int(f.vertex) for f in project.features}
    bad = [n for n, v in feat_vertex.items() if not 0 <= v < n_vertices]
    if bad:
        raise FitError(f"feature(s) {', '.join(bad)} refer to vertices outside the generic mesh (0..{n_vertices - 1})")
    if not any(f.pose for f in project.features):
        raise FitError("no feature is marked for pose recovery (features[].pose = true)")
    return feat_vertex, curve_mesh


def _cameras_of_source(project, expression_name, source, feat_vertex) -> _CameraStage:
    """Cameras of another, fitted expression (same rig): triangulate the pose features, keep its frame."""
    pose_names = [f.name for f in project.features if f.pose]
    photo_ids = [p.id for p in project.expression(expression_name).photos]
    cameras = source_cameras(project, expression_name, source)
    obs_pose = project.observations(expression_name, pose_names)
    pose, kept, dropped = _fixed_camera_pose(cameras, obs_pose, pose_names, photo_ids)
    pose_names = [n for n, k in zip(pose_names, kept, strict=True) if k]
    pose_idx = np.array([feat_vertex[n] for n in pose_names])
    return _CameraStage(cameras, pose, pose_names, pose_idx, pose.points, dropped)


def _cameras_robust(project, expression_name, mesh, opt, feat_vertex) -> _CameraStage:
    """Every feature clicked in ≥ 2 photos places the cameras (photomodel.modeling.camera_solve:
    cheap starts, the paper's ALS, robust polish, suspects named and left out); the gauge is the
    similarity of the pose features onto the generic mesh."""
    photos = project.expression(expression_name).photos
    all_names = [f.name for f in project.features]
    pose_names = [f.name for f in project.features if f.pose]
    obs_all = project.observations(expression_name, all_names)
    weighted = weigh_auto_clicks(photos, opt.weigh_auto_clicks)
    sol = solve_cameras(
        obs_all,
        initial_cameras(photos),
        mesh.vertices[[feat_vertex[n] for n in all_names]],
        groups=project.camera_groups(expression_name),
        fixed_focal=opt.fixed_focal,
        names=all_names,
        view_names=[p.id for p in photos],
        weights=click_weights(photos, all_names) if weighted else None,
        confidence=_auto_confidence(photos, all_names) if (weighted and opt.person_prior) or len(photos) == 1 else None,
    )
    solved = np.isfinite(sol.points[:, 0])
    col = {n: i for i, n in enumerate(all_names)}
    dropped = [
        f"pose feature {n!r}: clicked in {int(np.isfinite(obs_all[:, col[n], 0]).sum())} photo(s), "
        f"needs {min(2, len(photos))} to be placed"
        for n in pose_names
        if not solved[col[n]]
    ]
    pose_names = [n for n in pose_names if solved[col[n]]]
    if len(photos) == 1:
        # one photo: every clicked feature was placed against the generic head, the pose features
        # alone may be a handful on one side (5 in a profile), too few to deform the mesh by;
        # the detector's unsure points (the outline) no more than in the refinement
        unsure = _unsure(photos[0])
        pose_names = [n for n in all_names if solved[col[n]] and n not in unsure]
    if len(pose_names) < 4:
        raise FitError(
            f"only {len(pose_names)} pose feature(s) are clicked in at least 2 photos; the first "
            "deformation of the generic mesh needs 4 — click more of: "
            + ", ".join(f.name for f in project.features if f.pose and f.name not in pose_names)
        )
    pose_idx = np.array([feat_vertex[n] for n in pose_names])
    pose_cols = [col[n] for n in pose_names]
    s, R, t = similarity_transform(sol.points[pose_cols], mesh.vertices[pose_idx])
    cameras = transform_cameras(sol.cameras, s, R, t)
    pose_points = sol.points[pose_cols] @ (s * R).T + t
    base = sol.pose_result()
    pose = replace(
        base,
        cameras=cameras,
        points=pose_points,
        per_point_rms_px=base.per_point_rms_px[pose_cols],
        residuals_px=base.residuals_px[:, pose_cols],
    )
    anchor_idx = anchor_points = None
    if len(photos) == 1:
        anchor_idx = np.array(sorted({feat_vertex[n] for n in all_names} - set(pose_idx.tolist())), dtype=int)
        sa, Ra, ta = similarity_transform(mesh.vertices[pose_idx], pose_points)
        anchor_points = mesh.vertices[anchor_idx] @ (sa * Ra).T + ta
    return _CameraStage(
        cameras,
        pose,
        pose_names,
        pose_idx,
        pose_points,
        dropped,
        anchor_idx=anchor_idx,
        anchor_points=anchor_points,
        suspects=sol.suspects,
        excluded=~sol.used & np.isfinite(obs_all[..., 0]),
        camera_report={
            "start": sol.start,
            "sigma_px": sol.sigma_px,
            "rms_all_px": sol.rms_all_px,
            "weighted_auto_clicks": bool(weighted),
        },
        bundle_report={"rms_px": float(sol.rms_px), "points": int(solved.sum())},
    )


def _cameras_paper(project, expression_name, mesh, opt, feat_vertex) -> _CameraStage:
    """The paper (§5.1.1): cameras from the pose features alone, gauged onto the generic mesh."""
    photos = project.expression(expression_name).photos
    pose_names = [f.name for f in project.features if f.pose]
    pose_idx = np.array([feat_vertex[n] for n in pose_names])
    pose = recover_poses(
        project.observations(expression_name, pose_names),
        initial_cameras(photos),
        mesh.vertices[pose_idx],
        fixed_focal=opt.fixed_focal,
        max_sweeps=opt.max_sweeps,
        names=pose_names,
        view_names=[p.id for p in photos],
    )
    s, R, t = similarity_transform(pose.points, mesh.vertices[pose_idx])
    cameras = transform_cameras(pose.cameras, s, R, t)
    pose_points = pose.points @ (s * R).T + t
    pose = replace(pose, cameras=cameras, points=pose_points, polish_iterations=0, rms_history=np.zeros(0))
    return _CameraStage(cameras, pose, pose_names, pose_idx, pose_points)


def _depth_unmeasured(stage: _CameraStage) -> np.ndarray | None:
    """The views' mean direction when the camera solve's last resort held the face's depth at the
    generic head's (:data:`~photomodel.modeling.camera_solve.DEPTH_HELD`: the views measure none;
    the other features are then placed at the depth of the pose features' mesh,
    :func:`~photomodel.modeling.refine.place_at_depth`); else None. (Where the clicks measure
    some depth — the real clip turning ±13° — triangulating them fits better: RMS 2.65 px
    against 3.02 px placed at depth, depth ratio 1.01 against 1.05.)"""
    if DEPTH_HELD not in str(stage.camera_report.get("start", "")):
        return None
    return np.mean([c.R[2] for c in stage.cameras], axis=0)


def _refine(
    project, expression_name, mesh, opt, stage: _CameraStage, vertices, curve_mesh, deform, progress, check_cancel
):
    """§5.1.3 with the cameras fixed: triangulate the other features and the curves, re-run the
    RBF from the generic mesh with every constraint; curves re-parameterised on the refined mesh
    ``curve_passes`` times. Returns ``(vertices, feature names, points (n, 3), dropped, curve report)``."""
    photos = project.expression(expression_name).photos
    extra = [f for f in project.features if not f.pose]
    extra_names = [f.name for f in extra]
    extra_idx = np.array([f.vertex for f in extra], dtype=int)
    obs_extra = project.observations(expression_name, extra_names) if extra else None
    if obs_extra is not None and stage.excluded is not None:  # suspect clicks stay out
        obs_extra[stage.excluded[:, [i for i, f in enumerate(project.features) if not f.pose]]] = np.nan
    curves = [c for c in project.curves if sum(c.name in p.curves for p in photos) >= min(2, len(photos))]
    curve_args = [
        (c.vertices, {k: p.curves[c.name] for k, p in enumerate(photos) if c.name in p.curves}) for c in curves
    ]
    pose_set = set(stage.pose_idx.tolist())
    axis = _depth_unmeasured(stage)
    prior = len(photos) == 1 or uses_person_prior(stage.camera_report)
    base = vertices  # the pose features' deformation: its depth where the views measure none
    n_passes = max(1, opt.curve_passes if curves else 1)
    for n_pass in range(n_passes):
        progress("refining: points and curves", 0.55 + 0.4 * n_pass / n_passes)
        # curves are parameterised on the current fitted mesh, so later passes see a better one
        param_mesh = curve_mesh if (n_pass == 0 and curve_mesh is not None) else vertices
        targets = refine_points(
            stage.cameras,
            param_mesh,
            point_vertices=extra_idx if extra else None,
            point_observations=obs_extra,
            curves=curve_args,
            point_names=extra_names,
            curve_names=[c.name for c in curves],
            depth_reference=None if axis is None else (base, axis),
        )
        keep = np.array([v not in pose_set for v in targets.vertices.tolist()], dtype=bool)
        goals = _weigh_auto_targets(targets, base, photos, curves, extra) if prior else targets.targets
        vertices = deform(mesh.vertices, *stage.constraints(targets.vertices[keep], goals[keep]))
        check_cancel()
    vertex_of = {int(v): i for i, v in enumerate(targets.vertices.tolist())}
    got = [
        (n, vertex_of[int(v)])
        for n, v in zip(extra_names, extra_idx, strict=True)
        if int(v) in vertex_of and int(v) not in pose_set
    ]
    points = np.concatenate([stage.pose_points, targets.targets[[i for _, i in got]].reshape(-1, 3)])
    curve_report = {c.name: {"views": len(d)} for c, (_, d) in zip(curves, curve_args, strict=True)}
    return vertices, [n for n, _ in got], points, list(targets.dropped), curve_report


def _weigh_auto_targets(targets, base, photos, curves, extra) -> np.ndarray:
    """The refinement's targets of the detector's clicks and curves (the eyelids and lips it draws)
    moved from where they triangulate towards ``base`` (the face the pose stage deformed, most
    probable under the person prior), as the camera solve weighs the detector's clicks: kept by
    σ²_person / (σ²_person + σ²_detector / views), the views those clicks or curves are in
    (:data:`~photomodel.modeling.camera_solve.PERSON_SIGMA_MM`,
    :data:`~photomodel.modeling.camera_solve.DETECTOR_SIGMA_MM`; the views' errors taken as
    independent, which flatters a detector whose error is mostly the same in every view). The
    artist's clicks and curves keep their targets, and a vertex a clicked feature targets is
    weighed as that click. Beyond the paper. Measured on the sample's photos with automatic
    landmarks only: the mesh 1.53 → 1.31 mm from the scan after the camera solve's
    :func:`~photomodel.modeling.camera_solve._map_estimate` (weighing these without it: 1.69 →
    1.75 mm, pulled towards a pose-stage face that followed the detector); one photo's worst
    1.81 → 1.69 mm."""
    views = {}
    for c in curves:
        n = sum(1 for p in photos if c.name in p.curves and p.curve_source(c.name) == "auto")
        for v in c.vertices if n else ():
            views[int(v)] = max(n, views.get(int(v), 0))
    for f in extra:  # a clicked feature's own vertex: weighed as its clicks (the artist's: kept)
        if any(f.name in p.points for p in photos):
            views[int(f.vertex)] = sum(1 for p in photos if f.name in p.points and p.sources.get(f.name) == "auto")
    n = np.array([views.get(int(v), 0) for v in targets.vertices.tolist()])
    moved = n > 0
    if not moved.any():
        return targets.targets
    kept = PERSON_SIGMA_MM**2 / (PERSON_SIGMA_MM**2 + DETECTOR_SIGMA_MM**2 / n[moved])
    ref = base[targets.vertices[moved]]
    out = targets.targets.copy()
    out[moved] = ref + kept[:, None] * (out[moved] - ref)
    return out


def fit_expression(
    project,
    expression_name: str,
    mesh,
    options: FitOptions | None = None,
    progress: Callable[[str, float], None] | None = None,
    cancel: Callable[[], bool] | None = None,
    *,
    deform: Callable[..., np.ndarray] | None = None,
    curve_mesh: np.ndarray | None = None,
) -> FitResult:
    """Fit the generic mesh to one expression's photos (§5.1).

    Parameters
    ----------
    project : photomodel.project.Project
    expression_name : str
    mesh : photomodel.modeling.generic_mesh.GenericMesh (``vertices`` (N, 3) mm, ``faces``)
    options : FitOptions
    progress : called as ``progress(stage, fraction)``.
    cancel : polled between stages; return True to abort with :class:`Cancelled`.
    deform : callable, optional
        Replaces :func:`photomodel.modeling.rbf.deform_vertices` (same signature, same result), e.g. a
        :class:`photomodel.modeling.refit.CachedDeformer` that reuses the RBF solve between refits.
    curve_mesh : (N, 3) float mm, optional
        Mesh on which hand-drawn curves are parameterised by arc length in the first
        refinement pass (default: the mesh deformed by the pose features). An interactive
        refit passes the previous fit's vertices, already close to the answer, with
        ``options.curve_passes = 1`` (see :mod:`photomodel.modeling.refit`).

    With ``cameras_from`` (the expression's, or ``options.cameras_from``) the cameras are the
    source expression's fitted ones and stay fixed; the result is in that expression's frame
    (see the module docstring).

    Raises
    ------
    MissingClicks
        (a FitError) when the clicks cannot support a fit: its ``checklist`` names every pose
        feature and photo still short of clicks (:mod:`photomodel.modeling.checklist`).
    FitError
        when the clicks cannot support a fit (the message names the feature/photo), or the
        expression whose cameras are reused is not fitted or lacks a photo's camera.
    """
    opt = options or FitOptions()
    source = cameras_source(project, expression_name, opt)
    project, left_out, profiles = _fit_input(project, expression_name, source)
    expr = project.expression(expression_name)
    progress = progress or (lambda stage, frac: None)
    deform = deform or deform_vertices

    def check_cancel():
        if cancel is not None and cancel():
            raise Cancelled("fit cancelled")

    feat_vertex, curve_mesh = _check_inputs(project, expr, mesh, curve_mesh)
    if source is None:  # everything still to click at once (MissingClicks), not one feature per try
        require_clicks(project, expression_name, pose_only=not opt.bundle_all)
    # 1–2. cameras and the gauge
    progress("pose recovery", 0.0)
    if source is not None:
        stage = _cameras_of_source(project, expression_name, source, feat_vertex)
    elif opt.bundle_all:
        stage = _cameras_robust(project, expression_name, mesh, opt, feat_vertex)
    else:
        stage = _cameras_paper(project, expression_name, mesh, opt, feat_vertex)
    check_cancel()
    # 3. scattered-data interpolation from the pose features
    progress("deforming the generic mesh", 0.4)
    initial_vertices = deform(mesh.vertices, *stage.constraints())
    check_cancel()
    # 4. refinement with fixed cameras, on the clicks the detector is sure of
    vertices, names, points_3d, dropped, curve_report = initial_vertices, [], stage.pose_points, [], {}
    refine_project, unsure, unsure_names = _sure_clicks(project, expression_name)
    if opt.refine:
        vertices, names, points_3d, dropped, curve_report = _refine(
            refine_project,
            expression_name,
            mesh,
            opt,
            stage,
            initial_vertices,
            curve_mesh,
            deform,
            progress,
            check_cancel,
        )
        dropped = _say_why_unsure(dropped, unsure_names)
    names = list(stage.pose_names) + names
    photo_ids = [p.id for p in expr.photos]
    report = build_report(photo_ids, stage.cameras, stage.pose, project, expression_name, names, points_3d)
    photos_left_out = {i: "no click (no face found?), left out of the fit" for i in left_out} | {
        i: "a profile, whose automatic clicks place its camera tens of degrees off (the detector sees a profile "
        "turned less than it is); they are left out — click or drag them by hand to fit it"
        for i in profiles
    }
    report.update(
        dropped=[f"photo {i!r}: {why}" for i, why in photos_left_out.items()] + stage.dropped + dropped,
        photos_left_out=photos_left_out,
        bundle=stage.bundle_report,
        suspect_clicks=stage.suspects,
        camera_solve=stage.camera_report,
        curves=curve_report,
        cameras_from=source,
        auto_clicks_left_out=unsure,
    )
    progress("done", 1.0)
    return FitResult(
        photo_ids=photo_ids,
        cameras=stage.cameras,
        feature_names=names,
        points_3d=points_3d,
        initial_vertices=initial_vertices,
        vertices=vertices,
        pose=stage.pose,
        report=report,
        cameras_from=source,
    )


#: Automatic clicks less sure than this are not fitted to: the landmark detector's jaw and chin
#: points (confidence 0.2–0.3, :mod:`photomodel.landmarks.mapping`) lie on the face's outline as
#: seen from that camera, not on fixed points of the skin. On the sample's photos with automatic
#: landmarks only, leaving them out took the refined mesh from 2.21 to 1.99 mm mean to the scan and
#: the RMS from 4.7 to 2.4 px; the RBF places the jaw from the rest. Beyond the paper.
MIN_AUTO_CONFIDENCE = 0.5
#: (The cameras are placed with every automatic click, weighed as :attr:`FitOptions.weigh_auto_clicks`
#: says. Leaving the outline points out of the camera solve altogether was measured before weights:
#: the sample's mesh 2.34 → 1.89 mm, but the real clip's face came out 57 % as deep as the generic
#: head: with frames of changing expression at ±13°, the outline is what holds the depth there.)


#: :attr:`FitOptions.weigh_auto_clicks`'s rule: weigh the automatic clicks when the photos that
#: have them are of views this far apart in azimuth (their ``preset``, which the detector's yaw
#: estimate sets: a front and a three-quarter view are 45° apart). A detector's outline points
#: are silhouette points: seen from directions this far apart they are different points of the
#: skin, and they pull the cameras towards each other (the sample's three-quarter views came out
#: 7–9° too near the front); frames of footage near the front (presets all "front") see nearly
#: the same silhouette, which there holds the depth.
WEIGH_FROM_SPREAD_DEG = 40.0


def uses_person_prior(camera_solve: dict | None) -> bool:
    """Whether a fit's camera solve (``report["camera_solve"]``) found the most probable face under
    the person prior (its start label says so, :data:`~photomodel.modeling.camera_solve.PERSON_PRIOR`)."""
    return PERSON_PRIOR in str((camera_solve or {}).get("start", ""))


def weigh_auto_clicks(photos, option: bool | None = None) -> bool:
    """Whether the camera solve weighs automatic clicks (:attr:`FitOptions.weigh_auto_clicks`):
    ``option`` when given, else :data:`WEIGH_FROM_SPREAD_DEG`'s rule on the photos' presets."""
    if option is not None:
        return bool(option)
    azimuths = [PRESET_AZIMUTH_DEG.get(p.preset, 0.0) for p in photos if p.auto_clicks()]
    return len(azimuths) >= 2 and max(azimuths) - min(azimuths) >= WEIGH_FROM_SPREAD_DEG


def click_weights(photos, names) -> np.ndarray | None:
    """(k, n) weight of each click in the camera solve: 1 for the artist's clicks, the square of
    the detector's confidence for an automatic click (its standard deviation taken as inversely
    proportional to the confidence); None when every click is the artist's (no weighting)."""
    conf = _auto_confidence(photos, names)
    if conf is None:
        return None
    return np.where(np.isfinite(conf), np.maximum(conf, 1e-3) ** 2, 1.0)


def _auto_confidence(photos, names) -> np.ndarray | None:
    """(k, n) the detector's confidence of each automatic click, NaN for the artist's clicks; None
    when every click is the artist's."""
    if not any(p.confidence for p in photos):
        return None
    out = np.full((len(photos), len(names)), np.nan)
    for j, p in enumerate(photos):
        for i, n in enumerate(names):
            if p.sources.get(n) == "auto" and n in p.confidence:
                out[j, i] = p.confidence[n]
    return out


def _with_photos(project, expression_name: str, photos):
    """A shallow copy of ``project`` whose expression ``expression_name`` has ``photos``."""
    expr = replace(project.expression(expression_name), photos=list(photos))
    expressions = [expr if e.name == expression_name else e for e in project.expressions]
    return replace(project, expressions=expressions, path=project.path)


def _fit_input(project, expression_name: str, source) -> tuple[object, list[str], list[str]]:
    """The project the cameras are fitted to: the expression's photos without any click left out (a
    photo where the automatic landmarks found no face, not yet clicked by hand; with reused cameras
    none is), and without the detector's clicks in a profile (:func:`_without_profile_detections`).
    A photo left out gets no camera: the result and its texture use the other photos. Returns the
    project (the original when nothing changes), the ids left out with no click, and the ids of the
    profiles whose automatic clicks were left out."""
    photos = project.expression(expression_name).photos
    if source is not None:
        return project, [], []
    kept, profiles = _without_profile_detections(photos)
    left_out = [p.id for p in kept if not p.points and p.id not in profiles]
    if not any(p.points for p in kept) or not (left_out or profiles):  # nothing to fit: the checklist says
        return project, [], []  # what to click; or nothing changed
    return _with_photos(project, expression_name, [p for p in kept if p.points]), left_out, profiles


#: Presets of a profile. The landmark detector sees a profile as a face turned about 55° (its yaw
#: estimate saturates there) and lays its points out so: measured on the james scan's renders
#: (3–5 views, a 60 mm lens), a fit from automatic landmarks placed the cameras of views at 70–75°
#: 16–34° off, and the sample's left profile (detected at 57°) 38–43° off, while its
#: three-quarter views were within 5°. Its texture then lands on the wrong part of the face.
PROFILE_PRESETS = ("left", "right")


def _without_profile_detections(photos) -> tuple[list, list[str]]:
    """``photos`` with the automatic clicks and curves of each profile photo (preset in
    :data:`PROFILE_PRESETS`, which the detector sets from its yaw estimate) removed, when another
    photo that is not a profile has clicks to place the cameras; the artist's clicks stay, so a
    profile clicked (or corrected) by hand is fitted. Returns the photos and the ids of those
    whose automatic clicks were removed. Leaving them out measured: the sample's auto fit mesh
    1.31 → 1.29 mm from the scan, its left camera no longer 43° off. Beyond the paper."""
    if not any(p.points and p.preset not in PROFILE_PRESETS for p in photos):
        return list(photos), []
    out, profiles = [], []
    for p in photos:
        auto = set(p.auto_clicks())
        auto_curves = {c for c in p.curves if p.curve_source(c) == "auto"}
        if p.preset in PROFILE_PRESETS and (auto or auto_curves):
            p = _photo_without(p, auto, auto_curves)
            profiles.append(p.id)
        out.append(p)
    return out, profiles


def _photo_without(photo, clicks, curves=()):
    """A copy of ``photo`` without the clicks of the features ``clicks`` (with their sources and
    confidences) and the curves ``curves``; the project's photo is left as it is."""
    return replace(
        photo,
        points={n: uv for n, uv in photo.points.items() if n not in clicks},
        sources={n: v for n, v in photo.sources.items() if n not in clicks},
        confidence={n: c for n, c in photo.confidence.items() if n not in clicks},
        curves={c: line for c, line in photo.curves.items() if c not in curves},
        curve_sources={c: v for c, v in photo.curve_sources.items() if c not in curves},
    )


def _sure_clicks(project, expression_name: str, least: float = MIN_AUTO_CONFIDENCE) -> tuple[object, int, dict]:
    """The project the shape is refined with: automatic clicks below ``least`` confidence removed
    (they still helped place the cameras). Returns it, the number removed and, per feature, how
    many of its clicks were removed."""
    photos, removed, names = [], 0, {}
    for p in project.expression(expression_name).photos:
        unsure = _unsure(p, least)
        if unsure:
            p = _photo_without(p, unsure)
            removed += len(unsure)
            for n in unsure:
                names[n] = names.get(n, 0) + 1
        photos.append(p)
    return (_with_photos(project, expression_name, photos) if removed else project), removed, names


def _unsure(photo, least: float = MIN_AUTO_CONFIDENCE) -> set[str]:
    """The features of ``photo`` whose automatic click is less sure than ``least``."""
    return {n for n, c in photo.confidence.items() if photo.sources.get(n) == "auto" and c < least}


def _say_why_unsure(dropped: list[str], unsure: dict) -> list[str]:
    """The refinement's "seen in n photo(s)" for a feature some of whose automatic clicks were
    left out as unsure (:data:`MIN_AUTO_CONFIDENCE`; ``unsure``: feature -> how many): it is
    clicked, so say why it is not refined to."""
    out = []
    for line in dropped:
        seen = re.match(r"([^:]*): seen in (\d+) photo", line)
        if seen and seen.group(1) in unsure:
            name = seen.group(1)
            line = (
                f"{name}: {unsure[name]} automatic click(s) unsure (confidence < {MIN_AUTO_CONFIDENCE:g}, "
                f"e.g. outline or far-side points) and {seen.group(2)} sure; triangulation needs 2 sure "
                "clicks, so the generic mesh places it: click or drag it by hand to fit to it"
            )
        out.append(line)
    return out


def build_report(photo_ids, cameras, pose, project, expression_name, names, points_3d) -> dict:
    """Per-view and per-point reprojection report (px) of every 3D feature."""
    obs = project.observations(expression_name, names)
    res = _reproject(cameras, points_3d, obs)
    per_view = _rms(res, axis=1)
    per_point = _rms(res, axis=0)
    pose_names = {f.name for f in project.features if f.pose}
    return {
        "pose": {
            "rms_px": float(pose.rms_px),
            "sweeps": int(pose.iterations),
            "converged": bool(pose.converged),
        },
        "rms_px": float(_rms(res)),
        "views": [
            {
                "photo": pid,
                "rms_px": None if not np.isfinite(r) else float(r),
                "points": int(np.isfinite(obs[k, :, 0]).sum()),
                "focal_px": float(c.f),
                "focal_mm": float(c.focal_mm),
            }
            for k, (pid, r, c) in enumerate(zip(photo_ids, per_view, cameras, strict=True))
        ],
        "points": [
            {
                "feature": n,
                "pose": n in pose_names,
                "rms_px": None if not np.isfinite(r) else float(r),
                "views": int(np.isfinite(obs[:, i, 0]).sum()),
            }
            for i, (n, r) in enumerate(zip(names, per_point, strict=True))
        ],
    }
