"""Products of many small matrices (a body's 6 x 6 block, a contact's 3 x 6 rows), written
as elementwise products and sums.

XLA fuses these with the elementwise work around them, where a ``dot_general`` is a
kernel of its own (on the CPU a thunk to run), and the step made 200 of them for
matrices no larger than 6 x 6.
"""
from __future__ import annotations

import jax
import jax.numpy as jnp


def mv(a: jax.Array, x: jax.Array) -> jax.Array:
    """a @ x over the leading axes: (..., i, j), (..., j) -> (..., i)."""
    return jnp.sum(a * x[..., None, :], -1)


def vm(x: jax.Array, a: jax.Array) -> jax.Array:
    """x @ a over the leading axes: (..., i), (..., i, j) -> (..., j)."""
    return jnp.sum(x[..., :, None] * a, -2)


def mm(a: jax.Array, b: jax.Array) -> jax.Array:
    """a @ b over the leading axes: (..., i, j), (..., j, k) -> (..., i, k)."""
    return jnp.sum(a[..., :, :, None] * b[..., None, :, :], -2)


def quad(a: jax.Array, m: jax.Array, b: jax.Array) -> jax.Array:
    """diag(a m b^T) over the leading axes: (..., i, j), (..., j, k), (..., i, k) -> (..., i)."""
    return jnp.sum(mm(a, m) * b, -1)
