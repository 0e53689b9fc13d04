"""The blend-shape face model of tracking (Pighin et al. 2002, §6.1.1) and its rendering (Eq. 5).

A :class:`FaceModel` holds ``m`` basic expressions ``E_1..E_m`` of one person on one mesh
(``E_1`` neutral): their geometries (m, n, 3) mm in the head frame and their textures (one
image per expression, their texture coordinates). The face is split into *control regions*
(:data:`CONTROL_REGIONS`: the generic mesh's mouth, eyes and forehead; the rest is constant,
§6.1.1 "the rest of the face … is constant"). Each region ``r`` has its own expression
parameters ``α_r`` and blending weights (Eq. 4)

    w_r = Q_r α_r + w*,      w* = (1, 0, …, 0),      Σ_k w_rk = 1,

with ``Q_r`` (m, a_r) spanning ``Σ_k w_k = 0``. ``Q_r`` comes from Gram–Schmidt of the directions
``E_k − E_1`` (k = 2..m) measured on the region's vertices (``basis="gram_schmidt"``; each column
is scaled so that ``α = 1`` moves the region's vertices by 1 mm RMS) or from a principal component
analysis of the region's geometries (``basis="pca"``). Directions that move the region by less
than :data:`MIN_DIRECTION_MM` RMS are dropped (the eyes region of an expression set that never
moves the eyes gets no parameter at all). Weights are limited to :data:`WEIGHT_RANGE`. The paper
takes ``w*`` as the mean of the expressions; we take the neutral expression, because with dropped
directions the mean is no longer reachable from the neutral (and ``α = 0`` is then the neutral face,
the natural start of the first frame).

Smooth transitions: every vertex has a *membership* ``μ_i`` (n, R) in the regions (one-hot on the
region labels, then smoothed over the mesh graph, :data:`MEMBERSHIP_SMOOTHING` passes), and its
blending weights are ``W_i = Σ_r μ_ir w_r`` with ``w_rest = e_1`` (neutral). The consensus geometry
is ``X_i = Σ_k W_ik E_k,i`` and the rendered image is Eq. (5), ``Î = Σ_k W_k Î_k``.

How we composite (Eq. 5)
------------------------
The paper rendered each ``Î_k`` with the weights in the 8-bit alpha channel, rescaled from
[−0.5, 1.5]. Our renderer has float targets, so no rescaling is needed, and one pass is enough:
the renderer's barycentric rasterisation
(:meth:`photomodel.rendering.renderer.Renderer.rasterize_barycentric`) gives, at every pixel the
consensus mesh covers, the triangle and the perspective-correct barycentric coordinates. Any
per-vertex quantity — uv, blending weights ``W_k``, memberships, camera-space positions, and the
per-vertex derivatives of §6.1.3 — is interpolated from these in numpy (a gather over the covered
pixels; exactly what rendering it as a float attribute would give, without one pass per four
channels). Each texture is sampled at the interpolated uv
(:func:`photomodel.rendering.sampling.sample_texture`, bilinear) and the samples are summed with
the interpolated weights ``W_k`` — Eq. (5) with Gouraud-interpolated weights, as in the paper.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import scipy.sparse as sparse

from photomodel.camera import Camera
from photomodel.rendering.barycentric import BarycentricRaster
from photomodel.rendering.sampling import sample_texture

__all__ = [
    "CONTROL_REGIONS",
    "WEIGHT_RANGE",
    "FaceModel",
    "ModelRender",
    "build_face_model",
    "control_regions",
    "smooth_membership",
    "expression_basis",
    "render_model",
]

#: Regions with their own expression parameters; index 0 (``rest``) is held neutral.
CONTROL_REGIONS = ("rest", "mouth", "eyes", "forehead")
#: Blending weights are never extrapolated beyond this range (§6.1.1).
WEIGHT_RANGE = (-0.5, 1.5)
#: Passes of neighbour averaging that smooth the region memberships: with the generic mesh's
#: ~3 mm edges, transitions about 1 cm wide (the paper blends regions smoothly, Fig. 9).
MEMBERSHIP_SMOOTHING = 12
#: Expression directions moving a region by less than this (mm RMS) are dropped.
MIN_DIRECTION_MM = 0.05


@dataclass
class FaceModel:
    """A blend-shape face model (§6.1.1). Build it with :func:`build_face_model`.

    Attributes
    ----------
    names : tuple of m str
        basic expressions, neutral first.
    geometry : (m, n, 3) float
        vertex positions of each basic expression, mm, head frame.
    faces : (f, 3) int64
    uv : (m, n, 2) float
        texture coordinates (v up, OBJ convention) of each expression's texture: a model built
        from photos has one cylindrical texture per expression, each in its own expression's
        cylinder (§5.2.2); expressions sharing a texture share its coordinates.
    textures : list of m (Ht, Wt, 3) float32
        each expression's texture in [0, 1]; identical entries may be the same array.
    regions : (n,) int
        control region of each vertex (index into :data:`CONTROL_REGIONS`).
    membership : (n, R) float
        smoothed region memberships, rows sum to 1.
    bases : list of R (m, a_r) float
        ``Q_r``; ``bases[0]`` (rest) has no column.
    centre : (3,) float
        the head centre (mm, head frame) about which the tracked rotation acts.
    face_mask : (n,) bool
        vertices used by accuracy metrics.
    shared : (m, s) float, optional
        a basis applied alike at every vertex, beside the regions' (beyond the paper): the
        rig's ARKit shapes (:mod:`tracking.arkit_face`). Its expressions are *displacements*
        (``E_k`` = the shape's offset from the neutral, mm, with a black texture: they move the
        surface and add no colour), each column one shape scaled to move the face by 1 mm at
        most per unit ``α``, so that ``W_k = α_k / s_k`` is the shape's own weight. Its
        parameters follow the regions' in the concatenated ``α``; :meth:`region_weights` then
        has one more row, the shared weights, added at every vertex (:meth:`vertex_weights`).
    """

    names: tuple
    geometry: np.ndarray
    faces: np.ndarray
    uv: np.ndarray
    textures: list
    regions: np.ndarray
    membership: np.ndarray
    bases: list
    centre: np.ndarray
    face_mask: np.ndarray
    shared: np.ndarray | None = None
    _texture_groups: list = field(default_factory=list, repr=False)
    _geometry_ndk: tuple = field(default=(None, None), repr=False)
    _group_uv: tuple | None = field(default=None, repr=False, compare=False)

    # -- parameter bookkeeping --------------------------------------------------------
    @property
    def m(self) -> int:
        return len(self.names)

    @property
    def n_alpha(self) -> list[int]:
        """Number of expression parameters of each region (rest: 0)."""
        return [Q.shape[1] for Q in self.bases]

    @property
    def n_shared(self) -> int:
        """Number of parameters of the shared basis (0 without one)."""
        return 0 if self.shared is None else self.shared.shape[1]

    @property
    def n_params(self) -> int:
        """Length of the concatenated ``α``: the regions' parameters, then the shared ones."""
        return sum(self.n_alpha) + self.n_shared

    @property
    def shared_slice(self) -> slice:
        """The shared basis' parameters in the concatenated ``α``."""
        a = sum(self.n_alpha)
        return slice(a, a + self.n_shared)

    @property
    def shared_expressions(self) -> np.ndarray:
        """(m,) bool: the expressions of the shared basis (displacements, see the class notes)."""
        if self.shared is None:
            return np.zeros(self.m, bool)
        return np.any(self.shared != 0, axis=1)

    @property
    def all_bases(self) -> list:
        """``bases`` and, with a shared basis, the shared basis last (one per row of :meth:`region_weights`)."""
        return list(self.bases) + ([self.shared] if self.n_shared else [])

    @property
    def all_membership(self) -> np.ndarray:
        """(n, R) memberships, with a column of ones for the shared basis when there is one."""
        if not self.n_shared:
            return self.membership
        return np.column_stack([self.membership, np.ones(len(self.membership))])

    @property
    def alpha_slices(self) -> list[slice]:
        """Slices of each region's ``α_r`` in the concatenated parameter vector."""
        out, start = [], 0
        for a in self.n_alpha:
            out.append(slice(start, start + a))
            start += a
        return out

    @property
    def w_star(self) -> np.ndarray:
        """The point ``w*`` of Eq. (4): the neutral expression ``e_1``."""
        return np.eye(self.m)[0]

    def region_weights(self, alpha: np.ndarray) -> np.ndarray:
        """(R, m) blending weights of each region from the concatenated ``α`` (Eq. 4);
        row 0 (rest) is neutral. With a shared basis, (R + 1, m): the last row holds the shared
        shapes' weights (0 on every other expression)."""
        alpha = np.asarray(alpha, float)
        W = np.zeros((len(self.bases) + (1 if self.n_shared else 0), self.m))
        W[0, 0] = 1.0
        for r, (Q, s) in enumerate(zip(self.bases, self.alpha_slices, strict=True)):
            if r:
                W[r] = Q @ alpha[s] + self.w_star
        if self.n_shared:
            W[-1] = self.shared @ alpha[self.shared_slice]
        return W

    def alpha_of_weights(self, weights: np.ndarray) -> np.ndarray:
        """Concatenated ``α`` closest (least squares) to region weights (R, m) or (m,) for all
        (with a shared basis, (R + 1, m) gives its row too; else its parameters are 0)."""
        W = np.asarray(weights, float)
        shared = np.zeros(self.n_shared)
        if self.n_shared and W.ndim == 2 and len(W) == len(self.bases) + 1:
            shared = np.linalg.lstsq(self.shared, W[-1], rcond=None)[0]
            W = W[:-1]
        W = np.broadcast_to(W, (len(self.bases), self.m))
        parts = [np.linalg.lstsq(Q, W[r] - self.w_star, rcond=None)[0] for r, Q in enumerate(self.bases) if r]
        return np.concatenate([np.zeros(0)] + parts + [shared])

    def vertex_weights(self, region_weights: np.ndarray) -> np.ndarray:
        """(n, m) per-vertex blending weights ``W_i = Σ_r μ_ir w_r`` (plus the shared row, alike
        at every vertex, when there is one)."""
        rw = np.asarray(region_weights, float)
        W = self.membership @ rw[: len(self.bases)]
        if len(rw) > len(self.bases):
            W += rw[len(self.bases)]
        return W

    def blend_geometry(self, vertex_weights: np.ndarray) -> np.ndarray:
        """(n, 3) mm consensus geometry ``X_i = Σ_k W_ik E_k,i``."""
        G, E = self._geometry_ndk
        if G is not self.geometry:  # (n, 3, m) contiguous: the product runs along the expressions (~10× faster)
            E = np.ascontiguousarray(np.transpose(self.geometry, (1, 2, 0)))
            self._geometry_ndk = (self.geometry, E)
        return np.einsum("nk,ndk->nd", vertex_weights, E)

    def geometry_at(self, alpha: np.ndarray) -> np.ndarray:
        """(n, 3) mm consensus geometry at expression parameters ``α``."""
        return self.blend_geometry(self.vertex_weights(self.region_weights(alpha)))

    def texture_groups(self) -> list[tuple[np.ndarray, list[int]]]:
        """Distinct (texture, uv) pairs and the expressions that use each: a texture shared by
        several expressions with the same coordinates is sampled once per rendering."""
        if not self._texture_groups:
            groups: list[tuple[np.ndarray, list[int]]] = []
            for k, T in enumerate(self.textures):
                for G, ks in groups:
                    if G is T and np.array_equal(self.uv[ks[0]], self.uv[k]):
                        ks.append(k)
                        break
                else:
                    groups.append((T, [k]))
            self._texture_groups = groups
        return self._texture_groups

    def group_uv(self) -> np.ndarray:
        """(n, 2G) the texture coordinates of each :meth:`texture_groups` entry, side by side
        (made once per grouping: every rendering needs it)."""
        groups = self.texture_groups()
        if self._group_uv is None or self._group_uv[0] is not groups:
            self._group_uv = (groups, np.concatenate([self.uv[ks[0]] for _, ks in groups], axis=1))
        return self._group_uv[1]


