"""Expression edits of a tracked clip (Yang et al. 2012, §4–5, Eq. 25) and their file, ``edits.json``.

An edit changes the region blending weights ``W_t`` (T, R, m) of the frames; the edited
parameters are the model's ``α`` closest to them (:meth:`tracking.blendshape_face.FaceModel.alpha_of_weights`,
exact for weights the model can reach). The edits of a clip are a list applied in order:

* ``scale`` — magnify (factor > 1) or suppress (< 1) one expression (Eq. 25,
  ``β'_t = β_0 + f (β_t − β_0)`` with ``β_0`` the neutral face, on that expression's component:
  its weight is multiplied by ``f`` and the neutral weight takes the difference, so each region's
  weights still sum to 1). ``f`` is a number, or a curve ``[[frame, f], …]`` interpolated linearly
  (held beyond its ends). Over a ``span`` the factor ramps in and out over ``ramp`` frames at the
  span's ends that are inside the clip (a smoothstep: no jump at the span's edge). The
  edited weights are limited to :data:`tracking.blendshape_face.WEIGHT_RANGE` (a frame's change is
  shortened), the model's extrapolation limit.
* ``replace`` — §5.2: the span's weights replaced by an interpolation through a chosen frame's:
  the chosen frame's weights at the span's centre, linear from the frames just outside the span
  (the span's own end frames at the clip's ends) to it. Weights interpolated linearly stay in the
  convex range of their ends.

``edits.json`` (:data:`FORMAT`, :data:`VERSION`), beside the track's ``track.json``::

    {"format": "facestudio-edits", "version": 1,
     "track": "track.json",              # the results the edits apply to (same folder)
     "frames": 40,                       # frames of the track when the edits were made
     "smooth": {"second_difference": 2.0, ...} | null,   # SmoothOptions of the solve, or none
     "edits": [{"op": "scale", "expression": "smile", "factor": 0.5, "span": [10, 40], "ramp": 3},
               {"op": "scale", "expression": "smile", "curve": [[10, 1.0], [25, 0.2], [40, 1.0]]},
               {"op": "replace", "span": [60, 90], "frame": 75}]}

Spans are inclusive frame ranges ``[first, last]``; ``span`` omitted means the whole clip.
"""

from __future__ import annotations

import json
import os
from pathlib import Path

import numpy as np

from photomodel.errors import FaceStudioError
from photomodel.exchange.files import atomic_write_bytes
from tracking.blendshape_face import WEIGHT_RANGE, FaceModel

__all__ = [
    "FORMAT",
    "VERSION",
    "DEFAULT_RAMP",
    "EditError",
    "check_edit",
    "scale_factors",
    "scale_expression",
    "replace_span",
    "apply_edits",
    "edited_alphas",
    "edits_document",
    "save_edits",
    "load_edits",
]

FORMAT = "facestudio-edits"
VERSION = 1
#: Frames over which a scale edit ramps in and out at a span's ends inside the clip.
DEFAULT_RAMP = 3


class EditError(FaceStudioError):
    """An edit that cannot apply: the message names the edit and the field."""


def _span(edit: dict, frames: int) -> tuple[int, int]:
    span = edit.get("span")
    if span is None:
        return 0, frames - 1
    a, b = (int(x) for x in span)
    if not 0 <= a <= b < frames:
        raise EditError(f"span {a}:{b} of the {edit.get('op')} edit is outside the clip's frames 0:{frames - 1}")
    return a, b


def check_edit(edit: dict, names, frames: int) -> dict:
    """``edit`` checked against a model's expression ``names`` and the clip's ``frames``; EditError
    naming the problem otherwise. Returns the edit itself."""
    op = edit.get("op")
    if op == "scale":
        if edit.get("expression") not in names[1:]:
            raise EditError(
                f"scale: expression {edit.get('expression')!r} is not one of the model's {', '.join(names[1:])}"
            )
        if ("factor" in edit) == ("curve" in edit):
            raise EditError("scale: give either a factor or a curve [[frame, factor], ...]")
        if "curve" in edit and (np.asarray(edit["curve"], float).ndim != 2 or len(edit["curve"]) < 1):
            raise EditError("scale: the curve must be a list of [frame, factor] pairs")
    elif op == "replace":
        a, b = _span(edit, frames) if edit.get("span") is not None else (None, None)
        if a is None:
            raise EditError("replace: a span [first, last] is needed")
        if not 0 <= int(edit.get("frame", -1)) < frames:
            raise EditError(f"replace: frame {edit.get('frame')} is outside the clip's frames 0:{frames - 1}")
    else:
        raise EditError(f"unknown edit op {op!r} (scale, replace)")
    _span(edit, frames)
    return edit


