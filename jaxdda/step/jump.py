"""Stage "impacts": the rows of the step's impact solve, and the velocity jump its
compression P1 gives (the impact law, ``impacts.impact_law``), with each body's clock
and the isolated pairs' windows (docs/design.md, "The step")."""
from __future__ import annotations

from typing import NamedTuple

import jax
import jax.numpy as jnp

from jaxdda.contact.kinematics import apply_jacobian, gap_frame_at, jacobians_at
from jaxdda.integrate import mesh_clock
from jaxdda.solver.sets import ContactSets
from jaxdda.step.frame import ContactFrame
from jaxdda.step.impacts import impact_law
from jaxdda.step.operators import Operators, apply_w, respond
from jaxdda.step.predict import Prediction, free_path, loose_bodies
from jaxdda.types import Model, Params, State


class ImpactRows(NamedTuple):
    """The impact solve's rows: each contact in its frame at its instant."""

    jac: jax.Array  # (C, 2, 3, 6)
    normal: jax.Array  # (C, 2)
    v_minus: jax.Array  # (C, 3) relative velocity at the instant, before the impulse
    sets: ContactSets
    struck: jax.Array  # (C,) bool: approaching, not loaded (restitution e)


def impact_rows(model: Model, state: State, params: Params, ops: Operators, frame: ContactFrame,
                pred: Prediction) -> ImpactRows:
    """Each engaged contact at its cluster's instant (frame, velocity: ``gap_frame_at``).
    Struck (with restitution) where it approaches, carried no force (a loaded or cemented
    contact is sustained: it does not bounce) and is closed then; the others are
    constraints, v+_n >= 0 (a later impact of the cluster, such as a block's second corner,
    is held from approaching at t*: first order)."""
    c = frame.contacts
    (move_a, vel_a), (move_b, vel_b) = (free_path(ops, c, pred.t_row, side, pred.accel) for side in (0, 1))
    pose_a = (state.centroid[c.a] + move_a[0], state.rotation[c.a] + move_a[1])
    pose_b = (state.centroid[c.b] + move_b[0], state.rotation[c.b] + move_b[1])
    gap_hit, normal_hit, point_hit = gap_frame_at(c, pose_a, pose_b)
    jac_hit = jacobians_at(c, normal_hit, point_hit, gap_hit, pose_a[0], pose_b[0])
    v_hit = jnp.einsum("cij,cj->ci", jac_hit[:, 0], vel_a) + jnp.einsum("cij,cj->ci", jac_hit[:, 1], vel_b)
    taking = pred.engaged
    struck = taking & ~pred.loaded & (v_hit[:, 0] < 0) & ((gap_hit <= params.margin) | (pred.t_row == 0))
    zero = jnp.zeros_like(frame.gap0)
    sets = frame.sets._replace(enabled=taking, cohesion=zero, tension=zero,
                               opposes=jnp.zeros(zero.shape + (2,), zero.dtype))
    return ImpactRows(jac=jac_hit, normal=normal_hit, v_minus=v_hit, sets=sets, struck=struck)


class Window(NamedTuple):
    """An isolated pair's contacts after its impact at t* (first half of the step): their
    force acts over h = dt - t* (docs/design.md, "Windows")."""

    windowed: jax.Array  # (C,) bool
    t_win: jax.Array  # (C,) its t*
    rest: jax.Array  # (C,) h (dt elsewhere)
    u_clock: jax.Array  # (N, 6) each body's motion until its window
    v_clock: jax.Array  # (N, 6) its velocity then, after the impulse


def window(model: Model, params: Params, ops: Operators, c, pred: Prediction, moved: jax.Array,
           v_star: jax.Array) -> Window:
    """The windows of the isolated pairs struck at 0 < t* <= dt / 2 between loose bodies."""
    n, dt = model.n_bodies, params.dt
    if not model.options.windows:  # every force acts over the whole step
        none = jnp.zeros_like(pred.t_row)
        return Window(windowed=none > 0, t_win=none, rest=none + dt, u_clock=jnp.zeros_like(v_star), v_clock=v_star)
    loose = loose_bodies(model) | model.fixed
    windowed = pred.isolated & moved & (pred.t_row > 0) & (pred.t_row <= 0.5 * dt) & loose[c.a] & loose[c.b]
    t_win = jnp.where(windowed, pred.t_row, 0.0)
    t_body = jnp.maximum(jax.ops.segment_max(t_win, c.a, n), jax.ops.segment_max(t_win, c.b, n))
    t_body = jnp.where(model.fixed, 0.0, jnp.maximum(t_body, 0.0))
    u_clock = ops.vel * t_body[:, None] + 0.5 * pred.accel * (t_body ** 2)[:, None]
    return Window(windowed=windowed, t_win=t_win, rest=jnp.where(windowed, dt - t_win, dt), u_clock=u_clock,
                  v_clock=v_star + pred.accel * t_body[:, None])


def held_clusters(approach: jax.Array, change: jax.Array, label: jax.Array, n: int) -> jax.Array:
    """Per row: whether its cluster's velocities jump at 0 rather than at its t* (the
    clock; docs/design.md): where one of its sustained contacts approaches at the start,
    moving on with the old velocities until t* would drive it into an overlap, which the
    position correction pushes out as velocity (energy from nothing). An approach counts
    against the impact's own change of the gap rates, ``change``: that energy goes as
    approach^2, the impact's as change^2, so an approach below sqrt(eps) |change| is
    round-off (a resting contact's rate under Newmark flips sign and grows from step to
    step: 2.5e-11 m/s after 80 steps of a resting column). ``label`` (C,): the rows'
    clusters, n for none."""
    def most(x):
        return jax.ops.segment_max(x, label, n + 1)[label]
    return most(approach) > jnp.sqrt(jnp.finfo(change.dtype).eps) * most(jnp.abs(change))


class Jump(NamedTuple):
    """The impacts' velocity jump."""

    impulse: jax.Array  # (C, 3) P = P1 + s K
    v_star: jax.Array  # (N, 6) the start velocity after the jump
    shift: jax.Array  # (N, 6) -(v* - v) clock: each body keeps its old velocity until its impact
    win: Window


def velocity_jump(model: Model, params: Params, ops: Operators, frame: ContactFrame, pred: Prediction,
                  rows: ImpactRows, op_m, p1: jax.Array) -> Jump:
    """The impact law on the compression ``p1`` (its solve's operand ``op_m``), v* = v +
    M^-1 J^T P, and each body's clock, its cluster's impact instant t* (a mesh's elements
    share their latest): it moves with v until t*, with v* after."""
    c, n = frame.contacts, model.n_bodies
    impulse, _, _ = impact_law(apply_w, op_m, rows.v_minus, rows.sets, frame.restitution, rows.struck, c.a, c.b,
                               model.fixed, p1)
    v_star = ops.vel + respond(ops.m_inv, rows.jac, c, impulse)
    moved = rows.sets.enabled & (impulse[:, 0] > 0)
    change = jnp.where(rows.sets.enabled, apply_jacobian(rows.jac, c, v_star - ops.vel)[:, 0], 0.0)
    at = jnp.where(moved & ~held_clusters(pred.approach, change, pred.cluster, n), pred.t_jump, 0.0)
    clock = jnp.maximum(jax.ops.segment_max(at, c.a, n), jax.ops.segment_max(at, c.b, n))
    clock = mesh_clock(model.mesh, jnp.where(model.fixed, 0.0, jnp.maximum(clock, 0.0)))
    return Jump(impulse=impulse, v_star=v_star, shift=-(v_star - ops.vel) * clock[:, None],
                win=window(model, params, ops, c, pred, moved, v_star))
