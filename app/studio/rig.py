"""The rig in the studio: the project's blend shapes on its fitted neutral, posed with weights.

:func:`read_rig` builds the :class:`RigState` the studio shows from the project's rig file and its
fits (the photographed expressions added as shapes, registered onto the neutral as tracking's face
model registers them); :func:`rig_job` makes a new rig in a worker as ``facestudio rig`` does
(:class:`photomodel.rig.build.RigBuilder`); :func:`store_new_rig` writes it with the project.
No Qt.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from photomodel.errors import FitError, ProjectError
from photomodel.project import load_rig_shapes, store_rig
from photomodel.rig.build import RigBuilder
from tracking.face_from_project import register_expression


@dataclass
class RigState:
    """The project's rig as the studio shows it: blend shapes on the fitted neutral, with weights.

    Attributes
    ----------
    neutral : str, the expression the rig was made on (``project.rig.neutral``).
    vertices : (N, 3) float mm, that expression's fitted mesh.
    names : list of str, the rig's ARKit shapes, then the photographed expressions.
    deltas : (k, N, 3) float mm, each shape's displacement from ``vertices``; a photographed
        expression's is its fitted mesh registered onto the neutral
        (:func:`tracking.face_from_project.register_expression`) minus the neutral.
    arkit : int, how many of ``names`` are the rig's (ARKit) shapes; the rest are photographed.
    weights : (k,) float in [0, 1].
    """

    neutral: str
    vertices: np.ndarray
    names: list
    deltas: np.ndarray
    arkit: int
    weights: np.ndarray

    def posed(self) -> np.ndarray:
        """The neutral plus Σ wᵢ·Δᵢ."""
        used = np.flatnonzero(self.weights)
        if not len(used):
            return self.vertices
        return self.vertices + np.tensordot(self.weights[used], self.deltas[used], axes=1)

    def set_weight(self, name: str, weight: float) -> bool:
        """Set one shape's weight (clipped to [0, 1]); returns whether it changed."""
        if name not in self.names:
            raise ProjectError(f"the rig has no shape {name!r}")
        w = float(np.clip(weight, 0.0, 1.0))
        i = self.names.index(name)
        if self.weights[i] == w:
            return False
        self.weights[i] = w
        return True

    def reset(self) -> bool:
        """Every weight back to 0 (the neutral); returns whether any changed."""
        if not np.any(self.weights):
            return False
        self.weights[:] = 0.0
        return True


def read_rig(project, fits: dict, face_mask: np.ndarray) -> tuple[RigState | None, str | None]:
    """``(rig, problem)``: the project's rig on its fitted neutral with every weight 0, or None and
    why it cannot be shown (None, None: the project has no rig).

    Parameters
    ----------
    project : Project
    fits : dict expression → app.studio.fitting.FitState, the studio's fits.
    face_mask : (N,) bool, the generic mesh's face vertices (they weigh the registration).
    """
    record = project.rig
    if record is None:
        return None, None
    fit = fits.get(record.neutral)
    if fit is None or fit.vertices is None:
        return None, f"the rig's neutral {record.neutral!r} has no fitted mesh"
    try:
        names, deltas = load_rig_shapes(project)
    except ProjectError as exc:
        return None, str(exc)
    if deltas.shape[1:] != fit.vertices.shape:
        return None, f"the rig has {deltas.shape[1]} vertices, the fitted mesh {len(fit.vertices)}"
    extra_names, extra = photographed_deltas(project, fits, record.neutral, fit.vertices, face_mask)
    D = np.concatenate([deltas, np.reshape(extra, (-1, *fit.vertices.shape))])
    return RigState(record.neutral, fit.vertices, list(names) + extra_names, D, len(names), np.zeros(len(D))), None


def photographed_deltas(
    project, fits: dict, neutral: str, N: np.ndarray, face_mask: np.ndarray
) -> tuple[list[str], list[np.ndarray]]:
    """The other fitted expressions as shapes on the neutral ``N`` (N, 3) mm: registered onto it as
    tracking's face model does (rigid when fitted with its cameras, else a similarity), minus it."""
    names, deltas = [], []
    weight = np.asarray(face_mask).astype(float)
    for e in project.expressions:
        fit = fits.get(e.name)
        if e.name == neutral or fit is None or fit.vertices is None or fit.vertices.shape != N.shape:
            continue
        try:
            shared = getattr(e, "cameras_from", None) == neutral
            moved, _ = register_expression(fit.vertices, N, weight, scale=not shared)
        except FitError:
            continue
        names.append(e.name)
        deltas.append(moved - N)
    return names, deltas


def rig_neutral(project, neutral: str | None = None) -> str | None:
    """The expression a new rig is made on: ``neutral``, else the rig's, else the first expression."""
    name = neutral or (project.rig.neutral if project.rig is not None else None)
    return name or (project.expressions[0].name if project.expressions else None)


def rig_job(project, fits: dict, mesh, neutral: str | None = None):
    """A job making the rig of a fitted expression (:func:`rig_neutral`) as ``facestudio rig`` does:
    a callable returning ``(neutral, RigResult)`` (a few seconds, for a worker). Reads only the
    fitted mesh, taken now; :class:`FitError` when that expression is not fitted."""
    name = rig_neutral(project, neutral)
    fit = fits.get(name) if name is not None else None
    if fit is None or fit.vertices is None:
        raise FitError(f"expression {name!r} is not fitted; fit it first")
    vertices = fit.vertices.copy()
    return lambda: (name, RigBuilder(mesh).rig(vertices))


def store_new_rig(project, neutral: str, rig) -> None:
    """Record a rig (:func:`rig_job`'s result) in the project, ``results/rig.npz`` written now next
    to the project file; :class:`ProjectError` when the project has no file yet."""
    if project.path is None:
        raise ProjectError("save the project first: the rig is written next to the project file")
    store_rig(project, neutral=neutral, names=rig.names, deltas=rig.deltas, report=dict(rig.report))


__all__ = ["RigState", "photographed_deltas", "read_rig", "rig_job", "rig_neutral", "store_new_rig"]
