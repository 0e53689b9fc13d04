"""The fragment-shader path of view-dependent texturing (photomodel.rendering.view_dependent_pass) against the numpy
path and against a synthetic scene whose answer is known (Pighin et al. 2002, §5.2.3).

* On the sample project (fitted mesh, recovered cameras, the five 1000×1000 photos) the shader
  frame of a new view must be the numpy frame: the same covered pixels and fallback pixels,
  and the same colours up to float rounding — plainly blended — or up to the registration's
  flow, which the two paths estimate at different resolutions.
* A flat textured quad photographed from two known cameras: the view-dependent frame from a
  third camera must be the quad rendered from that camera, and a photo's own camera must give
  back the photo.

No timing here: ``benchmarks/bench_texture.py`` measures frame times.
"""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np
import pytest

from photomodel.camera import orbit_camera, rodrigues
from photomodel.modeling.fit import fit_expression
from photomodel.modeling.generic_mesh import load_generic_mesh
from photomodel.project import load_project
from photomodel.rendering.renderer import get_renderer
from photomodel.rendering.view_dependent_pass import ViewDependentGL
from photomodel.texturing.cylindrical import single_view_weights
from photomodel.texturing.view_dependent import ViewDependentTexture, render_view_dependent

SAMPLE = Path(__file__).resolve().parents[1] / "sample_projects" / "james"


def psnr(a, b, mask) -> float:
    mse = float(((np.asarray(a, float) - np.asarray(b, float)) ** 2)[mask].mean())
    return 10.0 * np.log10(1.0 / max(mse, 1e-12))


# ----------------------------------------------------------------------------- the sample


@pytest.fixture(scope="module")
def sample():
    """The fitted sample model, its photos and a new view 20° from the front photo."""

    project = load_project(SAMPLE / "james.facestudio.json")
    expr = project.expression("neutral")
    photos = [cv2.cvtColor(cv2.imread(str(project.photo_path(p))), cv2.COLOR_BGR2RGB) for p in expr.photos]
    mesh = load_generic_mesh()
    fit = fit_expression(project, "neutral", mesh)
    cams = [fit.camera(p.id) for p in expr.photos]
    vdt = ViewDependentTexture(
        fit.vertices, mesh.faces, cams, photos, single_view=single_view_weights(fit.vertices, mesh.face_mask)
    )
    front = cams[[p.id for p in expr.photos].index("front")]
    new = front.copy()  # the front camera turned 20° about the head (the benchmark's new view)
    R = rodrigues(np.array([0.0, np.radians(20.0), 0.0]))
    new.R = front.R @ R.T
    new.t = front.R @ vdt.centre + front.t - new.R @ vdt.centre
    return {"vdt": vdt, "new": new, "cams": cams, "photos": photos}


@pytest.fixture(scope="module")
def plain_pair(sample):
    vdt, cam = sample["vdt"], sample["new"]
    bg = (0.86, 0.86, 0.85)
    return (
        vdt.render(cam, background=bg, method="numpy", align=False),
        vdt.render(cam, background=bg, method="shader", align=False),
    )


def test_shader_and_numpy_cover_the_same_pixels(plain_pair):
    a, b = plain_pair
    assert a.views == b.views and np.array_equal(a.view_weights, b.view_weights)
    assert a.mask.sum() > 100_000
    # the same triangles through the same projection: the same raster. A pixel centre lying on
    # an edge could fall either way with float32 positions; measured: 0 pixels differ
    differ = a.mask != b.mask
    assert differ.sum() <= 5
    if differ.any():  # only on the silhouette
        edge = cv2.morphologyEx(a.mask.astype(np.uint8), cv2.MORPH_GRADIENT, np.ones((3, 3), np.uint8)) > 0
        assert edge[differ].all()
    # the same fallback pixels (neither selected photo sees them), a few hundred
    assert 0 < a.filled.sum() < 0.01 * a.mask.sum()
    assert (a.filled != b.filled).sum() <= 5
    # background untouched, exactly
    off = b.color[~b.mask]
    np.testing.assert_array_equal(off, np.broadcast_to(np.float32([0.86, 0.86, 0.85]), off.shape))
    # the same depth buffer (mm)
    both = a.mask & b.mask
    assert np.abs(a.depth[both] - b.depth[both]).max() < 0.01
    assert np.isinf(b.depth[~b.mask]).all()


