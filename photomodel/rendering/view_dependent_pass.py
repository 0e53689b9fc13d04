"""View-dependent texturing in fragment shaders, drawn with the one renderer's GL context (§5.2.3).

:class:`ViewDependentGL` keeps, in a :class:`~photomodel.rendering.renderer.Renderer`'s context (reached
through its public :meth:`~photomodel.rendering.renderer.Renderer.context` and
:meth:`~photomodel.rendering.renderer.Renderer.program`), what
:class:`photomodel.texturing.view_dependent.ViewDependentTexture` needs to draw new views on the
GPU — Mesa's llvmpipe on machines without one — uploaded once:

* the photographs as one ``RGB8`` texture array (a layer per photograph, padded to the
  largest), sampled bilinearly and black outside a photograph, as ``cv2.remap`` samples them
  with its constant border;
* per photograph a ``RG32F`` layer with its **depth map** (``Z_cam`` rendered from its camera,
  a far sentinel off the model) and its feathered visibility map ``F_k(x_k, y_k)``
  (:func:`~photomodel.texturing.weights.image_feather_map`), both sampled bilinearly;
* the mesh: vertex normals and the §5.2.4 single-view weight as a static vertex buffer. Per
  frame only the new view's camera coordinates are uploaded, computed in float64 on the CPU as
  :meth:`Renderer.render` does, so a pixel is covered exactly when the renderer covers it;
* per pair of photographs, on its first frame, the pair's **registration maps** (floating
  textures: how far each photograph's texture must move to meet the other's), which the
  caller computes over the first photograph's image (:data:`ShiftFunction`); a few pairs are
  kept.

A frame (:meth:`ViewDependentGL.render`) is deferred shading in two passes:

1. **G-buffer** — the mesh from the new camera: per pixel ``Z_cam`` and, packed in one
   integer, the interpolated normal (octahedral, 2 × 12 bits), the single-view weight (7 bits)
   and a "covered" bit. The shader is trivial on purpose: a software rasteriser shades whole
   blocks of pixels wherever a small triangle touches them, so the expensive work is left to
   pass 2, which shades each covered pixel once. (Measured: one forward pass doing pass 2's
   work per fragment took 50 ms against 40 for both passes.)
2. **blend** — a full-screen pass over the model's bounding box; the depth test against pass
   1's depth buffer drops the pixels off the model. Per pixel, exactly the numpy path's
   weights: the surface point rebuilt from ``Z_cam`` (as the numpy path rebuilds it from the
   depth buffer), projected into the two selected photographs; visibility by the depth
   comparison ``z ≤ depth(x_k, y_k) + tol`` inside the image and ``P_k = n · d_k > 0``;
   ``g_k = F_k P_k V_k``, the §5.2.4 single-view mix
   (:func:`~photomodel.texturing.weights.apply_single_view`) and the blend. With the
   registration (*floating textures*, Eisemann et al. 2008) the registration maps, looked up
   where the point projects into photograph A, give ``delta_A`` and ``delta_B``, and
   photograph A is sampled at its projection minus ``w_B delta_A``, B at its own minus
   ``w_A delta_B``: each moves by the other's share of their disagreement.

Pixels neither selected photograph sees (the blend of every photograph, §5.2.3's fallback) are
rare — a few hundred in a 1000×1000 frame of the sample — and handed back
(:attr:`GLFrame.fallback`) to the caller's CPU code: a loop over all photographs in the shader
would cost every pixel, as a software rasteriser runs both sides of a branch.

Cost on llvmpipe (2 cores), one 1000×1000 frame of the fitted sample head (2026-12-02, each
pass followed by ``glFinish``): the G-buffer 11–17 ms (~7 ms of it llvmpipe's per-triangle
set-up on the calling thread), the blend 25–36 ms, clears, read-back and the CPU's part
~15 ms; ``vd_frame_ms`` of ``benchmarks/bench_texture.py`` and docs/texturing.md have the
figures of the whole frame. Tried and not kept: culling back faces in pass 1 (1–2 ms, but a
mesh wound the other way would lose its front), the weights ``F_k P_k`` precomputed in
texture space (3–5 ms less in pass 2, but visibility at texel instead of pixel resolution).
"""

from __future__ import annotations

import weakref
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import moderngl as mgl
import numpy as np

from photomodel.camera import Camera
from photomodel.rendering.renderer import Renderer, auto_near_far, gl_projection

__all__ = ["GLFrame", "ViewDependentGL", "ShiftFunction"]

