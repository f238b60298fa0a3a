"""Mass, effective stiffness and loads per body, on each body's active dof subspace."""
from __future__ import annotations

import jax
import jax.numpy as jnp

from jaxdda.bodies.shape import shape_function, to_world
from jaxdda.bodies.elastic import consistent_mass, current_moments
from jaxdda.types import NDOF, Model, Params, State


def mass_matrix(model: Model, params: Params, state: State) -> jax.Array:
    """Consistent mass matrix per body (N, 6, 6) in its current shape: integral of
    rho T^T T dA (Appendix A.5). For a rigid body it is diag(m, m, I) on the first three slots."""
    moments = current_moments(model.second_moment, state.rotation, state.stretch)
    return consistent_mass(params.density, model.area, moments)


def spd_inverse(a: jax.Array) -> jax.Array:
    """Inverse of a batch (..., n, n) of small symmetric positive definite matrices by n
    Gauss-Jordan sweeps, without pivoting (stable for SPD: every pivot is a positive Schur
    complement).

    Plain array code, not LAPACK: jaxlib's batched LAPACK kernels split their batch over
    XLA:CPU's intra-op thread pool and wait for it, so two of them running side by side on
    a 2-thread pool deadlock (docs/design.md, "Monte Carlo and devices")."""
    n = a.shape[-1]

    def sweep(k, a):
        pivot = jax.lax.dynamic_index_in_dim(jax.lax.dynamic_index_in_dim(a, k, -2, False), k, -1, True)
        row = jax.lax.dynamic_index_in_dim(a, k, -2, False) / pivot  # row k of the eliminated matrix
        col = jax.lax.dynamic_index_in_dim(a, k, -1, False)
        a = a - col[..., :, None] * row[..., None, :]
        at_k = jnp.arange(n) == k
        a = jnp.where(at_k[:, None], row[..., None, :], a)
        return jnp.where(at_k, jnp.where(at_k[:, None], 1.0 / pivot[..., None], -col[..., :, None] / pivot[..., None]), a)

    if n <= 12:  # the 6x6 per-body inverses: unrolled
        for k in range(n):
            a = sweep(k, a)
        return a
    return jax.lax.fori_loop(0, n, sweep, a)  # a group's R x R matrix: one traced sweep


def inverse_on_subspace(a: jax.Array, projector: jax.Array) -> jax.Array:
    """P (P A P + I - P)^-1 P: the inverse of A restricted to range(P), zero elsewhere.

    A fixed body has P = 0 and so zero flexibility.
    """
    eye = jnp.eye(a.shape[-1])
    reg = projector @ a @ projector + eye - projector
    return projector @ spd_inverse(reg) @ projector


def external_load(model: Model, params: Params, centroid: jax.Array, rotation: jax.Array,
                  time: jax.Array) -> jax.Array:
    """Generalised external load per body (N, 6) at ``time``: the body force (gravity) on
    u0, v0, plus each point load F(t) = F0 + rate t + h(t) as T(x)^T F at its material
    point x in the given configuration (eqs. 2, 7, 13); h interpolates the load's time
    history linearly and holds its end values outside it."""
    m = params.density * model.area * model.gravity_scale
    load = jnp.zeros((model.n_bodies, NDOF))
    load = load.at[:, 0].set(m * params.gravity[0]).at[:, 1].set(m * params.gravity[1])
    body = model.load_body
    x = to_world(centroid[body], rotation[body], model.load_point)
    history = jax.vmap(jax.vmap(jnp.interp, (None, None, 1)), (None, 0, 0))(time, model.load_times, params.load_history)
    force = params.load_force + params.load_rate * time + history
    generalised = jnp.einsum("lij,li->lj", shape_function(x, centroid[body]), force)
    return load + jax.ops.segment_sum(generalised, body, model.n_bodies)
