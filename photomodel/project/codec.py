"""A :class:`~photomodel.project.datamodel.Project` and the JSON-able dict of its file, both ways.

Writing (:func:`project_to_dict`) rounds to the documented precision (clicks 1e-3 px, 3-D points
and translations 1e-4 mm, rotations at full precision so they stay orthonormal), puts names in
definition order (features, curves, photos) and stores paths relative to the folder of the file
being written ("save as" re-expresses them so they still reach the same files). Reading
(:func:`project_from_dict`) validates the dict (:func:`photomodel.project.validate.validate`) and
builds the objects. Optional keys (``cameras_from``, ``camera_group``, ``click_sources``,
``curve_sources``, ``result.texture``, ``rig``, ``people``) are omitted when unset, so files without
them stay byte-identical.
"""

from __future__ import annotations

import math
import os
from pathlib import Path
from typing import Any

import numpy as np

from photomodel.camera import Camera
from photomodel.errors import ProjectError
from photomodel.project.datamodel import (
    CurveDef,
    Expression,
    ExpressionResult,
    Feature,
    Photo,
    Project,
    RigRecord,
    TextureResult,
)
from photomodel.project.format import FORMAT_NAME, FORMAT_VERSION
from photomodel.project.jsontext import plain
from photomodel.project.validate import validate

_PIXEL_DECIMALS = 3  # 1e-3 px: far below click accuracy, keeps files readable
_MM_DECIMALS = 4  # 1e-4 mm = 0.1 µm: far below scan/fit accuracy
_CONFIDENCE_DECIMALS = 3  # a detector's score means nothing past the third decimal


# ---------------------------------------------------------------------------------------
# Project → dict
# ---------------------------------------------------------------------------------------
def project_to_dict(project: Project, target: Path | None) -> dict:
    """The project as the JSON-able dict to write to ``target`` (rounded, canonical order).

    When ``target`` is in another folder than ``project.path`` (save as), relative paths are
    re-expressed so they still find their files.
    """
    origin = project.path.parent if project.path is not None else None
    folder = target.parent if target is not None else origin

    def stored(p: str) -> str:
        return _stored_path(p, origin, folder)

    order = {
        "feature": {f.name: i for i, f in enumerate(project.features)},
        "curve": {c.name: i for i, c in enumerate(project.curves)},
    }
    d = {
        "format": FORMAT_NAME,
        "version": FORMAT_VERSION,
        "name": project.name,
        "generic_mesh": (
            project.generic_mesh if project.generic_mesh.startswith("builtin:") else stored(project.generic_mesh)
        ),
        "features": [{"name": f.name, "vertex": int(f.vertex), "pose": bool(f.pose)} for f in project.features],
        "curves": [{"name": c.name, "vertices": [int(v) for v in c.vertices]} for c in project.curves],
        "expressions": [_expression_dict(e, order, stored) for e in project.expressions],
    }
    if project.rig is not None:  # optional (version 4): projects without a rig omit the key
        rig = project.rig
        d["rig"] = {
            "source": rig.source,
            "neutral": rig.neutral,
            "shapes": list(rig.shapes),
            "file": stored(rig.file),
            "report": _jsonable(rig.report),
        }
    if project.people:  # optional (version 6): projects referring to nobody omit the key
        d["people"] = [_person_path(p, origin, folder) for p in project.people]
    return d


def _person_path(p: str, origin: Path | None, folder: Path | None) -> str:
    """How a :attr:`Project.people` entry is written: relative to ``folder`` even when outside it
    (``../alice/alice.facestudio.json``: people are usually siblings), re-expressed when saving to
    another folder; an absolute entry stays absolute."""
    pp = Path(p)
    if pp.is_absolute() or origin is None or folder is None or origin == folder:
        return pp.as_posix()
    try:
        return Path(os.path.relpath(os.path.normpath(origin / pp), folder)).as_posix()
    except ValueError:  # another drive (Windows)
        return Path(os.path.normpath(origin / pp)).as_posix()


def _ordered(d: dict, order: dict) -> list:
    """Keys of ``d``: defined names in definition order, then any undefined ones (validation
    rejects them)."""
    return sorted(d, key=lambda k: (order.get(k, len(order)), k))


