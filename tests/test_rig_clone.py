"""photomodel.people.rig_clone: a performance moved between two held-out ICT people through their rigs
predicted by the multilinear model, against the mix of B's own shapes by deformation transfer."""

import numpy as np
import pytest

from photomodel.people.dataset import EXPRESSIONS
from photomodel.people.mapping import displacement_copy
from photomodel.people.rig_clone import RigClone

pytestmark = pytest.mark.slow  # the 30 model people are cached after the first run (~5 min of rigs)


def _mixes(rng, frames, k=51):
    W = np.zeros((frames, k))
    for f in range(frames):
        on = rng.choice(k, rng.integers(3, 9), replace=False)
        W[f, on] = rng.uniform(0.2, 1.0, len(on))
    return W


def _person(held, p, shapes):
    names = EXPRESSIONS[1:]
    n = held.neutrals[p]
    return n, {names[s]: n + held.deltas[p, s] for s in shapes}


def test_every_shape_photographed_clones_exactly(people):
    # with all 51 shapes photographed both rigs are the people's own: a mix of A's shapes is the same
    # mix of B's (the truth by construction, whatever the model predicts)
    model, held = people
    W = _mixes(np.random.default_rng(0), 20)
    clone = RigClone.between(model, *_person(held, 0, range(51)), *_person(held, 1, range(51)), held.face_mask)
    frames = held.neutrals[0].ravel() + W @ held.deltas[0].reshape(51, -1)
    truth = held.neutrals[1].ravel() + W @ held.deltas[1].reshape(51, -1)
    # 1e-6 mm: least squares of a full-rank 51-shape rig, float rounding only
    np.testing.assert_allclose(clone(frames), truth, atol=1e-6)
    np.testing.assert_allclose(clone.weights(frames), W, atol=1e-6)


def test_a_few_photographed_shapes_beat_the_displacement_copy(people):
    model, held = people
    rng = np.random.default_rng(1)
    fm = held.face_mask
    errs, copies = [], []
    for a, b in ((0, 1), (1, 2), (2, 3), (3, 0)):
        W = _mixes(rng, 10)
        sa, sb = (np.sort(rng.choice(51, 15, replace=False)) for _ in range(2))
        clone = RigClone.between(model, *_person(held, a, sa), *_person(held, b, sb), fm)
        frames = held.neutrals[a].ravel() + W @ held.deltas[a].reshape(51, -1)
        truth = (held.neutrals[b].ravel() + W @ held.deltas[b].reshape(51, -1)).reshape(10, -1, 3)
        errs.append(np.linalg.norm(clone(frames).reshape(10, -1, 3) - truth, axis=2)[:, fm].mean())
        copy = displacement_copy(frames, held.neutrals[a], held.neutrals[b], fm).reshape(10, -1, 3)
        copies.append(np.linalg.norm(copy - truth, axis=2)[:, fm].mean())
    # measured: 0.118 mm against the copy's 0.229 (0.52 ×) with this 30-person model over these 4 pairs
    # (the benchmark's 100-person model: 0.25–0.28 × over 50 pairs); the bound is the bar (0.7 ×)
    assert np.mean(errs) < 0.7 * np.mean(copies)
