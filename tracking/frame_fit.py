"""Fitting the face model to video frames: analysis by synthesis (Pighin et al. 2002, §6.1.2–6.1.3, App. B).

Parameters of a frame: head rotation ``R`` (updated as ``R ← R̂(ω) R``, App. B.2), translation ``t``
(camera-space position, mm, of the model's centre ``c``, so ``X_cam = R (X − c) + t``) and the
expression parameters ``α_r`` of every control region (:mod:`tracking.blendshape_face`). The error is

    ε(p) = ½ ‖I_t − Î(p)‖² + D(p),   D(p) = c Σ_r Σ_k [min(0, w_rk)² + max(0, w_rk − 1)²],

summed over the pixels and RGB channels the model covers (elsewhere ``Î`` is the frame itself, so
the residual is 0 there and ε stays continuous as the silhouette moves). ``c`` is
:attr:`TrackOptions.penalty` times the number of covered pixels, so the penalty weighs like an
image term. Each Levenberg–Marquardt step solves Eq. (6),

    [JᵀJ + λ diag(JᵀJ) + H_D] δp = Jᵀ (I_t − Î) − ∇D,

(Marquardt's scaled damping: rotation in radians and translation in mm differ by orders of
magnitude, so the paper's ``λI`` is applied to the diagonal), and a step is kept only if ε drops.
Weights are never taken outside [−0.5, 1.5]: a step that would is shortened.

Phases (§6.1.2): pose first (6 parameters), then the expression parameters; by default all regions'
``α`` in one LM (their Jacobian columns barely overlap, and one rendering serves all regions); with
``per_region=True`` each region gets its own LM in turn, as in the paper. For the expression phase
both the frame and the rendering are bandpass filtered (difference of Gaussians,
:attr:`TrackOptions.bandpass`), which removes the colour/brightness offsets between the footage and
the model's textures (§6.2).

Beyond the paper, the expression phase also refines the pose (``joint=True``, the default): pose
and expression are coupled (opening the jaw moves the chin like a change of depth or pitch), and
alternating them converges slowly — measured on the benchmark's sequence (a), the video rendered
from the model itself, one pose-then-expression round per frame left a steady ~1 mm depth error
(0.4 mm after 2 rounds, 0.2 mm after 3 rounds of 20 iterations), while one joint LM gets 0.06–0.1 mm at
a third of the cost.

Stopping (measured with ``benchmarks/bench_track.py``): each LM phase runs until a step would move,
or has just moved, the surface by less than a tolerance in mm (:meth:`FrameFitter._step_size`:
depth counts like the other translations although the image sees it least), or the quadratic model
predicts a negligible decrease of ε — :attr:`TrackOptions.pose_tolerance_mm` (1 mm: the pose phase
only has to bring the expression phase close) and :attr:`TrackOptions.step_tolerance_mm` (0.1 mm) —
with caps of :attr:`TrackOptions.pose_iterations` / :attr:`TrackOptions.expression_iterations`
that only a fast movement reaches. The former fixed budget (one pose step, three expression steps)
left a frame ~9° from its prediction at 1.8°, and the error then grew from frame to frame (a
10-frame version of the sample motion diverged); a tight image-space tolerance (0.02 px) spent
renderings on frames already converged. A tracked frame usually costs three renderings (the
prediction, one pose step, one joint step) and one bandpassed Jacobian: after an accepted step the
next one is solved with the previous Jacobian first, and the phase ends there when it is under the
tolerance (:meth:`FrameFitter._lm`).

Cost: the model is rasterised once into barycentric coordinates and triangle ids, only over its
bounding box (:func:`tracking.blendshape_face.render_model`, ~7 ms of GL on llvmpipe plus ~4 ms of numpy
at 300×300); the unfiltered analytic Jacobian has rows only at the covered pixels (it vanishes
elsewhere), the filtered one is bandpassed for all its columns in one call (~8 of its ~18 ms);
everything is float32 and laid out so that products run along the pixels; BLAS is kept to one
thread during a fit (its spinning second thread took a core from the software rasteriser).

Jacobians (§6.1.3): ``"analytic"`` — Eq. (7): the image gradient (Sobel) times the image motion of
the surface point under each pixel, ``∂x/∂p = ∂P/∂m' · ∂m'/∂p`` with ``∂P/∂m'`` of App. B.1 and
``∂m'/∂ω_l = e_l × R(m − c)``, ``∂m'/∂t_l = e_l``, ``∂m'/∂α = R Σ_k ∂W_k/∂α E_k`` (App. B.2), plus the
blending term ``Σ_k ∂W_k/∂α Î_k``. The per-vertex derivatives are interpolated at every pixel from
the barycentric render (:class:`tracking.blendshape_face.ModelRender`) — no loop over pixels or vertices.
Note the sign: a surface moving by ``δx`` changes the image at a fixed pixel by ``−∇Î·δx``
(Eq. 7 is written without it; the finite-difference test pins it). ``"fd"`` — central differences
(§6.1.3.1), two renderings per parameter. ``benchmarks/bench_track.py --jacobians`` compares them;
the defaults follow that measurement (see :data:`DEFAULT_JACOBIANS`).

Prediction (§6.2): the first frame starts from the user's pose (or :func:`pose_from_clicks`), later
ones from the linear extrapolation of the two previous results (:func:`predict`).
"""

from __future__ import annotations

import contextlib
from dataclasses import dataclass, field

import cv2
import numpy as np
from threadpoolctl import ThreadpoolController

from photomodel.camera import Camera, rodrigues, rotation_vector
from photomodel.errors import FitError
from photomodel.rendering.barycentric import interpolate
from photomodel.rendering.renderer import get_renderer
from tracking.blendshape_face import WEIGHT_RANGE, FaceModel, ModelRender, render_model, smooth_membership
from tracking.landmark_term import LandmarkTerm

__all__ = [
    "DEFAULT_JACOBIANS",
    "TrackOptions",
    "FrameState",
    "FrameResult",
    "FrameFitter",
    "Phase",
    "ExpressionSystem",
    "predict",
    "nearest_rotation",
    "track_frames",
    "single_threaded_blas",
    "pose_from_clicks",
    "bandpass",
    "home_regions",
    "outlier_pixels",
    "mirrored_pairs",
    "OUTLIER_FACTOR",
]

#: Jacobian used per phase by default; chosen from ``benchmarks/bench_track.py --jacobians``
#: (sequence b, 20 frames, 2-core llvmpipe): finite differences for the pose phase gave the same
#: accuracy (0.026° / 0.15 mm vs 0.027° / 0.14 mm) at 2.3× the time (19.6 vs 6.0 renderings per
#: frame); for the expression phase (with the pose, ``joint``) they were less accurate (0.21 vs
#: 0.14 mm) at 5.6× the time. Analytic columns point like the differences' (cosine 0.81 pose, 0.97
#: expression, mean) and cost 4 / 15 ms instead of 190 / 120 ms.
DEFAULT_JACOBIANS = {"pose": "analytic", "expression": "analytic"}
#: A frame whose image RMS after fitting exceeds this (intensity in [0, 1]) is flagged diverged.
DIVERGED_RMS = 0.12
#: Fewer covered pixels than this: the model left the frame.
MIN_PIXELS = 200
#: Central-difference steps: rotation (rad), translation (mm), expression parameter (mm RMS units).
#: Steps of a few tenths of a pixel or more: smaller ones see the rasterisation of internal
#: occlusion edges (nose, lips) flip pixels, and the differences become noise.
FD_STEPS = {"rotation": 1e-2, "translation": 2.0, "alpha": 0.3}
#: The approximate Gauss–Newton matrix of the bandpassed phase (:meth:`FrameFitter._filtered_system`)
#: sums every this-many-th covered pixel in each direction (the bandpassed Jacobian is smooth at
#: the filter's scale, σ ≥ 1 px).
HESSIAN_STRIDE = 2
#: ... and is used for systems of more columns than this (the rig's 51 shapes); fewer columns (the
#: photographed expressions) are filtered exactly, which costs little there and converges in fewer
#: steps (measured: a 9° head movement, 8 steps: 0.19° exact, 1.07° approximated).
APPROX_COLUMNS = 24
#: Radius (mm) over which a rotation step is turned into image motion for the stopping test.
HEAD_RADIUS_MM = 100.0
#: Most channels OpenCV's filters take in one call (a Jacobian of many parameters is filtered in parts).
CV_MAX_CHANNELS = 128
#: Smallest robust scale σ (intensity units): a frame the model renders exactly (the benchmark's
#: sequence a) would otherwise get σ → 0 and every pixel would count as an outlier.
ROBUST_FLOOR = 0.005
#: The same for a model with a shared basis (the rig's ARKit shapes): measured on renders of the
#: rigged sample (30 frames, talking, blinking), with 0.005 a blink or a jaw opening faster than
#: the prediction left the mouth and eyes as outliers, and the weights stayed behind (jawOpen
#: error 0.18, blinks missed); with 0.1, 0.007 — as without the robust error — while on real
#: footage σ is set by the median residual, not the floor.
SHARED_ROBUST_FLOOR = 0.1


