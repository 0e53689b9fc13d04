"""View-dependent texture mapping (Pighin et al. 2002, §5.2.3; Debevec et al. 1996).

Instead of one resampled, blended texture, each new view is coloured directly from the
photographs, "select[ing] just the two photographs whose view directions ``d_ℓ`` and
``d_{ℓ+1}`` are the closest to ``d``" and blending them per pixel with
``g_k = F_k(x_k, y_k) P_k(m) V_k(d)`` (:mod:`photomodel.texturing.weights`).

Three ways to draw a frame
--------------------------
The paper renders the model once per photograph, with per-vertex texture coordinates (the
vertex projected into the photograph) and per-vertex blending weights, and lets the hardware
blend the passes: ``method="per_vertex"``, kept for comparison. Per-vertex weights and
interpolated texture coordinates smear across occlusion boundaries (a triangle straddling the
nose's outline takes cheek colour from behind the nose), so the two other methods work **per
pixel**: each covered pixel's surface point is projected into the two selected photographs,
with bilinear colour lookups, depth-map visibility (§5.2.1), the image-space feather map
``F_k(x_k, y_k)``, ``P_k = n · d_k`` and ``V_k`` at that pixel.

* ``method="shader"`` (the default) does this in fragment shaders
  (:mod:`photomodel.rendering.view_dependent_pass`, on the one renderer's GL context): the photographs, their depth
  maps and feather maps are textures uploaded once; a frame is a G-buffer pass of the mesh and
  a full-screen pass that computes the weights, visibility and blend per pixel, exactly as the
  numpy path does. Pixels that neither selected photograph sees (a few hundred in a
  1000×1000 frame) come back to the CPU for the numpy path's fallback below.
* ``method="numpy"`` (older name ``"position_buffer"``): one geometry pass of the renderer with
  the normals (and the §5.2.4 single-view weight) as float attributes; each pixel's point is
  rebuilt from the depth buffer and everything else happens in numpy/OpenCV (``cv2.remap``).

Both per-pixel methods give the same image — same coverage and fallback pixels, 60 dB between
them with the plain blend, ~50 dB with the registration below (its flow is estimated
differently) — and the same held-out PSNR within a few hundredths of a dB;
``benchmarks/bench_texture.py`` measures them side by side (docs/texturing.md). The shader path
is ~7× faster (58–65 ms against 398–438 ms for a 1000×1000 registered frame of a moving view
on llvmpipe, 2026-12-02; the screen-space registration it replaced measured 85–89 ms against
61–70 in alternating runs), fast enough for the 3D view to show the registered
view-dependent rendering while orbiting. (Taking the photographs' weights from the
flow's quarter-resolution pass instead of per pixel made the frame ~17 % faster, 67 against
81 ms back to back, but it missed visibility slivers and took the shader frame from 47 to 38 dB
of the numpy path's at 1000×1000 and to 32 dB at 400×780, where the quarter-resolution pass is
coarse for the face: reverted.)

Floating textures
-----------------
Beyond the paper, ``align=True`` (the default) blends *floating textures*
(Eisemann et al. 2008): where the fitted geometry is slightly off, the two photographs
reprojected into the new view disagree by a few pixels and their blend ghosts; an optical
flow between the two (OpenCV's DIS) lets each be warped by the other's share of the
disagreement, so a feature lands at the weighted mean of its two positions — which is
where the true surface point appears when the new view lies between the two cameras.
On the held-out views of the fitted sample model it gains ~0.5 dB over the plain blend; with
exact geometry it changes nothing; see docs/texturing.md. ``align=False`` gives the paper's
plain blend.

The numpy path computes both flows (A→B and B→A) on the full-resolution reprojections (DIS
"fast", which estimates down to a quarter of the resolution) and warps the reprojected images.
The shader path registers the two photographs **once per pair**, over the first one's image
(:meth:`ViewDependentTexture.registration_shift`): B is reprojected into A's image through the
model, DIS "fast" gives the two flows between A and that reprojection, and each becomes a shift
in its photograph's pixels; per pixel the shader looks the shifts up where the point projects
into A and samples each photograph at its projection minus the other's share of the shift. The
disagreement between two photographs is a property of the model and the photographs, not of
the new view, so a moving view reuses it: the pair's first frame pays for it (~0.2 s), the
others nothing. On the sample's held-out views this gives the numpy path's PSNR within a few
hundredths of a dB and frames ~50 dB from its frames, against 41–45 dB with the screen-space
flow it replaced (a DIS flow on quarter-resolution reprojections in every frame, ~14 ms of
each; docs/texturing.md). Beyond the paper.

Holes
-----
Pixels where neither selected photograph sees the surface (occluded in both) fall back to
the view-independent blend ``F_k P_k`` of all photographs, and pixels no photograph sees
are filled with the mean of the seen pixels nearest to them (the smallest square around each
that holds any), so a new view has no black holes.
"""

