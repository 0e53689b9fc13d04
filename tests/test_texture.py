"""Tests of photomodel.texturing.cylindrical and .view_dependent against ground truth (§5.2.2–5.2.4).

Ground truth: the sample project's photos are renders of the james scan from known cameras
(``sample_projects/james/ground_truth.json``). Texturing the scan's *own geometry* from those
photos with the *true cameras* must give back the photos: a re-render of the cylindrical
texture, or a view-dependent render, from a photo's camera must match that photo. The photos
are downscaled 4× (250×250, cameras scaled to match) to keep the tests fast.
"""

from __future__ import annotations

import threading
from pathlib import Path

import cv2
import numpy as np
import pytest
from scipy.spatial import cKDTree

from photomodel.camera import Camera, orbit_camera
from photomodel.modeling.generic_mesh import load_generic_mesh
from photomodel.rendering.depth import project_points
from photomodel.rendering.renderer import get_renderer, vertex_normals
from photomodel.rendering.sampling import sample_image
from photomodel.samples.sample_data import load_james_scan
from photomodel.samples.synthetic import load_ground_truth, true_correspondence
from photomodel.texturing.cylindrical import (
    CylindricalTexture,
    cylinder_map_for,
    cylindrical_texture,
    fill_holes,
    rasterise_cylinder,
    render_cylindrical,
    single_view_weights,
)
from photomodel.texturing.view_dependent import ViewDependentTexture, render_view_dependent

SAMPLE = Path(__file__).resolve().parents[1] / "sample_projects" / "james"
SCALE = 4  # photos 1000 → 250 px
IDS = ["right", "three_quarter_right", "front", "three_quarter_left", "left"]


def psnr(a, b, mask) -> float:
    return float(10.0 * np.log10(1.0 / ((a - b) ** 2)[mask].mean()))


