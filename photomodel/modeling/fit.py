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

**One door.** :meth:`FitInputs.from_project` reads everything the fit needs from the project
once — the clicks with where they came from and how sure the detector was, the cameras to start
from (or to keep), the curves — as arrays with names; the stages take those arrays and return
arrays (:class:`_CameraStage`, :class:`_Refinement`), and the report is built from what they
returned. :func:`fit_expression` is a thin public function over them.

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
from photomodel.camera import Camera, focal_mm_to_px, preset_camera
from photomodel.errors import Cancelled, FitError, ProjectError
from photomodel.modeling.camera_solve import (
    DEPTH_HELD,
    DETECTOR_SIGMA_MM,
    PERSON_PRIOR,
    PERSON_SIGMA_MM,
    person_depth_prior,
    solve_cameras,
)
from photomodel.modeling.checklist import require_clicks
from photomodel.modeling.generic_mesh import ibug_index
from photomodel.modeling.mouth import MOVES_WITH_EXPRESSION, NEUTRAL, expressive_photos, mouth_scores
from photomodel.modeling.pose import PoseResult, recover_poses, reprojection_residuals
from photomodel.modeling.rbf import deform_vertices
from photomodel.modeling.refine import refine_points, triangulate

#: Default distance of a preset camera from the head (mm) when the project gives none.
PRESET_DISTANCE_MM = 600.0
#: Default lens of a preset camera (mm, 36 mm-wide sensor) when the photo gives no guess.
PRESET_FOCAL_MM = 50.0


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
    #: :func:`weigh_auto_clicks`'s rule — on when the cameras solved unweighed show the photos with
    #: automatic clicks from directions at least :data:`WEIGH_FROM_SPREAD_DEG` apart (then the
    #: cameras are solved again, weighed). Measured both ways: on
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
        the expression whose cameras were reused (None when they were recovered);
        ``report["expressive_photos"]`` and ``report["expression_clicks"]``: see
        :func:`expression_not_misclicks`.
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


# -- the door: what the fit reads from the project ----------------------------------------

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


#: :attr:`FitOptions.weigh_auto_clicks`'s rule: weigh the automatic clicks when the solved cameras
#: of the photos that have them look at the head from directions this far apart (the angle between
#: their optical axes, :func:`views_apart_deg`; a front and a three-quarter view are about 45° apart).
#: A detector's outline points are silhouette points: seen from directions this far apart they are
#: different points of the skin, and they pull the cameras towards each other (the sample's
#: three-quarter views came out 7–9° too near the front); frames of footage near the front see
#: nearly the same silhouette, which there holds the depth. The angle is the solved cameras', not
#: the photos' presets: the detector's yaw label once called a −26° frame of a near-frontal clip
#: "three quarter" (45°) and weighed its clicks (RMS 1.47 px against 0.81 px unweighed).
WEIGH_FROM_SPREAD_DEG = 40.0


#: Presets of a profile. The landmark detector sees a profile as a face turned about 55° (its yaw
#: estimate saturates there) and lays its points out so: measured on the james scan's renders
#: (3–5 views, a 60 mm lens), a fit from automatic landmarks placed the cameras of views at 70–75°
#: 16–34° off, and the sample's left profile (detected at 57°) 38–43° off, while its
#: three-quarter views were within 5°. Its texture then lands on the wrong part of the face.
PROFILE_PRESETS = ("left", "right")


@dataclass
class FitCurve:
    """One curve of the project as the fit reads it.

    Attributes
    ----------
    name : str
    vertices : (m,) int, the generic-mesh polyline it binds to.
    lines : dict photo index → (q, 2) float px, the photos it is drawn in (indices into
        :attr:`FitInputs.photo_ids`).
    auto : (k,) bool, drawn in that photo by the landmark detector.
    """

    name: str
    vertices: np.ndarray
    lines: dict[int, np.ndarray]
    auto: np.ndarray


