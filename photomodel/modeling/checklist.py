"""What a fit still needs from the artist: every missing or under-clicked feature and photo at once.

A fit places the cameras from features clicked in at least two photos (§5.1.1) and deforms the
generic mesh from the pose features. When the clicks cannot support that, the artist should see
*everything* that is missing in one go — the studio shows this checklist beside the feature list,
``facestudio fit`` prints it (and puts it in its ``--json`` error) — rather than one feature per
attempt. :func:`click_checklist` lists:

* every **pose feature** clicked (and not hidden) in fewer than 2 photos, with the photos it is
  clicked or hidden in, and what to do: click it in another photo where it shows, or leave it out
  of the pose features (``Feature.pose = False``) when the views cannot see it twice;
* every **photo** with fewer than :data:`~photomodel.modeling.pose.MIN_POINTS_PER_VIEW` clicks of
  features that another photo also has (a camera needs that many).

An expression of **one photo** is fitted against the generic head
(:mod:`photomodel.modeling.camera_solve`): a pose feature is then needed in that photo only, and
the photo needs :data:`~photomodel.modeling.pose.MIN_POINTS` clicks.

:func:`require_clicks` raises :class:`~photomodel.errors.MissingClicks` carrying the whole list
when the fit cannot go on. Arrays and dataclasses only; no Qt, no files.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, field

import numpy as np

from photomodel.errors import MissingClicks
from photomodel.modeling.pose import MIN_POINTS, MIN_POINTS_PER_VIEW

#: Photos a feature must be clicked in to be triangulated (and so to place the cameras).
NEEDED_PHOTOS = 2
#: Pose features placed in 2+ photos that the first deformation of the generic mesh needs
#: (the robust camera solve; the paper's pose recovery needs :data:`MIN_POINTS`).
MIN_POSE_FEATURES = 4


@dataclass
class ChecklistItem:
    """One thing a fit is missing.

    Attributes
    ----------
    feature : str or None, the pose feature (None for a photo's item).
    photo : str or None, the photo short of clicks (None for a feature's item).
    photos_clicked : int, photos the feature is clicked and not hidden in (a photo's item: its
        clicks of features another photo also has).
    needed : int, how many there must be.
    clicked_in, hidden_in : list[str], photo ids (a feature's item).
    hint : str, what to do, in words.
    """

    feature: str | None
    photo: str | None
    photos_clicked: int
    needed: int
    hint: str
    clicked_in: list[str] = field(default_factory=list)
    hidden_in: list[str] = field(default_factory=list)

    def to_dict(self) -> dict:
        return asdict(self)


def _feature_hint(
    name: str, clicked: list[str], hidden: list[str], others: list[str], needed: int = NEEDED_PHOTOS
) -> str:
    where = f"clicked only in {', '.join(map(repr, clicked))}" if clicked else "not clicked yet"
    if hidden:
        where += f", hidden in {', '.join(map(repr, hidden))}"
    todo = f"click it in {needed - len(clicked)} more photo(s) where it shows" + (
        f" ({', '.join(map(repr, others))})" if clicked and others else ""
    )
    return f"{where}; {todo}, or leave it out of the pose features (unflag it)"


def _needed_photos(photos) -> int:
    """Photos a feature must be clicked in: :data:`NEEDED_PHOTOS`, or 1 in a fit from one photo."""
    return min(NEEDED_PHOTOS, max(len(photos), 1))


def _feature_items(project, expression_name: str) -> list[ChecklistItem]:
    photos = project.expression(expression_name).photos
    needed = _needed_photos(photos)
    pose = [f.name for f in project.features if f.pose]
    obs = project.observations(expression_name, pose)
    seen = np.isfinite(obs[..., 0])
    items = []
    for i, name in enumerate(pose):
        if seen[:, i].sum() >= needed:
            continue
        clicked = [p.id for p, s in zip(photos, seen[:, i], strict=True) if s]
        hidden = [p.id for p in photos if name in p.hidden]
        others = [p.id for p in photos if p.id not in clicked and p.id not in hidden]
        items.append(
            ChecklistItem(
                name, None, len(clicked), needed, _feature_hint(name, clicked, hidden, others, needed), clicked, hidden
            )
        )
    return items


def _photo_items(project, expression_name: str, pose_only: bool) -> list[ChecklistItem]:
    photos = project.expression(expression_name).photos
    names = project.feature_names(pose_only=pose_only)
    seen = np.isfinite(project.observations(expression_name, names)[..., 0])
    which = "pose features" if pose_only else "features"
    if len(photos) == 1:  # its camera is placed against the generic head
        n = int(seen[0].sum())
        if n >= MIN_POINTS:
            return []
        return [
            ChecklistItem(
                None,
                photos[0].id,
                n,
                MIN_POINTS,
                f"the only photo: its camera is placed against the generic head from {MIN_POINTS} "
                f"clicks of {which}, not all on one line — click more of them here (or add photos)",
            )
        ]
    shared = seen & (seen.sum(0) >= NEEDED_PHOTOS)[None]
    items = []
    for photo, n in zip(photos, shared.sum(1), strict=True):
        if n < MIN_POINTS_PER_VIEW:
            items.append(
                ChecklistItem(
                    None,
                    photo.id,
                    int(n),
                    MIN_POINTS_PER_VIEW,
                    f"a camera needs {MIN_POINTS_PER_VIEW} clicks of {which} also clicked in another photo, "
                    "not all on one line — click more of them here",
                )
            )
    return items


def click_checklist(project, expression_name: str, *, pose_only: bool = False) -> list[ChecklistItem]:
    """Everything one expression's clicks lack for a fit: under-clicked pose features, then photos.

    Parameters
    ----------
    project : photomodel.project.Project
    expression_name : str
    pose_only : bool
        Count a photo's shared clicks over the pose features only (the paper's pose recovery,
        ``FitOptions(bundle_all=False)``); default: every feature (the robust camera solve).

    Returns
    -------
    list[ChecklistItem], empty when nothing is missing. A pose feature listed here is left out
    of the camera solve by the robust fit (it is reported as dropped), so the list is also what
    a successful fit leaves unused.
    """
    return _feature_items(project, expression_name) + _photo_items(project, expression_name, pose_only)


def require_clicks(project, expression_name: str, *, pose_only: bool = False) -> list[ChecklistItem]:
    """The checklist, or :class:`~photomodel.errors.MissingClicks` when a fit cannot go on with it.

    The robust camera solve (default) fails when a photo is short of shared clicks or fewer than
    :data:`MIN_POSE_FEATURES` pose features are clicked in 2 photos; the paper's (``pose_only``)
    needs every pose feature in 2 photos and at least :data:`MIN_POINTS` of them.
    """
    items = click_checklist(project, expression_name, pose_only=pose_only)
    n_pose = len(project.feature_names(pose_only=True))
    short = [it for it in items if it.feature is not None]
    placed = n_pose - len(short)
    photos = project.expression(expression_name).photos
    fails = (
        any(it.photo is not None for it in items)
        or placed < (MIN_POINTS if pose_only else MIN_POSE_FEATURES)
        or (pose_only and short)
    )
    if fails:
        note = None
        if photos and not any(p.points for p in photos):
            where = f" (`facestudio studio {project.path}`)" if project.path is not None else ""
            note = (
                f"no photo has a click yet — in a project `facestudio new` made, no face was found "
                f"automatically in any photo: click the features by hand in the studio{where}"
            )
        raise MissingClicks(
            expression_name,
            [it.to_dict() for it in items],
            placed=placed,
            pose_features=n_pose,
            note=note,
            needed_photos=_needed_photos(photos),
        )
    return items
