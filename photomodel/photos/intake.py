"""Photos into a project, with automatic landmarks: ``facestudio new`` and the studio's *Add photos…*.

One place for what happens to a photograph on its way into a project, so the CLI and the studio
do the same thing:

1. read with :func:`photomodel.photos.reading.read_photo` (EXIF orientation, a truncated file is
   a :class:`~photomodel.errors.PhotoError` naming it, a working resolution for very large ones);
   the project stores the oriented original's size and clicks in its pixels;
2. the focal length from EXIF (:func:`photomodel.photos.exif.focal_mm_guess_from_exif`) and a
   camera group (:func:`photomodel.photos.exif.camera_identity`: one camera at one focal length;
   or one name for all, e.g. the frames of one video);
3. the landmarks placed by the detector (:func:`photomodel.landmarks.place_landmarks`, or any
   ``placer`` with its signature), each stored as an automatic click (``source "auto"`` with its
   confidence, project format version 3) in the original photo's pixels, and the eyelids and
   outer lips as automatic curves (``curve_sources``, version 5); the view ``preset``
   from the detector's yaw estimate;
4. warnings, never errors, for what the artist fixes by hand: no face found (click by hand),
   several faces (the largest used), two photos of the same image;
5. the mouth from the most neutral photos (:func:`prefer_neutral_mouths`, for the
   :data:`~photomodel.modeling.mouth.NEUTRAL` expression only; the score is
   :func:`photomodel.modeling.mouth.mouth_expression`): an expressive photo's automatic mouth
   clicks are left out where other photos show a neutral mouth, so a smile is not fitted as the
   neutral face nor its mouth reported as misclicks; where none does, one warning per photo says
   that its mouth shows an expression and that the face is fitted as that expression, not as a
   neutral one (the expression is not fitted apart from the neutral: the fit says so again,
   ``report["expressive_photos"]``).

A photo that cannot be read stops the whole intake before the project is touched. The
functions here neither write files nor print: callers save (:func:`photomodel.project.save_project`)
and report the warnings.
"""

from __future__ import annotations

import os
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from photomodel.camera import PRESET_AZIMUTH_DEG
from photomodel.errors import NoFaceFound, PhotoError, ProjectError
from photomodel.landmarks import place_landmarks
from photomodel.modeling.generic_mesh import IBUG68_NAMES, GenericMesh, ibug_index
from photomodel.modeling.mouth import (  # noqa: F401 (lips_apart, OPEN_MOUTH_FROM: read here by tests and docs)
    MOUTH_IBUG,
    NEUTRAL,
    NEUTRAL_MOUTH_UP_TO,
    OPEN_MOUTH_FROM,
    lips_apart,
    mouth_expression,
)
from photomodel.photos.exif import camera_identity, focal_mm_guess_from_exif
from photomodel.photos.reading import (
    duplicate_pairs,
    fingerprint,
    photos_in_folder,
    read_photo,
    to_original,
    unreadable_note,
    unreadable_photos_in_folder,
)
from photomodel.project.datamodel import CurveDef, Expression, Feature, Photo, Project, new_project
from photomodel.project.format import FILE_SUFFIX
from photomodel.project.validate import OUT_OF_BOUNDS_MARGIN

#: A placer: ``(RGB uint8 image (h, w, 3), feature names) → placement`` with ``points`` (name →
#: (2,) px in that image), ``confidence`` (name → [0, 1]), ``preset`` and ``faces_found``
#: (:func:`photomodel.landmarks.place_landmarks`); raises :class:`NoFaceFound` when there is none.
Placer = Callable[[np.ndarray, Sequence[str]], object]
#: ``progress(label, fraction)``: the photo being read and how far the intake has come.
Progress = Callable[[str, float], None]

#: Side (px) at which photos already in an expression are read to compare them with new ones.
_COMPARE_SIDE = 512


@dataclass
class _Incoming:
    """One photo read and placed, before it joins the project."""

    photo: Photo
    fingerprint: np.ndarray
    warnings: list[str]


def default_features(mesh: GenericMesh) -> tuple[list[Feature], list[CurveDef]]:
    """The features and curves a new project starts with: those of the sample project.

    The 13 pose features of :data:`~photomodel.modeling.generic_mesh.INITIAL_FEATURES`
    (``pose: true``), then the other 55 iBUG-68 landmarks by their names (``pose: false``) —
    the features the landmark detector places — and every curve of the generic mesh
    (§5.1.3). These are the sample project's first 68 features, vertex for vertex; the sample's
    100 further ``extra_*`` correspondences are points of its synthetic ground truth that no
    detector places, so they are left out (copy them with ``features_from`` when wanted).
    """
    features = [Feature(name, mesh.features[name], True) for name in mesh.initial_features]
    used = {f.vertex for f in features}
    features += [
        Feature(name, int(mesh.landmarks[i]), False)
        for i, name in enumerate(IBUG68_NAMES)
        if int(mesh.landmarks[i]) not in used
    ]
    curves = [CurveDef(name, vertices) for name, vertices in mesh.curves.items()]
    return features, curves