@dataclass
class FitInputs:
    """What a fit reads from the project, read once at its door (:meth:`from_project`): the
    clicks with where they came from, the cameras to start from (or to keep) and the curves, as
    arrays with names. The stages of :func:`fit_expression` take these and return arrays; none of
    them sees the project.

    Attributes
    ----------
    expression : str
    photo_ids : list[str], the k photos fitted, in the expression's order (a photo with no click
        is left out, see :attr:`photos_left_out`).
    cameras : list[Camera], k: each photo's preset with its lens guess
        (:func:`initial_cameras`), or with :attr:`cameras_from` the source expression's fitted
        cameras (:func:`source_cameras`), which the fit keeps.
    camera_groups : list[int], k, photos sharing a camera index share a focal length.
    feature_names : list[str], the n features in the project's order.
    feature_vertices : (n,) int, each feature's generic-mesh vertex.
    pose : (n,) bool, the features that place the cameras (§5.1.1).
    observations : (k, n, 2) float px, the clicks, NaN where a feature is not clicked or hidden.
    clicked : (k, n) bool, a click exists (hidden or not).
    auto : (k, n) bool, the click was placed by the landmark detector.
    confidence : (k, n) float or None, the detector's confidence of an automatic click, NaN for
        the artist's; None when no photo has an automatic click with a confidence.
    curves : list[FitCurve], every curve of the project.
    cameras_from : str or None, the expression whose fitted cameras are reused.
    weigh_auto_clicks : bool or None, the camera solve weighs automatic clicks
        (:attr:`FitOptions.weigh_auto_clicks`); None: as :func:`weigh_auto_clicks` decides from
        the cameras solved unweighed.
    photos_left_out : dict photo id → why: photos without a click, and profiles whose automatic
        clicks are left out (:func:`_without_profile_detections`).
    """

    expression: str
    photo_ids: list[str]
    cameras: list[Camera]
    camera_groups: list[int]
    feature_names: list[str]
    feature_vertices: np.ndarray
    pose: np.ndarray
    observations: np.ndarray
    clicked: np.ndarray
    auto: np.ndarray
    confidence: np.ndarray | None
    curves: list[FitCurve]
    cameras_from: str | None = None
    weigh_auto_clicks: bool | None = None
    photos_left_out: dict[str, str] = field(default_factory=dict)

    @classmethod
    def from_project(
        cls, project, expression_name: str, options: FitOptions | None = None, *, n_vertices: int | None = None
    ) -> FitInputs:
        """Read one expression of ``project`` for a fit with ``options``.

        Photos with no click and the detector's clicks in profiles are left out
        (:func:`_fit_input`); the features are checked against a generic mesh of ``n_vertices``
        vertices (when given); with cameras to recover, the clicks must support a fit
        (:func:`~photomodel.modeling.checklist.require_clicks`); with ``cameras_from`` the source
        expression's fitted cameras are taken (:func:`source_cameras`).

        Raises
        ------
        MissingClicks, FitError
            as :func:`fit_expression` says.
        """
        opt = options or FitOptions()
        source = cameras_source(project, expression_name, opt)
        project, left_out, profiles = _fit_input(project, expression_name, source)
        photos = project.expression(expression_name).photos
        _check_features(project, expression_name, photos, n_vertices)
        if source is None:  # everything still to click at once (MissingClicks), not one feature per try
            require_clicks(project, expression_name, pose_only=not opt.bundle_all)
        names = project.feature_names()
        shape = (len(photos), len(names))
        return cls(
            expression=expression_name,
            photo_ids=[p.id for p in photos],
            cameras=initial_cameras(photos) if source is None else source_cameras(project, expression_name, source),
            camera_groups=project.camera_groups(expression_name),
            feature_names=names,
            feature_vertices=project.feature_vertices(names),
            pose=np.array([f.pose for f in project.features], dtype=bool),
            observations=project.observations(expression_name, names),
            clicked=np.array([[n in p.points for n in names] for p in photos], dtype=bool).reshape(shape),
            auto=np.array([[p.sources.get(n) == "auto" for n in names] for p in photos], dtype=bool).reshape(shape),
            confidence=_auto_confidence(photos, names),
            curves=[_read_curve(c, photos) for c in project.curves],
            cameras_from=source,
            weigh_auto_clicks=opt.weigh_auto_clicks,
            photos_left_out=_photos_left_out(left_out, profiles),
        )

    @property
    def pose_names(self) -> list[str]:
        """The pose features' names, in the project's order."""
        return [n for n, p in zip(self.feature_names, self.pose, strict=True) if p]

    def clicks_of(self, cols, drop: np.ndarray | None = None) -> np.ndarray:
        """(k, m, 2) float px, the clicks of the features ``cols`` (indices or an (n,) mask), NaN
        where ``drop`` (k, n) bool is set: a fresh C-ordered array, as the solvers were measured with
        (a strided view of the columns sums in another order, which moves the paper's pose recovery
        by ~1e-7 mm)."""
        obs = self.observations if drop is None else np.where(drop[..., None], np.nan, self.observations)
        return np.ascontiguousarray(obs[:, cols])

    def unsure(self, least: float = MIN_AUTO_CONFIDENCE) -> np.ndarray:
        """(k, n) bool, the automatic clicks less sure than ``least``."""
        if self.confidence is None:
            return np.zeros(self.clicked.shape, dtype=bool)
        with np.errstate(invalid="ignore"):
            return self.confidence < least


