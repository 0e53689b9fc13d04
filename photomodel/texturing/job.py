"""Texture one fitted expression of a project and store the result: shared by ``facestudio texture`` and the studio.

Pighin et al. (2002) §5.2: once the cameras are recovered and the mesh fitted, the photographs
are blended into a view-independent cylindrical texture (§5.2.2), the ears, hair and neck coming
from the single best photograph (§5.2.4). The steps, each a function so that a caller can run
the slow one in a worker and commit on its own thread:

1. :func:`load_texture_inputs` — the fitted mesh (from the project's mesh file, or the vertices
   the caller holds in memory), the recovered cameras and the RGB photographs, all checked;
2. :func:`extract_texture` — :func:`photomodel.texturing.cylindrical.cylindrical_texture` with the §5.2.4
   fallback weights (when the mesh has the generic mesh's topology), ``progress`` / ``cancel``;
3. :func:`encode_texture_outputs` — every file in memory: the texture PNG, one weight-map PNG per
   photo (black 0 … white 1), textured OBJ+MTL, glb and coloured PLY;
4. :func:`photomodel.project.results.store_texture_result` (or ``save_results``, which saves the
   project file too) — writes the files atomically and records a
   :class:`~photomodel.project.TextureResult` in the expression's result.

The way back, when the studio opens a textured project: :func:`load_stored_texture` rebuilds the
:class:`TextureJob` of a stored texture from its PNGs and the fitted mesh (no photograph is read:
:func:`load_texture_photos` reads them when view-dependent texturing needs them).
"""

from __future__ import annotations

import copy
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import cv2
import numpy as np

from photomodel.camera import Camera
from photomodel.errors import Cancelled, FitError, NoFaceFound, PhotoError, ProjectError
from photomodel.exchange.files import encode_png
from photomodel.exchange.gltf import encode_glb
from photomodel.exchange.obj import encode_textured_obj
from photomodel.exchange.ply import encode_colored_ply
from photomodel.exchange.uv import merge_uv_seams
from photomodel.landmarks.detect import detect_468
from photomodel.landmarks.segment import face_pixels
from photomodel.photos.intake import NEUTRAL
from photomodel.photos.reading import MAX_WORKING_SIDE, read_photo
from photomodel.project.io import default_filename
from photomodel.project.results import read_fitted_mesh
from photomodel.texturing.cylindrical import (
    CylinderMap,
    CylindricalTexture,
    cylinder_map_for,
    cylinder_surface,
    cylindrical_texture,
    seam_render_mesh,
    single_view_weights,
)
from photomodel.texturing.neutral_parts import expressive_mouth_masks

__all__ = [
    "TEXTURE_SIZES",
    "TextureInputs",
    "TextureJob",
    "encode_texture_outputs",
    "extract_texture",
    "fitted_expressions",
    "load_stored_texture",
    "load_texture_inputs",
    "load_texture_photos",
    "photo_side_for",
    "stored_cylinder",
    "texture_expression",
]

#: Texture sizes accepted (texels per side), as :func:`photomodel.texturing.cylindrical.cylindrical_texture`.
TEXTURE_SIZES = (8, 16384)
#: The smallest longest side (px) :func:`photo_side_for` reads photographs at for texturing.
MIN_TEXTURE_PHOTO_SIDE = 2048


@dataclass
class TextureInputs:
    """What texturing one expression needs.

    Attributes
    ----------
    expression : str
    vertices : (N, 3) float, mm, the fitted mesh.
    faces : (M, 3) int.
    photo_ids : list[str], the photos that have a recovered camera, in project order.
    cameras : list[Camera], their cameras.
    photos : list[(H, W, 3) uint8] or None, RGB, each the size of its camera; None for a texture
        read back from its files (:func:`load_stored_texture`; see :func:`load_texture_photos`).
    """

    expression: str
    vertices: np.ndarray
    faces: np.ndarray
    photo_ids: list
    cameras: list
    photos: list | None


