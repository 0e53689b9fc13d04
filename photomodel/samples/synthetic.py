"""Ground truth from the real ``james`` head scan: where each generic-mesh vertex truly
lies on the scan, camera rigs, visibility, and what an artist would click and draw.

Used **only** by tests, benchmarks and ``sample_projects/make_james.py``; the fit
(:mod:`photomodel.modeling.fit`) never reads anything from here. To keep the ground truth
independent of the code it judges, nothing here uses :mod:`photomodel.modeling.rbf` or
:mod:`photomodel.modeling.pose`: the generic→scan correspondence is a thin-plate-spline warp
(:class:`scipy.interpolate.RBFInterpolator`, a kept, well-tested implementation) followed
by a non-rigid closest-point refinement written below.

Units and conventions are those of :mod:`photomodel.camera` (mm, head frame, pixels with
centres at integers, ``v`` down).

What a synthetic artist does
----------------------------
* **Clicks** (§5.1.1 / §5.1.3 of Pighin et al. 2002: features clicked in each photo) are
  the exact projections of the true 3D feature positions plus Gaussian hand noise
  (σ ≈ 1 px), only where the feature is visible (:func:`visible`).
* **Curves** (§5.1.3: eyebrows, eyelids, lips and chin are drawn as curves) are the
  projection of the true curve on the scan, resampled irregularly (15–40 stroke points),
  with a smooth hand wobble, clipped to the visible part, sometimes drawn in reverse.
"""

from __future__ import annotations

import json
import weakref
from collections.abc import Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
import scipy.sparse as sparse
from scipy.interpolate import RBFInterpolator
from scipy.spatial import cKDTree

from photomodel.camera import PRESET_AZIMUTH_DEG, Camera, focal_mm_to_px, orbit_camera, rodrigues
from photomodel.closest_points import TriangleSurface
from photomodel.data.cache import cached_arrays
from photomodel.data.keys import code_key
from photomodel.rendering.renderer import get_renderer, vertex_normals
from photomodel.texturing import visibility

if TYPE_CHECKING:  # imported lazily at run time: only these functions need the sample data
    from photomodel.modeling.generic_mesh import GenericMesh
    from photomodel.samples.sample_data import Scan

#: Third-party packages whose numerics move the correspondence (measured: up to 0.01 mm between
#: versions, see tests/test_synthetic.py); their versions are part of its cache key.
CORRESPONDENCE_PACKAGES = ("numpy", "scipy", "trimesh")

#: Smoothing passes of the displacement field in each closest-point iteration: strong
#: first (the field moves the mesh as a whole), weaker later (local detail).
_SMOOTHING_SCHEDULE = (40, 20, 10, 5, 3, 2, 1, 1)
#: A closest-point match is trusted only if the surface normals agree (cos > this) and
#: it is closer than :data:`_MAX_MATCH_MM`: rejects matches across the lips, into the
#: nostrils and at the template's outer border, where the scan's surface is elsewhere.
_MIN_NORMAL_COS = 0.5
_MAX_MATCH_MM = 15.0

#: Rough centre of the james head in the head frame (mm): the middle of the scan's
#: bounding box in x and y, moved forward of the skull centre towards the face so the
#: face stays in frame in side views. Rigs aim near it.
HEAD_CENTRE_MM = np.array([0.0, 12.0, 55.0])
#: Apparent radius (mm) of the part of the head a rig frames, and the fraction of the
#: half-frame it fills.
_FRAMED_RADIUS_MM = 125.0
_FILL = 0.88

