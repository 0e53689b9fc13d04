"""An ARKit-style rig for a modeled face: ICT-FaceKit's expressions on the person's fitted neutral.

:class:`RigBuilder` holds what every rig of the generic mesh shares — ICT registered onto the
generic mesh (:func:`load_registration`, cached on disk), ICT's neutral, expressions and identity
modes resampled onto it, and the factorised deformation transfer — and :meth:`RigBuilder.rig`
makes one person's rig in three steps:

1. **Source nearest the person.** Deformation transfer's error grows with the difference between
   the source's and the target's neutral (a gradient ``T_j`` applied to an edge that the
   identity changed), so the source neutral is moved towards the person first: ICT's resampled
   neutral ``S⁰`` is aligned rigidly onto the person's ``P⁰`` over the face (Kabsch), then its
   first :data:`IDENTITY_MODES` identity modes are fitted by ridge least squares (twice: the
   second alignment is that of the fitted identity, :data:`ALIGN_ROUNDS`),

       ĉ = argmin_c ‖S⁰ + I c − P⁰‖²_face + λ ‖c‖²        (λ = :data:`IDENTITY_RIDGE` mm²:
                                                          ICT's prior c ~ N(0, 1), ~1 mm noise)

   and ``S⁰ + I ĉ`` is the source neutral. ICT's expressions are additive (the same ``Dᵉ`` for
   every identity), so the source expressions are ``S⁰ + I ĉ + Dᵉ``.
2. **Deformation transfer** (:mod:`photomodel.rig.transfer`) onto ``P⁰``.
3. **Support.** Each shape is kept where ICT's shape moves the skin: the transferred
   displacement is multiplied by ``smoothstep(|Dᵉ_i|; 0.05, 0.5 mm)`` (:data:`SUPPORT_MM`),
   so that the least-squares solve's small drift over the whole face (tenths of a millimetre)
   does not make an eye blink move the chin.

Shapes are ARKit's (:data:`photomodel.rig.ict.RIG_SHAPES`; ``browInnerUp`` and ``cheekPuff``
the sums of ICT's halves; ``Left`` is the subject's left), displacements in mm in the person's
head frame.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from photomodel.alignment import similarity_transform
from photomodel.data.cache import cached_arrays
from photomodel.data.keys import code_key
from photomodel.modeling.generic_mesh import GenericMesh
from photomodel.rig.ict import RIG_SHAPES, IctModel, arkit_deltas, load_ict
from photomodel.rig.registration import Registration, register_ict
from photomodel.rig.transfer import DeformationTransfer, soft_triangles

__all__ = [
    "Rig",
    "RigBuilder",
    "load_registration",
    "registration_key",
    "IDENTITY_MODES",
    "IDENTITY_RIDGE",
    "SUPPORT_MM",
]

#: ICT identity modes fitted to the person before the transfer (of the 100 shipped).
IDENTITY_MODES = 50
#: Rounds of (rigid alignment, identity fit).
ALIGN_ROUNDS = 2
#: Ridge λ (mm²) of the identity fit.
IDENTITY_RIDGE = 1.0
#: A shape fades in between these source displacements (mm).
SUPPORT_MM = (0.05, 0.5)
#: Third-party packages whose numerics move the registration; their versions are part of its key.
REGISTRATION_PACKAGES = ("numpy", "scipy", "trimesh")


def registration_key(mesh: GenericMesh, ict: IctModel) -> str:
    """The cache key of ICT's registration onto ``mesh``: :func:`register_ict`'s code (its module and
    what it imports), the arrays it reads and :data:`REGISTRATION_PACKAGES`' versions."""
    inputs = (mesh.vertices, mesh.faces, mesh.landmarks, ict.neutral, ict.faces, ict.landmarks)
    return code_key(register_ict, inputs=inputs, packages=REGISTRATION_PACKAGES)


def load_registration(mesh: GenericMesh, ict: IctModel | None = None) -> Registration:
    """ICT registered onto ``mesh``, from the cache (``<cache>/ict_registration-<key>.npz``,
    :func:`registration_key`) or computed (~15 s) and cached."""
    ict = ict or load_ict()
    arrays = cached_arrays(
        "ict_registration",
        registration_key(mesh, ict),
        lambda: register_ict(ict, mesh.vertices, mesh.faces, mesh.landmarks).to_arrays(),
    )
    return Registration.from_arrays(arrays)