@dataclass
class TextureJob:
    """A texture extracted for one expression, not yet written.

    Attributes
    ----------
    inputs : TextureInputs
    size : int, texels per side.
    texture : photomodel.texturing.cylindrical.CylindricalTexture
    single_view : (N,) float32 or None, the §5.2.4 fallback weights used.
    report : dict, ``coverage`` (fraction of the surface texels seen by a photo), ``extract_s``,
        ``photos``, ``single_view_fallback`` — the project's texture report.
    masks : list of (H_k, W_k) bool or None, the pixels each photo was allowed to give
        (:func:`photomodel.landmarks.segment.face_pixels`; the studio's weight-map dock shows
        them); None when the photos were not masked or the texture was read back from files.
    """

    inputs: TextureInputs
    size: int
    texture: object
    single_view: np.ndarray | None
    report: dict = field(default_factory=dict)
    masks: list | None = None

    @property
    def expression(self) -> str:
        return self.inputs.expression


def fitted_expressions(project, name: str | None) -> list[str]:
    """The expressions to texture: ``name`` or every fitted one; FitError if not fitted."""
    if name is not None:
        if project.expression(name).result is None:
            raise FitError(f"expression {name!r} has not been fitted yet: run `facestudio fit {project.path}` first")
        return [name]
    names = [e.name for e in project.expressions if e.result is not None]
    if not names:
        where = project.path.name if project.path is not None else project.name
        raise FitError(f"{where}: no expression has been fitted yet: run `facestudio fit {project.path}` first")
    return names


def photo_side_for(size: int) -> int:
    """The longest side (px) photographs are read at to texture a ``size``² texture: twice the
    texture's side, at least :data:`MIN_TEXTURE_PHOTO_SIDE`, at most the working resolution.

    A cylindrical texture spends about a quarter of its width on the face; a face filling an
    eighth of a photo's long side then meets it texel for pixel at twice the texture's side,
    so larger photos add no detail, only memory (three 6000² photos took 3.1 GB to texture at
    1024², 2026-12-02). The stored cameras are of the original photos; the reduced ones come
    with their cameras scaled (:func:`load_texture_inputs`)."""
    return int(min(MAX_WORKING_SIDE, max(MIN_TEXTURE_PHOTO_SIDE, 2 * int(size))))


def load_texture_inputs(
    project,
    name: str,
    vertices: np.ndarray | None = None,
    faces: np.ndarray | None = None,
    max_side: int = MAX_WORKING_SIDE,
) -> TextureInputs:
    """The fitted mesh, cameras and RGB photographs of a fitted expression.

    Parameters
    ----------
    project : Project
    name : str, a fitted expression (its ``result`` holds the cameras).
    vertices, faces : optional, the fitted mesh held in memory (the studio, before a save);
        default: read the expression's ``result.mesh_obj``.
    max_side : int
        read larger photographs reduced to this longest side (:func:`photo_side_for`), their
        cameras scaled; default the working resolution (:data:`~photomodel.photos.reading.MAX_WORKING_SIDE`).

    Raises
    ------
    FitError
        the expression is not fitted, or no photo has a camera.
    ProjectError
        naming the mesh or photo that is missing, unreadable or of the wrong size.
    """
    expr = project.expression(name)
    result = expr.result
    if result is None:
        raise FitError(f"expression {name!r} has not been fitted yet")
    if vertices is None or faces is None:
        vertices, faces = read_fitted_mesh(project, name)
    ids, cameras, photos = _read_photos(project, name, [p.id for p in expr.photos if p.id in result.cameras], max_side)
    if not cameras:
        raise FitError(f"expression {name!r}: no photo has a recovered camera; run `facestudio fit` first")
    return TextureInputs(name, np.asarray(vertices, dtype=float), np.asarray(faces), ids, cameras, photos)