def control_regions(mesh_regions: np.ndarray, vertices: np.ndarray, landmarks: np.ndarray) -> np.ndarray:
    """(n,) control region of each vertex: the generic mesh's labels (:data:`CONTROL_REGIONS` order,
    the same as :data:`photomodel.modeling.generic_mesh.REGION_NAMES`), with the jaw below the mouth corners
    (between iBUG 3 and 13) joined to the mouth: the jaw moves with the mouth when it opens.

    Parameters
    ----------
    mesh_regions : (n,) int, generic-mesh region labels.
    vertices : (n, 3) float, neutral geometry, mm.
    landmarks : (68,) int, vertex index of each iBUG-68 landmark.
    """
    regions = np.asarray(mesh_regions).astype(np.int64).copy()
    L = vertices[landmarks]
    x, y = vertices[:, 0], vertices[:, 1]
    jaw = (regions == 0) & (y < min(L[48, 1], L[54, 1])) & (x > L[3, 0]) & (x < L[13, 0])
    regions[jaw] = CONTROL_REGIONS.index("mouth")
    return regions


def smooth_membership(regions: np.ndarray, faces: np.ndarray, passes: int = MEMBERSHIP_SMOOTHING) -> np.ndarray:
    """(n, R) memberships: one-hot of ``regions`` averaged ``passes`` times with the mesh
    neighbours (rows keep summing to 1)."""
    n = len(regions)
    mu = np.eye(len(CONTROL_REGIONS))[regions]
    edges = faces[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2)
    adj = sparse.coo_matrix((np.ones(len(edges)), (edges[:, 0], edges[:, 1])), shape=(n, n))
    adj = ((adj + adj.T) > 0).astype(float).tocsr()
    mean = sparse.diags(1.0 / np.maximum(np.asarray(adj.sum(1)).ravel(), 1)) @ adj
    for _ in range(passes):
        mu = 0.5 * mu + 0.5 * (mean @ mu)
    return mu / mu.sum(1, keepdims=True)


