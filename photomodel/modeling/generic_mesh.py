"""The generic face mesh: the shape Pighin et al. (2002), §5.1, deform into each person.

Built once from menpo3d's ``template.ply`` (see :mod:`photomodel.data.menpo3d`), a
53k-vertex generic head surface (face, ears, neck; open at the back and at the mouth) with the
68 iBUG landmarks, and cached as ``generic_mesh-<key>.npz`` in the cache folder, the key a hash
of this module's code and what it imports (:func:`generic_mesh_key`), so any change of the recipe
below builds it again:

1. **Simplify** to ~8k vertices, an interactive size, with quadric-error decimation
   (``trimesh.Trimesh.simplify_quadric_decimation``, backed by the kept
   ``fast_simplification`` package; deterministic for a given input).
2. **Landmark vertices.** The 68 template landmarks go to 68 distinct mesh vertices
   (optimal assignment of landmarks to nearby vertices), which are moved exactly onto the
   landmark positions. They are the features an artist clicks (§5.1.1) and the centres
   of the scattered-data interpolation (§5.1.2).
3. **Exact vertex mapping.** Every other vertex is snapped onto a template vertex, no two
   onto the same one, so ``source_index`` maps the mesh back to ``template.ply`` exactly;
   vertices whose triangles the snap folds over or flattens into slivers are moved to a
   better nearby template vertex.
4. **Curves** (§5.1.3: eyebrows, eyelids, lips and chin are drawn as curves in the
   photos) are vertex paths along mesh edges: shortest paths (Dijkstra over edge lengths)
   between consecutive landmark vertices, from the subject's right to left.
5. **Regions** (the partition of the face used for expression blending, §6.1, Fig. 9) and
   the **face mask** used by accuracy metrics, from landmark geometry (see
   :class:`GenericMesh`).

Everything is in millimetres in the head frame of :mod:`photomodel.camera` (``+x``
subject's left, ``+y`` up, ``+z`` out of the face). Suffix ``_r`` means the subject's
right (``x < 0``), ``_l`` the subject's left.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sparse
import trimesh
from scipy.optimize import linear_sum_assignment
from scipy.sparse.csgraph import connected_components, dijkstra
from scipy.spatial import cKDTree

from photomodel.data.cache import cached_arrays
from photomodel.data.keys import code_key
from photomodel.data.menpo3d import Template, load_template
from photomodel.rendering.renderer import vertex_normals

#: Target triangle count of the decimation; gives ~8.1k vertices for the open face mask.
TARGET_FACES = 16000

REGION_NAMES = ("rest", "mouth", "eyes", "forehead")
REST, MOUTH, EYES, FOREHEAD = range(4)


def _ibug68_names() -> tuple[str, ...]:
    return tuple(
        [f"jaw_{i:02d}" for i in range(17)]  # 0-16, subject's right ear → left ear
        + [f"brow_r_{i}" for i in range(5)]  # 17-21, outer → inner
        + [f"brow_l_{i}" for i in range(5)]  # 22-26, inner → outer
        + [f"nose_bridge_{i}" for i in range(4)]  # 27-30, top → tip
        + [f"nose_base_{i}" for i in range(5)]  # 31-35, right → left
        + [f"eye_r_{i}" for i in range(6)]  # 36-41, outer corner, over the top
        + [f"eye_l_{i}" for i in range(6)]  # 42-47, inner corner, over the top
        + [f"lip_outer_{i:02d}" for i in range(12)]  # 48-59, right corner, over the top
        + [f"lip_inner_{i}" for i in range(8)]  # 60-67, right corner, over the top
    )


#: Readable name of each iBUG-68 landmark, in iBUG order.
IBUG68_NAMES = _ibug68_names()

#: Semantic aliases → iBUG-68 index.
FEATURE_ALIASES = {
    "eye_r_outer": 36,
    "eye_r_inner": 39,
    "eye_l_inner": 42,
    "eye_l_outer": 45,
    "brow_r_outer": 17,
    "brow_r_mid": 19,
    "brow_r_inner": 21,
    "brow_l_inner": 22,
    "brow_l_mid": 24,
    "brow_l_outer": 26,
    "nose_bridge": 27,
    "nose_tip": 30,
    "nostril_r": 31,
    "subnasale": 33,
    "nostril_l": 35,
    "mouth_r": 48,
    "mouth_l": 54,
    "lip_upper": 51,
    "lip_lower": 57,
    "chin": 8,
}


def ibug_index(name: str) -> int | None:
    """iBUG-68 index of a feature name (``jaw_03``, ``eye_r_outer`` …); None if it is not one."""
    if name in FEATURE_ALIASES:
        return FEATURE_ALIASES[name]
    try:
        return IBUG68_NAMES.index(name)
    except ValueError:
        return None


#: The default set of features clicked for pose recovery (§5.1.1): well spread, easy
#: to find in every view.
INITIAL_FEATURES = (
    "eye_r_outer",
    "eye_r_inner",
    "eye_l_inner",
    "eye_l_outer",
    "brow_r_mid",
    "brow_l_mid",
    "nose_tip",
    "nostril_r",
    "nostril_l",
    "mouth_r",
    "mouth_l",
    "lip_upper",
    "chin",
)

#: iBUG landmarks each curve passes through, in order (subject's right → left).
CURVE_LANDMARKS = {
    "brow_r": (17, 18, 19, 20, 21),
    "brow_l": (22, 23, 24, 25, 26),
    "eyelid_r_upper": (36, 37, 38, 39),
    "eyelid_r_lower": (36, 41, 40, 39),
    "eyelid_l_upper": (42, 43, 44, 45),
    "eyelid_l_lower": (42, 47, 46, 45),
    "lip_upper": (48, 49, 50, 51, 52, 53, 54),
    "lip_lower": (48, 59, 58, 57, 56, 55, 54),
    "chin": tuple(range(3, 14)),
}

# Region and mask geometry, mm (see GenericMesh).
MOUTH_MARGIN_MM = 15.0
EYES_MARGIN_BELOW_MM = 10.0
EYES_MARGIN_SIDE_MM = 12.0
BROW_BAND_MM = 5.0
FOREHEAD_MARGIN_SIDE_MM = 10.0
MASK_MARGIN_SIDE_MM = 25.0
MASK_ABOVE_BROWS_MM = 20.0
MASK_BORDER_MM = 10.0


@dataclass
class GenericMesh:
    """The generic face mesh (see the module docstring for how it is built).

    Attributes
    ----------
    vertices : (n, 3) float
        mm, head frame. n ≈ 8.1k.
    faces : (m, 3) int64
        triangles, counter-clockwise seen from outside (normals point out of the face).
    source_index : (n,) int64
        the ``template.ply`` vertex each vertex came from, all distinct. For every
        non-landmark vertex ``vertices[i] == template.vertices[source_index[i]]``
        exactly; a landmark vertex sits exactly on its template landmark and
        ``source_index`` names the template vertex nearest to it (≤ 1.2 mm away).
    landmarks : (68,) int64
        vertex index of each iBUG-68 landmark (distinct);
        ``vertices[landmarks] == template.landmarks``.
    features : dict[str, int]
        named feature vertices: the 68 landmarks as :data:`IBUG68_NAMES` plus the
        aliases of :data:`FEATURE_ALIASES`.
    initial_features : list[str]
        the 13 features clicked by default for pose recovery (:data:`INITIAL_FEATURES`).
    curves : dict[str, (k,) int64]
        vertex paths along mesh edges (consecutive vertices share an edge) through the
        landmarks of :data:`CURVE_LANDMARKS`, starting and ending on its first and last
        landmark vertex, ordered from the subject's right to left. ``lip_upper`` and
        ``lip_lower`` follow the outer lip contour corner to corner; ``chin`` follows
        the jaw contour from iBUG 3 to 13.
    regions : (n,) uint8
        index into :data:`REGION_NAMES`, the partition of Pighin et al. (2002) Fig. 9.
        With ``brow_y(x)`` the height of the brow line (iBUG 17–26 joined in order,
        held constant beyond its ends) and distances in 3D:

        * ``mouth``: within 15 mm of the closed outer lip contour (iBUG 48–59), which
          includes the lips themselves.
        * ``forehead``: above ``brow_y(x) − 5 mm`` (the brows move with the forehead,
          as in the paper's forehead tracking, Fig. 14), for ``x`` within 10 mm of
          the outer brow ends.
        * ``eyes``: below that line, no lower than 10 mm under the lowest eye landmark,
          for ``x`` within 12 mm of the outer eye corners (both eyes, lids and the
          bridge of the nose between them).
        * ``rest``: everything else (cheeks, nose, jaw, border), which the paper keeps
          constant across expressions.
    face_mask : (n,) bool
        the face used by accuracy metrics: ``x`` within 25 mm beyond the outer eye
        corners (iBUG 36, 45; excludes ears and the sides of the head), ``y`` from the
        jaw contour (iBUG 0–16 joined, so the neck is excluded) up to 20 mm above the
        highest brow landmark, and at least 10 mm from the mask's outer open boundary
        (the mouth slit is not a border for this purpose); of the vertices passing these
        tests, only the piece joined to the nose tip by mesh edges is kept (this drops a
        patch of neck behind the jaw).
    """

    vertices: np.ndarray
    faces: np.ndarray
    source_index: np.ndarray
    landmarks: np.ndarray
    features: dict[str, int]
    initial_features: list[str]
    curves: dict[str, np.ndarray]
    regions: np.ndarray
    face_mask: np.ndarray

    @property
    def vertex_normals(self) -> np.ndarray:
        """(n, 3) float unit normals (area-weighted face normals), pointing out of the face."""
        return vertex_normals(self.vertices, self.faces)


def generic_mesh_key() -> str:
    """The cache key of the generic mesh: :func:`build_generic_mesh_arrays`' code (this module and
    what it imports, the template's loader and checksums among them).

    No library versions: the mesh fixes every project's vertex order, so an upgrade of trimesh or
    numpy does not replace it by itself; ``tests/test_generic_mesh.py`` builds it afresh and
    compares, which is where such a drift shows."""
    return code_key(build_generic_mesh_arrays, inputs=(TARGET_FACES,))


def load_generic_mesh() -> GenericMesh:
    """The generic face mesh, built from the template on first use and cached
    (``<cache>/generic_mesh-<key>.npz``, :func:`generic_mesh_key`).

    Returns
    -------
    GenericMesh

    Raises
    ------
    SampleDataError
        when the template cannot be obtained (see :func:`photomodel.data.menpo3d.menpo3d_dir`).
    """
    arrays = cached_arrays("generic_mesh", generic_mesh_key(), lambda: build_generic_mesh_arrays(load_template()))
    landmarks = arrays["landmarks"]
    features = {name: int(landmarks[i]) for i, name in enumerate(IBUG68_NAMES)}
    features.update({name: int(landmarks[i]) for name, i in FEATURE_ALIASES.items()})
    return GenericMesh(
        vertices=arrays["vertices"],
        faces=arrays["faces"],
        source_index=arrays["source_index"],
        landmarks=landmarks,
        features=features,
        initial_features=list(INITIAL_FEATURES),
        curves={name: arrays[f"curve_{name}"] for name in CURVE_LANDMARKS},
        regions=arrays["regions"],
        face_mask=arrays["face_mask"],
    )


# ----------------------------------------------------------------------------- building


def build_generic_mesh_arrays(template: Template, target_faces: int = TARGET_FACES) -> dict[str, np.ndarray]:
    """Arrays of :class:`GenericMesh` built from ``template`` (the uncached path)."""

    full = trimesh.Trimesh(template.vertices, template.faces, process=False)
    simple = full.simplify_quadric_decimation(face_count=target_faces)
    decimated = np.asarray(simple.vertices, float)
    faces = np.asarray(simple.faces, np.int64)

    lm_vertex = _assign_landmark_vertices(decimated, template.landmarks)
    wanted = decimated.copy()  # where each vertex would like to be
    wanted[lm_vertex] = template.landmarks
    source = _unique_nearest(wanted, template.vertices, priority=lm_vertex)
    vertices = template.vertices[source]
    vertices[lm_vertex] = template.landmarks
    source = _unfold(vertices, faces, decimated, source, template.vertices, fixed=lm_vertex)
    vertices = template.vertices[source]
    vertices[lm_vertex] = template.landmarks

    # normals out of the face: the nose tip's normal must point along +z
    if vertex_normals(vertices, faces)[lm_vertex[30], 2] < 0:
        faces = faces[:, ::-1].copy()

    arrays = {
        "vertices": vertices,
        "faces": faces,
        "source_index": source,
        "landmarks": lm_vertex,
        "regions": _regions(vertices, template.landmarks),
        "face_mask": _face_mask(vertices, faces, template.landmarks),
    }
    graph = _edge_graph(vertices, faces)
    for name, ids in CURVE_LANDMARKS.items():
        arrays[f"curve_{name}"] = _curve(graph, vertices, lm_vertex[list(ids)])
    return arrays


def _assign_landmark_vertices(vertices: np.ndarray, landmarks: np.ndarray, k: int = 8) -> np.ndarray:
    """(68,) distinct vertex per landmark minimising the total distance moved."""
    dist, idx = cKDTree(vertices).query(landmarks, k=k)
    candidates, col = np.unique(idx, return_inverse=True)
    cost = np.full((len(landmarks), len(candidates)), 1e9)
    cost[np.repeat(np.arange(len(landmarks)), k), col.ravel()] = dist.ravel()
    rows, cols = linear_sum_assignment(cost)
    return candidates[cols[np.argsort(rows)]].astype(np.int64)


def _unique_nearest(points: np.ndarray, targets: np.ndarray, priority: np.ndarray, k: int = 16) -> np.ndarray:
    """(n,) distinct index into ``targets`` near each point: each round, every unassigned
    point bids for its nearest free target and the closest bidder wins; ``priority``
    points are assigned first."""
    tree = cKDTree(targets)
    result = np.full(len(points), -1, np.int64)
    taken = np.zeros(len(targets), bool)
    for group in (np.asarray(priority), np.setdiff1d(np.arange(len(points)), priority)):
        pending = group
        kk = k
        while len(pending):
            dist, idx = tree.query(points[pending], k=kk)
            free = ~taken[idx]
            has = free.any(axis=1)
            if not has.all():
                kk *= 2  # rare: all k nearest are taken; look further next round
            first = np.argmax(free, axis=1)
            bid = idx[np.arange(len(pending)), first]
            bid_d = dist[np.arange(len(pending)), first]
            order = np.lexsort((bid_d, bid))
            sel = order[has[order]]
            winners = sel[np.r_[True, bid[sel][1:] != bid[sel][:-1]]] if len(sel) else sel
            result[pending[winners]] = bid[winners]
            taken[bid[winners]] = True
            pending = np.setdiff1d(pending, pending[winners])
    return result


def _triangle_normals(tri: np.ndarray) -> np.ndarray:
    """(..., 3) unit normals of triangles (..., 3, 3); zero for degenerate ones."""
    n = np.cross(tri[..., 1, :] - tri[..., 0, :], tri[..., 2, :] - tri[..., 0, :])
    return n / np.maximum(np.linalg.norm(n, axis=-1, keepdims=True), 1e-12)


def _triangle_quality(tri: np.ndarray) -> np.ndarray:
    """(...,) shape quality of triangles (..., 3, 3): 1 equilateral, 0 degenerate."""
    cross = np.cross(tri[..., 1, :] - tri[..., 0, :], tri[..., 2, :] - tri[..., 0, :])
    area2 = np.linalg.norm(cross, axis=-1)  # twice the area
    edges2 = (np.linalg.norm(np.roll(tri, -1, axis=-2) - tri, axis=-1) ** 2).sum(-1)
    return 2.0 * np.sqrt(3.0) * area2 / np.maximum(edges2, 1e-300)


def _triangle_score(tri: np.ndarray, reference_normals: np.ndarray) -> np.ndarray:
    """(...,) how well snapped triangles keep the decimated ones' orientation and shape:
    the cosine between their normals, capped by 4 × shape quality so slivers count as bad."""
    agree = np.einsum("...j,...j->...", _triangle_normals(tri), reference_normals)
    return np.minimum(agree, 4.0 * _triangle_quality(tri))


def _unfold(
    vertices: np.ndarray,
    faces: np.ndarray,
    decimated: np.ndarray,
    source: np.ndarray,
    template_vertices: np.ndarray,
    fixed: np.ndarray,
    rounds: int = 4,
    k: int = 24,
    threshold: float = 0.4,
) -> np.ndarray:
    """Improve snapped vertices whose triangles turned over or became slivers.

    Snapping to the nearest template vertex moves a vertex by up to ~1.5 mm, which can
    fold or flatten a thin decimated triangle. Each vertex of such a triangle (score
    below ``threshold``, see :func:`_triangle_score`) that is not ``fixed`` moves to the
    free template vertex among its ``k`` nearest that maximises the worst score of its
    triangles. Only tens of vertices need it, so a loop over them is cheap.
    """
    reference = _triangle_normals(decimated[faces])
    source = source.copy()
    vertices = vertices.copy()
    taken = np.zeros(len(template_vertices), bool)
    taken[source] = True
    is_fixed = np.zeros(len(vertices), bool)
    is_fixed[fixed] = True
    incident = sparse.csr_matrix(
        (np.ones(faces.size), (faces.ravel(), np.repeat(np.arange(len(faces)), 3))),
        shape=(len(vertices), len(faces)),
    )
    tree = cKDTree(template_vertices)
    for _ in range(rounds):
        score = _triangle_score(vertices[faces], reference)
        bad = np.unique(faces[score < threshold])
        bad = bad[~is_fixed[bad]]
        if not len(bad):
            break
        for v in bad:
            tri_ids = incident[v].indices
            tris = faces[tri_ids]
            _, cand = tree.query(decimated[v], k=k)
            cand = np.r_[source[v], cand[~taken[cand]]]
            trial = np.repeat(vertices[tris][None], len(cand), axis=0)  # (c, t, 3, 3)
            trial[:, tris == v] = template_vertices[cand][:, None]
            worst = _triangle_score(trial, reference[tri_ids]).min(axis=1)
            best = cand[int(np.argmax(worst))]
            if best != source[v]:
                taken[source[v]] = False
                taken[best] = True
                source[v] = best
                vertices[v] = template_vertices[best]
    return source


def _edge_graph(vertices: np.ndarray, faces: np.ndarray) -> sparse.csr_matrix:
    """Symmetric sparse matrix of mesh edge lengths (mm)."""
    edges = np.unique(np.sort(faces[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2), axis=1), axis=0)
    length = np.linalg.norm(vertices[edges[:, 0]] - vertices[edges[:, 1]], axis=1)
    n = len(vertices)
    g = sparse.coo_matrix((length, (edges[:, 0], edges[:, 1])), shape=(n, n))
    return (g + g.T).tocsr()


def _curve(graph: sparse.csr_matrix, vertices: np.ndarray, waypoints: np.ndarray) -> np.ndarray:
    """Vertex path along edges through ``waypoints`` (shortest path between consecutive ones)."""
    path = [int(waypoints[0])]
    for a, b in zip(waypoints[:-1], waypoints[1:], strict=True):
        limit = 3.0 * np.linalg.norm(vertices[a] - vertices[b]) + 10.0  # bounds the search
        _, pred = dijkstra(graph, indices=int(a), return_predecessors=True, limit=limit)
        seg = [int(b)]
        while seg[-1] != a:
            if pred[seg[-1]] < 0:
                raise RuntimeError(f"no mesh path between vertices {a} and {b}")
            seg.append(int(pred[seg[-1]]))
        path.extend(seg[::-1][1:])
    return np.asarray(path, np.int64)


def _polyline_distance(points: np.ndarray, polyline: np.ndarray, closed: bool) -> np.ndarray:
    """(n,) Euclidean distance from each point to a 3D polyline (k, 3)."""
    a = polyline if closed else polyline[:-1]
    b = np.roll(polyline, -1, axis=0) if closed else polyline[1:]
    ab = b - a
    t = np.einsum("nsj,sj->ns", points[:, None] - a[None], ab) / np.einsum("sj,sj->s", ab, ab)
    closest = a[None] + np.clip(t, 0.0, 1.0)[..., None] * ab[None]
    return np.linalg.norm(points[:, None] - closest, axis=2).min(axis=1)


def _brow_y(x: np.ndarray, landmarks: np.ndarray) -> np.ndarray:
    brow = landmarks[17:27]  # right brow outer → inner, then left brow inner → outer: x increases
    return np.interp(x, brow[:, 0], brow[:, 1])


def _regions(vertices: np.ndarray, landmarks: np.ndarray) -> np.ndarray:
    x, y = vertices[:, 0], vertices[:, 1]
    regions = np.full(len(vertices), REST, np.uint8)
    line = _brow_y(x, landmarks) - BROW_BAND_MM
    brow = landmarks[17:27]
    forehead = (
        (y >= line)
        & (x >= brow[:, 0].min() - FOREHEAD_MARGIN_SIDE_MM)
        & (x <= brow[:, 0].max() + FOREHEAD_MARGIN_SIDE_MM)
    )
    eye = landmarks[36:48]
    eyes = (
        (y < line)
        & (y >= eye[:, 1].min() - EYES_MARGIN_BELOW_MM)
        & (x >= landmarks[36, 0] - EYES_MARGIN_SIDE_MM)
        & (x <= landmarks[45, 0] + EYES_MARGIN_SIDE_MM)
    )
    mouth = _polyline_distance(vertices, landmarks[48:60], closed=True) <= MOUTH_MARGIN_MM
    regions[forehead] = FOREHEAD
    regions[eyes] = EYES
    regions[mouth] = MOUTH
    return regions


def _outer_boundary_points(vertices: np.ndarray, faces: np.ndarray, step_mm: float = 0.5) -> np.ndarray:
    """Points every ~``step_mm`` along the longest boundary loop (the mask's outer edge)."""
    edges = np.sort(faces[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2), axis=1)
    uniq, count = np.unique(edges, axis=0, return_counts=True)
    border = uniq[count == 1]
    n = len(vertices)
    g = sparse.coo_matrix((np.ones(len(border)), (border[:, 0], border[:, 1])), shape=(n, n))
    _, label = connected_components(g, directed=False)
    loops, size = np.unique(label[border[:, 0]], return_counts=True)
    outer = border[label[border[:, 0]] == loops[np.argmax(size)]]
    t = np.linspace(0.0, 1.0, 1 + int(np.ceil(6.0 / step_mm)))  # decimated edges are < 6 mm
    a, b = vertices[outer[:, 0]], vertices[outer[:, 1]]
    return (a[:, None] + t[None, :, None] * (b - a)[:, None]).reshape(-1, 3)


def _face_mask(vertices: np.ndarray, faces: np.ndarray, landmarks: np.ndarray) -> np.ndarray:
    x, y = vertices[:, 0], vertices[:, 1]
    jaw = landmarks[0:17]  # subject's right ear → left ear: x increases
    border_dist, _ = cKDTree(_outer_boundary_points(vertices, faces)).query(vertices)
    inside = (
        (x >= landmarks[36, 0] - MASK_MARGIN_SIDE_MM)
        & (x <= landmarks[45, 0] + MASK_MARGIN_SIDE_MM)
        & (y >= np.interp(x, jaw[:, 0], jaw[:, 1]))
        & (y <= landmarks[17:27, 1].max() + MASK_ABOVE_BROWS_MM)
        & (border_dist >= MASK_BORDER_MM)
    )
    # keep the piece connected to the face: the box above also catches a patch of the
    # neck behind the jaw, below the ear, which is not joined to the face
    edges = faces[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2)
    edges = edges[inside[edges[:, 0]] & inside[edges[:, 1]]]
    n = len(vertices)
    g = sparse.coo_matrix((np.ones(len(edges)), (edges[:, 0], edges[:, 1])), shape=(n, n))
    _, label = connected_components(g, directed=False)
    nose_tip = np.argmin(np.linalg.norm(vertices - landmarks[30], axis=1))
    return inside & (label == label[nose_tip])
