"""Plots of tracked parameters over frames, like Figs. 12–19 of Pighin et al. 2002 (§6.2), drawn with OpenCV.

The paper shows, for each tracked sequence, the expression weights of each region, the head's
rotation and translation, and the fitting error over the frames. :func:`track_plots` draws the
same from tracking records (:mod:`tracking.track_result`):

* ``weights.png`` — one panel per control region with parameters, one curve per basic expression
  (the neutral one included: in each region the weights sum to 1);
* ``arkit.png`` — for a track in ARKit terms (:mod:`tracking.arkit_face`), the rig's shapes'
  weights in three panels (jaw and mouth, eyes, brows/cheeks/nose), the shapes that move most
  (:data:`ARKIT_CURVES` per panel, weight ≥ :data:`ARKIT_SHOWN`);
* ``rotation.png`` — the head's rotation relative to facing the camera, as a rotation vector in
  degrees about the camera's x (pitch), y (yaw) and z (roll) axes;
* ``translation.png`` — the model centre in camera space (x right, y down, z depth), mm, one panel
  per axis (depth is ~650 mm, the others a few mm: one scale would flatten them);
* ``rms.png`` — the image RMS after fitting (intensity in [0, 1]), with diverged frames in red and
  the divergence threshold dashed.

OpenCV rather than matplotlib: it is already a dependency, and a line plot needs only lines and
text. Images are RGB ``uint8``; :func:`line_panel` is the one drawing routine.
"""

from __future__ import annotations

import math

import cv2
import numpy as np

__all__ = ["COLORS", "line_panel", "stack_panels", "nice_ticks", "track_plots"]

#: Curve colours (RGB), in order.
COLORS = [
    (31, 119, 180),
    (214, 39, 40),
    (44, 160, 44),
    (148, 103, 189),
    (255, 127, 14),
    (140, 86, 75),
    (227, 119, 194),
    (127, 127, 127),
    (23, 190, 207),
    (188, 189, 34),
]
FONT = cv2.FONT_HERSHEY_SIMPLEX
PANEL_SIZE = (860, 220)  # (width, height) px of one panel
MARGINS = (74, 170, 30, 40)  # left, right (legend), top (title), bottom (x ticks) px


def nice_ticks(lo: float, hi: float, count: int = 5) -> np.ndarray:
    """Round tick values (steps of 1, 2 or 5 × 10^k) covering [lo, hi] with about ``count`` ticks."""
    if not (math.isfinite(lo) and math.isfinite(hi)):
        return np.array([0.0])
    if hi - lo < 1e-12:
        lo, hi = lo - 0.5, hi + 0.5
    raw = (hi - lo) / max(count - 1, 1)
    mag = 10.0 ** math.floor(math.log10(raw))
    step = next(s * mag for s in (1.0, 2.0, 5.0, 10.0) if s * mag >= raw)
    first = math.floor(lo / step + 1e-9) * step
    last = math.ceil(hi / step - 1e-9) * step
    return np.arange(round((last - first) / step) + 1) * step + first


def _fmt(v: float, step: float) -> str:
    digits = max(0, -int(math.floor(math.log10(step) + 1e-9))) if step > 0 else 0
    return f"{v:.{digits}f}"


def line_panel(
    x: np.ndarray,
    series: list[tuple[str, np.ndarray]],
    *,
    title: str,
    ylabel: str = "",
    xlabel: str = "frame",
    ylim: tuple | None = None,
    hline: float | None = None,
    marks: np.ndarray | None = None,
    size: tuple = PANEL_SIZE,
) -> np.ndarray:
    """One plot: curves over ``x``.

    Parameters
    ----------
    x : (T,) float, abscissae (frame indices).
    series : list of (label, (T,) float), the curves (NaN: gap); colours from :data:`COLORS`.
    title, ylabel, xlabel : str (ASCII: OpenCV's Hershey fonts have no other glyphs).
    ylim : (lo, hi), optional, the y range to include (extended to the data).
    hline : float, optional, a dashed horizontal line (a threshold).
    marks : (T,) bool, optional, frames drawn as red dots on the first curve (diverged frames).
    size : (width, height) px.

    Returns
    -------
    (height, width, 3) uint8 RGB
    """
    W, H = size
    img = np.full((H, W, 3), 255, np.uint8)
    x = np.asarray(x, float)
    ys = [np.asarray(v, float) for _, v in series]
    axes = _Axes(x, ys, ylim, hline, size)
    axes.draw_frame(img, title, ylabel, xlabel)
    if hline is not None:
        axes.draw_threshold(img, hline)
    for k, ((label, _), y) in enumerate(zip(series, ys, strict=True)):
        axes.draw_curve(img, k, label, x, y)
    if marks is not None and ys:
        u, v = axes.px(x, ys[0])
        for i in np.flatnonzero(np.asarray(marks, bool) & np.isfinite(v)):
            cv2.circle(img, (int(round(u[i])), int(round(v[i]))), 4, (220, 0, 0), -1, cv2.LINE_AA)
    return img


