"""The one renderer of Face Studio: triangle meshes seen through a :class:`~photomodel.camera.Camera`.

Texture extraction (Pighin et al. 2002, §5.2.1: "render the face model using the recovered
viewing parameters and save the resulting depth map from the Z-buffer" for visibility —
``RenderResult.depth`` / ``face_id``), tracking (§6.1: rendering the textured model at a pose,
and per-vertex derivatives as float attributes for the Jacobian of §6.1.3), the GUI previews
and the sample-project generator all draw through this renderer, so a pixel means the same
thing everywhere. Public API: :meth:`Renderer.render` (colour, depth, face id, coverage),
:meth:`Renderer.rasterize_barycentric` (the triangle and barycentric coordinates under each
covered pixel, for per-vertex quantities interpolated in numpy: the tracker's face model),
:meth:`Renderer.upload_texture`, and for shader code beside this module
:meth:`Renderer.context`, :meth:`Renderer.program`, :meth:`Renderer.defer_release`. CPU twins
of what the shaders compute: :func:`vertex_normals` (Lambert shading) here, the texture look-up
in :mod:`photomodel.rendering.sampling`.

Why moderngl
------------
OpenGL rasterisation is what the paper's pipeline assumes (z-buffer visibility, texture
lookups); ``moderngl`` is a small, kept Python binding that creates a *headless* context on
EGL (Mesa ``llvmpipe`` on machines without a GPU), needs no window system and reads float
render targets back into numpy. A hand-written numpy rasteriser would be slower and would
re-implement the GL fill rules.

Conventions (see :mod:`photomodel.camera`)
------------------------------------------
* Vertices are in world millimetres and go through ``X_cam = R X + t`` on the CPU in float64;
  only camera coordinates (float32) reach the GPU, so large translations lose no precision.
* Our pixel ``(u, v)`` (centres at integers, ``v`` down) is the GL pixel whose window
  coordinates are ``(u + 0.5, v + 0.5)`` — GL samples at pixel centres ``i + 0.5``. The
  projection of :func:`gl_projection` maps ``v`` *down* to window ``y`` *up*, so the
  framebuffer's first row read back is image row 0 (the top of the image): no flip is needed
  after reading. A consequence is that the mirror flips the winding: triangles that are
  counter-clockwise seen from outside (OBJ convention) are clockwise in the window, hence
  ``front_face='cw'`` when culling.
* A rendered vertex lands exactly on :meth:`Camera.project` of it (to float32 and GL
  sub-pixel precision, ~1/256 px on llvmpipe); a pixel is covered when its centre lies in the
  projected triangle (GL fill rule on shared edges).
* Texture coordinates have ``v`` up (OBJ/OpenGL): ``uv = (0, 0)`` is the bottom-left corner
  of the texture image and ``(0, 1)`` its top-left, i.e. image row 0. Textures are sampled
  bilinearly with clamp-to-edge.

Threads
-------
An OpenGL context belongs to the thread that created it. :func:`get_renderer` therefore
keeps one :class:`Renderer` *per thread* (``threading.local``); a :class:`Renderer` refuses
(``RuntimeError``) to be used from another thread than the one that created it.

Code beside this module
-----------------------
:mod:`photomodel.rendering.barycentric` holds the barycentric pass that
:meth:`Renderer.rasterize_barycentric` runs (shaders, buffers kept between calls, its result).
:mod:`photomodel.rendering.view_dependent_pass` (view-dependent texturing in fragment shaders) draws in the same
context through public methods only: :meth:`Renderer.context` (the checked moderngl context),
:meth:`Renderer.program` (programs compiled once per renderer) and
:meth:`Renderer.defer_release` (GL objects dropped by a finaliser, which may run in any thread,
are freed at the renderer's next use in its own thread).

Cost (Mesa llvmpipe, 2 shared CPU cores): ~55 ms per 1000×1000 frame of the 12k-triangle james
scan (colour, depth and face id read back), +10–35 ms when the 2400×1600 texture is uploaded
per call instead of once with :meth:`Renderer.upload_texture`. Vertex and index buffers are
uploaded per call: under 1 ms for meshes of this size, so they are not cached.

``python benchmarks/bench_render.py out.png`` renders the james sample scan from the front and times it.
"""

from __future__ import annotations

import threading
from collections import OrderedDict
from dataclasses import dataclass

import cv2
import moderngl
import numpy as np

from photomodel.camera import Camera
from photomodel.rendering import barycentric
from photomodel.rendering.barycentric import BarycentricRaster

__all__ = [
    "BarycentricRaster",
    "RenderResult",
    "Renderer",
    "GLTexture",
    "get_renderer",
    "gl_projection",
    "auto_near_far",
    "vertex_normals",
]

#: Framebuffers of this many (kind, image size) pairs are kept alive (least recently used first
#: out): four sizes of both the render and the barycentric target.
_MAX_CACHED_TARGETS = 8
#: Ambient term of the head-light Lambert shading: a face seen edge-on is not black.
_AMBIENT = 0.15
#: Albedo of an untextured, uncoloured mesh under ``shading``.
_ALBEDO = 0.8