_GBUFFER_VS = """
#version 330
uniform mat4 proj;
in vec3 in_pos;     // camera coordinates of the new view, mm
in vec4 in_ns;      // outward vertex normal (xyz), single-view weight s (w)
out vec4 v_ns;
out float v_z;
void main() {
    v_ns = in_ns;
    v_z = in_pos.z;
    gl_Position = proj * vec4(in_pos, 1.0);
}
"""

_GBUFFER_FS = """
#version 330
in vec4 v_ns;
in float v_z;
// Z_cam (float bits, mm) and the unit normal, octahedral in 2 × 12 bits, the single-view
// weight s in 7 bits and a "covered" bit (the clear value 0: off the model)
layout(location = 0) out uvec2 g;
void main() {
    vec3 n = v_ns.xyz / max(abs(v_ns.x) + abs(v_ns.y) + abs(v_ns.z), 1e-12);
    vec2 o = n.z >= 0.0 ? n.xy : (1.0 - abs(n.yx)) * vec2(n.x >= 0.0 ? 1.0 : -1.0, n.y >= 0.0 ? 1.0 : -1.0);
    uvec2 q = uvec2(round(clamp(o * 0.5 + 0.5, 0.0, 1.0) * 4095.0));
    uint s = uint(round(clamp(v_ns.w, 0.0, 1.0) * 127.0));
    g = uvec2(floatBitsToUint(v_z), q.x | (q.y << 12) | (s << 24) | 0x80000000u);
}
"""

_FULLSCREEN_VS = """
#version 330
uniform float depth;  // NDC depth of the triangle
void main() {  // one triangle over the whole viewport
    vec2 p = vec2(float((gl_VertexID & 1) << 2), float((gl_VertexID & 2) << 1)) - 1.0;
    gl_Position = vec4(p, depth, 1.0);
}
"""

