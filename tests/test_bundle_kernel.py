"""photomodel.modeling.bundle_kernel: the compiled normal equations' gradient is the cost's.

The Gauss–Newton gradient ``Jᵀ r`` the kernel assembles must be half the gradient of the
least-squares cost ``Σ ‖r‖²`` — checked against central finite differences of
:meth:`BundleProblem.cost` in every kind of unknown (points, rotation increments, t_x/t_y, image
scales, group log focal lengths). A wrong Jacobian entry shows here unless its residual happens
to vanish; the convergence tests of tests/test_bundle.py catch the rest.
"""

from __future__ import annotations

import numpy as np
import pytest

from peers.rigs import face_points, synthetic_rig
from photomodel.modeling.bundle import BundleProblem, BundleState
from photomodel.modeling.pose import rodrigues_batch


def _moved(st: BundleState, which: str, index, h: float) -> BundleState:
    new = st.copy()
    if which == "rot":
        j, a = index
        v = np.zeros((len(st.s), 3))
        v[j, a] = h
        new.R = rodrigues_batch(v) @ st.R
    else:
        getattr(new, which)[index] += h
    return new


@pytest.mark.parametrize("focal_free", [True, False])
def test_assembled_gradient_is_half_the_cost_gradient(focal_free):
    truth = face_points(30)
    rig = synthetic_rig(4, truth, rng=3, noise_px=1.0)
    obs = rig.observations
    valid = np.isfinite(obs[..., 0])
    pp = np.stack([cam.principal_point for cam in rig.init_cameras])
    prob = BundleProblem(obs, valid, pp, np.array([0, 1, 1, 2]), focal_free)
    st = prob.state_from_cameras(rig.true_cameras, truth + 2.0)  # off the minimum: non-zero residuals
    _, gc, _, _, gp = prob._normal_equations(st, prob.evaluate(st), np.inf, None)

    def fd(which, index, h):
        return (prob.cost(_moved(st, which, index, h), np.inf) - prob.cost(_moved(st, which, index, -h), np.inf)) / (
            2 * h
        )

    # central differences with these steps are accurate to ~1e-6 relative here (cost ~1e5 px²)
    for i in (0, 7, 29):
        for a in range(3):
            assert fd("m", (i, a), 1e-4) / 2 == pytest.approx(gp[i, a], rel=1e-5, abs=1e-6)
    k = len(st.s)
    for j in range(k):
        for a in range(3):
            assert fd("rot", (j, a), 1e-7) / 2 == pytest.approx(gc[6 * j + a], rel=1e-5, abs=1e-4)
        for a in range(2):
            assert fd("t2", (j, a), 1e-4) / 2 == pytest.approx(gc[6 * j + 3 + a], rel=1e-5, abs=1e-6)
        assert fd("s", j, 1e-7) / 2 == pytest.approx(gc[6 * j + 5], rel=1e-5, abs=1e-3)
    if focal_free:
        for g in range(3):
            assert fd("logf", g, 1e-6) / 2 == pytest.approx(gc[6 * k + g], rel=1e-5, abs=1e-3)