def test_shader_plain_blend_is_the_numpy_blend(plain_pair):
    a, b = plain_pair
    both = a.mask & b.mask
    # Measured 60 dB. What differs is rounding: the numpy path rounds each photo sample to
    # 8 bits (cv2.remap on uint8, ±0.5/255 alone caps the PSNR near 59 dB), OpenCV
    # interpolates with 1/32-px weights, the G-buffer stores normals in 12 bits and the
    # single-view weight in 7. A misplaced weight or a wrong visibility decision would show as
    # whole regions off by tens of grey levels (< 35 dB).
    assert psnr(a.color, b.color, both) > 50.0
    err = np.abs(a.color - b.color)[both].max(axis=1)
    assert np.quantile(err, 0.999) < 4.0 / 255.0


def test_shader_registration_matches_the_numpy_registration(sample, plain_pair):
    vdt, cam = sample["vdt"], sample["new"]
    a = vdt.render(cam, method="numpy")
    b = vdt.render(cam)  # the default: shader, aligned
    both = a.mask & b.mask
    assert np.array_equal(a.mask, b.mask)
    # Measured 47 dB. The shader path estimates one flow on quarter-resolution reprojections
    # (DIS "ultrafast") where the numpy path runs two on full-resolution ones ("fast"), and it
    # displaces samples on the tangent plane instead of in the reprojected image: features
    # land within a fraction of a pixel of each other, i.e. ~1/100 of the colour range where
    # detail is sharp. Without the registration the two frames differ by the ghosting it
    # removes (40 dB against each aligned frame), so 44 dB shows the shader registers.
    assert psnr(a.color, b.color, both) > 44.0
    plain = plain_pair[1]
    assert psnr(plain.color, b.color, both) < psnr(a.color, b.color, both)


def test_view_dependent_default_is_the_shader_path(sample):
    vdt, cam = sample["vdt"], sample["new"]
    small = cam.copy()
    small.f, small.width, small.height = cam.f / 4, cam.width // 4, cam.height // 4
    default = render_view_dependent(
        small, vdt.vertices, vdt.faces, vdt.cameras, vdt.photos, single_view=vdt.single_view
    )
    shader = vdt.render(small, method="shader").color
    np.testing.assert_allclose(default, shader, atol=1e-6)
    # the numpy path stays callable under both names
    np.testing.assert_array_equal(
        vdt.render(small, method="numpy").color, vdt.render(small, method="position_buffer").color
    )


def test_frames_of_other_sizes_and_out_of_view(sample):
    vdt, cam = sample["vdt"], sample["new"]
    for w, h in ((321, 203), (400, 780)):  # odd, non-square, not multiples of the flow's 4
        c = cam.copy()
        c.f, c.width, c.height = cam.f * min(w, h) / 1000.0, w, h
        a = vdt.render(c, method="numpy")
        b = vdt.render(c)
        assert b.color.shape == (h, w, 3) and b.color.dtype == np.float32
        assert (a.mask != b.mask).sum() <= 3
        assert psnr(a.color, b.color, a.mask & b.mask) > 38.0  # measured 42–45 dB
    away = orbit_camera(180.0, 64, 48, distance_mm=10.0, target=(0.0, 0.0, 5000.0))  # looks away
    out = vdt.render(away, background=(0.2, 0.3, 0.4))
    assert not out.mask.any() and np.isinf(out.depth).all()
    np.testing.assert_allclose(out.color, np.broadcast_to([0.2, 0.3, 0.4], (48, 64, 3)))


# ----------------------------------------------------------------------------- a known scene

QUAD_MM = 240.0


def quad_mesh(n: int = 24):
    """A flat square in the plane z = 0, facing +z, ``n × n`` cells; uv spans [0, 1]²."""
    s = np.linspace(-QUAD_MM / 2, QUAD_MM / 2, n + 1)
    X, Y = np.meshgrid(s, s)
    V = np.column_stack([X.ravel(), Y.ravel(), np.zeros(X.size)])
    uv = np.column_stack([(X.ravel() + QUAD_MM / 2) / QUAD_MM, (Y.ravel() + QUAD_MM / 2) / QUAD_MM])
    i = np.arange(n)[:, None] * (n + 1) + np.arange(n)[None, :]
    a, b, c, d = i.ravel(), i.ravel() + 1, i.ravel() + n + 1, i.ravel() + n + 2
    F = np.concatenate([np.column_stack([a, b, d]), np.column_stack([a, d, c])])  # counter-clockwise seen from +z
    return V, F, uv


