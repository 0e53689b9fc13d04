"""Tests of photomodel.rendering.renderer against analytic projection (photomodel.camera is the ground truth).

Every expectation is computed without GL: pixel coverage from the projected triangle's edge
functions, depth and texture coordinates from ray–plane intersections, visibility from an
analytic z-buffer. Tolerances are those of the hardware path: llvmpipe snaps vertices to
1/256 px, attributes are float32.
"""

from __future__ import annotations

import threading

import numpy as np
import pytest

from photomodel.camera import Camera, orbit_camera
from photomodel.rendering.renderer import (
    GLTexture,
    RenderResult,
    get_renderer,
    gl_projection,
    vertex_normals,
)
from photomodel.samples.sample_data import load_james_scan

# GL snaps window coordinates to 1/256 px, which moves an edge by at most ~0.006 px; pixel
# centres closer than this to an analytic edge may fall either way and are not judged.
EDGE_MARGIN_PX = 0.02

# Off-axis, non-square and odd-sized images: with an odd width the principal point sits on a
# pixel centre, with an even one between two — the half-pixel bookkeeping must hold for both.
CAMERAS = {
    "front 640x480": orbit_camera(0.0, 640, 480, distance_mm=500.0),
    "oblique 480x640": orbit_camera(35.0, 480, 640, distance_mm=450.0, elevation_deg=20.0, target=(10.0, -5.0, 20.0)),
    "side 321x203": orbit_camera(-70.0, 321, 203, distance_mm=700.0, focal_mm=85.0, elevation_deg=-10.0),
}


@pytest.fixture(scope="module")
def renderer():
    return get_renderer()


def pixel_grid(camera: Camera) -> np.ndarray:
    """(H, W, 2) pixel-centre coordinates (u, v) in our convention (centres at integers)."""
    v, u = np.mgrid[0 : camera.height, 0 : camera.width]
    return np.stack([u, v], axis=-1).astype(float)


def edge_functions(p: np.ndarray, tri2d: np.ndarray) -> np.ndarray:
    """(H, W, 3) signed distances (px) of points ``p`` (H, W, 2) to the 3 edges of ``tri2d``
    (3, 2), positive inside whatever the winding."""
    d = []
    for i in range(3):
        a, b = tri2d[i], tri2d[(i + 1) % 3]
        e = b - a
        cross = e[0] * (p[..., 1] - a[1]) - e[1] * (p[..., 0] - a[0])
        d.append(cross / np.linalg.norm(e))
    d = np.stack(d, axis=-1)
    (ax, ay), (bx, by) = tri2d[1] - tri2d[0], tri2d[2] - tri2d[0]
    area2 = ax * by - ay * bx
    return d * np.sign(area2)


def ray_plane_points(camera: Camera, uv: np.ndarray, point, normal) -> np.ndarray:
    """World points (…, 3) where the viewing rays of pixels ``uv`` (…, 2) meet a plane."""
    shape = uv.shape[:-1]
    origin, d = camera.rays(uv.reshape(-1, 2))
    s = ((np.asarray(point) - origin) @ normal) / (d @ normal)
    return (origin + s[:, None] * d).reshape(*shape, 3)


#: A triangle about 200 mm across around the cameras' targets, tilted to every view.
BIG_TRIANGLE = np.array([[-90.0, -70.0, 10.0], [110.0, -40.0, -30.0], [-20.0, 100.0, 25.0]])


def bumpy_mesh(n: int = 21, half: float = 80.0):
    """A height field ``2 half`` mm wide: ``n × n`` vertices, many small triangles, self-occlusion from the side."""
    g = np.linspace(-half, half, n)
    X, Y = np.meshgrid(g, g)
    Z = 25.0 * np.sin(X / 23.0) * np.cos(Y / 31.0)
    V = np.column_stack([X.ravel(), Y.ravel(), Z.ravel()])
    i = np.arange(n - 1)
    a = (i[:, None] * n + i[None, :]).ravel()
    F = np.concatenate([np.column_stack([a, a + 1, a + n + 1]), np.column_stack([a, a + n + 1, a + n])])
    return V, F