def _read_photos(project, name: str, photo_ids, max_side: int = MAX_WORKING_SIDE) -> tuple[list, list, list]:
    """``(ids, cameras, RGB photos)`` of the expression's photos ``photo_ids`` (all with a
    recovered camera), each checked against its camera; ProjectError naming the photo.

    Photos are read by :func:`photomodel.photos.reading.read_photo` (EXIF orientation applied,
    a truncated file refused); one larger than its working resolution comes back reduced, with
    its camera scaled to match (focal length and image size × ``scale``), so the texture is
    sampled from the working image. The stored cameras are not changed."""

    expr = project.expression(name)
    result = expr.result
    ids, cameras, photos = [], [], []
    for pid in photo_ids:
        photo = expr.photo(pid)
        cam = result.cameras.get(pid)
        who = f"expression {name!r}, photo {pid!r}"
        if cam is None:
            raise ProjectError(f"{who}: it has no recovered camera; run `facestudio fit {project.path}` again")
        path = project.photo_path(photo)
        if not path.is_file():
            raise ProjectError(f"{who}: {photo.path} does not exist (looked for {path})")
        try:
            read = read_photo(path, max_side)
        except PhotoError as exc:
            raise ProjectError(f"{who}: {exc}") from exc
        if (read.width, read.height) != (cam.width, cam.height):
            raise ProjectError(
                f"{who}: {photo.path} is {read.width}x{read.height} but its camera is "
                f"{cam.width}x{cam.height}; the photo changed since the fit"
            )
        if read.reduced:
            h, w = read.image.shape[:2]
            cam = Camera(cam.R, cam.t, cam.f * read.scale, w, h)
        ids.append(pid)
        cameras.append(cam)
        photos.append(read.image)
    return ids, cameras, photos


def _face_points(image: np.ndarray):
    """The face mesh's 468 points of a photo, or None when no face is found."""
    try:
        return detect_468(image).points
    except NoFaceFound:
        return None


def _photo_masks(inputs: TextureInputs) -> list[np.ndarray]:
    """The pixels each photo may give: its face and head (:func:`face_pixels`), and for the
    neutral, not the mouth of a photo whose mouth shows an expression another photo's does not
    (:func:`photomodel.texturing.neutral_parts.expressive_mouth_masks`)."""
    points = [_face_points(p) for p in inputs.photos]
    masks = [face_pixels(p, pts) for p, pts in zip(inputs.photos, points, strict=True)]
    if inputs.expression != NEUTRAL:
        return masks
    mouths = expressive_mouth_masks([p.shape for p in inputs.photos], points)
    return [m if out is None else m & ~out for m, out in zip(masks, mouths, strict=True)]


def extract_texture(
    inputs: TextureInputs,
    size: int = 1024,
    *,
    face_mask: np.ndarray | None = None,
    mask_photos: bool = True,
    progress: Callable[[str, float], None] | None = None,
    cancel: Callable[[], bool] | None = None,
) -> TextureJob:
    """The cylindrical texture of §5.2.2 with the §5.2.4 ears/hair fallback, each photo's
    background and clothes left out (``mask_photos``).

    Parameters
    ----------
    inputs : TextureInputs
    size : int, texels per side, within :data:`TEXTURE_SIZES`.
    face_mask : (N,) bool, optional
        the generic mesh's face (:attr:`GenericMesh.face_mask`); when given and the fitted mesh
        has as many vertices, vertices away from it are textured from the single best photo.
    mask_photos : bool
        take from each photo only its person's face and head
        (:func:`photomodel.landmarks.segment.face_pixels`: not the background, not below the jaw);
        the weight maps fall to 0 elsewhere and the texels come from the other photos or the hole
        filler. Measured on real photos (``benchmarks/bench_real.py``, docs/texturing.md).
    progress, cancel : see :func:`photomodel.texturing.cylindrical.cylindrical_texture` (``cancel`` raises
        :class:`photomodel.errors.Cancelled`).

    Raises
    ------
    FaceStudioError (ProjectError) for a size out of range.
    """

    lo, hi = TEXTURE_SIZES
    if not lo <= int(size) <= hi:
        raise ProjectError(f"texture size {size}: it must be between {lo} and {hi} texels")
    V = inputs.vertices
    t0 = time.perf_counter()
    single = single_view_weights(V, face_mask) if face_mask is not None and len(face_mask) == len(V) else None
    masks = _photo_masks(inputs) if mask_photos else None
    tex = cylindrical_texture(
        V,
        inputs.faces,
        inputs.cameras,
        inputs.photos,
        size=int(size),
        single_view=single,
        masks=masks,
        progress=progress,
        cancel=cancel,
    )
    seconds = time.perf_counter() - t0
    surface = int(tex.surface.sum())
    c = tex.cylinder
    report = {
        "coverage": float(tex.coverage.sum() / max(surface, 1)),
        "extract_s": round(seconds, 3),
        "photos": list(inputs.photo_ids),
        "single_view_fallback": single is not None,
        # each photo's share of pixels left out as background or clothes (None: not masked)
        "masked_pct": None if masks is None else [round(100.0 * float(1.0 - m.mean()), 1) for m in masks],
        # the texture's parameterisation: the tracking model maps its vertices with it
        "cylinder": {
            "centre": list(c.centre),
            "theta_cut": c.theta_cut,
            "phi_range": list(c.phi_range),
            "y_range": list(c.y_range),
        },
    }
    return TextureJob(inputs, int(size), tex, single, report, masks)


