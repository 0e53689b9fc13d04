"""Automatic landmarks: MediaPipe's face mesh (Apache-2.0) run offline, mapped to the project's features.

:func:`place_landmarks` is the one call the CLI and the studio make: a photo in, the named
features it can place out, each with a confidence, plus the view preset and the head's yaw.
:func:`detect_468` gives the raw 468 face-mesh points (the landmark benchmark uses it).
Modules: :mod:`~photomodel.landmarks.models` (the model files, fetched by package name),
:mod:`~photomodel.landmarks.detect` (the detector run with ``cv2.dnn``),
:mod:`~photomodel.landmarks.mapping` (468 points → named features, yaw, view),
:mod:`~photomodel.landmarks.outline` (the jaw moved onto the photo's own edges),
:mod:`~photomodel.landmarks.segment` (which pixels texturing may take) and
:mod:`~photomodel.landmarks.hands` (a hand in front of the face: ``hand_mask``).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

from photomodel.landmarks.detect import Face468, detect_468_near
from photomodel.landmarks.detect import detect_468 as _detect_468
from photomodel.landmarks.mapping import curves_from_mesh, estimate_yaw_deg, features_from_mesh, preset_for_yaw

__all__ = ["Placement", "detect_468", "place_landmarks", "place_landmarks_near"]


@dataclass
class Placement:
    """The features placed automatically in one photo.

    Attributes
    ----------
    points : dict[str, (2,) float]
        feature name → ``[u, v]`` in the ORIGINAL photo's pixels (centres at integers, y down).
        Only features the mapping knows and sees: names that are no iBUG landmark
        (``extra_*``) and far-side points of a profile are absent. Up to a three-quarter
        view all are placed, far-side jaw points on the face's visible outline, and the jaw
        moved onto the photo's own edges (:mod:`photomodel.landmarks.outline`).
    confidence : dict[str, float]
        same keys, in [0, 1]: low (0.1–0.3) for the jaw outline (0.1 on the far side's
        outline), up to 0.9 for eye and mouth corners in a frontal view, lower as the head turns.
    preset : str
        a key of :data:`photomodel.camera.PRESET_AZIMUTH_DEG` estimated from the points.
    yaw_deg : float
        estimated head yaw in degrees in the presets' azimuth convention: ``+`` when the
        camera sees the subject's left side (the subject turned to their right). Saturates
        near ±55–60°.
    faces_found : int
        faces found in the photo; when > 1 the largest was used (the caller says so).
    face_score : float
        face-presence score of the face mesh, in [0, 1].
    box : tuple of 4 float
        ``x0, y0, x1, y1`` of the face (its 468 points' box) in photo pixels.
    curves : dict[str, (m, 2) float]
        curve name (:data:`photomodel.modeling.generic_mesh.CURVE_LANDMARKS`) → the face mesh's
        contour drawn end to end, photo pixels: the eyelids and outer lips
        (:func:`photomodel.landmarks.mapping.curves_from_mesh`); none in a profile.
    """

    points: dict[str, np.ndarray]
    confidence: dict[str, float]
    preset: str
    yaw_deg: float
    faces_found: int
    face_score: float
    box: tuple[float, float, float, float]
    curves: dict[str, np.ndarray] = field(default_factory=dict)


def detect_468(image: np.ndarray, *, name: str = "the photo") -> tuple[np.ndarray, float, tuple]:
    """The 468 face-mesh points of the largest face in a photo.

    Parameters
    ----------
    image : (H, W, 3) uint8
        RGB photo, already EXIF-rotated.
    name : str
        how an error names the photo.

    Returns
    -------
    points : (468, 3) float
        ``u, v`` photo pixels and MediaPipe's relative depth ``z`` (same pixel scale).
    score : float
        face-presence score in [0, 1].
    box : tuple of 4 float
        ``x0, y0, x1, y1`` photo pixels.

    Raises
    ------
    photomodel.errors.NoFaceFound
        when no face is found (the caller falls back to clicks by hand).
    """
    face = _detect_468(image, name=name)
    return face.points, face.score, face.box


def placement_from_face(face: Face468, feature_names: Sequence[str], image: np.ndarray | None = None) -> Placement:
    """The :class:`Placement` of the named features from one detected face mesh; with the photo
    ``image``, the jaw on its edges (:mod:`photomodel.landmarks.outline`)."""
    yaw = estimate_yaw_deg(face.points)
    points, confidence = features_from_mesh(face.points, yaw, feature_names, image)
    return Placement(
        points=points,
        confidence=confidence,
        preset=preset_for_yaw(yaw),
        yaw_deg=yaw,
        faces_found=face.faces_found,
        face_score=face.score,
        box=face.box,
        curves=curves_from_mesh(face.points, yaw),
    )


def place_landmarks(image: np.ndarray, feature_names: Sequence[str], *, name: str = "the photo") -> Placement:
    """Place the project's features in a photo automatically.

    Parameters
    ----------
    image : (H, W, 3) uint8
        RGB photo, already EXIF-rotated; points come back in its pixels.
    feature_names : sequence of str
        the project's feature names (``eye_r_outer``, ``jaw_03`` …).
    name : str
        how an error names the photo (its file name).

    Returns
    -------
    Placement

    Raises
    ------
    photomodel.errors.NoFaceFound
        when no face is found: click the photo's landmarks by hand.
    """
    return placement_from_face(_detect_468(image, name=name), feature_names, image)


def place_landmarks_near(image: np.ndarray, feature_names: Sequence[str], box: tuple, angle: float) -> Placement | None:
    """:func:`place_landmarks` from one face-mesh pass on the crop around ``box`` turned by
    ``angle`` (:func:`photomodel.landmarks.detect.detect_468_near`: where a tracked face is, no
    face detector); None when the crop holds no face."""
    face = detect_468_near(image, box, angle)
    return None if face is None else placement_from_face(face, feature_names)