from __future__ import annotations

import threading
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import cv2
import numpy as np

from photomodel.camera import Camera
from photomodel.exchange.uv import check_mesh
from photomodel.rendering.depth import DEPTH_TOL_MM, FAR_SENTINEL_MM, project_points
from photomodel.rendering.renderer import get_renderer, vertex_normals
from photomodel.rendering.sampling import sample_image
from photomodel.rendering.view_dependent_pass import ViewDependentGL
from photomodel.texturing.cylindrical import check_photos
from photomodel.texturing.visibility import render_depth
from photomodel.texturing.weights import (
    FEATHER_WIDTH_MM,
    apply_single_view,
    blend,
    image_feather_map,
    positional_certainty,
    select_views,
    view_directions,
    view_similarity,
)

__all__ = ["ViewDependentRender", "ViewDependentTexture", "render_view_dependent"]

METHODS = ("shader", "numpy", "per_vertex")
#: Older name of ``method="numpy"``.
_ALIASES = {"position_buffer": "numpy"}
#: The shader path's registration maps go to the GPU reduced this many times (250² for a 1000²
#: photograph, 1 MB): DIS's "fast" preset estimates the flow at a quarter of its images'
#: resolution, so the finer maps hold nothing more, and the blend pass reads the small map faster.
SHIFT_REDUCE = 4


@dataclass
class ViewDependentRender:
    """One view-dependent frame.

    Attributes
    ----------
    color : (H, W, 3) float32
        RGB in [0, 1]; ``background`` where the model is not drawn.
    mask : (H, W) bool
        pixels covered by the model.
    views : (int, int)
        the two photographs ``ℓ, ℓ+1`` selected for this view (indices into the cameras).
    view_weights : (k,) float
        ``V_k(d)`` of every photograph.
    filled : (H, W) bool
        covered pixels coloured by a fallback: neither selected photograph sees them (blend
        of all photographs, or filled from the neighbourhood where none does).
    depth : (H, W) float32 or None
        ``Z_cam`` (mm) of the model in the new view, ``inf`` off it (what the renderer's
        ``RenderResult.depth`` holds, e.g. for occlusion tests of overlays).
    """

    color: np.ndarray
    mask: np.ndarray
    views: tuple[int, int]
    view_weights: np.ndarray
    filled: np.ndarray
    depth: np.ndarray | None = None


