"""The checks a parsed project dict passes before it becomes a project or is written.

:func:`validate` runs, in this order (after the JSON-level checks of
:func:`photomodel.project.jsontext.parse_json`):

1. ``format`` and ``version`` (a newer version is refused: "written by a newer Face Studio";
   an older one is upgraded in memory, see :data:`~photomodel.project.datamodel.FORMAT_VERSION`);
2. the structure, against ``schema.json`` beside this module (JSON Schema draft 2020-12, shipped
   with the package) — the single most relevant schema error is reported, worded with the
   schema's ``x-expected`` notes;
3. cross-references the schema cannot express (:func:`cross_reference_problems`): unique names
   and photo ids, points / hidden features / curves that name defined features and curves, known
   camera presets, points within reach of the photo, result cameras that are rotations of the
   right image size, and ``cameras_from`` naming another expression without a cycle.

Structure is validated with the :mod:`jsonschema` library rather than by hand: it is a kept,
widely used validator whose errors carry JSON-pointer paths to the offending value (which is
what our messages need), the schema doubles as a machine-readable spec of the format for
other tools, and hand-written type checks for a nested format rot as the format grows. (Only
the bulky maps of ``[u, v]`` / ``[x, y, z]`` arrays are checked by a small Python keyword, ~20×
faster; a test keeps it in agreement with the shipped schema — see :func:`_validator`.)
"""

from __future__ import annotations

import copy
import json
from dataclasses import dataclass
from functools import lru_cache
from importlib import resources
from typing import Any

import jsonschema
import numpy as np
from jsonschema.exceptions import ValidationError, best_match

from photomodel.camera import PRESET_AZIMUTH_DEG
from photomodel.errors import ProjectError
from photomodel.project.format import FILE_SUFFIX, FORMAT_NAME, FORMAT_VERSION
from photomodel.project.jsontext import check_depth
from photomodel.project.problems import did_you_mean, fmt_key, fmt_path, listing, problems_error, short

#: A click may lie outside its photo by at most this fraction of the image width/height.
#: Clicks slightly past the border are legitimate (a chin cut off by the frame, a point placed
#: by zooming out); a click far outside almost always means a wrong width/height or swapped
#: u/v, so it is an error. Nothing in between is warned about: a library warning at load time
#: reaches nobody, and the fit report shows each click's residual anyway.
OUT_OF_BOUNDS_MARGIN = 0.5

#: Tolerance on ``‖RᵀR − I‖`` for stored camera rotations (stored at full precision, so a
#: genuine rotation passes with ~1e-15; a hand-edited or truncated matrix does not).
ROTATION_TOL = 1e-6


def validate(d: Any, source: str) -> None:
    """All checks of a parsed project dict (steps 1-3 of the module docstring); ProjectError
    naming ``source`` and the JSON path of each problem."""
    check_depth(d, source)  # every check below walks the tree recursively
    _check_version(d, source)
    # Older versions need no upgrade: version 2 only added the optional photo camera_group,
    # version 3 the optional click_sources, which older files' photos do not have (their clicks
    # are all the artist's), version 4 the optional rig, version 5 the optional curve_sources
    # (every older curve was drawn by hand) and version 6 the optional people (references to other
    # projects) and the rig source "multilinear". (A future change that renames or restructures a field
    # converts the older dict here, before the schema check.)
    _check_schema(d, source)
    problems = cross_reference_problems(d)
    if problems:
        raise problems_error(source, problems)


def _check_version(d: Any, source: str) -> None:
    if not isinstance(d, dict) or d.get("format") != FORMAT_NAME:
        got = d.get("format") if isinstance(d, dict) else type(d).__name__
        raise ProjectError(
            f'{source}: not a Face Studio project file (expected "format": "{FORMAT_NAME}", got {short(got)})'
        )
    version = d.get("version")
    if isinstance(version, bool) or not isinstance(version, int):
        raise ProjectError(f"{source}: version: expected an integer format version, got {short(version)}")
    if version > FORMAT_VERSION:
        raise ProjectError(
            f"{source}: written by a newer Face Studio (project format version {version}; "
            f"this version reads up to {FORMAT_VERSION}); please update Face Studio"
        )
    if version < 1:
        raise ProjectError(f"{source}: version: unknown project format version {version}")


