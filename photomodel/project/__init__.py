"""The project file (format version 6, reads 1 to 5) in one place, for the CLI and the studio alike.

* :mod:`~photomodel.project.format` — the format's constants (name, version, file suffix, built-in
  mesh, click sources);
* :mod:`~photomodel.project.datamodel` — the dataclasses (``Project``, ``Expression``, ``Photo``,
  ``Feature``, ``CurveDef``, ``ExpressionResult``, ``TextureResult``), ``new_project``;
* :mod:`~photomodel.project.codec` — ``Project`` ⇄ the JSON-able dict of the file (rounding,
  canonical order, relative paths);
* :mod:`~photomodel.project.jsontext` — strict JSON parsing (line/column, duplicate keys, NaN
  literals) and the readable writer;
* :mod:`~photomodel.project.validate` — format/version, JSON Schema (``schema.json``) and
  cross-reference checks;
* :mod:`~photomodel.project.problems` — wording of errors: JSON paths, listings, "did you mean";
* :mod:`~photomodel.project.io` — ``load_project``, ``save_project`` (atomic, ``.bak``), ``load_person``
  (a project of ``people``, the other projects referred to);
* :mod:`~photomodel.project.results` — storing a fit (record + meshes) and a texture into a
  project, and saving the project with them.

The format is documented field by field in ``docs/project-format.md``.
"""

from photomodel.project.datamodel import (
    CurveDef,
    Expression,
    ExpressionResult,
    Feature,
    Photo,
    Project,
    RigRecord,
    TextureResult,
    new_project,
)
from photomodel.project.format import BUILTIN_MESH, FILE_SUFFIX, FORMAT_NAME, FORMAT_VERSION
from photomodel.project.io import (
    default_filename,
    encode_project,
    load_person,
    load_project,
    save_project,
    write_project,
)
from photomodel.project.results import (
    RIG_FILE,
    expression_result,
    load_rig_shapes,
    read_fitted_mesh,
    record_fit,
    save_results,
    store_fit_meshes,
    store_fit_result,
    store_rig,
    store_texture_result,
)
from photomodel.project.validate import OUT_OF_BOUNDS_MARGIN, ROTATION_TOL, project_schema

__all__ = [
    "BUILTIN_MESH",
    "FILE_SUFFIX",
    "FORMAT_NAME",
    "FORMAT_VERSION",
    "OUT_OF_BOUNDS_MARGIN",
    "ROTATION_TOL",
    "CurveDef",
    "Expression",
    "ExpressionResult",
    "Feature",
    "Photo",
    "Project",
    "RIG_FILE",
    "RigRecord",
    "TextureResult",
    "default_filename",
    "encode_project",
    "expression_result",
    "load_person",
    "load_project",
    "load_rig_shapes",
    "read_fitted_mesh",
    "new_project",
    "project_schema",
    "record_fit",
    "save_project",
    "save_results",
    "store_fit_meshes",
    "store_fit_result",
    "store_rig",
    "store_texture_result",
    "write_project",
]
