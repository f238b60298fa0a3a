"""Stages "predict", "impacts" and "contact VI": the step's velocity jumps and its contact
forces, two contact solves through one traced solver (docs/design.md, "The step").

    predict:    the free motion (with last step's forces that still act); each contact's
                impact time on it; impact clusters; isolated pairs
    impacts:    one velocity-level VI (``impacts.impact_law``): a cluster without sustained
                forces at its first t* (exact for an isolated pair), one with them at the
                step's start (Moreau)
    contact VI: the position-level VI of the step (paper eqs. 39-41) from v*, linearised once,
                at the predictor cut where it first overlaps; an isolated pair's force acts
                from its t* on (window)
"""
from __future__ import annotations

from typing import NamedTuple

import jax
import jax.numpy as jnp

from jaxdda import groups, pins
from jaxdda.contact.kinematics import (apply_jacobian, discrete_gradient, gap_change_at, gap_frame, gap_frame_at,
                                       jacobians, jacobians_at)
from jaxdda.integrate import exact_impact_time, free_displacement, matvec, mesh_clock, newmark_velocity
from jaxdda.solver import fista_newton
from jaxdda.solver.sets import ContactSets, sticking
from jaxdda.step import frame as frame_stage
from jaxdda.step.frame import ContactFrame
from jaxdda.step.impacts import cluster_labels, cluster_min, impact_law
from jaxdda.step.operators import Operators, apply_w, flexibility, is_pinned, respond
from jaxdda.types import Model, Params, State


class Resolution(NamedTuple):
    """What the impacts and the contact VI decide for the step."""

    displacement: jax.Array  # (N, 6) the step's displacement d (with the impacts' shift)
    velocity: jax.Array  # (N, 6) the end velocity (before pins hold it)
    memory: jax.Array  # (C, 3) each contact's force to warm-start the next step
    force: jax.Array  # (C, 3) the contact forces over the step (the VI's solution)
    gap_end: jax.Array  # (C,) their end gaps
    w_nn: jax.Array  # (C,) W's normal diagonal at the solution
    force_scale: jax.Array  # () the step's force scale
    point: jax.Array  # (C, 2) the contact points of the mid-step frame
    normal: jax.Array  # (C, 2) its normals
    parts: tuple  # ((mean force (C, 3) over the step, its normal (C, 2)), ...) for the report
    solutions: tuple  # the step's solves (fista_newton.Solution, stacked)


class Prediction(NamedTuple):
    """Stage "predict": the free motion and which contacts strike, when."""

    accel: jax.Array  # (N, 6) the free acceleration (loads only)
    t_row: jax.Array  # (C,) the instant each contact takes part in the impacts at
    isolated: jax.Array  # (C,) bool: a contact of an isolated pair (exact event)
    engaged: jax.Array  # (C,) bool: loaded, cemented, closed, or closing on the free path
    loaded: jax.Array  # (C,) bool: carried force last step, or cemented, and not opening
    p_prior: jax.Array  # (C, 3) last step's forces that still act (not on opening contacts)
    push0: jax.Array  # (N, 6) their displacement over the step, K^-1 J^T p_prior


def _path(ops, c, t, side, accel):
    """Each contact's side's free motion (shift, turn, strain) and velocity at time t (C,)."""
    body = c.a if side == 0 else c.b
    u = ops.vel[body] * t[:, None] + 0.5 * accel[body] * (t ** 2)[:, None]
    return (u[:, :2], u[:, 2], u[:, 3:]), ops.vel[body] + accel[body] * t[:, None]


def _loose(model: Model) -> jax.Array:
    """Per body: rigid-body mobility alone (no stiffness, no dof group, not pinned)."""
    n = model.n_bodies
    loose = ~model.fixed
    members = model.group_members.reshape(-1)
    loose = loose.at[jnp.where(members >= 0, members, n)].set(False, mode="drop")
    return loose.at[model.pin_body].set(False, mode="drop")