@dataclass
class TrackOptions:
    """Settings of :class:`FrameFitter` (defaults measured by ``benchmarks/bench_track.py``)."""

    #: most LM iterations of the pose phase and of the expression phase; both usually end earlier,
    #: on the tolerances below (a fast head movement takes more).
    pose_iterations: int = 6
    expression_iterations: int = 8
    pose_jacobian: str = DEFAULT_JACOBIANS["pose"]
    expression_jacobian: str = DEFAULT_JACOBIANS["expression"]
    #: (σ_fine, σ_coarse) px of the difference of Gaussians for the expression phase; None: off.
    bandpass: tuple | None = (1.0, 4.0)
    #: penalty constant per covered pixel (D's ``c`` = penalty × pixels).
    penalty: float = 0.01
    damping: float = 1e-3
    per_region: bool = False
    #: the expression phase refines the pose too (one LM over pose and α; beyond the paper)
    joint: bool = True
    #: pose-then-expression rounds per frame (a first frame far from the truth needs 2; tracked
    #: frames start from the prediction and need 1).
    rounds: int = 1
    #: extra tries with larger λ after a rejected step.
    max_rejections: int = 2
    #: the expression (last) phase ends when a step would move, or has just moved, the surface by
    #: less than this (mm: rotation over :data:`HEAD_RADIUS_MM`, translation including depth, α);
    #: or when the step's predicted decrease of ε is below ``decrease_tolerance`` × ε.
    step_tolerance_mm: float = 0.1
    #: the same for the pose phase, which only has to bring the expression phase close.
    pose_tolerance_mm: float = 1.0
    decrease_tolerance: float = 1e-3
    #: a tracked frame's phase (not one fitted in several rounds) also ends after an accepted step
    #: that lowered ε by less than this fraction (beyond the paper): with the rig's 51 shapes, real
    #: footage left steps of 0.3–1 mm that each lowered ε by 0.1–0.5 % — shapes the image barely
    #: tells apart, creeping to the iteration cap (see docs/tracking.md, "Per-frame budget").
    min_gain: float = 0.005
    #: weight in ε of the pixels where the model is not face — outside the generic mesh's face
    #: mask and the control regions (hair, ears, neck, the back of the head), with a smooth
    #: transition — and of the silhouette's surroundings
    #: that the bandpass reaches. Beyond the paper, which weighs every pixel of the model alike:
    #: a model modeled from photos is reliable on the face only (the clicks and curves constrain
    #: it; ears and hair are textured from one photo, their shape is the generic mesh's), and those
    #: pixels pulled its pose and expression (the sample video, seq. b: 4.1 → 1.8 mm geometry
    #: error with 1.0 → 0.0). 1.0: the paper's ε. A frame fitted in several ``rounds`` (the first)
    #: uses the paper's ε in all rounds but the last: the silhouette pulls a far start in.
    outside_weight: float = 0.0
    #: robust error (beyond the paper, whose ε is plain least squares): Geman–McClure on each
    #: pixel's residual with σ this many times the median residual of the frame (see
    #: :meth:`FrameFitter._robust`); None: the paper's ε. A hand over the mouth then weighs like a
    #: few pixels, not like the strongest edges of the image.
    robust_scale: float | None = 3.0
    #: the robust weights of the unfiltered (pose) phase come from the residual averaged over a
    #: ``robust_window`` × ``robust_window`` box (beyond the paper; 1: each pixel's own residual).
    #: An occluder is a region, not a pixel: averaging keeps its weight low, while per-pixel noise
    #: no longer raises σ (the median residual) and with it the weight of the model's own
    #: mismatch. Measured (bench_track.py, 20 frames; docs/tracking.md, "Noise and colour"):
    #: geometry b 0.924 → 0.895, d (noise) 1.043 → 1.020 mm, f's expression r 0.60 → 0.71.
    #: The filtered phase keeps each pixel's own: its bandpass already averages (box-averaging
    #: there cost b's expression r 0.999 → 0.953).
    robust_window: int = 3
    #: match the footage's colour to the model's (beyond the paper, whose ε assumes the video
    #: lit like the photos; Face2Face estimates the illumination per frame): after each frame that
    #: did not diverge, per channel gain and offset from the least-squares regression of the frame
    #: on the rendering over the covered inlier pixels (the frame regressed on the rendering, so
    #: that the footage's noise does not bias the gain), blended into the running estimate with
    #: weight ``colour_smoothing`` and applied to the next frame before it is compared.
    #: Measured: sequence c (channels ×1.10/0.92/1.05, offsets ±0.04) 1.006 → 0.931 mm.
    colour_match: bool = True
    colour_smoothing: float = 0.5
    #: strength of the coherence prior (beyond the paper; ``0`` turns it off), in units of
    #: :attr:`penalty`: a control region may show an expression no more than the expression's
    #: *home* region does (the region where the model's expression moves the face most), and the
    #: excess costs ``coherence · c · excess²``. A region that sees something no expression of
    #: the model makes (raised cheeks and lower lids of a real smile, in the eye region) then stays
    #: near neutral instead of borrowing an unrelated expression (the eyes' part of ``frown``)
    #: that the home region (the brows) does not show. See :meth:`FrameFitter._penalty`.
    coherence: float = 1.0
    #: Gauss–Newton matrix of the bandpassed analytic Jacobian: ``"filtered"`` — every column's
    #: image bandpassed (exact); ``"image"`` — from the bandpassed rendering's gradient, the
    #: gradient of ε still exact (:meth:`FrameFitter._filtered_system`; beyond the paper, measured
    #: in docs/tracking.md, "Per-frame budget").
    filtered_hessian: str = "image"  # for systems of more than APPROX_COLUMNS columns
    #: Priors on the weights of a shared basis (the rig's ARKit shapes, :mod:`tracking.arkit_face`;
    #: beyond the paper), each in units of :attr:`penalty` like :attr:`coherence`, for what the views
    #: cannot separate (see docs/tracking.md, "Tracking in ARKit terms", for the measurements):
    #: ``sparsity`` · c · Σ_k a_k (a shape not needed stays at 0: with 51 shapes several explain
    #: the same pixels), ``symmetry`` · c · Σ (a_left − a_right)² over the pairs of
    #: :func:`mirrored_pairs` (where
    #: the data are silent, the two sides move alike; a wink the image sees outweighs it), and
    #: ``smoothness`` · c · Σ_k (a_k − â_k)² with â the frame's prediction (the weights of the
    #: two frames before, extrapolated, clipped to [0, 1]; not on a frame fitted from a pose).
    #: No effect on a model without a shared basis.
    sparsity: float = 1e-3
    symmetry: float = 2e-4
    smoothness: float = 1e-2  # 1e-3 until 2026-12-05: docs/tracking.md, "The smoothness prior on real footage"
    #: weight κ of the detector's landmarks in ε when a frame is fitted with them (beyond the
    #: paper; :mod:`tracking.landmark_term`): every landmark an outlier costs κ × what every
    #: pixel an outlier costs. 0: analysis by synthesis alone. Used with the robust error only;
    #: ``facestudio track`` fits every tracked frame with them (``--landmark-weight``). Measured
    #: (docs/tracking.md, "The detector's landmarks in ε"): the real clip's mouth on wide smiles
    #: follows; on renders with known weights the ARKit weight error 0.003 → 0.007.
    landmarks: float = 0.05
    #: the Geman–McClure scale τ (px) of the landmark term: a detection further than a few τ
    #: from the model's feature (a landmark under a hand) pulls next to nothing.
    landmark_scale_px: float = 3.0
    #: a tracked frame takes the landmark term only where the prediction's features are on
    #: average further than this (px, in the fitted frame) from the detector's: where the
    #: prediction already agrees, the image alone holds the frame and the term's extra LM steps
    #: are not spent (0: every frame).
    landmark_gate_px: float = 0.0

    def __post_init__(self):
        for name in ("pose_jacobian", "expression_jacobian"):
            if getattr(self, name) not in ("analytic", "fd"):
                raise ValueError(f"{name} must be 'analytic' or 'fd', got {getattr(self, name)!r}")
        if self.filtered_hessian not in ("filtered", "image"):
            raise ValueError(f"filtered_hessian must be 'filtered' or 'image', got {self.filtered_hessian!r}")
        if not (isinstance(self.robust_window, int) and self.robust_window >= 1 and self.robust_window % 2):
            raise ValueError(f"robust_window must be an odd integer ≥ 1, got {self.robust_window!r}")
        if not 0.0 < self.colour_smoothing <= 1.0:
            raise ValueError(f"colour_smoothing must be within (0, 1], got {self.colour_smoothing}")


@dataclass
class FrameState:
    """Parameters of one frame: ``R`` (3, 3), ``t`` (3,) mm (model centre in camera space), ``alpha``."""

    R: np.ndarray
    t: np.ndarray
    alpha: np.ndarray

    def copy(self) -> FrameState:
        return FrameState(self.R.copy(), self.t.copy(), self.alpha.copy())


@dataclass
class FrameResult:
    """Result of fitting one frame.

    Attributes
    ----------
    state : FrameState
    weights : (R, m) blending weights per region.
    rms : float, image RMS over the covered pixels (intensity units, [0, 1] scale), unfiltered.
    pixels : int, covered pixels.
    evaluations : int, renderings used.
    diverged : bool, image RMS over :data:`DIVERGED_RMS` (with the robust error: over the pixels that
        are not outliers, :meth:`FrameFitter._inlier_rms`) or model (nearly) out of the frame.
    history : list of float, ε after each accepted step.
    """

    state: FrameState
    weights: np.ndarray
    rms: float
    pixels: int
    evaluations: int
    diverged: bool
    history: list = field(default_factory=list)


def bandpass(image: np.ndarray, sigmas: tuple) -> np.ndarray:
    """Difference of Gaussians ``G_σ1 * I − G_σ2 * I`` of an (H, W, C) float image (§6.2),
    kernels cut at 3σ (the fitter's crops keep 3σ2 of margin around the model).

    Not computed on an image pyramid, although 2–3× faster: decimation makes the operator
    shift-variant, ε then jitters as the model moves, and LM stalled (measured: joint fit from
    2°/9 mm ended at 0.25° instead of 0.02°)."""
    s1, s2 = sigmas
    if image.ndim == 3 and image.shape[2] > CV_MAX_CHANNELS:  # OpenCV filters at most this many at once
        out = np.empty_like(image)
        for c in range(0, image.shape[2], CV_MAX_CHANNELS):
            out[:, :, c : c + CV_MAX_CHANNELS] = bandpass(
                np.ascontiguousarray(image[:, :, c : c + CV_MAX_CHANNELS]), sigmas
            )
        return out
    k1, k2 = 2 * int(np.ceil(3 * s1)) + 1, 2 * int(np.ceil(3 * s2)) + 1
    a = cv2.GaussianBlur(image, (k1, k1), s1, borderType=cv2.BORDER_REPLICATE)
    b = cv2.GaussianBlur(image, (k2, k2), s2, borderType=cv2.BORDER_REPLICATE)
    return np.subtract(a, b, out=a)


