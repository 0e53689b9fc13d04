"""Writing an edited frame: the expression flow and its compositing (Yang et al. 2012, §4, Eq. 24).

The face is re-rendered with the edited weights, but the video's own pixels carry the appearance:
the frame is warped by the image motion between the model at the tracked and at the edited
weights (the paper's *expression flow*, Eq. 24), both at the frame's tracked pose.

**The flow** (:func:`expression_flow`) is a backward map, dense and without holes: the edited
model is rasterised (:meth:`photomodel.rendering.renderer.Renderer.rasterize_barycentric`, the
one renderer), and each covered output pixel — a point of a triangle at known barycentric
coordinates — takes its colour from where the *same surface point* projects with the tracked
weights (the per-vertex projections interpolated with the pixel's barycentric coordinates). The
paper's Eq. (24) is this difference of projected vertex positions.

**The face boundary** (our choice in place of the paper's optical flow outside the face and moving
least squares): outside the edited model's silhouette the flow is extended by normalised
convolution (a Gaussian of :attr:`FlowOptions.extend_px` over the covered pixels' flow, divided by
the blurred coverage) and faded to zero with the distance to the silhouette (a Gaussian falloff
of the same width, cut at :data:`FALLOFF_CUT` widths). Where the flow is under
:data:`STILL_PX` the frame's pixel is copied as it is, so the background away from the face is
untouched bit for bit; the model's ``rest`` region (hair, ears, neck) never moves, so the flow is
zero there already, and the feathering only acts where the edit moves the silhouette (the chin of
an opened or closed jaw).

**What the clip does not show** (an opened mouth, skin hidden by the nose in this frame): a
covered output pixel whose source point is hidden in the frame — the tracked model's depth at the
source pixel nearer than the point by more than :data:`HIDDEN_MM`, or the source pixel not covered
— is taken from the **most similar frame of the clip** (the frame whose tracked region weights are
nearest the edited ones, the paper's frame choice of §4 without its time warping), warped there by
the flow from that frame's tracked model (its own pose and weights) to the edited one; where that
frame hides the point too, from the **model's texture** (the edited rendering, Eq. 5 of Pighin et
al.). The filled pixels are feathered into the warp over :data:`FILL_FEATHER_PX` inside their border.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from photomodel.camera import Camera
from tracking.blendshape_face import FaceModel, render_model

__all__ = [
    "FALLOFF_CUT",
    "FILL_FEATHER_PX",
    "HIDDEN_MM",
    "STILL_PX",
    "FlowOptions",
    "Flow",
    "expression_flow",
    "warp_frame",
    "EditedFrame",
    "edit_frame",
]

#: Flows under this (px) copy the frame's pixel unchanged.
STILL_PX = 1e-3
#: The falloff of the flow outside the silhouette is cut (set to 0) beyond this many widths.
FALLOFF_CUT = 3.0
#: A source point is hidden when the tracked surface at its pixel is nearer by more than this (mm).
HIDDEN_MM = 2.0
#: Width (px) of the feather between the warp and the pixels filled from elsewhere.
FILL_FEATHER_PX = 1.5


@dataclass
class FlowOptions:
    """Settings of :func:`edit_frame`."""

    #: width (px) of the flow's extension beyond the silhouette and of its falloff.
    extend_px: float = 4.0
    #: fill the pixels the frame does not show from the most similar frame (else the model's texture).
    similar_frame: bool = True


@dataclass
class Flow:
    """A backward map from the edited image to a source image.

    Attributes
    ----------
    source : (N, 2) float32, source pixel (u, v) of each covered output pixel.
    pixels : (N,) int, flat indices of the covered output pixels (the edited model's coverage).
    hidden : (N,) bool, the source point is hidden in the source image (or out of it).
    """

    source: np.ndarray
    pixels: np.ndarray
    hidden: np.ndarray


def _depth_at(raster, Xc: np.ndarray, shape: tuple) -> np.ndarray:
    """(H, W) float32 camera depth (mm) of a raster's surface, +inf where uncovered."""
    depth = np.full(shape[0] * shape[1], np.inf, np.float32)
    depth[raster.pixels] = raster.interpolate(Xc[:, 2:3].astype(np.float32))[:, 0]
    return depth.reshape(shape)


def expression_flow(renderer, model: FaceModel, edited_raster, src_camera: Camera, src_vertices: np.ndarray) -> Flow:
    """The expression flow of Eq. (24) from one output image to one source image.

    Parameters
    ----------
    renderer : photomodel.rendering.renderer.Renderer
    model : FaceModel, the tracked model (its triangles).
    edited_raster : BarycentricRaster, the edited model rasterised in the output camera.
    src_camera : Camera, the source frame's tracked pose.
    src_vertices : (n, 3) float mm, the source frame's tracked geometry (head frame).

    Returns
    -------
    Flow
    """
    H, W = edited_raster.shape
    uv = src_camera.project(src_vertices).astype(np.float32)  # (n, 2)
    Xc = src_camera.to_camera(src_vertices)
    at = edited_raster.interpolate(np.concatenate([uv, Xc[:, 2:3].astype(np.float32)], axis=1))
    source, z = at[:, :2], at[:, 2]
    # is the point seen in the source? its own depth against the source surface at its pixel
    src_raster = renderer.rasterize_barycentric(src_camera, src_vertices, model.faces)
    depth = _depth_at(src_raster, Xc, (H, W))
    u = np.rint(source[:, 0]).astype(int)
    v = np.rint(source[:, 1]).astype(int)
    inside = (u >= 0) & (u < W) & (v >= 0) & (v < H)
    seen = np.full(len(u), np.inf, np.float32)
    seen[inside] = depth[v[inside], u[inside]]
    hidden = ~inside | (seen < z - HIDDEN_MM) | ~np.isfinite(seen)
    return Flow(source, edited_raster.pixels, hidden)


def _dense_flow(flow: Flow, shape: tuple, extend_px: float) -> np.ndarray:
    """(H, W, 2) float32 backward displacement (source − pixel) everywhere: the flow at the covered
    pixels, extended and faded beyond them (module docstring)."""
    H, W = shape
    d = np.zeros((H * W, 2), np.float32)
    py, px = np.divmod(flow.pixels, W)
    d[flow.pixels] = flow.source - np.column_stack([px, py]).astype(np.float32)
    d = d.reshape(H, W, 2)
    covered = np.zeros(H * W, np.float32)
    covered[flow.pixels] = 1.0
    covered = covered.reshape(H, W)
    if extend_px <= 0:
        return d
    k = 2 * int(np.ceil(FALLOFF_CUT * extend_px)) + 1
    num = cv2.GaussianBlur(d * covered[..., None], (k, k), extend_px)
    den = cv2.GaussianBlur(covered, (k, k), extend_px)
    dist = cv2.distanceTransform((covered == 0).astype(np.uint8), cv2.DIST_L2, 5)
    fall = np.exp(-0.5 * (dist / extend_px) ** 2) * (dist < FALLOFF_CUT * extend_px)
    ext = np.where(den[..., None] > 1e-6, num / np.maximum(den, 1e-6)[..., None], 0.0) * fall[..., None]
    return np.where(covered[..., None] > 0, d, ext).astype(np.float32)


def warp_frame(frame: np.ndarray, displacement: np.ndarray) -> np.ndarray:
    """``frame`` sampled at pixel + displacement (bilinear, OpenCV's remap), the pixels whose
    displacement is under :data:`STILL_PX` copied unchanged."""
    H, W = frame.shape[:2]
    gx, gy = np.meshgrid(np.arange(W, dtype=np.float32), np.arange(H, dtype=np.float32))
    out = cv2.remap(
        frame, gx + displacement[..., 0], gy + displacement[..., 1], cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE
    )
    still = np.abs(displacement).max(axis=2) < STILL_PX
    out[still] = frame[still]
    return out


@dataclass
class EditedFrame:
    """One written frame and how it was made.

    Attributes
    ----------
    image : (H, W, 3) float32, the edited frame.
    moved : (H, W) bool, pixels the edit changed (flow over :data:`STILL_PX` or filled).
    filled_similar, filled_texture : int, pixels taken from the most similar frame / the model's texture.
    """

    image: np.ndarray
    moved: np.ndarray
    filled_similar: int
    filled_texture: int


def edit_frame(
    renderer,
    model: FaceModel,
    camera: Camera,
    frame: np.ndarray,
    tracked_alpha: np.ndarray,
    edited_alpha: np.ndarray,
    similar=None,
    options: FlowOptions | None = None,
) -> EditedFrame:
    """Frame ``frame`` with the expression changed from ``tracked_alpha`` to ``edited_alpha`` (§4).

    Parameters
    ----------
    renderer : photomodel.rendering.renderer.Renderer
    model : FaceModel
    camera : Camera, the frame's tracked pose (``X_cam = R (X − c) + t``, as :meth:`FrameFitter.camera`).
    frame : (H, W, 3) float32 in [0, 1].
    tracked_alpha, edited_alpha : (a,) float, the frame's parameters before and after the edit.
    similar : ``(frame, camera, alpha)`` of the clip's most similar frame, optional (the fill).
    options : FlowOptions, optional.

    Returns
    -------
    EditedFrame
    """
    o = options or FlowOptions()
    frame = np.asarray(frame, np.float32)
    H, W = frame.shape[:2]
    Wv_e = model.vertex_weights(model.region_weights(edited_alpha))
    X_e = model.blend_geometry(Wv_e)
    X_t = model.geometry_at(tracked_alpha)
    raster = renderer.rasterize_barycentric(camera, X_e, model.faces)
    flow = expression_flow(renderer, model, raster, camera, X_t)
    disp = _dense_flow(flow, (H, W), o.extend_px)
    out = warp_frame(frame, disp)
    moved = np.abs(disp).max(axis=2) >= STILL_PX
    need = np.zeros(H * W, bool)
    need[flow.pixels[flow.hidden]] = True
    fill = np.zeros((H * W, 3), np.float32)
    n_similar = n_texture = 0
    if need.any():
        todo = need.copy()
        if similar is not None and o.similar_frame:
            s_frame, s_cam, s_alpha = similar
            sflow = expression_flow(renderer, model, raster, s_cam, model.geometry_at(s_alpha))
            ok = ~sflow.hidden & todo[sflow.pixels]
            if ok.any():
                src = sflow.source[ok]
                fill[sflow.pixels[ok]] = cv2.remap(
                    np.asarray(s_frame, np.float32),
                    src[:, 0:1],
                    src[:, 1:2],
                    cv2.INTER_LINEAR,
                    borderMode=cv2.BORDER_REPLICATE,
                )[:, 0]
            todo[sflow.pixels[ok]] = False
            n_similar = int(ok.sum())
        if todo.any():
            rendered = render_model(renderer, camera, model, X_e, Wv_e).image.reshape(-1, 3)
            fill[todo] = rendered[todo]
            n_texture = int(todo.sum())
        # feather: inside the filled pixels the fill's weight rises from the border over FILL_FEATHER_PX
        inside = cv2.distanceTransform(need.reshape(H, W).astype(np.uint8), cv2.DIST_L2, 3)
        wgt = np.clip(inside / (FILL_FEATHER_PX + 1.0), 0.0, 1.0)[..., None]
        out = ((1 - wgt) * out + wgt * fill.reshape(H, W, 3)).astype(np.float32)
        moved |= wgt[..., 0] > 0
    return EditedFrame(out, moved, n_similar, n_texture)
