"""Face Studio project files (format version 2): data model, validation, atomic save.

A project is one JSON file, ``<name>.facestudio.json``, that names the generic mesh, the
features (generic-mesh vertices the artist clicks, §5.1 of Pighin et al. 2002) and curves
(mesh polylines that hand-drawn image curves bind to, §5.1.3), and, per expression, the
photographs with their clicks and the fitted result. Every path in the file is relative to the
folder that holds it. Conventions are those of :mod:`photomodel.camera`: pixels ``u`` right,
``v`` down, pixel centres at integers; millimetres in the world. The format is documented field
by field in ``docs/project-format.md``.

Loading is the boundary where user data enters, so it is checked thoroughly and every
:class:`~photomodel.errors.ProjectError` names the file and the JSON path of the culprit, e.g.
``james.facestudio.json: expressions[0].photos[2].points.nose_tip: expected [u, v] of two
finite numbers, got [12.0]``. The checks run in this order:

1. JSON syntax (line and column), duplicate object keys, and the ``NaN``/``Infinity`` literals
   that Python's :mod:`json` accepts but JSON does not;
2. ``format`` and ``version`` (a newer version is refused: "written by a newer Face Studio";
   an older one is upgraded in memory, see :data:`FORMAT_VERSION`);
3. the structure, against ``schema.json`` beside this module (JSON Schema draft 2020-12, shipped with the
   package) — the single most relevant schema error is reported;
4. cross-references the schema cannot express: unique names and photo ids, points / hidden
   features / curves that name defined features and curves, known camera presets, points
   within reach of the photo, result cameras that are rotations of the right image size, and
   ``cameras_from`` naming another expression without a cycle.

Structure is validated with the :mod:`jsonschema` library rather than by hand: it is a kept,
widely used validator whose errors carry JSON-pointer paths to the offending value (which is
what our messages need), the schema doubles as a machine-readable spec of the format for
other tools, and hand-written type checks for a nested format rot as the format grows. (Only
the bulky maps of ``[u, v]`` / ``[x, y, z]`` arrays are checked by a small Python keyword, ~20×
faster; a test keeps it in agreement with the shipped schema — see :func:`_validator`.)

Saving is atomic: the text is written to a temporary file in the same folder, flushed and
fsynced, then moved over the project with :func:`os.replace`, so a crash leaves either the old
or the new file, never half of one. The previous version is kept as ``<file>.bak``. Saving to
another folder ("save as") rewrites relative paths so they still reach the same files.
"""

from __future__ import annotations

import difflib
import json
import math
import os
import re
import shutil
import tempfile
from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field
from functools import lru_cache
from importlib import resources
from pathlib import Path
from typing import Any

import numpy as np

from photomodel.camera import PRESET_AZIMUTH_DEG, Camera
from photomodel.errors import ProjectError

FORMAT_NAME = "facestudio-project"
#: The version this Face Studio writes; it reads every version from 1 up to this one.
#: History (``docs/project-format.md``, "Versioning"):
#:
#: * 1 — the first format.
#: * 2 — a photo may name its ``camera_group`` (photos taken with one camera and lens share one
#:   focal length). Upgrading a version-1 file: nothing to do (no photo has a group).
FORMAT_VERSION = 2
FILE_SUFFIX = ".facestudio.json"
BUILTIN_MESH = "builtin:template-v1"

#: A click may lie outside its photo by at most this fraction of the image width/height.
#: Clicks slightly past the border are legitimate (a chin cut off by the frame, a point placed
#: by zooming out); a click far outside almost always means a wrong width/height or swapped
#: u/v, so it is an error. Nothing in between is warned about: a library warning at load time
#: reaches nobody, and the fit report shows each click's residual anyway.
OUT_OF_BOUNDS_MARGIN = 0.5

#: Tolerance on ``‖RᵀR − I‖`` for stored camera rotations (stored at full precision, so a
#: genuine rotation passes with ~1e-15; a hand-edited or truncated matrix does not).
ROTATION_TOL = 1e-6

_PIXEL_DECIMALS = 3  # 1e-3 px: far below click accuracy, keeps files readable
_MM_DECIMALS = 4  # 1e-4 mm = 0.1 µm: far below scan/fit accuracy
_MAX_LISTED_PROBLEMS = 10


# ---------------------------------------------------------------------------------------
# data model
# ---------------------------------------------------------------------------------------
@dataclass
class Feature:
    """A named feature: the generic-mesh vertex that a click of that name corresponds to.

    Attributes
    ----------
    name : str
    vertex : int, index into the generic mesh's vertices.
    pose : bool, True if the feature is one of the initial features used for pose recovery
        (§5.1.1); False for refinement-only correspondences (§5.1.3).
    """

    name: str
    vertex: int
    pose: bool = False

    def __post_init__(self):
        self.vertex = int(self.vertex)
        self.pose = bool(self.pose)


@dataclass
class CurveDef:
    """A polyline on the generic mesh that hand-drawn image curves bind to (§5.1.3).

    Attributes
    ----------
    name : str
    vertices : (m,) int, generic-mesh vertex indices in order along the curve, m >= 2.
    """

    name: str
    vertices: np.ndarray

    def __post_init__(self):
        self.vertices = np.asarray(self.vertices, dtype=np.int64).reshape(-1)

    def __eq__(self, other):
        return (isinstance(other, CurveDef) and self.name == other.name
                and np.array_equal(self.vertices, other.vertices))


