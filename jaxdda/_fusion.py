"""A fusion boundary for XLA:CPU: ``materialize(x)`` is x, computed once into memory.

XLA:CPU fuses an elementwise producer into every consumer that reads it, recomputing
it in each: a chain whose values are read several times is duplicated at every read,
and the duplicates compound along the chain (ten steps of ``x = sin(x) + x / (x^2 + 2)``
read three times at the end compile to 75 sines). The step's gap change and the
projection were compiled, and computed in a batched run, up to three times over at each
call site. ``optimization_barrier`` does not stop it (XLA removes the barrier before
fusion); a reduction does, as XLA does not fuse one into its consumers. ``materialize``
reduces over a stacked axis of size two that leaves x exact: max(x, -inf), including -0
and NaN.
"""
from __future__ import annotations

import jax
import jax.numpy as jnp


@jax.custom_jvp
def materialize(x: jax.Array) -> jax.Array:
    """x (floating point), as a value XLA computes once (module docstring)."""
    return jnp.max(jnp.stack([x, jnp.full_like(x, -jnp.inf)]), 0)


@materialize.defjvp
def _materialize_jvp(primals, tangents):
    (x,), (dx,) = primals, tangents
    # The tangent the same way, by a sum (linear, so reverse mode can transpose it).
    return materialize(x), jnp.sum(jnp.stack([dx, jnp.zeros_like(dx)]), 0)
