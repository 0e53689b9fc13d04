"""A localised statistical face prior on the generic mesh, after Brunton, Bolkart & Wuhrer (2014).

Seed 004 (*Multilinear Wavelets*) fits noisy, partly missing face data with many small local
models whose weights are held in a hyper-box, coarse to fine: what is missing is filled plausibly
(the local models only know faces), what is present is fitted closely (many small models have
many degrees of freedom). This module builds such a prior from **ICT-FaceKit's identity modes**
(:mod:`photomodel.rig.ict`; the james scan and anything fitted from it are not training data)
resampled onto the generic mesh by the rig's registration (:mod:`photomodel.rig.registration`),
and fits it to 3D targets (clicked/triangulated features) and to scans.

The model (:class:`FacePrior`)
------------------------------
A shape is the generic mesh plus a displacement that is a sum over levels ``l`` (coarse to fine)
of columns ``B_l`` (3N, M_l), each one local mode at one standard deviation::

    X(b) = X⁰ + Σ_l B_l b_l,        |b_lj| ≤ c          (the hyper-box, paper Eq. 8)

**Localisation.** The paper decomposes a subdivision surface with a wavelet transform; our mesh
(a decimated scan template) has no subdivision hierarchy, so each level is a smooth
**partition of unity** instead: patch centres spread over the face by farthest-point sampling
(spacing 0.7 × the level's radius ``R``), Wendland weights ``φ(r) = (1 − r/R)⁴ (4r/R + 1)`` of
the Euclidean distance to the centre, normalised so that the patches of a level sum to one at
every vertex. Level 0 is one patch (global, a few modes: the coarse shape); finer levels have
smaller patches (:data:`LEVELS`). Like wavelet coefficients, each level describes what the
coarser ones left: level ``l`` is trained on the **residual** of the training shapes after the
coarser levels' reconstruction (each patch's least-squares projection, blended by ``φ``), which
decorrelates the levels as the wavelet transform decorrelates its coefficients.

**Per-patch PCA.** ICT's identity model is Gaussian, ``d = Σ_k c_k I_k``, ``c ~ N(0, 1)``, with
the 100 modes ``I_k`` at one σ: the covariance of any linear image of ``d`` (a patch's residual) is
``R Rᵀ`` with ``R`` that image of the mode matrix, so a patch's principal components and their
σ are the SVD of ``R`` restricted to the patch — exact, no sampling. A patch keeps the modes
that hold :data:`PATCH_ENERGY` of its variance (at most the level's count); column ``j`` of ``B_l``
is ``φ_p ⊙ u_j s_j``, so every weight is N(0, 1) under the training model and one box ±c bounds all.

Outside ICT's face area (the back of the head, the neck below ICT's) the registration's
``covered`` flag is false; there the modes fade to zero over :data:`FADE_MM` of distance to the
ICT surface, so the prior never moves what ICT knows nothing about.

Fitting (:func:`fit_face_prior`, paper §5)
-----------------------------------------
1. **Landmark stage**: a similarity (Umeyama) of the model's target vertices onto the targets,
   then each level's weights by bounded linear least squares (normal equations, active set)
   against the targets, coarse to fine, with the loose box :data:`LANDMARK_BOX`; three rounds
   (the photo fit's similarity after the first round from the model's surface instead of its
   target vertices, :func:`_surface_similarity`).
   The paper minimises its (multilinear, so nonlinear) energies with L-BFGS-B; ours is linear in
   the weights once correspondences are fixed, so a bounded least-squares solve is exact.
2. **Dense stage** (scans): robust point-to-plane ICP (paper Eq. 6): each face vertex's nearest
   scan point, weight zero beyond the cut-off distance (:data:`CUTOFF_MM`, decreasing coarse to
   fine) or where the normals disagree; similarity re-estimated, weights per level, with the
   tighter box :data:`DENSE_BOX` (widened to a weight's landmark-stage value where that is already
   outside, as the paper does).

A small ridge ``λ‖b‖²`` (:data:`RIDGE`) is added to the paper's energy: with ~70 targets and
~1000 local weights the landmark stage is underdetermined, and the ridge picks the least
surprising face inside the box instead of an arbitrary one.

The photo fit uses the prior through :class:`PriorDeformer`, a drop-in for
:func:`photomodel.modeling.rbf.deform_vertices`: the prior moves the generic mesh towards the
clicked targets first, then the RBF deforms *that* mesh so that every click is still met exactly
(Pighin's §5.1.2 on a better starting shape).
"""

from __future__ import annotations

from collections import OrderedDict
from dataclasses import dataclass, field

import numpy as np
import scipy.sparse as sparse
from scipy.linalg import cho_factor, cho_solve
from scipy.spatial import ConvexHull, QhullError, cKDTree

from photomodel.alignment import similarity_transform
from photomodel.closest_points import TriangleSurface
from photomodel.data.cache import cached_arrays
from photomodel.data.keys import code_key
from photomodel.errors import FitError
from photomodel.modeling.generic_mesh import generic_mesh_key
from photomodel.modeling.rbf import RBFInterpolant
from photomodel.rendering.renderer import vertex_normals
from photomodel.rig.build import load_registration
from photomodel.rig.ict import load_ict

