"""A frame's pose from the landmark detector: the first pose without clicks, and re-initialisation.

Pighin et al. (2002, §6.2) start tracking from a pose the user gives for the first frame. Beyond
the paper, :func:`detected_spec` finds it by itself: the automatic landmarks
(:func:`photomodel.landmarks.place_landmarks`, MediaPipe's face mesh mapped to the project's
features) place the project's pose features in the frame, and the result is written as a
first-pose JSON object (``focal_px`` and ``clicks``, :mod:`tracking.first_pose`) that
:func:`tracking.first_pose.pose_from_spec` solves like the user's clicks. The JSON is recorded in
``track.json``, so a continued run starts from the same pose.

The same detection watches the tracking (:class:`Redetector`): every :data:`REDETECT_EVERY`
frames, and on every frame after a diverged one, the tracked model's projected pose features are
compared with the detector's; a frame whose features are more than :data:`LOST_PX` from the
detector's (mean) is fitted again from the detected pose, like the first frame — the track
recovers from a lost face instead of staying lost. The check first runs the face mesh once on
the crop where the tracked model sees the face (MediaPipe's own tracking mode,
:func:`photomodel.landmarks.place_landmarks_near`, ~10 ms at 640×360 here); only when that finds
no face there, or finds its features further than :data:`LOST_PX`, does the full detector run
(face detector and three face-mesh passes, ~40 ms) — and its pose restarts the track.

The video camera's focal length (:func:`video_focal_px`): the project's fitted cameras of the
video's image size (a camera group made from frames of the same video, ``facestudio new
--camera-group``) when there are any, else :data:`DEFAULT_FOCAL_WIDTHS` × the frame's longer side.
"""

from __future__ import annotations

import numpy as np

from photomodel.errors import NoFaceFound
from photomodel.landmarks import place_landmarks, place_landmarks_near
from photomodel.photos.video import frame_uint8

__all__ = [
    "DEFAULT_FOCAL_WIDTHS",
    "LOST_PX",
    "MIN_CONFIDENCE",
    "REDETECT_EVERY",
    "Redetector",
    "detected_spec",
    "detected_features",
    "landmark_error_px",
    "pose_features",
    "projected_features",
    "video_focal_px",
]

#: Focal length, in widths of a landscape frame (of a portrait one: its height, the longer side),
#: assumed when the project has no camera of the video's size: a horizontal field of view of 58°,
#: between a phone's main camera (~65–70°) and a webcam's or a camcorder's (~50°). The real
#: sample's frames were fitted at 0.91 widths.
DEFAULT_FOCAL_WIDTHS = 0.9
#: Detected features with a lower confidence are not used to pose the model (the detector's jaw
#: outline: 0.1–0.3; eye, nose and mouth points are ≥ 0.59).
MIN_CONFIDENCE = 0.5
#: A tracked frame whose projected pose features are further than this (px, mean) from the
#: detector's has lost the face (the issue's definition of "lost").
LOST_PX = 15.0
#: The detector checks the tracking every this many frames (~90 ms a 640×360 frame on 2 cores:
#: ~9 ms a frame on average), and on every frame after a diverged one.
REDETECT_EVERY = 10


def video_focal_px(project, width: int, height: int) -> tuple[float, str]:
    """The video camera's focal length (px) and a sentence saying where it comes from.

    The median focal length of the project's fitted cameras whose image is ``width × height``
    (frames of the same video, or photos of the same camera), else :data:`DEFAULT_FOCAL_WIDTHS`
    × the longer of ``width`` and ``height`` — the width of a landscape frame; a phone held upright
    films through the same lens, its frame's height is what the width was (0.9 × the width gave a
    portrait clip's camera twice the true field of view).
    """
    found = [
        (f"{e.name}/{pid}", cam.f)
        for e in project.expressions
        if e.result is not None
        for pid, cam in e.result.cameras.items()
        if (cam.width, cam.height) == (width, height)
    ]
    if found:
        f = float(np.median([f for _, f in found]))
        return f, f"the project's fitted cameras of {width}x{height} images ({', '.join(n for n, _ in found)})"
    f = DEFAULT_FOCAL_WIDTHS * max(width, height)
    return f, (
        f"estimated: {DEFAULT_FOCAL_WIDTHS} x the frame's longer side (no fitted camera of {width}x{height} "
        f"images in the project; pass --focal-px if known)"
    )


def pose_features(project) -> list[str]:
    """The features whose detected positions pose the model: the project's pose features
    (the generic mesh's 13 initial features in a default project)."""
    return project.feature_names(pose_only=True) or project.feature_names()


def detected_features(frame: np.ndarray, names, *, name: str = "the frame") -> dict[str, list[float]] | None:
    """The detector's positions of the features ``names`` in ``frame`` (H, W, 3) RGB (uint8, or
    float in [0, 1]), those with confidence ≥ :data:`MIN_CONFIDENCE`: ``{feature: [u, v]}`` px
    (centres at integers, rounded to 1/1000 px so that the JSON is exact); None when no face is
    found."""
    img = frame_uint8(frame)
    try:
        placed = place_landmarks(img, list(names), name=name)
    except NoFaceFound:
        return None
    return {
        n: [round(float(u), 3), round(float(v), 3)]
        for n, (u, v) in placed.points.items()
        if placed.confidence.get(n, 0.0) >= MIN_CONFIDENCE
    }


def detected_spec(frame: np.ndarray, project, focal_px: float, *, name: str = "frame 0") -> dict | None:
    """A first-pose JSON object (:mod:`tracking.first_pose`) of ``frame`` from the detector:
    ``{"focal_px", "clicks": {feature: [u, v]}, "detected": true}``; None when no face is found
    or fewer than six pose features are placed."""
    clicks = detected_features(frame, pose_features(project), name=name)
    if clicks is None or len(clicks) < 6:
        return None
    return {"focal_px": float(focal_px), "clicks": clicks, "detected": True}


