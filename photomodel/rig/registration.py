"""ICT-FaceKit's head registered onto Face Studio's generic mesh: where each generic vertex lies on ICT.

The rig (:mod:`photomodel.rig.transfer`) needs ICT's expressions on the generic mesh's vertices.
:func:`register_ict` finds, for every generic-mesh vertex ``j``, a point on ICT's face surface —
a triangle ``τ_j`` and barycentric coordinates ``β_j`` — so that any ICT shape ``Y`` (9409, 3)
(its neutral, an identity, an expression) is *resampled* onto the generic mesh as

    Ŷ_j = s R (Σ_c β_jc Y_τj,c) + t,        i.e. Ŷ = s R (B Y) + t          (B sparse, (n, 9409))

in our head frame. The correspondence is found in three steps:

1. **Similarity** ``(s, R, t)`` of ICT's 68 landmark vertices onto the generic mesh's
   (Umeyama, :func:`photomodel.alignment.similarity_transform`); both use iBUG's order and both
   frames put the subject's left at ``+x``.
2. **Non-rigid fit** of the ICT surface onto the generic one (ICP-style): a smooth warp
   ``W(x) = x + f(x)``, ``f`` the radial-basis interpolant of Pighin et al. (2002, Eq. 3,
   :mod:`photomodel.modeling.rbf`) with a ridge ``λ`` (:data:`RIDGE`) so that it *approximates*
   its centres: the 68 landmarks (targets: the generic landmarks) and a spread of ICT vertices
   (targets: the nearest point of the generic surface, kept when within :data:`PAIR_MM` and the
   normals agree), :data:`ICP_ROUNDS` rounds, each starting from the previous warp.
3. **Closest points**: each generic vertex's nearest point on the warped ICT surface gives
   ``(τ_j, β_j)``; a vertex farther than :data:`COVER_MM` from it (the back of the head and
   the neck below ICT's face area) is not *covered*: ICT says nothing about it.

The landmark error printed by ``facestudio rig`` is the RMS distance between the warped ICT
landmarks and the generic ones after step 1 (``landmark_rms_rigid_mm``) and step 2
(``landmark_rms_mm``): the landmarks are approximated, not interpolated, so it measures how well
one smooth warp brings both definitions of the 68 points together.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

import numpy as np
import scipy.sparse as sparse

from photomodel.alignment import similarity_transform
from photomodel.closest_points import TriangleSurface, barycentric_coordinates
from photomodel.modeling.rbf import RBFInterpolant
from photomodel.rendering.renderer import vertex_normals
from photomodel.rig.ict import IctModel

__all__ = ["Registration", "register_ict", "ICP_ROUNDS", "PAIR_MM", "COVER_MM", "RIDGE"]

#: Rounds of closest-point pairing and warping.
ICP_ROUNDS = 4
#: A surface pair is used when the points are this close (mm) after the previous round…
PAIR_MM = 12.0
#: …and their normals within ~60° (cosine).
PAIR_NORMAL_COS = 0.5
#: ICT vertices used as warp centres (every k-th of the face area, plus the landmarks).
CENTRE_STRIDE = 12
#: Ridge of the warp's kernel matrix: ~1 mm of slack against a 1.6 m kernel (see rbf.py).
RIDGE = 5e-4
#: A generic vertex farther than this (mm) from the warped ICT surface is not covered.
COVER_MM = 4.0


@dataclass(frozen=True)
class Registration:
    """Where each generic-mesh vertex lies on ICT's face (see the module notes).

    Attributes
    ----------
    triangles : (n,) int, the ICT triangle ``τ_j`` of each generic vertex.
    barycentric : (n, 3) float, ``β_j``.
    covered : (n,) bool, the vertex lies within :data:`COVER_MM` of the warped ICT surface.
    scale, rotation, translation : float, (3, 3), (3,): ICT's frame → ours, ``x ↦ s R x + t``.
    landmark_rms_rigid_mm, landmark_rms_mm : float, the landmark error after steps 1 and 2.
    distance_mm : (n,) float, each generic vertex's distance to the warped ICT surface.
    """

    triangles: np.ndarray
    barycentric: np.ndarray
    covered: np.ndarray
    scale: float
    rotation: np.ndarray
    translation: np.ndarray
    landmark_rms_rigid_mm: float
    landmark_rms_mm: float
    distance_mm: np.ndarray
    ict_faces: np.ndarray
    n_ict: int

    _ARRAYS: ClassVar[tuple] = (
        "triangles",
        "barycentric",
        "covered",
        "rotation",
        "translation",
        "distance_mm",
        "ict_faces",
    )
    _SCALARS: ClassVar[tuple] = ("scale", "landmark_rms_rigid_mm", "landmark_rms_mm", "n_ict")

    def to_arrays(self) -> dict[str, np.ndarray]:
        """The registration as named arrays (for an ``.npz`` cache)."""
        return {k: np.asarray(getattr(self, k)) for k in self._ARRAYS + self._SCALARS}

    @classmethod
    def from_arrays(cls, arrays: dict[str, np.ndarray]) -> Registration:
        """The inverse of :meth:`to_arrays`."""
        kw = {k: np.asarray(arrays[k]) for k in cls._ARRAYS}
        kw.update({k: arrays[k].item() for k in cls._SCALARS})
        return cls(**kw)

    def matrix(self) -> sparse.csr_matrix:
        """``B`` (n, n_ict) sparse: row ``j`` holds ``β_j`` at the corners of ``τ_j``."""
        n = len(self.triangles)
        cols = self.ict_faces[self.triangles]
        return sparse.csr_matrix(
            (self.barycentric.ravel(), (np.repeat(np.arange(n), 3), cols.ravel())), shape=(n, self.n_ict)
        )

    def positions(self, shape: np.ndarray) -> np.ndarray:
        """(n, 3) mm in our frame: an ICT shape (n_ict, 3) (positions, ICT frame) resampled."""
        return self.displacements(shape) + self.translation

    def displacements(self, delta: np.ndarray) -> np.ndarray:
        """(n, 3) or (k, n, 3) mm in our frame: ICT displacements (…, n_ict, 3) resampled (``s R B D``)."""
        d = np.asarray(delta, float)
        corners = d[..., self.ict_faces[self.triangles], :]  # (…, n, 3 corners, 3)
        resampled = np.einsum("...nci,nc->...ni", corners, self.barycentric)
        return self.scale * resampled @ self.rotation.T


def _warp(centres: np.ndarray, targets: np.ndarray, points: np.ndarray) -> np.ndarray:
    """``points`` moved by the ridge RBF that takes ``centres`` towards ``targets``."""
    f = RBFInterpolant.fit(centres, targets - centres, smoothing=RIDGE)
    return points + f(points)


def register_ict(
    ict: IctModel, vertices: np.ndarray, faces: np.ndarray, landmarks: np.ndarray, rounds: int = ICP_ROUNDS
) -> Registration:
    """Register ICT's face onto a mesh with iBUG-68 landmark vertices (see the module notes).

    Parameters
    ----------
    ict : IctModel
    vertices : (n, 3) float mm, faces : (f, 3) int — the generic mesh (head frame).
    landmarks : (68,) int, its iBUG-68 vertices.
    rounds : int, ICP rounds of step 2.

    Returns
    -------
    Registration
    """
    target_lm = vertices[landmarks]
    s, R, t = similarity_transform(ict.neutral[ict.landmarks], target_lm)
    X = s * ict.neutral @ R.T + t
    rigid_rms = float(np.sqrt(np.mean(np.sum((X[ict.landmarks] - target_lm) ** 2, axis=1))))
    generic = TriangleSurface(vertices, faces)
    sample = np.setdiff1d(np.arange(0, len(X), CENTRE_STRIDE), ict.landmarks)
    W = X
    for _ in range(rounds):
        closest, distance, tri = generic.closest(W[sample])
        n_w = vertex_normals(W, ict.faces)[sample]
        keep = (distance < PAIR_MM) & (np.sum(n_w * generic.normals_at(closest, tri), axis=1) > PAIR_NORMAL_COS)
        centres = np.concatenate([X[ict.landmarks], X[sample[keep]]])
        W = _warp(centres, np.concatenate([target_lm, closest[keep]]), X)
    lm_rms = float(np.sqrt(np.mean(np.sum((W[ict.landmarks] - target_lm) ** 2, axis=1))))
    closest, distance, tri = TriangleSurface(W, ict.faces).closest(vertices)
    bary = barycentric_coordinates(closest, W[ict.faces[tri]])
    bary /= bary.sum(axis=1, keepdims=True)
    return Registration(
        triangles=tri.astype(np.int64),
        barycentric=bary,
        covered=distance < COVER_MM,
        scale=float(s),
        rotation=R,
        translation=t,
        landmark_rms_rigid_mm=rigid_rms,
        landmark_rms_mm=lm_rms,
        distance_mm=distance,
        ict_faces=ict.faces,
        n_ict=len(ict.neutral),
    )
