"""Fitting the face model to video frames: analysis by synthesis (Pighin et al. 2002, §6.1.2–6.1.3, App. B).

Parameters of a frame: head rotation ``R`` (updated as ``R ← R̂(ω) R``, App. B.2), translation ``t``
(camera-space position, mm, of the model's centre ``c``, so ``X_cam = R (X − c) + t``) and the
expression parameters ``α_r`` of every control region (:mod:`tracking.facemodel`). The error is

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

Jacobians (§6.1.3): ``"analytic"`` — Eq. (7): the image gradient (Sobel) times the image motion of
the surface point under each pixel, ``∂x/∂p = ∂P/∂m' · ∂m'/∂p`` with ``∂P/∂m'`` of App. B.1 and
``∂m'/∂ω_l = e_l × R(m − c)``, ``∂m'/∂t_l = e_l``, ``∂m'/∂α = R Σ_k ∂W_k/∂α E_k`` (App. B.2), plus the
blending term ``Σ_k ∂W_k/∂α Î_k``. The per-vertex derivatives are interpolated at every pixel from
the barycentric render (:class:`tracking.facemodel.ModelRender`) — no loop over pixels or vertices.
Note the sign: a surface moving by ``δx`` changes the image at a fixed pixel by ``−∇Î·δx``
(Eq. 7 is written without it; the finite-difference test pins it). ``"fd"`` — central differences
(§6.1.3.1), two renderings per parameter. ``benchmarks/bench_track.py --jacobians`` compares them;
the defaults follow that measurement (see :data:`DEFAULT_JACOBIANS`).

Prediction (§6.2): the first frame starts from the user's pose (or :func:`pose_from_clicks`), later
ones from the linear extrapolation of the two previous results (:func:`predict`).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import cv2
import numpy as np

from photomodel.camera import Camera, rodrigues
from photomodel.errors import FitError
from tracking.facemodel import WEIGHT_RANGE, FaceModel, ModelRender, render_model

__all__ = [
    "DEFAULT_JACOBIANS",
    "TrackOptions",
    "FrameState",
    "FrameResult",
    "FrameFitter",
    "predict",
    "track_frames",
    "pose_from_clicks",
    "bandpass",
]

#: Jacobian used per phase by default; chosen from ``benchmarks/bench_track.py --jacobians``.
DEFAULT_JACOBIANS = {"pose": "analytic", "expression": "analytic"}
#: A frame whose image RMS after fitting exceeds this (intensity in [0, 1]) is flagged diverged.
DIVERGED_RMS = 0.12
#: Fewer covered pixels than this: the model left the frame.
MIN_PIXELS = 200
#: Central-difference steps: rotation (rad), translation (mm), expression parameter (mm RMS units).
#: Steps of a few tenths of a pixel or more: smaller ones see the rasterisation of internal
#: occlusion edges (nose, lips) flip pixels, and the differences become noise.
FD_STEPS = {"rotation": 1e-2, "translation": 2.0, "alpha": 0.3}


@dataclass
class TrackOptions:
    """Settings of :class:`FrameFitter` (defaults measured by ``benchmarks/bench_track.py``)."""

    pose_iterations: int = 4
    expression_iterations: int = 3
    pose_jacobian: str = DEFAULT_JACOBIANS["pose"]
    expression_jacobian: str = DEFAULT_JACOBIANS["expression"]
    #: (σ_fine, σ_coarse) px of the difference of Gaussians for the expression phase; None: off.
    bandpass: tuple | None = (1.0, 4.0)
    #: penalty constant per covered pixel (D's ``c`` = penalty × pixels).
    penalty: float = 0.01
    damping: float = 1e-3
    per_region: bool = False
    #: pose-then-expression rounds per frame (a first frame far from the truth needs 2; tracked
    #: frames start from the prediction and need 1).
    rounds: int = 1
    #: extra tries with larger λ after a rejected step.
    max_rejections: int = 2

    def __post_init__(self):
        for name in ("pose_jacobian", "expression_jacobian"):
            if getattr(self, name) not in ("analytic", "fd"):
                raise ValueError(f"{name} must be 'analytic' or 'fd', got {getattr(self, name)!r}")


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
    diverged : bool, rms over :data:`DIVERGED_RMS` or model (nearly) out of the frame.
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
    """Difference of Gaussians ``G_σ1 * I − G_σ2 * I`` of an (H, W, C) float image (§6.2)."""
    s1, s2 = sigmas
    a = cv2.GaussianBlur(image, (0, 0), s1, borderType=cv2.BORDER_REPLICATE)
    b = cv2.GaussianBlur(image, (0, 0), s2, borderType=cv2.BORDER_REPLICATE)
    return a - b


def predict(previous: list[FrameState]) -> FrameState:
    """Initial parameters of the next frame: linear extrapolation of the last two (§6.2);
    the last one alone if there is only one. Rotation extrapolates as ``(R₁ R₀ᵀ) R₁``."""
    if not previous:
        raise ValueError("predict needs at least one previous frame")
    if len(previous) == 1:
        return previous[-1].copy()
    a, b = previous[-2], previous[-1]
    return FrameState((b.R @ a.R.T) @ b.R, 2 * b.t - a.t, 2 * b.alpha - a.alpha)


def pose_from_clicks(
    model: FaceModel, vertices: np.ndarray, clicks: np.ndarray, focal_px: float, width: int, height: int
) -> FrameState:
    """Head pose of the first frame from a few clicked points (neutral expression assumed).

    The modeling core's :func:`photomodel.pose.recover_poses` solves several photos and the 3D
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