def new_project_from_photos(
    photos: str | os.PathLike | Sequence[str | os.PathLike],
    project_path: str | os.PathLike,
    *,
    features: Sequence[Feature],
    curves: Sequence[CurveDef] = (),
    expression: str = NEUTRAL,
    camera_group: str | None = None,
    placer: Placer = place_landmarks,
    progress: Progress | None = None,
) -> tuple[Project, list[str]]:
    """A new project of one expression from a folder of photos (or a list of photo files).

    Parameters
    ----------
    photos : a folder (every photo file in it, :func:`photomodel.photos.reading.photos_in_folder`,
        sorted by name) or a sequence of photo files, in the order they are added.
    project_path : the project file it will be saved as; relative photo paths are written
        relative to its folder, and its name (less ``.facestudio.json``) names the project.
    features, curves : the project's definitions (:func:`default_features` for the sample's).
    expression : name of the expression the photos show.
    camera_group : one group for every photo (frames of one video); ``None``: by camera, from
        EXIF (:func:`photomodel.photos.exif.camera_identity`).
    placer, progress : see :func:`add_photos`.

    Returns
    -------
    (Project, list of str)
        the project, not yet saved (``project.path`` set), and the warnings.

    Raises
    ------
    PhotoError naming the file, when a photo is missing, truncated or cannot be decoded.
    """
    project_path = Path(project_path).absolute()
    name = project_path.name.removesuffix(FILE_SUFFIX).removesuffix(".json") or "face"
    project = new_project(name, features=features, curves=curves)
    project.path = project_path
    paths, skipped = photo_files([photos] if isinstance(photos, (str, os.PathLike)) else photos)
    warnings = add_photos(project, expression, paths, camera_group=camera_group, placer=placer, progress=progress)
    return project, warnings + skipped


def photo_files(sources: Sequence[str | os.PathLike]) -> tuple[list[Path], list[str]]:
    """The photo files a user named (:func:`gather_photo_files`) and the warnings for files of a
    type that is not read; the first problem (a folder without photos, a path that does not
    exist) is raised as a :class:`PhotoError` naming it."""
    paths, skipped, problems = gather_photo_files(sources)
    if problems:
        raise problems[0]
    return paths, skipped


def gather_photo_files(sources: Sequence[str | os.PathLike]) -> tuple[list[Path], list[str], list[PhotoError]]:
    """The photo files a user named (a command's arguments, a drop on the studio): each folder's
    photos in name order (:func:`photomodel.photos.reading.photos_in_folder`), each file as it is,
    in the order given.

    Returns the files, each once (a file named again, or also in a named folder, is taken where
    it first comes); a warning for each file in those folders of a type that is not read (HEIC,
    camera raw…: named with what to do, not passed over in silence); and, without raising, a
    :class:`PhotoError` naming each folder without photos and each path that does not exist.
    """
    paths: list[Path] = []
    skipped: list[str] = []
    problems: list[PhotoError] = []
    for source in sources:
        source = Path(source)
        if source.is_dir():
            try:
                paths += photos_in_folder(source)
            except PhotoError as exc:
                problems.append(exc)
                continue
            skipped += [unreadable_note(p) + "; not added" for p in unreadable_photos_in_folder(source)]
        elif source.exists():
            paths.append(source)
        else:
            problems.append(PhotoError(f"{source}: no such photo or folder"))
    once: dict[Path, Path] = {}  # the file itself -> the path it was first named by
    for p in paths:
        once.setdefault(p.resolve(), p)
    return list(once.values()), skipped, problems


