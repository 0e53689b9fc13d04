"""The people the multilinear model learns from: ICT-FaceKit identities, each with ARKit's 51 shapes.

Seed 000 (Vlasic et al. 2005, §4.1) builds its model from scans of people in the same expressions.
We have no scans; instead we *sample* people from ICT-FaceKit's identity PCA (:mod:`photomodel.rig.ict`,
``c ~ N(0, 1)`` over its 100 modes) and give each the 51 ARKit shapes by our own deformation transfer
(:class:`photomodel.rig.build.RigBuilder`, the rig ``facestudio rig`` makes), so every person of the
data set is a face the studio could have rigged. This is beyond the seed (its data are real scans); the
person's expressions depend on their identity only through the transfer (ICT's own expressions are
additive), which is what the model then learns.

On the generic mesh (:mod:`photomodel.modeling.generic_mesh`, ``n`` vertices): person ``p``'s neutral is

    P⁰_p = G + φ ⊙ (s R B Σ_k c_pk I_k)           (the generic head plus ICT's identity offset)

with ``G`` the generic mesh, ``s R B`` ICT's registration (:mod:`photomodel.rig.registration`) and ``φ``
(n,) fading the offset out (smoothstep) between 2 and 4 mm (:data:`FADE_MM`) from ICT's warped surface
(the back of the head ICT does not cover keeps the generic shape). Their shapes are
``RigBuilder.rig(P⁰_p).deltas`` (51, n, 3) mm.

The data tensor (seed 000, Fig. 3) is ``T[:, p, e]`` = vertices (3n) × people × expressions, expression 0
the neutral and ``1 + s`` ARKit shape ``s`` (:data:`EXPRESSIONS`). Two disjoint sets are drawn from
seeded generators: the *model* people (the multilinear model is built from them) and the *held-out*
people (the benchmark's). A set is cached (``cache_dir()/people-<kind>-<count>-<version>.npz``, about
2.5 MB a person: neutral float32, deltas float16 — 0.01 mm steps at the largest 20 mm displacement);
building one costs a rig per person (~5 s of one core).
"""

from __future__ import annotations

import io
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from photomodel.data.cache import cache_dir
from photomodel.exchange.files import atomic_write_bytes
from photomodel.modeling.generic_mesh import generic_mesh_key, load_generic_mesh
from photomodel.rig.build import RigBuilder
from photomodel.rig.ict import RIG_SHAPES

__all__ = [
    "EXPRESSIONS",
    "DATASET_VERSION",
    "FADE_MM",
    "SEEDS",
    "People",
    "identity_neutral",
    "build_people",
    "load_people",
    "people_cache_path",
]

#: The expression mode: the neutral, then ARKit's 51 shapes an ICT rig has.
EXPRESSIONS = ("neutral", *RIG_SHAPES)
#: Change when the recipe changes the cached data.
DATASET_VERSION = "1"
#: ICT's identity offset fades out between these distances (mm) from its warped surface.
FADE_MM = (2.0, 4.0)
#: Seeds of the two sets of people (disjoint draws).
SEEDS = {"model": 37_000, "held_out": 37_001}


@dataclass
class People:
    """Several people on the generic mesh, each with the 51 ARKit shapes.

    Attributes
    ----------
    names : tuple of p str.
    neutrals : (p, n, 3) float mm.
    deltas : (p, 51, n, 3) float mm, ARKit shape displacements (:data:`photomodel.rig.ict.RIG_SHAPES`).
    faces : (m, 3) int, the generic mesh's triangles.
    face_mask : (n,) bool, the face area (where errors are measured).
    """

    names: tuple
    neutrals: np.ndarray
    deltas: np.ndarray
    faces: np.ndarray
    face_mask: np.ndarray

    def tensor(self) -> np.ndarray:
        """(3n, p, 52) float: seed 000's data tensor, ``T[:, p, 0]`` the neutral, ``T[:, p, 1 + s]`` shape ``s``."""
        shapes = np.concatenate([self.neutrals[:, None], self.neutrals[:, None] + self.deltas], axis=1)
        p, e, n, _ = shapes.shape
        return shapes.reshape(p, e, 3 * n).transpose(2, 0, 1)

    def subset(self, index) -> People:
        """The people ``index`` (a sequence of ints)."""
        idx = np.asarray(index, int)
        return People(
            tuple(self.names[i] for i in idx), self.neutrals[idx], self.deltas[idx], self.faces, self.face_mask
        )

    def __len__(self) -> int:
        return len(self.names)


