"""Time integration: Newmark (gamma = 1, beta = 1/2; eq. 8) with resolved impacts.

Per body, K_eff = K + 2 M / dt^2 and f_eff = f + 2 M v / dt, so the displacement of a
step is d = K_eff^-1 (f_eff + C p) (eqs. 20-24) and the end velocity is v+ = 2 d / dt - v.

Newmark alone turns an impact whose gap g0 > 0 closes inside the step into
v+ = 2 g0 / dt - v- (not -v-). The step therefore resolves impacts first, at velocity level
(step.impacts), at the impact time t* found here, and places the impulse at t*: the body moves
with its old velocity until t* and its new one after, the exact event-driven path for an
isolated impact (docs/design.md, "The scheme"). For e = 1 and one frictionless contact this
position is the paper's "double contact displacement" (eq. 46).
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


# The impact-time refits have settled once no root moves by more than this many ulp of dt.
SETTLED_ULP = 8


def exact_impact_time(gap: jax.Array, vn: jax.Array, an: jax.Array, dt: jax.Array, touch: jax.Array, gap_at,
                      passes: int):
    """``impact_time`` on the exact gap along the predicted path: ``gap_at(t)`` (C,) is the
    gap with each contact's bodies moved to time t (C,) of their free motion. Returns the
    time, whether it falls in the step, and the exact gap's rate there.

    The linear model gap + vn t + an t^2 / 2 misses the gap's curvature: a disk sliding
    along the inside of a ring closes its gap at second order in its tangential motion
    (|v_t|^2 t^2 / 2 rho), which the normal velocity of the start frame does not see, and a
    turning corner does the same. Each pass fits the quadratic's curvature to the exact
    gap at the current root (an + 2 (gap_at(t) - linear(t)) / t^2) and solves it again;
    from the end of the step where the linear model finds no root, so an impact it misses
    is found. ``passes`` (static, ``StepOptions.impact_refits``) refits at most, fewer once
    they settle (a pass that moves no root beyond round-off, ``SETTLED_ULP``); 0: the start
    frame's quadratic alone. A last pass reads the rate at the root.

    The passes run on stopped values; the root is differentiated implicitly,
    dt* = -dg / (dg/dt) at g(t*) = 0 (``_root_shift``), so derivatives see no loop.
    """
    stopped = jax.lax.stop_gradient
    gap0, vn0, an0, dt0, touch0 = stopped((gap, vn, an, dt, touch))

    def refit(carry):  # one pass (a loop, not unrolled: gap_at is a large part of the step's code)
        i, t_hits, _, last, _ = carry
        # A root near 0 takes the curvature of the whole step; the last pass reads the root.
        at = jnp.where(last, t_hits[0], jnp.where(t_hits[0] > 1e-3 * dt0, t_hits[0], dt0))
        value, rate = stopped(jax.jvp(gap_at, (at,), (jnp.ones_like(at),)))
        fit_at = jnp.where(last, dt0, at)
        curvature = an0 + 2.0 * (value - (gap0 + vn0 * fit_at + 0.5 * an0 * fit_at * fit_at)) / (fit_at * fit_at)
        fitted = impact_time(gap0, vn0, curvature, dt0, touch0)
        # Settled: no root moved by more than round-off (a few ulp of the step), none came or
        # went. (Bit-equality never settles where the last pass flips an ulp, and under vmap
        # one such scenario runs every pass for the batch.)
        moved = ~(jnp.abs(fitted[0] - t_hits[0]) <= SETTLED_ULP * jnp.finfo(dt0.dtype).eps * dt0)
        settled = ~jnp.any(moved) & jnp.all(fitted[1] == t_hits[1])
        t_hits = jax.tree.map(lambda old, new: jnp.where(last, old, new), t_hits, fitted)
        return i + 1, t_hits, rate, settled | (i + 1 >= passes), last

    first = impact_time(gap0, vn0, an0, dt0, touch0)
    start = (jnp.int32(0), first, jnp.zeros_like(gap), jnp.asarray(passes == 0), jnp.asarray(False))
    _, (t, hits), rate, _, _ = jax.lax.while_loop(lambda carry: ~carry[4], refit, start)
    root = hits & (t > 0) & (t < dt0) & (rate < 0)  # a crossing inside the step (not a touch, not the clip)
    shift = _root_shift(gap_at(t), jnp.where(root, rate, -1.0))
    return jnp.where(t >= dt0, dt, t + jnp.where(root, shift, 0.0)), hits, rate


@jax.custom_jvp
def _root_shift(value: jax.Array, rate: jax.Array) -> jax.Array:
    """Zero, with the derivative -d value / rate: added to a root t* of g (value = g(t*),
    rate = dg/dt there) it carries the implicit derivative of the root."""
    return jnp.zeros_like(value)


@_root_shift.defjvp
def _root_shift_jvp(primals, tangents):
    value, rate = primals
    return jnp.zeros_like(value), -tangents[0] / rate


def mesh_clock(mesh: jax.Array, clock: jax.Array) -> jax.Array:
    """The elements of a meshed block are one body: they all change velocity at the latest
    clock among them (the time of the impact on the block), so the impact shift is a
    field of the nodes and the mesh stays conforming."""
    n = clock.shape[0]
    seg = jnp.where(mesh >= 0, mesh, n)
    latest = jax.ops.segment_max(clock, seg, n + 1)
    return jnp.where(mesh >= 0, latest[seg], clock)