@pytest.fixture(scope="module")
def quad():
    """The quad with a smooth random texture, photographed from ±30° by known cameras."""
    rng = np.random.default_rng(7)
    tex = cv2.resize(rng.uniform(0, 255, (24, 24, 3)).astype(np.float32), (512, 512), interpolation=cv2.INTER_CUBIC)
    tex = np.clip(tex, 0, 255).astype(np.uint8)
    V, F, uv = quad_mesh()
    r = get_renderer()
    cams = [orbit_camera(a, 320, 240, distance_mm=700.0, elevation_deg=e) for a, e in ((-30.0, 5.0), (30.0, -5.0))]
    photos = [
        (np.clip(r.render(c, V, F, uv=uv, texture=tex, background=0.5).color, 0, 1) * 255 + 0.5).astype(np.uint8)
        for c in cams
    ]
    return {"V": V, "F": F, "uv": uv, "tex": tex, "cams": cams, "photos": photos}


@pytest.mark.parametrize("method", ["shader", "numpy"])
def test_new_view_of_a_textured_quad_is_its_rendering(quad, method):
    """Exact geometry and cameras: a view between the two photos is the quad seen from there."""
    vdt = ViewDependentTexture(quad["V"], quad["F"], quad["cams"], quad["photos"], centre=np.zeros(3))
    between = orbit_camera(8.0, 320, 240, distance_mm=650.0, elevation_deg=2.0)
    out = vdt.render(between, background=0.5, method=method)
    truth = get_renderer().render(between, quad["V"], quad["F"], uv=quad["uv"], texture=quad["tex"], background=0.5)
    assert set(out.views) == {0, 1} and np.count_nonzero(out.view_weights) == 2
    assert np.array_equal(out.mask, truth.mask)
    assert not out.filled[cv2.erode(out.mask.astype(np.uint8), np.ones((5, 5), np.uint8)) > 0].any()
    # inside the quad (its outline ramps both photos' weights to 0 there): measured 46.5 dB for
    # both paths — the photos were resampled once (rendered at 320×240 from a 512² texture) and
    # are resampled again, each bilinear, and quantised to 8 bits
    inner = cv2.erode(truth.mask.astype(np.uint8), np.ones((9, 9), np.uint8)) > 0
    assert inner.sum() > 20_000
    assert psnr(out.color, truth.color, inner) > 38.0
    # exact geometry: nothing for the flow to register, the plain blend is the same frame
    # (measured 74 dB shader, 82 dB numpy: the flow finds sub-pixel noise)
    plain = vdt.render(between, background=0.5, method=method, align=False)
    assert psnr(out.color, plain.color, inner) > 55.0


def test_photos_of_other_sizes_and_a_view_outside_the_photographed_arc(quad):
    """Photos of different sizes share one padded texture array; outside the arc of the
    photos only the nearest one is used. Both as the numpy path."""
    r = get_renderer()
    cams = [quad["cams"][0], orbit_camera(30.0, 401, 299, distance_mm=700.0, elevation_deg=-5.0)]
    photos = [
        quad["photos"][0],
        (
            np.clip(
                r.render(cams[1], quad["V"], quad["F"], uv=quad["uv"], texture=quad["tex"], background=0.5).color, 0, 1
            )
            * 255
            + 0.5
        ).astype(np.uint8),
    ]
    vdt = ViewDependentTexture(quad["V"], quad["F"], cams, photos, centre=np.zeros(3))
    for az in (8.0, 55.0):
        cam = orbit_camera(az, 320, 240, distance_mm=650.0)
        a = vdt.render(cam, background=0.5, method="numpy", align=False)
        b = vdt.render(cam, background=0.5, align=False)
        assert np.count_nonzero(b.view_weights) == (2 if az == 8.0 else 1)
        assert np.array_equal(a.mask, b.mask) and np.array_equal(a.filled, b.filled)
        assert psnr(a.color, b.color, a.mask) > 50.0