# ----------------------------------------------------------------------------- geometry


@pytest.mark.parametrize("name", CAMERAS)
def test_coverage_is_the_analytic_projection(renderer, name):
    """A pixel is covered iff its centre is inside ``camera.project`` of the triangle."""
    cam = CAMERAS[name]
    tri = BIG_TRIANGLE
    res = renderer.render(cam, tri, np.array([[0, 1, 2]]))
    ef = edge_functions(pixel_grid(cam), cam.project(tri))
    inside = (ef > EDGE_MARGIN_PX).all(axis=-1)
    outside = (ef < -EDGE_MARGIN_PX).any(axis=-1)
    assert inside.sum() > 2500
    assert res.mask[inside].all()
    assert not res.mask[outside].any()
    # a half-pixel slip would move the centroid by 0.5 px; the sets above already pin it, this
    # is the summary number (exact agreement up to the handful of undecided edge pixels)
    v, u = np.nonzero(res.mask)
    v0, u0 = np.nonzero((ef >= 0).all(axis=-1))
    assert abs(u.mean() - u0.mean()) < 0.05 and abs(v.mean() - v0.mean()) < 0.05
    assert (res.face_id[res.mask] == 0).all() and (res.face_id[~res.mask] == -1).all()


@pytest.mark.parametrize("name", CAMERAS)
def test_interpolated_world_position_projects_to_its_pixel(renderer, name):
    """With ``colors = vertices`` every covered pixel shows the surface point on its own viewing
    ray: ``project(color) == pixel`` and ``depth == Z_cam(color)`` everywhere, not only at vertices.

    This checks the projection and perspective-correct interpolation at all pixels, and that
    colour targets are float and unclamped (positions are ±100 mm).
    """
    cam = CAMERAS[name]
    V, F = bumpy_mesh()  # 160 mm wide: many small triangles, self-occlusion from the side

    res = renderer.render(cam, V, F, colors=V)
    assert res.color.dtype == np.float32 and res.color.shape == (cam.height, cam.width, 3)
    P = res.color[res.mask].astype(float)
    assert len(P) > 3000 and np.abs(P).max() > 50.0  # float targets: nothing clamped to 0..1
    uv = pixel_grid(cam)[res.mask]
    # float32 positions (|X| ≤ 100 mm → 1e-5 mm) at ~1 px/mm: 1e-3 px is comfortably above noise
    np.testing.assert_allclose(cam.project(P), uv, atol=2e-3)
    # depth target: Z_cam in mm to float32 precision
    np.testing.assert_allclose(res.depth[res.mask], cam.depth(P), rtol=1e-5)
    assert np.isinf(res.depth[~res.mask]).all()


def test_depth_of_a_tilted_plane(renderer):
    """Depth equals the analytic ``Z_cam`` of the ray–plane intersection (brief: within 0.1 %)."""
    cam = CAMERAS["oblique 480x640"]
    n = np.array([0.3, -0.2, 1.0])
    n /= np.linalg.norm(n)
    e1 = np.cross(n, [0.0, 1.0, 0.0])
    e1 /= np.linalg.norm(e1)
    e2 = np.cross(n, e1)
    c = np.array([5.0, 0.0, 10.0])
    quad = c + 120.0 * np.array([-e1 - e2, e1 - e2, e1 + e2, -e1 + e2])
    res = renderer.render(cam, quad, np.array([[0, 1, 2], [0, 2, 3]]))
    Xw = ray_plane_points(cam, pixel_grid(cam)[res.mask], c, n)
    assert res.mask.sum() > 10000
    np.testing.assert_allclose(res.depth[res.mask], cam.depth(Xw), rtol=1e-5)  # float32 depth


