"""The face model of a project: its fitted and textured expressions, assembled for tracking (§6.1.1).

Pighin et al. (2002) build the tracking model from the basic expressions they modeled from
photographs (§5): each expression's fitted mesh (the generic mesh deformed, so every expression has
the same vertices and triangles) and its texture. :func:`face_model_from_project` does that for a
project whose expressions have been fitted (``facestudio fit``) and textured (``facestudio
texture``):

* **E_1** is the expression called ``neutral`` if there is one, else the project's first; the
  others follow in project order (or the order asked for).
* **One frame for all expressions.** Each fit is in its own head frame: an expression fitted with
  its own cameras has its gauge fixed by a similarity onto the generic mesh's pose features, some
  of which (the mouth corners…) move with the expression; one fitted with the rig's cameras
  (``cameras_from``) is in the rig's frame, which is the neutral's unless the head moved between
  the shots. The blend shapes must differ only where the face moves, so every expression is
  registered onto E_1 by the least-squares motion of its face vertices (the generic mesh's face
  mask) with Geman–McClure re-weighting (scale 1 mm; far points get no say at all), so that what
  the expression moves — the jaw, the lips, the cheeks, the brows, often half the face — does not
  pull the registration: the skull's
  parts (nose, eyes, temples, upper cheeks) agree to a fraction of a millimetre and decide. The
  re-weighting starts both from no motion and from the plain least-squares motion; the lower
  robust cost wins. A
  rigid motion when the expression shares E_1's cameras (their scale is common), a similarity
  otherwise (each gauge has its own scale). Beyond the paper, which does not say how its
  expressions were put in one frame.
* **Textures.** Each expression keeps its own cylindrical texture (§5.2.2) in its own cylinder
  (stored by ``facestudio texture`` in the texture's report; recomputed from the mesh for older
  projects, the same function the extraction used): the model's per-expression texture
  coordinates are that cylinder's coordinates of the expression's fitted vertices, so rendering
  Eq. (5) samples each texture exactly where its extraction put the surface. Textures are
  prefiltered down to ``texture_size`` (a 300-pixel face shows a 1024² cylinder texture ~3×
  minified; INTER_AREA avoids aliasing and makes sampling cheaper).
* **Regions take the expressions that move them.** Each control region is driven by the
  expressions that move it (:data:`MOVES_REGION_MM`): in a model from photos, ``E_k − E_1`` in a
  region that ``E_k`` leaves still is the two fits' noise, and a parameter for it would let the
  tracker explain image noise with it (with the scan's exact expressions such directions vanish
  by themselves, :data:`tracking.blendshape_face.MIN_DIRECTION_MM`).
* **Triangles**: those that do not cross the cylinder's seam in any expression (the back of the
  head; a crossing triangle would smear the whole texture row).
"""

from __future__ import annotations

from collections.abc import Sequence

import cv2
import numpy as np

from photomodel.alignment import similarity_transform
from photomodel.camera import rotation_angle_deg
from photomodel.errors import FitError, ProjectError
from photomodel.modeling.generic_mesh import load_generic_mesh
from photomodel.project import read_fitted_mesh
from photomodel.texturing.job import stored_cylinder
from tracking.blendshape_face import CONTROL_REGIONS, FaceModel, build_face_model, control_regions, smooth_membership

__all__ = [
    "MODEL_TEXTURE_SIZE",
    "face_model_from_project",
    "project_face_model",
    "model_expressions",
    "register_expression",
]

#: Texels per side of the textures in the tracking model (see the module notes).
MODEL_TEXTURE_SIZE = 512
#: Scale (mm) of the registration's robust re-weighting: fitted rest vertices agree to ~0.5 mm.
REGISTRATION_SCALE_MM = 1.0
#: An expression takes part in a region when it moves the region's vertices (membership > 0.5, face
#: mask) by at least this much (mm) at the 95th percentile: the sample's expressions move their
#: regions by 2.2-16 mm there, while the differences between fits of regions an expression leaves
#: still are fit noise, 0.5-1.5 mm (the fitted meshes are ~0.7 mm from the truth).
MOVES_REGION_MM = 2.0
#: A triangle whose corners' u differ by more than this crosses the cylinder's seam.
SEAM_SPAN_U = 0.5


