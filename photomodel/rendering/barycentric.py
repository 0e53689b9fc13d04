"""Barycentric rasterisation: which triangle covers each pixel, and where in it.

:meth:`photomodel.rendering.renderer.Renderer.rasterize_barycentric` draws a mesh once with
each triangle's corners carrying the barycentric basis (1, 0, 0), (0, 1, 0), (0, 0, 1) and
reads back, at every covered pixel centre, the triangle and the perspective-correct
barycentric coordinates. Any per-vertex quantity is then interpolated at the covered pixels in
numpy (:meth:`BarycentricRaster.interpolate`: a gather over the covered pixels, exactly what
rendering it as a float attribute would give, without one pass per four channels). The
tracker's face model (Pighin et al. 2002, §6.1: Eq. 5 and the Jacobian of §6.1.3) is drawn
this way.

This module holds the pass itself (shaders, the GL buffer kept between calls) and its result;
the renderer owns the context and calls it. The mesh is drawn unwelded — each triangle's three
corners in turn, ``3·m`` vertices in camera coordinates gathered per call — and the vertex shader
gives corner ``gl_VertexID mod 3`` its barycentric basis and triangle ``gl_VertexID div 3`` its
id. (It was a geometry shader on the welded mesh; llvmpipe runs geometry shaders slowly: the
face model's 15 630 triangles at 300×300 took 11.8 ms a pass with it, 9.2 ms without, the
coverage identical and one pixel of 24 437 taking the other triangle of a depth tie.) The target
is one RGBA32F image, ``(b1, b2, id + 1, 0)``, cleared and read back over the mesh's bounding box
only.
"""

from __future__ import annotations

from dataclasses import dataclass

import moderngl
import numpy as np

from photomodel.camera import Camera

__all__ = ["BarycentricRaster", "interpolate"]

VERTEX_SHADER = """
#version 330
uniform mat4 proj;
in vec3 in_pos;
out vec2 v_bary;
flat out float v_face;
void main() {
    int corner = gl_VertexID % 3;
    v_bary = vec2(corner == 1 ? 1.0 : 0.0, corner == 2 ? 1.0 : 0.0);
    v_face = float(gl_VertexID / 3 + 1);
    gl_Position = proj * vec4(in_pos, 1.0);
}
"""
FRAGMENT_SHADER = """
#version 330
in vec2 v_bary;
flat in float v_face;
out vec4 out_bary;
void main() { out_bary = vec4(v_bary, v_face, 0.0); }
"""


@dataclass
class BarycentricRaster:
    """What :meth:`~photomodel.rendering.renderer.Renderer.rasterize_barycentric` saw.

    Attributes
    ----------
    shape : (H, W), the camera's image.
    box : (y0, y1, x0, x1) int
        the image rows/columns holding the projected mesh (clipped to the image); every covered
        pixel lies inside. ``(0, 0, 0, 0)`` when nothing is in view.
    pixels : (N,) int, flat indices of the covered pixels in the (H, W) image, row-major order.
    face_ids : (N,) int, the triangle (row of ``faces``) under each covered pixel.
    corners : (N, 3) int, the vertex at each corner of that triangle.
    bary : (N, 3) float32, perspective-correct barycentric coordinates at the pixel centres.
    """

    shape: tuple[int, int]
    box: tuple[int, int, int, int]
    pixels: np.ndarray
    face_ids: np.ndarray
    corners: np.ndarray
    bary: np.ndarray

    @property
    def mask(self) -> np.ndarray:
        """(H, W) bool, the covered pixels."""
        mask = np.zeros(self.shape, bool)
        mask.reshape(-1)[self.pixels] = True
        return mask

    def interpolate(self, values: np.ndarray) -> np.ndarray:
        """(N, ...) the per-vertex ``values`` (n, ...) interpolated at the covered pixels."""
        values = np.asarray(values)
        flat = interpolate(values.reshape(len(values), -1), self.corners, self.bary)
        return flat.reshape((len(self.bary),) + values.shape[1:])


def interpolate(values: np.ndarray, corners: np.ndarray, bary: np.ndarray) -> np.ndarray:
    """(N, C) barycentric interpolation of per-vertex ``values`` (n, C) at pixels with ``corners``
    (N, 3) and ``bary`` (N, 3): three row gathers (``np.take``) accumulated in place; float32 in,
    float32 out (float64 stays float64)."""
    dtype = np.result_type(values.dtype, np.float32)
    values = np.asarray(values, dtype)
    c, b = corners.T, bary.T  # (3, N), contiguous rows when made by unpack
    at = np.take(values, c[0], axis=0)
    at *= b[0][:, None]
    t = np.take(values, c[1], axis=0)
    t *= b[1][:, None]
    at += t
    np.take(values, c[2], axis=0, out=t)
    t *= b[2][:, None]
    at += t
    return at