def test_near_far_and_behind_camera(renderer):
    cam = CAMERAS["front 640x480"]
    tri = BIG_TRIANGLE
    res = renderer.render(cam, tri, np.array([[0, 1, 2]]))
    z = cam.depth(tri)
    assert res.near < z.min() and res.far > z.max()
    # far plane closer than the triangle: clipped away
    clipped = renderer.render(cam, tri, np.array([[0, 1, 2]]), near=10.0, far=100.0)
    assert not clipped.mask.any()
    # everything behind the camera: an empty image, no error
    behind = renderer.render(cam, tri + cam.center * 3.0, np.array([[0, 1, 2]]))
    assert not behind.mask.any() and np.isinf(behind.depth).all()
    empty = renderer.render(cam, tri, np.zeros((0, 3), int), background=0.5)
    assert (empty.color == 0.5).all() and (empty.face_id == -1).all()


def test_depth_only_render_is_the_renders_depth(renderer):
    """``render_depth`` reads back only the depth target of the same draw: equal to ``render().depth``
    bit for bit, ``inf`` off the mesh, and nothing drawn when the mesh is clipped or behind."""
    V, F = bumpy_mesh()
    for cam in CAMERAS.values():
        np.testing.assert_array_equal(renderer.render_depth(cam, V, F), renderer.render(cam, V, F).depth)
    cam = CAMERAS["front 640x480"]
    tri = BIG_TRIANGLE
    assert np.isinf(renderer.render_depth(cam, tri, np.array([[0, 1, 2]]), near=10.0, far=100.0)).all()
    assert np.isinf(renderer.render_depth(cam, tri + cam.center * 3.0, np.array([[0, 1, 2]]))).all()
    assert np.isinf(renderer.render_depth(cam, tri, np.zeros((0, 3), int))).all()


def test_rgb8_render_is_the_renders_colour_in_8_bits(renderer):
    """``render_rgb8`` (the studio's 3D view) gives ``render()``'s colour clipped and rounded to
    ``uint8``, background included, and its depth, bit for bit — shaded and textured."""
    V, F = bumpy_mesh()
    bg = (0.16, 0.16, 0.18)
    rng = np.random.default_rng(0)
    tex = rng.integers(0, 256, (32, 32, 3), dtype=np.uint8)
    uv = rng.random((len(V), 2))
    for cam in CAMERAS.values():
        for kw in ({"shading": "lambert"}, {"uv": uv, "texture": tex}):
            out = renderer.render(cam, V, F, background=bg, **kw)
            rgb, depth = renderer.render_rgb8(cam, V, F, background=bg, **kw)
            np.testing.assert_array_equal(rgb, (np.clip(out.color[..., :3], 0, 1) * 255 + 0.5).astype(np.uint8))
            np.testing.assert_array_equal(depth, out.depth)
    rgb, depth = renderer.render_rgb8(CAMERAS["front 640x480"], BIG_TRIANGLE, np.zeros((0, 3), int), background=0.5)
    assert (rgb == 128).all() and np.isinf(depth).all()


# ----------------------------------------------------------------------------- textures


def facing_quad(half: float = 50.0):
    """A square in the plane z = 0 facing +z, uv (0, 0) at the bottom-left corner (v up)."""
    V = np.array([[-half, -half, 0.0], [half, -half, 0.0], [half, half, 0.0], [-half, half, 0.0]])
    uv = np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]])
    return V, np.array([[0, 1, 2], [0, 2, 3]]), uv


def test_texture_orientation_v_up(renderer):
    """A marker in the texture image's top-left corner (row 0) appears at uv (0, 1): the quad's
    top-left in a front view (world +y up, −x = subject's right on the image left)."""
    tex = np.zeros((64, 64, 3), np.uint8)
    tex[...] = (0, 0, 255)
    tex[:8, :8] = (255, 0, 0)
    V, F, uv = facing_quad()
    cam = orbit_camera(0.0, 400, 300, distance_mm=300.0)
    res = renderer.render(cam, V, F, uv=uv, texture=tex)
    (u_tl, v_tl), (u_br, v_br), (u_tr, v_tr) = np.round(
        cam.project(np.array([[-47.0, 47.0, 0.0], [47.0, -47.0, 0.0], [47.0, 47.0, 0.0]]))
    ).astype(int)
    assert u_tl < u_br and v_tl < v_br  # sanity of the camera itself: top-left is up-left
    np.testing.assert_allclose(res.color[v_tl, u_tl], [1.0, 0.0, 0.0], atol=1e-6)
    np.testing.assert_allclose(res.color[v_tr, u_tr], [0.0, 0.0, 1.0], atol=1e-6)
    np.testing.assert_allclose(res.color[v_br, u_br], [0.0, 0.0, 1.0], atol=1e-6)
    # only the one corner is red: 1/64 of the quad's area
    red = res.mask & (res.color[..., 0] > 0.5)
    assert 0.01 < red.sum() / res.mask.sum() < 0.02