def nearest_rotation(R: np.ndarray) -> np.ndarray:
    """The rotation closest to a (3, 3) matrix in the Frobenius norm (polar factor, via SVD)."""
    U, _, Vt = np.linalg.svd(np.asarray(R, float))
    if np.linalg.det(U @ Vt) < 0:
        U[:, -1] = -U[:, -1]
    return U @ Vt


def predict(previous: list[FrameState]) -> FrameState:
    """Initial parameters of the next frame: linear extrapolation of the last two (§6.2);
    the last one alone if there is only one.

    Rotation extrapolates as ``R̂(ω) R₁`` with ``ω`` the rotation vector of ``R₁ R₀ᵀ``, both
    projected onto rotations first. The plain product ``(R₁ R₀ᵀ) R₁`` does not stay a rotation:
    a small symmetric error ``R = Q (I + S)`` propagates as ``S₂ ≈ 2 S₁ + S₀`` (``R₀ᵀ`` is not
    ``R₀⁻¹`` when ``R₀`` is off), growing by ``1 + √2`` per frame from round-off — after ~35 frames
    the model shrank by percents and the tracker compensated in depth (the sample video's frames
    36–39 drifted by 5 → 87 mm before this)."""
    if not previous:
        raise ValueError("predict needs at least one previous frame")
    if len(previous) == 1:
        st = previous[-1].copy()
        st.R = nearest_rotation(st.R)
        return st
    a, b = previous[-2], previous[-1]
    Ra, Rb = nearest_rotation(a.R), nearest_rotation(b.R)
    R = rodrigues(rotation_vector(Rb @ Ra.T)) @ Rb
    return FrameState(R, 2 * b.t - a.t, 2 * b.alpha - a.alpha)


def pose_from_clicks(
    model: FaceModel, vertices: np.ndarray, clicks: np.ndarray, focal_px: float, width: int, height: int
) -> FrameState:
    """Head pose of the first frame from a few clicked points (neutral expression assumed).

    The modeling core's :func:`photomodel.modeling.pose.recover_poses` solves several photos and the 3D
    points together; here the 3D points are the model's and there is a single view, a
    perspective-n-point problem, solved with OpenCV's ``solvePnP`` (iterative LM from the EPnP
    estimate; a kept implementation).

    Parameters
    ----------
    model : FaceModel
    vertices : (k,) int, model vertex of each click (k ≥ 6).
    clicks : (k, 2) float px (u right, v down, centres at integers).
    focal_px, width, height : the video camera.
    """
    idx = np.asarray(vertices, np.int64)
    uv = np.asarray(clicks, float)
    if uv.shape != (len(idx), 2) or len(idx) < 6:
        raise FitError(f"need at least 6 clicks as (k, 2) pixels for k vertices; got {uv.shape} for {len(idx)}")
    ok = np.all(np.isfinite(uv), axis=1)
    if ok.sum() < 6:
        raise FitError(f"only {int(ok.sum())} finite clicks; at least 6 are needed for the first frame's pose")
    cam = Camera(np.eye(3), np.zeros(3), focal_px, width, height)
    X = model.geometry[0][idx[ok]] - model.centre
    found, rvec, tvec = cv2.solvePnP(X, uv[ok], cam.K, None, flags=cv2.SOLVEPNP_EPNP)
    if not found:
        raise FitError("the clicked points do not determine a pose (collinear or inconsistent clicks)")
    found, rvec, tvec = cv2.solvePnP(X, uv[ok], cam.K, None, rvec, tvec, True, cv2.SOLVEPNP_ITERATIVE)
    R = rodrigues(rvec.ravel())
    return FrameState(R, tvec.ravel().astype(float), model.alpha_of_weights(np.eye(model.m)[0]))


#: A covered pixel whose unfiltered residual (RMS over RGB) exceeds this many times the frame's
#: median is an outlier: left out of the divergence test and drawn as occluded in the overlay.
OUTLIER_FACTOR = 3.0


def outlier_pixels(pixel_rms: np.ndarray) -> np.ndarray:
    """(N,) bool: the covered pixels whose residual ``pixel_rms`` (N,) is over
    :data:`OUTLIER_FACTOR` × the median — what the robust error treats as not the face (a hand,
    hair, a reflection)."""
    r = np.asarray(pixel_rms)
    if not len(r):
        return np.zeros(0, bool)
    return r > OUTLIER_FACTOR * float(np.median(r))


def mirrored_pairs(names) -> np.ndarray:
    """(p, 2) int: the pairs of ``names`` that are one motion on the two sides of the face, which the
    symmetry prior (:attr:`TrackOptions.symmetry`) keeps alike: ``<stem>Left`` with ``<stem>Right``
    (ARKit's names; the subject's sides), except the sideways motions ``jawLeft``/``jawRight`` and
    ``mouthLeft``/``mouthRight`` (opposites, not sides), and with the gaze's conjugate pairs for the
    eyes (looking left turns the left eye out and the right eye in: ``eyeLookOutLeft`` with
    ``eyeLookInRight``, ``eyeLookInLeft`` with ``eyeLookOutRight``)."""
    names = list(names)
    swap = {"eyeLookOut": "eyeLookIn", "eyeLookIn": "eyeLookOut"}
    pairs = []
    for i, n in enumerate(names):
        if not n.endswith("Left") or n in ("jawLeft", "mouthLeft"):
            continue
        stem = n[: -len("Left")]
        partner = swap.get(stem, stem) + "Right"
        if partner in names:
            pairs.append((i, names.index(partner)))
    return np.array(pairs, int).reshape(-1, 2)


def home_regions(model: FaceModel) -> np.ndarray:
    """(m,) int: each expression's *home* control region (index into ``model``'s regions, ≥ 1; 0
    for neutral) — where it moves the face most: the largest ``Σ_i μ_ir ‖E_k,i − E_0,i‖²`` over the
    control regions (membership-weighted squared displacement from neutral). Used by the
    coherence prior (:attr:`TrackOptions.coherence`)."""
    disp = ((model.geometry - model.geometry[:1]) ** 2).sum(axis=2)  # (m, n)
    energy = disp @ model.membership[:, 1:]  # (m, R − 1)
    home = 1 + np.argmax(energy, axis=1)
    home[0] = 0
    if model.n_shared:  # a shared shape's home is the shared row (:meth:`FaceModel.region_weights`)
        home[model.shared_expressions] = len(model.bases)
    return home


@dataclass(frozen=True)
class Phase:
    """One Levenberg–Marquardt phase of a frame's fit (:meth:`FrameFitter.refine`).

    Attributes
    ----------
    params : (k,) int, the parameters the phase moves: 0–2 rotation ω, 3–5 translation, 6+ α.
    iterations : int, most LM iterations.
    jacobian : str, ``"analytic"`` or ``"fd"`` (see :data:`DEFAULT_JACOBIANS`).
    filtered : bool, ε on the bandpassed images (:attr:`TrackOptions.bandpass`).
    tolerance_mm : float or None, the step size (mm) that ends the phase; None:
        :attr:`TrackOptions.step_tolerance_mm`.
    reuse : bool, solve a step with the previous Jacobian first after an accepted one (the tracked
        frames' economy; off for a frame far from its optimum, see :meth:`FrameFitter.fit`).
    """

    params: np.ndarray
    iterations: int
    jacobian: str
    filtered: bool
    tolerance_mm: float | None = None
    reuse: bool = True


class _PixelSubset:
    """Some of a :class:`ModelRender`'s covered pixels (``sel``) seen as a render of their own
    (what :meth:`FrameFitter._pixel_jacobian` reads), with the texture colours ``colors`` there."""

    def __init__(self, render: ModelRender, sel: np.ndarray, colors: list):
        self.image, self.box = render.image, render.box
        self.pixels, self.X_cam, self.texture_colors = render.pixels[sel], render.X_cam[sel], colors
        self._corners, self._bary = render.corners[sel], render.bary[sel]

    def interpolate(self, values: np.ndarray) -> np.ndarray:
        values = np.asarray(values)
        flat = interpolate(values.reshape(len(values), -1), self._corners, self._bary)
        return flat.reshape((len(self._bary),) + values.shape[1:])


@dataclass
class ExpressionSystem:
    """A frame's image term linearised with respect to ``α`` (:meth:`FrameFitter.linearise_expression`).

    Attributes
    ----------
    JtJ : (a, a) float, ``JᵀJ`` of the weighted residual's Jacobian (Gauss–Newton Hessian).
    Jtr : (a,) float, ``Jᵀ r`` with ``r = I_t − Î`` the weighted residual.
    pixels : int, covered pixels (the scale of the penalty D).
    """

    JtJ: np.ndarray
    Jtr: np.ndarray
    pixels: int


@dataclass
class _Eval:
    state: FrameState
    render: ModelRender
    weights: np.ndarray  # (R, m)
    diff: np.ndarray  # (h, w, 3) float32 crop of frame − Î (0 outside the mask), filtered when bandpassed
    eps: float
    box: tuple  # (y0, y1, x0, x1) of the crop
    rms: float  # unfiltered image RMS over the covered pixels
    local: np.ndarray  # (N,) flat indices of the covered pixels in the crop
    sw: np.ndarray | None = None  # (h·w,) float32 √ of the pixels' weights in ε (None: all 1)
    pixel_rms: np.ndarray | None = None  # (N,) float32 unfiltered RMS over RGB of each covered pixel
    mark_c: float = 0.0  # c_L of the landmark term in ε (0: none; tracking.landmark_term)