def _read_curve(curve, photos) -> FitCurve:
    lines = {k: p.curves[curve.name] for k, p in enumerate(photos) if curve.name in p.curves}
    auto = np.array([curve.name in p.curves and p.curve_source(curve.name) == "auto" for p in photos], dtype=bool)
    return FitCurve(curve.name, curve.vertices, lines, auto)


def _photos_left_out(left_out: list[str], profiles: list[str]) -> dict[str, str]:
    return {i: "no click (no face found?), left out of the fit" for i in left_out} | {
        i: "a profile, whose automatic clicks place its camera tens of degrees off (the detector sees a profile "
        "turned less than it is); they are left out — click or drag them by hand to fit it"
        for i in profiles
    }


def _check_features(project, expression_name: str, photos, n_vertices: int | None) -> None:
    """A FitError naming the problem when the expression has no photo or the features cannot be fitted."""
    if not photos:
        raise FitError(f"expression {expression_name!r} has no photo; add photos of it to fit it")
    bad = [f.name for f in project.features if n_vertices is not None and not 0 <= int(f.vertex) < n_vertices]
    if bad:
        raise FitError(f"feature(s) {', '.join(bad)} refer to vertices outside the generic mesh (0..{n_vertices - 1})")
    if not any(f.pose for f in project.features):
        raise FitError("no feature is marked for pose recovery (features[].pose = true)")


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


def uses_person_prior(camera_solve: dict | None) -> bool:
    """Whether a fit's camera solve (``report["camera_solve"]``) found the most probable face under
    the person prior (its start label says so, :data:`~photomodel.modeling.camera_solve.PERSON_PRIOR`)."""
    return PERSON_PRIOR in str((camera_solve or {}).get("start", ""))


def weigh_auto_clicks(photos, cameras, option: bool | None = None) -> bool:
    """Whether the camera solve weighs automatic clicks (:attr:`FitOptions.weigh_auto_clicks`):
    ``option`` when given, else :data:`WEIGH_FROM_SPREAD_DEG`'s rule on ``cameras`` (one per photo,
    the solved ones): the photos with automatic clicks are views at least that far apart."""
    if option is not None:
        return bool(option)
    return _views_far_apart(cameras, np.array([bool(p.auto_clicks()) for p in photos], dtype=bool))


def _views_far_apart(cameras, with_auto: np.ndarray) -> bool:
    """The rule of :func:`weigh_auto_clicks` on the cameras of the photos ``with_auto`` ((k,) bool)."""
    cams = [c for c, a in zip(cameras, with_auto, strict=True) if a]
    return len(cams) >= 2 and views_apart_deg(cams) >= WEIGH_FROM_SPREAD_DEG


def views_apart_deg(cameras) -> float:
    """The largest angle (degrees) between two cameras' optical axes (in the head's frame, the
    third row of ``R``): how far apart the views are, whatever the photos' preset labels say."""
    axes = np.array([np.asarray(c.R)[2] for c in cameras], dtype=float)
    if len(axes) < 2:
        return 0.0
    axes /= np.linalg.norm(axes, axis=1, keepdims=True)
    return float(np.degrees(np.arccos(np.clip(axes @ axes.T, -1.0, 1.0))).max())


def click_weights(photos, names) -> np.ndarray | None:
    """(k, n) weight of each click in the camera solve: 1 for the artist's clicks, the square of
    the detector's confidence for an automatic click (its standard deviation taken as inversely
    proportional to the confidence); None when every click is the artist's (no weighting)."""
    return _weights_from_confidence(_auto_confidence(photos, names))