# Rigs: (azimuth°, elevation°, roll°, lens mm, aim offset mm from HEAD_CENTRE_MM). Azimuths
# are deliberately not the presets' so the artist's preset is only a rough guess.
_RIGS: dict[str, tuple[tuple[float, float, float, float, tuple[float, float, float]], ...]] = {
    "sample": (
        (-75.0, 4.0, -2.0, 35.0, (2.0, -3.0, 1.0)),
        (-35.0, 3.0, 1.5, 50.0, (-3.0, 2.0, 0.0)),
        (0.0, -7.0, -1.0, 85.0, (1.0, 4.0, -2.0)),  # from slightly below: the jaw line shows
        (40.0, -2.0, 2.5, 100.0, (-2.0, -1.0, 3.0)),
        (80.0, 10.0, -1.5, 70.0, (3.0, 2.0, -1.0)),
    ),
    "three": (
        (-45.0, 2.0, 1.0, 50.0, (-2.0, 1.0, 0.0)),
        (0.0, 6.0, -1.0, 85.0, (1.0, 3.0, -1.0)),
        (50.0, -3.0, 2.0, 70.0, (2.0, -2.0, 2.0)),
    ),
    "seven": (
        (-85.0, 3.0, -1.0, 50.0, (2.0, -2.0, 0.0)),
        (-60.0, 8.0, 2.0, 70.0, (-1.0, 3.0, 1.0)),
        (-28.0, -4.0, -2.5, 35.0, (3.0, 0.0, -2.0)),
        (3.0, 5.0, 1.0, 85.0, (0.0, 2.0, 1.0)),
        (32.0, -5.0, -1.0, 100.0, (-2.0, -3.0, 0.0)),
        (58.0, 9.0, 1.5, 50.0, (1.0, 1.0, 2.0)),
        (86.0, 0.0, -2.0, 70.0, (-3.0, 2.0, -1.0)),
    ),
}
_RIG_BY_COUNT = {5: "sample", 3: "three", 7: "seven"}
RIG_NAMES = tuple(_RIGS)


# ----------------------------------------------------------------------------- surface


#: The james scan's surface queries are those of any triangle surface.
ScanSurface = TriangleSurface

_SURFACES: dict[int, ScanSurface] = {}


def scan_surface(scan: Scan) -> ScanSurface:
    """The :class:`ScanSurface` of ``scan``'s welded surface, built once per scan object."""
    key = id(scan)
    if key not in _SURFACES:
        welded = scan.welded
        _SURFACES[key] = ScanSurface(np.asarray(welded.vertices), np.asarray(welded.faces))
        weakref.finalize(scan, _SURFACES.pop, key, None)
    return _SURFACES[key]


def deformed_scan(scan: Scan, vertices: np.ndarray, landmarks: np.ndarray | None = None) -> Scan:
    """A copy of ``scan`` whose surface is moved to ``vertices`` (same triangles, texture
    coordinates and texture): e.g. the scan in another facial expression.

    The copy is a new :class:`~photomodel.samples.sample_data.Scan` object, so its welded surface
    (:func:`scan_surface`, used by :func:`surface_distance`, :func:`visible` and
    :func:`dense_true_curve`) is built from the new vertices, not shared with ``scan``.

    Parameters
    ----------
    scan : Scan
    vertices : (n, 3) float mm, one per vertex of ``scan`` (vertices at the same OBJ position
        must move together, as any displacement field of space does).
    landmarks : (68, 3) float mm, optional; the moved landmarks (default: ``scan``'s).
    """

    V = _points3(vertices, "vertices")
    if V.shape != np.shape(scan.vertices):
        raise ValueError(f"vertices must be {np.shape(scan.vertices)} like the scan's, got {V.shape}")
    L = np.asarray(scan.landmarks if landmarks is None else landmarks, float)
    if L.shape != np.shape(scan.landmarks):
        raise ValueError(f"landmarks must be {np.shape(scan.landmarks)}, got {L.shape}")
    return replace(scan, vertices=V.copy(), landmarks=L.copy())


def surface_distance(points: np.ndarray, scan: Scan) -> np.ndarray:
    """(n,) float distance in mm from each of ``points`` (n, 3) to the welded scan surface."""
    return scan_surface(scan).closest(points)[1]


def surface_normals(points: np.ndarray, scan: Scan) -> np.ndarray:
    """(n, 3) unit outward scan normal at the surface point closest to each of ``points``."""
    surf = scan_surface(scan)
    closest, _, face = surf.closest(points)
    return surf.normals_at(closest, face)


# ----------------------------------------------------------------------------- correspondence


