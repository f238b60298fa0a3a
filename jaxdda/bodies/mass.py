"""Mass, effective stiffness and loads per body, on each body's active dof subspace."""
from __future__ import annotations

import jax
import jax.numpy as jnp

from jaxdda.types import NDOF, Model, Params


def mass_matrix(model: Model, params: Params) -> jax.Array:
    """Consistent mass matrix per body (N, 6, 6): integral of rho T^T T dA (Appendix A.5).

    For a rigid body about its centroid it is diag(m, m, I) on the first three slots.
    """
    m = params.density * model.area
    inertia = params.density * model.polar_moment
    zero = jnp.zeros_like(m)
    diag = jnp.stack([m, m, inertia, zero, zero, zero], -1)
    return diag[..., :, None] * jnp.eye(NDOF)


def inverse_on_subspace(a: jax.Array, projector: jax.Array) -> jax.Array:
    """P (P A P + I - P)^-1 P: the inverse of A restricted to range(P), zero elsewhere.

    A fixed body has P = 0 and so zero flexibility.
    """
    eye = jnp.eye(a.shape[-1])
    reg = projector @ a @ projector + eye - projector
    return projector @ jnp.linalg.inv(reg) @ projector


def external_load(model: Model, params: Params) -> jax.Array:
    """Generalised external load per body (N, 6): the body force (gravity) on u0, v0."""
    m = params.density * model.area * model.gravity_scale
    load = jnp.zeros((model.n_bodies, NDOF))
    return load.at[:, 0].set(m * params.gravity[0]).at[:, 1].set(m * params.gravity[1])