def projected_features(fitter, state, vertices: np.ndarray) -> np.ndarray:
    """(k, 2) px: the model's vertices ``vertices`` (k,) at ``state`` (pose and expression) seen
    by ``fitter``'s camera (:class:`tracking.frame_fit.FrameFitter`)."""
    model = fitter.model
    X = model.geometry_at(state.alpha)[np.asarray(vertices, np.int64)]
    return fitter.camera(state).project(X)


def landmark_error_px(tracked: dict, detected: dict) -> float:
    """Mean distance (px) between two ``{feature: [u, v]}`` over their common features (inf if none)."""
    common = [n for n in tracked if n in detected]
    if not common:
        return float("inf")
    a = np.array([tracked[n] for n in common], float)
    b = np.array([detected[n] for n in common], float)
    return float(np.linalg.norm(a - b, axis=1).mean())


class Redetector:
    """Watches a tracked video with the detector (see the module notes).

    Parameters
    ----------
    project : the project (its pose features).
    focal_px : the video camera's focal length (px).
    every : check every this many frames (and after every diverged frame); 0 never.
    """

    def __init__(self, project, focal_px: float, every: int = REDETECT_EVERY):
        self.project, self.focal_px, self.every = project, float(focal_px), int(every)
        self.names = pose_features(project)
        self.vertices = project.feature_vertices(self.names)
        self.last_diverged = False
        # the eye line turns the tracking-mode crop (as the detector's keypoints turn its crop)
        eyes = ["eye_r_outer", "eye_l_outer"]
        self._eyes = project.feature_vertices(eyes) if set(eyes) <= set(project.feature_names()) else None

    def landmarks(self, fitter, state) -> dict[str, list[float]]:
        """The model's projected pose features at ``state``: ``{feature: [u, v]}`` px."""
        uv = projected_features(fitter, state, self.vertices)
        return {n: [float(u), float(v)] for n, (u, v) in zip(self.names, uv, strict=True)}

    def restart_spec(self, index: int, frame: np.ndarray, fitter, result) -> dict | None:
        """The detected first-pose JSON to fit frame ``index`` again from, when its tracked
        ``result`` lost the face (its features > :data:`LOST_PX` from the detector's; checked
        every :attr:`every` frames and after a diverged one); None when the tracking holds, the
        check is not due, or no face is found."""
        due = self.every > 0 and (index % self.every == 0 or result.diverged or self.last_diverged)
        self.last_diverged = bool(result.diverged)
        if not due or self._holds_near(frame, fitter, result):
            return None
        spec = detected_spec(frame, self.project, self.focal_px, name=f"frame {index}")
        if spec is None:
            return None
        # the image RMS alone does not say lost: real footage against a model textured from a few
        # frames sits near DIVERGED_RMS (0.09–0.12 on the real sample) while the features hold
        if landmark_error_px(self.landmarks(fitter, result.state), spec["clicks"]) <= LOST_PX:
            return None
        return spec

    def _holds_near(self, frame: np.ndarray, fitter, result) -> bool:
        """True when one face-mesh pass on the crop where the tracked model sees the face (its
        face region's box, turned by its eye line) finds the features within :data:`LOST_PX` of
        the tracked ones; False when it cannot tell (no eye corners in the project, the model out
        of view, no face in the crop, the features further): the full detector decides then."""
        if result.diverged:
            return False
        seen = self.near_landmarks(frame, fitter, result.state)
        return seen is not None and landmark_error_px(self.landmarks(fitter, result.state), seen) <= LOST_PX

    def landmark_term(self, frame: np.ndarray, fitter, work, state):
        """The detector's pose features near ``state`` (:meth:`near_landmarks`, on the full
        ``frame`` with ``fitter``'s camera) as the landmark term of ``work`` — ``fitter`` itself or
        the fitter of the frames reduced by an integer factor (pixel centres mapped,
        ``x' = (x + ½)/k − ½``) — (:meth:`tracking.frame_fit.FrameFitter.landmark_term`); None when
        none is found."""
        seen = self.near_landmarks(frame, fitter, state)
        if not seen:
            return None
        at = [i for i, n in enumerate(self.names) if n in seen]
        k = fitter.W / work.W
        uv = (np.array([seen[self.names[i]] for i in at], float) + 0.5) / k - 0.5
        return work.landmark_term(np.asarray(self.vertices)[at], uv)

    def near_landmarks(self, frame: np.ndarray, fitter, state) -> dict[str, list[float]] | None:
        """The pose features found by one face-mesh pass on the crop where the model at ``state``
        sees the face (its face region's box, turned by its eye line; MediaPipe's tracking mode,
        ~10 ms): ``{feature: [u, v]}`` px of ``frame`` (those with confidence ≥
        :data:`MIN_CONFIDENCE`); None when it cannot tell (no eye corners in the project, the
        model out of view, no face in the crop)."""
        if self._eyes is None:
            return None
        model = fitter.model
        X = model.geometry_at(state.alpha)
        cam = fitter.camera(state)
        uv = cam.project(X[model.face_mask])
        eyes = cam.project(X[self._eyes])
        if not (np.all(np.isfinite(uv)) and np.all(np.isfinite(eyes))):
            return None
        d = eyes[1] - eyes[0]
        box, angle = (*uv.min(0), *uv.max(0)), float(np.arctan2(d[1], d[0]))
        placed = place_landmarks_near(frame_uint8(frame), self.names, box, angle)
        if placed is None:
            return None
        return {n: p for n, p in placed.points.items() if placed.confidence.get(n, 0.0) >= MIN_CONFIDENCE}