def true_correspondence(mesh: GenericMesh, scan: Scan, *, use_cache: bool = True) -> np.ndarray:
    """For every generic-mesh vertex, its true position on the james scan.

    1. Thin-plate-spline warp of the generic mesh driven by the 68 landmark pairs
       (generic landmark vertices → scan landmarks).
    2. Non-rigid closest-point refinement (:data:`_SMOOTHING_SCHEDULE` iterations): each
       vertex is matched to its closest scan point, matches whose normals disagree or
       that are too far are given zero weight, the displacement field is smoothed over
       the mesh graph (weighted, landmark displacements held), and applied.
    3. Every vertex is projected onto the scan surface (the smoothed field leaves it
       ~0.1–0.2 mm away), and the landmark vertices are put exactly on the scan landmarks
       (which lie within 0.15 mm of the surface).

    Parameters
    ----------
    mesh : GenericMesh
    scan : Scan
    use_cache : bool
        read/write ``<cache>/true_correspondence-<key>.npz`` (:func:`correspondence_key`).

    Returns
    -------
    (n, 3) float
        mm, head frame; row ``i`` is where generic vertex ``i`` truly lies on the scan.
    """
    return _correspondence_arrays(mesh, scan, use_cache)["points"]


def correspondence_residual(mesh: GenericMesh, scan: Scan, *, use_cache: bool = True) -> np.ndarray:
    """(n,) float mm: distance from the scan of each vertex of the smooth warp *before*
    the final projection of :func:`true_correspondence` (a quality measure of the
    smooth field; large only where the template's shape differs, e.g. inside the
    nostrils and between the lips)."""
    return _correspondence_arrays(mesh, scan, use_cache)["smooth_residual"]


def correspondence_key(mesh: GenericMesh, scan: Scan) -> str:
    """The cache key of the correspondence: :func:`build_correspondence`'s code (this module and
    what it imports), the meshes it is made from and :data:`CORRESPONDENCE_PACKAGES`' versions."""
    inputs = (mesh.vertices, mesh.faces, mesh.landmarks, scan.vertices, scan.faces, scan.landmarks)
    return code_key(build_correspondence, inputs=inputs, packages=CORRESPONDENCE_PACKAGES)


def _correspondence_arrays(mesh: GenericMesh, scan: Scan, use_cache: bool) -> dict[str, np.ndarray]:
    def build():
        points, residual = build_correspondence(mesh, scan)
        return {"points": points, "smooth_residual": residual}

    if not use_cache:
        return build()
    return cached_arrays("true_correspondence", correspondence_key(mesh, scan), build)


def build_correspondence(mesh: GenericMesh, scan: Scan) -> tuple[np.ndarray, np.ndarray]:
    """``(points, smooth_residual)`` of :func:`true_correspondence` and
    :func:`correspondence_residual`, computed (the uncached path)."""
    V, F, L = np.asarray(mesh.vertices, float), np.asarray(mesh.faces), np.asarray(mesh.landmarks)
    target = np.asarray(scan.landmarks, float)
    surf = scan_surface(scan)
    n = len(V)

    X = RBFInterpolator(V[L], target, kernel="thin_plate_spline")(V)

    edges = F[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2)
    adj = sparse.coo_matrix((np.ones(len(edges)), (edges[:, 0], edges[:, 1])), shape=(n, n))
    adj = ((adj + adj.T) > 0).astype(float).tocsr()
    mean_of_neighbours = sparse.diags(1.0 / np.maximum(np.asarray(adj.sum(1)).ravel(), 1)) @ adj

    for passes in _SMOOTHING_SCHEDULE:
        closest, dist, face = surf.closest(X)
        disp = closest - X
        agree = np.einsum("ij,ij->i", vertex_normals(X, F), surf.face_normals[face])
        weight = ((agree > _MIN_NORMAL_COS) & (dist < _MAX_MATCH_MM)).astype(float)
        disp[L] = target - X[L]
        weight[L] = 1.0
        wd, w = disp * weight[:, None], weight.copy()
        for _ in range(passes):  # weighted Laplacian smoothing, landmark values held
            wd = 0.5 * wd + 0.5 * (mean_of_neighbours @ wd)
            w = 0.5 * w + 0.5 * (mean_of_neighbours @ w)
            wd[L], w[L] = disp[L], 1.0
        X = X + wd / np.maximum(w, 1e-9)[:, None]

    closest, residual, _ = surf.closest(X)
    closest[L] = target
    return closest, residual


def true_feature_positions(mesh: GenericMesh, scan: Scan, vertices: Sequence[int]) -> np.ndarray:
    """(k, 3) float mm: the true scan position of generic-mesh ``vertices`` (k,)."""
    return true_correspondence(mesh, scan)[np.asarray(vertices, np.int64)]


