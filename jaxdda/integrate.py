"""Time integration: Newmark (gamma = 1, beta = 1/2; eq. 8) with resolved impacts.

Per body, K_eff = K + 2 M / dt^2 and f_eff = f + 2 M v / dt, so the displacement of a
step is d = K_eff^-1 (f_eff + C p) (eqs. 20-24) and the end velocity is v+ = 2 d / dt - v.

Newmark alone turns an impact whose gap g0 > 0 closes inside the step into
v+ = 2 g0 / dt - v- (not -v-). We therefore resolve impacts first, at velocity level
(restitution at the moment of impact t*: Poisson's law, step.resolve._poisson_impact), and place
the impulse at t*: the body moves with its old velocity until t* and its new one after, which is the
exact event-driven path for isolated impacts (see docs/design.md). For e = 1 and one
frictionless contact this position is the paper's "double contact displacement" (eq. 46).
"""
from __future__ import annotations

import jax
import jax.numpy as jnp

from jaxdda import groups
from jaxdda.groups import Flexibility


def matvec(blocks: jax.Array, x: jax.Array) -> jax.Array:
    """Per-body (N, 6, 6) @ (N, 6)."""
    return jnp.einsum("nij,nj->ni", blocks, x)


def free_displacement(k_inv: Flexibility, mass: jax.Array, load: jax.Array, velocity: jax.Array,
                      dt: jax.Array) -> jax.Array:
    """d_f = K_eff^-1 (f + 2 M v / dt): the step's displacement without contact (eqs. 23, 110)."""
    return groups.apply(k_inv, load + 2.0 * matvec(mass, velocity) / dt)


def newmark_velocity(d: jax.Array, velocity: jax.Array, dt: jax.Array, projector: jax.Array) -> jax.Array:
    """v+ = 2 d / dt - v (gamma = 1, beta = 1/2), on the active dof subspace."""
    return matvec(projector, 2.0 * d / dt - velocity)


# Impacts closer than SIMULTANEITY * dt are one impact. Corners of a rigid body that meet
# a wall together must be resolved together (Newton's law for one of them alone spins the
# body): when their common impact falls on a step boundary, round-off would otherwise
# split them between two steps, and inside a step it would apply their impulses at
# instants a few ulps apart, which turns the block by round-off that later steps amplify.
SIMULTANEITY = 1e-6


def impact_time(gap: jax.Array, vn: jax.Array, an: jax.Array, dt: jax.Array, touch: jax.Array):
    """Earliest t >= 0 with gap + vn t + an t^2 / 2 = 0 (clipped to dt), and whether it
    falls within the step (up to dt * (1 + SIMULTANEITY)).

    Closed contacts (gap <= ``touch``, the round-off of the gap) hit at t = 0: a block
    placed on a slope touches it, it does not fall 1e-15 m onto it. Uses the
    cancellation-free root 2 g / (-v + sqrt(.)).
    """
    disc = vn * vn - 2.0 * an * gap
    denom = -vn + jnp.where(disc > 0, jnp.sqrt(jnp.where(disc > 0, disc, 1.0)), 0.0)  # no NaN gradient at 0
    root_ok = (disc >= 0) & (denom > 0)
    t = jnp.where(root_ok, 2.0 * gap / jnp.where(root_ok, denom, 1.0), jnp.inf)
    t = jnp.where(gap <= touch, 0.0, t)
    return jnp.minimum(t, dt), t <= dt * (1.0 + SIMULTANEITY)


# Passes of exact_impact_time's root refinement, each fitting the gap's curvature anew: six
# bring a disk crossing a ring's hole (test_physics) to 1e-12 m/s, four left 9e-10.
IMPACT_PASSES = 6


def exact_impact_time(gap: jax.Array, vn: jax.Array, an: jax.Array, dt: jax.Array, touch: jax.Array, gap_at):
    """``impact_time`` on the exact gap along the predicted path: ``gap_at(t)`` (C,) is the
    gap with each contact's bodies moved to time t (C,) of their free motion.

    The linear model gap + vn t + an t^2 / 2 misses the gap's curvature: a disk sliding
    along the inside of a ring closes its gap at second order in its tangential motion
    (|v_t|^2 t^2 / 2 rho), which the normal velocity of the start frame does not see, and a
    turning corner does the same. Each pass fits the quadratic's curvature to the exact
    gap at the current root (an + 2 (gap_at(t) - linear(t)) / t^2) and solves it again;
    from the end of the step where the linear model finds no root, so an impact it misses
    is found.
    """
    def refit(_, t_hits):  # one pass (a loop, not unrolled: gap_at is a large part of the step's code)
        at = jnp.where(t_hits[0] > 1e-3 * dt, t_hits[0], dt)  # a root near 0 takes the curvature of the whole step
        linear = gap + vn * at + 0.5 * an * at * at
        return impact_time(gap, vn, an + 2.0 * (gap_at(at) - linear) / (at * at), dt, touch)

    return jax.lax.fori_loop(0, IMPACT_PASSES, refit, impact_time(gap, vn, an, dt, touch))