def add_photos(
    project: Project,
    expression: str,
    paths: Sequence[str | os.PathLike],
    *,
    camera_group: str | None = None,
    placer: Placer = place_landmarks,
    progress: Progress | None = None,
    skip_unreadable: bool = False,
) -> list[str]:
    """Add photos to an expression of ``project`` (created when absent), with automatic landmarks.

    Every photo is read and placed first; only when all of them could be read are they
    appended to the expression, so an error leaves the project untouched — or, with
    ``skip_unreadable`` (the studio's drop of many files), a photo that cannot be read is left
    out and named in a warning, and the others are added.

    Parameters
    ----------
    project : the project; its features name what the placer is asked for.
    expression : the expression's name.
    paths : photo files, in order. Ids are the file stems, made unique within the expression.
    camera_group : one group for every new photo; ``None``: by camera, from EXIF.
    placer : ``placer(image, feature_names)``, default :func:`photomodel.landmarks.place_landmarks`.
    progress : ``progress(label, fraction)`` after each photo, or ``None``.

    Returns
    -------
    list of str
        warnings, each naming its photo: no face found (its landmarks are clicked by hand),
        several faces (the largest used), two photos of the same image, an expressive mouth in the
        neutral expression (:func:`prefer_neutral_mouths`).

    Raises
    ------
    PhotoError naming the file, when a photo is missing, truncated or cannot be decoded (not
    with ``skip_unreadable``).
    """
    if camera_group is not None and (not isinstance(camera_group, str) or not camera_group):
        raise ProjectError(f"a camera group is a non-empty name or none, got {camera_group!r}")
    expr = _expression(project, expression)
    names = project.feature_names()
    curves = {c.name for c in project.curves}
    ids = {p.id for p in expr.photos}
    incoming, unread = [], []
    for k, path in enumerate(paths):
        if progress is not None:
            progress(f"reading {Path(path).name}", k / max(len(paths), 1))
        try:
            one = _intake_photo(Path(path).absolute(), ids, names, curves, camera_group, placer)
        except PhotoError as exc:
            if not skip_unreadable:
                raise
            unread.append(f"{exc}; not added")
            continue
        ids.add(one.photo.id)
        incoming.append(one)
    if progress is not None:
        progress("comparing photos", 1.0)
    warnings = unread + [w for one in incoming for w in one.warnings]
    warnings += _duplicate_warnings(project, expr, incoming)
    if expression == NEUTRAL:
        warnings += prefer_neutral_mouths([one.photo for one in incoming], expression)
    expr.photos.extend(one.photo for one in incoming)
    return warnings


def _expression(project: Project, name: str) -> Expression:
    for e in project.expressions:
        if e.name == name:
            return e
    if not isinstance(name, str) or not name.strip():
        raise ProjectError(f"an expression needs a non-empty name, got {name!r}")
    project.expressions.append(Expression(name=name))
    return project.expressions[-1]


def _intake_photo(
    path: Path, ids: set[str], names: list[str], curves: set[str], camera_group: str | None, placer: Placer
) -> _Incoming:
    """Read one photo, guess its camera, place its landmarks (see the module docstring)."""
    read = read_photo(path)
    photo = Photo(
        id=_unique_id(path, ids),
        path=str(path),
        width=read.width,
        height=read.height,
        focal_mm_guess=focal_mm_guess_from_exif(path, read.width, read.height),
        camera_group=camera_group if camera_group is not None else camera_identity(path),
    )
    warnings = []
    try:
        placement = placer(read.image, names)
    except NoFaceFound:
        warnings.append(f"no face found in {path.name}: click its landmarks by hand")
        return _Incoming(photo, fingerprint(read.image), warnings)
    faces = int(getattr(placement, "faces_found", 1))
    if faces > 1:
        warnings.append(f"{path.name}: {faces} faces found; the largest used")
    preset = getattr(placement, "preset", "front")
    photo.preset = preset if preset in PRESET_AZIMUTH_DEG else "front"
    _store_auto_clicks(photo, placement, read.scale, set(names), curves)
    return _Incoming(photo, fingerprint(read.image), warnings)


#: Photos whose mouth is within this much of the most neutral one's count as showing the same.
SAME_MOUTH_WITHIN = 0.03
#: The automatic curves drawn on the mouth.
MOUTH_CURVES = ("lip_upper", "lip_lower")


