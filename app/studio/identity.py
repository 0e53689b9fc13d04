"""New faces from dials: the multilinear people model's first identity modes as sliders (seed 000 §3, Eq. 5).

The people model (:class:`photomodel.people.multilinear.MultilinearModel`, the file of
:mod:`photomodel.people.model_file`) says a face of identity weights ``w2`` and expression weights ``w3``
as ``f = f̄ + Ǔ1 (C ×2 w2ᵀ ×3 w3ᵀ)``. The training people are the rows of its identity mode ``Ǔ2``,
whose columns ``e_k`` are the seed's identity knobs. :class:`IdentityFace` moves ``w2`` from the training
people's mean identity ``w̄2`` along :data:`IDENTITY_MODES` of them, each slider in units of the people's
spread along it (their standard deviation ``σ_k``, ±:data:`SIGMA_RANGE`):

    w2 = w̄2 + Σ_k s_k σ_k e_k

**Beyond the seed** (which takes the first columns): the columns offered are those that change the face
most over the people's spread, ``σ_k ‖C ×2 e_kᵀ‖_F`` (the core slice's norm is the mode-2 singular value),
largest first. ``Ǔ2`` comes from the SVD of a tensor centred on the mean *face*, not the mean *person*,
so one of its first columns is nearly the people's common part: on the 100-people model the third
column's spread is 0.003 where the others' are 0.1, and a slider along it does nothing. (The principal
directions of the centred rows are no better: with every person in the model ``Ǔ2`` is square and
orthogonal, its centred rows spread alike in every direction.)

All sliders at 0 give the mean identity, whose faces are — the model being linear in ``w2`` — the mean
of the training people's faces, expression by expression. The new face is the identity's neutral and
its 51 ARKit shapes (expression 0 and the others of ``expression_names``); :func:`save_new_face`
writes it as a project: the neutral as the fit of expression ``neutral`` (no photos) and the 51 shapes
as its rig (``source: "multilinear"``, format version 6), so it can take a performance through the rig
(the rig dock, ``export --glb``) and, with a borrowed texture, be cloned onto (``facestudio clone``).
No Qt.
"""

from __future__ import annotations

import shutil
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from app.studio.project_file import blank_project
from photomodel.errors import FaceStudioError, ProjectError
from photomodel.people.model_file import MODEL_PEOPLE, model_path
from photomodel.people.multilinear import MultilinearModel
from photomodel.project import ExpressionResult, Project, TextureResult, save_results, store_rig

__all__ = [
    "IDENTITY_MODES",
    "SIGMA_RANGE",
    "IdentityFace",
    "default_model_file",
    "load_identity_model",
    "save_new_face",
]

#: Identity modes offered as sliders (the first, largest ones).
IDENTITY_MODES = 8
#: Each slider spans ±this many standard deviations of the training people along its mode.
SIGMA_RANGE = 3.0


def default_model_file() -> Path:
    """The people model file the studio reads (:func:`photomodel.people.model_file.model_path`)."""
    return model_path(MODEL_PEOPLE)


def load_identity_model(path: str | Path | None = None) -> MultilinearModel:
    """The people model of ``path`` (default :func:`default_model_file`); :class:`FaceStudioError` saying
    how to build it when missing or unreadable (the studio never builds it: minutes of work)."""
    path = Path(path) if path is not None else default_model_file()
    if not path.is_file():
        raise FaceStudioError(
            f"the people model {path} is missing; build it once with: python -m photomodel.people.model_file"
        )
    try:
        return MultilinearModel.load(path)
    except ValueError as exc:
        raise FaceStudioError(str(exc)) from exc