# ---------------------------------------------------------------------------------------
# the JSON Schema
# ---------------------------------------------------------------------------------------
@lru_cache(maxsize=1)
def project_schema() -> dict:
    """The JSON Schema (draft 2020-12) of the format (versions 1 to 3), shipped as package data."""
    text = resources.files("photomodel.project").joinpath("schema.json").read_text(encoding="utf-8")
    return json.loads(text)


#: Where the bulk of a project lives — maps of many small coordinate arrays — and the
#: shipped-schema definition each map's values follow.
_LEAF_MAPS = {("photo", "points"): "pixel", ("photo", "curves"): "polyline", ("result", "points_3d"): "vec3"}


@lru_cache(maxsize=1)
def _validator():
    """The draft 2020-12 validator of :func:`project_schema`, with one speed-up.

    Checking every ``[u, v]`` through jsonschema's generic machinery costs ~40 µs each (a
    project with 25 000 clicks and curve points took 1 s), and saving validates too. So the
    maps of coordinate arrays (:data:`_LEAF_MAPS`) are checked by an ``x-leaves`` keyword in
    plain Python instead; the shipped schema keeps the full standard definition, and
    ``tests/test_project_validate.py`` checks that both agree.
    """

    schema = copy.deepcopy(project_schema())
    for (owner, prop), kind in _LEAF_MAPS.items():
        node = schema["$defs"][owner]["properties"][prop]
        del node["additionalProperties"]
        node["x-leaves"] = kind
    cls = jsonschema.validators.extend(jsonschema.Draft202012Validator, {"x-leaves": _leaves_keyword})
    return cls(_inline_refs(schema, schema))


def _inline_refs(node, root: dict):
    """``node`` with every local ``{"$ref": ...}`` replaced by (a copy of) what it points to.

    Resolving a ``$ref`` is most of jsonschema's time on a project (168 features, each a
    reference to a reference); the inlined schema validates 3x faster. The schema has no
    recursive references, and no ``$ref`` with sibling keywords, so error paths keep the same
    steps minus the ``$ref`` hops, which :func:`_expected_note` walks through anyway."""
    if isinstance(node, dict):
        if "$ref" in node:
            if len(node) != 1:
                raise ValueError(f"project schema: a $ref with sibling keywords is not inlined: {sorted(node)}")
            return _inline_refs(_resolve_ref(root, node["$ref"]), root)
        return {k: _inline_refs(v, root) for k, v in node.items() if k != "$defs"}
    if isinstance(node, list):
        return [_inline_refs(v, root) for v in node]
    return node


def _leaves_keyword(validator, kind, instance, schema):
    """jsonschema keyword: every value of the object ``instance`` is a ``kind`` leaf."""

    if not isinstance(instance, dict):
        return  # the "type" keyword reports it
    for key, value in instance.items():
        if kind == "polyline":
            if not isinstance(value, list) or len(value) < 2:
                msg = f"expected a polyline of at least two [u, v] points, got {short(value)}"
                yield ValidationError(msg, path=[key])
                continue
            for i, uv in enumerate(value):
                if not _is_numbers(uv, 2):
                    yield ValidationError(f"expected [u, v] of two finite numbers, got {short(uv)}", path=[key, i])
                    break
        elif kind == "pixel" and not _is_numbers(value, 2):
            yield ValidationError(f"expected [u, v] of two finite numbers, got {short(value)}", path=[key])
        elif kind == "vec3" and not _is_numbers(value, 3):
            yield ValidationError(f"expected [x, y, z] of three finite numbers (mm), got {short(value)}", path=[key])


def _is_numbers(v, n: int) -> bool:
    # exact types: a JSON true/false parses to bool, which is an int subclass but not a number here
    return type(v) is list and len(v) == n and all(type(x) is float or type(x) is int for x in v)