def encode_texture_outputs(project, job: TextureJob, folder: Path | None = None) -> tuple[dict, dict]:
    """Encode every file of a texture in memory: ``({absolute path: bytes}, relative paths)``.

    The relative paths are :meth:`Project.default_texture_paths` (``image``, ``weight_maps``
    {photo id: path} for the photos used, ``obj``, ``mtl``, ``glb``, ``ply``), relative to
    ``folder`` — the folder the project is being saved into (default: its own; the project must
    then have a file, ``project.path``, for them to resolve).
    """
    if folder is not None and (project.path is None or Path(folder) != project.path.parent):
        at_folder = copy.copy(project)  # shares the expressions; resolves paths in ``folder``
        at_folder.path = Path(folder).absolute() / default_filename(project.name)
        project = at_folder
    if project.path is None:
        raise ProjectError("the project has no file yet: save it before writing the texture")
    name, tex = job.expression, job.texture
    vertices, faces, ids = job.inputs.vertices, job.inputs.faces, job.inputs.photo_ids
    rel = project.default_texture_paths(name)
    # per-corner uv in the mesh's face order: the texture's seam-split rendering mesh, merged
    uv = merge_uv_seams(faces, tex.seam_vertices, tex.seam_faces, tex.seam_uv)
    png = encode_png(tex.image)  # encoded once: the file and the .glb embed the same bytes
    files = {project.resolve(rel["image"]): png}
    for pid, w in zip(ids, tex.weight_maps, strict=True):
        files[project.resolve(rel["weight_maps"][pid])] = encode_png(w)  # black 0 … white 1
    obj = encode_textured_obj(
        project.resolve(rel["obj"]),
        vertices,
        faces,
        uv,
        None,
        texture_path=project.resolve(rel["image"]),
        check_exists=False,
    )
    files.update(obj.files)  # after the PNG it refers to
    files[project.resolve(rel["glb"])] = encode_glb(vertices, faces, uv=uv, texture=png, name=name)
    files[project.resolve(rel["ply"])] = encode_colored_ply(vertices, faces, uv=uv, texture=tex.image)
    rel["weight_maps"] = {pid: rel["weight_maps"][pid] for pid in ids}
    return files, rel