def identity_neutral(builder: RigBuilder, coefficients: np.ndarray) -> np.ndarray:
    """(n, 3) mm: the generic head with ICT's identity offset ``Σ c_k I_k`` (see the module notes)."""
    c = np.asarray(coefficients, float)
    reg = builder.registration
    offset = reg.displacements(np.einsum("k,knd->nd", c, builder.ict.identities[: len(c)]))
    lo, hi = FADE_MM
    s = np.clip((hi - reg.distance_mm) / (hi - lo), 0.0, 1.0)
    return builder.mesh.vertices + (s * s * (3.0 - 2.0 * s))[:, None] * offset


def build_people(
    count: int, seed: int, builder: RigBuilder | None = None, progress: Callable[[int, int], None] | None = None
) -> People:
    """``count`` ICT identities drawn with ``seed`` (``c ~ N(0, 1)``, all of ICT's modes), rigged."""
    builder = builder or RigBuilder(load_generic_mesh())
    rng = np.random.default_rng(seed)
    k = len(builder.ict.identities)
    neutrals, deltas = [], []
    for i in range(count):
        P0 = identity_neutral(builder, rng.standard_normal(k))
        neutrals.append(P0)
        deltas.append(builder.rig(P0).deltas)
        if progress:
            progress(i + 1, count)
    return People(
        names=tuple(f"ict-{seed}-{i:03d}" for i in range(count)),
        neutrals=np.array(neutrals),
        deltas=np.array(deltas),
        faces=builder.mesh.faces,
        face_mask=builder.mesh.face_mask.copy(),
    )


def people_cache_path(kind: str, count: int) -> Path:
    """Where the set ``kind`` (``"model"`` or ``"held_out"``) of ``count`` people is cached."""
    # keyed on the generic mesh's code key (the mesh the rigs are on) and this module's hand-bumped
    # version: the rigs of 130 people take ~20 min, too dear to rebuild on any edit of the code below
    return cache_dir() / f"people-{kind}-{count}-{generic_mesh_key()}-{DATASET_VERSION}.npz"


def load_people(kind: str, count: int, progress: Callable[[int, int], None] | None = None) -> People:
    """The set ``kind`` of ``count`` people from the cache, or built (``count`` rigs) and cached."""
    if kind not in SEEDS:
        raise ValueError(f"kind must be one of {sorted(SEEDS)}, got {kind!r}")
    path = people_cache_path(kind, count)
    if path.is_file():
        try:
            with np.load(path, allow_pickle=False) as z:
                return People(
                    names=tuple(str(s) for s in z["names"]),
                    neutrals=z["neutrals"].astype(float),
                    deltas=z["deltas"].astype(float),
                    faces=z["faces"].astype(np.int64),
                    face_mask=z["face_mask"].astype(bool),
                )
        except (OSError, ValueError, KeyError, EOFError):
            pass  # unreadable: build it again
    people = build_people(count, SEEDS[kind], progress=progress)
    people.neutrals = people.neutrals.astype(np.float32).astype(float)  # as a reload gives them
    people.deltas = people.deltas.astype(np.float16).astype(float)
    buf = io.BytesIO()
    np.savez(
        buf,
        names=np.array(people.names),
        neutrals=people.neutrals.astype(np.float32),
        deltas=people.deltas.astype(np.float16),
        faces=people.faces.astype(np.int32),
        face_mask=people.face_mask,
    )
    path.parent.mkdir(parents=True, exist_ok=True)
    atomic_write_bytes(path, buf.getvalue())
    return people