def expression_basis(
    geometry: np.ndarray, weight: np.ndarray, basis: str = "gram_schmidt", use: np.ndarray | None = None
) -> np.ndarray:
    """``Q`` (m, a) of one region: directions in weight space spanning ``Σ_k w_k = 0``.

    Parameters
    ----------
    geometry : (m, n, 3) float, the basic expressions, mm.
    weight : (n,) float, how much each vertex belongs to the region (its membership).
    basis : ``"gram_schmidt"`` or ``"pca"``
        Gram–Schmidt of ``E_k − E_1`` in the region's geometric inner product
        ``⟨a, b⟩ = Σ_i μ_i (G a)_i·(G b)_i / Σ_i μ_i`` (``G`` maps weights to geometry), or the
        principal directions of the region's ``E_k − E_1`` in that inner product.
    use : (m,) bool, optional
        the expressions that take part in this region (default all); the others keep weight 0
        here (an expression that does not move the region: in a model from photos its
        ``E_k − E_1`` there is only the fits' noise, which the tracker could not estimate).

    Returns
    -------
    (m, a) float
        columns with ``Σ_k Q_kl = 0``, each moving the region by 1 mm RMS per unit ``α``,
        orthogonal in that inner product; directions under :data:`MIN_DIRECTION_MM` dropped.
    """
    m = geometry.shape[0]
    sw = np.sqrt(np.asarray(weight, float) / max(float(np.sum(weight)), 1e-12))
    G = (geometry * sw[None, :, None]).reshape(m, -1).T  # (3n, m): weights → weighted geometry
    use = np.ones(m, bool) if use is None else np.asarray(use, bool)
    if basis == "gram_schmidt":
        cols = []
        for k in range(1, m):
            if not use[k]:
                continue
            d = np.zeros(m)
            d[k], d[0] = 1.0, -1.0
            for q in cols:
                d = d - (G @ q) @ (G @ d) * q
            norm = np.linalg.norm(G @ d)  # RMS displacement of the region, mm
            if norm > MIN_DIRECTION_MM:
                cols.append(d / norm)
        return np.array(cols).T.reshape(m, len(cols))
    if basis == "pca":
        # principal directions of the differences from the neutral E_k − E_1 (the reachable set
        # then contains the neutral, as with Gram–Schmidt)
        C = np.vstack([-np.ones((1, m - 1)), np.eye(m - 1)])[:, use[1:]]  # (m, a): coefficients → weights
        U, S, Vt = np.linalg.svd(G @ C, full_matrices=False)
        keep = S > MIN_DIRECTION_MM
        return (C @ Vt[keep].T) / S[keep]
    raise ValueError(f"basis must be 'gram_schmidt' or 'pca', got {basis!r}")