def _expression_dict(expr: Expression, order: dict, stored) -> dict:
    ed: dict[str, Any] = {"name": expr.name}
    if expr.cameras_from is not None:  # optional: files without it omit the key
        ed["cameras_from"] = expr.cameras_from
    ed["photos"] = [_photo_dict(p, order, stored) for p in expr.photos]
    ed["result"] = None
    if expr.result is not None:
        photo_order = {p.id: i for i, p in enumerate(expr.photos)}
        ed["result"] = _result_dict(expr.result, order["feature"], photo_order, stored)
    return ed


def _photo_dict(p: Photo, order: dict, stored) -> dict:
    features = order["feature"]
    pd: dict[str, Any] = {
        "id": p.id,
        "path": stored(p.path),
        "width": int(p.width),
        "height": int(p.height),
        "preset": p.preset,
        "focal_mm_guess": None if p.focal_mm_guess is None else float(p.focal_mm_guess),
    }
    if p.camera_group is not None:  # optional: photos without a group omit the key
        pd["camera_group"] = p.camera_group
    pd["points"] = {k: _round_list(p.points[k], _PIXEL_DECIMALS) for k in _ordered(p.points, features)}
    meta = p.click_meta()
    if meta:  # optional (version 3): photos whose clicks are all the artist's omit the key
        pd["click_sources"] = {k: _click_source_dict(meta[k]) for k in _ordered(meta, features)}
    pd["hidden"] = sorted(p.hidden, key=lambda k: (features.get(k, len(features)), k))
    pd["curves"] = {k: _round_list(p.curves[k], _PIXEL_DECIMALS) for k in _ordered(p.curves, order["curve"])}
    curve_meta = p.curve_meta()
    if curve_meta:  # optional (version 5): photos whose curves are all the artist's omit the key
        pd["curve_sources"] = {k: curve_meta[k] for k in _ordered(curve_meta, order["curve"])}
    return pd


def _click_source_dict(meta: dict) -> dict:
    out = {"source": meta["source"]}
    if "confidence" in meta:
        out["confidence"] = round(float(meta["confidence"]), _CONFIDENCE_DECIMALS)
    return out


def _result_dict(r: ExpressionResult, feature_order: dict, photo_order: dict, stored) -> dict:
    rd: dict[str, Any] = {
        "cameras": {k: _camera_dict(r.cameras[k]) for k in _ordered(r.cameras, photo_order)},
        "points_3d": {k: _round_list(r.points_3d[k], _MM_DECIMALS) for k in _ordered(r.points_3d, feature_order)},
        "mesh_obj": None if r.mesh_obj is None else stored(r.mesh_obj),
        "mesh_ply": None if r.mesh_ply is None else stored(r.mesh_ply),
        "report": _jsonable(r.report),
    }
    if r.texture is not None:  # optional: files without a texture omit the key
        tx = r.texture
        rd["texture"] = {
            "size": int(tx.size),
            "image": stored(tx.image),
            "weight_maps": {k: stored(tx.weight_maps[k]) for k in _ordered(tx.weight_maps, photo_order)},
            "exports": {k: stored(tx.exports[k]) for k in sorted(tx.exports)},
            "report": _jsonable(tx.report),
        }
    return rd


def _stored_path(p: str, origin: Path | None, folder: Path | None) -> str:
    """How a path is written: POSIX separators; relative to ``folder`` when inside it, else
    absolute. A relative ``p`` is relative to ``origin`` (the folder the project was loaded
    from or last saved to) and kept as it is if the project has no folder yet."""
    pp = Path(p)
    if not pp.is_absolute():
        if origin is None or folder is None or origin == folder:
            return pp.as_posix()
        pp = Path(os.path.normpath(origin / pp))
    if folder is not None:
        try:
            return pp.relative_to(folder).as_posix()
        except ValueError:
            pass  # outside the project folder: kept absolute (documented as non-portable)
    return pp.as_posix()


#: Beyond this magnitude a double has no digits after the decimal point worth rounding away
#: (2^53: every double from there on is an integer), and ``np.round`` would overflow to inf.
_ROUND_LIMIT = 2.0**53


def _round_list(a: np.ndarray, decimals: int) -> list:
    """``a`` rounded to ``decimals`` as nested lists; values too large to have decimals are kept
    exactly (rounding -1e308 to 1e-4 would give -inf, a value nobody wrote)."""
    a = np.asarray(a, dtype=float)
    big = np.abs(a) >= _ROUND_LIMIT
    if not big.any():
        return np.round(a, decimals).tolist()
    with np.errstate(over="ignore", invalid="ignore"):
        return np.where(big, a, np.round(a, decimals)).tolist()