def model_expressions(project, names: Sequence[str] | None = None) -> list[str]:
    """The expressions of the face model, E_1 first (see the module notes).

    Raises
    ------
    ProjectError
        an unknown name, or no expression at all (one, the neutral, gives a model of head pose only).
    FitError
        an expression that is not fitted or not textured; the message lists every such one with
        the commands that produce them.
    """
    known = [e.name for e in project.expressions]
    if names is None:
        names = list(known)
        if "neutral" in names:
            names.remove("neutral")
            names.insert(0, "neutral")
    else:
        names = list(dict.fromkeys(names))
        for n in names:
            project.expression(n)  # ProjectError naming the known ones
    where = project.path if project.path is not None else project.name
    if not names:
        raise ProjectError(
            f"{where}: tracking needs a face model of at least one expression (a neutral one; "
            f"more expressions add expression tracking); the project has none"
        )
    unfitted = [n for n in names if project.expression(n).result is None]
    untextured = [n for n in names if n not in unfitted and project.expression(n).result.texture is None]
    if unfitted or untextured:
        parts = []
        if unfitted:
            parts.append(f"not fitted: {', '.join(unfitted)} (run `facestudio fit {where}`)")
        if untextured:
            parts.append(f"without a texture: {', '.join(untextured)} (run `facestudio texture {where}`)")
        raise FitError(f"{where}: the face model needs every expression fitted and textured; " + "; ".join(parts))
    return names


def _read_texture(project, name: str, size: int) -> np.ndarray:
    """(size, size, 3) float32 RGB in [0, 1], prefiltered."""
    rel = project.expression(name).result.texture.image
    path = project.resolve(rel)
    if not path.is_file():
        raise ProjectError(
            f"expression {name!r}: the texture {rel} does not exist (looked for {path}); "
            f"run `facestudio texture {project.path}` again"
        )
    img = cv2.imread(str(path), cv2.IMREAD_COLOR)
    if img is None:
        raise ProjectError(f"expression {name!r}: the texture {rel} is not an image OpenCV can read")
    img = cv2.cvtColor(img, cv2.COLOR_BGR2RGB)
    if img.shape[0] != size or img.shape[1] != size:
        img = cv2.resize(img, (size, size), interpolation=cv2.INTER_AREA if img.shape[0] > size else cv2.INTER_LINEAR)
    return img.astype(np.float32) / 255.0


def _texture_uv(project, name: str, V: np.ndarray, F: np.ndarray) -> np.ndarray:
    """(n, 2) the cylindrical texture coordinates (v up) of the expression's vertices."""

    return stored_cylinder(project.expression(name).result.texture, V, F).uv(V)


def register_expression(
    E: np.ndarray, E1: np.ndarray, weight: np.ndarray, *, scale: bool, iterations: int = 8
) -> tuple[np.ndarray, dict]:
    """``E`` (n, 3) mm moved onto ``E1`` (n, 3) by the robust least-squares motion of the vertices
    with ``weight`` (n,) > 0: rigid, or a similarity when ``scale``. Returns the moved vertices and a
    report: ``rms_mm`` over the vertices that agree after registration (within 2 mm: the skull's
    parts), ``agreeing`` (their fraction of the weighted vertices), ``scale``, ``rotation_deg``,
    ``translation_mm``."""

    w0 = np.asarray(weight, float)
    if np.count_nonzero(w0 > 0) < 3:
        raise FitError("cannot register the expressions: fewer than 3 vertices to register on")

    def robust(s, R, t):
        q = (np.linalg.norm(E @ (s * R).T + t - E1, axis=1) / REGISTRATION_SCALE_MM) ** 2
        return w0 / (1.0 + q) ** 2, float(w0 @ (q / (1.0 + q)))

    # two starts: no motion (the same rig and a still head: what moves is the expression) and the
    # plain least-squares motion of every weighted vertex (a head that moved, another gauge);
    # iteratively re-weighted from each, the lower robust cost wins
    best = None
    for start in ((1.0, np.eye(3), np.zeros(3)), similarity_transform(E, E1, w0, scale=scale)):
        motion = start
        for _ in range(iterations):
            w, _ = robust(*motion)
            motion = similarity_transform(E, E1, w, scale=scale)
        cost = robust(*motion)[1]
        if best is None or cost < best[0]:
            best = (cost, motion)
    s, R, t = best[1]
    moved = E @ (s * R).T + t
    r = np.linalg.norm(moved - E1, axis=1)
    sel = (w0 > 0) & (r < 2.0)
    report = {
        "rms_mm": float(np.sqrt(np.mean(r[sel] ** 2))) if sel.any() else float("nan"),
        "agreeing": float(sel.sum() / np.count_nonzero(w0 > 0)),
        "scale": float(s),
        "rotation_deg": float(rotation_angle_deg(R, np.eye(3))),
        "translation_mm": float(np.linalg.norm(t)),
    }
    return moved, report