@pytest.fixture(scope="module")
def scene():
    """Scan (welded), downscaled photos, matching true cameras, face masks per photo."""
    truth = load_ground_truth(SAMPLE / "ground_truth.json")
    scan = load_james_scan()
    welded = scan.welded
    mesh = load_generic_mesh()
    on_scan = true_correspondence(mesh, scan)
    photos, cams, masks = [], [], []
    r = get_renderer()
    for pid in IDS:
        img = cv2.cvtColor(cv2.imread(str(SAMPLE / "photos" / f"neutral_{pid}.png")), cv2.COLOR_BGR2RGB)
        # INTER_AREA averages 4×4 blocks: the new pixel i is centred on old 4i + 1.5, which is
        # exactly a camera with f / 4 and the centred principal point of a 250-pixel image
        photos.append(cv2.resize(img, (img.shape[1] // SCALE, img.shape[0] // SCALE), interpolation=cv2.INTER_AREA))
        c = truth.cameras["neutral"][pid]
        cam = Camera(c.R, c.t, c.f / SCALE, c.width // SCALE, c.height // SCALE)
        cams.append(cam)
        face = r.render(cam, on_scan, mesh.faces, colors=mesh.face_mask.astype(np.float32)).color[..., 0] > 0.5
        head = r.render(cam, welded.vertices, welded.faces).mask.astype(np.uint8)
        # 2 px inside the silhouette: the photos are anti-aliased there, renders are not
        masks.append(face & (cv2.erode(head, np.ones((5, 5), np.uint8)) > 0))
    return {
        "V": np.asarray(welded.vertices),
        "F": np.asarray(welded.faces),
        "photos": photos,
        "cams": cams,
        "masks": masks,
        "mesh": mesh,
        "on_scan": on_scan,
    }


@pytest.fixture(scope="module")
def scan_texture(scene):
    return cylindrical_texture(scene["V"], scene["F"], scene["cams"], scene["photos"], size=256)


# ----------------------------------------------------------------------------- the cylinder


def first_hits(cmap, V, F, uv):
    """Reference: cast rays from outside the cylinder towards its axis and keep the first
    intersection (Möller–Trumbore against every triangle, vectorised over rays × triangles)."""
    origin_axis, outward = cmap.ray(uv)
    origins = origin_axis + 400.0 * outward  # well outside the head
    dirs = -outward
    a, b, c = (V[F[:, i]] for i in range(3))
    e1, e2 = b - a, c - a
    hit = np.full((len(uv), 3), np.nan)
    tri = np.full(len(uv), -1)
    for i0 in range(0, len(uv), 20):
        o, d = origins[i0 : i0 + 20, None], dirs[i0 : i0 + 20, None]  # (r, 1, 3)
        p = np.cross(d, e2)  # (r, m, 3)
        det = np.einsum("mj,rmj->rm", e1, p)
        ok = np.abs(det) > 1e-12
        inv = np.where(ok, 1.0 / np.where(ok, det, 1.0), 0.0)
        s = o - a
        u = np.einsum("rmj,rmj->rm", s, p) * inv
        q = np.cross(s, e1)
        v = np.einsum("rmj,rmj->rm", np.broadcast_to(d, q.shape), q) * inv
        t = np.einsum("mj,rmj->rm", e2, q) * inv
        good = ok & (u >= 0) & (v >= 0) & (u + v <= 1) & (t > 0)
        t = np.where(good, t, np.inf)
        j = np.argmin(t, axis=1)
        tj = t[np.arange(len(j)), j]
        found = np.isfinite(tj)
        rows = np.arange(i0, i0 + len(j))[found]
        hit[rows] = origins[rows] + dirs[rows] * tj[found, None]
        tri[rows] = j[found]
    return hit, tri


@pytest.mark.parametrize("which", ["generic", "scan"])
def test_rasterised_cylinder_equals_casting_rays_towards_the_axis(scene, which):
    """§5.2.2 step 2: the rasterised route gives the first hit of the ray from the cylinder."""
    if which == "generic":
        V, F = scene["mesh"].vertices, scene["mesh"].faces
    else:
        V, F = scene["V"], scene["F"]
    size = 256
    cmap = cylinder_map_for(V, F, size)
    raster = rasterise_cylinder(cmap, V, F, size)
    # texels well inside the surface: the 3×3 neighbourhood is covered and the radius varies
    # smoothly, so the GL fill rule and the exact ray test cannot pick different triangles
    surf = raster.surface
    r = np.nan_to_num(raster.radius, nan=-1e3)
    interior = cv2.erode(surf.astype(np.uint8), np.ones((3, 3), np.uint8)) > 0
    smooth = (cv2.dilate(r, np.ones((3, 3))) - cv2.erode(r, np.ones((3, 3)))) < 3.0
    rows, cols = np.nonzero(interior & smooth)
    pick = np.random.default_rng(3).choice(len(rows), 300, replace=False)
    rows, cols = rows[pick], cols[pick]
    u, v = cmap.texel_uv(size)
    hit, tri = first_hits(cmap, V, F, np.column_stack([u[cols], v[rows]]))
    assert np.isfinite(hit).all(), "every picked texel's ray hits the mesh"
    err = np.linalg.norm(raster.points[rows, cols] - hit, axis=1)
    same = raster.face_id[rows, cols] == tri
    assert same.mean() > 0.97  # the same triangle, bar texels on a shared edge
    # the same triangle: the exact ray–plane intersection, stored as float32 (~1e-5 mm at 100 mm)
    assert err[same].max() < 1e-3
    # a neighbouring triangle across a shared edge: still the same surface point
    assert err.max() < 0.05


def test_cylinder_map_puts_the_seam_in_the_gap_of_a_face_mask(scene):
    mesh = scene["mesh"]
    cmap = cylinder_map_for(mesh.vertices, mesh.faces)
    span = np.degrees(cmap.phi_range[1] - cmap.phi_range[0])
    assert span < 300.0  # the open back of the mask is not part of the texture
    uv = cmap.uv(mesh.vertices)
    assert uv.min() > 0.0 and uv.max() < 1.0
    # the nose tip is in the middle of the texture, the subject's left (+x) on the right
    nose = uv[mesh.features["nose_tip"]]
    assert abs(nose[0] - 0.5) < 0.1
    assert uv[mesh.features["eye_l_outer"], 0] > nose[0] > uv[mesh.features["eye_r_outer"], 0]


def test_whole_head_seam_is_split_and_duplicated(scene, scan_texture):
    """The scan wraps all the way round: seam triangles get unwrapped duplicates."""
    tex = scan_texture
    F = scene["F"]
    assert len(tex.seam_faces) == len(F)
    assert len(tex.seam_vertices) > len(scene["V"])  # duplicated seam vertices
    assert tex.seam_uv.min() >= 0.0 and tex.seam_uv.max() <= 1.0
    # no rendering triangle wraps across the texture, except a few on the caps (the crown and
    # the open bottom), nearly horizontal and close to the axis, which no cylinder can map
    span = np.ptp(tex.seam_uv[tex.seam_faces][:, :, 0], axis=1)
    wide = span >= 0.05
    assert wide.mean() < 0.01
    v = tex.seam_uv[tex.seam_faces[wide]][:, :, 1].mean(axis=1)
    assert np.all((v < 0.15) | (v > 0.85))
    np.testing.assert_array_equal(tex.seam_vertices[tex.seam_faces].shape, F.shape)


# ----------------------------------------------------------------------------- the texture


def test_cylindrical_texture_reproduces_the_photos_from_their_cameras(scene, scan_texture):
    tex = scan_texture
    assert isinstance(tex, CylindricalTexture)
    assert tex.image.shape == (256, 256, 3) and tex.image.dtype == np.uint8
    assert tex.weight_maps.shape == (5, 256, 256)
    assert tex.weight_maps.min() >= 0.0 and tex.weight_maps.max() <= 1.0
    assert tex.coverage.sum() > 0.8 * tex.surface.sum()  # five photos see most of the head
    Vr, Fr, uvr = tex.render_mesh(scene["V"])
    for k in (1, 2, 3):
        res = render_cylindrical(scene["cams"][k], Vr, Fr, uvr, tex.image)
        ref = scene["photos"][k] / 255.0
        # measured 34–36 dB: a 256² texture of the whole head (~2 mm per texel) resampled to
        # 250² photos (~1.1 mm per pixel) blurs skin detail; a misplaced mapping gives < 25 dB
        assert psnr(res.color, ref, scene["masks"][k]) > 31.0


def test_weight_maps_follow_the_cameras(scene, scan_texture):
    """The front photo dominates the front of the face, each profile its own side."""
    tex = scan_texture
    cmap = tex.cylinder
    nose = cmap.uv(scene["on_scan"][[scene["mesh"].features["nose_tip"]]])[0]
    col = int(nose[0] * 256)
    row = int((1 - nose[1]) * 256)
    g = tex.weight_maps[:, row, col]
    assert np.argmax(g) == 2
    ear_l = cmap.uv(scene["on_scan"][[scene["mesh"].features["jaw_16"]]])[0]
    g = tex.weight_maps[:, int((1 - ear_l[1]) * 256), int(ear_l[0] * 256)]
    assert np.argmax(g) in (3, 4) and g[0] == 0.0  # the subject's left: not seen by the right profile


def test_single_view_region_takes_one_photo_unblended(scene):
    V, F, cams, photos = scene["V"], scene["F"], scene["cams"], scene["photos"]
    size = 128
    tex = cylindrical_texture(V, F, cams, photos, size=size, single_view=np.ones(len(V)), fill=False)
    raster = rasterise_cylinder(tex.cylinder, V, F, size)
    rows, cols = np.nonzero(tex.coverage)
    best = np.argmax(tex.weight_maps[:, rows, cols], axis=0)
    expected = np.zeros((len(rows), 3))
    pts = raster.points[rows, cols].astype(np.float32)
    for k in range(5):
        sel = best == k
        uv, _ = project_points(cams[k], pts[sel])
        expected[sel] = sample_image(photos[k], uv)
    # uint8 rounding of the sample and of the texture: at most 1 level apart
    assert np.abs(tex.image[rows, cols].astype(float) - expected).max() <= 1.0


def test_compiled_texel_loops_equal_the_numpy_route(scene, monkeypatch):
    """The texture's compiled per-texel loops (:mod:`photomodel.texturing.texel_kernels`) against
    the numpy functions whose formulas they follow, on the sample head with a single-view region."""
    from photomodel.rendering.depth import depth_visible
    from photomodel.texturing import cylindrical
    from photomodel.texturing.weights import apply_single_view, blend, positional_certainty

    def numpy_photo_texels(M, RT, pts, nrm, depth, tol_mm):  # the route before the compiled loop
        cam = numpy_photo_texels.camera
        uv, z = project_points(cam, pts)
        P = positional_certainty(cam, pts, nrm)
        return uv, P, depth_visible(cam, pts, depth, tol_mm=tol_mm, uv=uv, z=z) & (P > 0)

    def numpy_blend(g, colors, single):
        return blend(colors, apply_single_view(g, single))

    V, F, cams, photos = scene["V"], scene["F"], scene["cams"], scene["photos"]
    single = single_view_weights(V, np.linalg.norm(V - V.mean(axis=0), axis=1) < 60.0)
    compiled = cylindrical_texture(V, F, cams, photos, size=256, single_view=single)

    photo_weight = cylindrical._photo_weight

    def with_camera(texels, cam, *args, **kw):
        numpy_photo_texels.camera = cam
        return photo_weight(texels, cam, *args, **kw)

    monkeypatch.setattr(cylindrical, "photo_texels", numpy_photo_texels)
    monkeypatch.setattr(cylindrical, "blend_single_view", numpy_blend)
    monkeypatch.setattr(cylindrical, "_photo_weight", with_camera)
    reference = cylindrical_texture(V, F, cams, photos, size=256, single_view=single)
    # the same formulas in another order of float32 operations: a texel's colour may round to the
    # next level, and a point within ~1e-4 mm of the depth test's tolerance may flip (measured on
    # the 1024² sample texture: 1 level at most, 108 dB)
    diff = np.abs(compiled.image.astype(float) - reference.image.astype(float))
    assert 10.0 * np.log10(255.0**2 / max((diff**2).mean(), 1e-12)) > 60.0
    assert (diff > 1).mean() < 1e-4
    assert np.abs(compiled.weight_maps - reference.weight_maps).max() < 1e-3
    np.testing.assert_array_equal(compiled.coverage, reference.coverage)


def test_single_view_weights_ramp_away_from_the_face():
    mesh = load_generic_mesh()
    s = single_view_weights(mesh.vertices, mesh.face_mask, offset_mm=20.0, ramp_mm=15.0)
    assert s[mesh.face_mask].max() == 0.0  # the face itself is always blended

    dist, _ = cKDTree(mesh.vertices[mesh.face_mask]).query(mesh.vertices)
    assert s[dist >= 20.0].min() == 1.0 and s[dist <= 5.0].max() == 0.0
    ramp = (dist > 5.0) & (dist < 20.0)
    order = np.argsort(dist[ramp])
    assert np.all(np.diff(s[ramp][order]) >= 0)
    ears = np.abs(mesh.vertices[:, 0]) > 0.95 * np.abs(mesh.vertices[:, 0]).max()
    assert s[ears].min() == 1.0  # the ears are a single-view region


def test_fill_holes_keeps_known_texels_and_fills_smoothly():
    rng = np.random.default_rng(4)
    y, x = np.mgrid[0:64, 0:96].astype(np.float32)
    img = np.dstack([x, y, x + y]).astype(np.float32)
    known = rng.uniform(size=(64, 96)) > 0.7
    known[20:40, 30:70] = False  # a large hole
    out = fill_holes(img * known[..., None], known)
    np.testing.assert_array_equal(out[known], img[known])
    # a hole in a smooth image is filled with values between its neighbours'
    hole = ~known
    assert np.all(out[hole][:, 0] >= -1e-3) and np.all(out[hole][:, 0] <= 95.0 + 1e-3)
    assert np.abs(out[hole] - img[hole]).mean() < 6.0  # roughly right, not black
    const = np.full((32, 32, 3), 77, np.uint8)
    k = np.zeros((32, 32), bool)
    k[5, 7] = True
    assert np.array_equal(fill_holes(const * k[..., None], k), const)


def test_cylindrical_texture_refuses_mismatched_inputs(scene):
    V, F, cams, photos = scene["V"], scene["F"], scene["cams"], scene["photos"]
    with pytest.raises(ValueError, match="cameras but"):
        cylindrical_texture(V, F, cams[:2], photos[:3], size=64)
    with pytest.raises(ValueError, match=r"photos\[1\] is"):
        cylindrical_texture(V, F, cams[:2], [photos[0], photos[1][:-1]], size=64)
    with pytest.raises(ValueError, match="uint8"):
        cylindrical_texture(V, F, cams[:1], [photos[0].astype(float)], size=64)
    with pytest.raises(ValueError, match="size"):
        cylindrical_texture(V, F, cams, photos, size=4)


# ----------------------------------------------------------------------------- view-dependent


@pytest.fixture(scope="module")
def vdt(scene):
    return ViewDependentTexture(scene["V"], scene["F"], scene["cams"], scene["photos"])


def test_view_dependent_render_from_a_photo_camera_is_that_photo(scene, vdt):
    """V_k selects the photograph alone when the new view is its camera (§5.2.3)."""
    for k in (0, 2, 4):
        out = vdt.render(scene["cams"][k])
        assert out.views[0] == k and np.count_nonzero(out.view_weights) == 1
        # measured 49–52 dB: sampling the photo at its own pixel centres is exact up to
        # OpenCV's 1/32-px weights, float32 depth round trips and uint8 rounding
        assert psnr(out.color, scene["photos"][k] / 255.0, scene["masks"][k]) > 44.0


def test_view_dependent_selects_the_two_nearest_photos(scene, vdt):
    between = orbit_camera(20.0, 200, 200, distance_mm=900.0, target=(0.0, 12.0, 55.0))
    out = vdt.render(between)
    assert set(out.views) == {2, 3}  # front (0°) and three-quarter left (+40°)
    assert np.count_nonzero(out.view_weights) == 2
    assert out.view_weights[2] == pytest.approx(out.view_weights[3], rel=0.15)  # ~halfway
    side = orbit_camera(-60.0, 200, 200, distance_mm=900.0, target=(0.0, 12.0, 55.0))
    assert set(vdt.render(side).views) == {0, 1}


def test_view_dependent_registration_is_per_pair_and_kept(vdt):
    """The registration of two photographs is computed once per pair and kept: a view moved
    within the same pair reuses it, and computing it afresh gives the same image."""
    a = orbit_camera(20.0, 200, 200, distance_mm=900.0, target=(0.0, 12.0, 55.0))
    b = orbit_camera(-25.0, 200, 200, distance_mm=900.0, target=(0.0, 12.0, 55.0))
    vdt.forget_registration()
    fresh = vdt.render(a).color
    pair = tuple(sorted(vdt.view_weights(a)[0]))
    maps = vdt.registration_shift(*pair)
    assert np.abs(maps).max() > 0.1  # the photographs disagree somewhere: a real registration
    assert np.array_equal(vdt.render(a).color, fresh)  # kept: the same image
    vdt.render(b)  # another pair
    a.t = a.t + np.array([2.0, 0.0, 0.0])  # the view moved: the same pair's maps serve it
    moved = vdt.render(a).color
    assert vdt.registration_shift(*pair) is maps
    vdt.forget_registration()
    assert np.array_equal(vdt.render(a).color, moved)  # computed afresh: the same image


def test_view_dependent_registration_ahead_on_another_thread(scene, vdt):
    """The pairs an orbit selects are registered ahead on a worker thread (no GL there): the
    same maps as computed on demand, and a frame of such a pair computes nothing."""
    pairs = vdt.orbit_pairs()
    assert (2, 3) in pairs and (0, 1) in pairs  # the two pairs test_..._selects_the_two_nearest sees
    assert all(a < b for a, b in pairs) and len(set(pairs)) == len(pairs)
    fresh = ViewDependentTexture(scene["V"], scene["F"], scene["cams"], scene["photos"])
    with pytest.raises(RuntimeError, match="prepare_surfaces"):
        fresh.register_pairs()
    fresh.prepare_surfaces()
    worker = threading.Thread(target=fresh.register_pairs, kwargs={"pairs": [(3, 2), (0, 1)]})
    worker.start()
    worker.join()
    for pair in ((2, 3), (0, 1)):
        np.testing.assert_array_equal(fresh._shifts[pair], vdt.registration_shift(*pair))
    fresh._registration = None  # a frame of a registered pair must not compute again
    between = orbit_camera(20.0, 200, 200, distance_mm=900.0, target=(0.0, 12.0, 55.0))
    np.testing.assert_array_equal(fresh.render(between).color, vdt.render(between).color)
    assert fresh.register_pairs([(2, 3)], cancel=lambda: True) == 0


def test_view_dependent_held_out_view_with_true_geometry(scene):
    """Leave-one-out: textured from four photos, rendered from the fifth's camera."""
    keep = [0, 1, 3, 4]
    j = 2
    img = render_view_dependent(
        scene["cams"][j], scene["V"], scene["F"], [scene["cams"][i] for i in keep], [scene["photos"][i] for i in keep]
    )
    # measured 39.4 dB (the benchmark's 46 dB at full resolution); the bar of issue 4 is 30 dB
    assert psnr(img, scene["photos"][j] / 255.0, scene["masks"][j]) > 35.0


def test_per_vertex_multipass_agrees_with_the_position_buffer(scene, vdt):
    cam = orbit_camera(20.0, 200, 200, distance_mm=900.0, target=(0.0, 12.0, 55.0))
    a = vdt.render(cam, method="position_buffer")
    b = vdt.render(cam, method="per_vertex")
    both = a.mask & b.mask & ~a.filled & ~b.filled  # the fallbacks differ (crown, collar)
    # measured 55 dB: per-vertex weights and texture coordinates differ near occlusions only
    assert psnr(a.color, b.color, both) > 45.0
    with pytest.raises(ValueError, match="method"):
        vdt.render(cam, method="nope")


def test_normals_used_for_certainty_point_outward(scene):
    n = vertex_normals(scene["V"], scene["F"])
    nose = scene["on_scan"][scene["mesh"].features["nose_tip"]]
    i = int(np.argmin(np.linalg.norm(scene["V"] - nose, axis=1)))
    assert n[i, 2] > 0.8  # the nose tip's normal points out of the face (+z)


def test_view_dependent_out_of_view_is_background(vdt):
    away = orbit_camera(180.0, 64, 48, distance_mm=10.0, target=(0.0, 0.0, 5000.0))  # looks away
    for method in ("position_buffer", "per_vertex"):
        out = vdt.render(away, background=(0.2, 0.3, 0.4), method=method)
        assert not out.mask.any()
        np.testing.assert_allclose(out.color, np.broadcast_to([0.2, 0.3, 0.4], (48, 64, 3)))
