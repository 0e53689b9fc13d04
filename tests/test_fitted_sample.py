"""Tests of photomodel.samples.fitted_sample: the cached fitted sample (the ``fitted_sample`` fixture
of 16 test files) is what the fit and texturing code make now, not what an earlier version made."""

from __future__ import annotations

import cv2
import numpy as np

from photomodel.data.keys import code_modules
from photomodel.exchange.mesh import read_mesh
from photomodel.project import load_project
from photomodel.samples.fitted_sample import fitted_sample_key, make_fitted_sample


def test_the_cached_fitted_sample_is_a_fresh_fit(fitted_sample, tmp_path):
    """The neutral fitted and textured afresh (fit_expression, texture_expression: ~10 s of the ~30 s
    the whole sample takes) equals the cached sample's. Its cache key is the code that makes it, so
    the two come from the same code and libraries: they agree to rounding (measured: identical)."""
    fresh_file = make_fitted_sample(tmp_path, ["neutral"])
    fresh = load_project(fresh_file).expression("neutral").result
    cached = load_project(fitted_sample).expression("neutral").result
    assert fresh is not None and cached is not None
    assert fresh.cameras.keys() == cached.cameras.keys()
    for pid, cam in fresh.cameras.items():
        np.testing.assert_allclose(cam.R, cached.cameras[pid].R, atol=1e-9)
        np.testing.assert_allclose(cam.t, cached.cameras[pid].t, atol=1e-6)
        np.testing.assert_allclose(cam.f, cached.cameras[pid].f, rtol=1e-9)
    v_fresh, f_fresh = read_mesh(fresh_file.parent / fresh.mesh_ply)
    v_cached, f_cached = read_mesh(fitted_sample.parent / cached.mesh_ply)
    np.testing.assert_array_equal(f_fresh, f_cached)
    np.testing.assert_allclose(v_fresh, v_cached, atol=1e-6)  # mm
    tex_fresh = cv2.imread(str(fresh_file.parent / fresh.texture.image), cv2.IMREAD_UNCHANGED)
    tex_cached = cv2.imread(str(fitted_sample.parent / cached.texture.image), cv2.IMREAD_UNCHANGED)
    assert tex_fresh.shape == tex_cached.shape
    assert np.abs(tex_fresh.astype(int) - tex_cached.astype(int)).max() <= 1  # 8-bit rounding


def test_the_cache_key_follows_the_code(fitted_sample):
    """The fitted sample lies in a folder named by its key, and that key is the code's: the fit, the
    texturing and the project code are all part of it."""
    assert fitted_sample.parent.name == fitted_sample_key()
    modules = set(code_modules(make_fitted_sample))
    assert {"photomodel.modeling.fit", "photomodel.texturing.job", "photomodel.project.io"} <= modules
    assert not any(m.startswith("tracking") for m in modules)  # the tracker's changes do not remake it
