"""A performance moved between two people through their rigs predicted by the multilinear model.

Seed 000 (Vlasic et al. 2005) transfers a performance by fitting the source's expression weights ``w3``
with the source's identity and re-synthesising with the target's identity (its §5 and Eq. 5). Our model's
expression mode is ARKit's 51 shapes (:mod:`photomodel.people.dataset`), so a person's identity weights
give their whole rig, ``D_s = Ǔ1 (C ×2 w2ᵀ ×3 (u_{1+s} − u_0)ᵀ)``, and :func:`photomodel.people.personal_rig.
predict_rig` places each person in the identity space from their neutral and photographed expressions
(seed 000 §5.1's linear fit), keeping every shape photographed on its own as photographed. The clone is

    a = argmin ‖(x − P⁰_A) − Σ_s a_s D^A_s‖² over the face         (A's frame in A's rig, least squares)
    x_B = P⁰_B + Σ_s a_s D^B_s                                     (the same weights on B's rig)

one linear map per pair: ``x_B = P⁰_B + (x − P⁰_A)_face · pinv(D^A_face) · D^B`` (:class:`RigClone`).

**Beyond the seed:** the seed fits ``w3`` in the model's continuous expression space and rebuilds the
whole face with the target's model; here the weights are the named shapes' (the model's expression rows),
the target's displacement is added to B's own neutral and the photographed shapes replace the model's
(what §4.3's imputation keeps: known cells are data). Measured (2026-12-05) on 3 × 50 pairs of 30 of the
model's own people with a model of the other 70 (never the benchmark's people): 0.31 / 0.43 / 0.34 mm
for the seed's route in the model's coordinates (identities fitted to the own sets, ridge 0.1), 0.115 /
0.134 / 0.119 mm this way (displacement copy 0.36 / 0.56 / 0.44). The error left is mostly B's shapes
that were not photographed (0.087 / 0.084 / 0.079 mm with the true weights on B's predicted rig), the
rest A's weights; weights held in [0, 1] (ARKit's range, solved by a box-constrained least squares)
gained 5 % more (0.110 / 0.126 / 0.113 mm) at the cost of an iterative solve per frame: not kept.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from photomodel.people.multilinear import MultilinearModel
from photomodel.people.personal_rig import predict_rig

__all__ = ["RigClone"]


@dataclass
class RigClone:
    """The map of A's faces onto B (see the module notes); built by :meth:`between`, called on frames.

    Attributes
    ----------
    neutral_a, neutral_b : (d,) float mm, the two neutrals (d = 3n).
    weights_of : (d_face, 51) float, ``pinv(D^A_face)ᵀ``: A's displacement over the face → shape weights.
    rig_b : (51, d) float mm, B's shapes ``D^B``.
    face : (d,) bool, the coordinates of the face (where A's frames are fitted).
    """

    neutral_a: np.ndarray
    neutral_b: np.ndarray
    weights_of: np.ndarray
    rig_b: np.ndarray
    face: np.ndarray

    @classmethod
    def between(
        cls,
        model: MultilinearModel,
        neutral_a: np.ndarray,
        expressions_a: dict,
        neutral_b: np.ndarray,
        expressions_b: dict,
        face_mask: np.ndarray,
    ) -> RigClone:
        """The clone of A onto B: neutrals (n, 3) mm, photographed expressions ``{name: (n, 3) mm}`` in
        each neutral's head frame (an ARKit name is that shape done fully, any other name a mix the
        model solves for, :func:`predict_rig`), ``face_mask`` (n,) bool where A's frames are fitted."""
        rig_a = predict_rig(model, neutral_a, expressions_a).deltas.reshape(-1, np.size(neutral_a))
        rig_b = predict_rig(model, neutral_b, expressions_b).deltas.reshape(-1, np.size(neutral_b))
        face = np.repeat(np.asarray(face_mask, bool), 3)
        if not face.any():
            raise ValueError("the face mask holds no vertex")
        weights_of = np.linalg.pinv(rig_a[:, face])  # (d_face, 51)
        return cls(np.ravel(neutral_a).astype(float), np.ravel(neutral_b).astype(float), weights_of, rig_b, face)

    def weights(self, frames: np.ndarray) -> np.ndarray:
        """(f, 51): A's frames (f, d) mm said in A's rig (least squares over the face)."""
        return (np.asarray(frames, float)[:, self.face] - self.neutral_a[self.face]) @ self.weights_of

    def __call__(self, frames: np.ndarray) -> np.ndarray:
        """(f, d) mm: A's frames (f, d) on B."""
        return self.neutral_b + self.weights(frames) @ self.rig_b
