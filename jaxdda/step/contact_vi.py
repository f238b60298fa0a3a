"""Stage "contact VI": the step's position-level contact problem (paper eqs. 39-41) from
the velocity v* after the impacts, linearised once, at the predictor (docs/design.md,
"The step": the position correction)."""
from __future__ import annotations

from typing import NamedTuple

import jax
import jax.numpy as jnp

from jaxdda import groups, pins
from jaxdda.contact.kinematics import apply_jacobian, discrete_gradient, gap_frame, jacobians
from jaxdda.groups import Flexibility
from jaxdda.integrate import free_displacement
from jaxdda.solver.fista_newton import Problem
from jaxdda.solver.sets import sticking
from jaxdda.step import frame as frame_stage
from jaxdda.step.frame import ContactFrame
from jaxdda.step.jump import ImpactRows, Jump
from jaxdda.step.operators import Operators, flexibility, is_pinned, respond
from jaxdda.step.predict import Prediction
from jaxdda.types import Model, Params, State


class Linearised(NamedTuple):
    """What the step's end needs of the contact problem besides its operand."""

    d_base: jax.Array  # (N, 6) the displacement without this step's contact forces
    normal: jax.Array  # (C, 2) the rows' frame: its normals
    point: jax.Array  # (C, 2) and contact points


def mid_frame(state: State, c, d: jax.Array, start: jax.Array | None = None):
    """The rows (C, 2, 3, 6), normals and points of the frame half-way from ``start``
    (default: the step's start) to the motion d (N, 6)."""
    mid = 0.5 * d if start is None else 0.5 * (start + d)
    centroid, rotation = state.centroid + mid[:, :2], state.rotation + mid[:, 2]
    gap_mid, normal_mid, point_mid = gap_frame(c, centroid, rotation)
    return jacobians(c, normal_mid, point_mid, gap_mid, centroid), normal_mid, point_mid


def predictor(model: Model, state: State, params: Params, ops: Operators, c, jump: Jump, pred: Prediction,
              carried: jax.Array) -> tuple[jax.Array, jax.Array, Flexibility]:
    """d_base (the free motion from v*, with the impact shift) and the predictor d_base +
    K^-1 J^T p_carried; the flexibility K^-1 (a pinned body's turns about its pin with the
    lever of the mid-step configuration)."""
    def at(flex):
        d_base = free_displacement(flex, ops.mass, ops.load, jump.v_star, params.dt) + jump.shift
        return d_base, d_base + respond(flex, mid_frame(state, c, d_base + pred.push0)[0], c, carried)

    flex = ops.k_inv
    d_base, d_pred = at(flex)
    if is_pinned(model):
        maps = pins.pin_maps(model, ops.maps, pins.mid_centroid(model, state.centroid, d_pred))
        flex = groups.grouped(ops.k_eff, model.dof_projector, model, maps, ops.coupling)
        d_base, d_pred = at(flex)
    return d_base, d_pred, flex


def linearisation_point(model: Model, params: Params, c, gap0: jax.Array, d_pred: jax.Array,
                        change: jax.Array) -> jax.Array:
    """Per body, the predicted motion d_pred (N, 6) scaled to where it first overlaps one
    of its contacts by more than d0 (the exact gap, linear in between): 1 where it
    overlaps none. (The gap linearised there errs by the second order of the motion from
    it, which past that contact is motion the solve takes back: a block spun into a
    corner.)"""
    n = model.n_bodies
    g_pred = gap0 + change
    start = jnp.maximum(gap0, 0.0)
    over = c.valid & (g_pred < -params.margin)
    lam = jnp.where(over, start / jnp.where(over, start - g_pred, 1.0), 1.0)
    body = jnp.minimum(jax.ops.segment_min(lam, c.a, n), jax.ops.segment_min(lam, c.b, n))
    return d_pred * jnp.clip(body, 0.0, 1.0)[:, None]


def _at_partner(x: jax.Array, partner: jax.Array) -> jax.Array:
    """Per contact: ``x`` of its partner (the other contact of an edge-to-edge interface),
    its own where it has none."""
    mine = jnp.arange(partner.shape[0])
    return x[jnp.where(partner >= 0, partner, mine)]


