"""The constraint set's projection (solver/sets.py) on its own: random contacts, half of them
adjoint pairs sharing cohesion and tension budgets, checked against the set's definition
(eqs. 19, 42-45, 63-73) and against JAX's own derivative of the projection."""
from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from jaxdda.solver.sets import ContactSets, linearize, project

C = 12  # contacts: 0-1, 2-3, 4-5 adjoint pairs, the rest alone


def _case(seed: int):
    rng = np.random.default_rng(seed)
    partner = np.full(C, -1)
    for i in range(0, 6, 2):
        partner[i], partner[i + 1] = i + 1, i
    # A pair's budgets are given once per pair, on both contacts (a broken joint next to an
    # intact one: contact 5 keeps no tension budget of its own).
    cohesion, tension = rng.uniform(0, 2, C) * (rng.uniform(size=C) < 0.7), rng.uniform(0, 2, C)
    for i in range(0, 6, 2):
        cohesion[i + 1], tension[i + 1] = cohesion[i], tension[i]
    tension[5] = 0.0
    sets = ContactSets(enabled=jnp.asarray(rng.uniform(size=C) < 0.9), friction=jnp.asarray(rng.uniform(0.1, 1, C)),
                       cohesion=jnp.asarray(cohesion), tension=jnp.asarray(tension),
                       rolling=jnp.asarray(rng.uniform(0, 0.3, C) * (rng.uniform(size=C) < 0.5)),
                       partner=jnp.asarray(partner, jnp.int32))
    scale = jnp.asarray(rng.uniform(0.3, 3.0, (C, 3)))
    y = jnp.asarray(rng.normal(size=(C, 3)) * 3.0)
    return y, scale, sets


SEEDS = range(8)


@pytest.mark.parametrize("seed", SEEDS)
def test_projection_lies_in_the_set_and_is_idempotent(seed):
    y, scale, sets = _case(seed)
    p = np.asarray(project(y, scale, sets) * scale)
    on = np.asarray(sets.enabled)
    assert np.all(p[~on] == 0)
    part, mu, c, t = (np.asarray(a) for a in (sets.partner, sets.friction, sets.cohesion, sets.tension))
    p_n = np.maximum(p[:, 0], 0)
    excess = np.maximum(np.abs(p[:, 1]) - mu * p_n, 0)  # shear beyond friction: cohesion's share
    pull = np.maximum(-p[:, 0], 0)  # tension: the tensile budget's share
    pair = np.where(part >= 0, part, np.arange(C))
    shared = (part >= 0)
    tol = 1e-12 * (1 + np.abs(p).max())
    # A budget is shared where both contacts of the pair have one; a contact without one takes none.
    assert np.all(excess + np.where(shared & (c > 0) & (c[pair] > 0), excess[pair], 0) <= c + tol)
    assert np.all(pull + np.where(shared & (t > 0) & (t[pair] > 0), pull[pair], 0) <= t + tol)
    assert np.all(np.abs(p[:, 2]) <= np.asarray(sets.rolling) * p_n + tol)
    again = project(project(y, scale, sets), scale, sets)
    np.testing.assert_allclose(again, project(y, scale, sets), rtol=0, atol=1e-13)


@pytest.mark.parametrize("seed", SEEDS)
def test_projection_is_symmetric_in_a_pair(seed):
    """Relabelling the contacts relabels the projection (a pair's share does not depend on
    which of its contacts comes first)."""
    y, scale, sets = _case(seed)
    order = np.random.default_rng(seed).permutation(C)
    inverse = np.argsort(order)
    permuted = sets._replace(**{f: getattr(sets, f)[order] for f in ("enabled", "friction", "cohesion", "tension",
                                                                     "rolling")},
                             partner=jnp.where(sets.partner[order] >= 0, inverse[sets.partner[order]], -1))
    np.testing.assert_allclose(project(y[order], scale[order], permuted), project(y, scale, sets)[order], rtol=0,
                               atol=1e-14)


@pytest.mark.parametrize("seed", SEEDS)
def test_linearize_gives_the_projection_and_its_derivative(seed):
    """``linearize``'s explicit 3 x 3 blocks (own row, partner's row) against jax.jvp of
    ``project``, the partners' gather included, along random directions."""
    y, scale, sets = _case(seed)
    value, derivative = linearize(y, scale, sets)
    np.testing.assert_array_equal(value, project(y, scale, sets))
    for k in range(3):
        v = jnp.asarray(np.random.default_rng(100 + k).normal(size=y.shape))
        expected = jax.jvp(lambda a: project(a, scale, sets), (y,), (v,))[1]
        np.testing.assert_allclose(derivative(v), expected, rtol=1e-12, atol=1e-12)