def stored_cylinder(texture, vertices: np.ndarray, faces: np.ndarray):
    """The :class:`~photomodel.texturing.cylindrical.CylinderMap` of a stored texture (a
    :class:`~photomodel.project.TextureResult`): its ``report["cylinder"]``, or for a texture
    recorded before the cylinder was, :func:`~photomodel.texturing.cylindrical.cylinder_map_for` the fitted mesh
    at the texture's size (what its extraction used: the cylinder is a function of the mesh).
    """

    c = texture.report.get("cylinder") if isinstance(texture.report, dict) else None
    try:
        cmap = CylinderMap(
            centre=(float(c["centre"][0]), float(c["centre"][1])),
            theta_cut=float(c["theta_cut"]),
            phi_range=(float(c["phi_range"][0]), float(c["phi_range"][1])),
            y_range=(float(c["y_range"][0]), float(c["y_range"][1])),
        )
    except (TypeError, KeyError, IndexError, ValueError):
        return cylinder_map_for(vertices, faces, int(texture.size))
    ok = all(np.isfinite(cmap.centre + cmap.phi_range + cmap.y_range + (cmap.theta_cut,)))
    if not ok or cmap.phi_range[1] <= cmap.phi_range[0] or cmap.y_range[1] <= cmap.y_range[0]:
        return cylinder_map_for(vertices, faces, int(texture.size))
    return cmap


def _read_stored_png(project, name: str, rel: str, what: str, shape: tuple) -> np.ndarray:
    """One PNG of a stored texture as uint8 of ``shape``; ProjectError naming the file."""

    path = project.resolve(rel)
    who = f"expression {name!r}: the {what} {rel}"
    if not path.is_file():
        raise ProjectError(f"{who} does not exist (looked for {path})")
    img = cv2.imread(str(path), cv2.IMREAD_COLOR if len(shape) == 3 else cv2.IMREAD_GRAYSCALE)
    if img is None:
        raise ProjectError(f"{who} is not an image OpenCV can read (damaged or unknown format)")
    if img.shape != shape:
        raise ProjectError(
            f"{who} is {img.shape[1]}x{img.shape[0]}, but the texture is recorded as {shape[1]}x{shape[0]}"
        )
    return cv2.cvtColor(img, cv2.COLOR_BGR2RGB) if img.ndim == 3 else img


def _read_stored_weight_maps(project, name: str, result, S: int) -> tuple[list[str], np.ndarray]:
    """The photo ids of a stored texture's weight maps and the maps (k, S, S) float32 in [0, 1];
    ProjectError naming a photo without a camera or a file that cannot be read."""
    ids = list(result.texture.weight_maps)
    missing = [pid for pid in ids if pid not in result.cameras]
    if missing:
        raise ProjectError(
            f"expression {name!r}: the texture has weight maps of photos without a camera "
            f"({', '.join(missing)}); extract the texture again"
        )
    weights = np.zeros((len(ids), S, S), np.float32)
    for i, pid in enumerate(ids):
        png = _read_stored_png(project, name, result.texture.weight_maps[pid], f"weight map of photo {pid!r}", (S, S))
        weights[i] = png.astype(np.float32) / 255.0
    return ids, weights


