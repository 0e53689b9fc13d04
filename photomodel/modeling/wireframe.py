"""Line drawings of a fitted face mesh over a photograph: the studio's wireframe overlay.

An artist judges a fit by looking at the deformed mesh drawn over each photo with the
recovered camera (Pighin et al. 2002, Fig. 4 shows exactly this). Drawing every edge of the
~16k-triangle generic mesh would cover a 1000-pixel photo with a grey mush (its edges are
3–6 px long there), so the overlay draws lines that *live on the surface* instead:

* a **grid**: iso-lines of the generic mesh's height ``y`` (every ``spacing_mm``) and of the
  azimuth about a vertical axis through the head (every ``angle_step_deg``) — a cylindrical
  grid like the paper's cylindrical texture parameterisation (§5.2.2). Each segment lies in
  one triangle, its endpoints on two of its edges, so it follows the fitted mesh exactly;
* the mesh's **outline** (its boundary edges);
* the mesh's named **curves** (brows, eyelids, lips, chin), the lines the artist draws too.

Lines are defined once on the generic mesh (:func:`mesh_lines`) as points on edges
``(1 − t) V[a] + t V[b]`` and re-evaluated on any deformation of it (:func:`line_points`).
Hidden lines are removed with the depth map of :mod:`photomodel.rendering.renderer` (the z-buffer test of
§5.2.1): a segment is drawn when its midpoint is no deeper than the visible surface plus a
tolerance (:func:`project_lines`).
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np

from photomodel.camera import Camera
from photomodel.rendering.depth import depth_visible
from photomodel.rendering.renderer import get_renderer

#: Segment kinds of :class:`MeshLines`.
GRID, OUTLINE, CURVE = 0, 1, 2

#: A segment is hidden when its midpoint lies this far (mm) behind the visible surface.
#: Surface points are on the surface, up to the depth map's sampling: at half resolution a
#: pixel spans ~0.6 mm of face, ~3 mm of depth on a surface seen at 80° — hence the 3×3
#: maximum filter below plus this tolerance, far less than the nose's ~20 mm occlusions.
DEPTH_TOLERANCE_MM = 2.0


#: Vertical grid lines stop where the surface comes closer to the grid's axis than this fraction of
#: the median distance (the underside of the chin), instead of meeting in a fan.
AXIS_CLEARANCE = 0.6


@dataclass(frozen=True)
class MeshLines:
    """Line segments on a mesh surface, each endpoint a point on a mesh edge.

    Attributes
    ----------
    edge_vertices : (M, 2, 2) int
        ``edge_vertices[i, j] = (a, b)``: endpoint ``j`` of segment ``i`` lies on the edge ``a–b``.
    edge_t : (M, 2) float
        Its position along the edge: ``(1 − t) V[a] + t V[b]``.
    kind : (M,) uint8
        :data:`GRID`, :data:`OUTLINE` or :data:`CURVE`.
    """

    edge_vertices: np.ndarray
    edge_t: np.ndarray
    kind: np.ndarray

    def __len__(self) -> int:
        return int(self.kind.shape[0])


def _iso_segments(values: np.ndarray, faces: np.ndarray, levels: np.ndarray):
    """Segments of the iso-lines ``values == level`` through the triangles (piecewise linear)."""
    ev, et = [], []
    edges = ((0, 1), (1, 2), (2, 0))
    f = faces
    for level in levels:
        s = values[f] - level  # (m, 3)
        cross = np.stack([(s[:, i] < 0) != (s[:, j] < 0) for i, j in edges], axis=1)  # (m, 3)
        hit = np.flatnonzero(cross.sum(axis=1) == 2)  # a plane cuts a triangle in 0 or 2 edges
        if hit.size == 0:
            continue
        c = cross[hit]
        # the two crossed edges of each hit triangle, in edge order
        first = np.argmax(c, axis=1)
        second = 2 - np.argmax(c[:, ::-1], axis=1)
        seg_v = np.empty((hit.size, 2, 2), dtype=np.int64)
        seg_t = np.empty((hit.size, 2))
        for k, e in enumerate((first, second)):
            i = np.array([edges[x][0] for x in range(3)])[e]
            j = np.array([edges[x][1] for x in range(3)])[e]
            a, b = f[hit, i], f[hit, j]
            sa, sb = s[hit, i], s[hit, j]
            seg_v[:, k, 0], seg_v[:, k, 1] = a, b
            seg_t[:, k] = sa / (sa - sb)
        ev.append(seg_v)
        et.append(seg_t)
    if not ev:
        return np.zeros((0, 2, 2), np.int64), np.zeros((0, 2))
    return np.concatenate(ev), np.concatenate(et)


def mesh_lines(
    vertices: np.ndarray,
    faces: np.ndarray,
    *,
    spacing_mm: float = 10.0,
    angle_step_deg: float = 9.0,
    curves: dict | None = None,
) -> MeshLines:
    """The overlay's lines on a mesh (normally the *generic* mesh, before any deformation).

    Parameters
    ----------
    vertices : (N, 3) float mm, head frame (``+y`` up, ``+z`` out of the face).
    faces : (m, 3) int
    spacing_mm : float > 0
        Distance between the horizontal grid lines (levels of ``y``).
    angle_step_deg : float > 0
        Angle between the vertical grid lines (levels of the azimuth ``atan2(x − x̄, z − z̄)``
        about the vertical axis through the vertices' centroid).
    curves : dict name → (k,) int, optional
        Vertex paths drawn as :data:`CURVE` segments (e.g. ``GenericMesh.curves``).

    Returns
    -------
    MeshLines
    """
    V = np.asarray(vertices, dtype=float)
    F = np.asarray(faces, dtype=np.int64)
    if V.ndim != 2 or V.shape[1] != 3 or F.ndim != 2 or F.shape[1] != 3:
        raise ValueError(f"need (N, 3) vertices and (m, 3) faces, got {V.shape} and {F.shape}")
    if not (spacing_mm > 0 and angle_step_deg > 0):
        raise ValueError(f"spacing_mm and angle_step_deg must be positive, got {spacing_mm}, {angle_step_deg}")
    parts_v, parts_t, parts_k = [], [], []

    # horizontal lines: levels of y, offset by half a step so no level hits a vertex grid exactly
    y = V[:, 1]
    levels = np.arange(np.floor(y.min() / spacing_mm), np.ceil(y.max() / spacing_mm) + 1) * spacing_mm
    sv, st = _iso_segments(y, F, levels + 1e-6)
    parts_v.append(sv), parts_t.append(st), parts_k.append(np.full(len(st), GRID, np.uint8))

    # vertical lines: levels of the azimuth; triangles across the ±180° seam (at the back of the
    # head, where a face mask is open) are skipped, and so are those near the axis (under the
    # chin), where all the lines would meet in a fan
    centre = V.mean(axis=0)
    dx, dz = V[:, 0] - centre[0], V[:, 2] - centre[2]
    az = np.degrees(np.arctan2(dx, dz))
    radius = np.hypot(dx, dz)
    seam = np.ptp(az[F], axis=1) > 180.0
    near_axis = radius[F].min(axis=1) < AXIS_CLEARANCE * np.median(radius)
    Fa = F[~(seam | near_axis)]
    levels = np.arange(-180.0 + angle_step_deg / 2, 180.0, angle_step_deg)
    sv, st = _iso_segments(az, Fa, levels + 1e-9)
    parts_v.append(sv), parts_t.append(st), parts_k.append(np.full(len(st), GRID, np.uint8))

    # outline: edges used by one triangle only
    e = np.sort(np.concatenate([F[:, [0, 1]], F[:, [1, 2]], F[:, [2, 0]]]), axis=1)
    uniq, count = np.unique(e, axis=0, return_counts=True)
    border = uniq[count == 1]
    parts_v.append(np.stack([np.stack([border[:, 0], border[:, 0]], 1), np.stack([border[:, 1], border[:, 1]], 1)], 1))
    parts_t.append(np.zeros((len(border), 2)))
    parts_k.append(np.full(len(border), OUTLINE, np.uint8))

    for path in (curves or {}).values():
        p = np.asarray(path, dtype=np.int64)
        if p.size < 2:
            continue
        a, b = p[:-1], p[1:]
        parts_v.append(np.stack([np.stack([a, a], 1), np.stack([b, b], 1)], 1))
        parts_t.append(np.zeros((len(a), 2)))
        parts_k.append(np.full(len(a), CURVE, np.uint8))

    return MeshLines(np.concatenate(parts_v), np.concatenate(parts_t), np.concatenate(parts_k))


def line_points(lines: MeshLines, vertices: np.ndarray) -> np.ndarray:
    """(M, 2, 3) float mm: the segments' endpoints on a mesh with the same topology."""
    V = np.asarray(vertices, dtype=float)
    a = V[lines.edge_vertices[..., 0]]
    b = V[lines.edge_vertices[..., 1]]
    t = lines.edge_t[..., None]
    return (1.0 - t) * a + t * b


def visible_points(
    camera: Camera, points: np.ndarray, depth: np.ndarray, tolerance_mm: float = DEPTH_TOLERANCE_MM
) -> np.ndarray:
    """(m,) bool: which points are not hidden behind the surface of a depth map.

    Parameters
    ----------
    camera : Camera
        The camera the depth map was rendered with (any size: it is sampled at the points'
        projection scaled to its resolution).
    points : (m, 3) float mm
    depth : (h, w) float mm, camera ``Z`` of the visible surface, ``inf`` where empty
        (``RenderResult.depth``).
    tolerance_mm : float
        See :data:`DEPTH_TOLERANCE_MM`.
    """
    P = np.asarray(points, dtype=float).reshape(-1, 3)
    h, w = np.shape(depth)
    if (w, h) != (camera.width, camera.height):  # the camera of the map, as project_lines renders it
        camera = Camera(camera.R, camera.t, camera.f * w / camera.width, w, h)
    return depth_visible(camera, P, depth, tol_mm=tolerance_mm, lookup="max3x3")


def project_lines(
    camera: Camera,
    vertices: np.ndarray,
    faces: np.ndarray,
    lines: MeshLines,
    *,
    renderer=None,
    depth_scale: float = 0.5,
) -> tuple[np.ndarray, np.ndarray]:
    """The overlay of a (fitted) mesh in one photo: projected segments and their visibility.

    Parameters
    ----------
    camera : Camera
        The photo's (recovered) camera.
    vertices : (N, 3) float mm
        The mesh the lines are drawn on (same topology as the one :func:`mesh_lines` saw).
    faces : (m, 3) int
    lines : MeshLines
    renderer : photomodel.rendering.renderer.Renderer, optional
        Default :func:`photomodel.rendering.renderer.get_renderer` (this thread's).
    depth_scale : float in (0, 1]
        Resolution of the visibility depth map relative to the photo (0.5: a quarter of the
        pixels, ~25 ms for a 1000×1000 photo on llvmpipe).

    Returns
    -------
    uv : (M, 2, 2) float px
        Segment endpoints in the photo (pixel centres at integers).
    visible : (M,) bool
    """
    if not 0 < depth_scale <= 1:
        raise ValueError(f"depth_scale must be in (0, 1], got {depth_scale}")
    if renderer is None:
        renderer = get_renderer()
    P = line_points(lines, vertices)
    uv = camera.project(P.reshape(-1, 3)).reshape(-1, 2, 2)
    w = max(1, int(round(camera.width * depth_scale)))
    h = max(1, int(round(camera.height * depth_scale)))
    small = Camera(camera.R, camera.t, camera.f * w / camera.width, w, h)
    depth = renderer.render_depth(small, vertices, faces)
    visible = visible_points(camera, P.mean(axis=1), depth)
    return uv, visible


@dataclass(frozen=True)
class PhotoOverlay:
    """The overlay of one photo, ready to draw: its visible segments only.

    Attributes
    ----------
    segments : (k, 2, 2) float px
        Endpoints of the visible segments in the photo (pixel centres at integers).
    kind : (k,) uint8
        :data:`GRID`, :data:`OUTLINE` or :data:`CURVE` of each segment.
    note : str or None
        Why hidden lines were not removed (no OpenGL context), else None.
    elapsed_s : float
        Wall time of :func:`photo_overlay` (on whichever thread ran it).
    """

    segments: np.ndarray
    kind: np.ndarray
    note: str | None = None
    elapsed_s: float = 0.0


def photo_overlay(
    camera: Camera,
    vertices: np.ndarray,
    faces: np.ndarray,
    lines: MeshLines,
    *,
    renderer=None,
    depth_scale: float = 0.5,
) -> PhotoOverlay:
    """:func:`project_lines` reduced to what is drawn; without OpenGL, every line is drawn.

    Safe to call from a worker thread: the depth map comes from ``renderer`` (default this
    thread's :func:`photomodel.rendering.renderer.get_renderer`), and nothing else is shared. Parameters
    as :func:`project_lines`.
    """

    if not 0 < depth_scale <= 1:
        raise ValueError(f"depth_scale must be in (0, 1], got {depth_scale}")
    t0 = time.perf_counter()
    note = None
    try:
        uv, visible = project_lines(camera, vertices, faces, lines, renderer=renderer, depth_scale=depth_scale)
    except (RuntimeError, ValueError) as exc:  # no OpenGL (or a camera it cannot render): draw every line
        note = f"overlay without hidden-line removal: {exc}"
        uv = camera.project(line_points(lines, vertices).reshape(-1, 3)).reshape(-1, 2, 2)
        visible = np.ones(len(uv), dtype=bool)
    return PhotoOverlay(uv[visible], lines.kind[visible], note, time.perf_counter() - t0)
