"""The robust joint polish (photomodel.modeling.bundle.BundleProblem) on synthetic rigs with known truth.

The truth (cameras, points, clicks) is made in :mod:`peers.rigs`; the peer is the SciPy full
bundle adjustment of :mod:`peers.bundle_adjust`.
The analytic Jacobian is checked two ways: Gauss–Newton from near the truth with exact clicks
converges quadratically to the truth (a wrong Jacobian column gives at best linear convergence),
and at the point where :meth:`BundleProblem.solve` stops, the finite-difference gradient of
:meth:`BundleProblem.cost` vanishes (a wrong Jacobian stops elsewhere).
"""

from __future__ import annotations

import numpy as np
import pytest

from peers.bundle_adjust import bundle_adjust
from peers.rigs import (
    aligned,
    click_rms,
    face_points,
    focal_errors,
    generic_head,
    make_rig,
    perturbed_start,
    rotation_errors_deg,
)
from photomodel.alignment import transform_cameras
from photomodel.camera import rodrigues
from photomodel.modeling.bundle import BundleProblem, BundleState

AZ5 = [-70.0, -35.0, 0.0, 35.0, 70.0]
TRUTH = face_points(68)
GENERIC = generic_head(TRUTH)


def problem(rig, groups=None, **kw) -> BundleProblem:
    valid = np.isfinite(rig.observations[..., 0])
    pp = np.stack([c.principal_point for c in rig.true_cameras])
    groups = np.arange(len(rig.true_cameras)) if groups is None else np.asarray(groups)
    return BundleProblem(rig.observations, valid, pp, groups, **kw)


def fd_gradient(prob: BundleProblem, st: BundleState, c: float, h: float = 1e-6) -> np.ndarray:
    """Central finite differences of ``prob.cost`` over every unknown: per camera a rotation
    increment (``Rod(w) R``, radians), t_x, t_y (mm), s (px/mm); per group ln f; per point x, y, z."""
    k, n, G = prob.k, prob.n, prob.G
    N = 6 * k + G + 3 * n

    def moved(x):
        w, o = x[: 3 * k].reshape(k, 3), 3 * k
        t2, o = x[o : o + 2 * k].reshape(k, 2), o + 2 * k
        s, o = x[o : o + k], o + k
        lf, o = x[o : o + G], o + G
        R = np.stack([rodrigues(wi) for wi in w]) @ st.R
        return BundleState(R, st.t2 + t2, st.s + s, st.logf + lf, st.m + x[o:].reshape(n, 3))

    g = np.zeros(N)
    for i in range(N):
        e = np.zeros(N)
        e[i] = h
        g[i] = (prob.cost(moved(e), c) - prob.cost(moved(-e), c)) / (2.0 * h)
    return g