def _weights_from_confidence(conf: np.ndarray | None) -> np.ndarray | None:
    """:func:`click_weights` from the confidences (:attr:`FitInputs.confidence`)."""
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


# -- the stages ----------------------------------------------------------------------------


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

    The project is read once, into :class:`FitInputs`; the stages work on its arrays.

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
    if curve_mesh is not None:
        curve_mesh = np.asarray(curve_mesh, dtype=float)
        if curve_mesh.shape != mesh.vertices.shape:
            raise FitError(f"curve_mesh has shape {curve_mesh.shape}, the generic mesh {mesh.vertices.shape}")
    inputs = FitInputs.from_project(project, expression_name, opt, n_vertices=len(mesh.vertices))
    deform = deform or deform_vertices
    return _fit(inputs, mesh.vertices, opt, progress, cancel, deform, curve_mesh)


def _fit(inputs: FitInputs, generic, opt: FitOptions, progress, cancel, deform, curve_mesh) -> FitResult:
    """The stages of :func:`fit_expression` on ``inputs`` and the generic mesh's vertices ``generic`` (N, 3)."""
    progress = progress or (lambda stage, frac: None)

    def check_cancel():
        if cancel is not None and cancel():
            raise Cancelled("fit cancelled")

    # 1–2. cameras and the gauge
    progress("pose recovery", 0.0)
    stage = _camera_stage(inputs, generic, opt)
    check_cancel()
    # 3. scattered-data interpolation from the pose features
    progress("deforming the generic mesh", 0.4)
    initial_vertices = deform(generic, *stage.constraints())
    check_cancel()
    # 4. refinement with fixed cameras, on the clicks the detector is sure of
    if opt.refine:
        refined = _refine(inputs, generic, opt, stage, initial_vertices, curve_mesh, deform, progress, check_cancel)
    else:
        refined = _Refinement(initial_vertices, [], stage.pose_points)
    names = list(stage.pose_names) + refined.names
    report = _report(inputs, stage, refined, names)
    progress("done", 1.0)
    return FitResult(
        photo_ids=list(inputs.photo_ids),
        cameras=stage.cameras,
        feature_names=names,
        points_3d=refined.points,
        initial_vertices=initial_vertices,
        vertices=refined.vertices,
        pose=stage.pose,
        report=report,
        cameras_from=inputs.cameras_from,
    )


# -- 1–2. cameras and the gauge ------------------------------------------------------------


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


def _camera_stage(inputs: FitInputs, generic: np.ndarray, opt: FitOptions) -> _CameraStage:
    """Cameras reused from another expression, placed by every feature (robust), or by the pose
    features alone (the paper)."""
    if inputs.cameras_from is not None:
        return _cameras_of_source(inputs)
    if opt.bundle_all:
        return _cameras_robust(inputs, generic, opt)
    return _cameras_paper(inputs, generic, opt)


def _cameras_of_source(inputs: FitInputs) -> _CameraStage:
    """Cameras of another, fitted expression (same rig): triangulate the pose features, keep its frame."""
    pose_names = inputs.pose_names
    obs_pose = inputs.clicks_of(inputs.pose)
    pose, kept, dropped = _fixed_camera_pose(inputs.cameras, obs_pose, pose_names, inputs.photo_ids)
    pose_names = [n for n, k in zip(pose_names, kept, strict=True) if k]
    pose_idx = inputs.feature_vertices[inputs.pose][kept]
    return _CameraStage(inputs.cameras, pose, pose_names, pose_idx, pose.points, dropped)


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