@dataclass
class Photo:
    """One photograph of an expression with the artist's clicks.

    Attributes
    ----------
    id : str, unique within the expression (e.g. ``"front"``).
    path : str, image file relative to the project folder (POSIX separators).
    width, height : int, image size in pixels.
    preset : str, rough initial camera, a key of :data:`photomodel.camera.PRESET_AZIMUTH_DEG`.
    focal_mm_guess : float or None, lens guess in mm on a 36 mm-wide sensor.
    camera_group : str or None, photos with the same (non-empty) group name were taken with one
        camera and lens (frames of one video, a fixed lens) and so share one focal length; None:
        a camera of its own (:meth:`Expression.camera_groups`). Format version 2.
    points : dict[str, (2,) float], clicked feature positions ``[u, v]`` in pixels.
    hidden : set[str], features the artist marked as not visible in this photo (a hidden
        feature is unobserved even if it also has a click).
    curves : dict[str, (m, 2) float], hand-drawn polylines in pixels, m >= 2.
    """

    id: str
    path: str
    width: int
    height: int
    preset: str = "front"
    focal_mm_guess: float | None = None
    points: dict[str, np.ndarray] = field(default_factory=dict)
    hidden: set[str] = field(default_factory=set)
    curves: dict[str, np.ndarray] = field(default_factory=dict)
    camera_group: str | None = None

    def __post_init__(self):
        self.path = Path(self.path).as_posix() if isinstance(self.path, Path) else str(self.path)
        self.width = int(self.width)
        self.height = int(self.height)
        self.focal_mm_guess = None if self.focal_mm_guess is None else float(self.focal_mm_guess)
        self.points = {k: np.asarray(v, dtype=float).reshape(2) for k, v in self.points.items()}
        self.hidden = set(self.hidden)
        self.curves = {k: np.asarray(v, dtype=float).reshape(-1, 2) for k, v in self.curves.items()}

    def __eq__(self, other):
        return (isinstance(other, Photo)
                and (self.id, self.path, self.width, self.height, self.preset, self.focal_mm_guess,
                     self.camera_group, self.hidden)
                == (other.id, other.path, other.width, other.height, other.preset,
                    other.focal_mm_guess, other.camera_group, other.hidden)
                and _array_dicts_equal(self.points, other.points)
                and _array_dicts_equal(self.curves, other.curves))


@dataclass
class TextureResult:
    """The texture of a fitted expression and the exports made with it (``facestudio texture``).

    Written when the texture is extracted from the photos (Pighin et al. 2002, §5.2); a new fit
    of the expression replaces the whole :class:`ExpressionResult` and so drops it (the
    texture belongs to the mesh it was made for).

    Attributes
    ----------
    size : int, the texture is ``size × size`` texels.
    image : str, the texture PNG relative to the project folder (``results/<expr>_texture.png``).
    weight_maps : dict[str, str], photo id → PNG of that photo's blending weight in texture
        space (``results/<expr>_weights_<photo>.png``; black = 0, white = 1).
    exports : dict[str, str], format → exported file relative to the project folder; formats
        are ``"obj"`` (with its ``.mtl`` next to it), ``"glb"`` and ``"ply"`` (vertex colours).
    report : dict, free-form JSON-able facts (coverage, timings...).
    """

    size: int
    image: str
    weight_maps: dict[str, str] = field(default_factory=dict)
    exports: dict[str, str] = field(default_factory=dict)
    report: dict = field(default_factory=dict)

    def __post_init__(self):
        self.size = int(self.size)
        self.weight_maps = {k: _posix(v) for k, v in self.weight_maps.items()}
        self.exports = {k: _posix(v) for k, v in self.exports.items()}
        self.image = _posix(self.image)


def _posix(p) -> str:
    return Path(p).as_posix() if isinstance(p, Path) else str(p)


def _file_stem(name: str, fallback: str) -> str:
    """``name`` with characters unsafe in file names replaced by ``_`` (never hidden or empty)."""
    return re.sub(r"[^A-Za-z0-9_.-]", "_", name).lstrip(".") or fallback


@dataclass
class ExpressionResult:
    """The fitted model of one expression (written by the fitter, :mod:`photomodel.modeling.fit`).

    Attributes
    ----------
    cameras : dict[str, Camera], recovered camera per photo id.
    points_3d : dict[str, (3,) float], recovered feature positions in mm.
    mesh_obj, mesh_ply : str or None, fitted mesh files relative to the project folder
        (by convention ``results/<expression>.obj`` / ``.ply``).
    report : dict, free-form JSON-able fit report (rms, per-view, per-point residuals...).
    texture : TextureResult or None, the extracted texture and exports (``facestudio texture``).
    """

    cameras: dict[str, Camera] = field(default_factory=dict)
    points_3d: dict[str, np.ndarray] = field(default_factory=dict)
    mesh_obj: str | None = None
    mesh_ply: str | None = None
    report: dict = field(default_factory=dict)
    texture: TextureResult | None = None

    def __post_init__(self):
        self.points_3d = {k: np.asarray(v, dtype=float).reshape(3) for k, v in self.points_3d.items()}

    def __eq__(self, other):
        if not isinstance(other, ExpressionResult):
            return False
        if ((self.mesh_obj, self.mesh_ply, self.report, self.texture)
                != (other.mesh_obj, other.mesh_ply, other.report, other.texture)):
            return False
        if self.cameras.keys() != other.cameras.keys():
            return False
        for k, a in self.cameras.items():
            b = other.cameras[k]
            if not (np.array_equal(a.R, b.R) and np.array_equal(a.t, b.t) and a.f == b.f
                    and (a.width, a.height) == (b.width, b.height)):
                return False
        return _array_dicts_equal(self.points_3d, other.points_3d)


@dataclass
class Expression:
    """One facial expression: its photographs and, once fitted, its result.

    Attributes
    ----------
    name : str
    photos : list[Photo]
    result : ExpressionResult or None
    cameras_from : str or None
        Name of another expression of the project whose photos were taken with the same
        cameras (the same rig, photo for photo by photo id, the head in the same place). The fit
        then reuses that expression's fitted cameras instead of recovering its own
        (:func:`photomodel.modeling.fit.fit_expression`), and its mesh lands in that expression's head
        frame. None (default): the cameras are recovered from this expression's own clicks.
    """

    name: str
    photos: list[Photo] = field(default_factory=list)
    result: ExpressionResult | None = None
    cameras_from: str | None = None

    def photo(self, photo_id: str) -> Photo:
        """The photo with id ``photo_id``; :class:`ProjectError` listing the ids if absent."""
        for p in self.photos:
            if p.id == photo_id:
                return p
        raise ProjectError(f"expression {self.name!r} has no photo {photo_id!r}; "
                           f"its photos are: {_listing(p.id for p in self.photos)}")

    def camera_groups(self) -> list[int]:
        """The camera of each photo, in photo order, as the index array a solver shares
        intrinsics by: photos with the same ``camera_group`` get the same index, a photo without
        a group an index of its own; indices are 0, 1, … in order of first appearance.

        E.g. groups ``["a", None, "a", "b", None]`` → ``[0, 1, 0, 2, 3]``.
        """
        index: dict[str, int] = {}
        out = []
        n = 0
        for p in self.photos:
            if p.camera_group is None:
                out.append(n)
                n += 1
            else:
                if p.camera_group not in index:
                    index[p.camera_group] = n
                    n += 1
                out.append(index[p.camera_group])
        return out