def extra_correspondences(
    mesh: GenericMesh, n: int = 100, *, seed: int = 0, min_landmark_distance_mm: float = 6.0
) -> dict[str, int]:
    """``n`` extra feature vertices spread over the face by farthest-point sampling.

    Candidates are the vertices of ``mesh.face_mask`` at least
    ``min_landmark_distance_mm`` from every landmark vertex (which are features already).
    The first is drawn with ``seed``; each next one is the candidate farthest (3D) from
    those chosen.

    Returns
    -------
    dict[str, int]
        ``{"extra_000": vertex, ...}`` in sampling order.
    """
    if n < 0:
        raise ValueError(f"n must be >= 0, got {n}")
    V = np.asarray(mesh.vertices, float)
    near_lm, _ = cKDTree(V[mesh.landmarks]).query(V)
    cand = np.flatnonzero(np.asarray(mesh.face_mask, bool) & (near_lm >= min_landmark_distance_mm))
    if n > len(cand):
        raise ValueError(f"only {len(cand)} candidate vertices for {n} extra correspondences")
    chosen = [int(cand[np.random.default_rng(seed).integers(len(cand))])]
    dist = np.linalg.norm(V[cand] - V[chosen[0]], axis=1)
    while len(chosen) < n:
        j = int(np.argmax(dist))
        chosen.append(int(cand[j]))
        dist = np.minimum(dist, np.linalg.norm(V[cand] - V[cand[j]], axis=1))
    return {f"extra_{i:03d}": v for i, v in enumerate(chosen[:n])}


# ----------------------------------------------------------------------------- rigs


def rig(name: str | int = "sample", width: int = 1000, height: int = 1000) -> list[Camera]:
    """The true cameras of a synthetic photo shoot of the james head.

    Parameters
    ----------
    name : {"sample", "three", "seven"} or {5, 3, 7}
        ``"sample"`` (5 cameras, the sample project): azimuths −75°, −35°, 0°, +40°,
        +80°, lenses 35, 50, 85, 100, 70 mm; ``"three"``: −45°, 0°, +50°; ``"seven"``:
        −85° … +86°. Each camera has its own small elevation (−7…+10°), roll (±2.5°) and
        aim offset (a few mm around :data:`HEAD_CENTRE_MM`), and a distance chosen so
        the head fills most of the frame whatever the lens.
    width, height : int
        image size in pixels.

    Returns
    -------
    list[Camera]
        ordered by azimuth (subject's right → left).
    """
    if isinstance(name, (int, np.integer)) and not isinstance(name, bool):
        if int(name) not in _RIG_BY_COUNT:
            raise ValueError(f"no rig with {name} cameras; choose {sorted(_RIG_BY_COUNT)}")
        name = _RIG_BY_COUNT[int(name)]
    if name not in _RIGS:
        raise ValueError(f"unknown rig {name!r}; choose one of {list(_RIGS)} or {sorted(_RIG_BY_COUNT)}")
    if int(width) < 1 or int(height) < 1:
        raise ValueError(f"image size must be positive, got {width}×{height}")
    cameras = []
    for az, el, roll, lens, offset in _RIGS[name]:
        f_px = focal_mm_to_px(lens, width)
        distance = f_px * _FRAMED_RADIUS_MM / (_FILL * min(width, height) / 2.0)
        cam = orbit_camera(
            az,
            width,
            height,
            distance_mm=distance,
            focal_mm=lens,
            elevation_deg=el,
            target=HEAD_CENTRE_MM + np.asarray(offset),
        )
        spin = rodrigues(np.array([0.0, 0.0, np.radians(roll)]))  # about the optical axis
        cameras.append(Camera(spin @ cam.R, spin @ cam.t, cam.f, width, height))
    return cameras


def azimuth_deg(camera: Camera) -> float:
    """Azimuth in degrees of ``camera``'s centre about the head (world +y axis through
    :data:`HEAD_CENTRE_MM`); 0 in front of the face, +90 at the subject's left."""
    c = camera.center - HEAD_CENTRE_MM
    return float(np.degrees(np.arctan2(c[0], c[2])))


