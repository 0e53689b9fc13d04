"""photomodel.people.mapping (seed 001) against cases with a known answer."""

import numpy as np
import pytest

from photomodel.people.mapping import ExpressionMapping, displacement_copy, expression_space


def _person(neutral, deltas, names):
    return np.array([neutral.ravel()] + [(neutral + deltas[k]).ravel() for k in names])


def test_identical_expression_spaces_map_a_performance_exactly():
    rng = np.random.default_rng(0)
    n = 40
    neutral = rng.standard_normal((n, 3)) * 30
    deltas = rng.standard_normal((10, n, 3))
    A = _person(neutral, deltas, range(6))
    space = expression_space(A)
    # B is A moved elsewhere (same shapes, translated): identical expression space up to the mean
    B = A + 5.0
    space_b = expression_space(B)
    weights = rng.random((20, 6)) * 0.3  # inside ±3σ of the training set
    frames = neutral.ravel() + weights @ deltas[:6].reshape(6, -1)
    for residual in (False, True):
        out = ExpressionMapping.between(space, space_b, residual=residual)(frames)
        np.testing.assert_allclose(out, frames + 5.0, atol=1e-9)


def test_residual_term_restores_what_the_target_space_lacks():
    rng = np.random.default_rng(1)
    n = 30
    neutral = rng.standard_normal((n, 3)) * 30
    deltas = rng.standard_normal((8, n, 3))
    A = expression_space(_person(neutral, deltas, [0, 1, 2, 3]))
    B = expression_space(_person(neutral, deltas, [0, 1]))  # lacks shapes 2 and 3
    frame = (neutral + 0.5 * deltas[2]).ravel()[None]
    plain = ExpressionMapping.between(A, B, residual=False)(frame)
    full = ExpressionMapping.between(A, B, residual=True)(frame)
    truth = A.project(frame) - A.mean + B.mean  # Eq. 4 without clipping: the projected displacement, copied
    assert np.linalg.norm(full - truth) < 0.05 * np.linalg.norm(plain - truth)


def test_mapped_parameters_stay_within_three_sigma():
    rng = np.random.default_rng(2)
    X = rng.standard_normal((6, 12))
    space = expression_space(X)
    m = ExpressionMapping.between(space, space, residual=False)
    p = m.map_parameters(np.full(len(space.variances), 1e6))
    np.testing.assert_allclose(p, 3 * np.sqrt(space.variances))


def test_displacement_copy_turns_the_displacement_with_the_heads():
    rng = np.random.default_rng(3)
    neutral = rng.standard_normal((50, 3)) * 40
    disp = rng.standard_normal((50, 3))
    c, s = np.cos(0.3), np.sin(0.3)
    R = np.array([[c, 0, s], [0, 1, 0], [-s, 0, c]])
    target = 1.1 * neutral @ R.T + 7.0
    out = displacement_copy((neutral + disp).ravel()[None], neutral, target)
    np.testing.assert_allclose(out[0], (target + 1.1 * disp @ R.T).ravel(), atol=1e-9)
    with pytest.raises(ValueError):
        expression_space(np.zeros((1, 9)))


def test_spaces_about_the_neutrals_map_a_shared_expression_between_different_sets():
    # one face, photographed in two different sets: a frame of a shape both sets hold must come back
    # exactly when both spaces are taken about the neutral (seed 001 §5's reference expression); about
    # the means, the two sets' mean expressions differ and their difference lands on every frame
    rng = np.random.default_rng(3)
    n = 30
    neutral = rng.standard_normal((n, 3)) * 30
    deltas = rng.standard_normal((8, n, 3))
    A, B = _person(neutral, deltas, [0, 1, 2, 3]), _person(neutral, deltas, [0, 1, 4])
    frame = (neutral + 0.5 * deltas[1]).ravel()[None]  # within 3σ of both sets (σ about the neutral ~ 0.5–0.7)
    about_neutral = ExpressionMapping.between(expression_space(A, 0), expression_space(B, 0))(frame)
    np.testing.assert_allclose(about_neutral, frame, atol=1e-9)
    about_mean = ExpressionMapping.between(expression_space(A), expression_space(B))(frame)
    assert np.abs(about_mean - frame).max() > 0.1  # the mean expressions' difference (shapes are ~1 mm)


def test_a_space_about_a_reference_spans_the_same_shapes():
    rng = np.random.default_rng(4)
    X = rng.standard_normal((5, 12))
    mean, ref = expression_space(X), expression_space(X, reference=0)
    np.testing.assert_allclose(ref.mean, X[0])
    y = rng.standard_normal((3, 12))
    np.testing.assert_allclose(ref.project(y), mean.project(y), atol=1e-9)  # the same affine span
    with pytest.raises(ValueError, match="reference 5"):
        expression_space(X, reference=5)