@pytest.mark.parametrize("name", ["oblique 480x640", "side 321x203"])
def test_texture_lookup_is_perspective_correct(renderer, name):
    """A float texture holding its own texel coordinates, bilinearly sampled, returns at every
    pixel the texel position of the analytic uv there: ``(u W - 0.5, (1 - v) H - 0.5)``."""
    Ht, Wt = 48, 80
    rows, cols = np.mgrid[0:Ht, 0:Wt].astype(np.float32)
    tex = np.stack([cols, rows], axis=-1)
    V, F, uv = facing_quad(60.0)
    R = orbit_camera(25.0, 10, 10).R  # tilt the quad too, so nothing is axis-aligned
    V = V @ R.T
    cam = CAMERAS[name]
    res = renderer.render(cam, V, F, uv=uv, texture=tex)
    assert res.color.shape == (cam.height, cam.width, 2)
    Xw = ray_plane_points(cam, pixel_grid(cam)[res.mask], V[0], np.cross(V[1] - V[0], V[3] - V[0]))
    # uv of a point on the quad: affine in the quad's own frame
    e_u, e_v = V[1] - V[0], V[3] - V[0]
    u = (Xw - V[0]) @ e_u / (e_u @ e_u)
    v = (Xw - V[0]) @ e_v / (e_v @ e_v)
    expect = np.column_stack([u * Wt - 0.5, (1.0 - v) * Ht - 0.5])
    got = res.color[res.mask]
    interior = ((expect > 0.5) & (expect < [Wt - 1.5, Ht - 1.5])).all(axis=1)  # away from the clamp
    assert interior.sum() > 1000
    # llvmpipe filters with 8-bit sub-texel weights: up to 1/256 texel; 0.02 leaves room
    np.testing.assert_allclose(got[interior], expect[interior], atol=0.02)


def test_uploaded_texture_handle_matches_array(renderer):
    scan_like = np.random.default_rng(0).integers(0, 256, (32, 48, 4), dtype=np.uint8)
    V, F, uv = facing_quad()
    cam = CAMERAS["front 640x480"]
    handle = renderer.upload_texture(scan_like)
    assert isinstance(handle, GLTexture) and handle.channels == 4 and handle.shape == (32, 48)
    a = renderer.render(cam, V, F, uv=uv, texture=scan_like)
    b = renderer.render(cam, V, F, uv=uv, texture=handle)
    np.testing.assert_array_equal(a.color, b.color)
    assert a.color.shape[2] == 4 and a.color.max() <= 1.0
    handle.release()
    with pytest.raises(ValueError, match="released"):
        renderer.render(cam, V, F, uv=uv, texture=handle)


# ----------------------------------------------------------------------------- visibility