def predict(model: Model, state: State, params: Params, ops: Operators, frame: ContactFrame,
            d_free: jax.Array) -> Prediction:
    """Impact times on the predicted path (exact gap, ``exact_impact_time``; the loads and
    last step's forces that still act) and the impact clusters (bodies joined by their
    loaded, closed or closing contacts): a cluster's contacts are taken at its first
    impact t* (0 if none strikes: Moreau's impact of its closed contacts). The isolated
    pairs, two bodies (rigid and loose, or the elements of one mesh; or one of them fixed)
    whose every such contact joins them to each other, none loaded, are exact events."""
    n, dt = model.n_bodies, params.dt
    c, gap0, jac = frame.contacts, frame.gap0, frame.jac
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
        return gap0 + gap_change_at(c, state.centroid, state.rotation, _path(ops, c, t, 0, accel)[0],
                                    _path(ops, c, t, 1, accel)[0])

    t_own, hits = exact_impact_time(gap0, v_rel[:, 0], a_rel[:, 0], dt, frame.touch, gap_on_path)
    live = c.valid & ~opening
    loaded = live & ((frame.p0[:, 0] > 0) | frame.cemented)
    engaged = live & (loaded | hits | (gap0 <= params.margin))
    # A cluster's impact: the first contact that closes approaching (read on the exact path:
    # a touching contact that does not approach strikes nothing).
    rate = jax.jvp(gap_on_path, (t_own,), (jnp.ones_like(t_own),))[1]
    striking = engaged & hits & ~loaded & (rate < -frame.touch / dt)
    label = cluster_labels(engaged, c.a, c.b, model.fixed)
    first = jax.ops.segment_min(jnp.where(striking, t_own, jnp.inf), label, n + 1)[label]
    # A cluster that carries a sustained force is struck at the step's start (Moreau): its
    # velocities at a later t* are not known without the forces before it.
    carrying = jax.ops.segment_max(loaded.astype(jnp.int32), label, n + 1)[label] > 0
    t_row = jnp.where(engaged & jnp.isfinite(first) & ~carrying, first, 0.0)
    # units: a mesh's elements are one body, every other body its own
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
    mobile = (jax.ops.segment_min(_loose(model).astype(jnp.int32), unit, units) > 0) | (jnp.arange(units) >= n)
    alone = fixed_u | ((lo == hi) & ~held & mobile)
    isolated = engaged & ~loaded & alone[ua] & alone[ub] & ~(fixed_u[ua] & fixed_u[ub])
    return Prediction(accel=accel, t_row=t_row, isolated=isolated, engaged=engaged, loaded=loaded,
                      p_prior=p_prior, push0=push0)


class ImpactRows(NamedTuple):
    """The impact solve's rows: each contact in its frame at its instant."""

    jac: jax.Array  # (C, 2, 3, 6)
    normal: jax.Array  # (C, 2)
    v_minus: jax.Array  # (C, 3) relative velocity at the instant, before the impulse
    sets: ContactSets
    struck: jax.Array  # (C,) bool: approaching, not loaded (restitution e)


def impact_rows(model, state, params, ops, frame, pred: Prediction) -> ImpactRows:
    """Each engaged contact at its cluster's instant (frame, velocity: ``gap_frame_at``).
    Struck (with restitution) where it approaches, carried no force (a loaded or cemented
    contact is sustained: it does not bounce) and is closed then; the others are
    constraints, v+_n >= 0 (a later impact of the cluster, such as a block's second corner,
    is held from approaching at t*: first order)."""
    c = frame.contacts
    (move_a, vel_a), (move_b, vel_b) = (_path(ops, c, pred.t_row, side, pred.accel) for side in (0, 1))
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


def _at_partner(x: jax.Array, partner: jax.Array) -> jax.Array:
    """Per contact: ``x`` of its partner (the other contact of an edge-to-edge interface),
    its own where it has none."""
    mine = jnp.arange(partner.shape[0])
    return x[jnp.where(partner >= 0, partner, mine)]


def _row_kinds(frame: ContactFrame, model: Model, end_velocity: jax.Array, held: jax.Array):
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
    start = end_velocity[:, 1:] * jnp.stack([jnp.ones_like(touch), model.bound_radius[c.a] + model.bound_radius[c.b]], -1)
    return end_velocity, jnp.where(jnp.abs(start) > touch[:, None], jnp.sign(start), 0.0)


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
    loose = _loose(model) | model.fixed
    windowed = pred.isolated & moved & (pred.t_row > 0) & (pred.t_row <= 0.5 * dt) & loose[c.a] & loose[c.b]
    t_win = jnp.where(windowed, pred.t_row, 0.0)
    t_body = jnp.maximum(jax.ops.segment_max(t_win, c.a, n), jax.ops.segment_max(t_win, c.b, n))
    t_body = jnp.where(model.fixed, 0.0, jnp.maximum(t_body, 0.0))
    u_clock = ops.vel * t_body[:, None] + 0.5 * pred.accel * (t_body ** 2)[:, None]
    return Window(windowed=windowed, t_win=t_win, rest=jnp.where(windowed, dt - t_win, dt), u_clock=u_clock,
                  v_clock=v_star + pred.accel * t_body[:, None])