@dataclass
class IdentityFace:
    """A face of the people model at slider values along its first identity modes (see the module notes).

    Attributes
    ----------
    model : MultilinearModel
    values : (k,) float, the sliders in standard deviations (k ≤ :data:`IDENTITY_MODES`), 0 = the mean.
    """

    model: MultilinearModel
    values: np.ndarray = field(default=None)

    def __post_init__(self):
        rows = self.model.identity_rows
        self._mean = rows.mean(axis=0)
        spread = rows.std(axis=0)
        impact = spread * np.sqrt(np.einsum("abc,abc->b", self.model.core, self.model.core))
        order = np.argsort(-impact, kind="stable")
        order = order[impact[order] > 1e-3 * impact[order[0]]][:IDENTITY_MODES]
        k = len(order)
        self.values = np.zeros(k) if self.values is None else np.asarray(self.values, float).reshape(k)
        self.columns = order  # the Ǔ2 column of each slider
        self._directions = np.eye(rows.shape[1])[order]
        self._sigma = spread[order]
        self._neutral: np.ndarray | None = None

    @property
    def modes(self) -> int:
        return len(self.values)

    @property
    def sigma(self) -> np.ndarray:
        """(k,) the training people's standard deviation along each slider's column."""
        return self._sigma

    @property
    def directions(self) -> np.ndarray:
        """(k, r2): the unit vectors ``e_k`` of the sliders' columns of ``Ǔ2`` (:attr:`columns`)."""
        return self._directions

    def identity(self) -> np.ndarray:
        """(r2,) the identity weights ``w̄2 + Σ s_k σ_k e_k``."""
        return self._mean + (self.values * self._sigma) @ self._directions

    def set_value(self, mode: int, value: float) -> bool:
        """Set slider ``mode`` (clipped to ±:data:`SIGMA_RANGE`); returns whether it changed."""
        if not 0 <= mode < self.modes:
            raise ValueError(f"identity mode {mode} is not one of the {self.modes} sliders")
        v = float(np.clip(value, -SIGMA_RANGE, SIGMA_RANGE))
        if self.values[mode] == v:
            return False
        self.values[mode] = v
        self._neutral = None
        return True

    def reset(self) -> bool:
        """Every slider back to 0 (the mean identity); returns whether any changed."""
        if not np.any(self.values):
            return False
        self.values[:] = 0.0
        self._neutral = None
        return True

    def neutral(self) -> np.ndarray:
        """(n, 3) mm: the neutral face (expression 0) at :meth:`identity`, Eq. 5; kept until a slider moves."""
        if self._neutral is None:
            self._neutral = self.model.face(self.identity(), self.model.expression_rows[0]).reshape(-1, 3)
        return self._neutral

    def faces(self) -> np.ndarray:
        """(E, n, 3) mm: every expression of the model at :meth:`identity` (expression 0 the neutral)."""
        m = self.model
        g = np.einsum("abc,b,ec->ea", m.core, self.identity(), m.expression_rows)  # (E, r1)
        return (m.mean + g @ m.vertex_basis.T).reshape(len(m.expression_rows), -1, 3)


def save_new_face(face: IdentityFace, target: str | Path, mesh, texture_from: Project | None = None) -> Path:
    """Write ``face`` as a new project at ``target`` (``<name>.facestudio.json``; results beside it) and
    return the file written.

    The project (name: the file's stem) has the generic ``mesh``'s pose features and curves, one
    expression ``neutral`` without photos whose fit is the face's neutral (``results/neutral.obj|.ply``),
    and a rig of the model's other expressions as displacements of it (``results/rig.npz``, source
    ``"multilinear"``). ``texture_from``: a project whose first textured expression's cylindrical texture is
    copied as the neutral's (borrowed skin: tracking and cloning need a texture), none when None or it
    has none. :class:`ProjectError` when the face's mesh is not ``mesh``'s.
    """
    target = Path(target).absolute()
    faces = face.faces()
    if faces.shape[1] != len(mesh.vertices):
        raise ProjectError(
            f"the people model has {faces.shape[1]} vertices, the generic mesh {len(mesh.vertices)}: rebuild the model"
        )
    name = target.name.split(".")[0] or "new_face"
    project = blank_project(mesh, name)
    neutral_name = project.expressions[0].name
    V = faces[0]
    report = {
        "people_model": {
            "identity_sigmas": [round(float(v), 4) for v in face.values],
            "people": len(face.model.people),
            "ranks": list(face.model.ranks),
        }
    }
    project.expressions[0].result = ExpressionResult(
        points_3d={f.name: V[f.vertex] for f in project.features}, report=report
    )
    project.path = target
    target.parent.mkdir(parents=True, exist_ok=True)
    names = list(face.model.expression_names[1:])
    store_rig(project, neutral=neutral_name, names=names, deltas=faces[1:] - V, report=report, source="multilinear")
    texture = _borrowed_texture(texture_from, target.parent)
    if texture is not None:
        project.expressions[0].result.texture = texture
    return save_results(project, target, fits={neutral_name: V}, faces=mesh.faces)


def _borrowed_texture(source: Project | None, folder: Path) -> TextureResult | None:
    """The first textured expression's texture of ``source``, its image copied to ``folder/results``."""
    if source is None:
        return None
    for e in source.expressions:
        tex = None if e.result is None else e.result.texture
        if tex is not None and source.resolve(tex.image).is_file():
            dst = folder / "results" / "neutral_texture.png"
            dst.parent.mkdir(parents=True, exist_ok=True)
            shutil.copyfile(source.resolve(tex.image), dst)
            report = {k: v for k, v in tex.report.items() if k == "cylinder"}
            report["borrowed_from"] = f"{source.path}: {e.name}"
            return TextureResult(size=tex.size, image="results/neutral_texture.png", report=report)
    return None