def face_model_from_project(
    project, names: Sequence[str] | None = None, *, texture_size: int = MODEL_TEXTURE_SIZE, basis: str = "gram_schmidt"
) -> tuple[FaceModel, dict]:
    """The blend-shape face model (§6.1.1) of a project's fitted and textured expressions.

    Parameters
    ----------
    project : photomodel.project.Project (saved: meshes and textures are read next to it)
    names : expressions to use, E_1 first (default: :func:`model_expressions`).
    texture_size : texels per side of the model's textures.
    basis : ``"gram_schmidt"`` or ``"pca"``.

    Returns
    -------
    model : FaceModel
    report : dict, JSON-able: ``expressions``, ``registration`` {expression: report of
        :func:`register_expression`}, ``texture_size``, ``triangles``.

    Raises
    ------
    FitError, ProjectError
        naming the expression and file that is missing, unreadable or inconsistent.
    """

    names = model_expressions(project, names)
    mesh = load_generic_mesh()
    meshes = [read_fitted_mesh(project, n) for n in names]
    n = len(mesh.vertices)
    for name, (V, F) in zip(names, meshes, strict=True):
        if V.shape != (n, 3) or not np.array_equal(F, mesh.faces):
            raise ProjectError(
                f"expression {name!r}: its fitted mesh has {len(V)} vertices and {len(F)} triangles "
                f"but the generic mesh {len(mesh.vertices)} and {len(mesh.faces)}; fit it again"
            )
    E1 = meshes[0][0]
    regions = control_regions(mesh.regions, E1, mesh.landmarks)
    weight = mesh.face_mask.astype(float)
    geometry, registration = [E1], {}
    for name, (V, _) in zip(names[1:], meshes[1:], strict=True):
        shared = _shares_cameras(project, name, names[0])
        moved, rep = register_expression(V, E1, weight, scale=not shared)
        rep["cameras_shared"] = bool(shared)
        geometry.append(moved)
        registration[name] = rep
    E = np.stack(geometry)
    uv = np.stack([_texture_uv(project, nm, V, F) for nm, (V, F) in zip(names, meshes, strict=True)])
    span = np.ptp(uv[:, mesh.faces, 0], axis=2).max(axis=0)  # (f,) worst u span over expressions
    faces = mesh.faces[span < SEAM_SPAN_U]
    textures = [_read_texture(project, nm, int(texture_size)) for nm in names]
    mu = smooth_membership(regions, mesh.faces)
    use = np.zeros((len(CONTROL_REGIONS), len(names)), bool)
    use[:, 0] = True
    motion = np.linalg.norm(E[1:] - E[0], axis=2)  # (m − 1, n) mm
    for r in range(1, len(CONTROL_REGIONS)):
        sel = (mu[:, r] > 0.5) & mesh.face_mask
        if sel.any():
            use[r, 1:] = np.percentile(motion[:, sel], 95, axis=1) >= MOVES_REGION_MM
    model = build_face_model(
        names, E, faces, uv, textures, regions, face_mask=mesh.face_mask, basis=basis, region_expressions=use
    )
    report = {
        "expressions": list(names),
        "registration": registration,
        "texture_size": int(texture_size),
        "triangles": int(len(faces)),
        "regions": {
            CONTROL_REGIONS[r]: [n for n, u in zip(names[1:], use[r, 1:], strict=True) if u]
            for r in range(1, len(CONTROL_REGIONS))
        },
    }
    return model, report


def project_face_model(project, names=None) -> tuple[FaceModel, str]:
    """The face model to track ``project`` with, and a sentence saying where it comes from: the
    blend-shape model of its fitted and textured expressions (:func:`face_model_from_project`;
    ``names`` picks them, E_1 first).

    Raises
    ------
    FitError, ProjectError
        no expression, or one not fitted or textured (the message says which and the
        command that does it), or a missing or damaged mesh or texture file.
    """
    model, report = face_model_from_project(project, names)
    reg = "; ".join(f"{n} {r['rms_mm']:.2f} mm" for n, r in report["registration"].items())
    return model, (
        f"project: the expressions {', '.join(model.names)} fitted and textured from the project's "
        f"photos (§6.1.1), registered onto {model.names[0]} by their rest of the face (RMS: {reg})"
    )


def _shares_cameras(project, name: str, source: str) -> bool:
    """True when ``name`` was fitted with ``source``'s cameras (``cameras_from``, followed along a chain)."""
    seen = set()
    while name not in seen:
        seen.add(name)
        nxt = getattr(project.expression(name), "cameras_from", None)
        if nxt is None:
            return False
        if nxt == source:
            return True
        name = nxt
    return False