@dataclass
class Project:
    """A Face Studio project (see ``docs/project-format.md``).

    Attributes
    ----------
    name : str
    generic_mesh : str, ``"builtin:template-v1"`` or a mesh path relative to the project folder.
    features : list[Feature]
    curves : list[CurveDef]
    expressions : list[Expression]
    path : Path or None, the project file (absolute) once loaded or saved.
    """

    name: str
    generic_mesh: str = BUILTIN_MESH
    features: list[Feature] = field(default_factory=list)
    curves: list[CurveDef] = field(default_factory=list)
    expressions: list[Expression] = field(default_factory=list)
    path: Path | None = field(default=None, compare=False)

    # -- look-ups --------------------------------------------------------------------
    @property
    def folder(self) -> Path:
        """The folder relative paths are resolved against (the cwd for an unsaved project)."""
        return self.path.parent if self.path is not None else Path.cwd()

    def resolve(self, relative: str | os.PathLike) -> Path:
        """Absolute path of a path stored in the project (relative to :attr:`folder`)."""
        return (self.folder / Path(relative)).absolute()

    def expression(self, name: str) -> Expression:
        """The expression called ``name``; :class:`ProjectError` listing the names if absent."""
        for e in self.expressions:
            if e.name == name:
                return e
        raise ProjectError(f"project {self.name!r} has no expression {name!r}; "
                           f"available: {_listing(e.name for e in self.expressions)}")

    def feature(self, name: str) -> Feature:
        for f in self.features:
            if f.name == name:
                return f
        raise ProjectError(f"project {self.name!r} has no feature {name!r}"
                           f"{_did_you_mean(name, self.feature_names())}")

    def feature_names(self, pose_only: bool = False) -> list[str]:
        """Feature names in definition order; only the pose-recovery ones if ``pose_only``."""
        return [f.name for f in self.features if f.pose or not pose_only]

    def feature_vertices(self, feature_names: Sequence[str] | None = None) -> np.ndarray:
        """(n,) int generic-mesh vertex of each named feature (all features by default)."""
        names = self.feature_names() if feature_names is None else list(feature_names)
        by_name = {f.name: f.vertex for f in self.features}
        self._require_features(names, by_name)
        return np.array([by_name[n] for n in names], dtype=np.int64)

    def camera_groups(self, expression_name: str) -> list[int]:
        """:meth:`Expression.camera_groups` of the expression called ``expression_name``: one
        camera index per photo, in the order of its photos (that of :meth:`observations`)."""
        return self.expression(expression_name).camera_groups()

    def photo_path(self, photo: Photo) -> Path:
        """Absolute path of ``photo``'s image file."""
        return self.resolve(photo.path)

    def observations(self, expression_name: str,
                     feature_names: Sequence[str] | None = None) -> np.ndarray:
        """Clicked feature positions of one expression as an observation array.

        Parameters
        ----------
        expression_name : str
        feature_names : sequence of n str, default all features in definition order.

        Returns
        -------
        (k, n, 2) float
            Pixel coordinates ``[u, v]`` of feature ``j`` in photo ``i`` (photos in the
            expression's order), ``NaN`` where the feature is not clicked or is hidden.
        """
        expr = self.expression(expression_name)
        names = self.feature_names() if feature_names is None else list(feature_names)
        self._require_features(names, {f.name for f in self.features})
        col = {n: j for j, n in enumerate(names)}
        obs = np.full((len(expr.photos), len(names), 2), np.nan)
        for i, photo in enumerate(expr.photos):
            for n, uv in photo.points.items():
                if n in col and n not in photo.hidden:
                    obs[i, col[n]] = uv
        return obs

    def default_result_paths(self, expression_name: str) -> tuple[str, str]:
        """``("results/<expr>.obj", "results/<expr>.ply")``, relative to the project folder;
        characters unsafe in file names are replaced by ``_``."""
        stem = _file_stem(expression_name, "expression")
        return f"results/{stem}.obj", f"results/{stem}.ply"

    def default_texture_paths(self, expression_name: str) -> dict:
        """Where ``facestudio texture`` writes, relative to the project folder.

        Returns ``{"image": "results/<expr>_texture.png", "weight_maps": {photo id:
        "results/<expr>_weights_<photo>.png"}, "obj": "results/<expr>_textured.obj", "mtl":
        "results/<expr>_textured.mtl", "glb": "results/<expr>.glb", "ply":
        "results/<expr>_colors.ply"}``; unsafe characters become ``_`` as in
        :meth:`default_result_paths` (photo ids that would then collide get their position in
        the expression appended).
        """
        stem = _file_stem(expression_name, "expression")
        weights: dict[str, str] = {}
        for i, photo in enumerate(self.expression(expression_name).photos):
            path = f"results/{stem}_weights_{_file_stem(photo.id, 'photo')}.png"
            if path in weights.values():
                path = path[: -len(".png")] + f"_{i}.png"
            weights[photo.id] = path
        return {
            "image": f"results/{stem}_texture.png",
            "weight_maps": weights,
            "obj": f"results/{stem}_textured.obj",
            "mtl": f"results/{stem}_textured.mtl",
            "glb": f"results/{stem}.glb",
            "ply": f"results/{stem}_colors.ply",
        }

    # -- checks that need more than the file ---------------------------------------------
    def check_vertices(self, n_vertices: int) -> None:
        """Raise :class:`ProjectError` if a feature or curve names a vertex ``>= n_vertices``.

        The file cannot know the generic mesh's size; the fitter calls this once the mesh is
        loaded.
        """
        problems = []
        for i, f in enumerate(self.features):
            if not 0 <= f.vertex < n_vertices:
                problems.append((f"features[{i}].vertex",
                                 f"feature {f.name!r}: vertex {f.vertex} is out of range for a "
                                 f"generic mesh with {n_vertices} vertices"))
        for i, c in enumerate(self.curves):
            bad = np.flatnonzero((c.vertices < 0) | (c.vertices >= n_vertices))
            if bad.size:
                problems.append((f"curves[{i}].vertices[{bad[0]}]",
                                 f"curve {c.name!r}: vertex {c.vertices[bad[0]]} is out of range for "
                                 f"a generic mesh with {n_vertices} vertices"))
        if problems:
            raise _problems_error(self._source(), problems)

    def check_photos(self, read: bool = False) -> None:
        """Raise :class:`ProjectError` naming every photo that is missing or unreadable.

        Parameters
        ----------
        read : bool
            If False (default, cheap) a photo must exist and OpenCV must recognise its format
            from the file header (``cv2.haveImageReader``). If True each image is decoded and
            its size compared with the ``width``/``height`` stored in the project.
        """
        import cv2  # local: loading/saving projects does not need OpenCV

        problems = []
        for ei, expr in enumerate(self.expressions):
            for pi, photo in enumerate(expr.photos):
                where = f"expressions[{ei}].photos[{pi}]"
                who = f"expression {expr.name!r}, photo {photo.id!r}"
                p = self.photo_path(photo)
                if not p.is_file():
                    problems.append((where, f"{who}: {photo.path} does not exist (looked for {p})"))
                elif not cv2.haveImageReader(str(p)):
                    problems.append((where, f"{who}: {photo.path} is not an image OpenCV can read"))
                elif read:
                    img = cv2.imread(str(p), cv2.IMREAD_UNCHANGED)
                    if img is None:
                        problems.append((where, f"{who}: {photo.path} could not be decoded"))
                    elif img.shape[:2] != (photo.height, photo.width):
                        problems.append((where, f"{who}: {photo.path} is {img.shape[1]}x{img.shape[0]} "
                                                f"but the project says {photo.width}x{photo.height}"))
        if problems:
            raise _problems_error(self._source(), problems)

    # -- (de)serialisation -----------------------------------------------------------
    def to_dict(self) -> dict:
        """The project as the JSON-able dict written to disk (rounded, canonical order)."""
        return self._to_dict_for(self.path)

    def _to_dict_for(self, target: Path | None) -> dict:
        """:meth:`to_dict` for writing to ``target``: when that is in another folder than
        :attr:`path` (save as), relative paths are re-expressed so they still find their files."""
        origin = self.path.parent if self.path is not None else None
        folder = target.parent if target is not None else origin

        def stored(p: str) -> str:
            return _stored_path(p, origin, folder)

        feature_order = {f.name: i for i, f in enumerate(self.features)}
        curve_order = {c.name: i for i, c in enumerate(self.curves)}

        def ordered(d: dict, order: dict) -> list:
            # defined names in definition order, then any undefined ones (validation rejects them)
            return sorted(d, key=lambda k: (order.get(k, len(order)), k))

        d: dict[str, Any] = {
            "format": FORMAT_NAME,
            "version": FORMAT_VERSION,
            "name": self.name,
            "generic_mesh": (self.generic_mesh if self.generic_mesh.startswith("builtin:")
                             else stored(self.generic_mesh)),
            "features": [{"name": f.name, "vertex": int(f.vertex), "pose": bool(f.pose)}
                         for f in self.features],
            "curves": [{"name": c.name, "vertices": [int(v) for v in c.vertices]} for c in self.curves],
            "expressions": [],
        }
        for expr in self.expressions:
            photos = []
            for p in expr.photos:
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
                pd |= {
                    "points": {k: _round_list(p.points[k], _PIXEL_DECIMALS)
                               for k in ordered(p.points, feature_order)},
                    "hidden": sorted(p.hidden, key=lambda k: (feature_order.get(k, len(feature_order)), k)),
                    "curves": {k: _round_list(p.curves[k], _PIXEL_DECIMALS)
                               for k in ordered(p.curves, curve_order)},
                }
                photos.append(pd)
            ed: dict[str, Any] = {"name": expr.name}
            if expr.cameras_from is not None:  # optional: files without it omit the key
                ed["cameras_from"] = expr.cameras_from
            ed["photos"], ed["result"] = photos, None
            if expr.result is not None:
                r = expr.result
                photo_order = {p.id: i for i, p in enumerate(expr.photos)}
                ed["result"] = {
                    "cameras": {k: _camera_dict(r.cameras[k]) for k in ordered(r.cameras, photo_order)},
                    "points_3d": {k: _round_list(r.points_3d[k], _MM_DECIMALS)
                                  for k in ordered(r.points_3d, feature_order)},
                    "mesh_obj": None if r.mesh_obj is None else stored(r.mesh_obj),
                    "mesh_ply": None if r.mesh_ply is None else stored(r.mesh_ply),
                    "report": _jsonable(r.report),
                }
                if r.texture is not None:  # optional: files without a texture omit the key
                    tx = r.texture
                    ed["result"]["texture"] = {
                        "size": int(tx.size),
                        "image": stored(tx.image),
                        "weight_maps": {k: stored(tx.weight_maps[k])
                                        for k in ordered(tx.weight_maps, photo_order)},
                        "exports": {k: stored(tx.exports[k]) for k in sorted(tx.exports)},
                        "report": _jsonable(tx.report),
                    }
            d["expressions"].append(ed)
        return d

    @classmethod
    def from_dict(cls, d: Any, path: str | os.PathLike | None = None) -> Project:
        """Validate a parsed project dict and build the :class:`Project`.

        ``path`` (the file it came from) is used for error messages and for resolving
        relative paths. Raises :class:`ProjectError` naming the field at fault.
        """
        source = Path(path).name if path is not None else "project"
        _validate(d, source)
        project = cls(
            name=d["name"],
            generic_mesh=d["generic_mesh"],
            features=[Feature(f["name"], f["vertex"], f["pose"]) for f in d["features"]],
            curves=[CurveDef(c["name"], c["vertices"]) for c in d.get("curves", [])],
            expressions=[_expression_from_dict(e) for e in d["expressions"]],
            path=None if path is None else Path(path).absolute(),
        )
        return project

    # -- internals ------------------------------------------------------------------
    def _source(self) -> str:
        return self.path.name if self.path is not None else f"project {self.name!r}"

    def _require_features(self, names: Iterable[str], defined) -> None:
        missing = [n for n in names if n not in defined]
        if missing:
            raise ProjectError(f"project {self.name!r} has no feature(s) {_listing(missing)}"
                               f"{_did_you_mean(missing[0], self.feature_names())}")