def preset_for(camera: Camera) -> str:
    """The preset (key of :data:`photomodel.camera.PRESET_AZIMUTH_DEG`) nearest in
    azimuth to ``camera``: the artist's rough initial guess for that photo."""
    az = azimuth_deg(camera)
    return min(PRESET_AZIMUTH_DEG, key=lambda p: abs(PRESET_AZIMUTH_DEG[p] - az))


# ----------------------------------------------------------------------------- rendering


def render_scan(camera: Camera, scan: Scan, *, background=0.0, supersample: int = 1):
    """Render the textured scan from ``camera`` with :func:`photomodel.rendering.renderer.get_renderer`.

    The texture is already lit (a scan's photographs), so it is drawn unshaded.
    ``background`` and ``supersample`` are passed to :meth:`photomodel.rendering.renderer.Renderer.render`.

    Returns
    -------
    RenderResult
        ``color`` (H, W, 3) float in [0, 1], ``depth`` (H, W) mm (inf on background),
        ``mask`` (H, W) bool.
    """

    return get_renderer().render(
        camera,
        scan.vertices,
        scan.faces,
        uv=scan.uv,
        texture=scan.texture,
        background=background,
        supersample=supersample,
    )


def scan_depth(camera: Camera, scan: Scan) -> np.ndarray:
    """(H, W) float: rendered depth ``Z_cam`` (mm) of the scan from ``camera``, inf on background."""
    return np.asarray(render_scan(camera, scan).depth, float)


# ----------------------------------------------------------------------------- visibility

#: Where an artist still clicks a feature. Features on a silhouette (the nose tip, lips and
#: chin in a profile) are clicked on the contour, where the true point lies a millimetre or
#: two behind the surface the camera grazes: clicks accept surfaces seen edge-on and that
#: much depth slack (the defaults of :func:`visible`, n·view > 0.1 and 1.5 mm, would drop them).
CLICK_MIN_COS = -0.05
CLICK_TOL_MM = 2.5


def visible(
    camera: Camera,
    points: np.ndarray,
    scan: Scan,
    *,
    depth: np.ndarray | None = None,
    normals: np.ndarray | None = None,
    tol_mm: float = 1.5,
    min_cos: float = 0.1,
) -> np.ndarray:
    """Which scan-surface ``points`` a camera sees.

    A point is visible when it projects inside the image, it is not more than ``tol_mm``
    behind the scan's rendered depth there (bilinear between the four surrounding covered
    pixels, so sloped surfaces are not penalised by rounding; a point *in front* of the
    rendered depth lies on a silhouette, where the pixel already shows what is behind
    it), and the surface faces the camera: ``n · (c − p)/‖c − p‖ > min_cos``. This is
    :func:`photomodel.texturing.visibility.visible` with the ``"covered"`` depth lookup.

    Parameters
    ----------
    camera : Camera
    points : (n, 3) float
        mm, on (or within a fraction of a mm of) the scan surface.
    scan : Scan
    depth : (H, W) float, optional
        the scan's depth map from ``camera`` (:func:`scan_depth`); rendered if omitted.
    normals : (n, 3) float, optional
        unit outward normals at ``points``; the scan's (:func:`surface_normals`) if omitted.

    Returns
    -------
    (n,) bool
    """
    points = _points3(points, "points")
    if depth is None:
        depth = scan_depth(camera, scan)
    if normals is None:
        normals = surface_normals(points, scan)
    return visibility.visible(camera, points, normals, depth, tol_mm=tol_mm, min_cos=min_cos, lookup="covered")


# ----------------------------------------------------------------------------- the artist


def synthesize_clicks(
    cameras: Sequence[Camera],
    points3d: np.ndarray,
    visible: np.ndarray,
    noise_px: float = 1.0,
    rng: np.random.Generator | int | None = None,
) -> np.ndarray:
    """What an artist clicks: projections plus Gaussian hand noise, where visible.

    Parameters
    ----------
    cameras : k cameras.
    points3d : (n, 3) float, true feature positions (mm).
    visible : (k, n) bool, feature ``j`` visible in photo ``i``.
    noise_px : float, σ of the isotropic Gaussian click noise (px).
    rng : Generator or seed.

    Returns
    -------
    (k, n, 2) float
        clicks ``[u, v]`` clipped to the image, NaN where not visible (the observation
        array of ``docs/architecture.md``).
    """
    points3d = _points3(points3d, "points3d")
    visible = np.asarray(visible, bool)
    if visible.shape != (len(cameras), len(points3d)):
        raise ValueError(f"visible is {visible.shape}, expected {(len(cameras), len(points3d))}")
    if noise_px < 0:
        raise ValueError(f"noise_px must be >= 0, got {noise_px}")
    rng = np.random.default_rng(rng)
    out = np.full((len(cameras), len(points3d), 2), np.nan)
    for i, cam in enumerate(cameras):
        uv = cam.project(points3d) + rng.normal(scale=noise_px, size=(len(points3d), 2))
        uv = np.clip(uv, 0.0, [cam.width - 1, cam.height - 1])
        out[i, visible[i]] = uv[visible[i]]
    return out


