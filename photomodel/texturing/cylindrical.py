"""View-independent cylindrical texture extraction (Pighin et al. 2002, §5.2.2).

"This texture map is constructed on a virtual cylinder enclosing the face model." A texel
``(u, v)`` names the first point where a horizontal ray from the cylinder towards its
(vertical) axis meets the mesh; the photographs are sampled where that point projects and
blended with the weight maps ``g_k = F_k P_k`` of §5.2.1 (:mod:`photomodel.texturing.weights`).

The cylinder (:class:`CylinderMap`)
-----------------------------------
The axis is the head frame's vertical (``+y``, :mod:`photomodel.camera`) through the
centre of the circle that best fits the mesh's vertices seen from above (least squares in
``x, z``), which lies inside the head (the bounding-box centre of a face mask open at the
back would lie behind the neck, outside the surface). With ``θ = atan2(x − c_x, z − c_z)``
the angle about it (0 in front of the face, increasing towards the subject's left) and
``φ = (θ − θ_cut) mod 2π`` the angle measured from the **seam** ``θ_cut``, a texel's
``u ∈ [0, 1]`` spans ``φ ∈ [φ_0, φ_1]`` and ``v ∈ [0, 1]`` (up, as OBJ/OpenGL) spans
the height ``y ∈ [y_0, y_1]``. The seam is put in the middle of the widest angular gap
between the mesh's vertices — the open back of a face mask (then ``[φ_0, φ_1]`` is just
the mesh's angular extent, so no texel is wasted on the missing back of the head) or,
for a whole head, the sparsest direction, normally the back. The texture looks like the
face unrolled: the subject's left on the right, as in a front photograph.

The (u, v) ↔ surface mapping: rasterised, equal to ray casting
---------------------------------------------------------------
Casting one ray per texel (§5.2.2 step 2) is replaced by an equivalent, faster route:
the mesh is **rasterised in cylindrical coordinates** by the one renderer
(:mod:`photomodel.rendering.renderer`). Each vertex is placed at its texel position ``(u, v)`` with a
depth that *decreases* with its distance ``r`` from the axis, so the z-buffer keeps, at
every texel, the triangle with the largest ``r`` on the texel's ray — the first triangle
a ray cast from the cylinder towards the axis meets. The texel's 3D point is then the
*exact* intersection of its ray with that triangle's plane; per-vertex normals (and the
single-view weight of §5.2.4) are interpolated as float attributes. The only
approximation is in *which* triangle wins: the z-buffer compares ``r`` interpolated
linearly in ``(θ, y)``, which differs from the true intersection by ~0.01–0.3 mm (most
on surfaces the ray grazes), so two surfaces closer than that along a ray (never on a
face) could be swapped, and triangle edges are straight in ``(θ, y)`` where the true
projections curve slightly (well under a texel). ``tests/test_texture.py`` checks the
texel points against ray–triangle intersections.

*Implementation note*: the renderer draws through a pinhole :class:`Camera`; an
orthographic-like raster is obtained by giving each vertex camera coordinates
``((p_x − c) Z / f, (p_y − c) Z / f, Z)``, which project exactly to the wanted pixel
``(p_x, p_y)`` whatever ``Z``, with ``Z = Z_0 − r`` and ``Z_0`` = 10 m so that the
perspective-correct interpolation differs from a linear one by ``Δr / Z_0 < 10⁻³`` of a
triangle. No extension of the renderer is needed.

Seam: triangles whose ``φ`` span crosses the seam are drawn twice, once unwrapped past
``2π`` and once before ``0``, and the texture's ``φ`` range is widened to contain both
copies, so no texel near the seam is lost. The widening is capped at 0.1 rad: near the
crown (and an open bottom) of a whole head, nearly horizontal triangles close to the axis
span large angles and cannot be mapped to a cylinder at all; they are clipped. For
rendering with the texture, seam-crossing triangles get duplicated vertices with the
unwrapped ``u`` (:attr:`CylindricalTexture.seam_faces`); for meshes with no triangle across
the seam (a face mask) the per-vertex ``uv`` serves directly.

Hole filling: a pull–push pyramid (Gortler et al. 1996, the paper's alternative to
one-pixel growth): texels no photograph sees, and texels off the surface, get the
normalised average of the known texels around them at the coarsest scale that has any,
which keeps the texture continuous under bilinear and mipmapped sampling.

Cost (2 shared cores, llvmpipe): a 1024² texture of the 8k-vertex fitted mesh from five
1000×1000 photographs (~880k surface texels) took 1.05–1.6 s wall (load-dependent; ~1.0 s of
CPU). Since 2026-12-04 it takes ~0.57–0.65 s of CPU (``benchmarks/bench_texture.py``
``extract_s``, docs/benchmarks.md): the per-texel arithmetic — each photo's projection,
positional certainty and depth test, the single-view blend, the raster's exact ray–plane
points — runs in compiled loops (:mod:`photomodel.texturing.texel_kernels`, the same formulas
in the same precision: the texture is within one level of the numpy route's, 108 dB), and the
depth maps are read back without the colour and face targets
(:meth:`~photomodel.rendering.renderer.Renderer.render_depth`). What remains per photo: its
depth map (~27 ms), the texel pass (~18 ms), the feathering's distance transform (~17 ms) and
the photo's samples (``remap``, ~10 ms); then the raster (~100 ms, half of it GL) and the hole
filling (~25 ms).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import cv2
import numpy as np
from scipy.spatial import cKDTree

from photomodel.camera import Camera
from photomodel.errors import Cancelled
from photomodel.exchange.uv import check_mesh
from photomodel.rendering.depth import DEPTH_TOL_MM
from photomodel.rendering.renderer import get_renderer, vertex_normals
from photomodel.rendering.sampling import sample_image
from photomodel.texturing.texel_kernels import blend_single_view, cylinder_points, photo_texels
from photomodel.texturing.visibility import render_depth
from photomodel.texturing.weights import (
    FEATHER_WIDTH_MM,
    blend,
    cubic_ramp,
    feather,
)

__all__ = [
    "CylinderMap",
    "CylinderRaster",
    "CylindricalTexture",
    "SINGLE_VIEW_OFFSET_MM",
    "SINGLE_VIEW_RAMP_MM",
    "cylinder_map_for",
    "cylinder_surface",
    "rasterise_cylinder",
    "cylindrical_texture",
    "fill_holes",
    "render_cylindrical",
    "seam_render_mesh",
    "single_view_weights",
    "check_photos",
]

#: Angular gap (degrees) between the mesh's vertices above which the seam sits in the gap
#: and the texture spans only the mesh's angular extent.
_MIN_GAP_DEG = 5.0
#: Margin (texels) kept around the mesh's extent in the texture, for bilinear/mipmap sampling.
_MARGIN_TEXELS = 2
#: How far (rad) the texture extends past the seam to hold unwrapped seam-crossing triangles.
#: Triangles close to the axis (the crown of a whole head) span large angles once unwrapped;
#: they are clipped at this margin instead of stretching the texture.
_MAX_UNWRAP = 0.1
#: ``Z_0`` of the cylindrical raster (mm), see the module notes.
_RASTER_Z0_MM = 1.0e4
#: §5.2.4 region of the generic mesh textured from a single photograph: vertices at least
#: this far (mm) from the face mask (:attr:`GenericMesh.face_mask`) get full weight ...
SINGLE_VIEW_OFFSET_MM = 20.0
#: ... with a cubic ramp over this distance (mm) below the offset: 0 up to 5 mm from the mask.
SINGLE_VIEW_RAMP_MM = 15.0


# ----------------------------------------------------------------------------- the cylinder


@dataclass(frozen=True)
class CylinderMap:
    """The cylindrical parameterisation of §5.2.2 (see the module notes).

    Attributes
    ----------
    centre : (float, float)
        ``(c_x, c_z)`` of the vertical axis, mm.
    theta_cut : float
        angle of the seam about the axis (rad), ``θ = atan2(x − c_x, z − c_z)``.
    phi_range : (float, float)
        ``(φ_0, φ_1)``, the angles from the seam (rad, ``0 ≤ φ < 2π`` plus unwrapped margins)
        that ``u = 0`` and ``u = 1`` stand for.
    y_range : (float, float)
        ``(y_0, y_1)``, heights (mm) of ``v = 0`` (bottom edge) and ``v = 1`` (top edge).
    """

    centre: tuple[float, float]
    theta_cut: float
    phi_range: tuple[float, float]
    y_range: tuple[float, float]

    def phi(self, points: np.ndarray) -> np.ndarray:
        """(n,) angle from the seam in ``[0, 2π)`` (rad) of points (n, 3) mm."""
        P = np.asarray(points, dtype=float).reshape(-1, 3)
        theta = np.arctan2(P[:, 0] - self.centre[0], P[:, 2] - self.centre[1])
        return np.mod(theta - self.theta_cut, 2.0 * np.pi)

    def radius(self, points: np.ndarray) -> np.ndarray:
        """(n,) distance (mm) of points (n, 3) from the axis."""
        P = np.asarray(points, dtype=float).reshape(-1, 3)
        return np.hypot(P[:, 0] - self.centre[0], P[:, 2] - self.centre[1])

    def u_of_phi(self, phi: np.ndarray) -> np.ndarray:
        p0, p1 = self.phi_range
        return (np.asarray(phi, dtype=float) - p0) / (p1 - p0)

    def uv(self, points: np.ndarray) -> np.ndarray:
        """(n, 2) texture coordinates ``(u, v)`` (v up) of points (n, 3) mm, without unwrapping."""
        P = np.asarray(points, dtype=float).reshape(-1, 3)
        y0, y1 = self.y_range
        return np.column_stack([self.u_of_phi(self.phi(P)), (P[:, 1] - y0) / (y1 - y0)])

    def ray(self, uv: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The horizontal rays of texture positions ``uv`` (n, 2): the point on the axis at
        the texel's height (n, 3) mm and the unit direction *away* from the axis (n, 3);
        the texel's surface point is ``axis_point + r · direction``."""
        uv = np.asarray(uv, dtype=float).reshape(-1, 2)
        p0, p1 = self.phi_range
        y0, y1 = self.y_range
        theta = self.theta_cut + p0 + uv[:, 0] * (p1 - p0)
        y = y0 + uv[:, 1] * (y1 - y0)
        origin = np.column_stack([np.full(len(uv), self.centre[0]), y, np.full(len(uv), self.centre[1])])
        direction = np.column_stack([np.sin(theta), np.zeros(len(uv)), np.cos(theta)])
        return origin, direction

    def texel_uv(self, size: int) -> tuple[np.ndarray, np.ndarray]:
        """Texture coordinates of the texel centres of a ``size × size`` image: ``u`` (size,)
        per column and ``v`` (size,) per row (row 0 = top, ``v`` near 1)."""
        c = (np.arange(size) + 0.5) / size
        return c, 1.0 - c