def _cameras_robust(inputs: FitInputs, generic: np.ndarray, opt: FitOptions) -> _CameraStage:
    """Every feature clicked in ≥ 2 photos places the cameras (photomodel.modeling.camera_solve:
    cheap starts, the paper's ALS, robust polish, suspects named and left out); the gauge is the
    similarity of the pose features onto the generic mesh."""
    n_photos = len(inputs.photo_ids)
    conf = inputs.confidence

    def solve(weighted: bool):
        return solve_cameras(
            inputs.observations,
            inputs.cameras,
            generic[inputs.feature_vertices],
            groups=inputs.camera_groups,
            fixed_focal=opt.fixed_focal,
            names=inputs.feature_names,
            view_names=inputs.photo_ids,
            weights=_weights_from_confidence(conf) if weighted else None,
            confidence=conf if (weighted and opt.person_prior) or n_photos == 1 else None,
        )

    weighted = inputs.weigh_auto_clicks
    if weighted is None:  # the rule: solve unweighed, weigh where the solved views are far apart
        sol = solve(False)
        weighted = conf is not None and n_photos > 1 and _views_far_apart(sol.cameras, inputs.auto.any(axis=1))
        if weighted:
            sol = solve(True)
    else:
        sol = solve(weighted)
    if _depth_from_person_prior(inputs, opt, sol.cameras, weighted):
        sol = person_depth_prior(
            inputs.observations,
            sol,
            inputs.cameras,
            generic[inputs.feature_vertices],
            conf,
            groups=inputs.camera_groups,
            fixed_focal=opt.fixed_focal,
            names=inputs.feature_names,
            view_names=inputs.photo_ids,
        )
    solved = np.isfinite(sol.points[:, 0])
    pose_cols, dropped = _placed_pose_features(inputs, solved)
    pose_idx = inputs.feature_vertices[pose_cols]
    s, R, t = similarity_transform(sol.points[pose_cols], generic[pose_idx])
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
    if n_photos == 1:
        anchor_idx = np.array(sorted(set(inputs.feature_vertices.tolist()) - set(pose_idx.tolist())), dtype=int)
        sa, Ra, ta = similarity_transform(generic[pose_idx], pose_points)
        anchor_points = generic[anchor_idx] @ (sa * Ra).T + ta
    return _CameraStage(
        cameras,
        pose,
        [inputs.feature_names[i] for i in pose_cols],
        pose_idx,
        pose_points,
        dropped,
        anchor_idx=anchor_idx,
        anchor_points=anchor_points,
        suspects=sol.suspects,
        excluded=~sol.used & np.isfinite(inputs.observations[..., 0]),
        camera_report={
            "start": sol.start,
            "sigma_px": sol.sigma_px,
            "rms_all_px": sol.rms_all_px,
            "weighted_auto_clicks": bool(weighted),
        },
        bundle_report={"rms_px": float(sol.rms_px), "points": int(solved.sum())},
    )


def _depth_from_person_prior(inputs: FitInputs, opt: FitOptions, cameras, weighted: bool) -> bool:
    """Whether the person prior holds the face's depth
    (:func:`~photomodel.modeling.camera_solve.person_depth_prior`): several photos with automatic
    clicks, unweighed, whose solved cameras (``cameras``) look from directions less than
    :data:`WEIGH_FROM_SPREAD_DEG` apart — views close together, which hardly measure depth — and
    the person prior on (:attr:`FitOptions.person_prior`). Beyond the paper."""
    if weighted or not opt.person_prior or inputs.confidence is None or len(inputs.photo_ids) < 2:
        return False
    return not _views_far_apart(cameras, inputs.auto.any(axis=1))


def _placed_pose_features(inputs: FitInputs, solved: np.ndarray) -> tuple[list[int], list[str]]:
    """The columns of the features the deformation starts from: the pose features the camera
    solve placed (``solved`` (n,) bool) — with one photo every placed feature the detector is sure
    of — and a line for each pose feature left out. FitError when fewer than 4."""
    obs = inputs.observations
    n_photos = obs.shape[0]
    pose_cols = np.flatnonzero(inputs.pose)
    dropped = [
        f"pose feature {inputs.feature_names[i]!r}: clicked in {int(np.isfinite(obs[:, i, 0]).sum())} photo(s), "
        f"needs {min(2, n_photos)} to be placed"
        for i in pose_cols
        if not solved[i]
    ]
    cols = [int(i) for i in pose_cols if solved[i]]
    if n_photos == 1:
        # one photo: every clicked feature was placed against the generic head, the pose features
        # alone may be a handful on one side (5 in a profile), too few to deform the mesh by;
        # the detector's unsure points (the outline) no more than in the refinement
        unsure = inputs.unsure()[0]
        cols = [i for i in range(len(inputs.feature_names)) if solved[i] and not unsure[i]]
    if len(cols) < 4:
        placed = {inputs.feature_names[i] for i in cols}
        raise FitError(
            f"only {len(cols)} pose feature(s) are clicked in at least 2 photos; the first "
            "deformation of the generic mesh needs 4 — click more of: "
            + ", ".join(n for n in inputs.pose_names if n not in placed)
        )
    return cols, dropped