def row_kinds(frame: ContactFrame, model: Model, end_velocity: jax.Array, held: jax.Array):
    """The shear and rolling rows' kinds: velocity level (G = J v+ times half the time span)
    or position level (G = the relative motion), and the signs their forces may not push
    along. A velocity-level row's force does work p (G + J (dt / 2) v*). Where last step's
    force already pushed along the slip (or roll) this step starts with, or the contact was
    ``held`` (stuck), the row is taken at position level (its work p G dissipates, and it
    can stick). Elsewhere the force may not push along that start slip: one that stops
    inside the step and would reverse ends it slipping back instead, by at most the drive
    over one step (docs/design.md, Energy). Slips within round-off are none. Returns the
    velocity part of the rows and ``opposes``."""
    c, p0, sets, touch = frame.contacts, frame.p0, frame.sets, frame.touch
    along = p0[:, 1:] * end_velocity[:, 1:] > 0
    along = along | _at_partner(along, sets.partner)  # an interface as one
    positional = jnp.stack([held, jnp.zeros_like(held)], -1) | along
    end_velocity = end_velocity.at[:, 1:].set(jnp.where(positional, 0.0, end_velocity[:, 1:]))
    reach = model.bound_radius[c.a] + model.bound_radius[c.b]
    start = end_velocity[:, 1:] * jnp.stack([jnp.ones_like(touch), reach], -1)
    return end_velocity, jnp.where(jnp.abs(start) > touch[:, None], jnp.sign(start), 0.0)


def held_rows(frame: ContactFrame, rows: ImpactRows, impulse: jax.Array) -> jax.Array:
    """Per contact: stuck last step (a shear force inside its cone), and not set sliding by
    the impacts; an interface's two contacts as one."""
    sets, p0 = frame.sets, frame.p0
    held = sticking(p0, sets) & (p0[:, 1] != 0.0) & ~((impulse[:, 0] > 0) & ~sticking(impulse, rows.sets))
    return held & _at_partner(held, sets.partner)


def contact_problem(model: Model, state: State, params: Params, ops: Operators, frame: ContactFrame,
                    pred: Prediction, rows: ImpactRows, jump: Jump) -> tuple[Problem, Linearised]:
    """The contact VI of the step: its rows over the motion from each body's window (its
    t*; the step's start for all others, u_clock = 0) to the linearisation point, in the
    frame half-way, the normal row the discrete gradient of the gap over that motion (it
    then does no work on a closed contact: docs/design.md, Energy); G's constant part b."""
    dt, c, win = params.dt, frame.contacts, jump.win

    def gap_change_by(d):
        return frame_stage.gap_change_by(model, state, c, d)

    carried = jnp.where(win.windowed[:, None], 0.0, pred.p_prior)  # a windowed force acts from t* only
    d_base, d_pred, flex = predictor(model, state, params, ops, c, jump, pred, carried)
    options = model.options
    d_lin = (linearisation_point(model, params, c, frame.gap0, d_pred, gap_change_by(d_pred))
             if options.linearisation_cut else d_pred)
    change = gap_change_by(d_lin)
    jac, normal, point = mid_frame(state, c, d_lin, win.u_clock)
    if options.discrete_gradient:
        jac = discrete_gradient(jac, c, d_lin - win.u_clock, change - gap_change_by(win.u_clock), model.bound_radius)
    w = win.windowed[:, None]
    end_velocity = jnp.where(w, 0.5 * win.rest[:, None] * apply_jacobian(jac, c, win.v_clock),
                             apply_jacobian(jac, c, 0.5 * dt * jump.v_star))
    end_velocity, opposes = row_kinds(frame, model, end_velocity, held_rows(frame, rows, jump.impulse))
    since = jnp.where(w, apply_jacobian(jac, c, win.u_clock), apply_jacobian(jac, c, jump.shift))
    b = apply_jacobian(jac, c, d_base) - since - end_velocity
    b = b.at[:, 0].set(frame.gap0 + change - apply_jacobian(jac, c, d_lin - d_base)[:, 0])
    sets = frame.sets._replace(opposes=opposes, cohesion=frame.sets.cohesion * (win.rest / dt) ** 2)
    operand, diag = flexibility(jac, c, flex)
    return (Problem(operand, diag, b, sets, frame.p0, ops.momentum / dt),
            Linearised(d_base=d_base, normal=normal, point=point))