def pixel_box(camera: Camera, Xc: np.ndarray, near: float) -> tuple[int, int, int, int] | None:
    """(y0, y1, x0, x1): the image rows/columns that camera-space vertices ``Xc`` (n, 3) can cover
    — their projections' bounding box when all lie beyond ``near``, the whole frame when some do
    not (their projections say nothing) — or None when nothing can be seen."""
    W, H = camera.width, camera.height
    z = Xc[:, 2]
    front = z > near
    if not np.any(front):
        return None
    if np.all(front):
        uv = camera.f * Xc[:, :2] / z[:, None] + camera.principal_point
        (u0, v0), (u1, v1) = uv.min(0), uv.max(0)
        x0, x1 = int(np.clip(np.floor(u0), 0, W)), int(np.clip(np.ceil(u1) + 1, 0, W))
        y0, y1 = int(np.clip(np.floor(v0), 0, H)), int(np.clip(np.ceil(v1) + 1, 0, H))
    else:
        x0, x1, y0, y1 = 0, W, 0, H
    if x1 <= x0 or y1 <= y0:
        return None
    return y0, y1, x0, x1


def unpack(raw: np.ndarray, box: tuple, shape: tuple[int, int], faces: np.ndarray) -> BarycentricRaster:
    """The :class:`BarycentricRaster` of a read-back ``raw`` (h, w, 4) of (b1, b2, id + 1, 0) over the
    image rows/columns ``box``. Its (N, 3) arrays are transposes of (3, N) ones, so that each
    corner's column is contiguous for :func:`interpolate`."""
    y0, _, x0, x1 = box
    ids = raw[..., 2].reshape(-1)  # face id + 1 (exact in float32); 0 is the cleared background
    local = np.flatnonzero(ids > 0.5)
    py, px = np.divmod(local, max(x1 - x0, 1))
    pixels = (py + y0) * shape[1] + (px + x0)
    fid = ids[local].astype(np.intp) - 1
    B = np.empty((3, len(local)), np.float32)
    B[1] = raw[..., 0].reshape(-1)[local]
    B[2] = raw[..., 1].reshape(-1)[local]
    np.subtract(1.0, B[1], out=B[0])
    B[0] -= B[2]
    corners = np.take(np.ascontiguousarray(faces.T), fid, axis=1)  # (3, N)
    return BarycentricRaster(tuple(shape), tuple(box), pixels, fid, corners.T, B.T)


def empty(shape: tuple[int, int], faces: np.ndarray) -> BarycentricRaster:
    """The raster of a mesh that covers no pixel."""
    return unpack(np.zeros((0, 0, 4), np.float32), (0, 0, 0, 0), shape, faces)


class BarycentricPass:
    """The GL side of barycentric rasterisation in one renderer's context, with its vertex buffer
    kept between calls (re-made when the number of triangles changes): the triangles' corners
    are gathered and written per call (15k triangles, ~0.5 ms), and only the bounding box is
    cleared and read. Made and called by the renderer inside its context, into a framebuffer of
    its cache."""

    def __init__(self, ctx, program):
        self.ctx = ctx
        self.prog = program
        self._m = -1
        self.vbo = self.vao = None

    def _buffers(self, m: int) -> None:
        if self._m == m:
            return
        for obj in (self.vao, self.vbo):
            if obj is not None:
                obj.release()
        self.vbo = self.ctx.buffer(reserve=max(m, 1) * 36)
        self.vao = self.ctx.vertex_array(self.prog, [(self.vbo, "3f", "in_pos")])
        self._m = m

    def draw(self, fbo, proj: np.ndarray, Xc: np.ndarray, faces: np.ndarray, box: tuple):
        """Rasterise camera-space vertices ``Xc`` (n, 3) mm with the GL projection ``proj`` (4, 4)
        into ``fbo`` (one RGBA32F colour attachment and a depth buffer, the frame's size); returns
        the (h, w, 4) float32 read-back of ``box``."""

        y0, y1, x0, x1 = box
        out = np.empty((y1 - y0, x1 - x0, 4), np.float32)
        self._buffers(len(faces))
        fbo.use()
        fbo.viewport = (0, 0, *fbo.size)
        self.ctx.disable(moderngl.BLEND | moderngl.CULL_FACE)
        self.ctx.enable(moderngl.DEPTH_TEST)
        view = (x0, y0, x1 - x0, y1 - y0)  # framebuffer row i is image row i (gl_projection)
        fbo.clear(0.0, 0.0, 0.0, 0.0, depth=1.0, viewport=view)
        self.prog["proj"].write(proj.T.astype(np.float32).tobytes())
        self.vbo.write(np.asarray(Xc, np.float32)[np.asarray(faces).reshape(-1)].tobytes())
        self.vao.render(moderngl.TRIANGLES, vertices=3 * len(faces))
        fbo.read_into(out, viewport=view, components=4, attachment=0, dtype="f4", alignment=1)
        return out

    def release(self) -> None:
        """Free the buffers (the program and the framebuffers belong to the renderer's caches)."""
        for obj in (self.vao, self.vbo):
            if obj is not None:
                obj.release()
        self.vbo = self.vao = None
        self._m = -1
