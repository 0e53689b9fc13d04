"""photomodel.modeling.bundle_kernel: the compiled normal equations equal the numpy formulation."""

from __future__ import annotations

import numpy as np
import pytest

from peers.rigs import face_points, synthetic_rig
from photomodel.modeling.bundle import BundleProblem


@pytest.mark.parametrize("focal_free", [True, False])
@pytest.mark.parametrize("c", [np.inf, 2.0])
def test_compiled_assembly_equals_the_array_formulation(focal_free, c):
    truth = face_points(40)
    rig = synthetic_rig(5, truth, rng=3, noise_px=1.0)
    obs = rig.observations
    valid = np.isfinite(obs[..., 0])
    pp = np.stack([cam.principal_point for cam in rig.init_cameras])
    prob = BundleProblem(obs, valid, pp, np.array([0, 1, 1, 2, 3]), focal_free)
    st = prob.state_from_cameras(rig.true_cameras, truth + 2.0)  # off the minimum: non-zero residuals
    ev = prob.evaluate(st)
    compiled = prob._normal_equations(st, ev, c, None)
    reference = prob._normal_equations_numpy(st, ev, c)
    for a, b in zip(compiled, reference, strict=True):
        # the same sums in another order: equal to rounding (1e-12 of the largest entry)
        np.testing.assert_allclose(a, b, rtol=0, atol=1e-12 * np.abs(b).max())