def _cameras_paper(inputs: FitInputs, generic: np.ndarray, opt: FitOptions) -> _CameraStage:
    """The paper (§5.1.1): cameras from the pose features alone, gauged onto the generic mesh."""
    pose_names = inputs.pose_names
    pose_idx = inputs.feature_vertices[inputs.pose]
    pose = recover_poses(
        inputs.clicks_of(inputs.pose),
        inputs.cameras,
        generic[pose_idx],
        fixed_focal=opt.fixed_focal,
        max_sweeps=opt.max_sweeps,
        names=pose_names,
        view_names=inputs.photo_ids,
    )
    s, R, t = similarity_transform(pose.points, generic[pose_idx])
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


# -- 4. refinement -------------------------------------------------------------------------


@dataclass
class _Refinement:
    """What the refinement hands on: the fitted mesh, the features it placed besides the pose
    features (``names``), every placed feature's point (pose features first) and what it dropped."""

    vertices: np.ndarray
    names: list[str]
    points: np.ndarray
    dropped: list[str] = field(default_factory=list)
    curve_report: dict = field(default_factory=dict)


def _refine(inputs: FitInputs, generic, opt, stage: _CameraStage, vertices, curve_mesh, deform, progress, check_cancel):
    """§5.1.3 with the cameras fixed: triangulate the other features and the curves, re-run the
    RBF from the generic mesh with every constraint; curves re-parameterised on the refined mesh
    ``curve_passes`` times. Only the clicks the detector is sure of are refined to
    (:data:`MIN_AUTO_CONFIDENCE`). Returns a :class:`_Refinement`."""
    n_photos = len(inputs.photo_ids)
    unsure = inputs.unsure()
    extra = np.flatnonzero(~inputs.pose)
    extra_names = [inputs.feature_names[i] for i in extra]
    extra_idx = inputs.feature_vertices[extra]
    obs_extra = None
    if extra.size:
        obs_extra = inputs.clicks_of(extra, drop=unsure)
        if stage.excluded is not None:  # suspect clicks stay out
            obs_extra[stage.excluded[:, extra]] = np.nan
    curves = [c for c in inputs.curves if len(c.lines) >= min(2, n_photos)]
    curve_args = [(c.vertices, c.lines) for c in curves]
    pose_set = set(stage.pose_idx.tolist())
    axis = _depth_unmeasured(stage)
    prior = n_photos == 1 or uses_person_prior(stage.camera_report)
    sure = inputs.clicked & ~unsure
    base = vertices  # the pose features' deformation: its depth where the views measure none
    n_passes = max(1, opt.curve_passes if curves else 1)
    for n_pass in range(n_passes):
        progress("refining: points and curves", 0.55 + 0.4 * n_pass / n_passes)
        # curves are parameterised on the current fitted mesh, so later passes see a better one
        param_mesh = curve_mesh if (n_pass == 0 and curve_mesh is not None) else vertices
        targets = refine_points(
            stage.cameras,
            param_mesh,
            point_vertices=extra_idx if extra.size else None,
            point_observations=obs_extra,
            curves=curve_args,
            point_names=extra_names,
            curve_names=[c.name for c in curves],
            depth_reference=None if axis is None else (base, axis),
        )
        keep = np.array([v not in pose_set for v in targets.vertices.tolist()], dtype=bool)
        goals = targets.targets
        if prior:
            goals = _weigh_auto_targets(
                targets, base, curves, extra_idx, sure[:, extra], (sure & inputs.auto)[:, extra]
            )
        vertices = deform(generic, *stage.constraints(targets.vertices[keep], goals[keep]))
        check_cancel()
    vertex_of = {int(v): i for i, v in enumerate(targets.vertices.tolist())}
    got = [
        (n, vertex_of[int(v)])
        for n, v in zip(extra_names, extra_idx, strict=True)
        if int(v) in vertex_of and int(v) not in pose_set
    ]
    points = np.concatenate([stage.pose_points, targets.targets[[i for _, i in got]].reshape(-1, 3)])
    if n_photos == 1:
        idx_all, pts_all = stage.constraints(targets.vertices[keep], goals[keep])
        idx_all, pts_all = onto_one_photos_clicks(stage.cameras[0], inputs, vertices, idx_all, pts_all)
        vertices = deform(generic, idx_all, pts_all)
        points = vertices[np.concatenate([stage.pose_idx, targets.vertices[[i for _, i in got]]]).astype(int)]
    per_feature = unsure.sum(axis=0)
    unsure_names = {n: int(c) for n, c in zip(inputs.feature_names, per_feature, strict=True) if c}
    return _Refinement(
        vertices,
        [n for n, _ in got],
        points,
        _say_why_unsure(list(targets.dropped), unsure_names),
        {c.name: {"views": len(c.lines)} for c in curves},
    )


