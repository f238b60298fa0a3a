"""Time integration: Newmark (gamma = 1, beta = 1/2; eq. 8) with resolved impacts.

Per body, K_eff = K + 2 M / dt^2 and f_eff = f + 2 M v / dt, so the displacement of a
step is d = K_eff^-1 (f_eff + C p) (eqs. 20-24) and the end velocity is v+ = 2 d / dt - v.

Newmark alone turns an impact whose gap g0 > 0 closes inside the step into
v+ = 2 g0 / dt - v- (not -v-). We therefore resolve impacts first, at velocity level
(Newton's law v+_n = -e v-_n at the moment of impact t*), and place the impulse at t*:
the body moves with its old velocity until t* and its new one after, which is the
exact event-driven path for isolated impacts (see docs/design.md). For e = 1 and one
frictionless contact this position is the paper's "double contact displacement" (eq. 46).
"""
from __future__ import annotations

import jax
import jax.numpy as jnp


def matvec(blocks: jax.Array, x: jax.Array) -> jax.Array:
    """Per-body (N, 6, 6) @ (N, 6)."""
    return jnp.einsum("nij,nj->ni", blocks, x)


def free_displacement(k_inv: jax.Array, mass: jax.Array, load: jax.Array, velocity: jax.Array,
                      dt: jax.Array) -> jax.Array:
    """d_f = K_eff^-1 (f + 2 M v / dt): the step's displacement without contact (eq. 23)."""
    return matvec(k_inv, load + 2.0 * matvec(mass, velocity) / dt)


def newmark_velocity(d: jax.Array, velocity: jax.Array, dt: jax.Array, projector: jax.Array) -> jax.Array:
    """v+ = 2 d / dt - v (gamma = 1, beta = 1/2), on the active dof subspace."""
    return matvec(projector, 2.0 * d / dt - velocity)


# Impacts closer than SIMULTANEITY * dt are one impact. Corners of a rigid body that meet
# a wall together must be resolved together (Newton's law for one of them alone spins the
# body): when their common impact falls on a step boundary, round-off would otherwise
# split them between two steps, and inside a step it would apply their impulses at
# instants a few ulps apart, which turns the block by round-off that later steps amplify.
SIMULTANEITY = 1e-6


def impact_time(gap: jax.Array, vn: jax.Array, an: jax.Array, dt: jax.Array):
    """Earliest t >= 0 with gap + vn t + an t^2 / 2 = 0 (clipped to dt), and whether it
    falls within the step (up to dt * (1 + SIMULTANEITY)).

    Closed contacts (gap <= 0) hit at t = 0. Uses the cancellation-free root 2 g / (-v + sqrt(.)).
    """
    disc = vn * vn - 2.0 * an * gap
    denom = -vn + jnp.where(disc > 0, jnp.sqrt(jnp.where(disc > 0, disc, 1.0)), 0.0)  # no NaN gradient at 0
    root_ok = (disc >= 0) & (denom > 0)
    t = jnp.where(root_ok, 2.0 * gap / jnp.where(root_ok, denom, 1.0), jnp.inf)
    t = jnp.where(gap <= 0, 0.0, t)
    return jnp.minimum(t, dt), t <= dt * (1.0 + SIMULTANEITY)


def common_impact_time(t_hit: jax.Array, struck: jax.Array, a: jax.Array, b: jax.Array, n_bodies: int,
                       dt: jax.Array) -> jax.Array:
    """Impact times with those within SIMULTANEITY * dt after the first impact of either
    body moved onto it (one impact, e.g. two corners meeting a wall), others unchanged."""
    t = jnp.where(struck, t_hit, jnp.inf)
    first = jnp.minimum(jax.ops.segment_min(t, a, n_bodies), jax.ops.segment_min(t, b, n_bodies))
    near = jnp.minimum(first[a], first[b])
    return jnp.where(struck & (t_hit - near <= SIMULTANEITY * dt), near, t_hit)
