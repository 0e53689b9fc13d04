"""Texturing in the studio: the texture of an expression's fit, made in a worker or read back.

:class:`TextureState` is one expression's texture as the studio holds it (with the view-dependent
texture of the same photos, built on first use); :func:`texture_inputs` gathers on the GUI thread
what :func:`compute_texture` needs in a worker (:func:`photomodel.texturing.job.texture_expression`);
:func:`read_stored_texture` reads back the texture an opened project stores
(:func:`photomodel.texturing.job.load_stored_texture`). No Qt.
"""

from __future__ import annotations

import copy
from dataclasses import dataclass

import numpy as np

from photomodel.errors import FitError, ProjectError
from photomodel.texturing.job import load_stored_texture, load_texture_photos, photo_side_for, texture_expression
from photomodel.texturing.view_dependent import ViewDependentTexture


@dataclass
class TextureState:
    """The texture extracted for one expression's fit (:mod:`photomodel.texturing.job`).

    Attributes
    ----------
    job : photomodel.texturing.job.TextureJob, the texture, its weight maps and inputs.
    vertices : (N, 3) float mm, the fitted mesh it was made for (a new fit drops it).
    saved : bool, its files (``results/<expr>_texture.png`` …) are written next to the project.
    photos_from : Project or None, where to read the photographs of a texture read back from its
        files (``job.inputs.photos`` None: :func:`photomodel.texturing.job.load_stored_texture`).
    """

    job: object
    vertices: np.ndarray
    saved: bool = False
    photos_from: object = None
    _view_dependent: object = None

    def view_dependent(self):
        """The :class:`photomodel.texturing.view_dependent.ViewDependentTexture` of the same photos (built once).

        A stored texture's photographs are read now (:class:`ProjectError` names a missing one).
        """
        if self._view_dependent is None:
            i = self.job.inputs
            if i.photos is None:
                if self.photos_from is None:
                    raise ProjectError(f"the photographs of the texture of {i.expression!r} are not known")
                load_texture_photos(self.photos_from, i, photo_side_for(self.job.size))
            self._view_dependent = ViewDependentTexture(
                i.vertices, i.faces, i.cameras, i.photos, single_view=self.job.single_view
            )
        return self._view_dependent


def texture_inputs(project, name: str | None, fit, mesh) -> tuple:
    """What texturing an expression's fit needs, read on the GUI thread (no pixels yet).

    Parameters
    ----------
    project : Project, copied here (edits go on while the worker textures).
    name : str or None, the expression.
    fit : app.studio.fitting.FitState or None, its fit.
    mesh : photomodel.modeling.generic_mesh.GenericMesh

    Returns
    -------
    ``(snapshot Project, expression name, vertices (N, 3), faces, face_mask)``; :class:`FitError`
    when the expression is not fitted with a mesh.
    """
    if name is None or fit is None:
        raise FitError(f"expression {name!r} is not fitted yet: fit it first (Fit → Fit)")
    if fit.vertices is None:
        raise FitError(f"expression {name!r}: its fitted mesh is missing; fit it again")
    return copy.deepcopy(project), name, fit.vertices, mesh.faces, mesh.face_mask


def compute_texture(inputs, size: int, *, progress=None, cancel=None):
    """Extract the texture of :func:`texture_inputs` (worker thread): a TextureJob of ``size``² px."""
    snapshot, name, vertices, faces, face_mask = inputs
    return texture_expression(
        snapshot, name, size, face_mask=face_mask, vertices=vertices, faces=faces, progress=progress, cancel=cancel
    )


def stored_texture_wanted(project, name: str, fit) -> bool:
    """Whether the expression has a stored texture to read back: a saved project, the expression's
    result names a texture, and the studio holds its fit."""
    if project.path is None or fit is None:
        return False
    try:
        e = project.expression(name)
    except ProjectError:
        return False
    return e.result is not None and e.result.texture is not None


def read_stored_texture(project, name: str, fit, mesh) -> TextureState:
    """The texture stored with an expression's fit (:func:`stored_texture_wanted`), read back.

    Raises :class:`~photomodel.errors.FaceStudioError`, :class:`OSError` or :class:`ValueError`
    naming the file when it is missing or unreadable, or when the fitted mesh could not be read.
    """
    if fit.vertices is None:
        mesh_file = project.expression(name).result.mesh_obj
        raise ProjectError(f"expression {name!r}: its fitted mesh {mesh_file} could not be read")
    job = load_stored_texture(project, name, fit.vertices, mesh.faces, face_mask=mesh.face_mask)
    return TextureState(job, fit.vertices, saved=True, photos_from=project)


__all__ = ["TextureState", "compute_texture", "read_stored_texture", "stored_texture_wanted", "texture_inputs"]