# ---------------------------------------------------------------------------------------------
# (a) the Jacobian: exact clicks → quadratic convergence to the truth; noisy → the peer's minimum
# ---------------------------------------------------------------------------------------------
@pytest.mark.parametrize(
    "groups, focal_free", [(None, True), ([0, 0, 1, 1, 2], True), (None, False)], ids=["free", "groups", "fixed_f"]
)
def test_exact_clicks_converge_quadratically_to_the_truth(groups, focal_free):
    # lenses that the groups [0, 0, 1, 1, 2] hold
    rig = make_rig(TRUTH, AZ5, seed=3, noise_px=0.0, focal_mm=[40.0, 40.0, 60.0, 60.0, 90.0])
    prob = problem(rig, groups, focal_free=focal_free)
    start_cams, start_pts = perturbed_start(rig.true_cameras, TRUTH, seed=3, focal=0.05 if focal_free else 0.0)
    st0 = prob.state_from_cameras(start_cams, start_pts)
    assert click_rms(start_cams, start_pts, rig.observations) > 10.0  # a real start: tens of px off
    # RMS after 1, 2, ... iterations from 26 px. Measured: 0.4–0.8, 0.6–1.4e-3, 0.9–3.8e-7, 3–27e-12 px —
    # the error squares each iteration, which only the exact Jacobian gives (Gauss–Newton on a
    # zero-residual problem; LM's damping starts at 1e-3 and shrinks ×10 per accepted step)
    rms = []
    for m in range(1, 6):
        st, _, _ = prob.solve(st0.copy(), c=np.inf, max_iter=m, tol=0.0)
        rms.append(click_rms(prob.cameras(st, rig.true_cameras), st.m, rig.observations))
    assert rms[1] < 0.05 and rms[2] < 1e-5 and rms[3] < 1e-9, rms
    st, its, converged = prob.solve(st0.copy(), c=np.inf)
    assert converged and its <= 6
    cams, pts = aligned(prob.cameras(st, rig.true_cameras), st.m, TRUTH)
    # exact clicks, 1e-11 px RMS: the truth to near machine precision (rotation angles come from
    # an arccos, good to ~1e-6°); measured focal 5e-12, centres 1e-8 mm, points 6e-11 mm
    assert rotation_errors_deg(cams, rig.true_cameras).max() < 1e-4
    assert focal_errors(cams, rig.true_cameras).max() < 1e-8
    assert max(np.linalg.norm(a.center - b.center) for a, b in zip(cams, rig.true_cameras, strict=True)) < 1e-5
    assert np.abs(pts - TRUTH).max() < 1e-7
    if groups is not None:
        assert prob.G == 3 and st.logf.shape == (3,)
    if not focal_free:
        assert [c.f for c in prob.cameras(st, rig.true_cameras)] == pytest.approx([c.f for c in start_cams], rel=1e-12)


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_least_squares_reaches_the_peer_bundle_adjustment_minimum(seed):
    rig = make_rig(TRUTH, AZ5, seed=seed, noise_px=1.0)
    prob = problem(rig)
    start_cams, start_pts = perturbed_start(rig.true_cameras, TRUTH, seed=seed)
    st, _, converged = prob.solve(prob.state_from_cameras(start_cams, start_pts), c=np.inf, max_iter=100, tol=1e-10)
    ours = click_rms(prob.cameras(st, rig.true_cameras), st.m, rig.observations)
    peer_cams, peer_pts, _ = bundle_adjust(rig.observations, start_cams, start_pts)
    peer = click_rms(peer_cams, peer_pts, rig.observations)
    # the same minimum: measured relative differences 2e-8–8e-8 (SciPy stops at ftol = 1e-8)
    assert converged
    assert ours == pytest.approx(peer, rel=1e-4)


@pytest.mark.parametrize("c", [np.inf, 2.5], ids=["least_squares", "huber"])
def test_solve_stops_where_the_finite_difference_gradient_vanishes(c):
    rig = make_rig(TRUTH, AZ5, seed=3, noise_px=1.0)
    prob = problem(rig, [0, 1, 1, 2, 2])
    st0 = prob.state_from_cameras(*perturbed_start(rig.true_cameras, TRUTH, seed=3))
    st, _, _ = prob.solve(st0.copy(), c=c, max_iter=100, tol=1e-14)
    g0 = np.linalg.norm(fd_gradient(prob, st0, c))
    g = np.linalg.norm(fd_gradient(prob, st, c))
    # measured |∇| / |∇ at the start|: 3e-12 for least squares (Newton-fast; the rest is the
    # finite-difference round-off), 6e-6 for Huber after 100 iterations (re-weighting converges
    # linearly). With one term of the Jacobian dropped or scaled by 0.9 the solver stops at
    # 4e-6–4e-3 (measured); a whole column scaled is a change of variables and goes unseen here,
    # but not by the quadratic-convergence test above
    assert g < (1e-9 if np.isinf(c) else 1e-4) * g0, (g, g0)


def test_prior_polish_converges_and_keeps_the_scene_scale():
    rig = make_rig(TRUTH, AZ5, seed=3, noise_px=1.0)
    prob = problem(rig, [0, 1, 1, 2, 2], prior_points=GENERIC, prior_weight=(1.0 / 15.0) ** 2)
    st0 = prob.state_from_cameras(*perturbed_start(rig.true_cameras, TRUTH, seed=3))
    early, _, _ = prob.solve(st0.copy(), c=np.inf, max_iter=3, tol=0.0)
    st, _, converged = prob.solve(st0.copy(), c=np.inf, max_iter=50, tol=1e-12)

    def size(m):
        return np.sqrt(((m - m.mean(0)) ** 2).sum(1).mean())

    g0 = np.linalg.norm(fd_gradient(prob, st0, np.inf))
    g = np.linalg.norm(fd_gradient(prob, st, np.inf))
    # nothing in the cost fixes the scene's scale (clicks and prior are similarity-invariant), so
    # once the points have settled (3 iterations) the scale has no reason to move. Measured with
    # the basis at st.m: converged in 7 iterations, |∇| / |∇₀| = 5e-11, the size after 3 and after
    # 50 iterations equal to 0.01 %; as it is: 58.5 → 15.4 mm, |∇| / |∇₀| = 3e-3
    assert size(st.m) == pytest.approx(size(early.m), rel=0.01)
    assert converged and g < 1e-6 * g0


