"""The sample project fitted and textured, as a user gets it with ``facestudio fit`` then
``facestudio texture``: made once into the cache under a key of the code that makes it.

Tests and benchmarks track with it (:func:`tracking.synthetic_sequences.ground_truth.fitted_sample_model`)
and open it in the studio; ``tests/test_fitted_sample.py`` makes its neutral afresh and compares.
"""

from __future__ import annotations

import shutil
from collections.abc import Callable, Sequence
from pathlib import Path

from photomodel.data.cache import cache_dir, cached_folder
from photomodel.data.keys import code_key
from photomodel.modeling.fit import FitOptions, fit_expression, fit_order
from photomodel.modeling.generic_mesh import load_generic_mesh
from photomodel.project import load_project, save_project, store_fit_result, store_texture_result
from photomodel.texturing.job import encode_texture_outputs, texture_expression

#: The sample project file (its photos are next to it).
SAMPLE_PROJECT = Path(__file__).resolve().parents[2] / "sample_projects" / "james" / "james.facestudio.json"
#: Third-party packages whose numerics move the fits and textures; their versions are part of the key.
FITTED_SAMPLE_PACKAGES = ("numpy", "scipy", "cv2")


def make_fitted_sample(
    folder: Path,
    expressions: Sequence[str] | None = None,
    progress: Callable[[str, float], None] | None = None,
) -> Path:
    """Copy the sample project into the empty ``folder``, fit and texture ``expressions`` (default
    every one, in :func:`~photomodel.modeling.fit.fit_order`) and save it: the uncached path of
    :func:`fitted_sample_project`.

    Parameters
    ----------
    folder : Path, an existing empty folder.
    expressions : names to fit and texture, in an order :func:`fit_order` allows (an expression
        that reuses another's cameras comes after it); default all.
    progress : ``progress(stage, fraction)``, told how far it got.

    Returns
    -------
    Path of the project file in ``folder``.
    """
    report = progress or (lambda stage, frac: None)
    folder = Path(folder)
    shutil.copy2(SAMPLE_PROJECT, folder / SAMPLE_PROJECT.name)
    shutil.copytree(SAMPLE_PROJECT.parent / "photos", folder / "photos")
    project = load_project(folder / SAMPLE_PROJECT.name)
    mesh = load_generic_mesh()
    order = fit_order(project) if expressions is None else list(expressions)
    steps = 2 * len(order)
    for i, name in enumerate(order):
        report(f"fitting {name}", i / steps)
        result = fit_expression(project, name, mesh, FitOptions())
        store_fit_result(project, name, result, mesh.faces)
    for i, name in enumerate(order):
        report(f"texturing {name}", (len(order) + i) / steps)
        job = texture_expression(project, name, face_mask=mesh.face_mask)
        files, rel = encode_texture_outputs(project, job)
        store_texture_result(project, job, files, rel)
    save_project(project)
    report("done", 1.0)
    return folder / SAMPLE_PROJECT.name


def fitted_sample_key() -> str:
    """The cache key of the fitted sample: :func:`make_fitted_sample`'s code (this module and what it
    imports: the whole fit and texturing pipeline and the generic mesh), the project file, its photos
    and :data:`FITTED_SAMPLE_PACKAGES`' versions."""
    project = load_project(SAMPLE_PROJECT)
    photos = [project.photo_path(p) for e in project.expressions for p in e.photos]
    return code_key(make_fitted_sample, inputs=(SAMPLE_PROJECT, *photos), packages=FITTED_SAMPLE_PACKAGES)


def fitted_sample_project(progress: Callable[[str, float], None] | None = None) -> Path:
    """A copy of the sample project with every expression fitted and textured: the path of its
    project file, made once in ``<cache>/fitted_james/<key>/`` (:func:`fitted_sample_key`; about
    half a minute on two cores) and reused; ``progress(stage, fraction)`` is told how far it got."""
    folder = cached_folder(
        cache_dir() / "fitted_james", fitted_sample_key(), lambda staged: make_fitted_sample(staged, progress=progress)
    )
    return folder / SAMPLE_PROJECT.name