# ---------------------------------------------------------------------------------------
# file I/O
# ---------------------------------------------------------------------------------------
def new_project(name: str, *, generic_mesh: str = BUILTIN_MESH,
                features: Sequence[Feature] = (), curves: Sequence[CurveDef] = ()) -> Project:
    """An empty project (no expressions) called ``name``; not yet saved."""
    if not isinstance(name, str) or not name.strip():
        raise ProjectError(f"a project needs a non-empty name, got {name!r}")
    return Project(name=name, generic_mesh=generic_mesh, features=list(features), curves=list(curves))


def default_filename(name: str) -> str:
    """``<name>.facestudio.json`` with characters unsafe in file names replaced by ``_``."""
    return re.sub(r"[^\w.-]", "_", name).lstrip(".") + FILE_SUFFIX


def load_project(path: str | os.PathLike) -> Project:
    """Read and validate a project file; raises :class:`ProjectError` naming the problem."""
    path = Path(path)
    try:
        raw = path.read_bytes()
    except FileNotFoundError:
        raise ProjectError(f"{path}: no such project file") from None
    except OSError as exc:
        raise ProjectError(f"{path}: cannot read the project file: {exc.strerror or exc}") from exc
    try:
        text = raw.decode("utf-8-sig")
    except UnicodeDecodeError as exc:
        raise ProjectError(f"{path.name}: not a text (UTF-8) file: {exc.reason} at byte {exc.start}"
                           ) from None
    data = _parse_json(text, path.name)
    return Project.from_dict(data, path)


