"""Stage "predict": the step's smooth part (docs/design.md, "The step"): the free motion
under the loads and the forces that still act, each contact's impact time on it, the
impact clusters and the isolated pairs (exact events)."""
from __future__ import annotations

from typing import NamedTuple

import jax
import jax.numpy as jnp

from jaxdda.contact.kinematics import apply_jacobian, gap_change_at
from jaxdda.integrate import exact_impact_time, free_displacement
from jaxdda.step import frame as frame_stage
from jaxdda.step.frame import ContactFrame
from jaxdda.step.impacts import cluster_labels
from jaxdda.step.operators import Operators, respond
from jaxdda.types import Model, Params, State


class Prediction(NamedTuple):
    """The free motion and which contacts strike, when."""

    accel: jax.Array  # (N, 6) the free acceleration (loads and prior forces)
    t_row: jax.Array  # (C,) the instant each contact takes part in the impacts at
    t_jump: jax.Array  # (C,) its cluster's first t*: the instant its velocities jump at, unless held
    cluster: jax.Array  # (C,) its impact cluster's label (``cluster_labels``)
    approach: jax.Array  # (C,) a sustained contact's approach speed at the start, max(-v_n, 0)
    isolated: jax.Array  # (C,) bool: a contact of an isolated pair (exact event)
    engaged: jax.Array  # (C,) bool: loaded, cemented, closed, or closing on the free path
    loaded: jax.Array  # (C,) bool: carried force last step, or cemented, and not opening
    p_prior: jax.Array  # (C, 3) last step's forces that still act (not on opening contacts)
    push0: jax.Array  # (N, 6) their displacement over the step, K^-1 J^T p_prior


def free_path(ops: Operators, c, t: jax.Array, side: int, accel: jax.Array):
    """Each contact's side's free motion (shift, turn, strain) and velocity at time t (C,)."""
    body = c.a if side == 0 else c.b
    u = ops.vel[body] * t[:, None] + 0.5 * accel[body] * (t ** 2)[:, None]
    return (u[:, :2], u[:, 2], u[:, 3:]), ops.vel[body] + accel[body] * t[:, None]


def loose_bodies(model: Model) -> jax.Array:
    """Per body: rigid-body mobility alone (no stiffness, no dof group, not pinned)."""
    n = model.n_bodies
    loose = ~model.fixed
    members = model.group_members.reshape(-1)
    loose = loose.at[jnp.where(members >= 0, members, n)].set(False, mode="drop")
    return loose.at[model.pin_body].set(False, mode="drop")


def predict(model: Model, state: State, params: Params, ops: Operators, frame: ContactFrame) -> Prediction:
    """Impact times on the predicted path (exact gap, ``exact_impact_time``; the loads and
    last step's forces that still act) and the impact clusters (bodies joined by their
    loaded, closed or closing contacts): a cluster's contacts are taken at its first
    impact t* (0 if none strikes: Moreau's impact of its closed contacts)."""
    dt = params.dt
    c, gap0, jac = frame.contacts, frame.gap0, frame.jac
    d_free = free_displacement(ops.k_inv, ops.mass, ops.load, ops.vel, dt)
    v_rel = apply_jacobian(jac, c, ops.vel)
    # Signorini's law at velocity level: a contact that separates at the start (v_n dt > d0)
    # and stays open on the free path carries nothing from t = 0 on, whatever it carried.
    gap_free = gap0 + frame_stage.gap_change_by(model, state, c, d_free)
    opening = c.valid & (v_rel[:, 0] * dt > params.margin) & (gap_free > params.margin) & ~frame.cemented
    p_prior = jnp.where(opening[:, None], 0.0, frame.p0)
    push0 = respond(ops.k_inv, jac, c, p_prior)  # their displacement over the step
    accel = 2.0 * (d_free + push0 - ops.vel * dt) / dt ** 2
    a_rel = apply_jacobian(jac, c, accel)

    def gap_on_path(t):
        return gap0 + gap_change_at(c, state.centroid, state.rotation, free_path(ops, c, t, 0, accel)[0],
                                    free_path(ops, c, t, 1, accel)[0])

    t_own, hits, rate = exact_impact_time(gap0, v_rel[:, 0], a_rel[:, 0], dt, frame.touch, gap_on_path,
                                          model.options.impact_refits)
    live = c.valid & ~opening
    loaded = live & ((frame.p0[:, 0] > 0) | frame.cemented)
    engaged = live & (loaded | hits | (gap0 <= params.margin))
    # A cluster's impact: the first contact that closes approaching (read on the exact path:
    # a touching contact that does not approach strikes nothing).
    striking = engaged & hits & ~loaded & (rate < -frame.touch / dt)
    t_row, t_jump, cluster = impact_instants(model, c, engaged, loaded, striking, t_own,
                                             model.options.impact_instants)
    return Prediction(accel=accel, t_row=t_row, t_jump=t_jump, cluster=cluster,
                      approach=jnp.where(loaded, jnp.maximum(-v_rel[:, 0], 0.0), 0.0),
                      isolated=isolated_pairs(model, c, engaged, loaded),
                      engaged=engaged, loaded=loaded, p_prior=p_prior, push0=push0)