def _angular_gap(theta: np.ndarray) -> tuple[float, float]:
    """Centre and width (rad) of the widest gap between angles ``theta`` on the circle."""
    t = np.sort(np.mod(theta, 2.0 * np.pi))
    gaps = np.diff(np.concatenate([t, [t[0] + 2.0 * np.pi]]))
    i = int(np.argmax(gaps))
    return float(t[i] + gaps[i] / 2.0), float(gaps[i])


def _axis_centre(points: np.ndarray) -> tuple[float, float]:
    """``(c_x, c_z)``: centre of the circle fitted (algebraic least squares) to the points'
    ``(x, z)``; the bounding-box centre if the fit is degenerate."""
    x, z = points[:, 0], points[:, 2]
    A = np.column_stack([x, z, np.ones_like(x)])
    sol, *_ = np.linalg.lstsq(A, x * x + z * z, rcond=None)
    cx, cz = sol[0] / 2.0, sol[1] / 2.0
    lo, hi = points.min(axis=0), points.max(axis=0)
    inside = lo[0] <= cx <= hi[0] and lo[2] <= cz <= hi[2]
    if not (np.isfinite(cx) and np.isfinite(cz) and inside):
        cx, cz = (lo[0] + hi[0]) / 2.0, (lo[2] + hi[2]) / 2.0
    return float(cx), float(cz)