@dataclass
class Rig:
    """One person's blend shapes.

    Attributes
    ----------
    names : tuple of k str, ARKit's names.
    neutral : (n, 3) float mm, the person's neutral ``P⁰``.
    deltas : (k, n, 3) float mm, each shape's displacement from the neutral.
    report : dict, what the build measured (``identity_rms_mm``: the fitted source's distance
        to the person over the face before the transfer; ``landmark_rms_mm``: the registration's).
    """

    names: tuple
    neutral: np.ndarray
    deltas: np.ndarray
    report: dict = field(default_factory=dict)


class RigBuilder:
    """Rigs of the generic mesh's faces (see the module notes).

    Parameters
    ----------
    mesh : GenericMesh, the generic mesh (its faces, face mask and landmarks).
    ict : IctModel, optional (default: the shipped data).
    registration : Registration, optional (default: :func:`load_registration`).
    names : the ARKit shapes to make (default all of :data:`RIG_SHAPES`).
    """

    def __init__(
        self, mesh: GenericMesh, ict: IctModel | None = None, registration: Registration | None = None, names=RIG_SHAPES
    ):
        self.mesh = mesh
        self.ict = ict or load_ict()
        self.registration = registration or load_registration(mesh, self.ict)
        reg = self.registration
        self.names = tuple(names)
        self.source_neutral = reg.positions(self.ict.neutral)
        self.source_deltas = reg.displacements(arkit_deltas(self.ict, self.names))
        self.identity_modes = reg.displacements(self.ict.identities[:IDENTITY_MODES])
        self.face = mesh.face_mask & reg.covered
        anchors = ~reg.covered & ~mesh.face_mask
        soft = soft_triangles(self.source_neutral, mesh.faces, reg.covered)
        self.transfer = DeformationTransfer(mesh.faces, len(mesh.vertices), soft, anchors)
        lo, hi = SUPPORT_MM
        s = np.clip((np.linalg.norm(self.source_deltas, axis=2) - lo) / (hi - lo), 0.0, 1.0)
        self.support = s * s * (3.0 - 2.0 * s)  # (k, n) smoothstep

    def fitted_source(self, neutral: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Step 1: ``(S⁰ + I ĉ, R, ĉ)`` in the person's frame, ``R`` the rotation applied to ICT's shapes."""
        P0 = np.asarray(neutral, float)
        f = self.face
        c = np.zeros(len(self.identity_modes))
        for _ in range(ALIGN_ROUNDS):  # the pose of the identity fitted so far, then the identity again
            source = self.source_neutral + np.einsum("k,knd->nd", c, self.identity_modes)
            _, R, t = similarity_transform(source[f], P0[f], scale=False)
            S0 = self.source_neutral @ R.T + t
            modes = self.identity_modes @ R.T  # (K, n, 3)
            A = modes[:, f].reshape(len(modes), -1).T
            c = np.linalg.solve(A.T @ A + IDENTITY_RIDGE * np.eye(len(modes)), A.T @ (P0 - S0)[f].ravel())
        return S0 + np.einsum("k,knd->nd", c, modes), R, c

    def rig(self, neutral: np.ndarray) -> Rig:
        """The rig of the person whose fitted neutral (generic mesh's vertices, mm) is ``neutral``."""
        P0 = np.asarray(neutral, float)
        if P0.shape != self.mesh.vertices.shape:
            raise ValueError(
                f"the neutral must have the generic mesh's {len(self.mesh.vertices)} vertices (n, 3), got {P0.shape}"
            )
        S0, R, c = self.fitted_source(P0)
        D = self.source_deltas @ R.T
        deltas = self.transfer(S0, D, P0) * self.support[..., None]
        gap = np.sqrt(np.mean(np.sum((S0 - P0)[self.face] ** 2, axis=1)))
        report = {
            "identity_rms_mm": float(gap),
            "identity_modes": len(c),
            "landmark_rms_mm": self.registration.landmark_rms_mm,
            "landmark_rms_rigid_mm": self.registration.landmark_rms_rigid_mm,
        }
        return Rig(self.names, P0.copy(), deltas, report)