def onto_one_photos_clicks(camera: Camera, inputs: FitInputs, vertices, idx, points) -> tuple[np.ndarray, np.ndarray]:
    """One photo: the deformation's targets ``idx`` (m,) / ``points`` (m, 3) mm with every clicked
    feature's vertex moved across the line of sight onto its click, its depth kept (the prior's,
    from the fit so far); the clicked features not yet targeted (the detector's unsure jaw and
    outline points) are added, from ``vertices`` (N, 3). One photo fixes where each point lies in
    the image, never how deep: the prior holds the depth, not the outline. Before this (2026-12)
    the prior held the outline too, and a portrait's wireframe sat 7.5–15 px RMS off its clicks,
    its jaw on the generic head's rather than on the photo's. Beyond the paper."""
    obs = inputs.observations[0]
    clicked = np.flatnonzero(np.isfinite(obs[:, 0]))
    by_vertex = {int(inputs.feature_vertices[i]): obs[i] for i in clicked}
    idx = np.asarray(idx, dtype=int)
    missing = [v for v in by_vertex if v not in set(idx.tolist())]
    idx = np.concatenate([idx, np.array(missing, dtype=int)])
    points = np.concatenate([np.asarray(points, float).reshape(-1, 3), vertices[missing].reshape(-1, 3)])
    on = np.array([int(v) in by_vertex for v in idx], dtype=bool)
    if not on.any():
        return idx, points
    uv = np.array([by_vertex[int(v)] for v in idx[on]])
    x_cam = points[on] @ camera.R.T + camera.t
    z = x_cam[:, 2:3]
    x_cam = np.column_stack([(uv - camera.principal_point) * z / camera.f, z])
    points = points.copy()
    points[on] = (x_cam - camera.t) @ camera.R
    return idx, points


def _weigh_auto_targets(targets, base, curves, extra_idx, clicked, auto) -> np.ndarray:
    """The refinement's targets of the detector's clicks and curves (the eyelids and lips it draws)
    moved from where they triangulate towards ``base`` (the face the pose stage deformed, most
    probable under the person prior), as the camera solve weighs the detector's clicks: kept by
    σ²_person / (σ²_person + σ²_detector / views), the views those clicks or curves are in
    (:data:`~photomodel.modeling.camera_solve.PERSON_SIGMA_MM`,
    :data:`~photomodel.modeling.camera_solve.DETECTOR_SIGMA_MM`; the views' errors taken as
    independent, which flatters a detector whose error is mostly the same in every view). The
    artist's clicks and curves keep their targets, and a vertex a clicked feature targets is
    weighed as that click. ``curves``: the refined :class:`FitCurve`; ``extra_idx`` (m,) int the
    other features' vertices, ``clicked`` and ``auto`` (k, m) bool their (sure) clicks and those
    of the detector. Beyond the paper. Measured on the sample's photos with automatic
    landmarks only: the mesh 1.53 → 1.31 mm from the scan after the camera solve's
    :func:`~photomodel.modeling.camera_solve._map_estimate` (weighing these without it: 1.69 →
    1.75 mm, pulled towards a pose-stage face that followed the detector); one photo's worst
    1.81 → 1.69 mm."""
    views = {}
    for c in curves:
        n = int(c.auto.sum())
        for v in c.vertices if n else ():
            views[int(v)] = max(n, views.get(int(v), 0))
    for j, v in enumerate(extra_idx.tolist()):  # a clicked feature's own vertex: weighed as its clicks
        if clicked[:, j].any():  # (the artist's: kept)
            views[int(v)] = int(auto[:, j].sum())
    n = np.array([views.get(int(v), 0) for v in targets.vertices.tolist()])
    moved = n > 0
    if not moved.any():
        return targets.targets
    kept = PERSON_SIGMA_MM**2 / (PERSON_SIGMA_MM**2 + DETECTOR_SIGMA_MM**2 / n[moved])
    ref = base[targets.vertices[moved]]
    out = targets.targets.copy()
    out[moved] = ref + kept[:, None] * (out[moved] - ref)
    return out


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