# the blend pass: the G-buffer, the selected photographs A and B, g_k = F_k P_k, the blend.
# Everything is written in the new view's homogeneous pixel q = (x, y, 1): its viewing ray is
# r = M q (world directions, Z_cam = 1), the point X = c + Z_cam r, and a photograph's
# homogeneous pixel K_k (R_k X + t_k) = Z_cam H_k q + h_k, with M, H_k and h_k composed per
# frame in float64 on the CPU (ViewDependentGL._set_photos): 12 multiply-adds and a division
# per projection instead of a rotation, a translation and the intrinsics.
_BLEND_FS = """
#version 330
uniform usampler2D gbuf;
uniform sampler2DArray geo;     // R: depth map Z_cam (far sentinel off the model), G: feather F_k
uniform mat3 a_H;               // K_a R_a M: the new view's homogeneous pixel -> A's, per unit Z_cam
uniform vec3 a_h;               // K_a (R_a c + t_a): the new view's centre in A's homogeneous pixels
uniform vec3 a_d;               // A's centre minus the new view's
uniform vec3 a_max;             // W - 1, H - 1 (the last pixel centres), texture layer
uniform mat3 b_H;
uniform vec3 b_h;
uniform vec3 b_d;
uniform vec3 b_max;
uniform vec2 tex_scale;         // 1 / (array width, height)
uniform float tol;              // depth tolerance, mm
uniform vec2 sel_v;             // V_k(d) of A and B (B's 0 when one photograph is selected)
uniform float use_single;       // 1: mix in the single-view weight s, 0: plain blend
uniform mat3 view_M;            // the new view: homogeneous pixel -> viewing ray (world, Z_cam = 1)

struct Surface {
    vec3 q;        // homogeneous pixel of the new view
    vec3 r;        // its viewing ray, world directions, Z_cam = 1 (the point: c + z r)
    vec3 n;        // unit normal
    float s;       // single-view weight
    float z;       // Z_cam in the new view
};

Surface surface(ivec2 p) {
    uvec2 g = texelFetch(gbuf, p, 0).rg;
    float z = uintBitsToFloat(g.x);
    vec2 o = vec2(uvec2(g.y, g.y >> 12) & 0xFFFu) / 4095.0 * 2.0 - 1.0;
    vec3 n = vec3(o, 1.0 - abs(o.x) - abs(o.y));
    if (n.z < 0.0) n.xy = (1.0 - abs(n.yx)) * vec2(n.x >= 0.0 ? 1.0 : -1.0, n.y >= 0.0 ? 1.0 : -1.0);
    float s = float((g.y >> 24) & 0x7Fu) / 127.0 * use_single;
    // the point from the depth, as the numpy path rebuilds it
    vec3 q = vec3(vec2(p), 1.0);
    return Surface(q, view_M * q, normalize(n), s, z);
}

// the pixel of a photograph (H, h) where the point seen at homogeneous pixel q with depth z lies
vec2 project(mat3 H, vec3 h, vec3 q, float z) {
    vec3 x = z * (H * q) + h;
    return x.xy / x.z;
}

vec3 layer(vec2 uv, float k) {
    return vec3((uv + 0.5) * tex_scale, k);
}

// F_k P_k of a photograph (H, h; d: its centre minus the new view's) at the surface point S,
// 0 where it does not see it; uv: the point's position in the photograph (pixels)
float weight(mat3 H, vec3 h, vec3 dc, vec3 mx, Surface S, out vec2 uv) {
    vec3 x = S.z * (H * S.q) + h;  // x.z: Z_cam in the photograph
    uv = x.xy / x.z;
    vec2 dz = textureLod(geo, layer(uv, mx.z), 0.0).rg;
    vec3 d = dc - S.z * S.r;
    float P = dot(S.n, d) / max(length(d), 1e-12);
    bool vis = x.z > 0.0 && uv.x >= 0.0 && uv.y >= 0.0 && uv.x <= mx.x && uv.y <= mx.y
               && x.z <= dz.r + tol && P > 0.0;
    return vis ? dz.g * P : 0.0;
}

// the blending shares of A and B (§5.2.3 with the §5.2.4 single-view mix); 0 where neither sees
vec2 shares(float ga, float gb, float s) {
    float tot = ga + gb;
    if (!(tot > 0.0)) return vec2(0.0);
    vec2 w = (1.0 - s) * vec2(ga, gb) / tot;
    if (gb > ga) w.y += s; else w.x += s;  // argmax, the first photograph on a tie
    return w;
}

uniform sampler2DArray photos;  // RGB8, one layer per photograph, row 0 = top
uniform sampler2D shift;        // registration over A's image: delta_A (xy), delta_B (zw), pixels of A and B
uniform float align;            // 1: register A and B by the shift maps
layout(location = 0) out vec3 o_color;   // colour; where neither sees: normal (1 + s)
layout(location = 1) out float o_depth;  // Z_cam; -Z_cam where neither sees

void main() {
    Surface S = surface(ivec2(gl_FragCoord.xy));
    vec2 ua, ub;
    float ga = weight(a_H, a_h, a_d, a_max, S, ua) * sel_v.x;
    float gb = weight(b_H, b_h, b_d, b_max, S, ub) * sel_v.y;
    vec2 w = shares(ga, gb, S.s);
    if (align > 0.0) {
        // floating textures: A moves by B's share of their disagreement, B by A's
        // (the maps are over photograph A's image: looked up where the point projects into A)
        vec4 d = textureLod(shift, (ua + 0.5) / (a_max.xy + 1.0), 0.0);
        ua -= w.y * d.xy;
        ub -= w.x * d.zw;
    }
    vec3 col = w.x * textureLod(photos, layer(ua, a_max.z), 0.0).rgb
             + w.y * textureLod(photos, layer(ub, b_max.z), 0.0).rgb;
    // (only covered pixels get here: the depth test against the G-buffer's rejects the rest)
    bool seen = ga + gb > 0.0;
    o_color = seen ? col : S.n * (1.0 + S.s);
    o_depth = seen ? S.z : -S.z;
}
"""

#: The registration of two photographs (floating textures), asked for once per pair ``a < b``:
#: ``shift(a, b) -> (h, w, 4) float32`` over photograph ``a``'s image (any reduction of it: the
#: map spans the whole image, row 0 = top), ``delta_A`` (channels 0, 1) and ``delta_B`` (2, 3)
#: in pixels of ``a`` and ``b`` at the surface point seen at each pixel of ``a``: where both
#: see a point, A is sampled at its projection minus ``w_B delta_A``, B at its own minus
#: ``w_A delta_B``.
ShiftFunction = Callable[[int, int], np.ndarray]

#: Registration maps kept on the GPU (pairs of photographs; an orbit visits a few).
_KEPT_PAIRS = 4