class _Axes:
    """The plot area of a :func:`line_panel`: data ranges, ticks and the data → pixel mapping."""

    def __init__(self, x: np.ndarray, ys: list[np.ndarray], ylim, hline, size: tuple):
        self.W, self.H = size
        self.ml, mr, self.mt, mb = MARGINS
        finite = np.concatenate([v[np.isfinite(v)] for v in ys] + [np.zeros(0)])
        lo, hi = (float(finite.min()), float(finite.max())) if finite.size else (0.0, 1.0)
        if ylim is not None:
            lo, hi = min(lo, ylim[0]), max(hi, ylim[1])
        if hline is not None:
            lo, hi = min(lo, hline), max(hi, hline)
        self.yt = nice_ticks(lo, hi)
        self.y0, self.y1 = float(self.yt[0]), float(self.yt[-1])
        x0, x1 = (float(x.min()), float(x.max())) if x.size else (0.0, 1.0)
        if x1 - x0 < 1e-9:
            x0, x1 = x0 - 0.5, x1 + 0.5
        self.x0, self.x1 = x0, x1
        xt = nice_ticks(x0, x1, 8)
        self.xt = xt[(xt >= x0 - 1e-9) & (xt <= x1 + 1e-9)]
        self.pw, self.ph = self.W - self.ml - mr, self.H - self.mt - mb

    def px(self, xv, yv):
        """Pixel (u, v) of data (x, y)."""
        u = self.ml + (np.asarray(xv, float) - self.x0) / (self.x1 - self.x0) * self.pw
        v = self.mt + (self.y1 - np.asarray(yv, float)) / (self.y1 - self.y0) * self.ph
        return u, v

    def draw_frame(self, img: np.ndarray, title: str, ylabel: str, xlabel: str) -> None:
        """Grid lines with their tick labels, the box, the title and the axis labels."""
        ml, mt, pw, ph, yt, xt = self.ml, self.mt, self.pw, self.ph, self.yt, self.xt
        grey, black = (225, 225, 225), (0, 0, 0)
        for t in yt:
            _, v = self.px(self.x0, t)
            cv2.line(img, (ml, int(round(v))), (ml + pw, int(round(v))), grey, 1)
            label = _fmt(t, float(yt[1] - yt[0]) if len(yt) > 1 else 1.0)
            (tw, th), _ = cv2.getTextSize(label, FONT, 0.4, 1)
            cv2.putText(img, label, (ml - tw - 6, int(round(v)) + th // 2), FONT, 0.4, black, 1, cv2.LINE_AA)
        for t in xt:
            u, _ = self.px(t, self.y0)
            cv2.line(img, (int(round(u)), mt), (int(round(u)), mt + ph), grey, 1)
            label = _fmt(t, float(xt[1] - xt[0]) if len(xt) > 1 else 1.0)
            (tw, th), _ = cv2.getTextSize(label, FONT, 0.4, 1)
            cv2.putText(img, label, (int(round(u)) - tw // 2, mt + ph + th + 6), FONT, 0.4, black, 1, cv2.LINE_AA)
        cv2.rectangle(img, (ml, mt), (ml + pw, mt + ph), black, 1)
        cv2.putText(img, title, (ml, mt - 10), FONT, 0.5, black, 1, cv2.LINE_AA)
        if ylabel:  # above the tick labels, left of the title
            cv2.putText(img, ylabel, (6, mt - 10), FONT, 0.4, (90, 90, 90), 1, cv2.LINE_AA)
        (tw, _), _ = cv2.getTextSize(xlabel, FONT, 0.4, 1)
        cv2.putText(img, xlabel, (ml + pw - tw, self.H - 6), FONT, 0.4, (90, 90, 90), 1, cv2.LINE_AA)

    def draw_threshold(self, img: np.ndarray, hline: float) -> None:
        """A dashed horizontal line at ``hline``, labelled in the legend column."""
        ml, pw = self.ml, self.pw
        _, v = self.px(self.x0, hline)
        for s in range(ml, ml + pw, 12):
            cv2.line(img, (s, int(round(v))), (min(s + 6, ml + pw), int(round(v))), (120, 120, 120), 1, cv2.LINE_AA)
        cv2.putText(img, "threshold", (ml + pw + 12, int(round(v)) + 4), FONT, 0.4, (120, 120, 120), 1, cv2.LINE_AA)

    def draw_curve(self, img: np.ndarray, k: int, label: str, x: np.ndarray, y: np.ndarray) -> None:
        """Curve ``k`` (colour ``COLORS[k]``) and its legend entry."""
        ml, mt, pw = self.ml, self.mt, self.pw
        color = COLORS[k % len(COLORS)]
        u, v = self.px(x, y)
        ok = np.isfinite(v)
        pts = np.column_stack([u, v])
        # polylines over each run of finite values (NaN: gap); lone points as dots
        run_id = np.cumsum(~ok)
        for r in np.unique(run_id[ok]):
            seg = pts[ok & (run_id == r)]
            if len(seg) == 1:
                cv2.circle(img, tuple(np.round(seg[0]).astype(int)), 3, color, -1, cv2.LINE_AA)
            else:
                cv2.polylines(img, [np.round(seg * 16).astype(np.int32)], False, color, 2, cv2.LINE_AA, shift=4)
        ly = mt + 14 + 18 * k
        cv2.line(img, (ml + pw + 12, ly - 4), (ml + pw + 34, ly - 4), color, 2, cv2.LINE_AA)
        cv2.putText(img, label, (ml + pw + 40, ly), FONT, 0.42, (0, 0, 0), 1, cv2.LINE_AA)


#: Curves per panel of ``arkit.png``, and the smallest largest weight a shape needs to be drawn.
ARKIT_CURVES = 6
ARKIT_SHOWN = 0.05
#: The panels of ``arkit.png``: a title and how its shapes' names start.
ARKIT_PANELS = (
    ("jaw and mouth", ("jaw", "mouth", "cheekPuff")),
    ("eyes", ("eye",)),
    ("brows, cheeks, nose", ("brow", "cheekSquint", "nose")),
)


def arkit_panels(frames: list[dict]) -> list[np.ndarray]:
    """The panels of ``arkit.png`` from records with ``arkit`` {shape: weight} (none without)."""
    names = list(frames[0].get("arkit", {})) if frames else []
    if not names:
        return []
    x = np.array([f["frame"] for f in frames], float)
    W = np.array([[f["arkit"].get(n, 0.0) for n in names] for f in frames], float)
    panels = []
    for title, prefixes in ARKIT_PANELS:
        idx = [i for i, n in enumerate(names) if n.startswith(prefixes) and W[:, i].max() >= ARKIT_SHOWN]
        idx = sorted(idx, key=lambda i: -W[:, i].max())[:ARKIT_CURVES]
        series = [(names[i], W[:, i]) for i in idx] or [("(none moves)", np.zeros(len(x)))]
        panels.append(line_panel(x, series, title=f"ARKit weights: {title}", ylabel="weight", ylim=(0.0, 1.0)))
    return panels


def stack_panels(panels: list[np.ndarray]) -> np.ndarray:
    """Panels of one width stacked top to bottom."""
    return np.concatenate(panels, axis=0)


def track_plots(
    frames: list[dict], regions: list[str], expressions: list[str], diverged_rms: float | None = None
) -> dict[str, np.ndarray]:
    """The plots of a tracked sequence.

    Parameters
    ----------
    frames : list of per-frame records (:func:`tracking.track_result.frame_record`: ``frame``, ``weights``
        {region: {expression: w}}, ``head_rotation_deg`` (3,), ``centre_mm`` (3,), ``rms``, ``diverged``).
    regions : control regions to plot (those with expression parameters).
    expressions : basic expression names, neutral first.
    diverged_rms : float, optional, the divergence threshold drawn on the RMS plot.

    Returns
    -------
    dict file name → (H, W, 3) uint8 RGB image: ``weights.png``, ``arkit.png`` (records with
    ``arkit`` weights), ``rotation.png``, ``translation.png``, ``rms.png``.
    """
    x = np.array([f["frame"] for f in frames], float)
    out = {}
    panels = []
    for r in regions:
        series = [(e, np.array([f["weights"][r][e] for f in frames], float)) for e in expressions]
        panels.append(line_panel(x, series, title=f"expression weights: {r}", ylabel="weight", ylim=(0.0, 1.0)))
    if panels:
        out["weights.png"] = stack_panels(panels)
    shapes = arkit_panels(frames)
    if shapes:
        out["arkit.png"] = stack_panels(shapes)
    rot = np.array([f["head_rotation_deg"] for f in frames], float).reshape(-1, 3)
    out["rotation.png"] = line_panel(
        x,
        [(n, rot[:, i]) for i, n in enumerate(("pitch (x)", "yaw (y)", "roll (z)"))],
        title="head rotation relative to facing the camera",
        ylabel="deg",
    )
    cen = np.array([f["centre_mm"] for f in frames], float).reshape(-1, 3)
    out["translation.png"] = stack_panels(
        [
            line_panel(x, [(f"{a} (mm)", cen[:, i])], title=f"model centre in camera space: {a} ({d})", ylabel="mm")
            for i, (a, d) in enumerate((("x", "right"), ("y", "down"), ("z", "depth")))
        ]
    )
    rms = np.array([f["rms"] for f in frames], float)
    div = np.array([f["diverged"] for f in frames], bool)
    out["rms.png"] = line_panel(
        x,
        [("image RMS", rms)],
        title="image RMS after fitting (intensity 0..1; red: diverged)",
        ylabel="RMS",
        ylim=(0.0, float(np.nanmax(rms)) if rms.size else 0.1),
        hline=diverged_rms,
        marks=div,
    )
    return out