def _seam_phi(cmap_cut: float, centre, vertices: np.ndarray, faces: np.ndarray):
    """φ of every vertex and the triangles that cross the seam (φ span > π)."""
    theta = np.arctan2(vertices[:, 0] - centre[0], vertices[:, 2] - centre[1])
    phi = np.mod(theta - cmap_cut, 2.0 * np.pi)
    pf = phi[faces]
    crossing = (pf.max(axis=1) - pf.min(axis=1)) > np.pi
    return phi, crossing


def cylinder_map_for(
    vertices: np.ndarray,
    faces: np.ndarray,
    size: int = 1024,
    *,
    centre: tuple[float, float] | None = None,
) -> CylinderMap:
    """The cylinder enclosing a mesh (§5.2.2; see the module notes for the choices).

    Parameters
    ----------
    vertices : (N, 3) float, mm, head frame (``+y`` up).
    faces : (M, 3) int.
    size : int
        texture size the margins are computed for (2 texels on every side).
    centre : (c_x, c_z), optional
        the axis; default the centre of the circle fitted to the vertices' ``(x, z)``.

    Returns
    -------
    CylinderMap
    """
    V = np.asarray(vertices, dtype=float)
    F = np.asarray(faces)
    used = np.unique(F)
    if centre is None:
        centre = _axis_centre(V[used])
    theta = np.arctan2(V[used, 0] - centre[0], V[used, 2] - centre[1])
    gap_centre, gap = _angular_gap(theta)
    cut = gap_centre if np.degrees(gap) >= _MIN_GAP_DEG else float(np.pi)  # whole head: seam at the back
    cut = float(np.mod(cut + np.pi, 2.0 * np.pi) - np.pi)
    phi, crossing = _seam_phi(cut, centre, V, F)
    lo_phi, hi_phi = float(phi[used].min()), float(phi[used].max())
    if crossing.any():  # copies unwrapped past 2π and before 0, at most _MAX_UNWRAP beyond
        pf = phi[F[crossing]]
        hi_phi = max(hi_phi, min(float(np.where(pf < np.pi, pf + 2.0 * np.pi, pf).max()), 2.0 * np.pi + _MAX_UNWRAP))
        lo_phi = min(lo_phi, max(float(np.where(pf >= np.pi, pf - 2.0 * np.pi, pf).min()), -_MAX_UNWRAP))
    y = V[used, 1]
    frac = _MARGIN_TEXELS / max(size - 2 * _MARGIN_TEXELS, 1)
    dp = (hi_phi - lo_phi) * frac
    dy = (float(y.max()) - float(y.min())) * frac
    return CylinderMap(
        centre=(float(centre[0]), float(centre[1])),
        theta_cut=cut,
        phi_range=(lo_phi - dp, hi_phi + dp),
        y_range=(float(y.min()) - dy, float(y.max()) + dy),
    )


def _seam_mesh(cmap: CylinderMap, vertices: np.ndarray, faces: np.ndarray, both: bool):
    """Vertices (as indices into ``vertices``), faces and unwrapped φ of a mesh whose
    seam-crossing triangles use duplicated vertices: unwrapped past 2π, and (``both``)
    a second copy unwrapped before 0.

    Returns ``(vertex_index (M,), faces (F', 3), phi (M,), face_index (F',))``.
    """
    phi, crossing = _seam_phi(cmap.theta_cut, cmap.centre, vertices, faces)
    n = len(vertices)
    idx = [np.arange(n)]
    phis = [phi]
    out_faces = [faces[~crossing]]
    face_index = [np.flatnonzero(~crossing)]
    if crossing.any():
        cf = faces[crossing]
        shifts = [(+1, phi[cf] < np.pi)] + ([(-1, phi[cf] >= np.pi)] if both else [])
        for sign, moved in shifts:
            m = cf.size
            base = n + sum(len(p) for p in phis[1:])
            idx.append(cf.reshape(-1))
            phis.append((phi[cf] + sign * 2.0 * np.pi * moved).reshape(-1))
            out_faces.append(base + np.arange(m).reshape(-1, 3))
            face_index.append(np.flatnonzero(crossing))
    return (
        np.concatenate(idx),
        np.concatenate(out_faces).astype(np.int64),
        np.concatenate(phis),
        np.concatenate(face_index),
    )