def _camera_dict(cam: Camera) -> dict:
    d = cam.to_dict()
    # rotation at full precision (it must stay orthonormal); translation at the mm precision
    d["rotation"] = np.asarray(cam.R, float).tolist()
    d["translation_mm"] = _round_list(cam.t, _MM_DECIMALS)
    d["focal_px"] = round(float(cam.f), _PIXEL_DECIMALS + 3)
    return d


def _jsonable(node):
    """A free-form report as plain JSON: numpy → Python, non-finite floats → None (null)."""
    if isinstance(node, dict):
        return {str(k): _jsonable(v) for k, v in node.items()}
    if isinstance(node, (list, tuple)):
        return [_jsonable(v) for v in node]
    if isinstance(node, np.ndarray):
        return _jsonable(node.tolist())
    if isinstance(node, (bool, np.bool_)):
        return bool(node)
    if isinstance(node, (int, np.integer)):
        return int(node)
    if isinstance(node, (float, np.floating)):
        x = float(node)
        return x if math.isfinite(x) else None
    if node is None or isinstance(node, str):
        return node
    if isinstance(node, Path):
        return node.as_posix()
    raise ProjectError(f"fit report value {node!r} of type {type(node).__name__} cannot be stored in JSON")


# ---------------------------------------------------------------------------------------
# dict → Project
# ---------------------------------------------------------------------------------------
def project_from_dict(d: Any, path: str | os.PathLike | None = None) -> Project:
    """Validate a parsed project dict and build the :class:`Project`.

    ``path`` (the file it came from) is used for error messages and for resolving relative
    paths. Raises :class:`ProjectError` naming the field at fault.
    """
    source = Path(path).name if path is not None else "project"
    validate(d, source)
    return Project(
        name=d["name"],
        generic_mesh=d["generic_mesh"],
        features=[Feature(f["name"], f["vertex"], f["pose"]) for f in d["features"]],
        curves=[CurveDef(c["name"], c["vertices"]) for c in d.get("curves", [])],
        expressions=[_expression_from_dict(e) for e in d["expressions"]],
        rig=_rig_from_dict(d.get("rig")),
        people=list(d.get("people", [])),
        path=None if path is None else Path(path).absolute(),
    )


def _rig_from_dict(r: dict | None) -> RigRecord | None:
    if r is None:
        return None
    return RigRecord(
        source=r["source"],
        neutral=r["neutral"],
        shapes=list(r["shapes"]),
        file=r["file"],
        report=plain(r.get("report", {})),
    )


def _expression_from_dict(e: dict) -> Expression:
    photos = [_photo_from_dict(p) for p in e["photos"]]
    r = e.get("result")
    result = None if r is None else _result_from_dict(r)
    return Expression(name=e["name"], photos=photos, result=result, cameras_from=e.get("cameras_from"))


def _photo_from_dict(p: dict) -> Photo:
    return Photo(
        id=p["id"],
        path=p["path"],
        width=p["width"],
        height=p["height"],
        preset=p["preset"],
        focal_mm_guess=p.get("focal_mm_guess"),
        points=p.get("points", {}),
        hidden=p.get("hidden", []),
        curves=p.get("curves", {}),
        camera_group=p.get("camera_group"),
        sources={k: c["source"] for k, c in p.get("click_sources", {}).items()},
        confidence={k: c["confidence"] for k, c in p.get("click_sources", {}).items() if "confidence" in c},
        curve_sources=p.get("curve_sources", {}),
    )


def _result_from_dict(r: dict) -> ExpressionResult:
    result = ExpressionResult(
        cameras={k: Camera.from_dict(c) for k, c in r["cameras"].items()},
        points_3d=r["points_3d"],
        mesh_obj=r.get("mesh_obj"),
        mesh_ply=r.get("mesh_ply"),
        report=plain(r.get("report", {})),
    )
    t = r.get("texture")
    if t is not None:
        result.texture = TextureResult(
            size=t["size"],
            image=t["image"],
            weight_maps=t["weight_maps"],
            exports=t.get("exports", {}),
            report=plain(t.get("report", {})),
        )
    return result