__all__ = [
    "FacePrior",
    "PriorFit",
    "PriorDeformer",
    "ScanData",
    "build_face_prior",
    "global_prior",
    "fit_face_prior",
    "load_face_prior",
    "prior_deformer",
    "LEVELS",
    "LANDMARK_BOX",
    "DENSE_BOX",
    "CUTOFF_MM",
    "RIDGE",
    "CLICK_RIDGE",
    "LOCAL_AFTER_GLOBAL_RIDGE",
    "OFFSET_FADE_MM",
]

#: Levels, coarse to fine: (patch radius mm or None for one global patch, most modes per patch).
LEVELS = ((None, 12), (70.0, 8), (40.0, 6), (24.0, 4))
#: A patch keeps the modes holding this fraction of its (residual) variance.
PATCH_ENERGY = 0.98
#: Patch centres are this fraction of the radius apart (farthest-point sampling).
CENTRE_SPACING = 0.7
#: Box ±c (in σ) of the landmark stage (loose) and of the dense stage (tight), paper §5.2.
LANDMARK_BOX = 3.0
DENSE_BOX = 2.0
#: Ridge λ on the weights (in units of σ², against residuals in mm²).
RIDGE = 0.5
#: Ridge of the photo fit's landmark stage (:class:`PriorDeformer`): triangulated clicks are
#: noisier than a scan, and a landmark's definition differs between meshes (below).
CLICK_RIDGE = 2.0
#: Ridge of the local prior's landmark stage when the global model has fitted the coarse shape
#: first (:class:`PriorDeformer` with ``coarse``): the local weights then only describe what the
#: global model left, and are held nearer zero. Chosen on ICT identities held out of the prior
#: (module notes, *Choosing the photo fit's settings*), not on the sample.
LOCAL_AFTER_GLOBAL_RIDGE = 8.0
#: Length (mm) over which :func:`slide_onto`'s normal offset fades outside the clicks' outline.
#: First looked at on the sample, then chosen on ICT people out of the prior's span (a prior
#: trained on a random half of ICT's identity space, people drawn from all of it, their 68
#: landmark vertices as targets with σ = 1 mm noise: 2.5–10 mm alike, no fade worse;
#: docs/modeling.md).
OFFSET_FADE_MM = 5.0
#: Prior fits kept by a :class:`PriorDeformer` for its warm refits (one per constrained-vertex set).
KEPT_SHAPES = 4
#: Point-to-plane cut-off (mm) of the dense stage per level (coarse to fine).
CUTOFF_MM = (10.0, 6.0, 4.0, 3.0)
#: Modes fade to zero between these distances (mm) of a vertex to the registered ICT surface.
FADE_MM = (4.0, 25.0)


@dataclass(frozen=True)
class FacePrior:
    """A multi-level local linear shape model on the generic mesh (see the module notes).

    Attributes
    ----------
    basis : (3N, M) sparse CSC float, column ``j`` the displacement (mm, rows ``3v + axis``) of
        weight ``j`` at one σ.
    level : (M,) int, the level of each column (0 coarsest).
    support : (N,) float in [0, 1], how much the prior may move each vertex (1 on ICT's face).
    faces : (F, 3) int, the mesh's triangles (normals for the dense stage).
    """

    basis: sparse.csc_matrix
    level: np.ndarray
    support: np.ndarray
    faces: np.ndarray

    @property
    def n_weights(self) -> int:
        return int(self.basis.shape[1])

    @property
    def levels(self) -> list[np.ndarray]:
        """Column indices of each level, coarse to fine."""
        return [np.flatnonzero(self.level == lv) for lv in np.unique(self.level)]

    def displacement(self, weights: np.ndarray) -> np.ndarray:
        """(N, 3) mm, the displacement of ``weights`` (M,)."""
        return (self.basis @ np.asarray(weights, float)).reshape(-1, 3)

    def to_arrays(self) -> dict[str, np.ndarray]:
        b = self.basis.tocsc()
        return {
            "data": b.data.astype(np.float32),
            "indices": b.indices,
            "indptr": b.indptr,
            "shape": np.array(b.shape),
            "level": self.level,
            "support": self.support,
            "faces": self.faces,
        }

    @classmethod
    def from_arrays(cls, a: dict) -> FacePrior:
        shape = tuple(int(x) for x in a["shape"])
        basis = sparse.csc_matrix((a["data"].astype(float), a["indices"], a["indptr"]), shape=shape)
        return cls(basis, np.asarray(a["level"]), np.asarray(a["support"], float), np.asarray(a["faces"]))


# -- building -------------------------------------------------------------------------------


def _farthest_points(points: np.ndarray, spacing: float) -> np.ndarray:
    """Indices of points chosen by farthest-point sampling until every point is within ``spacing``."""
    chosen = [int(np.argmin(np.linalg.norm(points - points.mean(0), axis=1)))]
    d = np.linalg.norm(points - points[chosen[0]], axis=1)
    while d.max() > spacing:
        j = int(d.argmax())
        chosen.append(j)
        d = np.minimum(d, np.linalg.norm(points - points[j], axis=1))
    return np.array(chosen)