def scale_factors(edit: dict, frames: int) -> np.ndarray:
    """(T,) the factor of a ``scale`` edit at each frame (1 outside its span, ramped at its ends)."""
    a, b = _span(edit, frames)
    t = np.arange(frames, dtype=float)
    if "curve" in edit:
        c = np.asarray(edit["curve"], float)
        c = c[np.argsort(c[:, 0])]
        f = np.interp(t, c[:, 0], c[:, 1])
    else:
        f = np.full(frames, float(edit["factor"]))
    ramp = max(int(edit.get("ramp", DEFAULT_RAMP)), 0)
    s = ((t >= a) & (t <= b)).astype(float)
    if ramp:
        up = np.clip((t - a + 1) / (ramp + 1), 0, 1) if a > 0 else np.ones(frames)
        down = np.clip((b + 1 - t) / (ramp + 1), 0, 1) if b < frames - 1 else np.ones(frames)
        r = np.minimum(up, down)
        s = s * r * r * (3 - 2 * r)  # smoothstep
    return 1.0 + s * (f - 1.0)


def scale_expression(weights: np.ndarray, k: int, factors: np.ndarray) -> np.ndarray:
    """Eq. (25) on expression ``k``: weights (T, R, m) with ``w_k ← f_t w_k`` and the neutral
    weight taking the difference; each frame's change shortened to stay in :data:`WEIGHT_RANGE`."""
    W = np.array(weights, float)
    change = (np.asarray(factors, float)[:, None] - 1.0) * W[:, :, k]  # (T, R)
    lo, hi = WEIGHT_RANGE
    with np.errstate(divide="ignore", invalid="ignore"):
        # w_k + s·change ∈ range and w_0 − s·change ∈ range
        lim = np.stack(
            [
                np.where(change > 0, (hi - W[:, :, k]) / change, np.inf),
                np.where(change < 0, (lo - W[:, :, k]) / change, np.inf),
                np.where(change > 0, (W[:, :, 0] - lo) / change, np.inf),
                np.where(change < 0, (W[:, :, 0] - hi) / change, np.inf),
            ]
        ).min(axis=0)
    s = np.clip(lim.min(axis=1), 0.0, 1.0)[:, None]
    W[:, :, k] += s * change
    W[:, :, 0] -= s * change
    return W


def replace_span(weights: np.ndarray, first: int, last: int, chosen: int) -> np.ndarray:
    """§5.2: frames ``first..last`` of weights (T, R, m) replaced by the linear interpolation from
    the frame before the span to frame ``chosen``'s weights at the span's centre and on to the frame
    after it (the span's own ends at the clip's ends)."""
    W = np.array(weights, float)
    T = len(W)
    lo, hi = max(first - 1, 0), min(last + 1, T - 1)
    mid = 0.5 * (first + last)
    key_t = np.array([lo, mid, hi], float)
    keys = np.stack([W[lo], np.asarray(weights, float)[chosen], W[hi]])
    t = np.arange(first, last + 1, dtype=float)
    flat = keys.reshape(3, -1)
    W[first : last + 1] = np.stack([np.interp(t, key_t, flat[:, j]) for j in range(flat.shape[1])], 1).reshape(
        len(t), *W.shape[1:]
    )
    return W


def apply_edits(model: FaceModel, weights: np.ndarray, edits: list[dict]) -> np.ndarray:
    """(T, R, m) weights after ``edits`` (applied in order; each checked by :func:`check_edit`)."""
    W = np.array(weights, float)
    T = len(W)
    for e in edits:
        check_edit(e, model.names, T)
        if e["op"] == "scale":
            W = scale_expression(W, model.names.index(e["expression"]), scale_factors(e, T))
        else:
            a, b = _span(e, T)
            W = replace_span(W, a, b, int(e["frame"]))
    return W


def edited_alphas(model: FaceModel, alphas: np.ndarray, edits: list[dict]) -> np.ndarray:
    """(T, a) parameters after ``edits`` of the tracked (or smoothed) ``alphas`` (T, a)."""
    alphas = np.asarray(alphas, float)
    W = np.array([model.region_weights(a) for a in alphas])
    E = apply_edits(model, W, edits)
    return np.array([model.alpha_of_weights(w) for w in E]).reshape(alphas.shape)


def edits_document(edits: list[dict], frames: int, smooth: dict | None) -> dict:
    """The ``edits.json`` document (module docstring)."""
    return {
        "format": FORMAT,
        "version": VERSION,
        "track": "track.json",
        "frames": int(frames),
        "smooth": smooth,
        "edits": list(edits),
    }


def save_edits(track_dir: str | os.PathLike, doc: dict) -> Path:
    """Write ``doc`` as ``<track_dir>/edits.json`` atomically; returns the path."""
    path = Path(track_dir) / "edits.json"
    atomic_write_bytes(path, json.dumps(doc, indent=1).encode())
    return path


def load_edits(track_dir: str | os.PathLike) -> dict | None:
    """``<track_dir>/edits.json`` (None when there is none); EditError when unreadable or of another format."""
    path = Path(track_dir) / "edits.json"
    if not path.is_file():
        return None
    try:
        doc = json.loads(path.read_text())
    except (OSError, ValueError) as exc:
        raise EditError(f"{path}: cannot read the edits ({exc})") from exc
    if not isinstance(doc, dict) or doc.get("format") != FORMAT or not isinstance(doc.get("edits"), list):
        raise EditError(f"{path}: not a Face Studio edits file")
    if doc.get("version") != VERSION:
        raise EditError(f"{path}: edits file version {doc.get('version')} (this Face Studio reads {VERSION})")
    return doc