def test_a_photo_camera_gives_back_the_photo(quad):
    vdt = ViewDependentTexture(quad["V"], quad["F"], quad["cams"], quad["photos"], centre=np.zeros(3))
    for k, cam in enumerate(quad["cams"]):
        out = vdt.render(cam, background=0.5)
        assert out.views[0] == k and np.count_nonzero(out.view_weights) == 1
        inner = cv2.erode(out.mask.astype(np.uint8), np.ones((9, 9), np.uint8)) > 0
        # sampled at its own pixel centres: exact up to float32 projection (measured > 115 dB)
        assert psnr(out.color, quad["photos"][k] / 255.0, inner) > 60.0


def test_an_occluder_hides_a_photo_behind_it(quad):
    """Per-pixel depth-map visibility in the shader: a small square in front of the quad hides
    part of it from the left photo only; behind it the new view must take the right photo's
    colour (here: the right photo is painted red, the left blue, so each pixel shows which)."""
    V, F, _ = quad["V"], quad["F"], quad["uv"]
    Vo, Fo, _ = quad_mesh(2)
    Vo = Vo * 0.25 + np.array([-20.0, 0.0, 80.0])  # 60 mm square, 80 mm in front, a little left
    Vall = np.vstack([V, Vo])
    Fall = np.vstack([F, Fo + len(V)])
    cams = [orbit_camera(-40.0, 320, 240, distance_mm=700.0), orbit_camera(40.0, 320, 240, distance_mm=700.0)]
    blue = np.zeros((240, 320, 3), np.uint8)
    blue[..., 2] = 255
    red = np.zeros((240, 320, 3), np.uint8)
    red[..., 0] = 255
    vdt = ViewDependentTexture(Vall, Fall, cams, [blue, red], centre=np.zeros(3), feather_mm=0.0)
    new = orbit_camera(-5.0, 320, 240, distance_mm=700.0)
    for method in ("shader", "numpy"):
        out = vdt.render(new, method=method, align=False)
        # the quad point behind the occluder as the left camera sees it: (-20, 0, 80) pushed
        # along the left camera's ray onto z = 0
        c = cams[0].center
        o = np.array([-20.0, 0.0, 80.0])
        hidden = c + (o - c) * (c[2] / (c[2] - o[2]))
        u, v = np.round(new.project(hidden[None])[0]).astype(int)
        assert out.mask[v, u]
        r, g, b = out.color[v, u]
        assert r > 0.95 and b < 0.05, (method, out.color[v, u])  # only the right photo sees it
        # a point of the quad far from the occluder is blended from both
        u2, v2 = np.round(new.project(np.array([[80.0, 60.0, 0.0]]))[0]).astype(int)
        assert out.color[v2, u2, 0] > 0.1 and out.color[v2, u2, 2] > 0.1


# ----------------------------------------------------------------------------- GL resources


def test_gl_state_is_made_once_and_released(quad):

    vdt = ViewDependentTexture(quad["V"], quad["F"], quad["cams"], quad["photos"], centre=np.zeros(3))
    cam = orbit_camera(5.0, 160, 120, distance_mm=700.0)
    first = vdt.render(cam).color
    gl = vdt.gl_state()
    assert isinstance(gl, ViewDependentGL) and vdt.gl_state() is gl and gl.renderer is get_renderer()
    np.testing.assert_array_equal(vdt.render(cam).color, first)  # deterministic
    gl.release()
    with pytest.raises(RuntimeError, match="released"):
        gl.render(cam, [0, 1], [0.5, 0.5])
    np.testing.assert_array_equal(vdt.render(cam).color, first)  # a new one is made
    assert vdt.gl_state() is not gl


def test_renderer_programs_are_cached_and_dropped_objects_freed_later():
    r = get_renderer()
    vs = "#version 330\nin vec2 p; void main() { gl_Position = vec4(p, 0.0, 1.0); }\n"
    fs = "#version 330\nout vec4 c; void main() { c = vec4(1.0); }\n"
    assert r.program(vs, fs) is r.program(vs, fs)
    with r.context() as ctx:
        buf = ctx.buffer(reserve=64)
    r.defer_release([buf])  # as a finaliser in another thread would
    r.render(orbit_camera(0.0, 8, 8), np.zeros((3, 3)), np.zeros((0, 3), int))  # its next use frees it
    # moderngl swaps a released object's handle for an InvalidObject, which has no methods: a buffer
    # not freed would take the write
    with pytest.raises(AttributeError, match="'InvalidObject' object has no attribute 'write'"):
        buf.write(b"\0" * 4)