@dataclass
class _Eval:
    state: FrameState
    render: ModelRender
    weights: np.ndarray  # (R, m)
    diff: np.ndarray  # (h, w, 3) crop of frame − Î (0 outside the mask), filtered when bandpassed
    eps: float
    box: tuple  # (y0, y1, x0, x1)
    rms: float  # unfiltered image RMS over the covered pixels


class FrameFitter:
    """Fits :class:`FaceModel` parameters to frames seen by one fixed video camera.

    Parameters
    ----------
    model : FaceModel
    focal_px : float, the video camera's focal length (pixels).
    width, height : int, frame size.
    options : TrackOptions, optional.
    renderer : photomodel.render.Renderer, optional (default: this thread's).
    """

    def __init__(self, model: FaceModel, focal_px: float, width: int, height: int,
                 options: TrackOptions | None = None, renderer=None):  # fmt: skip
        from photomodel.render import get_renderer

        self.model = model
        self.f, self.W, self.H = float(focal_px), int(width), int(height)
        self.options = options or TrackOptions()
        self.renderer = renderer or get_renderer()
        self.evaluations = 0
        # ∂X_i/∂α per vertex (n, A, 3): μ_ir Σ_k Q_r(k, l) E_k,i (App. B.2), and the blending
        # coefficients per texture group (G, A): Σ_{k in group} Q_r(k, l)
        cols, blend, region_of = [], [], []
        groups = model.texture_groups()
        for r, Q in enumerate(model.bases):
            for j in range(Q.shape[1]):
                cols.append(model.membership[:, r, None] * np.einsum("k,knd->nd", Q[:, j], model.geometry))
                blend.append([Q[ks, j].sum() for _, ks in groups])
                region_of.append(r)
        n = model.geometry.shape[1]
        self._dX_dalpha = np.stack(cols, axis=1) if cols else np.zeros((n, 0, 3))
        self._blend = np.array(blend).reshape(len(cols), len(groups))
        self._alpha_region = np.array(region_of, int)
        self.n_alpha = len(cols)

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
        box = self._box(render.mask, filtered)
        y0, y1, x0, x1 = box
        diff = frame[y0:y1, x0:x1] - render.image[y0:y1, x0:x1]
        rms = float(np.sqrt((diff * diff).sum() / max(3 * len(render.pixels), 1)))
        if filtered:
            diff = bandpass(diff, self.options.bandpass)
        eps = 0.5 * float((diff * diff).sum()) + self._penalty(weights, render)[0]
        return _Eval(state, render, weights, diff, eps, box, rms)

    def _box(self, mask: np.ndarray, filtered: bool) -> tuple:
        ys, xs = np.nonzero(np.any(mask, axis=1)), np.nonzero(np.any(mask, axis=0))
        if not len(ys[0]):
            return (0, self.H, 0, self.W)
        m = 2 + (int(np.ceil(3 * self.options.bandpass[1])) if filtered and self.options.bandpass else 0)
        y0, y1 = max(ys[0][0] - m, 0), min(ys[0][-1] + m + 1, self.H)
        return (y0, y1, max(xs[0][0] - m, 0), min(xs[0][-1] + m + 1, self.W))

    def _penalty(self, weights: np.ndarray, render: ModelRender):
        """D, its gradient and Hessian with respect to the concatenated α."""
        c = self.options.penalty * max(len(render.pixels), 1)
        lo, hi = np.minimum(weights[1:], 0.0), np.maximum(weights[1:] - 1.0, 0.0)
        D = c * float((lo**2).sum() + (hi**2).sum())
        grad = np.zeros(self.n_alpha)
        hess = np.zeros((self.n_alpha, self.n_alpha))
        for r, (Q, s) in enumerate(zip(self.model.bases, self.model.alpha_slices, strict=True)):
            if r == 0 or Q.shape[1] == 0:
                continue
            g = 2 * c * (lo[r - 1] + hi[r - 1])
            active = ((weights[r] < 0) | (weights[r] > 1)).astype(float)
            grad[s] = Q.T @ g
            hess[s, s] = 2 * c * (Q.T * active) @ Q
        return D, grad, hess

    # -- Jacobians --------------------------------------------------------------------
    def jacobian(self, frame: np.ndarray, ev: _Eval, params: np.ndarray, method: str, filtered: bool):
        """(P, k) Jacobian of the (cropped, optionally filtered) rendering with respect to the
        parameters ``params`` (indices: 0–2 rotation ω, 3–5 translation, 6+ α), P = crop pixels × 3."""
        if method == "fd":
            return self._jacobian_fd(frame, ev, params, filtered)
        return self._jacobian_analytic(ev, params, filtered)

    def _jacobian_analytic(self, ev: _Eval, params: np.ndarray, filtered: bool) -> np.ndarray:
        y0, y1, x0, x1 = ev.box
        r = ev.render
        img = np.ascontiguousarray(r.image[y0:y1, x0:x1])
        gx = cv2.Sobel(img, cv2.CV_32F, 1, 0, ksize=3) / 8.0  # Sobel ×8 for a unit slope
        gy = cv2.Sobel(img, cv2.CV_32F, 0, 1, ksize=3) / 8.0
        h, w = img.shape[:2]
        py, px = np.divmod(r.pixels, self.W)
        local = (py - y0) * w + (px - x0)
        gx = gx.reshape(-1, 3)[local].astype(float)
        gy = gy.reshape(-1, 3)[local].astype(float)
        Xc = r.X_cam
        Z = Xc[:, 2]
        dPx = np.column_stack([self.f / Z, np.zeros_like(Z), -self.f * Xc[:, 0] / Z**2])
        dPy = np.column_stack([np.zeros_like(Z), self.f / Z, -self.f * Xc[:, 1] / Z**2])
        rel = Xc - ev.state.t  # R (m − c)
        cols = []
        for p in params:
            if p < 3:
                dm = np.cross(np.eye(3)[p], rel)
            elif p < 6:
                dm = np.broadcast_to(np.eye(3)[p - 3], Xc.shape)
            else:
                a = p - 6
                dm = r.interpolate(self._dX_dalpha[:, a]) @ ev.state.R.T
            dx, dy = (dPx * dm).sum(1), (dPy * dm).sum(1)
            col = -(gx * dx[:, None] + gy * dy[:, None])
            if p >= 6:  # blending term Σ_k ∂W_k/∂α Î_k (App. B.3)
                mu = r.interpolate(self.model.membership[:, self._alpha_region[p - 6]])
                for g, c in enumerate(r.texture_colors):
                    col = col + self._blend[p - 6, g] * mu[:, None] * c
            J = np.zeros((h * w, 3))
            J[local] = col
            J = J.reshape(h, w, 3).astype(np.float32)
            if filtered:
                J = bandpass(J, self.options.bandpass)
            cols.append(J.reshape(-1))
        return np.stack(cols, axis=1).astype(float)

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
            cols.append(((imgs[0] - imgs[1]) / (2 * h)).reshape(-1))
        return np.stack(cols, axis=1).astype(float)

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

    def _lm(self, frame, state, params, iterations, method, filtered, history, render=None):
        ev = self._evaluate(frame, state, filtered, render)
        lam = self.options.damping
        expr = params >= 6
        for _ in range(iterations):
            J = self.jacobian(frame, ev, params, method, filtered)
            r = ev.diff.reshape(-1).astype(float)
            A = J.T @ J
            g = J.T @ r
            if np.any(expr):
                _, gD, hD = self._penalty(ev.weights, ev.render)
                ia = params[expr] - 6
                sel = np.flatnonzero(expr)
                g[sel] -= gD[ia]
                A[np.ix_(sel, sel)] += hD[np.ix_(ia, ia)]
            improved = False
            for _ in range(1 + self.options.max_rejections):
                M = A + lam * np.diag(np.maximum(np.diag(A), 1e-9))
                try:
                    delta = np.linalg.solve(M, g)
                except np.linalg.LinAlgError:
                    delta = np.linalg.lstsq(M, g, rcond=None)[0]
                delta *= self._feasible_fraction(ev.state, params, delta)
                trial = self._evaluate(frame, self._step(ev.state, params, delta), filtered)
                if trial.eps < ev.eps and len(trial.render.pixels) >= MIN_PIXELS:
                    ev, lam, improved = trial, max(lam / 10.0, 1e-7), True
                    history.append(ev.eps)
                    break
                lam *= 10.0
            if not improved:
                break
        return ev

    def fit(self, frame: np.ndarray, initial: FrameState) -> FrameResult:
        """Fit one frame (H, W, 3) float in [0, 1] from ``initial``: pose, then expression."""
        frame = np.asarray(frame, np.float32)
        if frame.shape != (self.H, self.W, 3):
            raise FitError(f"frame must be ({self.H}, {self.W}, 3), got {frame.shape}")
        o = self.options
        start = self.evaluations
        history: list[float] = []
        ev = None
        for _ in range(max(1, o.rounds)):
            ev = self._lm(frame, initial.copy() if ev is None else ev.state, np.arange(6), o.pose_iterations,
                          o.pose_jacobian, False, history, None if ev is None else ev.render)  # fmt: skip
            if not self.n_alpha:
                continue
            filtered = o.bandpass is not None
            groups = (
                [np.flatnonzero(self._alpha_region == r) + 6 for r in np.unique(self._alpha_region)]
                if o.per_region
                else [np.arange(self.n_alpha) + 6]
            )
            for params in groups:
                ev = self._lm(frame, ev.state, params, o.expression_iterations, o.expression_jacobian, filtered,
                              history, ev.render)  # fmt: skip
        npx, rms = len(ev.render.pixels), ev.rms  # the last rendering's unfiltered RMS
        return FrameResult(
            state=ev.state, weights=ev.weights, rms=rms, pixels=npx,
            evaluations=self.evaluations - start, diverged=bool(rms > DIVERGED_RMS or npx < MIN_PIXELS),
            history=history,
        )  # fmt: skip


def track_frames(fitter: FrameFitter, frames, first: FrameState, *, previous: list | None = None,
                 first_rounds: int = 3, callback=None) -> list[FrameResult]:  # fmt: skip
    """Track a sequence: the first frame from ``first`` (with ``first_rounds`` pose/expression
    rounds), each later one from :func:`predict` of the two previous results.

    Parameters
    ----------
    fitter : FrameFitter
    frames : iterable of (H, W, 3) float images.
    first : FrameState, the user's (or :func:`pose_from_clicks`') pose of the first frame.
    previous : list of FrameState, optional, results of frames before these (resuming).
    callback : callable ``(index, FrameResult) -> bool | None``; True stops.
    """
    states = list(previous or [])
    out = []
    for i, frame in enumerate(frames):
        if states:
            res = fitter.fit(frame, predict(states[-2:]))
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