def test_face_id_is_the_nearest_triangle(renderer):
    """Overlapping triangles at different depths: ``face_id`` is the one an analytic z-buffer
    picks (nearest along the pixel's ray among those whose projection contains the centre)."""
    rng = np.random.default_rng(3)
    cam = CAMERAS["oblique 480x640"]
    m = 12
    centres = rng.uniform(-50.0, 50.0, (m, 1, 3))
    tris = centres + rng.uniform(-60.0, 60.0, (m, 3, 3))
    V = tris.reshape(-1, 3)
    F = np.arange(3 * m).reshape(m, 3)
    res = renderer.render(cam, V, F)

    px = pixel_grid(cam)
    best = np.full((cam.height, cam.width), np.inf)
    expect = np.full((cam.height, cam.width), -1)
    ambiguous = np.zeros((cam.height, cam.width), bool)
    for k in range(m):  # m analytic rasterisations; each is vectorised over all pixels
        ef = edge_functions(px, cam.project(tris[k]))
        ambiguous |= (np.abs(ef) <= EDGE_MARGIN_PX).any(axis=-1)
        inside = (ef > 0).all(axis=-1)
        n = np.cross(tris[k, 1] - tris[k, 0], tris[k, 2] - tris[k, 0])
        z = np.full(inside.shape, np.inf)
        z[inside] = cam.depth(ray_plane_points(cam, px[inside], tris[k, 0], n))
        nearer = z < best
        # two surfaces within 0.01 mm (interpenetration lines) are a toss-up for the depth buffer
        with np.errstate(invalid="ignore"):  # inf - inf off the triangles
            ambiguous |= inside & (np.abs(z - best) < 1e-2)
        best[nearer], expect[nearer] = z[nearer], k
    judged = ~ambiguous
    assert (expect[judged] >= 0).sum() > 10000 and len(np.unique(expect[judged])) == m + 1
    np.testing.assert_array_equal(res.face_id[judged], expect[judged])
    np.testing.assert_allclose(res.depth[judged & (expect >= 0)], best[judged & (expect >= 0)], rtol=1e-5)


def test_backface_culling(renderer):
    """Counter-clockwise seen from the camera = front (OBJ winding); culling drops the other."""
    cam = CAMERAS["front 640x480"]
    front = np.array([[-40.0, -30.0, 0.0], [40.0, -30.0, 0.0], [0.0, 40.0, 0.0]])  # ccw from +z
    V = np.concatenate([front - [50.0, 0.0, 0.0], front + [50.0, 0.0, 0.0]])
    F = np.array([[0, 1, 2], [3, 5, 4]])  # the second one reversed: its back faces the camera
    both = renderer.render(cam, V, F)
    culled = renderer.render(cam, V, F, cull_backfaces=True)
    assert set(np.unique(both.face_id)) == {-1, 0, 1}
    assert set(np.unique(culled.face_id)) == {-1, 0}
    np.testing.assert_array_equal(culled.mask, both.face_id == 0)


# ----------------------------------------------------------------------------- options


def test_many_channels_and_background(renderer):
    """``colors`` with k > 4 channels is rendered 4 per pass; per-channel background."""
    cam = CAMERAS["side 321x203"]
    tri = BIG_TRIANGLE
    A = np.arange(18, dtype=float).reshape(3, 6) * [1.0, -2.0, 3.0, 1e3, -1e-3, 7.0]
    bg = np.arange(6) + 100.0
    res = renderer.render(cam, tri, np.array([[0, 1, 2]]), colors=A, background=bg)
    assert res.color.shape == (cam.height, cam.width, 6)
    np.testing.assert_array_equal(res.color[~res.mask], np.broadcast_to(bg, ((~res.mask).sum(), 6)))
    low = renderer.render(cam, tri, np.array([[0, 1, 2]]), colors=A[:, :4])
    high = renderer.render(cam, tri, np.array([[0, 1, 2]]), colors=A[:, 4:])
    np.testing.assert_array_equal(res.color[res.mask], np.concatenate([low.color, high.color], -1)[res.mask])


def test_supersample_keeps_geometry_and_antialiases(renderer):
    cam = CAMERAS["front 640x480"]
    tri = BIG_TRIANGLE
    F = np.array([[0, 1, 2]])
    one = renderer.render(cam, tri, F, colors=np.ones((3, 3)))
    three = renderer.render(cam, tri, F, colors=np.ones((3, 3)), supersample=3)
    # the central sub-sample sits exactly on the pixel centre (vertices snap to a finer grid,
    # so centres within EDGE_MARGIN_PX of an edge may flip)
    sure = (np.abs(edge_functions(pixel_grid(cam), cam.project(tri))) > EDGE_MARGIN_PX).all(axis=-1)
    np.testing.assert_array_equal(three.mask[sure], one.mask[sure])
    np.testing.assert_array_equal(three.face_id[sure], one.face_id[sure])
    both = sure & one.mask
    np.testing.assert_allclose(three.depth[both], one.depth[both], rtol=1e-6)
    # colour = covered fraction (white on black); fractional only along the edges
    np.testing.assert_allclose(three.color[..., 0], three.coverage, atol=1e-6)
    edge = (three.coverage > 0) & (three.coverage < 1)
    assert 0 < edge.sum() < 0.05 * one.mask.sum()
    with pytest.raises(ValueError, match="odd"):
        renderer.render(cam, tri, F, supersample=2)