@dataclass
class GLFrame:
    """One frame of :meth:`ViewDependentGL.render`, one value per pixel (row 0 = top).

    Attributes
    ----------
    color : (H, W, 3) float32
        RGB in [0, 1]; ``background`` off the model; meaningless at ``fallback``.
    mask : (H, W) bool
        pixels covered by the model.
    depth : (H, W) float32
        ``Z_cam`` (mm) of the new view, ``inf`` off the model.
    fallback : (n,) int
        flat indices of the covered pixels that neither selected photograph sees: the caller
        colours them (the blend of every photograph, §5.2.3's fallback).
    fallback_normals : (n, 3) float32
        the interpolated unit normal there.
    fallback_single : (n,) float32
        the single-view weight ``s`` there (0 without one).
    """

    color: np.ndarray
    mask: np.ndarray
    depth: np.ndarray
    fallback: np.ndarray
    fallback_normals: np.ndarray
    fallback_single: np.ndarray


class ViewDependentGL:
    """The photographs, depth maps, feather maps and mesh of a view-dependent texture on the GPU.

    Made by :meth:`photomodel.texturing.view_dependent.ViewDependentTexture.gl_state` for the
    renderer of its thread; see the module notes for what a frame does. The GL objects are
    freed by :meth:`release`, or by the renderer at its next use after this is dropped.

    Parameters
    ----------
    renderer : Renderer
        whose context holds everything (use it from the renderer's thread only).
    vertices : (N, 3) float, mm; faces : (M, 3) int; normals : (N, 3) unit outward normals.
    cameras : k Camera; photos : k (H_k, W_k, 3) uint8 RGB.
    depths : k (H_k, W_k) float, the model's depth maps from ``cameras`` (``inf`` off it).
    feather_maps : k (H_k, W_k) float, ``F_k``.
    centre : (3,) float, mm, a point near the model (positions are stored relative to it).
    single_view : (N,) float or None, the §5.2.4 weight ``s``.
    tol_mm : float, depth tolerance of the visibility test.
    far_sentinel_mm : float, the depth standing for "off the model" before interpolation.
    """

    def __init__(
        self,
        renderer: Renderer,
        vertices: np.ndarray,
        faces: np.ndarray,
        normals: np.ndarray,
        cameras: Sequence[Camera],
        photos: Sequence[np.ndarray],
        depths: Sequence[np.ndarray],
        feather_maps: Sequence[np.ndarray],
        *,
        centre: np.ndarray,
        single_view: np.ndarray | None,
        tol_mm: float,
        far_sentinel_mm: float,
    ):

        self.renderer = renderer
        ctx = renderer.context()
        k = len(cameras)
        if k == 0 or not (len(photos) == len(depths) == len(feather_maps) == k):
            raise ValueError("need one photo, depth map and feather map per camera (at least one)")
        self.k = k
        self.vertices = np.asarray(vertices, dtype=float)
        self.centre = np.asarray(centre, dtype=float).reshape(3)
        self.faces = np.ascontiguousarray(faces, dtype=np.int32).reshape(-1, 3)
        self.tol_mm = float(tol_mm)
        self.use_single = single_view is not None
        Wm = max(c.width for c in cameras)
        Hm = max(c.height for c in cameras)
        if max(Wm, Hm) > int(ctx.info["GL_MAX_TEXTURE_SIZE"]):
            raise ValueError(f"photos of {Wm}×{Hm} px exceed the GL texture size limit")
        self.array_size = (Wm, Hm)

        stack, geo = _photo_layers(cameras, photos, depths, feather_maps, (Wm, Hm), far_sentinel_mm)
        n = len(self.vertices)
        s = np.zeros(n, np.float32) if single_view is None else np.asarray(single_view, np.float32).reshape(n)
        ns = np.column_stack([np.asarray(normals, np.float32).reshape(n, 3), s]).astype(np.float32)
        self._cam_uniforms = _camera_uniforms(cameras, self.centre)
        self._gbuffer = renderer.program(_GBUFFER_VS, _GBUFFER_FS)
        self._blend = renderer.program(_FULLSCREEN_VS, _BLEND_FS)
        with ctx:
            self._photos = ctx.texture_array((Wm, Hm, k), 3, stack.tobytes(), alignment=1, dtype="f1")
            self._geo = ctx.texture_array((Wm, Hm, k), 2, geo.tobytes(), alignment=1, dtype="f4")
            black = (0.0, 0.0, 0.0, 0.0)  # outside a photograph, as cv2.remap's constant border
            self._photo_sampler = ctx.sampler(texture=self._photos, filter=(mgl.LINEAR, mgl.LINEAR), border_color=black)
            self._geo_sampler = ctx.sampler(
                texture=self._geo, filter=(mgl.LINEAR, mgl.LINEAR), repeat_x=False, repeat_y=False
            )
            self._pos = ctx.buffer(reserve=max(n, 1) * 12)
            self._ns = ctx.buffer(ns.tobytes())
            self._idx = ctx.buffer(self.faces.tobytes() if len(self.faces) else np.zeros(3, np.int32).tobytes())
            attrs = [(self._pos, "3f", "in_pos"), (self._ns, "4f", "in_ns")]
            self._vao = ctx.vertex_array(self._gbuffer, attrs, index_buffer=self._idx, index_element_size=4)
            self._blend_vao = ctx.vertex_array(self._blend, [])
            self._no_shift = ctx.texture((1, 1), 4, bytes(16), dtype="f4")
        # every GL object held; dropped unreleased, the renderer frees them at its next use
        self._owned = [
            self._photo_sampler,
            self._geo_sampler,
            self._photos,
            self._geo,
            self._vao,
            self._blend_vao,
            self._pos,
            self._ns,
            self._idx,
            self._no_shift,
        ]
        self._finalizer = weakref.finalize(self, renderer.defer_release, self._owned)
        self._targets: dict[tuple[int, int], dict] = {}
        self._shifts: dict[tuple[int, int], object] = {}  # (a, b) -> texture, oldest first
        self.released = False

    # ------------------------------------------------------------------------------------
    @property
    def usable(self) -> bool:
        """Whether the GL objects are alive (neither this nor its renderer released)."""
        return not self.released and not self.renderer.released

    def forget_registration(self) -> None:
        """Drop the registration maps kept on the GPU: the next frame of each pair of photographs
        asks its ``shift`` function again (what a pair's first frame costs)."""
        for tex in self._shifts.values():
            self._owned.remove(tex)
            tex.release()
        self._shifts.clear()

    def release(self) -> None:
        """Free the GL objects now (idempotent)."""
        self._finalizer.detach()
        if self.usable:
            with self.renderer.context():
                for obj in self._owned:
                    obj.release()
        self._owned.clear()
        self._targets.clear()
        self._shifts.clear()
        self.released = True

    def _frame_targets(self, W: int, H: int) -> dict:
        key = (W, H)
        if key in self._targets:
            return self._targets[key]
        while len(self._targets) >= 2:  # a view being resized: keep the two latest sizes
            old = self._targets.pop(next(iter(self._targets)))  # the oldest
            for obj in old["objects"]:
                self._owned.remove(obj)
                obj.release()
        ctx = self.renderer.context()
        gbuf = ctx.texture((W, H), 2, dtype="u4")
        gbuf.filter = (mgl.NEAREST, mgl.NEAREST)
        zbuf = ctx.depth_renderbuffer((W, H))
        color = ctx.renderbuffer((W, H), components=3, dtype="f4")
        depth = ctx.renderbuffer((W, H), components=1, dtype="f4")
        t = {
            "gbuffer": ctx.framebuffer([gbuf], zbuf),
            # pass 2 tests against the G-buffer's depth: only covered pixels are shaded
            "out": ctx.framebuffer([color, depth], zbuf),
            # the output's attachments alone, to clear each to its own value
            "out_color": ctx.framebuffer([color]),
            "out_depth": ctx.framebuffer([depth]),
            "gbuf": gbuf,
        }
        t["objects"] = [t["gbuffer"], t["out"], t["out_color"], t["out_depth"], gbuf, zbuf, color, depth]
        self._owned.extend(t["objects"])
        self._targets[key] = t
        return t

    def _shift_maps(self, sel, shift: ShiftFunction) -> np.ndarray | None:
        """The registration maps of the pair ``sel`` from ``shift`` when they are not on the GPU
        yet (asked before the frame's GL work: ``shift`` may draw with the renderer itself)."""
        if (sel[0], sel[1]) in self._shifts:
            return None
        maps = np.ascontiguousarray(shift(sel[0], sel[1]), np.float32)
        if maps.ndim != 3 or maps.shape[2] != 4:
            raise ValueError(f"registration maps must be (h, w, 4), got shape {maps.shape}")
        return maps

    def _shift_texture(self, sel, maps: np.ndarray | None):
        """The registration maps of the pair ``sel`` on the GPU (``maps``: new ones to upload)."""
        key = (sel[0], sel[1])
        tex = self._shifts.pop(key, None)
        if tex is None:
            while len(self._shifts) >= _KEPT_PAIRS:
                old = self._shifts.pop(next(iter(self._shifts)))
                self._owned.remove(old)
                old.release()
            ctx = self.renderer.context()
            tex = ctx.texture((maps.shape[1], maps.shape[0]), 4, maps.tobytes(), dtype="f4")
            tex.filter = (mgl.LINEAR, mgl.LINEAR)
            tex.repeat_x = tex.repeat_y = False
            self._owned.append(tex)
        self._shifts[key] = tex  # the newest last
        return tex

    def _set_photos(self, prog, camera: Camera, sel, vw, align: bool) -> None:
        """The uniforms of the selected photographs ``sel`` (weights ``vw``) seen from the frame's
        view, composed in float64 (see ``_BLEND_FS``)."""
        view_c = camera.center - self.centre
        M = camera.R.T @ np.linalg.inv(camera.K)  # homogeneous pixel -> ray (world, Z_cam = 1)
        prog["view_M"].write(_gl_mat3(M))
        for prefix, k in (("a_", sel[0]), ("b_", sel[1])):
            u = self._cam_uniforms[k]
            KR = u["K"] @ u["R"]
            prog[prefix + "H"].write(_gl_mat3(KR @ M))
            _set(prog, prefix + "h", tuple(float(x) for x in KR @ view_c + u["K"] @ u["t"]))
            _set(prog, prefix + "d", tuple(float(x) for x in u["c"] - view_c))
            _set(prog, prefix + "max", u["max"])
        for name, unit in (("gbuf", 0), ("geo", 2), ("photos", 3), ("shift", 4)):
            _set(prog, name, unit)
        _set(prog, "tex_scale", (1.0 / self.array_size[0], 1.0 / self.array_size[1]))
        _set(prog, "tol", self.tol_mm)
        _set(prog, "sel_v", tuple(vw))
        _set(prog, "use_single", 1.0 if self.use_single else 0.0)
        _set(prog, "align", 1.0 if align else 0.0)

    def render(
        self,
        camera: Camera,
        selected: Sequence[int],
        weights: Sequence[float],
        *,
        background=0.0,
        shift: ShiftFunction | None = None,
    ) -> GLFrame:
        """Draw the model from ``camera``, blending the ``selected`` photographs (§5.2.3).

        Parameters
        ----------
        camera : Camera
            the new view.
        selected : one or two photograph indices; weights : their ``V_k(d)`` (> 0).
        background : float or (3,), colour off the model.
        shift : ShiftFunction or None
            with two photographs, register them by these maps before blending (floating
            textures), asked once per pair and kept; ``None`` blends them as they are.

        Returns
        -------
        GLFrame
        """
        if not self.usable:
            raise RuntimeError("this ViewDependentGL was released")
        ctx = self.renderer.context()
        W, H = self._check_frame(camera)
        sel, vw, two = self._selection(selected, weights)
        bg = tuple(float(x) for x in np.broadcast_to(np.asarray(background, np.float32).reshape(-1), (3,)))

        Xc = camera.to_camera(self.vertices)
        planes = auto_near_far(Xc[:, 2]) if len(self.vertices) and len(self.faces) else None
        box = _bounding_box(camera, Xc) if planes is not None else None
        align = two and shift is not None and box is not None
        if box is None:
            return _frame(*_background(W, H, bg, (0, 0, 0, 0)), (0, 0, 0, 0))
        x0, y0, x1, y1 = box
        inner = (x0, y0, x1 - x0, y1 - y0)
        maps = self._shift_maps(sel, shift) if align else None
        with ctx:
            t = self._frame_targets(W, H)
            (self._shift_texture(sel, maps) if align else self._no_shift).use(location=4)
            t["out_color"].use()
            t["out_color"].clear(*bg, 0.0, viewport=inner)
            t["out_depth"].use()
            t["out_depth"].clear(float("inf"), viewport=inner)
            self._gbuffer_pass(ctx, t, camera, Xc, planes, inner)
            self._blend_pass(ctx, t, camera, sel, vw, align, planes, float(Xc[:, 2].max()), inner)
            box_color = np.empty((y1 - y0, x1 - x0, 3), np.float32)
            box_depth = np.empty((y1 - y0, x1 - x0), np.float32)
            t["out"].read_into(box_color, viewport=inner, components=3, attachment=0, dtype="f4", alignment=1)
            t["out"].read_into(box_depth, viewport=inner, components=1, attachment=1, dtype="f4", alignment=1)
        # off the model's bounding box nothing is drawn: the background is filled here, and the
        # GL clears and read-back cover the box alone (a third of a 1000×1000 frame of a face)
        color, depth = _background(W, H, bg, box)
        color[y0:y1, x0:x1] = box_color
        depth[y0:y1, x0:x1] = box_depth
        return _frame(color, depth, box)

    def _check_frame(self, camera: Camera) -> tuple[int, int]:
        """(W, H) of a camera the renderer can draw."""
        if not isinstance(camera, Camera):
            raise TypeError(f"camera must be a photomodel.camera.Camera, got {type(camera).__name__}")
        W, H = camera.width, camera.height
        if W < 1 or H < 1 or max(W, H) > self.renderer.max_size:
            raise ValueError(f"cannot render a {W}×{H} frame (GL limit {self.renderer.max_size} px)")
        return W, H

    def _selection(self, selected, weights) -> tuple[list[int], list[float], bool]:
        """The two photographs (in index order; one twice, weight 0, when only one is selected),
        their weights, and whether there are two."""
        sel = [int(i) for i in selected]
        vw = [float(v) for v in weights]
        if len(sel) not in (1, 2) or len(vw) != len(sel) or not all(0 <= i < self.k for i in sel):
            raise ValueError(f"select one or two photographs with their weights, got {selected}, {weights}")
        if len(sel) == 2 and sel[0] > sel[1]:
            sel, vw = sel[::-1], vw[::-1]
        two = len(sel) == 2
        if not two:
            sel, vw = [sel[0], sel[0]], [vw[0], 0.0]
        return sel, vw, two

    def _gbuffer_pass(self, ctx, t: dict, camera: Camera, Xc: np.ndarray, planes, inner) -> None:
        """Pass 1: the G-buffer (depth, normal, single-view weight),
        cleared over ``inner`` (the model's bounding box); then bound for the blend."""
        ctx.disable(mgl.BLEND | mgl.CULL_FACE)
        fbo = t["gbuffer"]
        fbo.use()
        fbo.viewport = (0, 0, camera.width, camera.height)
        fbo.clear(0.0, 0.0, 0.0, 0.0, depth=1.0, viewport=inner)  # uint: bits 0
        ctx.enable(mgl.DEPTH_TEST)
        self._pos.write(np.ascontiguousarray(Xc, np.float32).tobytes())
        self._gbuffer["proj"].write(gl_projection(camera, *planes).T.astype(np.float32).tobytes())
        self._vao.render(mgl.TRIANGLES, vertices=3 * len(self.faces))
        ctx.disable(mgl.DEPTH_TEST)
        t["gbuf"].use(location=0)
        self._geo_sampler.use(location=2)

    def _blend_pass(self, ctx, t: dict, camera: Camera, sel, vw, align: bool, planes, z_max: float, inner) -> None:
        """Pass 2: weights, registration and blend, per pixel of the bounding box ``inner`` that
        the G-buffer covers (``z_max``: the farthest vertex's ``Z_cam``)."""
        self._photo_sampler.use(location=3)
        p = self._blend
        self._set_photos(p, camera, sel, vw, align)
        # its NDC depth: behind every surface (the farthest vertex), in front of the clear (1)
        near, far = planes
        ndc_far = (far + near) / (far - near) - 2.0 * far * near / ((far - near) * z_max)
        _set(p, "depth", 0.5 * (min(ndc_far, 1.0) + 1.0))
        fbo = t["out"]
        fbo.use()
        fbo.viewport = (0, 0, *fbo.size)
        fbo.depth_mask = False
        ctx.enable(mgl.DEPTH_TEST)
        ctx.depth_func = ">"  # passes where the G-buffer holds a surface, fails on its clear value
        ctx.scissor = inner
        self._blend_vao.render(mgl.TRIANGLES, vertices=3)
        ctx.scissor = None
        ctx.depth_func = "<"
        ctx.disable(mgl.DEPTH_TEST)
        fbo.depth_mask = True