def prefer_neutral_mouths(photos: list[Photo], expression: str) -> list[str]:
    """The mouth from the most neutral photos: each photo's automatic mouth clicks (iBUG 48–67)
    and lip curves are left out where its mouth shows an expression the most neutral photo does
    not (:func:`~photomodel.modeling.mouth.mouth_expression` over :data:`NEUTRAL_MOUTH_UP_TO` and
    more than :data:`SAME_MOUTH_WITHIN` over the least): the fit is of one face, and a smile's or a
    word's mouth would disagree with the neutral's clicks and be reported as misclicks. The other
    features of those photos stay. Returns the warnings, one per expressive photo: its mouth left
    out, or — where no photo's mouth is neutral — kept, the face then fitted as that expression
    (not a neutral face, and the expression not fitted apart from it); then, in that case, one
    line of what to do."""
    scores = {p.id: mouth_expression({n: p.points[n] for n in p.auto_clicks()}) for p in photos}
    known = {pid: v for pid, v in scores.items() if v is not None}
    if not known:
        return []
    least = min(known.values())
    keep_up_to = max(NEUTRAL_MOUTH_UP_TO, least + SAME_MOUTH_WITHIN)
    warnings = []
    for p in photos:
        v = known.get(p.id)
        if v is None or v <= NEUTRAL_MOUTH_UP_TO:
            continue
        shows = (
            f"{p.id}: the mouth shows an expression ({v:.2f} eye distances from a closed, relaxed one; "
            f"neutral is under {NEUTRAL_MOUTH_UP_TO})"
        )
        if v <= keep_up_to:
            warnings.append(
                f"{shows}, and no photo of {expression!r} shows a neutral one: its mouth is kept, so the face is "
                "fitted as this expression, not as a neutral face (the expression is not fitted apart from the "
                "neutral); its mouth clicks are not misclicks"
            )
            continue
        for name in p.auto_clicks():
            if ibug_index(name) in MOUTH_IBUG:
                p.remove_click(name)
        for name in MOUTH_CURVES:
            if p.curve_source(name) == "auto" and name in p.curves:
                p.set_curve(name, None)
        warnings.append(
            f"{shows}: its mouth clicks are left out and the mouth of {expression!r} is taken from the photos "
            "where it is neutral"
        )
    if least > NEUTRAL_MOUTH_UP_TO:
        best = min(known, key=known.get)
        warnings.append(
            f"no photo of {expression!r} shows a neutral mouth (the most neutral, {best}, is {least:.2f} eye "
            f"distances from a closed, relaxed one; neutral is under {NEUTRAL_MOUTH_UP_TO}): the mouth is fitted "
            "to that expression, not to a neutral face. Add a photo with the mouth closed and relaxed, or name "
            "the expression (--expression smile)"
        )
    return warnings


def _store_auto_clicks(photo: Photo, placement, scale: float, names: set[str], curve_names: set[str]) -> None:
    """The placement's points (working-image pixels) as automatic clicks in the original's
    pixels, and its curves (those the project defines) as automatic curves; points that are not
    finite or lie beyond the margin a project accepts are dropped, and curves with such a point."""
    confidence = getattr(placement, "confidence", {}) or {}
    reach = OUT_OF_BOUNDS_MARGIN * 0.9  # inside what validation accepts, with room for rounding
    lo = -0.5 - reach * np.array([photo.width, photo.height])
    hi = np.array([photo.width, photo.height]) - 0.5 + reach * np.array([photo.width, photo.height])

    def kept(uv) -> np.ndarray | None:  # (..., 2) working-image px → original px, None if not storable
        uv = to_original(np.asarray(uv, float), scale)
        return uv if np.all(np.isfinite(uv)) and np.all(uv >= lo) and np.all(uv <= hi) else None

    for name, uv in placement.points.items():
        if name not in names or (uv := kept(np.reshape(uv, 2))) is None:
            continue
        c = confidence.get(name)
        c = None if c is None or not np.isfinite(c) else float(np.clip(c, 0.0, 1.0))
        photo.set_click(name, uv, source="auto", confidence=c)
    for name, line in (getattr(placement, "curves", {}) or {}).items():
        if name in curve_names and (line := kept(np.reshape(line, (-1, 2)))) is not None and len(line) >= 2:
            photo.set_curve(name, line, source="auto")


def _unique_id(path: Path, ids: set[str]) -> str:
    stem = path.name.split(".")[0] or "photo"
    pid, k = stem, 2
    while pid in ids:
        pid, k = f"{stem}_{k}", k + 1
    return pid


def _duplicate_warnings(project: Project, expr: Expression, incoming: list[_Incoming]) -> list[str]:
    """Warnings for pairs of photos that are the same image: among the new photos, and between
    a new photo and one already in the expression (read small; an unreadable one is skipped —
    :meth:`Project.check_photos` reports it)."""
    old = []
    for p in expr.photos:
        try:
            old.append((p, fingerprint(read_photo(project.photo_path(p), max_side=_COMPARE_SIDE).image)))
        except PhotoError:
            continue
    entries = old + [(one.photo, one.fingerprint) for one in incoming]
    first_new = len(old)
    out = []
    for i, j in duplicate_pairs([f for _, f in entries]):
        if j < first_new:
            continue  # two old photos: said when they were added
        a, b = entries[i][0], entries[j][0]
        out.append(
            f"{Path(a.path).name} and {Path(b.path).name} are the same image (photos {a.id!r} "
            f"and {b.id!r}): two views must be different photographs; remove one"
        )
    return out