class ViewDependentTexture:
    """The photographs of a fitted model, prepared for view-dependent rendering (§5.2.3).

    Preparation renders each photograph's depth map and its feathered visibility map
    ``F_k(x_k, y_k)`` once; :meth:`render` then draws any new view.

    Parameters
    ----------
    vertices : (N, 3) float
        the fitted mesh, mm.
    faces : (M, 3) int
    cameras : k Camera
        recovered cameras, in the order of ``photos``.
    photos : k (H_k, W_k, 3) uint8 RGB
    single_view : (N,) float in [0, 1], optional
        per-vertex weight of the single-best-view fallback of §5.2.4
        (:func:`photomodel.texturing.cylindrical.single_view_weights`).
    feather_mm : float
        width of the feathering ramp on the surface (mm).
    tol_mm : float
        depth-comparison tolerance of the visibility test (mm).
    depths : k (H_k, W_k) float, optional
        the mesh's depth maps from ``cameras`` if already rendered.
    centre : (3,) float, optional
        the point view directions are measured from; default the centroid of the vertices.
    """

    def __init__(
        self,
        vertices: np.ndarray,
        faces: np.ndarray,
        cameras: Sequence[Camera],
        photos: Sequence[np.ndarray],
        *,
        single_view: np.ndarray | None = None,
        feather_mm: float = FEATHER_WIDTH_MM,
        tol_mm: float = DEPTH_TOL_MM,
        depths: Sequence[np.ndarray] | None = None,
        centre: np.ndarray | None = None,
    ):

        V, F = check_mesh(vertices, faces)
        self.photos = check_photos(cameras, photos)
        self.cameras = list(cameras)
        self.vertices, self.faces = V, F
        self.normals = vertex_normals(V, F)
        self.single_view = None
        if single_view is not None:
            self.single_view = np.asarray(single_view, dtype=np.float32).reshape(-1)
            if self.single_view.shape != (len(V),):
                raise ValueError(f"single_view must be ({len(V)},), got shape {np.shape(single_view)}")
        self.tol_mm = float(tol_mm)
        if depths is None:
            depths = [render_depth(c, V, F) for c in self.cameras]
        if len(depths) != len(self.cameras):
            raise ValueError(f"{len(self.cameras)} cameras but {len(depths)} depth maps")
        self.depths = [np.asarray(d, dtype=np.float32) for d in depths]
        # off the model a far sentinel before bilinear lookups (as depth_visible), made once
        self._depths_far = [np.where(np.isfinite(d), d, np.float32(FAR_SENTINEL_MM)) for d in self.depths]
        self.feather_maps = []
        for cam, d in zip(self.cameras, self.depths, strict=True):
            finite = d[np.isfinite(d)]
            mm_per_px = float(np.median(finite)) / cam.f if finite.size else 1.0
            self.feather_maps.append(image_feather_map(d, feather_mm, mm_per_px))
        self.centre = V.mean(axis=0) if centre is None else np.asarray(centre, dtype=float).reshape(3)
        self.directions = view_directions(self.cameras, self.centre)
        self._gl_textures = None
        self._gl = None  # photomodel.rendering.view_dependent_pass.ViewDependentGL of this thread's renderer
        self._surfaces: dict[int, tuple[np.ndarray, np.ndarray, np.ndarray]] = {}  # per photograph
        self._shifts: dict[tuple[int, int], np.ndarray] = {}  # registration maps per pair
        self._pair_locks: dict[tuple[int, int], threading.Lock] = {}  # one computation per pair at a time
        self._locks_lock = threading.Lock()

    # -------------------------------------------------------------------------------------
    def view_weights(self, camera: Camera) -> tuple[tuple[int, int], np.ndarray]:
        """The selected photographs and ``V_k(d)`` for a new camera (§5.2.3)."""
        d = camera.center - self.centre
        d = d / np.linalg.norm(d)
        return select_views(d, self.directions), view_similarity(d, self.directions)

    def _photo_weights(self, k: int, pts: np.ndarray, nrm: np.ndarray):
        """Colour (n, 3) uint8 and ``F_k P_k`` (n,) of points in photograph ``k``."""
        cam = self.cameras[k]
        uv, z = project_points(cam, pts)
        P = positional_certainty(cam, pts, nrm)
        # depth_visible's test, with the sentinel-filled depth map prepared once
        W, H = cam.width, cam.height
        with np.errstate(invalid="ignore"):
            inside = (z > 0) & (uv[:, 0] >= 0) & (uv[:, 0] <= W - 1) & (uv[:, 1] >= 0) & (uv[:, 1] <= H - 1)
        far = sample_image(self._depths_far[k], uv, border_value=FAR_SENTINEL_MM)
        vis = inside & (z <= far + self.tol_mm) & (P > 0)
        Fk = sample_image(self.feather_maps[k], uv)
        g = np.where(vis, Fk * P, 0.0).astype(np.float32)
        return sample_image(self.photos[k], uv), g

    def render(
        self,
        camera: Camera,
        *,
        background=0.0,
        method: str = "shader",
        align: bool = True,
    ) -> ViewDependentRender:
        """Render the model from a new camera with view-dependent texturing (§5.2.3).

        Parameters
        ----------
        camera : Camera
            the new view.
        background : float or (3,) sequence
            colour (0..1) of pixels the model does not cover.
        method : ``"shader"`` (default), ``"numpy"`` or ``"per_vertex"``
            per-pixel weights and blend in a fragment shader; the same per pixel in
            numpy/OpenCV from a position buffer (``"position_buffer"`` is an older name of
            it); or the paper's multi-pass rendering with per-vertex texture coordinates and
            weights (see the module notes).
        align : bool
            beyond the paper, ``shader`` and ``numpy``: register the two photographs to each
            other with optical flow before blending (*floating textures*, see the module
            notes); ``False`` is the paper's plain blend.

        Returns
        -------
        ViewDependentRender
        """
        if not isinstance(camera, Camera):
            raise TypeError(f"camera must be a photomodel.camera.Camera, got {type(camera).__name__}")
        method = _ALIASES.get(method, method)
        if method not in METHODS:
            raise ValueError(f"method must be one of {METHODS}, got {method!r}")
        views, V = self.view_weights(camera)
        if method == "per_vertex":
            return self._render_per_vertex(camera, views, V, background)
        if method == "shader":
            return self._render_shader(camera, views, V, background, align)
        return self._render_numpy(camera, views, V, background, align)

    def _render_numpy(self, camera: Camera, views, V, background, align: bool) -> ViewDependentRender:
        """:meth:`render`'s ``"numpy"`` method: the shader's per-pixel weights and blend in
        numpy/OpenCV from a position buffer."""
        sv = np.zeros(len(self.vertices), np.float32) if self.single_view is None else self.single_view
        attr = np.column_stack([self.normals, sv]).astype(np.float32)
        res = get_renderer().render(camera, self.vertices, self.faces, colors=attr)
        H, W = camera.height, camera.width
        idx = np.flatnonzero(res.mask)  # flat indices: much faster than 2D fancy indexing
        color = np.empty((H, W, 3), np.float32)
        color[:] = np.broadcast_to(np.asarray(background, np.float32).reshape(-1), (3,))
        if idx.size == 0:  # the model is out of view
            return ViewDependentRender(color, res.mask, views, V, np.zeros((H, W), bool), res.depth)
        rows, cols = np.divmod(idx, W)
        pts = _pixel_points(camera, idx, res.depth)
        attr_px = res.color.reshape(-1, 4)[idx]
        nrm = attr_px[:, :3]
        nrm /= np.maximum(np.sqrt(np.einsum("ij,ij->i", nrm, nrm)), np.float32(1e-12))[:, None]
        s = attr_px[:, 3] if self.single_view is not None else None

        selected = [k for k in range(len(V)) if V[k] > 0]  # the two of §5.2.3 (or one)
        colors, weights = [], []
        for k in selected:
            c, g = self._photo_weights(k, pts, nrm)
            colors.append(c)
            weights.append(g * np.float32(V[k]))
        g = np.array(weights)
        out = np.zeros((len(pts), 3), np.float32)
        have = g.sum(axis=0) > 0
        if align and len(selected) == 2 and have.any():
            shares = apply_single_view(g, np.zeros(len(pts)) if s is None else s)  # normalised
            colors = _floating_alignment((H, W), rows, cols, colors, shares)
        if have.any():
            out[have] = blend(np.array(colors)[:, have], apply_single_view(g[:, have], None if s is None else s[have]))[
                0
            ]
        filled = ~have
        unseen = np.zeros(len(pts), bool)
        if filled.any():  # §5.2.3 keeps two photographs; where both are occluded, use them all
            out[filled], unseen[filled] = self._fallback(pts[filled], nrm[filled], None if s is None else s[filled])
        color.reshape(-1, 3)[idx] = out * np.float32(1.0 / 255.0)
        _fill_unseen(color, res.mask, idx[unseen])
        filled_map = np.zeros((H, W), bool)
        filled_map.reshape(-1)[idx] = filled
        return ViewDependentRender(color, res.mask, views, V, filled_map, res.depth)

    def _fallback(self, pts, nrm, s):
        """The blend of every photograph (``F_k P_k``, single-view mix) at points that neither
        selected photograph sees: colours (n, 3) in 0..255 and whether no photograph sees them."""
        fc, fg = [], []
        for k in range(len(self.cameras)):
            c, gk = self._photo_weights(k, pts, nrm)
            fc.append(c)
            fg.append(gk)
        blended, total = blend(np.array(fc), apply_single_view(np.array(fg), s))
        return blended, total <= 0

    def gl_state(self):
        """The GPU copy of the photographs, maps and mesh for this thread's renderer
        (:class:`photomodel.rendering.view_dependent_pass.ViewDependentGL`), made on first use."""

        renderer = get_renderer()
        gl = self._gl
        if gl is None or gl.renderer is not renderer or not gl.usable:
            gl = self._gl = ViewDependentGL(
                renderer,
                self.vertices,
                self.faces,
                self.normals,
                self.cameras,
                self.photos,
                self._depths_far,
                self.feather_maps,
                centre=self.centre,
                single_view=self.single_view,
                tol_mm=self.tol_mm,
                far_sentinel_mm=FAR_SENTINEL_MM,
            )
        return gl

    def _render_shader(self, camera, views, V, background, align) -> ViewDependentRender:
        """The per-pixel weights and blend in a fragment shader (:mod:`photomodel.rendering.view_dependent_pass`)."""
        selected = [k for k in range(len(V)) if V[k] > 0]  # the two of §5.2.3 (or one)
        frame = self.gl_state().render(
            camera,
            selected,
            [V[k] for k in selected],
            background=background,
            shift=self.registration_shift if align else None,
        )
        color, idx = frame.color, frame.fallback
        filled = np.zeros(frame.mask.shape, bool)
        if idx.size:  # neither selected photograph sees these: every photograph, on the CPU
            filled.reshape(-1)[idx] = True
            pts = _pixel_points(camera, idx, frame.depth)
            s = frame.fallback_single if self.single_view is not None else None
            out, unseen = self._fallback(pts, frame.fallback_normals, s)
            color.reshape(-1, 3)[idx] = out * np.float32(1.0 / 255.0)
            _fill_unseen(color, frame.mask, idx[unseen])
        return ViewDependentRender(color, frame.mask, views, V, filled, frame.depth)

    def _photo_surface(self, k: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The model as photograph ``k`` sees it: its covered pixels (flat indices), their world
        points (n, 3) float32 and unit normals (n, 3); made once per photograph."""
        if k not in self._surfaces:
            cam = self.cameras[k]
            res = get_renderer().render(cam, self.vertices, self.faces, colors=self.normals)
            idx = np.flatnonzero(res.mask)
            nrm = res.color.reshape(-1, 3)[idx]
            nrm /= np.maximum(np.sqrt(np.einsum("ij,ij->i", nrm, nrm)), np.float32(1e-12))[:, None]
            self._surfaces[k] = (idx, _pixel_points(cam, idx, res.depth), nrm)
        return self._surfaces[k]

    def registration_shift(self, a: int, b: int) -> np.ndarray:
        """The floating-texture registration of photographs ``a`` and ``b`` over ``a``'s image
        (:data:`photomodel.rendering.view_dependent_pass.ShiftFunction`), computed once per pair.

        Photograph B is reprojected into A's image through the model (B's colour at the
        surface point each pixel of A sees; A's own where B does not see it, so that nothing
        moves there), OpenCV's DIS ("fast" preset, as the numpy path) gives the flows ``f_ab``
        and ``f_ba`` between A and that reprojection, and each becomes a shift in its
        photograph's pixels: ``delta_A = f_ab`` (A's image is the parameterisation) and
        ``delta_B(x) = x_B(x) - x_B(x - f_ba(x))`` (``x_B``: B's pixel of the point seen at
        ``x``), so that B sampled at ``x_B - w_A delta_B`` is B's reprojection displaced by A's
        share of the flow (to first order in ``w_A``; exact at 0 and 1), as the numpy path
        displaces the reprojections in the new view.

        Returns
        -------
        (h, w, 4) float32
            ``delta_A`` (channels 0, 1) and ``delta_B`` (2, 3), pixels of A and B; 0 off the
            model; A's image reduced :data:`SHIFT_REDUCE` times (row 0 = top).
        """
        key = (int(a), int(b))
        if key in self._shifts:
            return self._shifts[key]
        with self._locks_lock:
            lock = self._pair_locks.setdefault(key, threading.Lock())
        with lock:  # another thread computing this pair (register_pairs): wait for its maps
            if key not in self._shifts:
                self._shifts[key] = self._registration(key)
        return self._shifts[key]

    def _registration(self, key: tuple[int, int]) -> np.ndarray:
        """The registration maps of the pair ``key`` (see :meth:`registration_shift`)."""
        cam = self.cameras[key[0]]
        H, W = cam.height, cam.width
        out = np.zeros((H, W, 4), np.float32)
        idx, pts, nrm = self._photo_surface(key[0])
        color_b, gb = self._photo_weights(key[1], pts, nrm)
        seen = gb > 0
        if key[0] != key[1] and seen.any():
            rows, cols = np.divmod(idx, W)
            m = 16  # margin for the flow's patches
            r0, r1 = max(int(rows.min()) - m, 0), min(int(rows.max()) + m + 1, H)
            c0, c1 = max(int(cols.min()) - m, 0), min(int(cols.max()) + m + 1, W)
            h, w = r1 - r0, c1 - c0
            flat = (rows - r0) * w + (cols - c0)
            img_a = cv2.cvtColor(np.ascontiguousarray(self.photos[key[0]][r0:r1, c0:c1]), cv2.COLOR_RGB2GRAY)
            img_b = img_a.copy()
            grey_b = color_b[seen].astype(np.float32) @ np.float32([0.299, 0.587, 0.114])
            img_b.reshape(-1)[flat[seen]] = np.clip(np.round(grey_b), 0, 255).astype(np.uint8)
            f_ab, f_ba = _flows(img_a, img_b)  # A(x) ≈ B'(x + f_ab(x))
            x_b = np.zeros((h * w, 3), np.float32)  # B's pixel of the point seen at each pixel, "on the model"
            uv_b, _ = project_points(self.cameras[key[1]], pts)
            x_b[flat, :2] = uv_b
            x_b[flat, 2] = 1.0
            x_b = x_b.reshape(h, w, 3)
            gy, gx = np.mgrid[0:h, 0:w].astype(np.float32)
            back = cv2.remap(
                x_b,
                gx - f_ba[..., 0],
                gy - f_ba[..., 1],
                cv2.INTER_LINEAR,
                borderMode=cv2.BORDER_CONSTANT,
                borderValue=0,
            )
            on = x_b[..., 2] > 0
            out[r0:r1, c0:c1, :2] = np.where(on[..., None], f_ab, 0.0)
            # on the model at both ends (displaced off it: no shift)
            ok = on & (back[..., 2] > 0.999)
            out[r0:r1, c0:c1, 2:] = np.where(ok[..., None], x_b[..., :2] - back[..., :2], 0.0)
        if SHIFT_REDUCE > 1:
            size = (max(W // SHIFT_REDUCE, 1), max(H // SHIFT_REDUCE, 1))
            out = cv2.resize(out, size, interpolation=cv2.INTER_AREA)
        return out

    def orbit_pairs(self, step_deg: float = 5.0, elevations_deg: Sequence[float] = (-20.0, 0.0, 20.0)) -> list:
        """The pairs of photographs (:func:`~photomodel.texturing.weights.select_views`, two
        different ones) that views orbiting the head select: azimuths all round in ``step_deg``
        steps (0 = the head's front, +z) at ``elevations_deg``, the pairs nearest the front first."""
        seen: dict[tuple[int, int], float] = {}
        for el in np.radians(np.asarray(elevations_deg, float)):
            for az in np.radians(np.arange(-180.0, 180.0, step_deg)):
                d = np.array([np.sin(az) * np.cos(el), np.sin(el), np.cos(az) * np.cos(el)])
                a, b = sorted(int(i) for i in select_views(d, self.directions))
                if a != b:
                    seen[(a, b)] = min(seen.get((a, b), np.inf), abs(az) + abs(el))
        return sorted(seen, key=seen.get)

    def prepare_surfaces(self, photos: Sequence[int] | None = None) -> None:
        """Render the model as photographs ``photos`` (default: every one) see it, kept, on this
        thread's renderer: what :meth:`register_pairs` needs before it can run on another thread."""
        for k in range(len(self.cameras)) if photos is None else photos:
            self._photo_surface(int(k))

    def register_pairs(
        self, pairs: Sequence[tuple[int, int]] | None = None, cancel: Callable[[], bool] | None = None
    ) -> int:
        """Compute the registration of ``pairs`` (default :meth:`orbit_pairs`) ahead of the
        frames that need them — on any thread, after :meth:`prepare_surfaces` (no GL here), so
        the studio's orbit never waits a pair's ~0.2 s. A frame asking for a pair being computed
        waits for it rather than computing it twice. Stops early when ``cancel()`` is true.
        Returns the number of pairs computed here."""
        if len(self._surfaces) < len(self.cameras):
            raise RuntimeError("call prepare_surfaces() on the renderer's thread first")
        done = 0
        for a, b in self.orbit_pairs() if pairs is None else pairs:
            if cancel is not None and cancel():
                break
            key = (min(int(a), int(b)), max(int(a), int(b)))
            if key not in self._shifts:
                self.registration_shift(*key)
                done += 1
        return done

    def forget_registration(self) -> None:
        """Drop the registration maps computed so far (here and on the GPU): the next frame of
        each pair computes them again."""
        self._shifts.clear()
        if self._gl is not None and self._gl.usable:
            self._gl.forget_registration()

    def _render_per_vertex(self, camera, views, V, background) -> ViewDependentRender:
        """The paper's multi-pass rendering: one textured pass per selected photograph
        (texture coordinates = the vertices' projections) and one pass for the per-vertex
        weights ``F_k P_k V_k``; blended per pixel."""

        renderer = get_renderer()
        if self._gl_textures is None or self._gl_textures[0].renderer is not renderer:
            self._gl_textures = [renderer.upload_texture(p) for p in self.photos]
        selected = [k for k in range(len(V)) if V[k] > 0]  # the two of §5.2.3 (or one)
        Vx = self.vertices
        weights, layers = [], []
        for k in selected:
            cam = self.cameras[k]
            uv, _ = project_points(cam, Vx)
            tex_uv = np.column_stack([(uv[:, 0] + 0.5) / cam.width, 1.0 - (uv[:, 1] + 0.5) / cam.height])
            _, g = self._photo_weights(k, Vx, self.normals)
            weights.append(g * np.float32(V[k]))
            layers.append(renderer.render(camera, Vx, self.faces, uv=tex_uv, texture=self._gl_textures[k]).color)
        w_attr = np.column_stack(weights + ([self.single_view] if self.single_view is not None else []))
        wres = renderer.render(camera, Vx, self.faces, colors=w_attr)
        nsel = len(selected)
        g = np.moveaxis(wres.color[..., :nsel], -1, 0)
        s = wres.color[..., nsel] if self.single_view is not None else None
        g = apply_single_view(np.maximum(g, 0.0), s)
        total = g.sum(axis=0)
        num = sum(g[i][..., None] * layers[i] for i in range(nsel))
        color = np.where(total[..., None] > 0, num / np.maximum(total, 1e-12)[..., None], layers[0])
        mask = wres.mask
        color[~mask] = np.broadcast_to(np.asarray(background, np.float32).reshape(-1), (3,))
        return ViewDependentRender(color.astype(np.float32), mask, views, V, mask & (total <= 0), wres.depth)


def _floating_alignment(shape, rows, cols, colors, weights):
    """Align the two reprojected photographs before blending them (Eisemann et al. 2008,
    *Floating Textures*): optical flow between the two, each warped by the other's share of
    the flow so that a feature lands at the weighted mean of its two positions.

    Parameters
    ----------
    shape : (H, W)
    rows, cols : (n,) int, the covered pixels.
    colors : two (n, 3) uint8, each photograph's colour at those pixels.
    weights : (2, n) float, normalised blending weights (0 where a photograph does not see).

    Returns
    -------
    two (n, 3) float32, the aligned colours.
    """

    H, W = shape
    # the flow only needs the model's bounding box (plus a margin for the flow's patches)
    m = 16
    r0, r1 = max(int(rows.min()) - m, 0), min(int(rows.max()) + m + 1, H)
    c0, c1 = max(int(cols.min()) - m, 0), min(int(cols.max()) + m + 1, W)
    h, w = r1 - r0, c1 - c0
    rr, cc = rows - r0, cols - c0
    wa, wb = weights[0], weights[1]
    imgs = []
    for mine, other, blind in ((colors[0], colors[1], wa <= 0), (colors[1], colors[0], wb <= 0)):
        img = np.zeros((h, w, 3), np.uint8)
        # where this photograph does not see the surface, show the other one: no motion there
        img.reshape(-1, 3)[rr * w + cc] = np.where(blind[:, None], other, mine)
        imgs.append(img)
    f_ab, f_ba = _flows(*(cv2.cvtColor(i, cv2.COLOR_RGB2GRAY) for i in imgs))  # A(x) ≈ B(x + f_ab(x))
    out = []
    for img, flow, share in ((imgs[0], f_ab, wb), (imgs[1], f_ba, wa)):
        f = flow.reshape(-1, 2)[rr * w + cc]
        src = np.column_stack([cc - share * f[:, 0], rr - share * f[:, 1]])
        out.append(sample_image(img.astype(np.float32), src))
    return out


def _flows(a: np.ndarray, b: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The optical flows between two grey images both ways, ``(f_ab, f_ba)`` with
    ``a(x) ≈ b(x + f_ab(x))``: OpenCV's DIS, "fast" preset (it estimates down to a quarter of
    the images' resolution)."""
    dis = cv2.DISOpticalFlow_create(cv2.DISOPTICAL_FLOW_PRESET_FAST)
    return dis.calc(a, b, None), dis.calc(b, a, None)


def _pixel_points(camera: Camera, idx: np.ndarray, depth: np.ndarray) -> np.ndarray:
    """(n, 3) float32 world points of the pixels ``idx`` (flat) from the depth buffer ``depth``."""

    rows, cols = np.divmod(idx, camera.width)
    z = depth.reshape(-1)[idx]
    # X_cam = (Z (u - c) / f, Z (v - c) / f, Z), X = Rᵀ (X_cam - t)
    # (cv2.transform: ~10× numpy's matmul on (n, 3) float32)
    cx, cy = camera.principal_point
    Xc = np.empty((len(z), 1, 3), np.float32)
    Xc[:, 0, 0] = (cols - np.float32(cx)) * z / np.float32(camera.f)
    Xc[:, 0, 1] = (rows - np.float32(cy)) * z / np.float32(camera.f)
    Xc[:, 0, 2] = z
    return cv2.transform(Xc, np.column_stack([camera.R.T, -camera.R.T @ camera.t])).reshape(-1, 3)


def _fill_unseen(color: np.ndarray, mask: np.ndarray, unseen: np.ndarray) -> None:
    """Fill the covered pixels ``unseen`` (flat indices) that no photograph sees, in place, with
    the mean of the seen pixels in the smallest square around each (half-width 2, 4, 8, … px)
    that holds any: the nearest colours, at a cost set by the holes, not by the frame."""

    H, W = mask.shape
    todo = np.asarray(unseen)
    if todo.size == 0:
        return
    flat = color.reshape(-1, 3)
    known = mask.copy()
    known.reshape(-1)[todo] = False
    r = 2
    while todo.size:
        rows, cols = np.divmod(todo, W)
        if r <= 8:  # gather the (2r + 1)² neighbours of each pixel
            d = np.arange(-r, r + 1)
            yy = rows[:, None, None] + d[None, :, None]
            xx = cols[:, None, None] + d[None, None, :]
            inside = (yy >= 0) & (yy < H) & (xx >= 0) & (xx < W)
            yy, xx = np.clip(yy, 0, H - 1), np.clip(xx, 0, W - 1)
            k = (known[yy, xx] & inside).reshape(len(todo), -1)
            n = k.sum(axis=1).astype(np.float64)
            total = np.einsum("ij,ijc->ic", k, color[yy, xx].reshape(len(todo), -1, 3), dtype=np.float64)
        else:  # wide: summed-area tables over the holes' bounding box
            y0, y1 = max(int(rows.min()) - r, 0), min(int(rows.max()) + r + 1, H)
            x0, x1 = max(int(cols.min()) - r, 0), min(int(cols.max()) + r + 1, W)
            kw = known[y0:y1, x0:x1].astype(np.float32)
            sc = cv2.integral(color[y0:y1, x0:x1] * kw[..., None], sdepth=cv2.CV_64F)
            sk = cv2.integral(kw, sdepth=cv2.CV_64F)
            ya, yb = np.maximum(rows - r, y0) - y0, np.minimum(rows + r + 1, y1) - y0
            xa, xb = np.maximum(cols - r, x0) - x0, np.minimum(cols + r + 1, x1) - x0
            n = sk[yb, xb] - sk[ya, xb] - sk[yb, xa] + sk[ya, xa]
            total = sc[yb, xb] - sc[ya, xb] - sc[yb, xa] + sc[ya, xa]
        ok = n > 0
        flat[todo[ok]] = (total[ok] / n[ok, None]).astype(np.float32)
        if r >= max(H, W):  # no seen pixel anywhere: leave them
            break
        todo = todo[~ok]
        r *= 2


def render_view_dependent(
    camera_new: Camera,
    vertices: np.ndarray,
    faces: np.ndarray,
    cameras: Sequence[Camera],
    photos: Sequence[np.ndarray],
    *,
    background=0.0,
    method: str = "shader",
    align: bool = True,
    **options,
) -> np.ndarray:
    """One view-dependent frame of a fitted model from a new camera (§5.2.3).

    A convenience for a single frame: it prepares a :class:`ViewDependentTexture` (one depth
    map per photograph) each call; keep the object to render many frames.

    Parameters
    ----------
    camera_new : Camera
        the new view.
    vertices, faces, cameras, photos :
        as :class:`ViewDependentTexture`; other keyword ``options`` go to it too
        (``single_view``, ``feather_mm``, ``tol_mm``, ``depths``, ``centre``).
    background : float or (3,)
        colour of uncovered pixels (0..1).
    method, align : see :meth:`ViewDependentTexture.render`.

    Returns
    -------
    (H, W, 3) float32
        RGB in [0, 1].
    """
    vdt = ViewDependentTexture(vertices, faces, cameras, photos, **options)
    return vdt.render(camera_new, background=background, method=method, align=align).color