def _background(W: int, H: int, bg: tuple, box) -> tuple[np.ndarray, np.ndarray]:
    """An (H, W, 3) frame of colour ``bg`` and an (H, W) depth of ``inf``, both left unset
    inside ``box`` = (x0, y0, x1, y1), which the read-back fills."""
    x0, y0, x1, y1 = box
    color = np.empty((H, W, 3), np.float32)
    depth = np.empty((H, W), np.float32)
    row = np.empty((W, 3), np.float32)
    row[:] = bg
    for rows, cols in (((0, y0), (0, W)), ((y1, H), (0, W)), ((y0, y1), (0, x0)), ((y0, y1), (x1, W))):
        color[rows[0] : rows[1], cols[0] : cols[1]] = row[cols[0] : cols[1]]  # ~8x faster than broadcasting a 3-vector
        depth[rows[0] : rows[1], cols[0] : cols[1]] = np.inf
    return color, depth


def _frame(color: np.ndarray, depth: np.ndarray, box) -> GLFrame:
    """The :class:`GLFrame` of the read-back output (drawn inside ``box``; ``inf`` depth outside):
    a negative depth marks a pixel of the single-view fallback, whose colour then carries its
    direction and weight."""
    x0, y0, x1, y1 = box
    W = depth.shape[1]
    rows, cols = np.nonzero(depth[y0:y1, x0:x1] < 0.0)
    fallback = (rows + y0) * W + cols + x0
    c = color.reshape(-1, 3)[fallback]
    length = np.sqrt(np.einsum("ij,ij->i", c, c))
    depth.reshape(-1)[fallback] *= -1.0
    mask = np.zeros(depth.shape, bool)
    mask[y0:y1, x0:x1] = depth[y0:y1, x0:x1] < np.inf
    return GLFrame(
        color,
        mask,
        depth,
        fallback,
        c / np.maximum(length, 1e-12)[:, None],
        np.clip(length - 1.0, 0.0, 1.0).astype(np.float32),
    )