def save_project(project: Project, path: str | os.PathLike | None = None) -> Path:
    """Write ``project`` atomically and return the absolute path written.

    ``path`` defaults to ``project.path``; an existing directory means
    ``<dir>/<name>.facestudio.json``. The project is validated first, so a file that could not
    be loaded back is never written. The text goes to a temporary file in the target folder,
    is flushed and fsynced, and replaces the target with :func:`os.replace`; a previous
    version of the target is kept as ``<file>.bak``. On failure the target is untouched and
    the temporary file removed. ``project.path`` is set to the written file on success.
    """
    if path is None:
        if project.path is None:
            raise ProjectError(f"project {project.name!r} has not been saved yet: give a file name "
                               f"(e.g. {default_filename(project.name)})")
        path = project.path
    path = Path(path).absolute()
    if path.is_dir():
        path = path / default_filename(project.name)

    # serialise and validate before touching the disk (paths relative to the *target* folder)
    d = project._to_dict_for(path)
    try:
        json.dumps(d, allow_nan=False)  # fast C check for NaN/inf clicks or results ...
    except ValueError:
        problems: list[tuple[str, str]] = []
        _scan_parsed(d, (), problems)  # ... then find where they are
        raise _problems_error(path.name, problems) from None
    _validate(d, path.name)
    text = _dumps(d) + "\n"

    tmp_name = None
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        fd, tmp_name = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=".tmp")
        with os.fdopen(fd, "w", encoding="utf-8", newline="\n") as fh:
            fh.write(text)
            fh.flush()
            os.fsync(fh.fileno())
        if path.exists():
            shutil.copymode(path, tmp_name)
            _backup(path)
        else:
            os.chmod(tmp_name, 0o644)  # mkstemp makes 0600; a project is an ordinary document
        os.replace(tmp_name, path)
        tmp_name = None
        _fsync_dir(path.parent)
    except OSError as exc:
        raise ProjectError(f"{path}: could not save the project: {exc.strerror or exc}") from exc
    finally:
        if tmp_name is not None:
            try:
                os.unlink(tmp_name)
            except OSError:
                pass
    project.path = path
    return path


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


def _backup(path: Path) -> None:
    """Copy ``path`` to ``path.bak`` atomically (via a temporary copy and os.replace)."""
    bak = path.with_name(path.name + ".bak")
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{bak.name}.", suffix=".tmp")
    os.close(fd)
    try:
        shutil.copy2(path, tmp)
        os.replace(tmp, bak)
    except BaseException:
        try:
            os.unlink(tmp)
        except OSError:
            pass
        raise


def _fsync_dir(folder: Path) -> None:
    """Persist the rename itself (POSIX); not possible / not needed on Windows."""
    if os.name != "posix":
        return
    fd = os.open(folder, os.O_RDONLY)
    try:
        os.fsync(fd)
    except OSError:
        pass  # some filesystems refuse fsync on directories; the data file itself is synced
    finally:
        os.close(fd)


@lru_cache(maxsize=1)
def project_schema() -> dict:
    """The JSON Schema (draft 2020-12) of the format (versions 1 and 2), shipped as package data."""
    text = resources.files("photomodel.project").joinpath("schema.json").read_text(encoding="utf-8")
    return json.loads(text)


#: Where the bulk of a project lives — maps of many small coordinate arrays — and the
#: shipped-schema definition each map's values follow.
_LEAF_MAPS = {("photo", "points"): "pixel", ("photo", "curves"): "polyline",
              ("result", "points_3d"): "vec3"}


@lru_cache(maxsize=1)
def _validator():
    """The draft 2020-12 validator of :func:`project_schema`, with one speed-up.

    Checking every ``[u, v]`` through jsonschema's generic machinery costs ~40 µs each (a
    project with 25 000 clicks and curve points took 1 s), and saving validates too. So the
    maps of coordinate arrays (:data:`_LEAF_MAPS`) are checked by an ``x-leaves`` keyword in
    plain Python instead; the shipped schema keeps the full standard definition, and
    ``tests/test_project.py`` checks that both agree.
    """
    import copy

    import jsonschema  # local: importing jsonschema costs ~0.1 s; only load/save need it

    schema = copy.deepcopy(project_schema())
    for (owner, prop), kind in _LEAF_MAPS.items():
        node = schema["$defs"][owner]["properties"][prop]
        del node["additionalProperties"]
        node["x-leaves"] = kind
    cls = jsonschema.validators.extend(jsonschema.Draft202012Validator, {"x-leaves": _leaves_keyword})
    return cls(schema)