def impact_instants(model: Model, c, engaged: jax.Array, loaded: jax.Array, striking: jax.Array,
                    t_own: jax.Array, at_instants: bool = True) -> tuple[jax.Array, jax.Array, jax.Array]:
    """Per contact: the instant its impact rows are read at; its cluster's impact instant
    t*, the first of its ``striking`` contacts (0 where none strikes), at which its
    velocities jump (unless ``jump.held_clusters``); and its cluster's label. The rows are
    read at t*, or at 0 for a cluster that carries a sustained force (Moreau: its
    velocities at t* are not known without the forces before it, so the jump is computed
    from the step's start, and still takes effect at t*: docs/design.md, "Clock").
    Without ``at_instants`` (static) every cluster jumps at 0."""
    n = model.n_bodies
    label = cluster_labels(engaged, c.a, c.b, model.fixed)
    first = jax.ops.segment_min(jnp.where(striking, t_own, jnp.inf), label, n + 1)[label]
    if not at_instants:  # Moreau: every impact at the step's start
        first = jnp.where(jnp.isfinite(first), 0.0, first)
    carrying = jax.ops.segment_max(loaded.astype(jnp.int32), label, n + 1)[label] > 0
    t_jump = jnp.where(engaged & jnp.isfinite(first), first, 0.0)
    return jnp.where(carrying, 0.0, t_jump), t_jump, label


def isolated_pairs(model: Model, c, engaged: jax.Array, loaded: jax.Array) -> jax.Array:
    """Per contact: one of an isolated pair, two units (a loose rigid body, or a mesh's
    elements together; or one of them fixed) whose every engaged contact joins them to
    each other, none loaded: its impact is an exact event."""
    n = model.n_bodies
    units = 2 * n
    unit = jnp.where(model.mesh >= 0, n + model.mesh, jnp.arange(n))
    ua, ub = unit[c.a], unit[c.b]
    pair = jnp.minimum(ua, ub) * units + jnp.maximum(ua, ub)

    def least(x):
        return jnp.minimum(jax.ops.segment_min(x, ua, units), jax.ops.segment_min(x, ub, units))

    def most(x):
        return jnp.maximum(jax.ops.segment_max(x, ua, units), jax.ops.segment_max(x, ub, units))

    lo, hi = least(jnp.where(engaged, pair, units * units)), most(jnp.where(engaged, pair, -1))
    held = most((engaged & loaded).astype(jnp.int32)) > 0
    fixed_u = jax.ops.segment_max(model.fixed.astype(jnp.int32), unit, units) > 0
    mobile = (jax.ops.segment_min(loose_bodies(model).astype(jnp.int32), unit, units) > 0) | (jnp.arange(units) >= n)
    alone = fixed_u | ((lo == hi) & ~held & mobile)
    return engaged & ~loaded & alone[ua] & alone[ub] & ~(fixed_u[ua] & fixed_u[ub])