# ----------------------------------------------------------------------------- rasterisation


@dataclass
class CylinderRaster:
    """The mesh rasterised in cylindrical coordinates: one surface point per texel.

    Attributes
    ----------
    surface : (S, S) bool
        the texel's ray hits the mesh.
    points : (S, S, 3) float32
        mm, the first hit (largest radius) on the texel's ray; NaN off the surface.
    radius : (S, S) float32
        its distance from the axis (mm); NaN off the surface.
    attributes : (S, S, C) float32
        interpolated per-vertex attributes; 0 off the surface.
    face_id : (S, S) int64
        index into the mesh's ``faces`` of the hit triangle; ``-1`` off the surface.
    """

    surface: np.ndarray
    points: np.ndarray
    radius: np.ndarray
    attributes: np.ndarray
    face_id: np.ndarray


def _render_cylinder(cmap: CylinderMap, V: np.ndarray, F: np.ndarray, size: int, attributes=None):
    """The seam-split mesh drawn at its texel positions (see the module notes): the renderer's
    ``RenderResult`` (mask, depth ``Z_0 − r``, interpolated attributes, face ids of the split
    mesh) and ``face_index`` (F',), the mesh face of each split face."""

    vidx, sfaces, phi, face_index = _seam_mesh(cmap, V, F, both=True)
    y0, y1 = cmap.y_range
    u = cmap.u_of_phi(phi)
    v = (V[vidx, 1] - y0) / (y1 - y0)
    r = cmap.radius(V[vidx])
    # pixel position of each vertex in the raster (row 0 = top = v 1), then a pinhole
    # placement that projects exactly there whatever its depth
    px = u * size - 0.5
    py = (1.0 - v) * size - 0.5
    c = (size - 1) / 2.0
    f = float(size)
    Z = _RASTER_Z0_MM - r
    fake = np.column_stack([(px - c) * Z / f, (py - c) * Z / f, Z])
    cam = Camera(np.eye(3), np.zeros(3), f, size, size)
    near = _RASTER_Z0_MM - float(r.max()) - 1.0
    far = _RASTER_Z0_MM - float(r.min()) + 1.0
    if attributes is None:
        attr = np.zeros((len(vidx), 1), np.float32)
    else:
        attr = np.asarray(attributes, dtype=np.float32)
        attr = attr.reshape(len(V), -1)[vidx]
    res = get_renderer().render(cam, fake, sfaces, colors=attr, near=near, far=far)
    return res, face_index


def rasterise_cylinder(
    cmap: CylinderMap,
    vertices: np.ndarray,
    faces: np.ndarray,
    size: int,
    attributes: np.ndarray | None = None,
) -> CylinderRaster:
    """Rasterise a mesh in the cylindrical coordinates of ``cmap`` (§5.2.2 step 2).

    Equivalent to casting, from every texel centre on the cylinder, a horizontal ray
    towards the axis and keeping the first intersection (see the module notes).

    Parameters
    ----------
    cmap : CylinderMap
    vertices : (N, 3) float, mm.
    faces : (M, 3) int.
    size : int, the texture is ``size × size``.
    attributes : (N, C) float, optional
        per-vertex values to interpolate (e.g. normals).

    Returns
    -------
    CylinderRaster
    """
    V = np.asarray(vertices, dtype=float)
    F = np.asarray(faces, dtype=np.int64)
    res, face_index = _render_cylinder(cmap, V, F, size, attributes)
    surface = res.mask
    face_id = np.where(surface, face_index[np.maximum(res.face_id, 0)], -1)
    rows, cols = np.nonzero(surface)
    # the z-buffer has picked the first triangle on each texel's ray; the point itself is the
    # exact intersection of the ray with that triangle's plane (the rasterised r is linear in
    # (θ, y) and errs by up to ~0.1 mm on surfaces the ray grazes). The ray of texel (row, col)
    # leaves the axis point (c_x, y_row, c_z) along (sin θ_col, 0, cos θ_col), so with the plane
    # n·p = n·a of each triangle, r = (n·a − n_x c_x − n_z c_z − n_y y_row) / (n_x sin θ_col +
    # n_z cos θ_col): per-triangle, per-row and per-column terms, gathered per texel.
    uu, vv = cmap.texel_uv(size)
    p0, p1 = cmap.phi_range
    y0, y1 = cmap.y_range
    theta = cmap.theta_cut + p0 + uu * (p1 - p0)  # (size,) per column
    y_row = y0 + vv * (y1 - y0)  # (size,) per row
    cx, cz = cmap.centre
    tri = V[F]
    n = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])  # (M, 3) per triangle
    offset = np.einsum("ij,ij->i", n, tri[:, 0]) - n[:, 0] * cx - n[:, 2] * cz
    r_raster = _RASTER_Z0_MM - res.depth[rows, cols].astype(np.float64)
    radius, points = cylinder_points(
        rows, cols, face_id[rows, cols], n, offset, np.sin(theta), np.cos(theta), y_row, r_raster, cx, cz, size
    )
    attrs = res.color  # the render's background is 0: attributes are 0 off the surface
    return CylinderRaster(surface=surface, points=points, radius=radius, attributes=attrs, face_id=face_id)


