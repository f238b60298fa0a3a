"""``materialize``: a value XLA:CPU computes once, however many kernels read it, and which
is the value itself, in value and derivative."""
import re

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import jaxdda  # noqa: F401  (its XLA flags, as the step compiles with them)
from jaxdda._fusion import materialize

pytestmark = pytest.mark.smoke
STEPS = 10


def _chain(x):
    for _ in range(STEPS):
        x = jnp.sin(x) * 1.1 + x / (x * x + 2.0)
    return x


def test_a_materialized_chain_is_compiled_once_for_all_its_readers():
    def three_readers(x, idx):
        y = materialize(_chain(x))
        return y + 1.0, jnp.sum(y * y), y[idx] * 3.0

    hlo = jax.jit(three_readers).lower(jnp.ones(32), jnp.arange(32)[::-1]).compile().as_text()
    assert len(re.findall(r" sine\(", hlo)) == STEPS


def test_materialize_is_the_identity_in_value_and_derivative():
    x = jnp.array([-0.0, 0.0, 1.5, -2.25e-300, jnp.inf, -jnp.inf, jnp.nan, 1e300])
    out = jax.jit(materialize)(x)
    np.testing.assert_array_equal(np.signbit(out), np.signbit(x))
    np.testing.assert_array_equal(out, x)  # NaN where NaN
    y = jnp.linspace(-1.0, 2.0, 7)
    _, tangent = jax.jvp(materialize, (y,), (jnp.arange(7.0),))
    np.testing.assert_array_equal(tangent, jnp.arange(7.0))
    grad = jax.grad(lambda v: jnp.sum(jnp.sin(materialize(v))))(y)
    np.testing.assert_allclose(grad, jnp.cos(y), rtol=1e-15)
    np.testing.assert_array_equal(jax.vmap(materialize)(jnp.stack([y, -y])), jnp.stack([y, -y]))