@pytest.mark.parametrize("shading", ["lambert", "flat"])
def test_headlight_lambert(renderer, shading):
    """A plane at angle θ to the optical axis is shaded 0.15 + 0.85 cos θ, times the albedo 0.8."""
    cam = orbit_camera(0.0, 300, 300, distance_mm=400.0)
    V, F, _ = facing_quad(40.0)
    for theta in (0.0, 60.0):
        R = orbit_camera(theta, 10, 10).R  # rotation by θ about +y
        res = renderer.render(cam, V @ R.T, F, shading=shading)
        n_cam = cam.R @ (R @ [0.0, 0.0, 1.0])
        expect = 0.8 * (0.15 + 0.85 * abs(n_cam[2] / np.linalg.norm(n_cam)))
        np.testing.assert_allclose(res.color[res.mask], expect, atol=2e-3)  # flat: float derivatives
    tex = renderer.render(cam, V, F, shading=shading, colors=np.full((4, 3), 0.5))
    np.testing.assert_allclose(tex.color[tex.mask], 0.5 * (0.15 + 0.85 * 1.0), atol=2e-3)


def test_vertex_normals_of_a_box_corner():
    V = np.array([[0.0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]])
    F = np.array([[0, 2, 1], [0, 1, 3], [0, 3, 2]])  # the three faces at the origin, outward
    n = vertex_normals(V, F)
    np.testing.assert_allclose(n[0], -np.ones(3) / np.sqrt(3), atol=1e-12)
    np.testing.assert_allclose(np.linalg.norm(n, axis=1), 1.0)


def test_vertex_normals_are_area_weighted_and_zero_on_isolated_vertices():
    """A vertex shared by a big and a small triangle leans towards the big one's normal by area;
    a vertex no triangle uses gets 0 (no NaN); integer input is fine."""
    V = np.array([[0, 0, 0], [4, 0, 0], [0, 4, 0], [0, 0, 1], [9, 9, 9]])
    F = np.array([[0, 1, 2], [0, 3, 1]])  # areas 8 (normal +z) and 2 (normal +y)
    n = vertex_normals(V, F)
    expect = 8 * np.array([0, 0, 1.0]) + 2 * np.array([0, 1.0, 0])
    np.testing.assert_allclose(n[0], expect / np.linalg.norm(expect), atol=1e-12)
    np.testing.assert_allclose(n[2], [0, 0, 1.0], atol=1e-12)
    np.testing.assert_array_equal(n[4], 0.0)


def test_gl_projection_maps_pixels_to_window_coordinates():
    """The matrix itself: window = (project(X) + 0.5) for any point in view (the renderer's
    contract, independent of the rasteriser)."""
    cam = CAMERAS["oblique 480x640"]
    X = np.random.default_rng(1).uniform(-80, 80, (50, 3))
    clip = np.column_stack([cam.to_camera(X), np.ones(50)]) @ gl_projection(cam, 100.0, 2000.0).T
    ndc = clip[:, :3] / clip[:, 3:]
    window = (ndc[:, :2] + 1.0) / 2.0 * [cam.width, cam.height]
    np.testing.assert_allclose(window, cam.project(X) + 0.5, atol=1e-9)
    np.testing.assert_allclose(gl_projection(cam, 100.0, 2000.0) @ [0, 0, 100.0, 1] / 100.0, [0, 0, -1, 1], atol=1e-12)


# ----------------------------------------------------------------------------- boundaries