def _wendland(r: np.ndarray) -> np.ndarray:
    r = np.clip(r, 0.0, 1.0)
    return (1.0 - r) ** 4 * (4.0 * r + 1.0)


def _partition(vertices: np.ndarray, active: np.ndarray, radius: float) -> sparse.csr_matrix:
    """(P, N) patch weights φ of one level, summing to one over patches at every active vertex."""
    pts = vertices[active]
    centres = pts[_farthest_points(pts, CENTRE_SPACING * radius)]
    tree = cKDTree(vertices[active])
    rows, cols, vals = [], [], []
    for p, c in enumerate(centres):
        near = np.asarray(tree.query_ball_point(c, radius), dtype=np.int64)
        w = _wendland(np.linalg.norm(pts[near] - c, axis=1) / radius)
        rows.append(np.full(len(near), p))
        cols.append(active[near])
        vals.append(w)
    phi = sparse.csr_matrix(
        (np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))), shape=(len(centres), len(vertices))
    )
    total = np.asarray(phi.sum(axis=0)).ravel()
    scale = np.where(total > 1e-12, 1.0 / np.maximum(total, 1e-12), 0.0)
    return (phi @ sparse.diags(scale)).tocsr()


def _rows(v: np.ndarray) -> np.ndarray:
    """Rows ``3v + axis`` of vertices ``v``."""
    return (3 * np.asarray(v)[:, None] + np.arange(3)).ravel()


def build_face_prior(
    vertices: np.ndarray, faces: np.ndarray, modes: np.ndarray, support: np.ndarray, levels=LEVELS
) -> FacePrior:
    """Train the local prior (module notes) from identity modes on the mesh.

    Parameters
    ----------
    vertices : (N, 3) float mm, faces : (F, 3) int — the generic mesh (patch geometry).
    modes : (K, N, 3) float mm, identity modes at one σ on the mesh (ICT's, resampled).
    support : (N,) float in [0, 1], the fade of the modes outside ICT's face area (already applied
        to ``modes``; patches cover the vertices where it is > 0).
    levels : sequence of (radius mm or None, most modes per patch).

    Returns
    -------
    FacePrior
    """
    V = np.asarray(vertices, float)
    R = np.asarray(modes, float).reshape(len(modes), -1).T.copy()  # (3N, K)
    active = np.flatnonzero(support > 0)
    cols, lv_of = [], []
    for lv, (radius, most) in enumerate(levels):
        if radius is None:
            U, s = _thin_svd(R)
            m = min(most, _kept(s))
            cols.append(sparse.csc_matrix(U[:, :m] * s[:m]))
            R = R - U[:, :m] @ (U[:, :m].T @ R)
            lv_of += [lv] * m
            continue
        phi = _partition(V, active, radius)
        recon = np.zeros_like(R)
        blocks = []
        for p in range(phi.shape[0]):
            row = phi.getrow(p)
            vs, w = row.indices, row.data
            rr = _rows(vs)
            U, s = _thin_svd(R[rr])
            m = min(most, _kept(s))
            if m == 0:
                continue
            w3 = np.repeat(w, 3)[:, None]
            local = U[:, :m]
            recon[rr] += w3 * (local @ (local.T @ R[rr]))
            blocks.append((rr, w3 * local * s[:m]))
        for rr, block in blocks:
            n, m = block.shape
            cols.append(
                sparse.csc_matrix((block.T.ravel(), np.tile(rr, m), np.arange(0, n * m + 1, n)), shape=(R.shape[0], m))
            )
            lv_of += [lv] * m
        R = R - recon
    basis = sparse.hstack(cols, format="csc")
    basis.sort_indices()
    return FacePrior(basis, np.array(lv_of, dtype=np.int64), np.asarray(support, float), np.asarray(faces))