def _photo_layers(cameras, photos, depths, feather_maps, size: tuple[int, int], far_sentinel_mm: float):
    """The texture-array layers: (k, Hm, Wm, 3) uint8 photographs and (k, Hm, Wm, 2) float32
    (depth with the far sentinel off the model, feather), each photo in the top-left corner of
    its layer of ``size`` = (Wm, Hm)."""
    k, (Wm, Hm) = len(cameras), size
    stack = np.zeros((k, Hm, Wm, 3), np.uint8)
    geo = np.zeros((k, Hm, Wm, 2), np.float32)
    geo[..., 0] = far_sentinel_mm
    for i, (cam, ph, d, fm) in enumerate(zip(cameras, photos, depths, feather_maps, strict=True)):
        h, w = cam.height, cam.width
        stack[i, :h, :w] = ph
        geo[i, :h, :w, 0] = np.where(np.isfinite(d), d, np.float32(far_sentinel_mm))
        geo[i, :h, :w, 1] = fm
    return stack, geo


def _camera_uniforms(cameras, centre: np.ndarray) -> list[dict]:
    """Per-photograph constants, float64: ``X_k = R (X - c) + (R c + t)`` (``t`` below), the
    intrinsics ``K``, the centre minus ``c`` and the texture-array limits."""
    return [
        {
            "R": np.asarray(c.R, float),
            "t": c.R @ centre + c.t,
            "c": c.center - centre,
            "K": c.K,
            "max": (c.width - 1.0, c.height - 1.0, float(i)),
        }
        for i, c in enumerate(cameras)
    ]