def _check_schema(d: dict, source: str) -> None:

    errors = list(_validator().iter_errors(d))
    if not errors:
        return
    err = best_match(errors)
    path, message = _describe_schema_error(err, d)
    more = f" (and {len(errors) - 1} more problem{'s' if len(errors) > 2 else ''})" if len(errors) > 1 else ""
    exc = ProjectError(f"{source}: {path}: {message}{more}")
    exc.problems = [(path, message)]
    raise exc


_ONE_STEP = {"properties", "patternProperties", "prefixItems"}  # keyword, name → subschema, +1 depth
_DESCEND = {"items", "additionalProperties", "contains", "unevaluatedItems", "unevaluatedProperties"}
_BRANCH = {"anyOf", "oneOf", "allOf", "$defs"}  # keyword, index → subschema, same depth


def _describe_schema_error(err, instance) -> tuple[str, str]:
    """(path, message) for a jsonschema error, worded with the schema's ``x-expected`` notes.

    The deepest subschema on the failing keyword's path with an ``x-expected`` note
    (:func:`_expected_note`) names what the value at that depth should have been. Errors about
    an object's keys (``required``, ``additionalProperties``) keep jsonschema's own, already
    precise, wording.
    """
    ipath = list(err.absolute_path)
    if err.validator in ("required", "additionalProperties", "dependentRequired", "x-leaves"):
        return fmt_path(ipath), err.message
    expected = _expected_note(list(err.absolute_schema_path))
    if expected is None:
        return fmt_path(ipath), err.message
    text, depth = expected
    value = instance
    for k in ipath[:depth]:
        value = value[k]
    return fmt_path(ipath[:depth]), f"expected {text}, got {short(value)}"


def _expected_note(spath: list) -> tuple[str, int] | None:
    """The deepest ``x-expected`` note on a schema path and how deep into the instance it
    applies: walks the path from the root, following ``$ref``, counting instance steps."""
    root = project_schema()
    node, depth, expected = root, 0, None
    i = 0
    while True:
        while isinstance(node, dict) and "$ref" in node and (i >= len(spath) or spath[i] not in node):
            node = _resolve_ref(root, node["$ref"])
        if isinstance(node, dict) and "x-expected" in node:
            expected = (node["x-expected"], depth)
        if i >= len(spath) or not isinstance(node, dict):
            return expected
        key = spath[i]
        if key in _ONE_STEP and i + 1 < len(spath):
            node, depth, i = node[key][spath[i + 1]], depth + 1, i + 2
        elif key in _BRANCH and i + 1 < len(spath):
            node, i = node[key][spath[i + 1]], i + 2
        elif key in _DESCEND and isinstance(node.get(key), dict):
            node, depth, i = node[key], depth + 1, i + 1
        else:
            return expected  # the failing keyword itself


def _resolve_ref(root: dict, ref: str) -> dict:
    if not ref.startswith("#/"):
        raise ValueError(f"project schema: only local $refs are supported, got {ref!r}")
    node = root
    for part in ref[2:].split("/"):
        node = node[part.replace("~1", "/").replace("~0", "~")]
    return node


# ---------------------------------------------------------------------------------------
# cross-references
# ---------------------------------------------------------------------------------------
@dataclass(frozen=True)
class _Defined:
    """The names a project defines, as lists (for suggestions) and sets (for look-ups)."""

    features: list
    curves: list
    feature_set: frozenset
    curve_set: frozenset


def cross_reference_problems(d: dict) -> list[tuple[str, str]]:
    """Checks of a schema-valid dict that JSON Schema cannot express; (path, message) each."""
    features = [f["name"] for f in d["features"]]
    curves = [c["name"] for c in d.get("curves", [])]
    problems: list[tuple[str, str]] = []
    problems += _duplicates(features, "features", "feature name")
    problems += _duplicates(curves, "curves", "curve name")
    problems += _duplicates([e["name"] for e in d["expressions"]], "expressions", "expression name")
    problems += _cameras_from_problems(d["expressions"])
    defined = _Defined(features, curves, frozenset(features), frozenset(curves))
    for ei, e in enumerate(d["expressions"]):
        problems += _expression_problems(f"expressions[{ei}]", e, defined)
    rig = d.get("rig")
    names = [e["name"] for e in d["expressions"]]
    if rig is not None and rig["neutral"] not in names:
        problems.append(
            (
                "rig.neutral",
                f"names no expression ({short(rig['neutral'])}); "
                f"expressions: {listing(names)}{did_you_mean(rig['neutral'], names)}",
            )
        )
    for i, ref in enumerate(d.get("people", [])):
        if not ref.endswith(FILE_SUFFIX):
            problems.append((f"people[{i}]", f"expected the path of a project file (*{FILE_SUFFIX}), got {short(ref)}"))
    return problems