# ---------------------------------------------------------------------------------------------
# (b) camera groups share one focal length
# ---------------------------------------------------------------------------------------------
@pytest.mark.parametrize("seed", [0, 1, 2])
def test_one_group_recovers_one_focal_length(seed):
    rig = make_rig(TRUTH, [-60.0, -20.0, 20.0, 60.0], seed=seed, noise_px=1.0, focal_mm=60.0)
    prob = problem(rig, [0, 0, 0, 0])
    # each photo starts from its own focal length (off by up to 15 %): the group takes their mean
    start_cams, start_pts = perturbed_start(rig.true_cameras, TRUTH, seed=seed, focal=0.15)
    st, _, converged = prob.solve(prob.state_from_cameras(start_cams, start_pts), c=np.inf, max_iter=100, tol=1e-10)
    assert converged and prob.G == 1 and st.logf.shape == (1,)
    cams = prob.cameras(st, rig.true_cameras)
    assert len({c.f for c in cams}) == 1
    # measured over 8 draws: the shared focal length within 0.2–1.6 % (each photo alone: up to 8 %)
    assert focal_errors(cams, rig.true_cameras).max() < 0.04


# ---------------------------------------------------------------------------------------------
# (c) Huber down-weights a gross outlier
# ---------------------------------------------------------------------------------------------
@pytest.mark.parametrize("seed", [0, 4, 9])
def test_huber_down_weights_a_gross_outlier(seed):
    rig = make_rig(TRUTH, AZ5, seed=seed, noise_px=1.0)
    rig.observations[2, 4] += [60.0, 45.0]  # the nose tip in the front photo 75 px off
    start = perturbed_start(rig.true_cameras, TRUTH, seed=seed)
    err = {}
    for c in (np.inf, 2.5):  # c = 2.5 σ with σ = 1 px, the threshold camera_solve uses
        prob = problem(rig)
        st, _, _ = prob.solve(prob.state_from_cameras(*start), c=c, max_iter=100, tol=1e-10)
        cams, _ = aligned(prob.cameras(st, rig.true_cameras), st.m, TRUTH)
        err[c] = rotation_errors_deg(cams, rig.true_cameras).max()
    # measured over 10 draws: least squares 1.1–1.5°, Huber 0.18–0.44° (as without the outlier)
    assert err[2.5] < 0.6
    assert err[2.5] < 0.5 * err[np.inf], err


# ---------------------------------------------------------------------------------------------
# (d) the generic-head prior is invariant under a similarity of the scene
# ---------------------------------------------------------------------------------------------
def test_prior_cost_is_similarity_invariant():
    rig = make_rig(TRUTH, AZ5, seed=5, noise_px=1.0)
    beta = (1.0 / 15.0) ** 2
    with_prior = problem(rig, prior_points=GENERIC, prior_weight=beta)
    no_prior = problem(rig)
    cams, pts = perturbed_start(rig.true_cameras, TRUTH, seed=5)
    st = with_prior.state_from_cameras(cams, pts)
    prior_cost = with_prior.cost(st, np.inf) - no_prior.cost(st, np.inf)
    # not vacuous: points up to 3 mm off a truth that is ~5 % and 4 mm from the generic head
    assert prior_cost > 1.0
    # the whole scene ×2 (points, translations): the images and so the click cost are unchanged
    doubled = with_prior.state_from_cameras(transform_cameras(cams, 2.0, np.eye(3), np.zeros(3)), 2.0 * pts)
    assert doubled.m == pytest.approx(2.0 * pts) and doubled.t2 == pytest.approx(2.0 * st.t2)
    assert no_prior.cost(doubled, np.inf) == pytest.approx(no_prior.cost(st, np.inf), rel=1e-10)
    assert with_prior.cost(doubled, np.inf) == pytest.approx(with_prior.cost(st, np.inf), rel=1e-10)
    # and any similarity (rotation, translation, scale 0.3)
    R = rodrigues([0.4, -0.7, 0.2])
    t = np.array([30.0, -50.0, 200.0])
    moved = with_prior.state_from_cameras(transform_cameras(cams, 0.3, R, t), 0.3 * pts @ R.T + t)
    assert with_prior.cost(moved, np.inf) == pytest.approx(with_prior.cost(st, np.inf), rel=1e-10)