def _gl_mat3(m: np.ndarray) -> bytes:
    """A (3, 3) matrix as a GLSL ``mat3`` uniform's bytes (column-major float32)."""
    return np.ascontiguousarray(np.asarray(m, float).T, np.float32).tobytes()


def _set(prog, name, value) -> None:
    """Set a uniform that the compiler kept (unused ones are optimised away)."""
    if name in prog:
        prog[name].value = value


def _bounding_box(camera: Camera, Xc: np.ndarray) -> tuple[int, int, int, int] | None:
    """The pixels ``[x0, x1) × [y0, y1)`` that the mesh (camera coordinates ``Xc``) can cover,
    or None when it is out of view. Vertices behind the camera make it the whole image."""
    W, H = camera.width, camera.height
    z = Xc[:, 2]
    if not np.any(z > 0):
        return None
    if np.any(z <= 0):  # clipped by the near plane: no bound from the projections
        return 0, 0, W, H
    uv = camera.f * Xc[:, :2] / z[:, None] + camera.principal_point
    x0, y0 = np.floor(uv.min(axis=0)).astype(int) - 1
    x1, y1 = np.ceil(uv.max(axis=0)).astype(int) + 2
    x0, y0, x1, y1 = max(x0, 0), max(y0, 0), min(x1, W), min(y1, H)
    if x1 <= x0 or y1 <= y0:
        return None
    return int(x0), int(y0), int(x1), int(y1)