def _expression_problems(ep: str, e: dict, defined: _Defined) -> list[tuple[str, str]]:
    """Photo ids, each photo, and the result of one expression dict."""
    problems = _duplicates([p["id"] for p in e["photos"]], f"{ep}.photos", "photo id", field_name="id")
    sizes: dict[str, tuple[int, int]] = {}
    for pi, p in enumerate(e["photos"]):
        sizes.setdefault(p["id"], (p["width"], p["height"]))
        problems += _photo_problems(f"{ep}.photos[{pi}]", p, defined)
    r = e.get("result")
    if r is not None:
        problems += _result_problems(f"{ep}.result", r, sizes, defined)
    return problems


def _photo_problems(pp: str, p: dict, defined: _Defined) -> list[tuple[str, str]]:
    """A photo's preset, and its points, hidden features and curves: defined and within reach."""
    problems: list[tuple[str, str]] = []
    fset, cset = defined.feature_set, defined.curve_set
    w, h = p["width"], p["height"]
    if p["preset"] not in PRESET_AZIMUTH_DEG:
        problems.append(
            (
                f"{pp}.preset",
                f"unknown camera preset {p['preset']!r}; choose one of {', '.join(sorted(PRESET_AZIMUTH_DEG))}",
            )
        )
    points = p.get("points", {})
    for name in points:
        if name not in fset:
            problems.append(
                (
                    f"{pp}.points{fmt_key(name)}",
                    f"no feature named {name!r} is defined{did_you_mean(name, defined.features)}",
                )
            )
    if points:
        names, uvs = list(points), list(points.values())
        for j in np.flatnonzero(_far_outside(np.array(uvs, float), w, h)):
            problems.append((f"{pp}.points{fmt_key(names[j])}", _outside_message(uvs[j], w, h)))
    for name in p.get("click_sources", {}):
        if name not in points:
            problems.append(
                (
                    f"{pp}.click_sources{fmt_key(name)}",
                    f"{name!r} has no click in this photo's points; a click's source needs the click",
                )
            )
    for hi, name in enumerate(p.get("hidden", [])):
        if name not in fset:
            problems.append(
                (f"{pp}.hidden[{hi}]", f"no feature named {name!r} is defined{did_you_mean(name, defined.features)}")
            )
    for name, line in p.get("curves", {}).items():
        at = f"{pp}.curves{fmt_key(name)}"
        if name not in cset:
            problems.append((at, f"no curve named {name!r} is defined{did_you_mean(name, defined.curves)}"))
        bad = np.flatnonzero(_far_outside(np.asarray(line, float), w, h))
        if bad.size:
            problems.append((f"{at}[{bad[0]}]", _outside_message(line[bad[0]], w, h)))
    for name in p.get("curve_sources", {}):
        if name not in p.get("curves", {}):
            problems.append(
                (
                    f"{pp}.curve_sources{fmt_key(name)}",
                    f"{name!r} is not drawn in this photo's curves; a curve's source needs the curve",
                )
            )
    return problems