def build_face_model(
    names,
    geometry: np.ndarray,
    faces: np.ndarray,
    uv: np.ndarray,
    textures,
    regions: np.ndarray,
    *,
    face_mask: np.ndarray | None = None,
    basis: str = "gram_schmidt",
    smoothing: int = MEMBERSHIP_SMOOTHING,
    region_expressions: np.ndarray | None = None,
) -> FaceModel:
    """Assemble a :class:`FaceModel` from basic expressions.

    Parameters
    ----------
    names : sequence of m str, neutral first; m = 1 (the neutral alone) gives a model of head
        pose only (no region has a parameter).
    geometry : (m, n, 3) float mm.
    faces : (f, 3) int.
    uv : (n, 2) float shared by every texture, or (m, n, 2) one per expression; v up.
    textures : sequence of m images (Ht, Wt, 3), uint8 or float in [0, 1]; pass the same array
        (and uv) for expressions sharing a texture (it is then sampled once per frame).
    regions : (n,) int, control regions (:func:`control_regions`).
    face_mask : (n,) bool, optional, vertices of the face for metrics (default all).
    basis : ``"gram_schmidt"`` or ``"pca"`` (:func:`expression_basis`).
    smoothing : int, membership smoothing passes.
    region_expressions : (R, m) bool, optional, which expressions take part in each region
        (:func:`expression_basis` ``use``; default all).
    """
    names = tuple(names)
    E = np.asarray(geometry, float)
    m = len(names)
    if m < 1 or E.ndim != 3 or E.shape[0] != m or E.shape[2] != 3:
        raise ValueError(f"geometry must be (m, n, 3) with m = {m} ≥ 1 expressions, got {E.shape}")
    n = E.shape[1]
    F = np.asarray(faces, np.int64)
    uv = np.asarray(uv, float)
    if uv.shape == (n, 2):
        uv = np.broadcast_to(uv, (m, n, 2))
    if uv.shape != (m, n, 2):
        raise ValueError(f"uv must be ({n}, 2) or ({m}, {n}, 2), got {uv.shape}")
    uv = np.ascontiguousarray(uv)
    if len(textures) != m:
        raise ValueError(f"need one texture per expression ({m}), got {len(textures)}")
    converted: dict[int, np.ndarray] = {}
    tex = []
    for T in textures:
        if id(T) not in converted:
            A = np.asarray(T)
            A = A.astype(np.float32) / 255.0 if A.dtype == np.uint8 else A.astype(np.float32)
            if A.ndim != 3 or A.shape[2] != 3:
                raise ValueError(f"textures must be (Ht, Wt, 3) RGB, got {A.shape}")
            converted[id(T)] = A
        tex.append(converted[id(T)])
    regions = np.asarray(regions, np.int64)
    mu = smooth_membership(regions, F, smoothing)
    R = len(CONTROL_REGIONS)
    use = np.ones((R, m), bool) if region_expressions is None else np.asarray(region_expressions, bool)
    if use.shape != (R, m):
        raise ValueError(f"region_expressions must be ({R}, {m}) bool, got {use.shape}")
    bases = [np.zeros((m, 0))] + [expression_basis(E, mu[:, r], basis, use[r]) for r in range(1, R)]
    mask = np.ones(n, bool) if face_mask is None else np.asarray(face_mask, bool)
    centre = E[0][mask].mean(axis=0)
    return FaceModel(names, E, F, uv, tex, regions, mu, bases, centre, mask)