def dense_true_curve(points3d: np.ndarray, scan: Scan, spacing_mm: float = 0.5) -> np.ndarray:
    """Densify a 3D polyline (m, 3) to points every ≤ ``spacing_mm`` and project them onto
    the scan surface: the true curve on the scan, (p, 3) float mm."""
    points3d = _points3(points3d, "points3d")
    if len(points3d) < 2:
        raise ValueError("a curve needs at least two points")
    seg = np.diff(points3d, axis=0)
    steps = np.maximum(1, np.ceil(np.linalg.norm(seg, axis=1) / spacing_mm).astype(int))
    parts = [points3d[i] + np.outer(np.arange(s) / s, seg[i]) for i, s in enumerate(steps)]
    dense = np.vstack(parts + [points3d[-1:]])
    return scan_surface(scan).closest(dense)[0]


def synthesize_curve(
    camera: Camera,
    polyline_points3d: np.ndarray,
    noise_px: float = 1.0,
    rng: np.random.Generator | int | None = None,
    *,
    visible: np.ndarray | None = None,
    n_points: tuple[int, int] = (15, 40),
    min_length_px: float = 10.0,
) -> np.ndarray | None:
    """What an artist draws for a curve (§5.1.3) in one photo.

    The projection of the dense true 3D curve is cut to its longest visible run,
    resampled at ``n_points`` (drawn uniformly in the inclusive range) irregularly spaced
    stroke points (gamma-distributed gaps, as a hand's speed varies), ends included;
    a smooth wobble (a few random low-frequency sinusoids along the stroke, RMS
    ``noise_px`` per axis) is added, the result clipped to the image, and half the
    strokes (by the ``rng``) are drawn in reverse.

    Parameters
    ----------
    camera : Camera
    polyline_points3d : (p, 3) float
        the dense true curve on the scan (:func:`dense_true_curve`), mm.
    noise_px : float
    rng : Generator or seed.
    visible : (p,) bool, optional
        visibility of each curve point (:func:`visible`); all visible if omitted.
    n_points : (int, int)
    min_length_px : float
        a visible run shorter than this on screen is not drawn.

    Returns
    -------
    (q, 2) float or None
        the stroke in pixels, or None when too little of the curve is visible.
    """
    pts = _points3(polyline_points3d, "polyline_points3d")
    rng = np.random.default_rng(rng)
    vis = np.ones(len(pts), bool) if visible is None else np.asarray(visible, bool)
    if vis.shape != (len(pts),):
        raise ValueError(f"visible is {vis.shape}, expected ({len(pts)},)")
    start, stop = _longest_run(vis)
    if stop - start < 2:
        return None
    uv = camera.project(pts[start:stop])
    arc = np.r_[0.0, np.cumsum(np.linalg.norm(np.diff(uv, axis=0), axis=1))]
    length = arc[-1]
    if length < min_length_px:
        return None
    q = int(rng.integers(n_points[0], n_points[1] + 1))
    q = max(2, min(q, int(length / 3.0) + 1))  # no denser than ~3 px between stroke points
    gaps = rng.gamma(2.0, size=q - 1)
    s = np.r_[0.0, np.cumsum(gaps)] / gaps.sum() * length
    stroke = np.column_stack([np.interp(s, arc, uv[:, 0]), np.interp(s, arc, uv[:, 1])])
    if noise_px > 0:
        t = s / length
        freq = rng.uniform(0.5, 3.0, size=(3, 1, 2))
        phase = rng.uniform(0.0, 2 * np.pi, size=(3, 1, 2))
        amp = rng.normal(size=(3, 1, 2))
        wobble = (amp * np.sin(2 * np.pi * freq * t[None, :, None] + phase)).sum(0)
        wobble -= wobble.mean(0)
        wobble *= noise_px / np.maximum(np.sqrt((wobble**2).mean(0)), 1e-9)
        stroke += wobble
    stroke = np.clip(stroke, 0.0, [camera.width - 1, camera.height - 1])
    if rng.random() < 0.5:
        stroke = stroke[::-1].copy()
    return stroke