def _result_problems(rp: str, r: dict, sizes: dict, defined: _Defined) -> list[tuple[str, str]]:
    """A result's cameras (of photos of the expression, of their size, rotations), its 3-D points
    (of defined features) and its texture's weight maps (of photos of the expression)."""
    problems: list[tuple[str, str]] = []
    for pid, cam in r["cameras"].items():
        at = f"{rp}.cameras{fmt_key(pid)}"
        if pid not in sizes:
            problems.append(
                (
                    at,
                    f"camera for photo {pid!r}, which is not a photo of this expression"
                    f"{did_you_mean(pid, list(sizes))}",
                )
            )
        elif (cam["width"], cam["height"]) != sizes[pid]:
            problems.append(
                (
                    at,
                    f"camera image size {cam['width']}x{cam['height']} differs from photo "
                    f"{pid!r} ({sizes[pid][0]}x{sizes[pid][1]})",
                )
            )
        R = np.asarray(cam["rotation"], float)
        with np.errstate(over="ignore", invalid="ignore"):  # a huge entry: inf/nan, refused below
            err = float(np.abs(R.T @ R - np.eye(3)).max())
            det = float(np.linalg.det(R))
        if not err <= ROTATION_TOL or not det > 0:
            problems.append((f"{at}.rotation", f"not a rotation matrix (max |RᵀR − I| = {err:.2g}, det = {det:.6g})"))
    for name in r["points_3d"]:
        if name not in defined.feature_set:
            problems.append(
                (
                    f"{rp}.points_3d{fmt_key(name)}",
                    f"no feature named {name!r} is defined{did_you_mean(name, defined.features)}",
                )
            )
    for pid in (r.get("texture") or {}).get("weight_maps", {}):
        if pid not in sizes:
            problems.append(
                (
                    f"{rp}.texture.weight_maps{fmt_key(pid)}",
                    f"weight map for photo {pid!r}, which is not a photo of this expression"
                    f"{did_you_mean(pid, list(sizes))}",
                )
            )
    return problems


def _cameras_from_problems(expressions: list[dict]) -> list[tuple[str, str]]:
    """``cameras_from`` must name another expression of the project, without a cycle."""
    problems: list[tuple[str, str]] = []
    names = [e["name"] for e in expressions]
    source = {e["name"]: e.get("cameras_from") for e in expressions}
    for ei, e in enumerate(expressions):
        src = e.get("cameras_from")
        if src is None:
            continue
        at = f"expressions[{ei}].cameras_from"
        if src == e["name"]:
            problems.append((at, f"expression {src!r} cannot take its cameras from itself"))
        elif src not in source:
            problems.append(
                (
                    at,
                    f"no expression named {src!r} to take the cameras from"
                    f"{did_you_mean(src, [n for n in names if n != e['name']])}; "
                    f"expressions: {listing(names)}",
                )
            )
        else:
            chain, seen = [e["name"]], {e["name"]}
            while src is not None and src in source and src not in seen:
                chain.append(src)
                seen.add(src)
                src = source[src]
            if src == e["name"]:
                problems.append(
                    (
                        at,
                        "cameras_from goes round in a cycle ("
                        + " → ".join(chain + [src])
                        + "); one expression must recover its own "
                        "cameras",
                    )
                )
    return problems


def _duplicates(names: list[str], list_path: str, what: str, field_name: str = "name"):
    seen: dict[str, int] = {}
    out = []
    for i, n in enumerate(names):
        if n in seen:
            out.append(
                (f"{list_path}[{i}].{field_name}", f"{what} {n!r} is used twice (also at {list_path}[{seen[n]}])")
            )
        else:
            seen[n] = i
    return out


def _far_outside(uv: np.ndarray, width: int, height: int) -> np.ndarray:
    """(m,) bool: points more than OUT_OF_BOUNDS_MARGIN of the image size outside the image.

    The image covers ``[-0.5, W-0.5] × [-0.5, H-0.5]`` (pixel centres at integers).
    """
    mu, mv = OUT_OF_BOUNDS_MARGIN * width, OUT_OF_BOUNDS_MARGIN * height
    u, v = uv[:, 0], uv[:, 1]
    return (u < -0.5 - mu) | (u > width - 0.5 + mu) | (v < -0.5 - mv) | (v > height - 0.5 + mv)


def _outside_message(uv, width: int, height: int) -> str:
    return (
        f"[{uv[0]:g}, {uv[1]:g}] lies far outside the {width}x{height} photo (more than "
        f"{OUT_OF_BOUNDS_MARGIN:.0%} of its size beyond the border); check the photo's width/height "
        f"and that points are [u, v] in pixels"
    )