class FrameFitter:
    """Fits :class:`FaceModel` parameters to frames seen by one fixed video camera.

    Parameters
    ----------
    model : FaceModel
    focal_px : float, the video camera's focal length (pixels).
    width, height : int, frame size.
    options : TrackOptions, optional.
    renderer : photomodel.rendering.renderer.Renderer, optional (default: this thread's).
    """

    def __init__(
        self,
        model: FaceModel,
        focal_px: float,
        width: int,
        height: int,
        options: TrackOptions | None = None,
        renderer=None,
    ):

        self.model = model
        self.f, self.W, self.H = float(focal_px), int(width), int(height)
        self.options = options or TrackOptions()
        self.renderer = renderer or get_renderer()
        self.evaluations = 0
        # ∂X_i/∂α per vertex (n, A, 3): μ_ir Σ_k Q_r(k, l) E_k,i (App. B.2), and the blending
        # coefficients per texture group (G, A): Σ_{k in group} Q_r(k, l)
        # (a shared basis, when the model has one, is the last "region", its membership 1 everywhere)
        cols, blend, region_of = [], [], []
        groups = model.texture_groups()
        membership = model.all_membership
        for r, Q in enumerate(model.all_bases):
            for j in range(Q.shape[1]):
                cols.append(membership[:, r, None] * np.einsum("k,knd->nd", Q[:, j], model.geometry))
                blend.append([Q[ks, j].sum() for _, ks in groups])
                region_of.append(r)
        n = model.geometry.shape[1]
        self._dX_dalpha = np.stack(cols, axis=1) if cols else np.zeros((n, 0, 3))
        self._blend = np.array(blend).reshape(len(cols), len(groups))
        self._alpha_region = np.array(region_of, int)
        self.n_alpha = len(cols)
        self._dX_dalpha32 = self._dX_dalpha.astype(np.float32)
        self._dX_dalpha32_flat = np.ascontiguousarray(self._dX_dalpha32.reshape(n, -1))
        self._dX_by_axis = np.ascontiguousarray(self._dX_dalpha32.transpose(2, 0, 1))  # (3, n, A)
        # D's weights are linear in α: w_r = Q_r α_r + w* (regions 1.., rows (region, expression))
        m = model.m
        bases = model.all_bases
        slices = model.alpha_slices + ([model.shared_slice] if model.n_shared else [])
        self._dw_dalpha = np.zeros(((len(bases) - 1) * m, self.n_alpha))
        for r, (Q, sl) in enumerate(zip(bases, slices, strict=True)):
            if r:
                self._dw_dalpha[(r - 1) * m : r * m, sl] = Q
        self._home = home_regions(model)
        self._membership32 = membership.astype(np.float32)
        # the shared shapes' weights in D's flattened weights (rows: regions 1.., then the shared
        # row), their Left/Right pairs, and the prediction the smoothness prior pulls towards
        shared = np.flatnonzero(model.shared_expressions)
        self._shared_w = (len(bases) - 2) * m + shared if len(shared) else np.zeros(0, int)
        self._shared_pairs = mirrored_pairs([model.names[k] for k in shared])
        self._anchor: np.ndarray | None = None
        self._prior_scale = 1.0
        self._marks: LandmarkTerm | None = None  # the frame's landmarks (fit(landmarks=...))
        self._mark_c: dict[bool, float] = {}  # c_L per phase (filtered or not) of the frame
        # per-vertex weight of the pixels in ε (TrackOptions.outside_weight): 1 on the face,
        # ``outside_weight`` elsewhere, across a transition as wide as the regions' (smoothed)
        o = float(self.options.outside_weight)
        if not 0.0 <= o <= 1.0:
            raise ValueError(f"outside_weight must be within [0, 1], got {o}")
        self._face_weight, self._weighted = None, True
        self._sigma2: dict[bool, float] = {}  # robust scale² per phase (filtered or not) of the frame
        self._colour: np.ndarray | None = None  # (2, 3) gain, offset taking the footage to the model
        if o < 1.0:
            face = smooth_membership(np.asarray(model.face_mask, np.int64), model.faces)[:, 1]
            face = np.maximum(face, 1.0 - model.membership[:, 0])  # and the control regions (the jaw)
            self._face_weight = (o + (1.0 - o) * np.clip(face, 0.0, 1.0)).astype(np.float32)

    # -- model at parameters -----------------------------------------------------------
    def camera(self, state: FrameState) -> Camera:
        """The model's pose as a camera: ``X_cam = R (X − c) + t``."""
        return Camera(state.R, state.t - state.R @ self.model.centre, self.f, self.W, self.H)

    def _evaluate(self, frame: np.ndarray, state: FrameState, filtered: bool, render=None) -> _Eval:
        """ε at ``state``; ``render`` reuses a rendering of that state (another phase's)."""
        model = self.model
        weights = model.region_weights(state.alpha)
        if render is None:
            Wv = model.vertex_weights(weights)
            X = model.blend_geometry(Wv)
            render = render_model(self.renderer, self.camera(state), model, X, Wv, background=frame)
            self.evaluations += 1
        box = self._box(render.box, filtered)
        y0, y1, x0, x1 = box
        diff = frame[y0:y1, x0:x1] - render.image[y0:y1, x0:x1]
        py, px = np.divmod(render.pixels, self.W)
        local = (py - y0) * (x1 - x0) + (px - x0)
        # over the covered pixels only, each channel's residual clipped to the intensities' range
        covered = np.clip(np.take(diff.reshape(-1, 3), local, axis=0), -1.0, 1.0)
        pixel_rms = np.sqrt((covered * covered).mean(axis=1))
        rms = float(np.sqrt((covered * covered).sum() / max(covered.size, 1)))
        if filtered:
            diff = bandpass(diff, self.options.bandpass)
        sw = None
        if self._face_weight is not None and self._weighted:
            sw = np.full((y1 - y0) * (x1 - x0), np.sqrt(self.options.outside_weight), np.float32)
            sw[local] = np.sqrt(np.maximum(render.interpolate(self._face_weight), 0.0))
            diff = diff * sw.reshape(y1 - y0, x1 - x0, 1)
        image_eps, robust = self._robust(diff, local, filtered)
        if robust is not None:
            diff = diff * robust.reshape(y1 - y0, x1 - x0, 1)
            sw = robust if sw is None else sw * robust
        eps = image_eps + self._penalty(weights, render)[0]
        c_mark = self._mark_weight(filtered, robust is not None, len(render.pixels))
        if c_mark:
            eps += c_mark * self._marks.value(state)
        return _Eval(state, render, weights, diff, eps, box, rms, local, sw, pixel_rms, c_mark)

    def landmark_term(self, vertices, uv) -> LandmarkTerm:
        """The landmark term (:mod:`tracking.landmark_term`) of the model's vertices ``vertices``
        (k,) detected at ``uv`` (k, 2) px in this fitter's frames."""
        v = np.asarray(vertices, np.int64)
        X0 = self.model.geometry_at(np.zeros(self.n_alpha))[v]
        principal = self.camera(FrameState(np.eye(3), np.zeros(3), np.zeros(self.n_alpha))).principal_point
        uv = np.asarray(uv, float).reshape(-1, 2)
        return LandmarkTerm(
            X0,
            self._dX_dalpha[v],
            uv,
            np.asarray(self.model.centre, float),
            self.f,
            principal,
            float(self.options.landmark_scale_px),
        )

    def _mark_weight(self, filtered: bool, robust: bool, pixels: int) -> float:
        """``c_L`` of the landmark term in this phase of the frame (0 without landmarks, without
        the robust error, or with :attr:`TrackOptions.landmarks` 0): κ σ² N / k, fixed at the
        phase's first evaluation so that ε stays one function within it."""
        if self._marks is None or not robust or not self.options.landmarks or not len(self._marks.uv):
            return 0.0
        c = self._mark_c.get(filtered)
        if c is None:
            c = self.options.landmarks * self._prior_scale * max(pixels, 1) / len(self._marks.uv)
            self._mark_c[filtered] = c
        return c

    def _robust(self, diff: np.ndarray, local: np.ndarray, filtered: bool) -> tuple[float, np.ndarray | None]:
        """The image part of ε and the √ of the pixels' robust weights (h·w,) float32 (None: plain ε).

        Geman–McClure on each pixel's residual norm ``r`` (RGB, after the filter and the face
        weights): ``ρ(r) = ½ σ² r² / (σ² + r²)`` — quadratic for ``r ≪ σ``, bounded by ``½ σ²``
        for an outlier (a hand over the mouth, hair across the brow), so an occluder cannot drag
        the pose or the expression however different it looks. LM then works on the re-weighted
        least squares of the same minimum (IRLS): rows weighted by ``√w = σ² / (σ² + r²)``.
        ``σ`` is :attr:`TrackOptions.robust_scale` × the median ``r`` over the covered pixels of the
        phase's first evaluation in this frame (:attr:`_sigma2`, per phase: filtered residuals
        are smaller), so that ε stays one function within a phase (LM compares its values) and
        the scale follows the footage (noise, lighting, the model's own texture error).
        """
        self._prior_scale = 1.0
        if self.options.robust_scale is None or not self._weighted:
            return 0.5 * float((diff * diff).sum()), None
        r2 = np.einsum("ijc,ijc->ij", diff, diff).reshape(-1)
        k = self.options.robust_window
        if k > 1 and not filtered:  # the weights from the box-averaged residual (TrackOptions.robust_window)
            box = cv2.blur(np.ascontiguousarray(diff, np.float32), (k, k))
            q2 = np.einsum("ijc,ijc->ij", box, box).reshape(-1)
        else:
            q2 = r2
        s2 = self._sigma2.get(filtered)
        if s2 is None:
            med = float(np.median(np.sqrt(np.take(q2, local)))) if len(local) else 0.0
            floor = SHARED_ROBUST_FLOOR if len(self._shared_w) else ROBUST_FLOOR
            s2 = max(self.options.robust_scale * med, floor) ** 2
            self._sigma2[filtered] = s2
        self._prior_scale = float(s2)  # the image part below carries σ²: so does a shared basis' prior
        s2 = np.float32(s2)
        w = s2 / (s2 + q2)
        return 0.5 * float(s2) * float((r2 * w).sum()), w

    def _box(self, box: tuple, filtered: bool) -> tuple:
        """The crop of the residual: the model's box plus a margin (2 px; the bandpass's reach
        when filtered)."""
        y0, y1, x0, x1 = box
        if y1 <= y0 or x1 <= x0:
            return (0, self.H, 0, self.W)
        m = 2 + (int(np.ceil(3 * self.options.bandpass[1])) if filtered and self.options.bandpass else 0)
        return (max(y0 - m, 0), min(y1 + m, self.H), max(x0 - m, 0), min(x1 + m, self.W))

    def _sides(self, weights: np.ndarray) -> np.ndarray:
        """(2, R − 1, m) int, the quadratic pieces of D that the weights are on: row 0, −1 where a
        control region's weight is below 0, +1 above 1, else 0; row 1, 1 where a region shows an
        expression more than the expression's home region (:func:`home_regions`), else 0."""
        return self._pieces(weights[1:], self._excess(weights))

    @staticmethod
    def _pieces(w: np.ndarray, excess: np.ndarray) -> np.ndarray:
        """:meth:`_sides` from the control regions' weights ``w`` and their :meth:`_excess`."""
        bounds = (w > 1.0).astype(int) - (w < 0.0).astype(int)
        return np.stack([bounds, (excess > 0.0).astype(int)])

    def _excess(self, weights: np.ndarray) -> np.ndarray:
        """(R − 1, m): each region's weight of each expression minus its home region's (0 for
        neutral, for the home region itself, and with the coherence prior off)."""
        w = weights[1:]
        out = np.zeros_like(w)
        if self.options.coherence > 0 and w.shape[1] > 1:
            out[:, 1:] = w[:, 1:] - w[self._home[1:] - 1, np.arange(1, w.shape[1])]
        return out

    def _penalty(self, weights: np.ndarray, render: ModelRender, sides: np.ndarray | None = None):
        """D, its gradient and Hessian with respect to the concatenated α.

        D = c Σ_r Σ_k [min(0, w_rk)² + max(0, w_rk − 1)²] + coherence · c Σ_{k>0} Σ_{r≠h(k)}
        max(0, w_rk − w_h(k)k)², ``h(k)`` the home region of expression ``k``
        (:attr:`TrackOptions.coherence`). ``sides`` (:meth:`_sides`) chooses the quadratic piece
        each term is on (default: where it is). D itself is always evaluated where the weights
        are; the gradient and Hessian are those of the chosen pieces — :meth:`_lm_step` uses
        pieces a step would enter. Weights are linear in α, so the derivatives are those with
        respect to the weights mapped through ``∂w/∂α``."""
        c = self.options.penalty * max(len(render.pixels), 1)
        kappa = c * self.options.coherence
        w = weights[1:]
        R1, m = w.shape
        excess = self._excess(weights)
        lo, hi = np.minimum(w, 0.0), np.maximum(w - 1.0, 0.0)
        D = c * float((lo**2).sum() + (hi**2).sum()) + kappa * float((np.maximum(excess, 0.0) ** 2).sum())
        if sides is None:
            sides = self._pieces(w, excess)
        bounds, above = sides
        resid = np.where(bounds < 0, w, np.where(bounds > 0, w - 1.0, 0.0))
        g_w = (2 * c * resid).ravel()
        H_w = np.diag(2 * c * (bounds != 0).ravel().astype(float))
        r, k = np.nonzero(above)  # the pairs (w_rk, w_hk): κ (w_rk − w_hk)²
        if len(r):
            i, j, e = r * m + k, (self._home[k] - 1) * m + k, 2 * kappa * excess[r, k]
            np.add.at(g_w, i, e)
            np.add.at(g_w, j, -e)
            for a_, b_, sign in ((i, i, 1.0), (j, j, 1.0), (i, j, -1.0), (j, i, -1.0)):
                np.add.at(H_w, (a_, b_), sign * 2 * kappa)
        if len(self._shared_w):
            Dp, gp, Hp = self.shared_prior(w.ravel(), c)
            # in ε beside the image part, scaled like it (σ² with the robust error, :meth:`_robust`);
            # in the normal equations beside JᵀJ, which is not scaled
            D, g_w, H_w = D + self._prior_scale * Dp, g_w + gp, H_w + Hp
        B = self._dw_dalpha
        return D, B.T @ g_w, B.T @ H_w @ B

    def shared_prior(self, w: np.ndarray, c: float) -> tuple[float, np.ndarray, np.ndarray]:
        """The priors on a shared basis' weights (:attr:`TrackOptions.sparsity`, ``symmetry``,
        ``smoothness``): value, gradient and Hessian with respect to D's flattened weights ``w``
        (rows: control regions 1.., then the shared row; see :meth:`_penalty`). Quadratic in ``w``,
        so exact in the normal equations; ``c`` the penalty constant of the frame."""
        o = self.options
        idx = self._shared_w
        D, g, H = 0.0, np.zeros(len(w)), np.zeros((len(w), len(w)))
        if o.sparsity:
            D += o.sparsity * c * float(w[idx].sum())
            g[idx] += o.sparsity * c
        if o.symmetry and len(self._shared_pairs):
            left, right = idx[self._shared_pairs[:, 0]], idx[self._shared_pairs[:, 1]]
            d = w[left] - w[right]
            k = o.symmetry * c
            D += k * float(d @ d)
            g[left] += 2 * k * d
            g[right] -= 2 * k * d
            H[left, left] += 2 * k
            H[right, right] += 2 * k
            H[left, right] -= 2 * k
            H[right, left] -= 2 * k
        if o.smoothness and self._anchor is not None:
            d = w[idx] - self._anchor
            k = o.smoothness * c
            D += k * float(d @ d)
            g[idx] += 2 * k * d
            H[idx, idx] += 2 * k
        return D, g, H

    # -- Jacobians --------------------------------------------------------------------
    def jacobian(self, frame: np.ndarray, ev: _Eval, params: np.ndarray, method: str, filtered: bool):
        """(P, k) float32 Jacobian of the (cropped, optionally filtered) rendering with respect to
        the parameters ``params`` (indices: 0–2 rotation ω, 3–5 translation, 6+ α); P = crop
        pixels × 3, rows in the order of ``ev.diff.reshape(-1)``."""
        if method == "fd":
            return self._jacobian_fd(frame, ev, params, filtered)
        return self._jacobian_analytic(ev, params, filtered)

    def _pixel_jacobian(
        self, ev: _Eval, params: np.ndarray, image: np.ndarray | None = None, colors: list | None = None, at=None
    ) -> tuple[np.ndarray, np.ndarray]:
        """Analytic derivatives of Î (RGB) at the covered pixels (Eq. 7, App. B): ``(J, rows)``,
        J (k, 3, N) float32 laid out parameter × channel × pixel (every product runs along the
        pixels), ``rows`` (N,) the pixels' flat indices in ``ev``'s crop box.

        Only the covered pixels: tried (measured on sequence a), extending the rows to the ring
        just outside the silhouette — where the Sobel gradient of Î (the frame outside the model)
        sees the other half of the edge — made LM converge more slowly, not faster.

        ``image`` (the crop of ``ev``'s box plus one pixel, as below) and ``colors`` (the
        texture groups' colours at the covered pixels) replace the rendering's own — the
        bandpassed ones for :meth:`_filtered_system`; ``at`` the interpolated geometry table of
        an earlier call with the same ``params`` (:meth:`_alpha_table`)."""
        r = ev.render
        N = len(r.pixels)
        G, q = self._motion_gradients(ev, image)
        Gx, Gy, Gz = G
        J = np.empty((len(params), 3, N), np.float32)
        for j, p in enumerate(params):
            if p < 3:  # ∂m'/∂ω_l = e_l × R(m − c): (e_l × q) · G
                a, b = (p + 1) % 3, (p + 2) % 3
                np.multiply(q[a], G[b], out=J[j])
                J[j] -= q[b] * G[a]
            elif p < 6:  # ∂m'/∂t_l = e_l
                J[j] = G[p - 3]
        alpha = np.flatnonzero(params >= 6)
        if len(alpha):  # ∂m'/∂α = R Σ_k ∂W_k/∂α E_k, plus the blending term Σ_k ∂W_k/∂α Î_k (App. B.3)
            a = params[alpha] - 6
            A = len(a)
            if at is None:
                at = self._alpha_table(ev, a)
            colors = [np.ascontiguousarray(c.T) for c in (r.texture_colors if colors is None else colors)]  # (3, N)
            for i, j in enumerate(alpha):
                Jj = J[j]
                np.multiply(Gx, at[3 * i], out=Jj)
                Jj += Gy * at[3 * i + 1]
                Jj += Gz * at[3 * i + 2]
                for g, c in enumerate(colors):
                    if self._blend[a[i], g]:
                        Jj += c * (np.float32(self._blend[a[i], g]) * at[3 * A + i])
        return J, ev.local

    def _alpha_table(self, ev: _Eval, a: np.ndarray) -> np.ndarray:
        """(4A, N) float32 at ``ev``'s covered pixels: ``∂m'/∂α`` (3 rows per parameter of ``a``)
        and the parameters' region memberships (the blending term's factor). Interpolated at the
        pixels first and rotated there (fewer pixels than vertices)."""
        A = len(a)
        full = A == self.n_alpha and np.array_equal(a, np.arange(A))
        dX = self._dX_dalpha32_flat if full else self._dX_dalpha32[:, a].reshape(len(self._dX_dalpha32), 3 * A)
        at = ev.render.interpolate(dX)  # (N, 3A)
        N = len(at)
        rot = (at.reshape(N * A, 3) @ ev.state.R.T.astype(np.float32)).reshape(N, 3 * A)
        mem = ev.render.interpolate(self._membership32[:, self._alpha_region[a]])
        return np.ascontiguousarray(np.concatenate([rot, mem], axis=1).T)

    def _filtered_system(self, ev: _Eval, params: np.ndarray) -> tuple:
        """The bandpassed analytic system without filtering the Jacobian's columns (beyond the
        paper; :attr:`TrackOptions.filtered_hessian` ``"image"``): ``(None, A, ("adjoint", ev))``.

        The gradient stays exact (:meth:`_adjoint_gradient`, at whichever evaluation the step is
        solved from). The Gauss–Newton matrix ``JᵀJ`` is approximated: the Jacobian is built from
        the gradient of the *bandpassed* rendering and the bandpassed texture colours —
        ``B(∇Î · v) ≈ ∇(BÎ) · v`` where the image motion ``v`` varies slowly over the filter's
        reach — at every :data:`HESSIAN_STRIDE`-th covered pixel in each direction, the sum scaled
        to all of them. LM's fixed point is the exact one (its gradient is); only the path there
        uses the approximation. Measured in docs/tracking.md ("Per-frame budget")."""
        r = ev.render
        k = len(params)
        y0, y1, x0, x1 = ev.box
        h, w = y1 - y0, x1 - x0
        sigmas = self.options.bandpass
        py, px = np.divmod(r.pixels, self.W)
        sel = np.flatnonzero((py % HESSIAN_STRIDE == 0) & (px % HESSIAN_STRIDE == 0))
        if len(sel) < 4 * k:
            sel = np.arange(len(py))
        image = bandpass(r.image[y0:y1, x0:x1], sigmas)
        colors = r.texture_colors
        a = params[params >= 6] - 6
        if len(a) and np.any(self._blend[a]):
            groups = np.zeros((h * w, 3 * len(colors)), np.float32)
            groups[ev.local] = np.concatenate(colors, axis=1)
            flat = bandpass(groups.reshape(h, w, -1), sigmas).reshape(h * w, -1)[ev.local[sel]]
            colors = [flat[:, 3 * g : 3 * g + 3] for g in range(len(colors))]
        else:
            colors = [c[sel] for c in colors]
        sub = _PixelSubset(r, sel, colors)
        # _pixel_jacobian takes the crop of the model's box plus one pixel: ev's box holds it
        by0, by1, bx0, bx1 = r.box
        cy0, cx0 = max(by0 - 1, 0) - y0, max(bx0 - 1, 0) - x0
        cy1, cx1 = min(by1 + 1, self.H) - y0, min(bx1 + 1, self.W) - x0
        view = _Eval(ev.state, sub, ev.weights, ev.diff, ev.eps, ev.box, ev.rms, ev.local[sel])
        approx, _ = self._pixel_jacobian(view, params, image=image[cy0:cy1, cx0:cx1])
        if ev.sw is not None:
            approx *= ev.sw[ev.local[sel]]
        Ja = approx.reshape(k, -1)
        A = (Ja @ Ja.T).astype(float) * (len(py) / len(sel))
        pose = np.flatnonzero(params < 6)
        if len(pose):  # the pose block exact (6 columns filtered: cheap; the head's motion converges as before)
            Jp = self._jacobian_analytic(ev, params[pose], True)
            if ev.sw is not None:
                Jp = Jp * np.repeat(ev.sw, 3)[:, None]
            A[np.ix_(pose, pose)] = Jp.T @ Jp
        return None, A, ("adjoint", ev)

    def _adjoint_gradient(self, ev: _Eval, params: np.ndarray) -> np.ndarray:
        """``Jᵀ s`` (k,) of the bandpassed analytic Jacobian at ``ev`` without forming ``J``: with
        ``s = √w ⊙ r_B`` the weighted filtered residual, ``(√w ⊙ B J)ᵀ s = Jᵀ z``,
        ``z = Bᵀ(√w ⊙ s)`` (``B`` symmetric: one 3-channel filtering), and ``J``'s columns are
        per-pixel sums over the surface point's three vertices (Eq. 7), so ``Jᵀ z`` is summed per
        vertex first (``np.bincount``) and then mapped through ``∂X/∂α`` — the same value as
        the product with the full Jacobian, at a fraction of its cost."""
        r = ev.render
        y0, y1, x0, x1 = ev.box
        h, w = y1 - y0, x1 - x0
        s = ev.diff if ev.sw is None else ev.diff * ev.sw.reshape(h, w, 1)
        z = np.take(bandpass(s, self.options.bandpass).reshape(-1, 3), ev.local, axis=0).T  # (3, N)
        G, q = self._motion_gradients(ev)
        sa = [np.einsum("cn,cn->n", Ga, z) for Ga in G]  # −∇Î·∂x/∂m'_axis against z, per pixel
        g = np.zeros(len(params))
        for j, p in enumerate(params):
            if p < 3:
                a_, b_ = (p + 1) % 3, (p + 2) % 3
                g[j] = float(q[a_] @ sa[b_] - q[b_] @ sa[a_])
            elif p < 6:
                g[j] = float(sa[p - 3].sum())
        alpha = np.flatnonzero(params >= 6)
        if len(alpha):
            a = params[alpha] - 6
            n = self._dX_dalpha32.shape[0]
            corners, bary = r.corners.ravel(), r.bary.astype(np.float32)
            u = np.stack([np.bincount(corners, (bary * x[:, None]).ravel(), n) for x in sa], axis=1)
            u = (u @ ev.state.R).astype(np.float32)  # ∂m'/∂α = R ∂X/∂α: Σ (R dX)·u = dX·(Rᵀu)
            full = len(a) == self.n_alpha and np.array_equal(a, np.arange(len(a)))
            ga = sum(u[:, d] @ (self._dX_by_axis[d] if full else self._dX_by_axis[d][:, a]) for d in range(3))
            groups = np.flatnonzero(np.any(self._blend[a], axis=0))
            for gi in groups:  # the blending term: Σ_g blend · membership · (Î_g · z)
                t = np.einsum("nc,cn->n", r.texture_colors[gi], z)
                ug = np.bincount(corners, (bary * t[:, None]).ravel(), n)
                ga += self._blend[a, gi] * (ug @ self._membership32[:, self._alpha_region[a]])
            g[alpha] = ga
        return g

    def _motion_gradients(self, ev: _Eval, image: np.ndarray | None = None) -> tuple:
        """``G`` (3 axes of (3 channels, N)): ``−∇Î · ∂x/∂m'`` at ``ev``'s covered pixels, and
        ``q = R(m − c)`` (3 of (N,)) — the pieces of Eq. 7 (App. B.1: u = f X/Z + c_x, v = f Y/Z +
        c_y; the minus sign: a surface moving by δx changes the image at a fixed pixel by −∇Î·δx).
        ``image``: the crop to take the gradient of instead of the rendering's (see
        :meth:`_pixel_jacobian`)."""
        r = ev.render
        # image gradient (Sobel, scaled to a unit slope) at the covered pixels; the crop keeps
        # one pixel around the model so the 3×3 kernel sees the background as in the full image
        y0, y1, x0, x1 = r.box
        y0, x0, y1, x1 = max(y0 - 1, 0), max(x0 - 1, 0), min(y1 + 1, self.H), min(x1 + 1, self.W)
        img = r.image[y0:y1, x0:x1] if image is None else image
        py, px = np.divmod(r.pixels, self.W)
        li = (py - y0) * (x1 - x0) + (px - x0)
        gx = np.take(cv2.Sobel(img, cv2.CV_32F, 1, 0, ksize=3, scale=0.125).reshape(-1, 3), li, axis=0).T
        gy = np.take(cv2.Sobel(img, cv2.CV_32F, 0, 1, ksize=3, scale=0.125).reshape(-1, 3), li, axis=0).T
        X, Y, Z = np.asarray(r.X_cam, np.float32).T
        iz = 1.0 / Z
        fz = np.float32(-self.f) * iz
        Gx, Gy = gx * fz, gy * fz
        Gz = Gx * (X * iz)
        Gz += Gy * (Y * iz)
        np.negative(Gz, out=Gz)
        t = ev.state.t.astype(np.float32)
        return (Gx, Gy, Gz), (X - t[0], Y - t[1], Z - t[2])

    def _jacobian_analytic(self, ev: _Eval, params: np.ndarray, filtered: bool) -> np.ndarray:
        col, at_px = self._pixel_jacobian(ev, params)  # (k, 3, N + M)
        k = len(params)
        y0, y1, x0, x1 = ev.box
        h, w = y1 - y0, x1 - x0
        J = np.zeros((h * w, 3, k), np.float32)  # rows (pixel, channel), as ev.diff
        J[at_px] = col.transpose(2, 1, 0)
        if filtered:  # all columns' images filtered in one call (3·k channels)
            J = bandpass(J.reshape(h, w, 3 * k), self.options.bandpass)
        return J.reshape(h * w * 3, k)

    def _jacobian_fd(self, frame: np.ndarray, ev: _Eval, params: np.ndarray, filtered: bool) -> np.ndarray:
        y0, y1, x0, x1 = ev.box
        cols = []
        for p in params:
            h = FD_STEPS["rotation"] if p < 3 else FD_STEPS["translation"] if p < 6 else FD_STEPS["alpha"]
            imgs = []
            for sign in (1.0, -1.0):
                st = self._step(ev.state, np.array([p]), np.array([sign * h]))
                model = self.model
                Wv = model.vertex_weights(model.region_weights(st.alpha))
                rr = render_model(self.renderer, self.camera(st), model, model.blend_geometry(Wv), Wv, background=frame)
                self.evaluations += 1
                img = rr.image[y0:y1, x0:x1]
                imgs.append(bandpass(img, self.options.bandpass) if filtered else img)
            cols.append(((imgs[0] - imgs[1]) / np.float32(2 * h)).reshape(-1))
        return np.stack(cols, axis=1)

    # -- the whole-clip solve's seam (tracking.smooth) ----------------------------------
    def linearise_expression(self, frame: np.ndarray, state: FrameState) -> ExpressionSystem:
        """The frame's ε linearised at ``state`` with respect to ``α`` alone, as the expression
        phase sees it: bandpassed (when :attr:`TrackOptions.bandpass` is set), face- and
        robust-weighted (a robust scale of this frame's own, as :meth:`fit` starts a frame), with
        :attr:`TrackOptions.expression_jacobian`; without the penalty D. Renders once.

        Parameters
        ----------
        frame : (H, W, 3) float image in [0, 1].
        state : FrameState, where to linearise.
        """
        o = self.options
        filtered = o.bandpass is not None
        frame = self._matched(np.asarray(frame, np.float32))
        self._start_frame(weighted=True)
        ev = self._evaluate(frame, state, filtered)
        params = 6 + np.arange(self.n_alpha)
        system = self._system(frame, ev, params, o.expression_jacobian, filtered)
        return ExpressionSystem(system[1], self._gradient(system, ev, params), len(ev.render.pixels))

    def refine(self, frame: np.ndarray, state: FrameState, phase: Phase) -> FrameState:
        """``state`` after one LM ``phase`` on ``frame`` (H, W, 3) float in [0, 1], started as a
        new frame (its own robust scale, ε weighing the face as the last round of :meth:`fit`).
        The parameters outside ``phase.params`` are held."""
        self._start_frame(weighted=True)
        return self._lm(self._matched(np.asarray(frame, np.float32)), state, phase, []).state

    def _start_frame(self, weighted: bool) -> None:
        """Forget the robust scale of the previous frame (:meth:`_robust`); ``weighted``: ε weighs
        the face (:attr:`TrackOptions.outside_weight`) and uses the robust error."""
        self._sigma2 = {}
        self._mark_c = {}
        self._weighted = weighted

    # -- LM ---------------------------------------------------------------------------
    def _step(self, state: FrameState, params: np.ndarray, delta: np.ndarray) -> FrameState:
        st = state.copy()
        d = np.zeros(6 + self.n_alpha)
        d[params] = delta
        if np.any(d[:3]):
            st.R = rodrigues(d[:3]) @ st.R  # R ← R̂(ω) R (App. B.2)
        st.t = st.t + d[3:6]
        st.alpha = st.alpha + d[6:]
        return st

    def _feasible_fraction(self, state: FrameState, params: np.ndarray, delta: np.ndarray) -> float:
        """Largest s ≤ 1 keeping every weight of ``state + s·delta`` in :data:`WEIGHT_RANGE`."""
        if not np.any(params >= 6):
            return 1.0
        d = np.zeros(self.n_alpha)
        d[params[params >= 6] - 6] = delta[params >= 6]
        w0 = self.model.region_weights(state.alpha)[1:]
        dw = self.model.region_weights(state.alpha + d)[1:] - w0
        lo, hi = WEIGHT_RANGE
        s = 1.0
        with np.errstate(divide="ignore", invalid="ignore"):
            up = np.where(dw > 1e-12, (hi - w0) / dw, np.inf)
            down = np.where(dw < -1e-12, (lo - w0) / dw, np.inf)
        s = min(s, float(up.min(initial=np.inf)), float(down.min(initial=np.inf)))
        return max(s, 0.0)

    @staticmethod
    def _step_size(params: np.ndarray, delta: np.ndarray) -> float:
        """Largest surface motion (mm) a step causes, roughly: rotations over the head's radius
        (:data:`HEAD_RADIUS_MM`), translations (depth included: it is what the image sees least,
        about 0.16 px per mm at 600 mm, yet it moves the surface as much as the others), α in mm
        (its unit)."""
        rot = np.abs(delta[params < 3]).max(initial=0.0) * HEAD_RADIUS_MM
        return float(max(rot, np.abs(delta[params >= 3]).max(initial=0.0)))

    def _system(self, frame, ev: _Eval, params: np.ndarray, method: str, filtered: bool) -> tuple:
        """``(Jᵀ, JᵀJ, rows)`` at ``ev``: the transposed Jacobian (k, P) float32, its Gram matrix
        (float64) and how the residual is laid out along P — ``ev`` itself for the unfiltered
        analytic Jacobian (rows at ``ev``'s covered pixels, channel-major: it vanishes elsewhere),
        else the crop box (y0, y1, x0, x1) whose pixels × channels the rows cover."""
        if (
            method == "analytic"
            and filtered
            and self.options.filtered_hessian == "image"
            and len(params) > APPROX_COLUMNS
        ):
            return self._filtered_system(ev, params)
        if method == "analytic" and not filtered:
            col, at_px = self._pixel_jacobian(ev, params)
            if ev.sw is not None:  # the rows of ε's weighted residual
                col *= ev.sw[at_px]
            Jt, rows = col.reshape(len(params), -1), (ev, at_px)
        else:
            Jt = self.jacobian(frame, ev, params, method, filtered).T
            if ev.sw is not None:
                Jt = Jt * np.repeat(ev.sw, 3)
            rows = ev.box
        return Jt, (Jt @ Jt.T).astype(float), rows

    def _residual(self, ev: _Eval, rows) -> np.ndarray | None:
        """The residual ``I_t − Î`` of ``ev`` laid out as a Jacobian's rows (see :meth:`_system`);
        None when it cannot be: covered-pixel rows of another evaluation, or a box that does not
        hold all of ``ev``'s residual (the model moved out of it)."""
        if isinstance(rows[0], _Eval):
            return np.take(ev.diff.reshape(-1, 3), rows[1], axis=0).T.reshape(-1) if rows[0] is ev else None
        if rows == ev.box:
            return ev.diff.reshape(-1)
        (y0, y1, x0, x1), (b0, b1, c0, c1) = rows, ev.box
        if b0 < y0 or b1 > y1 or c0 < x0 or c1 > x1:
            return None
        # ev's residual vanishes outside its own box (the model's box and the filter's reach)
        r = np.zeros((y1 - y0, x1 - x0, 3), np.float32)
        r[b0 - y0 : b1 - y0, c0 - x0 : c1 - x0] = ev.diff
        return r.reshape(-1)

    def _gradient(self, system: tuple, ev: _Eval, params: np.ndarray) -> np.ndarray | None:
        """``Jᵀ(I_t − Î)`` (k,) of ``system``'s Jacobian at ``ev`` (None when ``ev``'s residual does
        not fit its rows; see :meth:`_residual`); exact at ``ev`` for :meth:`_filtered_system`."""
        Jt, _, rows = system
        if rows[0] == "adjoint":
            return self._adjoint_gradient(ev, params)
        r = self._residual(ev, rows)
        return None if r is None else (Jt @ r).astype(float)

    def _normal_equations(self, system: tuple, ev: _Eval, params: np.ndarray):
        """``(A, g)`` of Eq. (6) at ``ev`` with ``system``'s Jacobian: ``JᵀJ + H_D`` and
        ``Jᵀ(I_t − Î) − ∇D``; ``(None, None)`` when ``ev``'s residual does not fit its rows."""
        A = system[1]
        g = self._gradient(system, ev, params)
        if g is None:
            return None, None
        expr = params >= 6
        if np.any(expr):  # the penalty D is part of ε
            sel, ia = np.flatnonzero(expr), params[expr] - 6
            _, gD, hD = self._penalty(ev.weights, ev.render)
            A = A.copy()
            g[sel] -= gD[ia]
            A[np.ix_(sel, sel)] += hD[np.ix_(ia, ia)]
        if ev.mark_c:  # the landmark term is part of ε
            hL, gL = self._marks.gauss_newton(ev.state)
            A = A + ev.mark_c * hL[np.ix_(params, params)]
            g = g - ev.mark_c * gL[params]
        return A, g

    def _lm(self, frame, state: FrameState, phase: Phase, history: list, render=None) -> _Eval:
        """Levenberg–Marquardt of ``phase`` from ``state`` (or the evaluation of ``render``);
        ``history`` gets ε after each accepted step.

        Ends when a step would move the surface by less than the tolerance (checked before
        rendering it) or has just done so; when the predicted decrease of ε is negligible; after a
        rejected step under 5× the tolerance (at that scale ε's rasterisation noise — pixels
        flipping at occlusion edges — rejects steps, and smaller ones do no better); or after
        ``iterations``. Jacobian reuse: after an accepted step, the next one is first solved with
        the previous Jacobian (only the residual is new; the Jacobian barely changed over the step);
        if that step is under the tolerance the phase ends without a new Jacobian — the usual end of
        a tracked frame. Otherwise the step is solved again with the Jacobian of the new point.
        ``phase.reuse=False`` turns this off (see :meth:`fit`)."""
        o = self.options
        params, method, filtered = phase.params, phase.jacobian, phase.filtered
        tol = o.step_tolerance_mm if phase.tolerance_mm is None else phase.tolerance_mm
        reuse = phase.reuse
        ev = self._evaluate(frame, state, filtered, render)
        lam = o.damping
        system = None
        for _ in range(phase.iterations):
            reused = system is not None and reuse
            A, g = self._normal_equations(system, ev, params) if reused else (None, None)
            if A is None:
                reused = False
                system = self._system(frame, ev, params, method, filtered)
                A, g = self._normal_equations(system, ev, params)
            delta, size = self._lm_step(A, g, lam, ev, params)
            if size < tol or delta @ g - 0.5 * delta @ (A @ delta) < o.decrease_tolerance * ev.eps:
                break  # converged, no rendering spent
            if reused:
                system = self._system(frame, ev, params, method, filtered)
                A, g = self._normal_equations(system, ev, params)
                delta, size = self._lm_step(A, g, lam, ev, params)
            improved = False
            for _ in range(1 + o.max_rejections):
                trial = self._evaluate(frame, self._step(ev.state, params, delta), filtered)
                if trial.eps < ev.eps and len(trial.render.pixels) >= MIN_PIXELS:
                    gain = (ev.eps - trial.eps) / max(ev.eps, 1e-30)
                    ev, lam, improved = trial, max(lam / 10.0, 1e-7), True
                    history.append(ev.eps)
                    break
                lam *= 10.0
                if size < 5 * o.step_tolerance_mm:
                    break
                delta, size = self._lm_step(A, g, lam, ev, params)
            if not improved or size < tol or (reuse and gain < o.min_gain):
                break
        return ev

    def _lm_step(self, A, g, lam, ev: _Eval, params):
        """The damped step ``[A + λ diag(A)] δ = g``, shortened to keep the weights in range, and
        its size (mm, :meth:`_step_size`).

        The penalty D is piecewise quadratic and ``A, g`` hold the pieces the weights are on now;
        a weight at a bound (the neutral face: 1 and 0s) sees D as flat there and any step across
        it as free. So the step is re-solved with the pieces it would enter (an active-set
        iteration, ≤ 3 passes): a weight about to leave [0, 1] is held near its bound by D's
        curvature instead of the step being rejected after a rendering."""
        state = ev.state

        def solve(A, g):
            M = A + lam * np.diag(np.maximum(np.diag(A), 1e-9))
            try:
                return np.linalg.solve(M, g)
            except np.linalg.LinAlgError:
                return np.linalg.lstsq(M, g, rcond=None)[0]

        delta = solve(A, g)
        expr = params >= 6
        if np.any(expr):
            sel, ia = np.flatnonzero(expr), params[expr] - 6
            now = self._sides(ev.weights)
            _, g0, h0 = self._penalty(ev.weights, ev.render, now)
            sides = now
            for _ in range(3):
                d = np.zeros(self.n_alpha)
                d[ia] = delta[sel]
                entered = self._sides(self.model.region_weights(state.alpha + d))
                merged = np.where(sides != 0, sides, entered)
                if np.array_equal(merged, sides):
                    break
                sides = merged
                _, g1, h1 = self._penalty(ev.weights, ev.render, sides)
                A2, g2 = A.copy(), g.copy()
                A2[np.ix_(sel, sel)] += (h1 - h0)[np.ix_(ia, ia)]
                g2[sel] -= (g1 - g0)[ia]
                delta = solve(A2, g2)
        delta *= self._feasible_fraction(state, params, delta)
        return delta, self._step_size(params, delta)

    def fit(self, frame: np.ndarray, initial: FrameState, landmarks: LandmarkTerm | None = None) -> FrameResult:
        """Fit one frame (H, W, 3) float in [0, 1] from ``initial``: pose, then expression;
        ``landmarks`` (:meth:`landmark_term`) adds the detector's landmarks to ε
        (:attr:`TrackOptions.landmarks`).

        A tracked frame (``options.rounds == 1``, starting from :func:`predict`) uses two economies:
        the pose phase ends at :attr:`TrackOptions.pose_tolerance_mm` (it only has to bring the
        expression phase close), and Jacobian reuse ends a phase without a new Jacobian
        (:meth:`_lm`). A frame fitted in several rounds (the first one, from the user's pose and a
        neutral face) uses neither: far from the optimum of a strong expression, the filtered ε
        has a long shallow valley where steps stay small (0.3–0.5 mm) for many iterations before
        they grow; measured from 2°/9 mm and a neutral face, either economy ended the fit there at
        2.8 mm geometry error, instead of 0.01 mm."""
        self._marks = landmarks
        try:
            with single_threaded_blas():
                return self._fit(frame, initial)
        finally:
            self._marks = None

    def _fit(self, frame: np.ndarray, initial: FrameState) -> FrameResult:
        frame = np.asarray(frame, np.float32)
        if frame.shape != (self.H, self.W, 3):
            raise FitError(f"frame must be ({self.H}, {self.W}, 3), got {frame.shape}")
        raw, frame = frame, self._matched(frame)
        o = self.options
        start = self.evaluations
        history: list[float] = []
        ev = None
        self._start_frame(weighted=True)
        # a frame fitted in several rounds starts far from its optimum (the first frame, from the
        # user's pose and a neutral face): no tracking economies there (see fit())
        far = o.rounds > 1
        # the smoothness prior of a shared basis pulls towards the prediction (not from a pose)
        self._anchor = None
        if len(self._shared_w) and not far:
            predicted = self.model.region_weights(initial.alpha)[1:].ravel()[self._shared_w]
            self._anchor = np.clip(predicted, 0.0, 1.0)
        pose_tol = o.step_tolerance_mm if far else o.pose_tolerance_mm
        rounds = max(1, o.rounds)
        for k in range(rounds):
            # a frame far from its optimum is first brought close by every pixel of the model (its
            # silhouette against the background pulls it in from afar); the last round weighs the
            # face alone (TrackOptions.outside_weight)
            self._weighted = k == rounds - 1
            pose = Phase(np.arange(6), o.pose_iterations, o.pose_jacobian, False, pose_tol, not far)
            if ev is None:
                ev = self._lm(frame, initial.copy(), pose, history)
            else:
                ev = self._lm(frame, ev.state, pose, history, ev.render)
            if not self.n_alpha:
                if o.bandpass is not None:  # a pose-only model: the pose on the bandpassed images too
                    pose = Phase(np.arange(6), o.expression_iterations, o.pose_jacobian, True, None, not far)
                    ev = self._lm(frame, ev.state, pose, history, ev.render)
                continue
            filtered = o.bandpass is not None
            groups = (
                [np.flatnonzero(self._alpha_region == r) + 6 for r in np.unique(self._alpha_region)]
                if o.per_region
                else [np.arange(self.n_alpha) + 6]
            )
            for params in groups:
                if o.joint:
                    params = np.concatenate([np.arange(6), params])
                expression = Phase(params, o.expression_iterations, o.expression_jacobian, filtered, None, not far)
                ev = self._lm(frame, ev.state, expression, history, ev.render)
        npx, rms = len(ev.render.pixels), ev.rms  # the last rendering's unfiltered RMS
        diverged = bool(self._inlier_rms(ev) > DIVERGED_RMS or npx < MIN_PIXELS)
        if o.colour_match and not diverged:
            self._update_colour(raw, ev)
        return FrameResult(
            state=ev.state,
            weights=ev.weights,
            rms=rms,
            pixels=npx,
            evaluations=self.evaluations - start,
            diverged=diverged,
            history=history,
        )

    @property
    def colour(self) -> np.ndarray | None:
        """(2, 3) per channel gain and offset the next frame is taken through before it is
        compared (:attr:`TrackOptions.colour_match`), or None before the first fitted frame."""
        return None if self._colour is None else self._colour.copy()

    @colour.setter
    def colour(self, value) -> None:
        """Restore a match (a resumed run continues with the one its last saved frame left)."""
        if value is None:
            self._colour = None
            return
        a = np.array(value, float)
        if a.shape != (2, 3) or not np.all(np.isfinite(a)):
            raise ValueError(f"a colour match is (2, 3) finite gains and offsets, got {value!r}")
        self._colour = a

    def _matched(self, frame: np.ndarray) -> np.ndarray:
        """``frame`` with the running colour match applied (:attr:`TrackOptions.colour_match`;
        as is before the first fitted frame). The whole-clip solve's :meth:`linearise_expression`
        and :meth:`refine` use the latest match: a clip's lighting changes slowly."""
        if self._colour is None or not self.options.colour_match:
            return frame
        return (frame * self._colour[0].astype(np.float32) + self._colour[1].astype(np.float32)).astype(np.float32)

    def _update_colour(self, frame: np.ndarray, ev: _Eval) -> None:
        """Blend this frame's colour match into the running one (:attr:`TrackOptions.colour_match`):
        per channel, the frame ``F ≈ a′ Î + b′`` by least squares over the covered pixels that are
        not outliers; the next frame is compared as ``(F − b′) / a′`` (gain clipped to [0.5, 2])."""
        r = ev.render
        keep = ~outlier_pixels(ev.pixel_rms) if ev.pixel_rms is not None and len(ev.pixel_rms) else slice(None)
        F = frame.reshape(-1, 3)[r.pixels][keep].astype(np.float64)
        Im = r.image.reshape(-1, 3)[r.pixels][keep].astype(np.float64)
        if len(F) < MIN_PIXELS:
            return
        Ic, Fc = Im - Im.mean(0), F - F.mean(0)
        slope = (Ic * Fc).sum(0) / np.maximum((Ic * Ic).sum(0), 1e-9)
        gain = np.clip(1.0 / np.maximum(slope, 1e-3), 0.5, 2.0)
        new = np.stack([gain, Im.mean(0) - gain * F.mean(0)])
        k = self.options.colour_smoothing
        self._colour = new if self._colour is None else (1.0 - k) * self._colour + k * new

    def _inlier_rms(self, ev: _Eval) -> float:
        """The image RMS that says whether a frame diverged: with the robust error, over the covered
        pixels within 3× the median pixel residual (an occluding hand is not divergence: its pixels
        are the outliers the robust error leaves out); else over every covered pixel."""
        r = ev.pixel_rms
        if self.options.robust_scale is None or r is None or not len(r):
            return ev.rms
        keep = ~outlier_pixels(r)
        return float(np.sqrt(np.mean(r[keep] ** 2)))