# ----------------------------------------------------------------------------- rendering


@dataclass
class ModelRender:
    """The model seen by a camera (Eq. 5), with what the Jacobian of §6.1.3 needs.

    Attributes
    ----------
    image : (H, W, 3) float32
        ``Î`` where the model covers the pixel; ``background`` (the target frame, when given)
        elsewhere.
    mask : (H, W) bool, covered pixels.
    raster : BarycentricRaster
        what the renderer's barycentric pass saw; its fields are also this object's:
        ``pixels`` (N,) flat indices of the covered pixels (row-major order), ``corners`` (N, 3)
        the vertex at each corner of the triangle under each covered pixel, ``bary`` (N, 3)
        float32 perspective-correct barycentric coordinates at the pixel centres, ``box``
        (y0, y1, x0, x1) the image rows/columns holding the projected model (clipped to the
        image; every covered pixel lies inside).
    X_cam : (N, 3) float, camera-space point (mm) under each covered pixel.
    texture_colors : list of (N, 3) float32, each distinct texture sampled at the pixels
        (``model.texture_groups()`` order).
    """

    image: np.ndarray
    mask: np.ndarray
    raster: BarycentricRaster
    X_cam: np.ndarray
    texture_colors: list

    pixels = property(lambda self: self.raster.pixels)
    corners = property(lambda self: self.raster.corners)
    bary = property(lambda self: self.raster.bary)
    box = property(lambda self: self.raster.box)

    def interpolate(self, values: np.ndarray) -> np.ndarray:
        """(N, ...) per-pixel interpolation of per-vertex ``values`` (n, ...)."""
        return self.raster.interpolate(values)