def test_bad_inputs_are_named(renderer):
    cam = CAMERAS["front 640x480"]
    tri = BIG_TRIANGLE
    F = np.array([[0, 1, 2]])
    with pytest.raises(ValueError, match="vertices"):
        renderer.render(cam, tri[:, :2], F)
    with pytest.raises(ValueError, match="outside"):
        renderer.render(cam, tri, np.array([[0, 1, 3]]))
    with pytest.raises(ValueError, match="uv"):
        renderer.render(cam, tri, F, texture=np.zeros((4, 4, 3), np.uint8))
    with pytest.raises(ValueError, match="colors"):
        renderer.render(cam, tri, F, colors=np.zeros((4, 3)))
    with pytest.raises(ValueError, match="not both"):
        renderer.render(cam, tri, F, uv=np.zeros((3, 2)), texture=np.zeros((4, 4)), colors=np.zeros(3))
    with pytest.raises(ValueError, match="shading"):
        renderer.render(cam, tri, F, shading="phong")
    with pytest.raises(ValueError, match="background"):
        renderer.render(cam, tri, F, background=[1.0, 2.0])
    with pytest.raises(ValueError, match="NaN"):
        renderer.render(cam, np.full((3, 3), np.nan), F)


def test_one_renderer_per_thread(renderer):
    assert get_renderer() is renderer
    out = {}

    def worker():
        try:
            renderer.render(CAMERAS["front 640x480"], np.eye(3), np.array([[0, 1, 2]]))
        except RuntimeError as exc:
            out["error"] = str(exc)
        own = get_renderer()
        out["own"] = own
        out["result"] = own.render(CAMERAS["front 640x480"], BIG_TRIANGLE, np.array([[0, 1, 2]]))
        own.release()

    t = threading.Thread(target=worker)
    t.start()
    t.join()
    assert "thread" in out["error"]
    assert out["own"] is not renderer and out["own"].released
    assert isinstance(out["result"], RenderResult) and out["result"].mask.any()


# ----------------------------------------------------------------------------- the real scan


def test_james_scan_front_view_is_upright_and_not_mirrored(renderer):
    """The textured scan from the front: subject's left (+x) on the image right, +y up, and the
    landmarks land on the rendered surface. (The picture itself: python benchmarks/bench_render.py.)"""
    scan = load_james_scan()
    cam = orbit_camera(0.0, 200, 250, distance_mm=900.0, target=(0.0, 10.0, 0.0))
    res = renderer.render(cam, scan.vertices, scan.faces, colors=scan.vertices)
    x, y = res.color[..., 0], res.color[..., 1]
    m = res.mask
    cols = np.nonzero(m.any(axis=0))[0]
    rows = np.nonzero(m.any(axis=1))[0]
    mid_u, mid_v = (cols[0] + cols[-1]) // 2, (rows[0] + rows[-1]) // 2
    assert x[:, mid_u + 20 :][m[:, mid_u + 20 :]].min() > 0  # image right = subject's left
    assert x[:, : mid_u - 20][m[:, : mid_u - 20]].max() < 0
    assert y[: mid_v - 40][m[: mid_v - 40]].mean() > y[mid_v + 40 :][m[mid_v + 40 :]].mean()  # up is up
    # eye corners (iBUG 36 = subject's right outer, 45 = left outer) are visible at their pixels
    lm = scan.landmarks[[36, 45, 30]]
    p = np.round(cam.project(lm)).astype(int)
    assert p[0, 0] < p[1, 0]
    np.testing.assert_allclose(res.depth[p[:, 1], p[:, 0]], cam.depth(lm), atol=5.0)  # mm; ±½ px slope
    textured = renderer.render(cam, scan.vertices, scan.faces, uv=scan.uv, texture=scan.texture)
    assert textured.color.shape == (250, 200, 3) and 0.05 < textured.color[m].mean() < 0.9


# ----------------------------------------------------------------------------- barycentric rasterisation


