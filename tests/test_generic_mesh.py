"""Tests of photomodel.modeling.generic_mesh against the template it is built from."""

from __future__ import annotations

import numpy as np
import pytest

from photomodel.modeling.generic_mesh import (
    CURVE_LANDMARKS,
    FEATURE_ALIASES,
    IBUG68_NAMES,
    REGION_NAMES,
    build_generic_mesh_arrays,
)


def _edges(faces: np.ndarray) -> set[tuple[int, int]]:
    e = np.sort(faces[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2), axis=1)
    return set(map(tuple, e.tolist()))


def test_size_and_arrays(mesh):
    n = len(mesh.vertices)
    assert 5000 <= n <= 15000  # interactive size
    assert mesh.vertices.shape == (n, 3) and mesh.faces.shape[1] == 3
    assert mesh.faces.min() == 0 and mesh.faces.max() == n - 1  # every vertex used
    assert mesh.source_index.shape == (n,) and mesh.regions.shape == (n,) and mesh.face_mask.shape == (n,)


def test_landmark_vertices_sit_on_the_template_landmarks(mesh, template):
    assert mesh.landmarks.shape == (68,) and len(np.unique(mesh.landmarks)) == 68
    assert np.array_equal(mesh.vertices[mesh.landmarks], template.landmarks)


def test_source_index_maps_back_to_the_template_exactly(mesh, template):
    src = mesh.source_index
    assert len(np.unique(src)) == len(src)
    others = np.setdiff1d(np.arange(len(src)), mesh.landmarks)
    assert np.array_equal(mesh.vertices[others], template.vertices[src[others]])
    # landmarks are ≤ 1.13 mm from their nearest template vertex (measured on the template)
    gap = np.linalg.norm(template.vertices[src[mesh.landmarks]] - template.landmarks, axis=1)
    assert gap.max() < 1.2


def test_triangles_are_sound(mesh):
    tri = mesh.vertices[mesh.faces]
    cross = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    edges2 = (np.linalg.norm(np.roll(tri, -1, axis=1) - tri, axis=2) ** 2).sum(1)
    quality = 2 * np.sqrt(3) * np.linalg.norm(cross, axis=1) / edges2  # 1 = equilateral
    assert quality.min() > 0.05  # snapping onto template vertices left no slivers
    # consistent winding: every directed edge appears once
    directed = mesh.faces[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2)
    assert len(np.unique(directed, axis=0)) == len(directed)


def test_normals_point_out_of_the_face(mesh):
    n = mesh.vertex_normals
    np.testing.assert_allclose(np.linalg.norm(n, axis=1), 1.0, atol=1e-9)
    assert n[mesh.features["nose_tip"], 2] > 0.5
    assert n[mesh.face_mask, 2].mean() > 0.5


def test_features(mesh):
    assert len(IBUG68_NAMES) == len(set(IBUG68_NAMES)) == 68
    for i, name in enumerate(IBUG68_NAMES):
        assert mesh.features[name] == mesh.landmarks[i]
    for alias, i in FEATURE_ALIASES.items():
        assert mesh.features[alias] == mesh.landmarks[i]
    assert mesh.features["eye_r_outer"] == mesh.landmarks[36] and mesh.features["chin"] == mesh.landmarks[8]
    assert len(mesh.initial_features) == 13 and set(mesh.initial_features) <= set(mesh.features)
    # "_r" is the subject's right: x < 0 (head frame)
    for name, v in mesh.features.items():
        if "_r_" in name or name.endswith("_r"):
            assert mesh.vertices[v, 0] < 0, name
        if "_l_" in name or name.endswith("_l"):
            assert mesh.vertices[v, 0] > 0, name


@pytest.mark.parametrize("name", list(CURVE_LANDMARKS))
def test_curves_are_edge_paths_through_their_landmarks(mesh, name):
    path = mesh.curves[name]
    edges = _edges(mesh.faces)
    assert all((min(a, b), max(a, b)) in edges for a, b in zip(path[:-1], path[1:], strict=True))
    waypoints = mesh.landmarks[list(CURVE_LANDMARKS[name])]
    assert path[0] == waypoints[0] and path[-1] == waypoints[-1]
    positions = [int(np.nonzero(path == w)[0][0]) for w in waypoints]
    assert positions == sorted(positions)  # passes the landmarks in order
    assert mesh.vertices[path[0], 0] < mesh.vertices[path[-1], 0]  # subject's right → left
    # a shortest path hugs the landmark polyline; edges zigzag, adding 1–8 % (measured)
    length = np.linalg.norm(np.diff(mesh.vertices[path], axis=0), axis=1).sum()
    chord = np.linalg.norm(np.diff(mesh.vertices[waypoints], axis=0), axis=1).sum()
    assert chord <= length < 1.15 * chord


def test_regions_are_plausible(mesh):
    assert REGION_NAMES == ("rest", "mouth", "eyes", "forehead")
    assert mesh.regions.dtype == np.uint8 and mesh.regions.max() < len(REGION_NAMES)
    assert np.all(np.bincount(mesh.regions, minlength=4) > 300)
    region_of = mesh.regions[mesh.landmarks]
    assert np.all(region_of[48:68] == REGION_NAMES.index("mouth"))
    assert np.all(region_of[36:48] == REGION_NAMES.index("eyes"))
    assert np.all(region_of[17:27] == REGION_NAMES.index("forehead"))  # brows move with the forehead
    assert np.all(region_of[[0, 8, 16, 30]] == REGION_NAMES.index("rest"))  # jaw, chin, nose tip
    # forehead above the eyes, mouth below them
    y = mesh.vertices[:, 1]
    assert y[mesh.regions == 3].min() > y[mesh.landmarks[36:48]].max()
    assert y[mesh.regions == 1].max() < y[mesh.landmarks[36:48]].min()


def test_face_mask(mesh):
    lm = mesh.landmarks
    assert mesh.face_mask[lm[17:68]].all()  # brows, eyes, nose, mouth
    assert not mesh.face_mask[lm[[0, 16]]].any()  # jaw ends at the ears
    # at least 10 mm from the outer border: no border vertex in the mask
    e = np.sort(mesh.faces[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2), axis=1)
    uniq, count = np.unique(e, axis=0, return_counts=True)
    border = np.unique(uniq[count == 1])
    slit = np.linalg.norm(mesh.vertices[border] - mesh.vertices[lm[62]], axis=1) < 30  # mouth opening
    outer = border[~slit]
    assert slit.sum() > 10 and len(outer) > 100
    d = np.linalg.norm(mesh.vertices[mesh.face_mask][:, None] - mesh.vertices[outer][None], axis=2)
    assert d.min() >= 10.0
    assert 2000 < mesh.face_mask.sum() < len(mesh.vertices) * 0.8


def test_cache_matches_a_fresh_build(mesh, template):
    # deterministic, and the cached file was built by the current recipe
    fresh = build_generic_mesh_arrays(template)
    assert np.array_equal(fresh["vertices"], mesh.vertices)
    assert np.array_equal(fresh["faces"], mesh.faces)
    assert np.array_equal(fresh["regions"], mesh.regions)
    assert np.array_equal(fresh["face_mask"], mesh.face_mask)
    for name in CURVE_LANDMARKS:
        assert np.array_equal(fresh[f"curve_{name}"], mesh.curves[name])