def linearisation_point(model: Model, params: Params, c, gap0: jax.Array, d_pred: jax.Array,
                        change: jax.Array) -> jax.Array:
    """Per body, the predicted motion d_pred (N, 6) scaled to where it first overlaps one
    of its contacts by more than d0 (the exact gap, linear in between): 1 where it
    overlaps none."""
    n = model.n_bodies
    g_pred = gap0 + change
    start = jnp.maximum(gap0, 0.0)
    over = c.valid & (g_pred < -params.margin)
    lam = jnp.where(over, start / jnp.where(over, start - g_pred, 1.0), 1.0)
    body = jnp.minimum(jax.ops.segment_min(lam, c.a, n), jax.ops.segment_min(lam, c.b, n))
    return d_pred * jnp.clip(body, 0.0, 1.0)[:, None]


def resolve_contacts(model: Model, state: State, params: Params, ops: Operators, frame: ContactFrame) -> Resolution:
    """The step's impacts and contact forces (``model`` in the bodies' current shape)."""
    n, dt = model.n_bodies, params.dt
    proj = model.dof_projector
    c, gap0, sets, p0 = frame.contacts, frame.gap0, frame.sets, frame.p0
    k_inv, vel = ops.k_inv, ops.vel
    d_free = free_displacement(k_inv, ops.mass, ops.load, vel, dt)
    pred = predict(model, state, params, ops, frame, d_free)
    rows = impact_rows(model, state, params, ops, frame, pred)
    op_m, diag_m = flexibility(rows.jac, c, ops.m_inv)
    force_scale = ops.momentum / dt
    p_prior, push0 = pred.p_prior, pred.push0

    def gap_change_by(d):
        return frame_stage.gap_change_by(model, state, c, d)

    def mid_frame(d, start=None):  # the frame half-way from ``start`` (default: the step's start) to d
        mid = 0.5 * d if start is None else 0.5 * (start + d)
        centroid, rotation = state.centroid + mid[:, :2], state.rotation + mid[:, 2]
        gap_mid, normal_mid, point_mid = gap_frame(c, centroid, rotation)
        return jacobians(c, normal_mid, point_mid, gap_mid, centroid), normal_mid, point_mid

    def contact_problem(p1):
        """Stage "contact VI" from the impacts' compression p1: the position-level problem
        over the step, linearised at the predictor, and what the step's end needs."""
        impulse, _, _ = impact_law(apply_w, op_m, rows.v_minus, rows.sets, frame.restitution, rows.struck, c.a, c.b,
                                   model.fixed, p1)
        v_star = vel + respond(ops.m_inv, rows.jac, c, impulse)
        moved = rows.sets.enabled & (impulse[:, 0] > 0)
        clock = jnp.maximum(jax.ops.segment_max(jnp.where(moved, pred.t_row, 0.0), c.a, n),
                            jax.ops.segment_max(jnp.where(moved, pred.t_row, 0.0), c.b, n))
        # Each body moves with its old velocity until its cluster's impact, its new one after.
        clock = mesh_clock(model.mesh, jnp.where(model.fixed, 0.0, jnp.maximum(clock, 0.0)))
        shift = -(v_star - vel) * clock[:, None]
        win = window(model, params, ops, c, pred, moved, v_star)
        carried = jnp.where(win.windowed[:, None], 0.0, p_prior)  # a windowed contact's force acts from t* only
        flex = k_inv

        def predictor(flex):
            d_base = free_displacement(flex, ops.mass, ops.load, v_star, dt) + shift
            return d_base, d_base + respond(flex, mid_frame(d_base + push0)[0], c, carried)

        d_base, d_pred = predictor(flex)
        if is_pinned(model):  # a pinned body turns about its pin with the lever of the mid-step configuration
            maps = pins.pin_maps(model, ops.maps, pins.mid_centroid(model, state.centroid, d_pred))
            flex = groups.grouped(ops.k_eff, proj, model, maps, ops.coupling)
            d_base, d_pred = predictor(flex)
        # The rows over the motion from each body's window (its t*; the step's start for
        # all others, u_clock = 0) to the predictor: the frame half-way, the normal row the
        # discrete gradient of the gap over that motion (it then does no work on a closed
        # contact: docs/design.md, Energy).
        # Linearised at the predictor, or short of it: a body's predicted motion is cut
        # where it first overlaps a contact by more than d0 (the gap linearised there errs
        # by the second order of the motion from it, which past that contact is motion the
        # solve takes back: a block spun into a corner).
        d_lin = linearisation_point(model, params, c, gap0, d_pred, gap_change_by(d_pred))
        change = gap_change_by(d_lin)
        jac, nrm, pt = mid_frame(d_lin, win.u_clock)
        jac = discrete_gradient(jac, c, d_lin - win.u_clock, change - gap_change_by(win.u_clock), model.bound_radius)
        w = win.windowed
        held = sticking(p0, sets) & (p0[:, 1] != 0.0) & ~((impulse[:, 0] > 0) & ~sticking(impulse, rows.sets))
        held = held & _at_partner(held, sets.partner)  # an interface as one
        end_velocity = jnp.where(w[:, None], 0.5 * win.rest[:, None] * apply_jacobian(jac, c, win.v_clock),
                                 apply_jacobian(jac, c, 0.5 * dt * v_star))
        end_velocity, opposes = _row_kinds(frame, model, end_velocity, held)
        since = jnp.where(w[:, None], apply_jacobian(jac, c, win.u_clock), apply_jacobian(jac, c, shift))
        b = apply_jacobian(jac, c, d_base) - since - end_velocity
        b = b.at[:, 0].set(gap0 + change - apply_jacobian(jac, c, d_lin - d_base)[:, 0])
        con_sets = sets._replace(opposes=opposes, cohesion=sets.cohesion * (win.rest / dt) ** 2)
        op, diag = flexibility(jac, c, flex)
        problem = (op, diag, b, con_sets, p0, force_scale)
        return problem, (impulse, v_star, shift, d_base, win, nrm, pt, flex)

    # The two solves through one traced solver: the impacts' compression, then the contact VI.
    impact_problem = (op_m, diag_m, rows.v_minus, rows.sets, jnp.zeros_like(p0), ops.momentum)
    context = jax.eval_shape(lambda p: contact_problem(p)[1], p0)

    def solve(p1, second):
        problem, ctx = jax.lax.cond(
            second, contact_problem,
            lambda _: (impact_problem, jax.tree.map(lambda s: jnp.zeros(s.shape, s.dtype), context)), p1)
        op, diag, b, con_sets, warm, scale = problem
        sol = fista_newton.solve(apply_w, op, diag, b, con_sets, warm, params.tol, params.max_iter, scale)
        return sol.force, (sol, ctx, problem[:3])

    _, (sols, ctxs, problems) = jax.lax.scan(solve, jnp.zeros_like(p0), jnp.arange(2) > 0)
    impulse, v_star, shift, d_base, win, nrm, pt, flex = jax.tree.map(lambda x: x[1], ctxs)
    op_k, diag_k, b_con = jax.tree.map(lambda x: x[1], problems)
    con = sols.force[1]
    jac_con = op_k[0]
    d = d_base + respond(flex, jac_con, c, con)
    v_newmark = newmark_velocity(d - shift, v_star, dt, proj)
    new_vel = v_newmark + matvec(proj, respond(ops.m_inv, jac_con, c, _late_kick(model, c, jac_con, ops, win, con,
                                                                                  v_newmark, params)))
    rest_mean = (dt / win.rest)[:, None]  # a windowed force acts over h: its mean over the step
    return Resolution(displacement=d, velocity=new_vel, memory=con, force=con,
                      gap_end=apply_w(op_k, con)[:, 0] + b_con[:, 0], w_nn=diag_k[:, 0], force_scale=force_scale,
                      point=pt, normal=nrm, parts=((impulse / dt, rows.normal), (con * rest_mean, nrm)),
                      solutions=(sols,))


def _late_kick(model, c, jac, ops, win: Window, con, v_newmark, params):
    """A windowed force's late impulse q dt t* / h: it holds a body its impact stopped at t*
    (cancels the approach Newmark's velocity leaves; a block landing inside the step rests),
    and never opens a contact. Each row's kick is cut to what cancels its approach, and a
    cluster of bodies joined by kicked rows shares the smallest cut (internal forces)."""
    late = jnp.where(win.windowed, win.t_win * params.dt / win.rest, 0.0)
    kick = con * late[:, None]
    proj = model.dof_projector
    kick_vel = matvec(proj, respond(ops.m_inv, jac, c, kick))
    rate, rate_kick = apply_jacobian(jac, c, v_newmark)[:, 0], apply_jacobian(jac, c, kick_vel)[:, 0]
    kicked = jnp.any(kick != 0.0, -1)
    cut_to = jnp.where(kicked & (rate_kick > 0), jnp.clip(-rate / jnp.where(rate_kick > 0, rate_kick, 1.0), 0.0, 1.0),
                       1.0)
    return kick * cluster_min(cut_to, kicked, c.a, c.b, model.fixed)[:, None]