_BLAS_CONTROLLER: list = []


def single_threaded_blas():
    """A context limiting BLAS to one thread (:mod:`threadpoolctl`, when installed): every BLAS
    loaded when first called — numpy's, scipy's and the one OpenCV's wheel brings for ``cv2.dnn``.

    The products here are small (10 × 10⁵): a second BLAS thread gains little, and its
    spin-waiting takes a core from the software rasteriser and numpy — measured on the 2-core
    machine, 3.3 instead of 2.0 frames/s. :func:`tracking.run.track_video` holds it over its whole
    loop, not frame by frame: each restore to two threads woke OpenBLAS's thread server, which
    then spun between the frames — 38 s of CPU for 25 s of tracking, 26 s with the limit held
    (2026-12-05, 120 frames of the real clip, wall time the same)."""
    if not _BLAS_CONTROLLER:
        _BLAS_CONTROLLER.append(ThreadpoolController())
    ctl = _BLAS_CONTROLLER[0]
    return contextlib.nullcontext() if ctl is None else ctl.limit(limits=1, user_api="blas")


def track_frames(
    fitter: FrameFitter,
    frames,
    first: FrameState,
    *,
    previous: list | None = None,
    first_rounds: int = 3,
    callback=None,
    landmarks=None,
) -> list[FrameResult]:
    """Track a sequence: the first frame from ``first`` (with ``first_rounds`` pose/expression
    rounds), each later one from :func:`predict` of the two previous results.

    Parameters
    ----------
    fitter : FrameFitter
    frames : iterable of (H, W, 3) float images.
    first : FrameState, the user's (or :func:`pose_from_clicks`') pose of the first frame.
    previous : list of FrameState, optional, results of frames before these (resuming).
    callback : callable ``(index, FrameResult) -> bool | None``; True stops.
    landmarks : callable ``(index, predicted FrameState) -> LandmarkTerm | None``, optional: the
        detector's landmarks of a tracked frame (:meth:`FrameFitter.fit`).
    """
    states = list(previous or [])
    out = []
    with single_threaded_blas():  # held over the loop (see single_threaded_blas)
        for i, frame in enumerate(frames):
            if states:
                start = predict(states[-2:])
                res = fitter.fit(frame, start, None if landmarks is None else landmarks(i, start))
            else:
                rounds = fitter.options.rounds
                fitter.options.rounds = max(first_rounds, rounds)
                try:
                    res = fitter.fit(frame, first)
                finally:
                    fitter.options.rounds = rounds
            states.append(res.state)
            out.append(res)
            if callback is not None and callback(i, res):
                break
    return out
