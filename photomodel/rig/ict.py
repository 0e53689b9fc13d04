"""ICT-FaceKit's face model as Face Studio ships it, named by ARKit's 52 blend shapes.

The data (``ict_facekit.npz``, converted once by :mod:`photomodel.rig.make_ict_data` from the
public ICT-FaceKit repository, MIT licence, © 2020 USC Institute for Creative Technologies) is
ICT's *full face area* (9409 vertices): a neutral head, 53 expression shapes named like ARKit's
and ICT's identity PCA modes, all as displacements in millimetres, and the 68 iBUG landmark
vertices. ICT's linear model is

    X(c, w) = N + Σ_k c_k I_k + Σ_e w_e D_e,        c ~ N(0, 1)

with ``N`` (9409, 3) the neutral, ``I_k`` the identity modes at one standard deviation and ``D_e``
the expression displacements (the same for every identity).

ARKit names
-----------
ARKit's 52 names in order are :data:`photomodel.exchange.livelink.ARKIT_SHAPES` (the Live Link CSV's
columns; a file format below the rig). ICT names the sides ``_L``/``_R``; ARKit ``…Left``/``…Right``.
Both mean the **subject's** left and right (ICT's ``eyeBlink_L`` closes the eye at ``+x``, the
subject's left in our head frame too, :mod:`photomodel.camera`), so ``eyeBlink_L`` → ``eyeBlinkLeft``. ICT splits
``browInnerUp`` and ``cheekPuff`` into halves: ARKit's shape is the sum of the two. ARKit's
``tongueOut`` has no ICT counterpart (and Face Studio's mesh has no tongue), so a rig has the
other 51 (:data:`RIG_SHAPES`); the Live Link CSV still carries its column.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path

import numpy as np

from photomodel.exchange.livelink import ARKIT_SHAPES

__all__ = ["ARKIT_SHAPES", "RIG_SHAPES", "ICT_DATA_PATH", "IctModel", "load_ict", "arkit_source", "arkit_deltas"]

#: The shapes a rig made from ICT-FaceKit has: ARKit's without ``tongueOut``.
RIG_SHAPES = tuple(s for s in ARKIT_SHAPES if s != "tongueOut")

#: ARKit shapes whose Left/Right is a direction, not a side: ICT spells them the same.
_WHOLE = ("jawLeft", "jawRight", "mouthLeft", "mouthRight")

ICT_DATA_PATH = Path(__file__).with_name("ict_facekit.npz")


@dataclass(frozen=True)
class IctModel:
    """ICT-FaceKit's face area (see the module notes).

    Attributes
    ----------
    neutral : (n, 3) float, mm, ICT's frame (``+x`` subject's left, ``+y`` up, ``+z`` forward).
    faces : (f, 3) int, triangles of the face area.
    expression_names : tuple of 53 str, ICT's names (``_L``/``_R``).
    expressions : (53, n, 3) float, displacements ``D_e``, mm.
    identities : (k, n, 3) float, identity modes ``I_k`` at one standard deviation, mm.
    landmarks : (68,) int, the iBUG-68 vertices, in iBUG order.
    """

    neutral: np.ndarray
    faces: np.ndarray
    expression_names: tuple
    expressions: np.ndarray
    identities: np.ndarray
    landmarks: np.ndarray

    def identity(self, coefficients) -> np.ndarray:
        """(n, 3) mm, the neutral of the identity with PCA ``coefficients`` (k',) (k' ≤ k)."""
        c = np.asarray(coefficients, float)
        return self.neutral + np.einsum("k,knd->nd", c, self.identities[: len(c)])


@lru_cache(maxsize=1)
def load_ict(path: str | Path = ICT_DATA_PATH) -> IctModel:
    """The shipped ICT-FaceKit data (cached: ~40 MB as float64)."""
    with np.load(path) as d:
        return IctModel(
            neutral=d["neutral"].astype(float),
            faces=d["faces"].astype(np.int64),
            expression_names=tuple(str(s) for s in d["expression_names"]),
            expressions=d["expressions"].astype(float),
            identities=d["identities"].astype(float),
            landmarks=d["landmarks"].astype(np.int64),
        )


def arkit_source(name: str) -> tuple[str, ...]:
    """ICT's expressions whose sum is ARKit's shape ``name`` (one, or the two halves)."""
    if name not in RIG_SHAPES:
        raise ValueError(f"{name!r} is not an ARKit shape an ICT rig has (one of {', '.join(RIG_SHAPES)})")
    if name in ("browInnerUp", "cheekPuff"):
        return (f"{name}_L", f"{name}_R")
    if name in _WHOLE:
        return (name,)
    for side, tag in (("Left", "_L"), ("Right", "_R")):
        if name.endswith(side):
            return (name[: -len(side)] + tag,)
    return (name,)


def arkit_deltas(model: IctModel, names=RIG_SHAPES) -> np.ndarray:
    """(len(names), n, 3) mm, ICT's displacement of each ARKit shape (halves summed)."""
    index = {e: i for i, e in enumerate(model.expression_names)}
    return np.stack([sum(model.expressions[index[e]] for e in arkit_source(s)) for s in names])