def render_model(
    renderer,
    camera: Camera,
    model: FaceModel,
    vertices: np.ndarray,
    vertex_weights: np.ndarray,
    background: np.ndarray | None = None,
) -> ModelRender:
    """Render the model with consensus geometry ``vertices`` and per-vertex weights (Eq. 5).

    One GL pass draws the barycentric coordinates and triangle ids
    (:meth:`photomodel.rendering.renderer.Renderer.rasterize_barycentric`, reading back only the
    model's bounding box); uv, weights and camera-space points are interpolated at the covered
    pixels in numpy, the textures sampled with
    :func:`photomodel.rendering.sampling.sample_texture` (OpenCV's remap).

    Parameters
    ----------
    renderer : photomodel.rendering.renderer.Renderer
    camera : Camera, the model's pose as a camera (``X_cam = R X + t``).
    model : FaceModel
    vertices : (n, 3) float mm, consensus geometry (:meth:`FaceModel.blend_geometry`).
    vertex_weights : (n, m) float, ``W``.
    background : (H, W, 3) float, optional, image under uncovered pixels (default 0).
    """
    V = np.asarray(vertices, float)
    if V.shape != (model.geometry.shape[1], 3):
        raise ValueError(f"vertices must be ({model.geometry.shape[1]}, 3) mm, got {V.shape}")
    H, W = camera.height, camera.width
    raster = renderer.rasterize_barycentric(camera, V, model.faces)
    Xc = camera.to_camera(V)  # (n, 3) camera mm, float64 on the CPU
    groups = model.texture_groups()
    G = len(groups)
    Wg = np.column_stack([np.asarray(vertex_weights)[:, ks].sum(1) for _, ks in groups])
    # (n, 3 + 2G + G) per-vertex attributes, float32 (camera mm to ~1e-4 mm), interpolated at once
    table = np.concatenate([Xc, model.group_uv(), Wg], axis=1).astype(np.float32)
    at = raster.interpolate(table)
    X_cam, uv, Wpix = at[:, :3], at[:, 3 : 3 + 2 * G], at[:, 3 + 2 * G :]
    colors = [sample_texture(T, uv[:, 2 * g : 2 * g + 2]) for g, (T, _) in enumerate(groups)]
    out = Wpix[:, 0:1] * colors[0]
    for g in range(1, G):
        out += Wpix[:, g : g + 1] * colors[g]
    image = np.zeros((H, W, 3), np.float32) if background is None else np.array(background, np.float32, copy=True)
    image.reshape(-1, 3)[raster.pixels] = out
    return ModelRender(image, raster.mask, raster, X_cam, colors)