def load_stored_texture(
    project, name: str, vertices: np.ndarray, faces: np.ndarray, *, face_mask: np.ndarray | None = None
) -> TextureJob:
    """The texture stored with a fitted expression (``result.texture``) as the :class:`TextureJob`
    its extraction gave, for showing it (the studio, on opening a project) or writing it again.

    Rebuilt from the files and the fitted mesh, without the photographs:

    * ``image`` — the texture PNG, exactly (PNG is lossless);
    * ``weight_maps`` — the weight-map PNGs, to 8 bits (within 0.5/255 of the extraction's);
    * ``uv``, ``seam_*`` — from the cylinder of ``report["cylinder"]``
      (:func:`stored_cylinder`), exactly the extraction's for the same vertices;
    * ``surface`` — :func:`photomodel.texturing.cylindrical.cylinder_surface`, the extraction's raster (needs
      OpenGL; without it, ``coverage`` stands in — it only matters for statistics);
    * ``coverage`` — the texels some weight map is non-zero at (the 8-bit maps lose weights below
      0.5/255, a few texels at the feathered edges);
    * ``single_view`` — :func:`~photomodel.texturing.cylindrical.single_view_weights` again when the report says
      the §5.2.4 fallback was used and ``face_mask`` is given;
    * ``inputs.cameras`` — the fit's cameras of the weight maps' photos; ``inputs.photos`` is None.

    Parameters
    ----------
    project : Project, with a file (the texture's paths are relative to its folder).
    name : str, an expression whose result holds a texture.
    vertices : (N, 3) float, mm, the fitted mesh the texture was made for (``result.mesh_obj``).
    faces : (M, 3) int.
    face_mask : (N,) bool, optional, the generic mesh's face (as for :func:`extract_texture`).

    Returns
    -------
    TextureJob, its ``report`` the stored one.

    Raises
    ------
    FitError
        the expression has no fit or no stored texture.
    ProjectError
        naming the texture file that is missing, unreadable or of the wrong size, or a weight map
        whose photo has no camera.
    """

    result = project.expression(name).result
    if result is None or result.texture is None:
        raise FitError(f"expression {name!r} has no stored texture")
    stored = result.texture
    V = np.asarray(vertices, dtype=float)
    F = np.asarray(faces)
    if V.ndim != 2 or V.shape[1] != 3 or F.ndim != 2 or F.shape[1] != 3:
        raise ValueError(f"vertices must be (N, 3) and faces (M, 3), got {V.shape} and {F.shape}")
    S = int(stored.size)
    image = _read_stored_png(project, name, stored.image, "texture", (S, S, 3))
    ids, weights = _read_stored_weight_maps(project, name, result, S)
    cmap = stored_cylinder(stored, V, F)
    coverage = weights.max(axis=0, initial=0.0) > 0.0
    try:
        surface = cylinder_surface(cmap, V, F, S)
    except RuntimeError:  # no OpenGL context (photomodel.rendering.renderer.get_renderer): statistics only, see above
        surface = coverage.copy()
    vidx, sfaces, seam_uv = seam_render_mesh(cmap, V, F)
    report = dict(stored.report) if isinstance(stored.report, dict) else {}
    single = None
    if report.get("single_view_fallback") and face_mask is not None and len(face_mask) == len(V):
        single = single_view_weights(V, face_mask)
    tex = CylindricalTexture(
        image=image,
        weight_maps=weights,
        uv=cmap.uv(V),
        coverage=coverage,
        surface=surface,
        cylinder=cmap,
        seam_vertices=vidx,
        seam_faces=sfaces,
        seam_uv=seam_uv,
    )
    inputs = TextureInputs(name, V, F, ids, [result.cameras[pid] for pid in ids], None)
    return TextureJob(inputs, S, tex, single, report)


def load_texture_photos(project, inputs: TextureInputs, max_side: int = MAX_WORKING_SIDE) -> list:
    """The RGB photographs of ``inputs.photo_ids`` (for a :func:`load_stored_texture` job, whose
    ``inputs.photos`` is None), each checked against its camera, larger ones reduced to
    ``max_side`` (:func:`photo_side_for`); sets and returns ``inputs.photos``. ProjectError
    names a photo that is missing, unreadable or resized."""
    _, cameras, photos = _read_photos(project, inputs.expression, inputs.photo_ids, max_side)
    inputs.photos = photos
    inputs.cameras = cameras  # a photo read at a working resolution comes with its scaled camera
    return photos


def texture_expression(
    project,
    name: str,
    size: int = 1024,
    *,
    face_mask: np.ndarray | None = None,
    vertices: np.ndarray | None = None,
    faces: np.ndarray | None = None,
    progress: Callable[[str, float], None] | None = None,
    cancel: Callable[[], bool] | None = None,
) -> TextureJob:
    """:func:`load_texture_inputs` then :func:`extract_texture` (progress 0 → 1 over both)."""

    def stage(label: str, frac: float) -> None:
        if progress is not None:
            progress(label, frac)

    stage("loading photos", 0.0)
    if cancel is not None and cancel():
        raise Cancelled("texture extraction cancelled")
    inputs = load_texture_inputs(project, name, vertices, faces, photo_side_for(size))
    job = extract_texture(
        inputs, size, face_mask=face_mask, cancel=cancel, progress=lambda label, f: stage(label, 0.1 + 0.85 * f)
    )
    stage("done", 1.0)
    return job