def _leaves_keyword(validator, kind, instance, schema):
    """jsonschema keyword: every value of the object ``instance`` is a ``kind`` leaf."""
    from jsonschema.exceptions import ValidationError

    if not isinstance(instance, dict):
        return  # the "type" keyword reports it
    for key, value in instance.items():
        if kind == "polyline":
            if not isinstance(value, list) or len(value) < 2:
                msg = f"expected a polyline of at least two [u, v] points, got {_short(value)}"
                yield ValidationError(msg, path=[key])
                continue
            for i, uv in enumerate(value):
                if not _is_numbers(uv, 2):
                    yield ValidationError(f"expected [u, v] of two finite numbers, got {_short(uv)}",
                                          path=[key, i])
                    break
        elif kind == "pixel" and not _is_numbers(value, 2):
            yield ValidationError(f"expected [u, v] of two finite numbers, got {_short(value)}", path=[key])
        elif kind == "vec3" and not _is_numbers(value, 3):
            yield ValidationError(f"expected [x, y, z] of three finite numbers (mm), got {_short(value)}",
                                  path=[key])


def _is_numbers(v, n: int) -> bool:
    # exact types: a JSON true/false parses to bool, which is an int subclass but not a number here
    return type(v) is list and len(v) == n and all(type(x) is float or type(x) is int for x in v)


# ---------------------------------------------------------------------------------------
# parsing and validation
# ---------------------------------------------------------------------------------------
class _NonFinite:
    """Placeholder for a NaN/Infinity literal (or an overflowing number) found while parsing."""

    def __init__(self, literal: str):
        self.literal = literal


class _KeyedDict(dict):
    """A JSON object that remembers keys it saw more than once."""

    duplicates: tuple = ()


def _object_pairs(pairs):
    d = _KeyedDict()
    dups = []
    for k, v in pairs:
        if k in d and k not in dups:
            dups.append(k)
        d[k] = v
    d.duplicates = tuple(dups)
    return d


def _parse_json(text: str, source: str):
    suspect = False  # set by the hooks, so that a clean file skips the tree scan

    def constant(literal: str):
        nonlocal suspect
        suspect = True
        return _NonFinite(literal)

    def number(literal: str):
        x = float(literal)
        return x if math.isfinite(x) else constant(literal)

    def pairs(items):
        nonlocal suspect
        d = _object_pairs(items)
        suspect = suspect or bool(d.duplicates)
        return d

    try:
        data = json.loads(text, parse_constant=constant, parse_float=number, object_pairs_hook=pairs)
    except json.JSONDecodeError as exc:
        raise ProjectError(f"{source}: not valid JSON: {exc.msg} (line {exc.lineno}, column {exc.colno})"
                           ) from None
    if suspect:
        problems: list[tuple[str, str]] = []
        _scan_parsed(data, (), problems)
        if problems:
            raise _problems_error(source, problems)
    return data


def _scan_parsed(node, path: tuple, problems: list) -> None:
    """Find NaN/Infinity literals (or non-finite floats) and repeated keys; (path, message) each."""
    if isinstance(node, float) and not math.isfinite(node):
        node = _NonFinite(repr(node))
    if isinstance(node, _NonFinite):
        problems.append((_fmt_path(path), f"{node.literal} is not a finite number (JSON has no NaN or "
                                          f"Infinity); remove the value or use null where allowed"))
    elif isinstance(node, dict):
        for k in getattr(node, "duplicates", ()):
            problems.append((_fmt_path(path), f"key {k!r} appears more than once"))
        for k, v in node.items():
            _scan_parsed(v, (*path, k), problems)
    elif isinstance(node, list):
        for i, v in enumerate(node):
            _scan_parsed(v, (*path, i), problems)


def _validate(d: Any, source: str) -> None:
    """All load-time checks of a parsed project dict (steps 2-4 of the module docstring)."""
    if not isinstance(d, dict) or d.get("format") != FORMAT_NAME:
        got = d.get("format") if isinstance(d, dict) else type(d).__name__
        raise ProjectError(f"{source}: not a Face Studio project file "
                           f"(expected \"format\": \"{FORMAT_NAME}\", got {_short(got)})")
    version = d.get("version")
    if isinstance(version, bool) or not isinstance(version, int):
        raise ProjectError(f"{source}: version: expected an integer format version, got {_short(version)}")
    if version > FORMAT_VERSION:
        raise ProjectError(f"{source}: written by a newer Face Studio (project format version {version}; "
                           f"this version reads up to {FORMAT_VERSION}); please update Face Studio")
    if version < 1:
        raise ProjectError(f"{source}: version: unknown project format version {version}")
    # Older versions need no upgrade: version 2 only added the optional photo camera_group, and a
    # version-1 file's photos have none. (A future change that renames or restructures a field
    # converts the older dict here, before the schema check.)

    _check_schema(d, source)
    problems = _cross_reference_problems(d)
    if problems:
        raise _problems_error(source, problems)