def cylinder_surface(cmap: CylinderMap, vertices: np.ndarray, faces: np.ndarray, size: int) -> np.ndarray:
    """(S, S) bool, the texels whose ray hits the mesh: :attr:`CylinderRaster.surface` (the same
    raster) without the texel points, ~0.07 s for a 1024² texture instead of ~0.4 s.

    Used to rebuild a stored texture's :attr:`CylindricalTexture.surface`
    (:func:`photomodel.texturing.job.load_stored_texture`).
    """
    V = np.asarray(vertices, dtype=float)
    F = np.asarray(faces, dtype=np.int64)
    res, _ = _render_cylinder(cmap, V, F, int(size))
    return np.asarray(res.mask, dtype=bool)


def seam_render_mesh(
    cmap: CylinderMap, vertices: np.ndarray, faces: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The rendering mesh of a cylindrical texture (:attr:`CylindricalTexture.seam_vertices`,
    ``seam_faces``, ``seam_uv``): triangles crossing the seam use duplicated vertices whose
    ``u`` is unwrapped past 1.

    Parameters
    ----------
    cmap : CylinderMap
    vertices : (N, 3) float, mm.
    faces : (M, 3) int.

    Returns
    -------
    vertex_index : (K,) int, the mesh vertex of each rendering vertex.
    faces : (M, 3) int64, the rendering triangles.
    uv : (K, 2) float in [0, 1], ``v`` up.
    """
    V = np.asarray(vertices, dtype=float)
    F = np.asarray(faces, dtype=np.int64)
    vidx, sfaces, phi, _ = _seam_mesh(cmap, V, F, both=False)
    y0, y1 = cmap.y_range
    # clipped to the texture: only triangles pierced by the axis (see _MAX_UNWRAP) reach beyond
    uv = np.clip(np.column_stack([cmap.u_of_phi(phi), (V[vidx, 1] - y0) / (y1 - y0)]), 0.0, 1.0)
    return vidx, sfaces, uv


# ----------------------------------------------------------------------------- hole filling


def fill_holes(image: np.ndarray, known: np.ndarray) -> np.ndarray:
    """Fill unknown texels with a pull–push pyramid (§5.2.2; Gortler et al. 1996).

    *Pull*: colour × weight and weight are averaged 2×2 down to 1×1 (the weight of a
    coarse texel is the fraction of known texels under it). *Push*: from the coarsest
    level down, each level's normalised colour is mixed with the upsampled coarser result
    in proportion to its weight, so known texels keep their colour exactly and holes get a
    smooth average of the nearest known texels.

    Parameters
    ----------
    image : (H, W, C) or (H, W) float or uint8
    known : (H, W) bool

    Returns
    -------
    array like ``image`` (float32 for float input, uint8 for uint8 input)
        equal to ``image`` on known texels; holes filled. An image with no known texel is
        returned unchanged.
    """

    img = np.asarray(image)
    K = np.asarray(known, dtype=bool)
    if K.shape != img.shape[:2]:
        raise ValueError(f"known mask is {K.shape}, image is {img.shape[:2]}")
    if K.all() or not K.any():
        return img.copy()
    squeeze = img.ndim == 2
    col = img.astype(np.float32).reshape(img.shape[0], img.shape[1], -1)
    w = K.astype(np.float32)
    levels = [(col * w[..., None], w)]
    while max(levels[-1][1].shape) > 1:
        c, wl = levels[-1]
        h, wd = wl.shape
        size = (max(1, (wd + 1) // 2), max(1, (h + 1) // 2))
        cd = cv2.resize(c, size, interpolation=cv2.INTER_AREA).reshape(size[1], size[0], -1)
        wd_ = cv2.resize(wl, size, interpolation=cv2.INTER_AREA)
        levels.append((cd, wd_))
    filled = None
    for level, (c, wl) in enumerate(reversed(levels)):
        h, wd = wl.shape
        if filled is not None:
            up = cv2.resize(filled, (wd, h), interpolation=cv2.INTER_LINEAR).reshape(h, wd, -1)
        if level == len(levels) - 1:  # the finest level: known texels as they are, holes from above
            out = np.where(K[..., None], col, up)
            break
        norm = np.divide(c, wl[..., None], out=np.zeros_like(c), where=wl[..., None] > 0)
        if filled is None:
            filled = norm
            continue
        alpha = np.clip(wl, 0.0, 1.0)[..., None]
        filled = alpha * norm + (1.0 - alpha) * up
    if squeeze:
        out = out[..., 0]
    if img.dtype == np.uint8:
        return np.clip(np.round(out), 0, 255).astype(np.uint8)
    return out.astype(np.float32)


# ----------------------------------------------------------------------------- §5.2.4 region


def single_view_weights(
    vertices: np.ndarray,
    face_mask: np.ndarray,
    *,
    offset_mm: float = SINGLE_VIEW_OFFSET_MM,
    ramp_mm: float = SINGLE_VIEW_RAMP_MM,
) -> np.ndarray:
    """Per-vertex weight ``s`` of the single-best-view fallback (§5.2.4: ears and hair).

    The generic mesh has no separate eye, teeth, ear or hair parts, so the paper's
    per-part textures become a *region* of the one mesh: vertices far from the face mask
    (the ears, the sides and back of the head, the hairline and the neck), where the
    fitted geometry is least constrained by the clicks and a blend of several photographs
    would smear misregistered ears and hair. There ``s = 1`` and the texture comes from
    the single photograph with the largest weight; ``s`` ramps (cubic) to 0 towards the
    face so that no seam shows.

    Parameters
    ----------
    vertices : (N, 3) float, mm (the fitted mesh).
    face_mask : (N,) bool
        the face (e.g. :attr:`photomodel.modeling.generic_mesh.GenericMesh.face_mask`).
    offset_mm, ramp_mm : float
        ``s = cubic_ramp((dist − (offset − ramp)) / ramp)`` with ``dist`` the 3D distance
        to the nearest face-mask vertex: 0 up to ``offset − ramp`` from the face, 1 from
        ``offset`` on.

    Returns
    -------
    (N,) float32 in [0, 1]
    """

    V = np.asarray(vertices, dtype=float)
    M = np.asarray(face_mask, dtype=bool)
    if M.shape != (len(V),):
        raise ValueError(f"face_mask must be ({len(V)},) bool, got shape {M.shape}")
    if not M.any():
        return np.ones(len(V), np.float32)
    dist, _ = cKDTree(V[M]).query(V)
    return cubic_ramp((dist - (offset_mm - ramp_mm)) / max(ramp_mm, 1e-9)).astype(np.float32)


# ----------------------------------------------------------------------------- texture


@dataclass
class CylindricalTexture:
    """A view-independent cylindrical texture and how it was made (§5.2.2).

    Attributes
    ----------
    image : (S, S, 3) uint8
        the texture, RGB, row 0 = top (``v = 1``); holes filled (pull–push).
    weight_maps : (k, S, S) float32
        ``g_k = F_k P_k`` per photograph (before the §5.2.4 single-view fallback), 0 off
        the surface — the images of Fig. 5(c).
    uv : (N, 2) float
        per-vertex cylindrical texture coordinates, ``v`` up; valid for rendering every
        triangle that does not cross the seam (all of them for a face mask).
    coverage : (S, S) bool
        texels coloured from at least one photograph.
    surface : (S, S) bool
        texels whose ray hits the mesh.
    cylinder : CylinderMap
    seam_vertices : (M,) int
        rendering mesh: the original vertex of each rendering vertex ...
    seam_faces : (F, 3) int
        ... its triangles (seam-crossing ones use duplicated vertices) ...
    seam_uv : (M, 2) float
        ... and their texture coordinates in [0, 1], unwrapped across the seam.
    """

    image: np.ndarray
    weight_maps: np.ndarray
    uv: np.ndarray
    coverage: np.ndarray
    surface: np.ndarray
    cylinder: CylinderMap
    seam_vertices: np.ndarray
    seam_faces: np.ndarray
    seam_uv: np.ndarray

    def render_mesh(self, vertices: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``(vertices (M, 3), faces (F, 3), uv (M, 2))`` to draw the textured mesh without a
        seam artefact (vertices of seam-crossing triangles duplicated)."""
        return np.asarray(vertices)[self.seam_vertices], self.seam_faces, self.seam_uv


def check_photos(cameras: Sequence[Camera], photos: Sequence[np.ndarray]) -> list[np.ndarray]:
    """Validate photographs against their cameras; return them as (H, W, 3) uint8 arrays.

    Raises
    ------
    ValueError
        naming the photo whose count, shape or type does not fit.
    """
    if len(cameras) != len(photos):
        raise ValueError(f"{len(cameras)} cameras but {len(photos)} photos")
    if len(cameras) == 0:
        raise ValueError("texturing needs at least one photograph")
    out = []
    for i, (cam, ph) in enumerate(zip(cameras, photos, strict=True)):
        if not isinstance(cam, Camera):
            raise TypeError(f"cameras[{i}] is a {type(cam).__name__}, not a photomodel.camera.Camera")
        a = np.asarray(ph)
        if a.ndim != 3 or a.shape[2] != 3 or a.dtype != np.uint8:
            raise ValueError(f"photos[{i}] must be an (H, W, 3) uint8 RGB image, got {a.shape} {a.dtype}")
        if a.shape[:2] != (cam.height, cam.width):
            raise ValueError(f"photos[{i}] is {a.shape[1]}×{a.shape[0]} but its camera is {cam.width}×{cam.height}")
        out.append(np.ascontiguousarray(a))
    return out


# long: a 55-line numpy docstring for 14 parameters; the body is 38 lines of named steps (one loop over the photos)
def cylindrical_texture(
    vertices: np.ndarray,
    faces: np.ndarray,
    cameras: Sequence[Camera],
    photos: Sequence[np.ndarray],
    size: int = 1024,
    *,
    single_view: np.ndarray | None = None,
    feather_mm: float = FEATHER_WIDTH_MM,
    tol_mm: float = DEPTH_TOL_MM,
    depths: Sequence[np.ndarray] | None = None,
    cylinder: CylinderMap | None = None,
    fill: bool = True,
    masks: Sequence[np.ndarray] | None = None,
    progress=None,
    cancel=None,
) -> CylindricalTexture:
    """Extract the view-independent cylindrical texture of a fitted mesh (§5.2.2).

    For every texel: its surface point ``m`` and normal from the cylindrical raster
    (:func:`rasterise_cylinder`); in each photograph ``k`` its projection ``(x_k, y_k)``,
    visibility (depth map and front-facing, :mod:`photomodel.texturing.visibility`) and positional
    certainty ``P_k(m) = n · d_k``; the binary visibility maps are feathered in texture
    space (``F_k``, cubic ramp over ``feather_mm``) and the photographs, sampled
    bilinearly, are blended with ``g_k = F_k P_k`` (§5.2.1). Texels no photograph sees are
    filled by pull–push (:func:`fill_holes`).

    Parameters
    ----------
    vertices : (N, 3) float
        the fitted mesh, mm.
    faces : (M, 3) int
        its triangles (counter-clockwise from outside).
    cameras : k Camera
        recovered cameras, in the order of ``photos``.
    photos : k (H_k, W_k, 3) uint8
        RGB photographs, each the size of its camera.
    size : int
        the texture is ``size × size`` (default 1024).
    single_view : (N,) float in [0, 1], optional
        per-vertex weight of the single-best-view fallback (§5.2.4,
        :func:`single_view_weights`); ``None``: blend everywhere.
    feather_mm : float
        width of the cubic feathering ramp on the surface (mm).
    tol_mm : float
        depth-comparison tolerance of the visibility test (mm).
    depths : k (H_k, W_k) float, optional
        the mesh's depth maps from ``cameras`` if already rendered.
    cylinder : CylinderMap, optional
        default :func:`cylinder_map_for` the mesh.
    fill : bool
        fill the holes (default True).
    masks : k (H_k, W_k) bool, optional
        the pixels of each photograph that may be taken (the person's face and head, not the
        background or clothes: :func:`photomodel.landmarks.segment.face_pixels`); a texel seen
        elsewhere counts as not visible in that photo, so its weight ramps to 0 there and
        it comes from the other photos or the hole filler. None: every pixel.
    progress : callable ``(stage: str, fraction: float)``, optional
        called before the raster, each photograph and the hole filling (fraction in [0, 1]).
    cancel : callable returning bool, optional
        polled at the same points; when it returns True, :class:`photomodel.errors.Cancelled` is
        raised (the studio's Cancel button).

    Returns
    -------
    CylindricalTexture

    Raises
    ------
    photomodel.errors.Cancelled
        ``cancel()`` returned True.
    """

    V, F, photos, size, single_view = _check_texture_inputs(
        vertices, faces, cameras, photos, size, depths, single_view, masks
    )
    k = len(cameras)

    def step(stage: str, fraction: float) -> None:
        if cancel is not None and cancel():
            raise Cancelled(f"texture extraction cancelled ({stage})")
        if progress is not None:
            progress(stage, fraction)

    step("cylindrical raster", 0.0)
    cmap = cylinder or cylinder_map_for(V, F, size)
    texels = _surface_texels(cmap, V, F, size, single_view)
    weight_maps = np.zeros((k, size, size), np.float32)
    g = np.zeros((k, texels.idx.size), np.float32)
    colors = np.zeros((k, texels.idx.size, 3), np.uint8)
    for i, (cam, photo) in enumerate(zip(cameras, photos, strict=True)):
        step(f"photo {i + 1} of {k}", 0.15 + 0.7 * i / k)
        depth = render_depth(cam, V, F) if depths is None else depths[i]
        mask = None if masks is None else masks[i]
        g[i], colors[i] = _photo_weight(texels, cam, photo, depth, size, feather_mm, tol_mm, mask)
        weight_maps[i].reshape(-1)[texels.idx] = g[i]

    step("blending and hole filling", 0.85)
    image, coverage = _blend_texels(texels, colors, g, size, fill)
    vidx, sfaces, seam_uv = seam_render_mesh(cmap, V, F)
    return CylindricalTexture(
        image=image,
        weight_maps=weight_maps,
        uv=cmap.uv(V),
        coverage=coverage,
        surface=texels.raster.surface,
        cylinder=cmap,
        seam_vertices=vidx,
        seam_faces=sfaces,
        seam_uv=seam_uv,
    )


def _check_texture_inputs(vertices, faces, cameras, photos, size, depths, single_view, masks=None):
    """:func:`cylindrical_texture`'s arguments checked: ``(V, F, photos, size, single_view)``, or a
    ValueError naming the one that does not fit."""
    V, F = check_mesh(vertices, faces)
    size = int(size)
    if not 8 <= size <= 16384:
        raise ValueError(f"texture size must be between 8 and 16384 texels, got {size}")
    photos = check_photos(cameras, photos)
    if depths is not None and len(depths) != len(cameras):
        raise ValueError(f"{len(cameras)} cameras but {len(depths)} depth maps")
    if masks is not None:
        if len(masks) != len(cameras):
            raise ValueError(f"{len(cameras)} cameras but {len(masks)} masks")
        for i, (m, p) in enumerate(zip(masks, photos, strict=True)):
            if np.shape(m) != p.shape[:2]:
                raise ValueError(f"mask {i} is {np.shape(m)} but its photo is {p.shape[:2]}")
    if single_view is not None:
        single_view = np.asarray(single_view, dtype=np.float32).reshape(-1)
        if single_view.shape != (len(V),):
            raise ValueError(f"single_view must be ({len(V)},), got shape {np.shape(single_view)}")
    return V, F, photos, size, single_view


@dataclass
class _SurfaceTexels:
    """The texels on the mesh's surface: their indices into the flattened ``size × size`` raster
    ``idx`` (t,), surface points ``pts`` (t, 3) float32 mm, unit normals ``nrm`` (t, 3) and the texel's
    size on the surface ``(sy, sx)`` mm (for a feathering width in mm), and the single-view
    fallback's weight ``single_view`` (t,) float32 (None: blend everywhere)."""

    raster: CylinderRaster
    idx: np.ndarray
    pts: np.ndarray
    nrm: np.ndarray
    texel_mm: tuple[float, float]
    single_view: np.ndarray | None


def _surface_texels(cmap: CylinderMap, V, F, size: int, single_view) -> _SurfaceTexels:
    normals = vertex_normals(V, F)
    attr = np.column_stack([normals, np.zeros(len(V)) if single_view is None else single_view])
    raster = rasterise_cylinder(cmap, V, F, size, attr)
    surf = raster.surface
    idx = np.flatnonzero(surf)
    pts = raster.points.reshape(-1, 3)[idx]  # float32: see project_points
    nrm = raster.attributes.reshape(-1, 4)[idx, :3]
    nrm /= np.maximum(np.sqrt(np.einsum("ij,ij->i", nrm, nrm)), np.float32(1e-12))[:, None]
    r_med = float(np.median(raster.radius[surf])) if idx.size else 1.0
    sx = r_med * (cmap.phi_range[1] - cmap.phi_range[0]) / size
    sy = (cmap.y_range[1] - cmap.y_range[0]) / size
    s = None if single_view is None else raster.attributes.reshape(-1, 4)[idx, 3]
    return _SurfaceTexels(raster, idx, pts, nrm, (sy, sx), s)


def _photo_weight(texels: _SurfaceTexels, cam, photo, depth, size: int, feather_mm: float, tol_mm: float, mask=None):
    """One photograph's blending weight ``g_k = F_k P_k`` (t,) of each surface texel and its
    colour there (t, 3) uint8 (§5.2.1); texels seen outside ``mask`` (H, W) bool are not visible."""
    idx, pts = texels.idx, texels.pts
    # project_points, positional_certainty and the bilinear depth_visible in one compiled pass
    RT = np.column_stack([cam.R, cam.t])
    M = np.zeros((4, 4))
    M[:2] = (cam.K @ RT)[:2]
    M[2, 3] = 1.0
    M[3] = RT[2]
    depth = np.ascontiguousarray(depth, dtype=np.float32)
    uv, P, vis = photo_texels(M, RT, pts, texels.nrm, depth, float(tol_mm))
    if mask is not None:
        h, w = mask.shape
        col = np.clip(np.round(uv[:, 0]), 0, w - 1).astype(np.intp)
        row = np.clip(np.round(uv[:, 1]), 0, h - 1).astype(np.intp)
        vis &= mask[row, col]
    binary = np.ones((size, size), bool)  # texels off the surface are not a visibility boundary
    binary.reshape(-1)[idx] = vis
    Fk = feather(binary, feather_mm, pixel_size=texels.texel_mm).reshape(-1)[idx]
    return Fk * P, sample_image(photo, uv)  # F_k is 0 wherever the texel is not visible


def _blend_texels(texels: _SurfaceTexels, colors, g, size: int, fill: bool) -> tuple[np.ndarray, np.ndarray]:
    """The blended ``size × size`` texture (uint8 RGB), holes filled when ``fill``, and its coverage."""
    idx = texels.idx
    if texels.single_view is None:
        blended, total = blend(colors, g)
    else:  # apply_single_view and blend in one compiled pass
        blended, total = blend_single_view(g, colors, np.ascontiguousarray(texels.single_view, dtype=np.float32))
    image = np.zeros((size * size, 3), np.float32)
    image[idx] = blended
    coverage = np.zeros(size * size, bool)
    coverage[idx] = total > 0
    image = image.reshape(size, size, 3)
    coverage = coverage.reshape(size, size)
    if fill:
        image = fill_holes(image, coverage)
    return np.clip(np.round(image), 0, 255).astype(np.uint8), coverage


def render_cylindrical(
    camera: Camera,
    vertices: np.ndarray,
    faces: np.ndarray,
    uv: np.ndarray,
    texture,
    **kwargs,
):
    """Render the mesh with its cylindrical texture: :meth:`photomodel.rendering.renderer.Renderer.render`
    with ``uv`` and ``texture`` (a (S, S, 3) uint8 image or an uploaded ``GLTexture``).

    For a mesh with triangles across the seam pass :meth:`CylindricalTexture.render_mesh`'s
    vertices, faces and uv. Other keyword arguments go to the renderer (``background``,
    ``supersample``, ...).

    Returns
    -------
    photomodel.rendering.renderer.RenderResult
        ``color`` (H, W, 3) float32 in [0, 1].
    """

    return get_renderer().render(camera, vertices, faces, uv=uv, texture=texture, **kwargs)
