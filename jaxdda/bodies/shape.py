"""Shape functions and poses of bodies (paper eqs. 3, 7, 16)."""
from __future__ import annotations

import jax
import jax.numpy as jnp


def rotation_matrix(theta: jax.Array) -> jax.Array:
    """Counter-clockwise rotation matrices, shape ``theta.shape + (2, 2)``."""
    c, s = jnp.cos(theta), jnp.sin(theta)
    return jnp.stack([jnp.stack([c, -s], -1), jnp.stack([s, c], -1)], -2)


def to_world(centroid: jax.Array, theta: jax.Array, local: jax.Array) -> jax.Array:
    """World coordinates of body-fixed points ``local`` (..., 2) of a body at (centroid, theta).

    For a rigid body this is exactly the post-adjusted displacement of eq. 16: a finite
    rotation about the centroid plus a translation, so no false volume growth.
    """
    return centroid + jnp.einsum("...ij,...j->...i", rotation_matrix(theta), local)


def shape_function(point: jax.Array, centroid: jax.Array) -> jax.Array:
    """Interpolation matrix T(x, y) of eq. 7 over the 6 dof slots, shape (..., 2, 6).

    Rigid bodies use only the first three columns (eq. 3): their other dofs are
    projected out, so one matrix serves every kind of body.
    """
    dx = point[..., 0] - centroid[..., 0]
    dy = point[..., 1] - centroid[..., 1]
    one, zero = jnp.ones_like(dx), jnp.zeros_like(dx)
    row_x = jnp.stack([one, zero, -dy, dx, zero, dy / 2], -1)
    row_y = jnp.stack([zero, one, dx, zero, dy, dx / 2], -1)
    return jnp.stack([row_x, row_y], -2)