_VERTEX_SHADER = """
#version 330
uniform mat4 proj;
in vec3 in_pos;      // camera coordinates, mm
in vec4 in_attr;     // per-vertex attribute: colour channels, or uv in .xy
in vec3 in_normal;   // camera coordinates (only read when shading == 1)
out vec4 v_attr;
out vec3 v_normal;
out vec3 v_pos;
void main() {
    v_attr = in_attr;
    v_normal = in_normal;
    v_pos = in_pos;
    gl_Position = proj * vec4(in_pos, 1.0);
}
"""

_FRAGMENT_SHADER = """
#version 330
uniform int mode;       // 0: interpolated attribute, 1: texture at uv, 2: constant albedo
uniform int shading;    // 0: none, 1: Lambert with vertex normals, 2: Lambert, flat
uniform float ambient;
uniform float albedo;
uniform sampler2D tex;
in vec4 v_attr;
in vec3 v_normal;
in vec3 v_pos;
layout(location = 0) out vec4 out_color;
layout(location = 1) out float out_depth;
layout(location = 2) out int out_face;
void main() {
    vec4 c;
    if (mode == 1) {
        c = texture(tex, vec2(v_attr.x, 1.0 - v_attr.y));  // v up; row 0 uploaded first = t 0
    } else if (mode == 0) {
        c = v_attr;
    } else {
        c = vec4(albedo, albedo, albedo, 1.0);
    }
    if (shading != 0) {
        vec3 n = (shading == 1) ? v_normal : cross(dFdx(v_pos), dFdy(v_pos));
        float len = length(n);
        // head-light along the optical axis: l = (0, 0, -1) in camera coordinates; two-sided
        float lambert = (len > 0.0) ? abs(n.z) / len : 1.0;
        c.rgb *= ambient + (1.0 - ambient) * lambert;
    }
    out_color = c;
    out_depth = v_pos.z;
    out_face = gl_PrimitiveID + 1;  // 0 is the cleared background
}
"""


# ----------------------------------------------------------------------------- pure helpers


def gl_projection(camera: Camera, near: float, far: float) -> np.ndarray:
    """The (4, 4) OpenGL projection of ``camera`` acting on *camera* coordinates.

    ``clip = P @ [X_cam, 1]`` gives, after the perspective division and the viewport
    transform of a ``width × height`` viewport, window coordinates
    ``(u + 0.5, v + 0.5)`` where ``(u, v) = camera.project(X)``; ``v`` down maps to window
    ``y`` up, so framebuffer row ``i`` read back is image row ``i`` (top first). Depth:
    ``Z_cam = near`` → NDC ``-1``, ``Z_cam = far`` → ``+1`` (standard perspective depth).

    Parameters
    ----------
    camera : Camera
        intrinsics ``f`` (px), principal point ``(c_x, c_y)``, image size ``W × H``.
    near, far : float
        clipping distances along the optical axis in mm, ``0 < near < far``.

    Returns
    -------
    (4, 4) float64, row-major (transpose before handing it to GL as column-major).
    """
    if not (0.0 < near < far):
        raise ValueError(f"need 0 < near < far, got near={near}, far={far}")
    W, H, f = camera.width, camera.height, camera.f
    cx, cy = camera.principal_point
    # x_ndc = 2 (u + 0.5) / W - 1 with u = f X/Z + cx, times w_clip = Z
    return np.array(
        [
            [2.0 * f / W, 0.0, 2.0 * (cx + 0.5) / W - 1.0, 0.0],
            [0.0, 2.0 * f / H, 2.0 * (cy + 0.5) / H - 1.0, 0.0],
            [0.0, 0.0, (far + near) / (far - near), -2.0 * far * near / (far - near)],
            [0.0, 0.0, 1.0, 0.0],
        ]
    )


def auto_near_far(z_cam: np.ndarray) -> tuple[float, float] | None:
    """Near and far planes (mm) that enclose the depths ``z_cam`` (n,) of a mesh's vertices.

    A 10 % margin on both sides; geometry behind the camera is clipped at ``near``.
    Returns ``None`` when no vertex is in front of the camera.
    """
    z = np.asarray(z_cam, dtype=float)
    z = z[z > 0]
    if z.size == 0:
        return None
    zmin, zmax = float(z.min()), float(z.max())
    # a near plane very close to the eye wastes depth-buffer precision; 1e-3·far is plenty
    near = max(0.9 * zmin, 1e-3 * zmax)
    far = 1.1 * zmax
    if far <= near:  # a single depth: give the planes room
        far = near * 2.0
    return near, far