@pytest.mark.parametrize("name", CAMERAS)
def test_barycentric_raster_is_the_render_of_the_same_mesh(renderer, name):
    """Same pixels and triangles as :meth:`render` (one rasteriser, one fill rule); the barycentric
    coordinates interpolate the world position to a point on the pixel's own viewing ray."""
    cam = CAMERAS[name]
    V, F = bumpy_mesh()
    raster = renderer.rasterize_barycentric(cam, V, F)
    ref = renderer.render(cam, V, F)
    np.testing.assert_array_equal(raster.mask, ref.mask)
    assert raster.shape == (cam.height, cam.width) and len(raster.pixels) == ref.mask.sum() > 3000
    np.testing.assert_array_equal(raster.face_ids, ref.face_id.reshape(-1)[raster.pixels])
    np.testing.assert_array_equal(raster.corners, F[raster.face_ids])
    np.testing.assert_allclose(raster.bary.sum(1), 1.0, atol=1e-5)
    # inside the triangle up to GL's interpolation error at centres on an edge (measured -2e-4)
    assert raster.bary.dtype == np.float32 and (raster.bary > -1e-3).all()
    P = raster.interpolate(V)  # float64 values interpolated with float32 coordinates
    assert P.shape == (len(raster.pixels), 3) and P.dtype == np.float64
    v, u = np.divmod(raster.pixels, cam.width)
    np.testing.assert_allclose(cam.project(P), np.column_stack([u, v]), atol=2e-3)
    np.testing.assert_allclose(cam.depth(P), ref.depth.reshape(-1)[raster.pixels], rtol=1e-5)
    y0, y1, x0, x1 = raster.box
    assert (v >= y0).all() and (v < y1).all() and (u >= x0).all() and (u < x1).all()
    assert raster.interpolate(np.ones((len(V), 2, 2), np.float32)).shape == (len(raster.pixels), 2, 2)


def test_barycentric_raster_of_a_mesh_out_of_view_or_half_behind(renderer):
    cam = CAMERAS["front 640x480"]
    V, F = bumpy_mesh(9)
    for gone in (V + cam.center * 3.0, V + [5000.0, 0.0, 0.0]):  # behind the camera; beside the image
        raster = renderer.rasterize_barycentric(cam, gone, F)
        assert len(raster.pixels) == 0 and raster.corners.shape == (0, 3) and raster.bary.shape == (0, 3)
        assert not raster.mask.any() and raster.interpolate(V).shape == (0, 3)
    # the camera inside the mesh's depth range: vertices behind the near plane, the whole frame read
    near_cam = Camera(cam.R, cam.t - [0.0, 0.0, cam.t[2] - 10.0], cam.f, cam.width, cam.height)
    raster = renderer.rasterize_barycentric(near_cam, V, F)
    ref = renderer.render(near_cam, V, F)
    assert raster.box == (0, cam.height, 0, cam.width)
    np.testing.assert_array_equal(raster.mask, ref.mask)


def test_barycentric_raster_follows_a_changed_triangle_list(renderer):
    """The index buffer is kept between calls, but never stale: a new list, or the same array
    edited in place, is drawn as it is now."""
    cam = CAMERAS["oblique 480x640"]
    V, F = bumpy_mesh(11)
    F = F.copy()
    full = renderer.rasterize_barycentric(cam, V, F)
    half = renderer.rasterize_barycentric(cam, V, F[: len(F) // 2])
    assert 0 < len(half.pixels) < len(full.pixels)
    np.testing.assert_array_equal(half.mask, renderer.render(cam, V, F[: len(F) // 2]).mask)
    F[: len(F) // 2] = F[len(F) // 2 :]  # in place: the first half now repeats the second
    edited = renderer.rasterize_barycentric(cam, V, F)
    np.testing.assert_array_equal(edited.mask, renderer.render(cam, V, F).mask)
    with pytest.raises(ValueError, match="outside"):
        renderer.rasterize_barycentric(cam, V, F + len(V))


def test_barycentric_pass_is_released_with_its_renderer():
    out = {}

    def worker():
        own = get_renderer()
        own.rasterize_barycentric(CAMERAS["front 640x480"], BIG_TRIANGLE, np.array([[0, 1, 2]]))
        own.release()
        out["released"] = own.released
        try:
            own.rasterize_barycentric(CAMERAS["front 640x480"], BIG_TRIANGLE, np.array([[0, 1, 2]]))
        except RuntimeError as exc:
            out["error"] = str(exc)

    t = threading.Thread(target=worker)
    t.start()
    t.join()
    assert out["released"] and "released" in out["error"]