# -- the report ----------------------------------------------------------------------------


def _report(inputs: FitInputs, stage: _CameraStage, refined: _Refinement, names: list[str]) -> dict:
    """The fit's report (JSON-serialisable) from what the stages returned."""
    col = {n: i for i, n in enumerate(inputs.feature_names)}
    cols = [col[n] for n in names]
    obs = inputs.clicks_of(cols)
    report = _reprojection_report(
        inputs.photo_ids, stage.cameras, stage.pose, obs, names, refined.points, inputs.pose_names
    )
    left_out = inputs.photos_left_out
    expressive, suspects, moved = expression_not_misclicks(inputs, stage.suspects)
    neutral = len(mouth_scores(inputs.photo_ids, inputs.feature_names, inputs.observations, inputs.auto)) - len(
        expressive
    )
    report.update(
        dropped=[f"photo {i!r}: {why}" for i, why in left_out.items()] + stage.dropped + refined.dropped,
        photos_left_out=dict(left_out),
        bundle=stage.bundle_report,
        suspect_clicks=suspects,
        expressive_photos=expressive,
        neutral_mouth_photos=neutral if inputs.expression == NEUTRAL else 0,
        expression_clicks=moved,
        camera_solve=stage.camera_report,
        curves=refined.curve_report,
        cameras_from=inputs.cameras_from,
        auto_clicks_left_out=int(inputs.unsure().sum()),
    )
    return report


def expression_not_misclicks(inputs: FitInputs, suspects: list[dict]) -> tuple[dict, list[dict], list[dict]]:
    """The :data:`~photomodel.modeling.mouth.NEUTRAL` expression's photos whose automatic mouth
    clicks show an expression (:func:`~photomodel.modeling.mouth.expressive_photos`: kept by the
    intake where no photo's mouth is neutral, so the face is fitted as that expression), and the
    suspects split into misclicks and the clicks of those photos that move with the expression
    (:data:`~photomodel.modeling.mouth.MOVES_WITH_EXPRESSION`): those disagree with the other
    photos because the face changed, not because the click is wrong, and are not called suspect.
    Both kinds stay out of the fit. Other expressions show their expression: nothing is moved."""
    if inputs.expression != NEUTRAL:
        return {}, suspects, []
    expressive = expressive_photos(
        mouth_scores(inputs.photo_ids, inputs.feature_names, inputs.observations, inputs.auto)
    )
    moves = [s for s in suspects if s["photo"] in expressive and ibug_index(s["feature"]) in MOVES_WITH_EXPRESSION]
    return expressive, [s for s in suspects if s not in moves], moves


def build_report(photo_ids, cameras, pose, project, expression_name, names, points_3d) -> dict:
    """Per-view and per-point reprojection report (px) of every 3D feature of ``project``'s
    expression ``expression_name``."""
    obs = project.observations(expression_name, names)
    return _reprojection_report(photo_ids, cameras, pose, obs, names, points_3d, project.feature_names(pose_only=True))


def _reprojection_report(photo_ids, cameras, pose, obs, names, points_3d, pose_names) -> dict:
    """Per-view and per-point reprojection report (px) of ``points_3d`` (n, 3) mm, features
    ``names``, against their clicks ``obs`` (k, n, 2) px; ``pose_names`` the pose features."""
    res = _reproject(cameras, points_3d, obs)
    per_view = _rms(res, axis=1)
    per_point = _rms(res, axis=0)
    pose_names = set(pose_names)
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


def _rms(res: np.ndarray, axis=None) -> np.ndarray:
    sq = np.nansum(res**2, axis=-1)
    cnt = np.sum(np.isfinite(res[..., 0]), axis=axis)
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.sqrt(np.nansum(sq, axis=axis) / cnt)


def _reproject(cameras: list[Camera], points: np.ndarray, obs: np.ndarray) -> np.ndarray:
    proj = np.stack([c.project(points) for c in cameras])
    return proj - obs