def common_impact_time(t_hit: jax.Array, struck: jax.Array, a: jax.Array, b: jax.Array, n_bodies: int,
                       dt: jax.Array) -> jax.Array:
    """Impact times with those within SIMULTANEITY * dt after the first impact of either
    body moved onto it (one impact, e.g. two corners meeting a wall), others unchanged."""
    t = jnp.where(struck, t_hit, jnp.inf)
    first = jnp.minimum(jax.ops.segment_min(t, a, n_bodies), jax.ops.segment_min(t, b, n_bodies))
    near = jnp.minimum(first[a], first[b])
    return jnp.where(struck & (t_hit - near <= SIMULTANEITY * dt), near, t_hit)


def _impact_source(t_hit: jax.Array, struck: jax.Array, carrying: jax.Array, a: jax.Array, b: jax.Array,
                   fixed: jax.Array) -> jax.Array:
    """Per body (N,): the struck contact whose impact reaches it first (-1: none).

    A body struck itself takes its first impact. One that is not struck takes the first
    impact that reaches it through ``carrying`` contacts between free bodies (a resting
    stack under a falling body, a free chain pushed at one end): the struck bodies' times
    spread along them, the earliest winning; fixed bodies pass nothing on. Discrete (which
    impact reaches which body): no derivative flows through it.
    """
    n = fixed.shape[0]
    idx = jnp.arange(t_hit.shape[0])
    t = jnp.where(struck, jax.lax.stop_gradient(t_hit), jnp.inf)
    first = jnp.minimum(jax.ops.segment_min(t, a, n), jax.ops.segment_min(t, b, n))

    def source(offer, body):  # per body: the contact whose time it takes (-1: none)
        return jax.ops.segment_max(jnp.where(offer & (t == first[body]), idx, -1), body, n)

    src = jnp.maximum(source(struck, a), source(struck, b))
    is_struck = src >= 0
    live = carrying & ~fixed[a] & ~fixed[b]

    def spread(carry):
        clock, src, _ = carry
        to_a, to_b = jnp.where(live, clock[b], jnp.inf), jnp.where(live, clock[a], jnp.inf)
        best = jnp.minimum(jax.ops.segment_min(to_a, a, n), jax.ops.segment_min(to_b, b, n))
        take = ~is_struck & (best < clock)
        via_a = jax.ops.segment_max(jnp.where(live & (to_a == best[a]), src[b], -1), a, n)
        via_b = jax.ops.segment_max(jnp.where(live & (to_b == best[b]), src[a], -1), b, n)
        return (jnp.where(take, best, clock), jnp.where(take, jnp.maximum(via_a, via_b), src), jnp.any(take))

    _, src, _ = jax.lax.while_loop(lambda c: c[2], spread, (jnp.where(is_struck, first, jnp.inf), src, True))
    return src


def strike_time(t_hit: jax.Array, striking: jax.Array, carrying: jax.Array, a: jax.Array, b: jax.Array,
                fixed: jax.Array) -> jax.Array:
    """Per contact (C,): the earliest impact time (``t_hit`` of ``striking`` contacts) that
    reaches either of its free bodies, directly or through ``carrying`` contacts
    (``_impact_source``); 0 where none does. A contact that strikes nothing itself (a
    resting or touching one) takes part in the impacts at that instant, also where the
    impact reaches it through other contacts (timed at the step's start, it gained energy
    in fuzz seed 7168)."""
    src = jnp.where(fixed, -1, _impact_source(t_hit, striking, carrying, a, b, fixed))
    first = jnp.where(src >= 0, t_hit[jnp.maximum(src, 0)], jnp.inf)
    at = jnp.minimum(first[a], first[b])
    return jnp.where(jnp.isfinite(at), at, 0.0)


def impact_clock(t_hit: jax.Array, struck: jax.Array, carrying: jax.Array, a: jax.Array, b: jax.Array,
                 fixed: jax.Array) -> jax.Array:
    """Per body (N,): the time in the step at which its velocity changes in the impact
    stage, so that it moves with its old velocity until then and its new one after: the
    time of the first impact that reaches it (``_impact_source``, through the ``carrying``
    contacts), 0 for others.

    Per body, not per contact: a stack under a falling disk takes the disk's impulse and
    the floor's equal and opposite one at the same instant, so its net velocity change
    (zero) is shifted by nothing. The spreading is discrete (which impact reaches which
    body); the clock itself is the differentiable t_hit of that impact.
    """
    src = _impact_source(t_hit, struck, carrying, a, b, fixed)
    return jnp.where(src >= 0, t_hit[jnp.maximum(src, 0)], 0.0)


def mesh_clock(mesh: jax.Array, clock: jax.Array) -> jax.Array:
    """The elements of a meshed block are one body: they all change velocity at the latest
    clock among them (the time of the impact on the block), so the impact shift is a
    field of the nodes and the mesh stays conforming."""
    n = clock.shape[0]
    seg = jnp.where(mesh >= 0, mesh, n)
    latest = jax.ops.segment_max(clock, seg, n + 1)
    return jnp.where(mesh >= 0, latest[seg], clock)
