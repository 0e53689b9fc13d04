"""photomodel.people.multilinear against tensors whose answer is known."""

import numpy as np
import pytest

from photomodel.people.multilinear import (
    MultilinearModel,
    average_displacement,
    build_model,
    impute,
    mode_product,
    n_mode_svd,
    unfold,
)


def _low_rank(shape, ranks, seed=0):
    rng = np.random.default_rng(seed)
    T = rng.standard_normal(ranks)
    for k, (d, r) in enumerate(zip(shape, ranks, strict=True)):
        T = mode_product(T, rng.standard_normal((d, r)), k)
    return T


def test_unfold_fold_and_mode_product_match_the_definition():
    rng = np.random.default_rng(1)
    T = rng.standard_normal((4, 5, 6))
    M = rng.standard_normal((3, 5))
    P = mode_product(T, M, 1)
    assert P.shape == (4, 3, 6)
    np.testing.assert_allclose(P, np.einsum("aje,bj->abe", T, M))
    assert unfold(T, 2).shape == (6, 20)


def test_n_mode_svd_of_a_known_rank_tensor_reconstructs_it_exactly():
    T = _low_rank((40, 7, 9), (5, 3, 4))
    core, U = n_mode_svd(T, (5, 3, 4))
    assert core.shape == (5, 3, 4)
    R = core
    for k, Uk in enumerate(U):
        np.testing.assert_allclose(Uk.T @ Uk, np.eye(Uk.shape[1]), atol=1e-10)
        R = mode_product(R, Uk, k)
    np.testing.assert_allclose(R, T, atol=1e-9 * np.abs(T).max())
    # one rank fewer in a mode loses something (the truncation is real)
    core2, U2 = n_mode_svd(T, (5, 2, 4))
    R2 = core2
    for k, Uk in enumerate(U2):
        R2 = mode_product(R2, Uk, k)
    assert np.linalg.norm(R2 - T) > 1e-3 * np.linalg.norm(T)


def test_model_face_reproduces_every_training_cell_and_survives_saving(tmp_path):
    T = _low_rank((30, 6, 5), (8, 6, 5), seed=2) + 50.0
    model = build_model(T, (None, None, None), [f"e{k}" for k in range(5)], [f"p{k}" for k in range(6)])
    for i in (0, 3):
        for e in (0, 4):
            np.testing.assert_allclose(
                model.face(model.identity_rows[i], model.expression_rows[e]), T[:, i, e], atol=1e-8
            )
    model.save(tmp_path / "m.npz")
    again = MultilinearModel.load(tmp_path / "m.npz")
    np.testing.assert_allclose(again.face(again.identity_rows[1], again.expression_rows[2]), T[:, 1, 2], atol=1e-3)
    # a training person's identity is found again from three of their faces
    w = model.fit_identity(T[:, 2, [0, 1, 3]].T, [0, 1, 3], ridge=1e-9)
    np.testing.assert_allclose(model.face(w, model.expression_rows[4]), T[:, 2, 4], atol=1e-5)


def _people_like(d=300, p=14, E=12, seed=3):
    """Neutral + expression displacement scaled per person + a low-rank interaction (known answer)."""
    rng = np.random.default_rng(seed)
    neutral = 100 + 5 * rng.standard_normal((d, p))
    disp = 3 * rng.standard_normal((d, E))
    disp[:, 0] = 0
    scale = 1 + 0.2 * rng.standard_normal(p)
    T = neutral[:, :, None] + scale[None, :, None] * disp[:, None, :]
    return T


def test_average_displacement_is_exact_for_additive_data_and_keeps_known_cells():
    rng = np.random.default_rng(4)
    T = 100 + rng.standard_normal((50, 6, 1)) + rng.standard_normal((50, 1, 5))
    known = rng.random((6, 5)) > 0.4
    known[:, 0] = True
    known[0] = True
    out = average_displacement(T, known)
    np.testing.assert_allclose(out, T, atol=1e-9)
    with pytest.raises(ValueError, match="neutral"):
        average_displacement(T, np.zeros((6, 5), bool))


def test_imputation_recovers_hidden_cells_of_a_low_rank_tensor_better_than_the_baseline():
    T = _people_like()
    rng = np.random.default_rng(5)
    for frac in (0.3,):
        known = rng.random(T.shape[1:]) > frac
        known[:, 0] = True
        hidden = ~known
        filled = impute(T, known, ranks=(2, 1.0), rounds=200)
        base = average_displacement(T, known)
        mean = T.mean(axis=(1, 2))[:, None]
        denom = np.linalg.norm(T[:, hidden] - mean)
        err = np.linalg.norm(filled[:, hidden] - T[:, hidden]) / denom
        err_base = np.linalg.norm(base[:, hidden] - T[:, hidden]) / denom
        np.testing.assert_array_equal(filled[:, known], T[:, known])
        # the per-person scale makes the residual rank two in the people mode (scale and the mean of the
        # people who have the expression): the modes learn it, the baseline cannot
        assert err < 0.5 * err_base, (frac, err, err_base)