def _check_schema(d: dict, source: str) -> None:
    from jsonschema.exceptions import best_match

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

    Walks the failing keyword's schema path from the root, following ``$ref``, tracking how
    deep into the instance each step goes; the deepest subschema with an ``x-expected`` note
    names what the value at that depth should have been. Errors about an object's keys
    (``required``, ``additionalProperties``) keep jsonschema's own, already precise, wording.
    """
    ipath = list(err.absolute_path)
    if err.validator in ("required", "additionalProperties", "dependentRequired", "x-leaves"):
        return _fmt_path(ipath), err.message

    root = project_schema()
    node, depth, expected = root, 0, None
    spath = list(err.absolute_schema_path)
    i = 0
    while True:
        while isinstance(node, dict) and "$ref" in node and (i >= len(spath) or spath[i] not in node):
            node = _resolve_ref(root, node["$ref"])
        if isinstance(node, dict) and "x-expected" in node:
            expected = (node["x-expected"], depth)
        if i >= len(spath) or not isinstance(node, dict):
            break
        key = spath[i]
        if key in _ONE_STEP and i + 1 < len(spath):
            node, depth, i = node[key][spath[i + 1]], depth + 1, i + 2
        elif key in _BRANCH and i + 1 < len(spath):
            node, i = node[key][spath[i + 1]], i + 2
        elif key in _DESCEND and isinstance(node.get(key), dict):
            node, depth, i = node[key], depth + 1, i + 1
        else:
            break  # the failing keyword itself
    if expected is None:
        return _fmt_path(ipath), err.message
    text, depth = expected
    value = instance
    for k in ipath[:depth]:
        value = value[k]
    return _fmt_path(ipath[:depth]), f"expected {text}, got {_short(value)}"


def _resolve_ref(root: dict, ref: str) -> dict:
    if not ref.startswith("#/"):
        raise ValueError(f"project schema: only local $refs are supported, got {ref!r}")
    node = root
    for part in ref[2:].split("/"):
        node = node[part.replace("~1", "/").replace("~0", "~")]
    return node


def _cross_reference_problems(d: dict) -> list[tuple[str, str]]:
    """Checks of a schema-valid dict that JSON Schema cannot express; (path, message) each."""
    problems: list[tuple[str, str]] = []
    features = [f["name"] for f in d["features"]]
    curves = [c["name"] for c in d.get("curves", [])]
    problems += _duplicates(features, "features", "feature name")
    problems += _duplicates(curves, "curves", "curve name")
    problems += _duplicates([e["name"] for e in d["expressions"]], "expressions", "expression name")
    problems += _cameras_from_problems(d["expressions"])
    fset, cset = set(features), set(curves)
    presets = sorted(PRESET_AZIMUTH_DEG)

    for ei, e in enumerate(d["expressions"]):
        ep = f"expressions[{ei}]"
        problems += _duplicates([p["id"] for p in e["photos"]], f"{ep}.photos", "photo id",
                                field_name="id")
        sizes = {}
        for pi, p in enumerate(e["photos"]):
            pp = f"{ep}.photos[{pi}]"
            w, h = p["width"], p["height"]
            sizes.setdefault(p["id"], (w, h))
            if p["preset"] not in PRESET_AZIMUTH_DEG:
                problems.append((f"{pp}.preset", f"unknown camera preset {p['preset']!r}; choose one of "
                                                 f"{', '.join(presets)}"))
            points = p.get("points", {})
            for name in points:
                if name not in fset:
                    problems.append((f"{pp}.points{_fmt_key(name)}", f"no feature named {name!r} is defined"
                                                                     f"{_did_you_mean(name, features)}"))
            if points:
                names, uvs = list(points), list(points.values())
                for j in np.flatnonzero(_far_outside(np.array(uvs, float), w, h)):
                    problems.append((f"{pp}.points{_fmt_key(names[j])}", _outside_message(uvs[j], w, h)))
            for hi, name in enumerate(p.get("hidden", [])):
                if name not in fset:
                    problems.append((f"{pp}.hidden[{hi}]", f"no feature named {name!r} is defined"
                                                           f"{_did_you_mean(name, features)}"))
            for name, line in p.get("curves", {}).items():
                at = f"{pp}.curves{_fmt_key(name)}"
                if name not in cset:
                    problems.append((at, f"no curve named {name!r} is defined{_did_you_mean(name, curves)}"))
                pts = np.asarray(line, float)
                bad = np.flatnonzero(_far_outside(pts, w, h))
                if bad.size:
                    problems.append((f"{at}[{bad[0]}]", _outside_message(line[bad[0]], w, h)))

        r = e.get("result")
        if r is None:
            continue
        rp = f"{ep}.result"
        for pid, cam in r["cameras"].items():
            at = f"{rp}.cameras{_fmt_key(pid)}"
            if pid not in sizes:
                problems.append((at, f"camera for photo {pid!r}, which is not a photo of this expression"
                                     f"{_did_you_mean(pid, list(sizes))}"))
            elif (cam["width"], cam["height"]) != sizes[pid]:
                problems.append((at, f"camera image size {cam['width']}x{cam['height']} differs from photo "
                                     f"{pid!r} ({sizes[pid][0]}x{sizes[pid][1]})"))
            R = np.asarray(cam["rotation"], float)
            err = float(np.abs(R.T @ R - np.eye(3)).max())
            if err > ROTATION_TOL or np.linalg.det(R) < 0:
                problems.append((f"{at}.rotation", f"not a rotation matrix (max |RᵀR − I| = {err:.2g}, "
                                                   f"det = {np.linalg.det(R):.6g})"))
        for name in r["points_3d"]:
            if name not in fset:
                problems.append((f"{rp}.points_3d{_fmt_key(name)}", f"no feature named {name!r} is defined"
                                                                    f"{_did_you_mean(name, features)}"))
        for pid in (r.get("texture") or {}).get("weight_maps", {}):
            if pid not in sizes:
                problems.append((f"{rp}.texture.weight_maps{_fmt_key(pid)}",
                                 f"weight map for photo {pid!r}, which is not a photo of this expression"
                                 f"{_did_you_mean(pid, list(sizes))}"))
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
            problems.append((at, f"no expression named {src!r} to take the cameras from"
                                 f"{_did_you_mean(src, [n for n in names if n != e['name']])}; "
                                 f"expressions: {_listing(names)}"))
        else:
            chain, seen = [e["name"]], {e["name"]}
            while src is not None and src in source and src not in seen:
                chain.append(src)
                seen.add(src)
                src = source[src]
            if src == e["name"]:
                problems.append((at, "cameras_from goes round in a cycle ("
                                     + " → ".join(chain + [src]) + "); one expression must recover its own "
                                     "cameras"))
    return problems


def _duplicates(names: list[str], list_path: str, what: str, field_name: str = "name"):
    seen: dict[str, int] = {}
    out = []
    for i, n in enumerate(names):
        if n in seen:
            out.append((f"{list_path}[{i}].{field_name}",
                        f"{what} {n!r} is used twice (also at {list_path}[{seen[n]}])"))
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
    return (f"[{uv[0]:g}, {uv[1]:g}] lies far outside the {width}x{height} photo (more than "
            f"{OUT_OF_BOUNDS_MARGIN:.0%} of its size beyond the border); check the photo's width/height "
            f"and that points are [u, v] in pixels")


def _expression_from_dict(e: dict) -> Expression:
    photos = [
        Photo(
            id=p["id"], path=p["path"], width=p["width"], height=p["height"], preset=p["preset"],
            focal_mm_guess=p.get("focal_mm_guess"),
            points=p.get("points", {}), hidden=p.get("hidden", []), curves=p.get("curves", {}),
            camera_group=p.get("camera_group"),
        )
        for p in e["photos"]
    ]
    result = None
    r = e.get("result")
    if r is not None:
        result = ExpressionResult(
            cameras={k: Camera.from_dict(c) for k, c in r["cameras"].items()},
            points_3d=r["points_3d"],
            mesh_obj=r.get("mesh_obj"),
            mesh_ply=r.get("mesh_ply"),
            report=_plain(r.get("report", {})),
        )
        t = r.get("texture")
        if t is not None:
            result.texture = TextureResult(size=t["size"], image=t["image"], weight_maps=t["weight_maps"],
                                           exports=t.get("exports", {}), report=_plain(t.get("report", {})))
    return Expression(name=e["name"], photos=photos, result=result, cameras_from=e.get("cameras_from"))


# ---------------------------------------------------------------------------------------
# formatting helpers
# ---------------------------------------------------------------------------------------
_IDENT = re.compile(r"^[A-Za-z_][A-Za-z0-9_-]*$")


def _fmt_key(k) -> str:
    if isinstance(k, int):
        return f"[{k}]"
    return f".{k}" if _IDENT.match(k) else f"[{json.dumps(k, ensure_ascii=False)}]"


def _fmt_path(path) -> str:
    """``("expressions", 0, "photos")`` → ``expressions[0].photos`` ("(top level)" if empty)."""
    s = "".join(_fmt_key(k) for k in path).lstrip(".")
    return s or "(top level)"


def _short(value, limit: int = 80) -> str:
    try:
        s = json.dumps(_plain(value), ensure_ascii=False)
    except (TypeError, ValueError):
        s = repr(value)
    return s if len(s) <= limit else s[: limit - 3] + "..."


def _listing(names: Iterable[str]) -> str:
    names = list(names)
    return ", ".join(repr(n) for n in names) if names else "(none)"


def _did_you_mean(name: str, candidates: Sequence[str]) -> str:
    close = difflib.get_close_matches(name, list(candidates), n=1, cutoff=0.6)
    return f" (did you mean {close[0]!r}?)" if close else ""


def _problems_error(source: str, problems: list[tuple[str, str]]) -> ProjectError:
    """One ProjectError for a list of (path, message); ``.problems`` keeps the list."""
    if len(problems) == 1:
        msg = f"{source}: {problems[0][0]}: {problems[0][1]}"
    else:
        lines = [f"  {p}: {m}" for p, m in problems[:_MAX_LISTED_PROBLEMS]]
        if len(problems) > _MAX_LISTED_PROBLEMS:
            lines.append(f"  ... and {len(problems) - _MAX_LISTED_PROBLEMS} more")
        msg = f"{source}: {len(problems)} problems:\n" + "\n".join(lines)
    exc = ProjectError(msg)
    exc.problems = list(problems)
    return exc


def _array_dicts_equal(a: dict, b: dict) -> bool:
    return a.keys() == b.keys() and all(np.array_equal(a[k], b[k]) for k in a)


def _round_list(a: np.ndarray, decimals: int) -> list:
    return np.round(np.asarray(a, dtype=float), decimals).tolist()


def _camera_dict(cam: Camera) -> dict:
    d = cam.to_dict()
    # rotation at full precision (it must stay orthonormal); translation at the mm precision
    d["rotation"] = np.asarray(cam.R, float).tolist()
    d["translation_mm"] = _round_list(cam.t, _MM_DECIMALS)
    d["focal_px"] = round(float(cam.f), _PIXEL_DECIMALS + 3)
    return d


def _plain(node):
    """Parsed JSON with our parse-time helper types replaced by plain dicts."""
    if isinstance(node, dict):
        return {k: _plain(v) for k, v in node.items()}
    if isinstance(node, list):
        return [_plain(v) for v in node]
    return node


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


_INLINE_DICT_WIDTH = 100


def _dumps(node, level: int = 0) -> str:
    """Readable, deterministic JSON: 2-space indent, lists of numbers and small flat objects on
    one line (a click is ``"nose_tip": [512.3, 601.8]``, a rotation is three rows)."""
    pad, pad1 = "  " * level, "  " * (level + 1)
    if isinstance(node, dict):
        if not node:
            return "{}"
        if all(not isinstance(v, (dict, list)) for v in node.values()):
            inline = "{" + ", ".join(f"{json.dumps(k, ensure_ascii=False)}: {_scalar(v)}"
                                     for k, v in node.items()) + "}"
            if len(inline) + len(pad1) <= _INLINE_DICT_WIDTH:
                return inline
        items = [f"{pad1}{json.dumps(k, ensure_ascii=False)}: {_dumps(v, level + 1)}"
                 for k, v in node.items()]
        return "{\n" + ",\n".join(items) + "\n" + pad + "}"
    if isinstance(node, list):
        if not node:
            return "[]"
        if all(not isinstance(v, (dict, list)) for v in node):
            return "[" + ", ".join(_scalar(v) for v in node) + "]"
        return "[\n" + ",\n".join(pad1 + _dumps(v, level + 1) for v in node) + "\n" + pad + "]"
    return _scalar(node)


def _scalar(v) -> str:
    # same text as json.dumps (floats use repr, the shortest round-tripping form), but ~5x faster
    if type(v) is float:
        if not math.isfinite(v):
            raise ValueError(f"non-finite number {v!r} cannot be written to JSON")
        return repr(v)
    if v is True:
        return "true"
    if v is False:
        return "false"
    if v is None:
        return "null"
    if type(v) is int:
        return str(v)
    return json.dumps(v, ensure_ascii=False, allow_nan=False)