def _longest_run(mask: np.ndarray) -> tuple[int, int]:
    """``(start, stop)`` of the longest run of True in a 1D bool array ((0, 0) if none)."""
    padded = np.r_[False, mask, False].astype(np.int8)
    edges = np.flatnonzero(np.diff(padded))
    if not len(edges):
        return 0, 0
    starts, stops = edges[0::2], edges[1::2]
    j = int(np.argmax(stops - starts))
    return int(starts[j]), int(stops[j])


def _points3(points: np.ndarray, what: str) -> np.ndarray:
    points = np.asarray(points, float)
    if points.ndim != 2 or points.shape[1] != 3:
        raise ValueError(f"{what} must be an (n, 3) array of mm positions, got shape {points.shape}")
    return points


@dataclass
class GroundTruth:
    """The ``ground_truth.json`` of a synthetic project (tests and benchmarks only).

    Attributes
    ----------
    cameras : dict expression → dict photo id → Camera, the true cameras.
    clean_points : dict expression → dict photo id → dict feature → (2,) px, noise-free
        projections of every feature (visible or not).
    features_3d : dict feature → (3,) mm, true positions on the neutral scan (head frame).
    noise_px : float, σ of the click noise.
    expression_features_3d : dict expression → dict feature → (3,) mm, true positions in each
        expression (the neutral's are :attr:`features_3d`), same head frame.
    visible : dict expression → dict photo id → set of the features clicked there.
    """

    cameras: dict
    clean_points: dict
    features_3d: dict
    noise_px: float
    expression_features_3d: dict = field(default_factory=dict)
    visible: dict = field(default_factory=dict)

    @property
    def expressions(self) -> list[str]:
        """The expressions of the project, in file order."""
        return list(self.cameras)

    def true_points(self, names: Sequence[str], expression: str | None = None) -> np.ndarray:
        """(n, 3) mm true positions of the named features (in ``expression``; default neutral)."""
        feats = self.features_3d if expression is None else self._expression_features(expression)
        return np.array([feats[n] for n in names], dtype=float)

    def _expression_features(self, expression: str) -> dict:
        if expression in self.expression_features_3d:
            return self.expression_features_3d[expression]
        if expression in self.cameras and len(self.cameras) == 1:  # a file from before expressions
            return self.features_3d
        raise KeyError(f"no ground truth for expression {expression!r}; have {self.expressions}")

    def clean_observations(self, expression: str, photo_ids: Sequence[str], names: Sequence[str]):
        """(k, n, 2) noise-free projections of the features, NaN where the file has none."""
        out = np.full((len(photo_ids), len(names), 2), np.nan)
        for k, pid in enumerate(photo_ids):
            pts = self.clean_points[expression][pid]
            for i, n in enumerate(names):
                if n in pts:
                    out[k, i] = pts[n]
        return out


def load_ground_truth(path) -> GroundTruth:
    """Read a ``ground_truth.json`` written by ``sample_projects/make_james.py``."""
    d = json.loads(Path(path).read_text())
    cameras, clean, per_expr, visible = {}, {}, {}, {}
    for expr, e in d["expressions"].items():
        cameras[expr] = {pid: Camera.from_dict(p["camera"]) for pid, p in e["photos"].items()}
        clean[expr] = {
            pid: {n: np.asarray(uv, float) for n, uv in p["points"].items()} for pid, p in e["photos"].items()
        }
        visible[expr] = {pid: set(p.get("visible", ())) for pid, p in e["photos"].items()}
        if "features_3d" in e:
            per_expr[expr] = {n: np.asarray(x, float) for n, x in e["features_3d"].items()}
    feats = {n: np.asarray(x, float) for n, x in d["features_3d"].items()}
    return GroundTruth(cameras, clean, feats, float(d["noise_px"]), per_expr, visible)
