"""The project's data model: features, curves, photos with their clicks, expressions and their results.

A project (one ``<name>.facestudio.json`` file, documented field by field in
``docs/project-format.md``) names the generic mesh, the features (generic-mesh vertices the artist
clicks, §5.1 of Pighin et al. 2002) and curves (mesh polylines that hand-drawn image curves bind
to, §5.1.3), and, per expression, the photographs with their clicks and the fitted result. Every
path stored in it is relative to the folder that holds the file. Conventions are those of
:mod:`photomodel.camera`: pixels ``u`` right, ``v`` down, pixel centres at integers; millimetres
in the world.

The format's name, version and file suffix are :mod:`photomodel.project.format`'s. This module
knows nothing of the file: the dict form written to disk is :mod:`photomodel.project.codec`'s
(``project_to_dict`` / ``project_from_dict``), its checks :mod:`photomodel.project.validate`'s,
reading and writing the file :mod:`photomodel.project.io`'s.
"""

from __future__ import annotations

import os
import re
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass, field
from pathlib import Path

import cv2
import numpy as np

from photomodel.camera import Camera
from photomodel.errors import PhotoError, ProjectError
from photomodel.project.format import BUILTIN_MESH, CLICK_SOURCES
from photomodel.project.problems import did_you_mean, listing, problems_error


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
        return isinstance(other, CurveDef) and self.name == other.name and np.array_equal(self.vertices, other.vertices)


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
    sources : dict[str, str], feature → where its click came from, ``"auto"`` (the landmark
        detector); a click without an entry was made by the artist (``"user"``). Format
        version 3. Use :meth:`set_click` / :meth:`remove_click` to keep it in step with
        :attr:`points`.
    confidence : dict[str, float], feature → the detector's confidence in ``[0, 1]`` of an
        automatic click (absent for the artist's clicks). Format version 3.
    curve_sources : dict[str, str], curve → ``"auto"`` for a curve drawn by the landmark
        detector; a curve without an entry was drawn by the artist. Format version 5. Use
        :meth:`set_curve` to keep it in step with :attr:`curves`.
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
    sources: dict[str, str] = field(default_factory=dict)
    confidence: dict[str, float] = field(default_factory=dict)
    curve_sources: dict[str, str] = field(default_factory=dict)

    def __post_init__(self):
        self.path = Path(self.path).as_posix() if isinstance(self.path, Path) else str(self.path)
        self.width = int(self.width)
        self.height = int(self.height)
        self.focal_mm_guess = None if self.focal_mm_guess is None else float(self.focal_mm_guess)
        self.points = {k: np.asarray(v, dtype=float).reshape(2) for k, v in self.points.items()}
        self.hidden = set(self.hidden)
        self.curves = {k: np.asarray(v, dtype=float).reshape(-1, 2) for k, v in self.curves.items()}
        self.sources = {k: str(v) for k, v in self.sources.items() if v != "user"}
        self.confidence = {k: float(v) for k, v in self.confidence.items()}
        self.curve_sources = {k: str(v) for k, v in self.curve_sources.items() if v != "user"}

    def __eq__(self, other):
        return (
            isinstance(other, Photo)
            and (
                self.id,
                self.path,
                self.width,
                self.height,
                self.preset,
                self.focal_mm_guess,
                self.camera_group,
                self.hidden,
                self.click_meta(),
                self.curve_meta(),
            )
            == (
                other.id,
                other.path,
                other.width,
                other.height,
                other.preset,
                other.focal_mm_guess,
                other.camera_group,
                other.hidden,
                other.click_meta(),
                other.curve_meta(),
            )
            and _array_dicts_equal(self.points, other.points)
            and _array_dicts_equal(self.curves, other.curves)
        )

    # -- clicks and where they came from (format version 3) ------------------------------
    def set_click(self, name: str, uv, source: str = "user", confidence: float | None = None) -> None:
        """Place or move the click of feature ``name`` at ``uv`` (2,) px, made by ``source``.

        The artist's edits (a click placed, dragged or moved by hand) use the default
        ``source="user"``, which turns an automatic click into the artist's and drops its
        confidence; the landmark detector passes ``source="auto"`` and its ``confidence`` in
        ``[0, 1]``. Raises :class:`ValueError` on a non-finite ``uv``, an unknown source or a
        confidence outside ``[0, 1]``.
        """
        uv = np.asarray(uv, dtype=float).reshape(2)
        if not np.all(np.isfinite(uv)):
            raise ValueError(f"click of {name!r} in photo {self.id!r} is not finite: {uv.tolist()}")
        if source not in CLICK_SOURCES:
            raise ValueError(f"a click's source is one of {CLICK_SOURCES}, got {source!r}")
        if confidence is not None and not 0.0 <= float(confidence) <= 1.0:
            raise ValueError(f"a click's confidence lies in [0, 1], got {confidence!r}")
        self.points[name] = uv
        self.sources.pop(name, None)
        self.confidence.pop(name, None)
        if source != "user":
            self.sources[name] = source
            if confidence is not None:
                self.confidence[name] = float(confidence)

    def remove_click(self, name: str) -> np.ndarray | None:
        """Delete the click of feature ``name`` (with its source and confidence); returns its
        ``uv`` or ``None`` when there was none."""
        self.sources.pop(name, None)
        self.confidence.pop(name, None)
        return self.points.pop(name, None)

    def click_source(self, name: str) -> str:
        """``"auto"`` or ``"user"``: where the click of feature ``name`` came from."""
        return self.sources.get(name, "user")

    def click_meta(self) -> dict[str, dict]:
        """Feature → ``{"source": ..., "confidence": ...}`` (confidence when known) of each
        click that is not the artist's: what the file's ``click_sources`` holds. Entries left
        behind by a click deleted from :attr:`points` directly are not included."""
        out = {}
        for n in self.points:
            if n in self.sources:
                out[n] = {"source": self.sources[n]}
                if n in self.confidence:
                    out[n]["confidence"] = self.confidence[n]
        return out

    def auto_clicks(self) -> list[str]:
        """Features whose click was placed automatically, in the order of :attr:`points`."""
        return [n for n in self.points if self.sources.get(n) == "auto"]

    # -- curves and where they came from (format version 5) ------------------------------
    def set_curve(self, name: str, polyline, source: str = "user") -> None:
        """Draw curve ``name`` as ``polyline`` (m, 2) px, m >= 2, drawn by ``source``
        (``"user"``: the artist, the default, which makes an automatic curve the artist's; the
        landmark detector passes ``"auto"``), or delete it (``polyline`` None). Raises
        :class:`ValueError` on fewer than 2 or non-finite points or an unknown source."""
        if source not in CLICK_SOURCES:
            raise ValueError(f"a curve's source is one of {CLICK_SOURCES}, got {source!r}")
        self.curve_sources.pop(name, None)
        if polyline is None:
            self.curves.pop(name, None)
            return
        line = np.asarray(polyline, dtype=float).reshape(-1, 2)
        if line.shape[0] < 2 or not np.all(np.isfinite(line)):
            raise ValueError(f"curve {name!r} in photo {self.id!r} needs at least 2 finite points")
        self.curves[name] = line
        if source != "user":
            self.curve_sources[name] = source

    def curve_source(self, name: str) -> str:
        """``"auto"`` or ``"user"``: who drew curve ``name``."""
        return self.curve_sources.get(name, "user")

    def curve_meta(self) -> dict[str, str]:
        """Curve → source of each drawn curve that is not the artist's: what the file's
        ``curve_sources`` holds."""
        return {n: self.curve_sources[n] for n in self.curves if n in self.curve_sources}

    def auto_curves(self) -> list[str]:
        """Curves drawn automatically, in the order of :attr:`curves`."""
        return [n for n in self.curves if self.curve_sources.get(n) == "auto"]


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
        if (self.mesh_obj, self.mesh_ply, self.report, self.texture) != (
            other.mesh_obj,
            other.mesh_ply,
            other.report,
            other.texture,
        ):
            return False
        if self.cameras.keys() != other.cameras.keys():
            return False
        for k, a in self.cameras.items():
            b = other.cameras[k]
            if not (
                np.array_equal(a.R, b.R)
                and np.array_equal(a.t, b.t)
                and a.f == b.f
                and (a.width, a.height) == (b.width, b.height)
            ):
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
        raise ProjectError(
            f"expression {self.name!r} has no photo {photo_id!r}; its photos are: {listing(p.id for p in self.photos)}"
        )

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
class RigRecord:
    """The project's rig (``facestudio rig``, :mod:`photomodel.rig`; format version 4).

    Attributes
    ----------
    source : str, where the expression shapes came from: ``"ict-facekit"`` (``facestudio rig``:
        ICT-FaceKit's expressions by deformation transfer) or ``"multilinear"`` (a face made with the
        studio's identity sliders: the people model's shapes at its identity, format version 6).
    neutral : str, the expression whose fitted mesh the shapes displace.
    shapes : list[str], the shapes' names (ARKit's), in the file's order.
    file : str, the ``.npz`` with ``names`` (k,) and ``deltas`` (k, n, 3) float32 mm, relative to
        the project folder (``results/rig.npz``).
    report : dict, free-form facts of the build (registration landmark error, seconds…).
    """

    source: str
    neutral: str
    shapes: list[str]
    file: str
    report: dict = field(default_factory=dict)


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
    rig : RigRecord or None, the blend-shape rig (format version 4), absent until ``facestudio rig``.
    people : list[str], other people's projects this one refers to (format version 6): paths of
        ``*.facestudio.json`` files relative to :attr:`folder` (``../alice/alice.facestudio.json``),
        e.g. those whose performances were cloned onto this face (their clones are this project's
        results, ``results/track_*_from_*``). Use :meth:`add_person`, :meth:`person_path`,
        :meth:`check_people`; :func:`photomodel.project.load_person` opens one.
    path : Path or None, the project file (absolute) once loaded or saved.
    """

    name: str
    generic_mesh: str = BUILTIN_MESH
    features: list[Feature] = field(default_factory=list)
    curves: list[CurveDef] = field(default_factory=list)
    expressions: list[Expression] = field(default_factory=list)
    rig: RigRecord | None = None
    people: list[str] = field(default_factory=list)
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
        raise ProjectError(
            f"project {self.name!r} has no expression {name!r}; available: {listing(e.name for e in self.expressions)}"
        )

    def feature(self, name: str) -> Feature:
        for f in self.features:
            if f.name == name:
                return f
        raise ProjectError(f"project {self.name!r} has no feature {name!r}{did_you_mean(name, self.feature_names())}")

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

    def observations(self, expression_name: str, feature_names: Sequence[str] | None = None) -> np.ndarray:
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

    # -- other people's projects (format version 6) ------------------------------------------
    def person_path(self, reference: str) -> Path:
        """Absolute path of a :attr:`people` entry (relative to :attr:`folder`)."""
        return Path(os.path.normpath(self.resolve(reference)))

    def add_person(self, path: str | os.PathLike) -> str | None:
        """Refer to the project file ``path`` (absolute, or relative to the cwd) in :attr:`people`,
        stored relative to :attr:`folder` (``../`` allowed); returns the entry, or None when it was
        there already (or is this project's own file). Nothing is read: a missing file is reported
        when it is opened (:func:`photomodel.project.load_person`) or by :meth:`check_people`."""
        target = Path(os.path.normpath(Path(path).absolute()))
        if self.path is not None and target == Path(os.path.normpath(self.path)):
            return None
        if any(self.person_path(p) == target for p in self.people):
            return None
        try:
            entry = Path(os.path.relpath(target, self.folder)).as_posix()
        except ValueError:  # another drive (Windows): only an absolute path reaches it
            entry = target.as_posix()
        self.people.append(entry)
        return entry

    def check_people(self) -> None:
        """Raise :class:`ProjectError` naming every :attr:`people` entry whose file is missing."""
        problems = [
            (f"people[{i}]", f"the referenced project {ref} does not exist (looked for {self.person_path(ref)})")
            for i, ref in enumerate(self.people)
            if not self.person_path(ref).is_file()
        ]
        if problems:
            raise problems_error(self._source(), problems)

    # -- checks that need more than the file ---------------------------------------------
    def check_vertices(self, n_vertices: int) -> None:
        """Raise :class:`ProjectError` if a feature or curve names a vertex ``>= n_vertices``.

        The file cannot know the generic mesh's size; the fitter calls this once the mesh is
        loaded.
        """
        problems = []
        for i, f in enumerate(self.features):
            if not 0 <= f.vertex < n_vertices:
                problems.append(
                    (
                        f"features[{i}].vertex",
                        f"feature {f.name!r}: vertex {f.vertex} is out of range for a "
                        f"generic mesh with {n_vertices} vertices",
                    )
                )
        for i, c in enumerate(self.curves):
            bad = np.flatnonzero((c.vertices < 0) | (c.vertices >= n_vertices))
            if bad.size:
                problems.append(
                    (
                        f"curves[{i}].vertices[{bad[0]}]",
                        f"curve {c.name!r}: vertex {c.vertices[bad[0]]} is out of range for "
                        f"a generic mesh with {n_vertices} vertices",
                    )
                )
        if problems:
            raise problems_error(self._source(), problems)

    def check_photos(self, read_size: Callable[[Path], tuple[int, int]] | None = None) -> None:
        """Raise :class:`ProjectError` naming every photo that is missing or unreadable.

        Parameters
        ----------
        read_size : callable, optional
            If None (default, cheap) a photo must exist and OpenCV must recognise its format
            from the file header (``cv2.haveImageReader``). If given — the photo reader's
            :func:`photomodel.photos.reading.photo_size`, passed in because the project's data
            model sits below :mod:`photomodel.photos` — each image is checked and decoded by it
            (a truncated JPEG or PNG is a problem: :class:`PhotoError`) and its oriented size
            (EXIF orientation applied) compared with the ``width``/``height`` stored in the project.
        """

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
                elif read_size is not None:
                    try:
                        w, h = read_size(p)
                    except PhotoError as exc:
                        problems.append((where, f"{who}: {photo.path} could not be decoded: {exc}"))
                        continue
                    if (w, h) != (photo.width, photo.height):
                        problems.append(
                            (where, f"{who}: {photo.path} is {w}x{h} but the project says {photo.width}x{photo.height}")
                        )
        if problems:
            raise problems_error(self._source(), problems)

    # -- internals ------------------------------------------------------------------
    def _source(self) -> str:
        return self.path.name if self.path is not None else f"project {self.name!r}"

    def _require_features(self, names: Iterable[str], defined) -> None:
        missing = [n for n in names if n not in defined]
        if missing:
            raise ProjectError(
                f"project {self.name!r} has no feature(s) {listing(missing)}"
                f"{did_you_mean(missing[0], self.feature_names())}"
            )


def new_project(
    name: str, *, generic_mesh: str = BUILTIN_MESH, features: Sequence[Feature] = (), curves: Sequence[CurveDef] = ()
) -> Project:
    """An empty project (no expressions) called ``name``; not yet saved."""
    if not isinstance(name, str) or not name.strip():
        raise ProjectError(f"a project needs a non-empty name, got {name!r}")
    return Project(name=name, generic_mesh=generic_mesh, features=list(features), curves=list(curves))


def _array_dicts_equal(a: dict, b: dict) -> bool:
    return a.keys() == b.keys() and all(np.array_equal(a[k], b[k]) for k in a)