def vertex_normals(vertices: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """(n, 3) unit vertex normals: area-weighted sums of the incident faces' normals.

    Counter-clockwise faces (seen from outside) give outward normals; isolated vertices get 0.
    """
    v = np.asarray(vertices, dtype=float)
    f = np.asarray(faces)
    face_n = np.cross(v[f[:, 1]] - v[f[:, 0]], v[f[:, 2]] - v[f[:, 0]])  # |·| = 2 area
    n = np.zeros_like(v)
    for k in range(3):
        n += np.stack([np.bincount(f[:, k], face_n[:, c], minlength=len(v)) for c in range(3)], axis=1)
    length = np.linalg.norm(n, axis=1, keepdims=True)
    return np.divide(n, length, out=np.zeros_like(n), where=length > 0)


# ----------------------------------------------------------------------------- result


@dataclass
class RenderResult:
    """What one :meth:`Renderer.render` call saw, one value per image pixel (row 0 = top).

    Attributes
    ----------
    color : (H, W, C) float32
        texture colour (``0..1`` for a ``uint8`` texture), interpolated per-vertex ``colors``
        (any float values, perspective-correct, not clamped) or shading; ``background``
        where nothing is drawn. ``C`` is the channel count of the texture / ``colors``
        (3 for plain shading).
    depth : (H, W) float32
        camera-space ``Z_cam`` in mm of the visible surface; ``inf`` on the background.
    mask : (H, W) bool
        pixel centre covered by a triangle.
    face_id : (H, W) int32
        index into ``faces`` of the visible triangle; ``-1`` on the background.
    coverage : (H, W) float32
        fraction of sub-samples covered (``supersample > 1``); equals ``mask`` otherwise.
    near, far : float
        the clipping planes used (mm).
    """

    color: np.ndarray
    depth: np.ndarray
    mask: np.ndarray
    face_id: np.ndarray
    coverage: np.ndarray
    near: float
    far: float


# ----------------------------------------------------------------------------- renderer


@dataclass(eq=False)
class GLTexture:
    """A texture resident in a :class:`Renderer`'s context (see :meth:`Renderer.upload_texture`).

    Attributes
    ----------
    renderer : Renderer
        the owner; the handle is only valid with it.
    gl : moderngl.Texture
    channels : int
        ``C`` of the image, the channel count of ``RenderResult.color``.
    shape : (int, int)
        ``(Ht, Wt)`` of the image in pixels.
    """

    renderer: Renderer
    gl: object
    channels: int
    shape: tuple[int, int]
    released: bool = False

    def release(self) -> None:
        """Free the GL texture (idempotent)."""
        if not self.released and not self.renderer.released:
            self.gl.release()
        self.released = True


def _create_context():

    errors = []
    for kwargs in ({"backend": "egl"}, {}):
        try:
            return moderngl.create_context(standalone=True, require=330, **kwargs)
        except Exception as exc:  # noqa: BLE001 - every backend failure is reported together
            errors.append(f"{kwargs.get('backend', 'default')}: {exc}")
    raise RuntimeError(
        "Face Studio could not create a headless OpenGL 3.3 context for rendering ("
        + "; ".join(errors)
        + "). Install an EGL/OpenGL driver, e.g. on Debian/Ubuntu `apt-get install libegl1 "
        "libgl1-mesa-dri` (Mesa's llvmpipe renders on the CPU when there is no GPU)."
    )


class Renderer:
    """A headless OpenGL renderer of triangle meshes through :class:`Camera` (see module notes).

    Create it with :func:`get_renderer` (one per thread) rather than directly. It owns a
    moderngl context, one compiled program and float framebuffers cached per image size;
    vertex buffers are uploaded per call. Use it only from the thread that created it, and
    call :meth:`release` to free the GL resources early.
    """

    def __init__(self):

        self._moderngl = moderngl
        self._thread = threading.get_ident()
        self.ctx = _create_context()
        with self.ctx:
            self._prog = self.ctx.program(vertex_shader=_VERTEX_SHADER, fragment_shader=_FRAGMENT_SHADER)
            self._prog["tex"].value = 0
            self._prog["ambient"].value = _AMBIENT
            self._prog["albedo"].value = _ALBEDO
            self.max_size = int(self.ctx.info["GL_MAX_RENDERBUFFER_SIZE"])
        self._fbos: OrderedDict[tuple[str, int, int], tuple] = OrderedDict()
        self._programs: dict[tuple[str, str, str | None], object] = {}
        self._barycentric: barycentric.BarycentricPass | None = None
        self._release_queue: list = []
        self.released = False

    # -- resources ----------------------------------------------------------------
    def _check_usable(self):
        if self.released:
            raise RuntimeError("this Renderer was released; call get_renderer() for a new one")
        if threading.get_ident() != self._thread:
            raise RuntimeError(
                "an OpenGL context belongs to the thread that created it: use get_renderer() "
                "in this thread instead of sharing a Renderer between threads"
            )

    def _framebuffer(self, kind: str, size: tuple[int, int]):
        """The framebuffer of ``kind`` (``"render"``: colour, ``Z_cam``, face id; ``"barycentric"``:
        :mod:`photomodel.rendering.barycentric`'s target) and ``size`` = (W, H), made on first use;
        the :data:`_MAX_CACHED_TARGETS` most recently used are kept."""
        key = (kind, *size)
        if key in self._fbos:
            self._fbos.move_to_end(key)
            return self._fbos[key][0]
        if kind == "render":
            attachments = [
                self.ctx.renderbuffer(size, components=4, dtype="f4"),  # colour
                self.ctx.renderbuffer(size, components=1, dtype="f4"),  # Z_cam
                self.ctx.renderbuffer(size, components=1, dtype="i4"),  # face index + 1
            ]
        else:
            attachments = [self.ctx.renderbuffer(size, components=4, dtype="f4")]  # (b1, b2, id + 1, 0)
        depth = self.ctx.depth_renderbuffer(size)
        fbo = self.ctx.framebuffer(attachments, depth)
        self._fbos[key] = (fbo, *attachments, depth)
        while len(self._fbos) > _MAX_CACHED_TARGETS:
            _, old = self._fbos.popitem(last=False)
            for obj in old:
                obj.release()
        return fbo

    def context(self):
        """The moderngl context, for GL code beside this module that draws with this renderer.

        :mod:`photomodel.rendering.view_dependent_pass` (view-dependent texturing in a fragment shader) builds its
        textures, buffers and framebuffers in this context, so everything Face Studio draws
        shares one context per thread. Enter it (``with renderer.context() as ctx:``) around
        GL calls; objects made in it die with :meth:`release`, after which this raises.

        Raises
        ------
        RuntimeError
            from another thread than the renderer's, or after :meth:`release`.
        """
        self._check_usable()
        self._collect()
        return self.ctx

    def defer_release(self, objects) -> None:
        """Release these GL objects of this renderer at its next use, in its own thread.

        For finalisers (``weakref.finalize``), which may run in any thread: a GL call is
        only valid in the context's thread, so they hand the objects over here instead.
        """
        self._release_queue.extend(objects)  # list.extend is atomic under the GIL

    def _collect(self) -> None:
        if not self._release_queue or self.released:
            return
        with self.ctx:
            while self._release_queue:
                self._release_queue.pop().release()

    def program(self, vertex_shader: str, fragment_shader: str, geometry_shader: str | None = None):
        """A ``moderngl.Program`` of these shader sources, compiled once per renderer (cached).

        Compiling costs ~10–100 ms on llvmpipe; code beside this module asks for its programs
        here instead of compiling per object. Released with the renderer.
        """
        self._check_usable()
        key = (vertex_shader, fragment_shader, geometry_shader)
        prog = self._programs.get(key)
        if prog is None:
            with self.ctx:
                prog = self._programs[key] = self.ctx.program(
                    vertex_shader=vertex_shader, fragment_shader=fragment_shader, geometry_shader=geometry_shader
                )
        return prog

    def release(self) -> None:
        """Free every GL object and the context. The renderer cannot be used afterwards."""
        if self.released:
            return
        for objs in self._fbos.values():
            for obj in objs:
                obj.release()
        self._fbos.clear()
        if self._barycentric is not None:
            self._barycentric.release()
            self._barycentric = None
        for prog in self._programs.values():
            prog.release()
        self._programs.clear()
        self._release_queue.clear()  # the context's release frees them
        self._prog.release()
        self.ctx.release()
        self.released = True

    def upload_texture(self, image: np.ndarray) -> GLTexture:
        """Upload a texture image once, to pass as ``texture=`` to many :meth:`render` calls.

        Uploading a 2400×1600 RGB image costs ~10–35 ms on llvmpipe, as much as the rest of
        a 1000×1000 frame, so a tracker rendering one texture per video frame keeps it here.
        The handle does not follow later changes of ``image``; upload again after editing it.

        Parameters
        ----------
        image : (Ht, Wt) or (Ht, Wt, C), C in 1..4
            ``uint8`` (read as ``0..1``), ``uint16`` (``0..1``) or float (values kept);
            row 0 is the top of the image (``v = 1``).
        """
        self._check_usable()
        data, channels = _texture_array(image)
        with self.ctx:
            gl = _upload_texture(self.ctx, data)
        return GLTexture(self, gl, channels, (data.shape[0], data.shape[1]))

    # -- rendering ------------------------------------------------------------------
    def render(
        self,
        camera: Camera,
        vertices: np.ndarray,
        faces: np.ndarray,
        *,
        uv: np.ndarray | None = None,
        texture: np.ndarray | None = None,
        colors: np.ndarray | None = None,
        background=0.0,
        cull_backfaces: bool = False,
        shading: str | None = None,
        near: float | None = None,
        far: float | None = None,
        supersample: int = 1,
    ) -> RenderResult:
        """Render a triangle mesh as ``camera`` sees it.

        Parameters
        ----------
        camera : Camera
            pose and intrinsics; the image is ``camera.height × camera.width``.
        vertices : (n, 3) float
            world positions in mm.
        faces : (m, 3) int
            triangles (indices into ``vertices``); ``face_id`` refers to rows of this array.
        uv : (n, 2) float, optional
            texture coordinates, ``v`` up (OBJ/OpenGL convention); required with ``texture``.
        texture : (Ht, Wt) or (Ht, Wt, C) with C in 1..4, or GLTexture, optional
            ``uint8`` (read as ``0..1``), ``uint16`` (``0..1``) or float (values kept); row 0
            is the top of the image. Uploaded per call; reuse a :meth:`upload_texture` handle
            to skip the upload.
        colors : (n,) or (n, k) float, optional
            per-vertex attributes of any ``k ≥ 1`` and any float values, interpolated
            perspective-correctly into float32 targets (no clamping) — e.g. vertex
            indices, world positions or derivatives. Rendered 4 channels per pass.
        background : float or (C,) sequence
            ``color`` value of uncovered pixels.
        cull_backfaces : bool
            drop triangles seen from behind (clockwise seen from outside = back).
        shading : None, ``'lambert'`` or ``'flat'``
            multiply the colour (the texture, ``colors`` or a grey albedo of 0.8 when neither
            is given) by a Lambert term ``0.15 + 0.85 |n·l|`` with a head-light along the
            optical axis; ``'lambert'`` uses interpolated vertex normals, ``'flat'`` face normals.
        near, far : float, optional
            clipping distances in mm; by default the vertices' depth range plus 10 %
            (:func:`auto_near_far`).
        supersample : odd int
            render at ``supersample``× the resolution and box-filter ``color`` (anti-aliased
            edges, with ``coverage`` the covered fraction). ``depth``, ``mask`` and
            ``face_id`` are those of the central sub-sample, which sits exactly on the pixel
            centre, so they equal the ``supersample=1`` render.

        Returns
        -------
        RenderResult
        """
        self._check_usable()
        self._collect()
        ss = self._check_frame(camera, supersample)
        frame = camera if ss == 1 else Camera(camera.R, camera.t, camera.f * ss, camera.width * ss, camera.height * ss)
        color, depth, face, bg, near, far = self._render_pass(
            camera, frame, vertices, faces, uv, texture, colors, background, shading, near, far, cull_backfaces, True
        )
        return _resolve(color, depth, face, bg, ss, near, far)

    def _render_pass(
        self, camera, frame, vertices, faces, uv, texture, colors, background, shading, near, far, cull, read_face
    ):
        """The checks and the draw :meth:`render` and :meth:`render_rgb8` share: the mesh as
        ``camera`` sees it, drawn into a framebuffer of ``frame`` (the camera, or its supersampled
        copy; checked by the caller). Returns (colour, ``Z_cam``, face ids + 1 or None, background,
        near, far)."""
        V, F = _check_mesh(vertices, faces)
        if texture is not None and colors is not None:
            raise ValueError("give either texture (with uv) or colors, not both")
        if shading not in _SHADING:
            raise ValueError(f"shading must be None, 'lambert' or 'flat', got {shading!r}")
        channels = self._channels(len(V), uv, texture, colors)
        bg = _background(background, channels.count)
        Xc = camera.to_camera(V)  # float64 on the CPU, float32 on the GPU
        near, far, F = _clip_planes(Xc, F, near, far)
        normals = vertex_normals(V, F) @ camera.R.T if shading == "lambert" and len(F) else np.zeros((len(V), 3))
        with self.ctx:
            fbo = self._framebuffer("render", (frame.width, frame.height))
            self._set_state(fbo, gl_projection(frame, near, far), channels.mode, shading, cull)
            color, depth, face = self._draw(fbo, Xc, F, normals, channels, read_face=read_face)
        return color, depth, face, bg, near, far

    def render_rgb8(
        self,
        camera: Camera,
        vertices: np.ndarray,
        faces: np.ndarray,
        *,
        uv: np.ndarray | None = None,
        texture: np.ndarray | None = None,
        background=0.0,
        shading: str | None = None,
    ) -> tuple[np.ndarray, np.ndarray]:
        """An image to show: ``render(...)``'s colour as 8-bit RGB, and its depth.

        The same draw as :meth:`render` (same arguments), but the face ids are not read back and
        no mask or coverage is built: coverage is where the depth was drawn (``Z_cam > 0``, as
        :meth:`render_depth` tells it). The colour is ``render().color[..., :3]`` clipped to
        ``0..1`` and rounded to ``uint8`` (``x · 255 + ½`` truncated, in float32), the background's
        pixels too — the studio's 3D view after every refit, where reading the face ids and
        filling the float image took ~4 of its ~11 ms of CPU on llvmpipe.

        Returns
        -------
        rgb : (H, W, 3) uint8
        depth : (H, W) float32, ``Z_cam`` (mm), ``inf`` on the background.
        """
        self._check_usable()
        self._collect()
        self._check_frame(camera, 1)
        color, depth, _, bg, _, _ = self._render_pass(
            camera, camera, vertices, faces, uv, texture, None, background, shading, None, None, False, False
        )
        background_px = ~(depth > 0)  # cleared to 0; a drawn fragment lies beyond the near plane (> 0)
        np.putmask(depth, background_px, np.inf)
        rgb = color[..., :3]
        np.clip(rgb, 0, 1, out=rgb)
        rgb *= 255
        rgb += 0.5
        rgb = rgb.astype(np.uint8)
        bg8 = (np.clip(np.asarray(bg[:3], np.float32), 0, 1) * 255 + 0.5).astype(np.uint8)
        # the background's colour where nothing was drawn (OpenCV's masked copy: numpy's boolean
        # assignment of a pixel per masked row took 3–4 ms on a 400×800 image)
        cv2.copyTo(np.broadcast_to(bg8, rgb.shape).copy(), background_px.view(np.uint8), rgb)
        return rgb, depth

    def render_depth(
        self, camera: Camera, vertices: np.ndarray, faces: np.ndarray, *, near: float | None = None, far=None
    ) -> np.ndarray:
        """``render(camera, vertices, faces, near=near, far=far).depth`` without the rest.

        The same draw, but only the ``Z_cam`` target is read back: a depth map is what the
        visibility tests (texturing, the studio's overlay) need, and reading the colour and face
        targets too moved 6× the bytes (~2/3 of a 1000×1000 depth map's time on llvmpipe).

        Returns
        -------
        (H, W) float32
            ``Z_cam`` (mm) of the nearest surface at each pixel centre, ``inf`` on the background.
        """
        self._check_usable()
        self._collect()
        self._check_frame(camera, 1)
        V, F = _check_mesh(vertices, faces)
        Xc = camera.to_camera(V)
        near, far, F = _clip_planes(Xc, F, near, far)
        depth = np.zeros((camera.height, camera.width), np.float32)
        channels = _Channels(2, 3, [np.zeros((len(V), 4), np.float32)])
        with self.ctx:
            fbo = self._framebuffer("render", (camera.width, camera.height))
            self._set_state(fbo, gl_projection(camera, near, far), channels.mode, None, False)
            fbo.clear(0.0, 0.0, 0.0, 0.0, depth=1.0)
            if len(F):
                self._draw_only(Xc, F, channels.passes[0])
            fbo.read_into(depth, components=1, attachment=1, dtype="f4", alignment=1)
        depth[~(depth > 0)] = np.inf  # cleared to 0; a drawn fragment lies beyond the near plane (> 0)
        return depth

    def _draw_only(self, Xc: np.ndarray, F: np.ndarray, attributes: np.ndarray) -> None:
        """Draw the mesh once into the bound framebuffer (the first pass of :meth:`_draw`, no read-back)."""
        ctx, n = self.ctx, len(Xc)
        bufs = [
            ctx.buffer(Xc.astype(np.float32).tobytes()),
            ctx.buffer(attributes.tobytes()),
            ctx.buffer(np.zeros((n, 3), np.float32).tobytes()),
            ctx.buffer(np.ascontiguousarray(F, dtype=np.int32).tobytes()),
        ]
        layout = [(bufs[0], "3f", "in_pos"), (bufs[1], "4f", "in_attr"), (bufs[2], "3f", "in_normal")]
        vao = ctx.vertex_array(self._prog, layout, index_buffer=bufs[3], index_element_size=4)
        try:
            vao.render(self._moderngl.TRIANGLES)
        finally:
            for obj in (vao, *bufs):
                obj.release()

    def rasterize_barycentric(self, camera: Camera, vertices: np.ndarray, faces: np.ndarray) -> BarycentricRaster:
        """The triangle and the perspective-correct barycentric coordinates at every pixel centre
        that a mesh covers (:mod:`photomodel.rendering.barycentric`).

        The same rasterisation as :meth:`render` (z-buffer, fill rule, no culling, clipping planes
        of :func:`auto_near_far`), drawn and read back over the mesh's bounding box only. The
        triangles' corners are uploaded per call (unwelded: no geometry shader).

        Parameters
        ----------
        camera : Camera
        vertices : (n, 3) float, world mm.
        faces : (m, 3) int

        Returns
        -------
        BarycentricRaster
            interpolate per-vertex values at the covered pixels with its ``interpolate``.
        """
        self._check_usable()
        self._collect()
        self._check_frame(camera, 1)
        V, F = _check_mesh(vertices, faces)
        shape = (camera.height, camera.width)
        Xc = camera.to_camera(V)
        planes = auto_near_far(Xc[:, 2]) if len(F) else None
        box = None if planes is None else barycentric.pixel_box(camera, Xc, planes[0])
        if box is None:
            return barycentric.empty(shape, F)
        if self._barycentric is None:
            prog = self.program(barycentric.VERTEX_SHADER, barycentric.FRAGMENT_SHADER)
            self._barycentric = barycentric.BarycentricPass(self.ctx, prog)
        proj = gl_projection(camera, *planes)
        with self.ctx:
            fbo = self._framebuffer("barycentric", (camera.width, camera.height))
            raw = self._barycentric.draw(fbo, proj, Xc, F, box)
        return barycentric.unpack(raw, box, shape, F)

    def _check_frame(self, camera: Camera, supersample: int) -> int:
        """The supersampling factor, once the camera and the frame size are known to be drawable."""
        if not isinstance(camera, Camera):
            raise TypeError(f"camera must be a photomodel.camera.Camera, got {type(camera).__name__}")
        W, H = camera.width, camera.height
        if W < 1 or H < 1:
            raise ValueError(f"camera image size must be positive, got {W}×{H}")
        ss = int(supersample)
        if ss != supersample or ss < 1 or ss % 2 == 0:
            raise ValueError(f"supersample must be an odd positive integer, got {supersample!r}")
        if max(W, H) * ss > self.max_size:
            raise ValueError(f"{W}×{H} at supersample {ss} exceeds the GL renderbuffer limit of {self.max_size} px")
        return ss

    def _channels(self, n: int, uv, texture, colors) -> _Channels:
        """What the colour channels of a render are: a texture at ``uv``, ``colors`` or the albedo."""
        if texture is not None:
            if uv is None:
                raise ValueError("texture needs uv (n, 2) texture coordinates")
            if isinstance(texture, GLTexture):
                if texture.renderer is not self or texture.released:
                    raise ValueError("this GLTexture was released or uploaded by another Renderer")
                data, count = None, texture.channels
            else:
                data, count = _texture_array(texture)
            uv = np.asarray(uv, dtype=np.float32)
            if uv.shape != (n, 2):
                raise ValueError(f"uv must be (n, 2) = ({n}, 2), got {uv.shape}")
            attr = np.column_stack([uv, np.zeros((n, 2), np.float32)])
            return _Channels(1, count, [attr], texture if data is None else None, data)
        if colors is not None:
            A = np.asarray(colors, dtype=np.float32)
            if A.ndim == 1:
                A = A[:, None]
            if A.ndim != 2 or A.shape[0] != n or A.shape[1] < 1:
                raise ValueError(f"colors must be (n,) or (n, k) with n={n}, got {np.shape(colors)}")
            count = A.shape[1]
            passes = []
            for c0 in range(0, count, 4):
                chunk = np.zeros((n, 4), np.float32)
                chunk[:, : min(4, count - c0)] = A[:, c0 : c0 + 4]
                passes.append(chunk)
            return _Channels(0, count, passes)
        return _Channels(2, 3, [np.zeros((n, 4), np.float32)])

    def _set_state(self, fbo, proj: np.ndarray, mode: int, shading: str | None, cull_backfaces: bool) -> None:
        """Bind ``fbo`` and set the GL state and uniforms of :meth:`render`'s program."""
        mgl, ctx = self._moderngl, self.ctx
        fbo.use()
        fbo.viewport = (0, 0, *fbo.size)
        ctx.disable(mgl.BLEND)
        ctx.enable(mgl.DEPTH_TEST)
        if cull_backfaces:
            ctx.enable(mgl.CULL_FACE)
            ctx.front_face = "cw"  # our y-down projection mirrors the winding
            ctx.cull_face = "back"
        else:
            ctx.disable(mgl.CULL_FACE)
        self._prog["proj"].write(proj.T.astype(np.float32).tobytes())
        self._prog["mode"].value = mode
        self._prog["shading"].value = _SHADING[shading]

    def _draw(self, fbo, Xc: np.ndarray, F: np.ndarray, normals: np.ndarray, channels: _Channels, read_face=True):
        """Draw the mesh once per four colour channels; returns colour (Hs, Ws, C), ``Z_cam``
        (Hs, Ws) and face index + 1 (Hs, Ws, 0 = background; None unless ``read_face``) as read back."""
        ctx, n = self.ctx, len(Xc)
        Ws, Hs = fbo.size
        C = channels.count
        gl_objects = []
        try:
            if channels.texture is not None:
                channels.texture.gl.use(location=0)
            elif channels.data is not None:
                tex = _upload_texture(ctx, channels.data)
                gl_objects.append(tex)
                tex.use(location=0)
            if len(F):
                pos_buf = ctx.buffer(Xc.astype(np.float32).tobytes())
                attr_buf = ctx.buffer(reserve=n * 16)
                nrm_buf = ctx.buffer(normals.astype(np.float32).tobytes())
                idx_buf = ctx.buffer(np.ascontiguousarray(F, dtype=np.int32).tobytes())
                gl_objects += [pos_buf, attr_buf, nrm_buf, idx_buf]
                attributes = [(pos_buf, "3f", "in_pos"), (attr_buf, "4f", "in_attr"), (nrm_buf, "3f", "in_normal")]
                vao = ctx.vertex_array(self._prog, attributes, index_buffer=idx_buf, index_element_size=4)
                gl_objects.append(vao)
            color = np.empty((Hs, Ws, C), np.float32)
            depth = np.empty((Hs, Ws), np.float32)
            face = np.empty((Hs, Ws), np.int32) if read_face else None
            for i, chunk in enumerate(channels.passes):
                fbo.clear(0.0, 0.0, 0.0, 0.0, depth=1.0)  # int target: float 0.0 bits = 0
                if len(F):
                    attr_buf.write(chunk.tobytes())
                    vao.render(self._moderngl.TRIANGLES)
                c0, c1 = 4 * i, min(4 * i + 4, C)
                # GL packs the channels we want; read_into writes straight into numpy
                target = color if (c0, c1) == (0, C) else np.empty((Hs, Ws, c1 - c0), np.float32)
                fbo.read_into(target, components=c1 - c0, attachment=0, dtype="f4", alignment=1)
                if target is not color:
                    color[..., c0:c1] = target
                if i == 0:
                    fbo.read_into(depth, components=1, attachment=1, dtype="f4", alignment=1)
                    if read_face:
                        fbo.read_into(face, components=1, attachment=2, dtype="i4", alignment=1)
        finally:
            for obj in gl_objects:
                obj.release()
        return color, depth, face


#: The fragment shader's ``shading`` uniform of each ``shading`` argument.
_SHADING = {None: 0, "lambert": 1, "flat": 2}


@dataclass
class _Channels:
    """What the colour channels of one :meth:`Renderer.render` are (:meth:`Renderer._channels`)."""

    mode: int  # the fragment shader's mode: 0 interpolated attributes, 1 texture at uv, 2 albedo
    count: int  # C, the channels of RenderResult.color
    passes: list  # (n, 4) float32 vertex attributes, one draw each
    texture: GLTexture | None = None  # a resident texture
    data: np.ndarray | None = None  # a texture image uploaded for this call


def _check_mesh(vertices, faces) -> tuple[np.ndarray, np.ndarray]:
    """``vertices`` as (n, 3) float64 and ``faces`` as (m, 3) integers, or a ValueError naming the problem."""
    V = np.asarray(vertices, dtype=float)
    if V.ndim != 2 or V.shape[1] != 3:
        raise ValueError(f"vertices must be (n, 3) mm, got shape {V.shape}")
    if not np.all(np.isfinite(V)):
        raise ValueError("vertices contain NaN or inf")
    n = len(V)
    F = np.asarray(faces)
    if F.size == 0:
        F = F.reshape(0, 3)
    if F.ndim != 2 or F.shape[1] != 3 or not np.issubdtype(F.dtype, np.integer):
        raise ValueError(f"faces must be (m, 3) integers, got shape {F.shape} dtype {F.dtype}")
    if F.size and (F.min() < 0 or F.max() >= n):
        raise ValueError(f"faces index vertices outside 0..{n - 1} (min {F.min()}, max {F.max()})")
    return V, F


def _background(background, count: int) -> np.ndarray:
    """(count,) float32 colour of uncovered pixels from a scalar or a sequence."""
    bg = np.asarray(background, dtype=np.float32).reshape(-1)
    if bg.size not in (1, count):
        raise ValueError(f"background must be a scalar or have {count} values, got {np.shape(background)}")
    return np.broadcast_to(bg, (count,))


def _clip_planes(Xc: np.ndarray, F: np.ndarray, near, far) -> tuple[float, float, np.ndarray]:
    """The clipping planes (given, or :func:`auto_near_far` of the camera-space vertices ``Xc``)
    and the faces to draw: none when nothing lies in front of the camera."""
    if near is None or far is None:
        auto = auto_near_far(Xc[:, 2]) if len(Xc) else None
        if auto is None:
            auto = (1.0, 2.0)  # nothing in front of the camera: any valid planes
            F = F[:0]
        near = auto[0] if near is None else near
        far = auto[1] if far is None else far
    return float(near), float(far), F


def _resolve(color, depth, face, bg, ss: int, near: float, far: float) -> RenderResult:
    """The :class:`RenderResult` of the read-back targets: background filled in, and with
    supersampling the colour box-filtered and the rest taken at the central sub-sample."""
    face -= 1
    mask = face >= 0
    background_px = ~mask
    color[background_px] = bg
    depth[background_px] = np.inf
    if ss > 1:
        H, W = face.shape[0] // ss, face.shape[1] // ss
        color = _box_downsample(color, ss)
        coverage = mask.reshape(H, ss, W, ss).mean(axis=(1, 3), dtype=np.float32)
        c = ss // 2
        depth = np.ascontiguousarray(depth[c::ss, c::ss])
        face = np.ascontiguousarray(face[c::ss, c::ss])
        mask = np.ascontiguousarray(mask[c::ss, c::ss])
    else:
        coverage = mask.astype(np.float32)
    return RenderResult(color=color, depth=depth, mask=mask, face_id=face, coverage=coverage, near=near, far=far)


def _box_downsample(image: np.ndarray, k: int) -> np.ndarray:
    """(H·k, W·k, C) → (H, W, C): mean of each k×k block (OpenCV's area filter is exactly this
    for an integer factor, and ~5× faster than a numpy reshape-mean)."""

    Hk, Wk, C = image.shape
    if C <= 4:
        out = cv2.resize(image, (Wk // k, Hk // k), interpolation=cv2.INTER_AREA)
        return out.reshape(Hk // k, Wk // k, C)
    return image.reshape(Hk // k, k, Wk // k, k, C).mean(axis=(1, 3), dtype=np.float32)


def _texture_array(texture) -> tuple[np.ndarray, int]:
    """Validate a texture image; return it as (Ht, Wt, C) uint8 or float32 and C."""
    T = np.asarray(texture)
    if T.ndim == 2:
        T = T[:, :, None]
    if T.ndim != 3 or T.shape[2] not in (1, 2, 3, 4) or T.shape[0] < 1 or T.shape[1] < 1:
        raise ValueError(f"texture must be (H, W) or (H, W, C) with C in 1..4, got shape {np.shape(texture)}")
    if T.dtype == np.uint8:
        return np.ascontiguousarray(T), T.shape[2]
    if T.dtype == np.uint16:
        return (T.astype(np.float32) / 65535.0), T.shape[2]
    if np.issubdtype(T.dtype, np.floating):
        return np.ascontiguousarray(T, dtype=np.float32), T.shape[2]
    raise ValueError(f"texture must be uint8, uint16 or float, got {T.dtype}")


def _upload_texture(ctx, T: np.ndarray):

    h, w, c = T.shape
    tex = ctx.texture((w, h), c, T.tobytes(), alignment=1, dtype="f1" if T.dtype == np.uint8 else "f4")
    tex.filter = (moderngl.LINEAR, moderngl.LINEAR)
    tex.repeat_x = tex.repeat_y = False  # clamp to edge: no bleeding across the u = 0 / 1 seam
    return tex


_local = threading.local()


def get_renderer() -> Renderer:
    """This thread's :class:`Renderer`, created on first use and reused afterwards.

    Raises
    ------
    RuntimeError
        when no headless OpenGL 3.3 context can be created; the message says what to install.
    """
    r = getattr(_local, "renderer", None)
    if r is None or r.released:
        r = _local.renderer = Renderer()
    return r