def _thin_svd(M: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Left singular vectors and values of a tall ``M`` (m, k) from the eigenvectors of ``MᵀM``
    (k × k): ~50× faster than LAPACK's SVD of the tall matrix here, and exact enough for the
    modes kept (those above 1 % of the variance)."""
    w, V = np.linalg.eigh(M.T @ M)
    order = np.argsort(w)[::-1]
    s = np.sqrt(np.maximum(w[order], 0.0))
    keep = s > 1e-9 * max(s[0], 1e-300)
    return (M @ V[:, order[keep]]) / s[keep], s[keep]


def _kept(s: np.ndarray) -> int:
    """Modes holding :data:`PATCH_ENERGY` of the variance ``s²`` (none when it is all round-off)."""
    e = s**2
    if e.sum() <= 1e-12:
        return 0
    return int(np.searchsorted(np.cumsum(e) / e.sum(), PATCH_ENERGY) + 1)


def global_prior(faces: np.ndarray, modes: np.ndarray, support: np.ndarray) -> FacePrior:
    """The peer: one global PCA over all identity modes (ICT's own model), one level, same box."""
    K = len(modes)
    basis = sparse.csc_matrix(np.asarray(modes, float).reshape(K, -1).T)
    return FacePrior(basis, np.zeros(K, dtype=np.int64), np.asarray(support, float), np.asarray(faces))


def ict_modes_on_mesh(mesh, registration=None, ict=None) -> tuple[np.ndarray, np.ndarray]:
    """ICT's identity modes (K, N, 3) mm resampled onto ``mesh`` and faded outside ICT's face
    area, with the fade ``support`` (N,)."""
    ict = ict or load_ict()
    reg = registration or load_registration(mesh, ict)
    lo, hi = FADE_MM
    t = np.clip((reg.distance_mm - lo) / (hi - lo), 0.0, 1.0)
    support = 1.0 - t * t * (3.0 - 2.0 * t)
    modes = reg.displacements(ict.identities) * support[None, :, None]
    return modes, support


_LOADED: dict = {}


def load_face_prior(mesh, kind: str = "local") -> FacePrior:
    """The prior of the built-in generic mesh (``kind`` "local" or "global"), from the cache or
    built (a few seconds) and cached."""
    key = (kind, len(mesh.vertices))
    if key in _LOADED:
        return _LOADED[key]

    def build() -> dict:
        modes, support = ict_modes_on_mesh(mesh)
        if kind == "local":
            return build_face_prior(mesh.vertices, mesh.faces, modes, support).to_arrays()
        return global_prior(mesh.faces, modes, support).to_arrays()

    # keyed on this module's code (and what it imports: the registration, the rig's data) and the mesh
    cache_key = code_key(build_face_prior, inputs=(kind, generic_mesh_key(), len(mesh.vertices)))
    prior = FacePrior.from_arrays(cached_arrays(f"face_prior-{kind}", cache_key, build))
    _LOADED[key] = prior
    return prior


# -- fitting --------------------------------------------------------------------------------


@dataclass
class ScanData:
    """A scan for the dense stage: points (n, 3) mm and unit normals (n, 3), in the targets' frame."""

    points: np.ndarray
    normals: np.ndarray
    tree: cKDTree = field(init=False, repr=False)

    def __post_init__(self):
        self.points = np.asarray(self.points, float)
        self.normals = np.asarray(self.normals, float)
        self.tree = cKDTree(self.points)


@dataclass
class PriorFit:
    """What :func:`fit_face_prior` returns.

    Attributes
    ----------
    vertices : (N, 3) float mm, the fitted shape in the targets' frame.
    weights : (M,) float, the prior's weights (σ units).
    scale, rotation, translation : the similarity model frame → targets' frame.
    report : dict, ``inliers`` (dense stage: vertices within the cut-off), ``rms_mm``.
    """

    vertices: np.ndarray
    weights: np.ndarray
    scale: float
    rotation: np.ndarray
    translation: np.ndarray
    report: dict = field(default_factory=dict)


def _solve_level(A, rhs, cols, weights, box, ridge):
    """Bounded ridge least squares for the weights ``cols`` (the others fixed).

    A level has at most a few hundred weights against thousands of rows, so the problem is
    reduced to its normal equations ``H x = g`` (``H = AᵀA + λI``, positive definite by the
    ridge) and the box is met by :func:`_box_qp`, a few small Cholesky solves (2026-12: a scan fit
    11.8 → 2.3 s; the sparse iterative bounded solve of the tall system was 90 % of it)."""
    A = A[:, cols]
    used = np.flatnonzero(np.asarray(abs(A).sum(axis=0)).ravel() > 0)
    if used.size == 0:
        return
    A = A[:, used]
    c = cols[used]
    hi = np.full(len(c), float(box)) if np.ndim(box) == 0 else np.asarray(box, float)[c]
    H = (A.T @ A).toarray() + ridge * np.eye(len(c))
    weights[c] = _box_qp(H, A.T @ rhs, -hi, hi)


def _box_qp(H: np.ndarray, g: np.ndarray, lo: np.ndarray, hi: np.ndarray, iterations: int = 50) -> np.ndarray:
    """argmin ½xᵀHx − gᵀx with ``lo ≤ x ≤ hi``, ``H`` (n, n) positive definite: an active-set
    method (a primal one, clamping every violator at once, then releasing the bound weights whose
    gradient points into the box; the last iterate is clipped if it has not settled)."""
    n = len(g)
    at = np.zeros(n, dtype=np.int8)  # 0 free, −1 at lo, +1 at hi
    x = np.zeros(n)
    for _ in range(iterations):
        free = at == 0
        x = np.where(at < 0, lo, np.where(at > 0, hi, 0.0))
        if free.any():
            rhs = g[free] - H[np.ix_(free, ~free)] @ x[~free]
            x[free] = cho_solve(cho_factor(H[np.ix_(free, free)], check_finite=False), rhs, check_finite=False)
        over, under = free & (x > hi), free & (x < lo)
        grad = H @ x - g
        release = ((at > 0) & (grad > 0)) | ((at < 0) & (grad < 0))
        if not (over.any() or under.any() or release.any()):
            return x
        at[over], at[under] = 1, -1
        if not (over.any() or under.any()):
            at[release] = 0
    return np.clip(x, lo, hi)


def fit_face_prior(
    prior: FacePrior,
    base: np.ndarray,
    idx: np.ndarray,
    targets: np.ndarray,
    *,
    target_weights: np.ndarray | None = None,
    scan: ScanData | None = None,
    face: np.ndarray | None = None,
    rounds: int = 3,
    dense_iterations: int = 4,
    landmark_box: float = LANDMARK_BOX,
    dense_box: float = DENSE_BOX,
    ridge: float = RIDGE,
    cutoffs=CUTOFF_MM,
    similarity: bool = True,
    tangent_weight: float = 1.0,
    surface_weight: float = 0.0,
    similarity_on_surface: bool = False,
) -> PriorFit:
    """Fit the prior to vertex targets and (optionally) a scan, coarse to fine (module notes).

    Parameters
    ----------
    prior : FacePrior
    base : (N, 3) float mm, the mean shape (the generic mesh) in the model frame.
    idx : (k,) int, targeted vertices; targets : (k, 3) float mm, in the targets' frame.
    target_weights : (k,) float, optional (default 1).
    scan : ScanData, optional: adds the dense stage (robust point-to-plane).
    face : (N,) bool, the vertices the dense stage fits (default: where the prior has support).
    similarity : fit a similarity model → targets (False: the identity; targets in the model frame).
    tangent_weight : weight of a target's residual along the surface (its normal's is 1).
    similarity_on_surface : after the first round, the similarity onto the targets from the model's
        surface, not its targeted vertices (:func:`_surface_similarity`; for ``tangent_weight`` 0).

    Returns
    -------
    PriorFit
    """
    X0 = np.asarray(base, float)
    idx = np.asarray(idx, dtype=np.int64)
    P = np.asarray(targets, float)
    wt = np.ones(len(idx)) if target_weights is None else np.asarray(target_weights, float)
    levels = prior.levels
    b = np.zeros(prior.n_weights)
    s, R, t = 1.0, np.eye(3), np.zeros(3)
    # each target's residual in its vertex's frame (normal, two tangents), the tangents weighed
    # down: a landmark's definition slides along the skin from one mesh to another
    F = _frames(vertex_normals(X0, prior.faces)[idx]) * np.array([1.0, tangent_weight, tangent_weight])[None, :, None]
    F *= np.sqrt(wt)[:, None, None]
    Fm = _block_diag(F)
    Bl = (Fm @ prior.basis[_rows(idx)]).tocsr()

    def shape():
        return X0 + prior.displacement(b)

    def to_model(Y):
        return (Y - t) @ R / s

    fitted = np.flatnonzero(prior.support > 0.5)
    for n_round in range(rounds):
        X = shape()
        if similarity:
            s, R, t = _landmark_similarity(X, prior.faces, idx, P, wt, (s, R, t), similarity_on_surface and n_round > 0)
        Pm = to_model(P)
        for cols in levels:
            X = shape()
            rows_v, rhs_v = Bl, Fm @ (Pm - X[idx]).ravel() + Bl[:, cols] @ b[cols]
            if surface_weight > 0:  # each target to the model's surface: point-to-plane at its nearest vertex
                A_s, rhs_s = _surface_rows(prior, X, fitted, Pm, surface_weight * np.sqrt(wt), cols, b)
                rows_v, rhs_v = sparse.vstack([rows_v, A_s]).tocsr(), np.concatenate([rhs_v, rhs_s])
            _solve_level(rows_v, rhs_v, cols, b, landmark_box, ridge)
    report = {"landmark_rms_mm": _rms(shape()[idx] @ (s * R).T + t - P)}
    if scan is not None:
        s, R, t, b, report["inliers"] = _dense_stage(
            prior, X0, b, (s, R, t), idx, P, wt, scan, face, dense_iterations, dense_box, ridge, cutoffs, similarity
        )
    V = shape() @ (s * R).T + t
    report["rms_mm"] = _rms(V[idx] - P)
    return PriorFit(V, b, float(s), R, t, report)


def _landmark_similarity(X, faces, idx, P, wt, sim, on_surface: bool):
    """The landmark stage's similarity model → targets: from the surface (:func:`_surface_similarity`)
    or from the targeted vertices ``X[idx]``."""
    return _surface_similarity(X, faces, P, wt, sim) if on_surface else similarity_transform(X[idx], P, wt)


def _surface_similarity(X, faces, P, wt, sim, iterations: int = 3):
    """The similarity model → targets that pairs each target ``P`` (k, 3) with its closest point on
    the model's surface ``X`` (N, 3) / ``faces`` (Umeyama, re-paired ``iterations`` times from
    ``sim``): blind, like the point-to-plane shape step, to where along the skin a target lies.

    Why: the photo fit's landmark stage fits the shape to the targets' normal components only,
    while the similarity was fitted vertex to vertex, chasing the 8–9 mm by which a landmark's
    vertex and its click differ along the skin. Alternating the two did not settle: on the
    sample's 68 landmarks the scale went 0.93 → 0.99 → 1.07 over 1, 3, 6 rounds and the fit from
    1.03 (1 round) through 0.94 (3) to 1.20 mm (6). With the similarity on the surface both steps
    minimise one energy (docs/modeling.md)."""
    s, R, t = sim
    surface = TriangleSurface(X, faces)
    for _ in range(iterations):
        closest = surface.closest((P - t) @ R / s)[0]
        s, R, t = similarity_transform(closest, P, wt)
    return s, R, t


def _surface_rows(prior, X, fitted, Pm, w, cols, b):
    """Point-to-plane rows (and right-hand side) of targets ``Pm`` (model frame) at their nearest
    ``fitted`` vertex of shape ``X``, weighed by ``w``, for solving the weights ``cols``."""
    near = fitted[cKDTree(X[fitted]).query(Pm)[1]]
    nv = vertex_normals(X, prior.faces)[near] * w[:, None]
    A_s = (_row_blocks(nv) @ prior.basis[_rows(near)]).tocsr()
    return A_s, np.sum(nv * (Pm - X[near]), axis=1) + A_s[:, cols] @ b[cols]


def _frames(normals: np.ndarray) -> np.ndarray:
    """(k, 3, 3) rows: each unit normal and two unit tangents."""
    n = normals / np.maximum(np.linalg.norm(normals, axis=1, keepdims=True), 1e-12)
    a = np.where(np.abs(n[:, :1]) < 0.9, np.array([[1.0, 0, 0]]), np.array([[0, 1.0, 0]]))
    t1 = np.cross(n, a)
    t1 /= np.linalg.norm(t1, axis=1, keepdims=True)
    return np.stack([n, t1, np.cross(n, t1)], axis=1)


def _row_blocks(n: np.ndarray) -> sparse.csr_matrix:
    """(k, 3k) matrix whose row i is ``n_i`` on columns 3i…3i+2 (a dot product per point)."""
    k = len(n)
    return sparse.csr_matrix((n.ravel(), (np.repeat(np.arange(k), 3), np.arange(3 * k))), shape=(k, 3 * k))


def _block_diag(F: np.ndarray) -> sparse.csr_matrix:
    """(3k, 3k) block-diagonal matrix of the k (3, 3) blocks ``F``."""
    k = len(F)
    rows = np.repeat(np.arange(3 * k), 3)
    cols = (3 * np.arange(k)[:, None, None] + np.zeros((1, 3, 1), int) + np.arange(3)[None, None, :]).ravel()
    return sparse.csr_matrix((F.ravel(), (rows, cols)), shape=(3 * k, 3 * k))


def _rms(d: np.ndarray) -> float:
    return float(np.sqrt(np.mean(np.sum(d**2, axis=-1)))) if len(d) else 0.0


def _dense_stage(prior, X0, b, sim, idx, P, wt, scan, face, iterations, box, ridge, cutoffs, similarity):
    """Robust point-to-plane ICP, coarse to fine (module notes, step 2)."""
    s, R, t = sim
    verts = np.flatnonzero(prior.support > 0.5 if face is None else face)
    Bf = prior.basis[_rows(verts)].tocsr()
    Bl = prior.basis[_rows(idx)].tocsr()
    bounds = np.maximum(box, np.abs(b))  # a weight already outside stays free to its value
    lm_w = np.repeat(np.sqrt(wt), 3)
    inliers = 0.0
    for lv, cols in enumerate(prior.levels):
        cut = cutoffs[min(lv, len(cutoffs) - 1)]
        for _ in range(iterations):
            X = X0 + prior.displacement(b)
            Y = X[verts] @ (s * R).T + t
            d, j = scan.tree.query(Y, distance_upper_bound=cut)
            ok = np.isfinite(d)
            j = np.where(ok, j, 0)
            q, n = scan.points[j], scan.normals[j]
            ny = vertex_normals(X, prior.faces)[verts] @ R.T
            ok &= np.abs(np.sum(n * ny, axis=1)) > 0.5
            inliers = float(ok.mean())
            if ok.sum() < 10:
                break
            if similarity:  # rigid update from the landmarks and the pairs projected on their planes
                foot = Y[ok] + n[ok] * np.sum(n[ok] * (q[ok] - Y[ok]), axis=1, keepdims=True)
                src = np.concatenate([X[idx], X[verts[ok]]])
                dst = np.concatenate([P, foot])
                w = np.concatenate([wt * 10.0, np.ones(ok.sum())])
                s, R, t = similarity_transform(src, dst, w)
            # point-to-plane rows in the model frame: n'·(B b) = n'·(q' − x_rest)
            qm = (q[ok] - t) @ R / s
            nm = n[ok] @ R
            sel = np.flatnonzero(ok)
            rows3 = (3 * sel[:, None] + np.arange(3)).ravel()
            Bk = Bf[rows3]
            G = sparse.csr_matrix(
                (nm.ravel(), (np.repeat(np.arange(len(sel)), 3), np.arange(3 * len(sel)))),
                shape=(len(sel), 3 * len(sel)),
            )
            A_pp = G @ Bk
            xr = X[verts[ok]] - (Bk[:, cols] @ b[cols]).reshape(-1, 3)
            rhs_pp = np.sum(nm * (qm - xr), axis=1)
            Pm = (P - t) @ R / s
            rest = X[idx] - (Bl[:, cols] @ b[cols]).reshape(-1, 3)
            A = sparse.vstack([A_pp, sparse.diags(lm_w) @ Bl]).tocsr()
            rhs = np.concatenate([rhs_pp, lm_w * (Pm - rest).ravel()])
            _solve_level(A, rhs, cols, b, bounds, ridge)
    return s, R, t, b, inliers


class PriorDeformer:
    """A drop-in for :func:`photomodel.modeling.rbf.deform_vertices`: the prior's landmark stage
    moves ``vertices`` towards the targets, then ``inner`` (the RBF) deforms that shape so every
    constrained vertex lands exactly on its target.

    The landmark stage here fits each target to the model's *surface* (point-to-plane at the
    nearest vertex), not to its own vertex: the generic mesh's landmark vertices lie 8–9 mm RMS
    from where the same iBUG points are on the james scan, mostly *along* the skin (the jaw
    outline 15–27 mm: a silhouette point, not a skin point), which no identity mode explains;
    fitted vertex to vertex the prior bent the face to chase them (1.16 → 1.5–2.0 mm from the
    scan). The sliding is left to the RBF, which meets every click exactly.

    Parameters
    ----------
    prior : FacePrior
    inner : callable, the RBF deformation (``deform_vertices`` or a ``CachedDeformer``).
    refit : callable, optional: a ``CachedDeformer`` for :meth:`warm` (the studio's refits).
    coarse : FacePrior, optional: a global model fitted first (ridge :data:`CLICK_RIDGE`); ``prior``
        then starts from its shape with the ridge :data:`LOCAL_AFTER_GLOBAL_RIDGE` — coarse to fine
        with ICT's whole identity model as the coarsest level. With 68 clicks the global model
        holds the face's overall shape better than the local prior's 12 global modes (ICT
        identities held out of the prior: 0.85 → 0.82 mm; the sample, measured after choosing:
        0.98 → 0.95 mm), and the local patches still fit what it cannot.
    outline : (k,) int, optional: vertices (the mesh's 68 landmarks) whose place on the prior's
        surface bounds, with the clicks, where :func:`slide_onto`'s offset is not faded.
    """

    def __init__(self, prior: FacePrior, inner, coarse: FacePrior | None = None, refit=None, outline=None):
        self.prior = prior
        self.outline = outline
        self.inner = inner
        self.coarse = coarse
        self.refit = refit
        self.last: PriorFit | None = None
        #: the last full call's answer per recent constrained-vertex set (bytes → (N, 3)), for :meth:`warm`
        self.shapes: OrderedDict = OrderedDict()

    def __call__(self, vertices, constrained, targets, **kw) -> np.ndarray:
        idx = np.asarray(constrained)
        T = np.asarray(targets, dtype=float)
        V = np.asarray(vertices, float)
        if idx.ndim != 1 or T.shape != (len(idx), 3) or len(idx) < 4 or not np.all(np.isfinite(T)):
            return self.inner(vertices, constrained, targets, **kw)  # let the RBF word the error
        try:
            return self._prior_then_inner(V, idx, T, **kw)
        except FitError:
            # the prior's shape brought two constrained vertices together (measured: a one-photo
            # fit in the studio, two centres 0.0008 mm apart asking for different values, which no
            # interpolant meets): the RBF alone on the given vertices, as without the prior
            return self.inner(vertices, constrained, targets, **kw)

    def _prior_then_inner(self, V, idx, T, **kw) -> np.ndarray:
        """:meth:`__call__`'s work: the prior's fit (coarse to fine), the RBF onto every target."""
        ridge = CLICK_RIDGE
        if self.coarse is not None:
            first = fit_face_prior(
                self.coarse,
                V,
                idx,
                T,
                tangent_weight=0.0,
                surface_weight=1.0,
                ridge=CLICK_RIDGE,
                similarity_on_surface=True,
            )
            V = (first.vertices - first.translation) @ first.rotation / first.scale  # its shape, model frame
            ridge = LOCAL_AFTER_GLOBAL_RIDGE
        fit = fit_face_prior(
            self.prior, V, idx, T, tangent_weight=0.0, surface_weight=1.0, ridge=ridge, similarity_on_surface=True
        )
        self.last = fit
        moved = self.inner(fit.vertices, idx, T, **kw)
        out = slide_onto(fit.vertices, self.prior.faces, moved, idx, T, outline=self.outline)
        if self.refit is not None:
            key = idx.astype(np.int64).tobytes()
            self.shapes[key] = out
            self.shapes.move_to_end(key)
            while len(self.shapes) > KEPT_SHAPES:
                self.shapes.popitem(last=False)
            self.refit(out, idx, T, **kw)  # builds the refit's cached solve on this answer now
        return out

    def warm(self, vertices, constrained, targets, **kw) -> np.ndarray:
        """The interactive refit's deformation (:class:`photomodel.modeling.refit.Refitter` after an
        edit): the answer of the last full call with the same constrained vertices deformed by the
        cached RBF ``refit`` onto the (moved) targets — every click met, in milliseconds instead of
        the prior's seconds, and with unchanged targets exactly the full call's answer; the prior
        itself is fitted again by the next full call (the studio's *Fit*). A set not seen yet (a
        new click), or no ``refit``, gets the full call."""
        base = self.shapes.get(np.asarray(constrained).astype(np.int64).tobytes())
        if base is None or self.refit is None:
            return self(vertices, constrained, targets, **kw)
        return self.refit(base, constrained, targets, **kw)


def slide_onto(
    surface: np.ndarray,
    faces: np.ndarray,
    moved: np.ndarray,
    idx: np.ndarray,
    targets: np.ndarray,
    fade_mm: float = OFFSET_FADE_MM,
    outline: np.ndarray | None = None,
):
    """The RBF's answer ``moved`` (N, 3) laid back onto the prior's surface ``surface`` (N, 3) plus
    a smooth offset along its normal that meets every target: each vertex goes to its closest point
    ``c`` on the prior's surface, then ``h(c)`` along the surface normal there, ``h`` the RBF
    interpolant of the targets' signed distances from that surface. The clicks' sliding along the
    skin (the RBF's tangential moves) is kept, its bending of the surface between clicks is not;
    the targeted vertices land on their targets (snapped, as the RBF snaps them).

    **Only between the clicks.** The interpolant has an affine part, so beyond the clicks it goes
    on along the trend of their offsets (above the brows, where the 68 landmarks end, it lifted the
    forehead: 1.17 mm from the james scan for the prior's own surface, 1.92 mm after the offset).
    So ``h`` is kept as it is inside the outline of the clicks and of the vertices ``outline`` on
    the prior's surface (the face's 68 landmark vertices: the face's own outline, clicked or not —
    the detector's jaw clicks are often too unsure to be targets, and there the offset's trend
    towards the jaw helped: the sample's detector fit 1.223 mm with them, 1.247 without) and
    faded as ``exp(−(d/fade_mm)²)`` with ``d`` a point's distance outside it
    (:func:`_outside_clicks`); ``fade_mm`` 0 or None: no fade. Fading by the distance to the
    *nearest* click instead (tried earlier) also weakens the offset on the cheeks, between clicks
    far apart, where it carries the face's shape.

    The normal at ``c`` is the vertex normals interpolated (smooth across edges). With the
    triangle's own normal (before 2026-12-04) a closest point on an edge took either neighbour's,
    and rounding-level changes of ``moved`` (1e-14 mm) moved a vertex by up to 2.6 mm: the
    studio's fit (cached RBF) and the CLI's differed. Searching only each vertex's own two-ring
    of triangles (against a vertex landing on another sheet, the lids, the lips) was tried and
    measured worse (68 landmarks 0.95 → 0.99 mm): the RBF slides vertices farther than that.

    Returns (N, 3) float mm."""
    surf = TriangleSurface(surface, faces)
    closest, _, tri = surf.closest(moved)
    normal = surf.normals_at(closest, tri)
    c_t, _, tri_t = surf.closest(targets)
    h_t = np.sum(surf.normals_at(c_t, tri_t) * (targets - c_t), axis=1)
    f = RBFInterpolant.fit(c_t, np.column_stack([h_t, np.zeros((len(h_t), 2))]), smoothing=0.0)
    h = f(closest)[:, 0]
    if fade_mm:
        hull = c_t if outline is None else np.concatenate([c_t, surface[np.asarray(outline, dtype=np.int64)]])
        h = h * np.exp(-((_outside_clicks(closest, hull) / fade_mm) ** 2))
    out = closest + normal * h[:, None]
    out[idx] = targets
    return out


def _outside_clicks(points: np.ndarray, clicks: np.ndarray) -> np.ndarray:
    """(n,) mm how far each of ``points`` (n, 3) lies outside the clicks' outline (0 inside): the
    convex hull of ``clicks`` (k, 3) seen along their direction of least spread — the face's
    front axis for clicks spread over a face, whatever the frame. Zeros where the clicks span no
    area (fewer than three, or on a line)."""
    centre = clicks.mean(axis=0)
    axes = np.linalg.svd(clicks - centre, full_matrices=False)[2][:2]  # the two of most spread
    flat = (clicks - centre) @ axes.T
    try:
        planes = ConvexHull(flat).equations  # n·x + c ≤ 0 inside
    except (QhullError, ValueError):
        return np.zeros(len(points))
    return np.maximum(((points - centre) @ axes.T @ planes[:, :2].T + planes[:, 2]).max(axis=1), 0.0)


def prior_deformer(mesh, inner, refit=None) -> PriorDeformer:
    """:class:`PriorDeformer` of the built-in mesh's local prior around ``inner`` (the RBF), the
    global model fitted first (coarse to fine), the mesh's 68 landmarks as the face's outline;
    ``refit`` as for :class:`PriorDeformer`."""
    return PriorDeformer(
        load_face_prior(mesh, "local"),
        inner,
        coarse=load_face_prior(mesh, "global"),
        refit=refit,
        outline=mesh.landmarks,
    )
