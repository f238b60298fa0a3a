"""Stages "impacts" and "contact VI" of the present scheme: the impacts of the step at
their instants (Poisson's law, velocity level) and the contact forces over the step
(position level, paper eqs. 39-41), from the step's operators and contact frame.
"""
from __future__ import annotations

from typing import NamedTuple

import jax
import jax.numpy as jnp

from jaxdda import groups, pins
from jaxdda.contact.kinematics import (apply_jacobian, discrete_gradient, gap_change_at, gap_frame,
                                       gap_frame_at, jacobians, jacobians_at)
from jaxdda.integrate import (SIMULTANEITY, common_impact_time, exact_impact_time, free_displacement, impact_clock,
                              matvec, mesh_clock, newmark_velocity, strike_time)
from jaxdda.groups import Flexibility
from jaxdda.solver import fista_newton
from jaxdda.solver.sets import ContactSets, sticking
from jaxdda.step import frame as frame_stage
from jaxdda.step.frame import ContactFrame
from jaxdda.step.operators import Operators, apply_w, flexibility, is_pinned, respond
from jaxdda.types import B_HOLE, Model, Params, State


def _at_partner(x: jax.Array, partner: jax.Array) -> jax.Array:
    """Per contact: ``x`` of its partner (the other contact of an edge-to-edge interface),
    its own where it has none."""
    mine = jnp.arange(partner.shape[0])
    return x[jnp.where(partner >= 0, partner, mine)]


def cluster_min(x: jax.Array, joined: jax.Array, a: jax.Array, b: jax.Array, fixed: jax.Array) -> jax.Array:
    """Per row: the least ``x`` over the rows of its cluster (free bodies joined by the
    ``joined`` rows; fixed bodies join nothing). A row that joins nothing keeps its own.
    The clusters are labelled (their least body) on integers, so the derivative flows
    through the minimum alone."""
    n = fixed.shape[0]

    def of_rows(label):  # a joined row's label: the smaller of its free bodies' labels (n: none)
        la, lb = jnp.where(fixed[a], n, label[a]), jnp.where(fixed[b], n, label[b])
        return jnp.where(joined, jnp.minimum(la, lb), n)

    def spread(carry):
        label, _ = carry
        row = of_rows(label)
        new = jnp.minimum(label, jnp.minimum(jax.ops.segment_min(row, a, n), jax.ops.segment_min(row, b, n)))
        return new, jnp.any(new != label)

    label = of_rows(jax.lax.while_loop(lambda c: c[1], spread, (jnp.arange(n), jnp.array(True)))[0])
    least = jax.ops.segment_min(jnp.where(label < n, x, jnp.inf), label, n + 1)
    return jnp.where(label < n, least[label], x)


def _poisson_impact(op_m, diag_m, v_hit: jax.Array, imp_sets: ContactSets, bounce: jax.Array, params: Params,
                    momentum: jax.Array, warm: tuple[jax.Array, jax.Array] | None = None
                    ) -> tuple[fista_newton.Solution, tuple[jax.Array, jax.Array]]:
    """Impulses P (C, 3) of the impacts by Poisson's law with Coulomb friction, in two phases.

    Compression: the plastic impact, P1 solving the VI with G = W P1 + v(t*) (no contact
    approaches after it). Restitution: P2 with P2_n >= e P1_n at each contact, on the
    velocities after compression: a VI in x = P2 - e P1_n (normal) with x_n >= 0, its
    friction bound mu (x_n + e P1_n) = mu x_n + (a cohesion of mu e P1_n). P = P1 + P2.

    Newton's law (v+_n = -e v-_n at once) with friction makes energy where a contact sticks
    while the normal impulse turns the body (Kane's paradox: a spinning polygon striking a
    wall, dKE = P . (v- + v+) / 2 > 0 with the shear impulse along the slip before it).
    Poisson's keeps each phase dissipative, and agrees with Newton's for a single
    frictionless contact, for e = 0, and for impulses passed through touching chains (the
    touching pair struck with e = 1 still leaves them at (-1/3, 2/3, 2/3) v). In the
    restitution phase the rolling bound is delta x_n (the rebound part only).

    Returns the impulses and the two phases' solutions, ``warm`` for a solve of the same
    impacts again (each phase starts from them).
    """
    warm = jnp.stack(warm) if warm else jnp.zeros((2,) + v_hit.shape, v_hit.dtype)

    def phase(comp, restitution):  # one solve in a loop of the two phases (the solver is most of the step's code)
        rebound = jnp.where(restitution, bounce * jnp.maximum(comp[:, 0], 0.0), 0.0)
        kick = jnp.zeros_like(v_hit).at[:, 0].set(rebound)
        b = jnp.where(restitution, apply_w(op_m, comp + kick) + v_hit, v_hit)
        sets = imp_sets._replace(cohesion=jnp.where(restitution, imp_sets.friction * rebound, imp_sets.cohesion),
                                 partner=jnp.where(restitution, -1, imp_sets.partner))
        sol = fista_newton.solve(apply_w, op_m, diag_m, b, sets, jnp.where(restitution, warm[1], warm[0]), params.tol,
                       params.max_iter, momentum)
        return jnp.where(restitution, comp, sol.force), (sol, kick)

    comp, (sols, kicks) = jax.lax.scan(phase, jnp.zeros_like(v_hit), jnp.array([False, True]))
    return fista_newton.Solution(comp + kicks[1] + sols.force[1], jnp.sum(sols.iterations).astype(jnp.int32),
                       jnp.max(sols.residual), jnp.all(sols.converged)), (sols.force[0], sols.force[1])


# The overlap a ring's cut row allows, as a share of the smaller body's size (step 2).
CUT_SLACK = 1e-9
# How many times the contact problem is linearised and solved in a step (step 2), and at
# most how many more times where the last solve's motion still overlaps a contact.
LINEARISATIONS = 2
EXTRA_LINEARISATIONS = 1


class _Ahead(NamedTuple):
    """What the first impact round decides for the rest of the step (``step``, 1 and 1b)."""

    v_hit: jax.Array  # (C, 3) the velocities at t* the second round solves on
    accel: jax.Array  # (N, dofs) the accelerations to t*, with the forces before the impacts
    clock: jax.Array  # (N,) each body's impact time
    windowed: jax.Array  # (C,) contacts whose force acts from t* on
    t_win: jax.Array  # (C,) the impact a contact's window starts at
    t_body: jax.Array  # (N,) the start of a body's window
    tau: jax.Array  # (N,) t_body / dt
    p_pre: jax.Array  # (C, 3) the forces before an impact
    by_pre: jax.Array  # (N, dofs) K_eff^-1 J^T p_pre
    normal_pre: jax.Array  # (C, 2) their frame
    before: fista_newton.Solution  # their solve
    k_inv: Flexibility | None  # a pinned scene's flexibility on the mid-step levers


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
    solutions: tuple  # the step's solves (fista_newton.Solution, some stacked over loops)


def resolve_contacts(model: Model, state: State, params: Params, ops: Operators, frame: ContactFrame) -> Resolution:
    """The step's impacts and contact forces (``model`` in the bodies' current shape)."""
    n, dt = model.n_bodies, params.dt
    proj = model.dof_projector
    pinned = is_pinned(model)
    centroid = state.centroid
    mass, stiff, load, k_eff, k_inv, m_inv = ops.mass, ops.stiff, ops.load, ops.k_eff, ops.k_inv, ops.m_inv
    vel, maps, coupling, momentum = ops.vel, ops.maps, ops.coupling, ops.momentum
    c, gap0, normal, point, jac = frame.contacts, frame.gap0, frame.normal, frame.point, frame.jac
    sets, cemented, restitution, p0, touch = frame.sets, frame.cemented, frame.restitution, frame.p0, frame.touch

    def gap_change_by(d):  # exact change of the gaps over the step's displacement d (N, 6)
        return frame_stage.gap_change_by(model, state, c, d)

    # 1. Impacts: Poisson's law at the impact time t*, impulses P (velocity level).
    # A contact that carried force last step, or is cemented, is sustained, not struck:
    # it is closed (its gap, however small, is not a free fall to an impact), it takes
    # part in the impact solve (so impulses pass through a resting stack) and it does not
    # bounce. Cohesion and cement are finite forces: they give no impulse.
    sustained = (p0[:, 0] > 0) | cemented
    # The acceleration towards an impact includes last step's contact forces: a disk
    # falling onto a resting column meets a column held up by the floor, not one that
    # falls with it (the relative acceleration, and so t* and v(t*), would be wrong).
    # Not those of contacts that open even without their own force (the end gap under the
    # free motion and the other forces that still act): a body leaving a wall is not
    # pushed by it. Dropped until none is left that opens, as a dropped force can open the
    # contacts it held: a heavy block leaving a chain of two bodies no longer pushes the
    # first into the second (kept, that push drove a light disk into a heavy ring at 3.4
    # m/s instead of 1 m/s, and the impact sized for it made 290 J: fuzz seed 16710).
    d_free = free_displacement(k_inv, mass, load, vel, dt)
    w_own = flexibility(jac, c, k_inv)[1][:, 0]
    w_div = jnp.where(w_own > 0, w_own, 1.0)  # W_nn to divide by (0 between fixed bodies)

    # The free motion's end gaps are exact, not linear in the start frame: a disk running
    # round a ring's hole leaves the hole's start tangent at +0.09 m/s and meets the curving
    # hole again within the step. Read linearly, its centripetal force (1.4 kN) opened and
    # was dropped, the disk struck the hole on the free path at 1.4 ms, and the impulse,
    # applied where the contact separates, made 0.031 J, 1e4 times the allowance (fuzz
    # seed 19661).
    gap_free = gap0 + gap_change_by(d_free)

    def opening(p):  # each end gap under the free motion and the forces p, less its own force's share
        pushed = respond(k_inv, jac, c, p)
        return gap_free + apply_jacobian(jac, c, pushed)[:, 0] - w_own * p[:, 0]

    def drop_opening(carry):
        keep, _ = carry
        opens = (opening(jnp.where(keep[:, None], p0, 0.0)) > 0) & ~cemented
        return keep & ~opens, jnp.any(keep & opens)

    # Nor those of contacts that separate at the start (v_n dt > d0), which carry no force
    # from t = 0 on (Signorini's law at velocity level), unless they still approach once
    # each loaded contact that approaches (v_n dt < -d0) is stopped by its own plastic
    # impulse (P = -v_n / W_nn, alone): a squeeze driven on; or once their free motion
    # closes them again (gap_free <= d0: a hole curving back onto a disk). A force last step spent
    # stopping a heavy block against a light ring wedged on a wall (7e5 N) was kept, held
    # up by the wall's, after the block had left at 0.66 m/s: the pair's small mismatch
    # drove the 0.7 kg ring at 3e4 m/s^2 into an impact that made 0.32 J (fuzz seed 5338).
    # Dropped from a driven squeeze (a heavy disk pressing a light ring on at 2.2 m/s into a
    # block it had left at 1.1 m/s), the ring ended 4.7 times its bound inside the block
    # (seed 1978). Kept where the drive does not catch up (a disk pressing a ring on at 1.4
    # m/s, the block in its hole leaving at 4.5 m/s), the squeeze's mismatch in frames
    # turned by the block's 40 rad/s drove the ring into it at 6.6 m/s (+22 J: seed 14193).
    # And each kept force is at most what holds its contact closed against the free motion
    # and the other kept forces (its share of an equilibrium, where it is last step's
    # exactly): the wall, left alone, closed by 1e-11 m.
    v_rel = apply_jacobian(jac, c, vel)
    pushes = (p0[:, 0] > 0) & (v_rel[:, 0] * dt < -params.margin)
    stop = jnp.where(pushes, -v_rel[:, 0] / w_div, 0.0)
    driven = apply_jacobian(jac, c, respond(k_inv, jac, c, jnp.zeros_like(p0).at[:, 0].set(stop)))
    lapsed = (jnp.minimum(v_rel[:, 0], v_rel[:, 0] + driven[:, 0]) * dt > params.margin) & (gap_free > params.margin) & ~cemented
    keep = jax.lax.while_loop(lambda carry: carry[1], drop_opening, (c.valid & ~lapsed, jnp.array(True)))[0]
    p_kept = jnp.where(keep[:, None], p0, 0.0)
    p_held = jnp.clip(-opening(p_kept) / w_div, 0.0, p_kept[:, 0])
    part = jnp.where(cemented | (p_kept[:, 0] <= 0), 1.0, p_held / jnp.where(p_kept[:, 0] > 0, p_kept[:, 0], 1.0))
    p_prior = p_kept * part[:, None]  # last step's forces that still act
    push0 = respond(k_inv, jac, c, p_prior)  # displacement by last step's forces
    accel = 2.0 * (d_free + push0 - vel * dt) / dt ** 2
    a_rel = apply_jacobian(jac, c, accel)
    # The time of impact on the exact gap along the predicted path (a concave contact
    # closes sooner, a convex one later than its linearisation says), and each contact's
    # frame and relative velocity at that instant: the impulse acts there, so Poisson's
    # law dissipates in the configuration it acts in.
    def path(t, side, acc=None):  # each contact's side's motion (shift, turn, strain) and velocity at time t
        body, acc = (c.a if side == 0 else c.b), (accel if acc is None else acc)
        u = vel[body] * t[:, None] + 0.5 * acc[body] * (t ** 2)[:, None]
        return (u[:, :2], u[:, 2], u[:, 3:]), vel[body] + acc[body] * t[:, None]

    def gap_on_path(t):
        return gap0 + gap_change_at(c, centroid, state.rotation, path(t, 0)[0], path(t, 1)[0])

    # Contacts that may carry an impact's impulse on: loaded, cemented or closed.
    may_carry = c.valid & ((p_prior[:, 0] > 0) | cemented | (gap0 <= params.margin))

    def timing(striking, t_own):  # struck contacts at their impact, the others at the first that reaches them
        t = common_impact_time(jnp.where(striking, t_own, 0.0), striking, c.a, c.b, n, dt)
        return jnp.where(striking, t, strike_time(t, striking, may_carry, c.a, c.b, model.fixed))

    # Each contact's time to touch, and to close d0 past the overlap it starts with (for
    # ``rushing`` below): one solve of the two (vmapped; gap_on_path is a large code).
    floor = jnp.minimum(gap0, 0.0) - params.margin

    def time_to(level):
        return exact_impact_time(gap0 - level, v_rel[:, 0], a_rel[:, 0], dt, touch, lambda t: gap_on_path(t) - level)

    times, reached = jax.vmap(time_to)(jnp.stack([jnp.zeros_like(floor), floor]))
    t_own, hits = times[0], reached[0]
    striking = c.valid & hits & ~sustained
    t_hit = timing(striking, t_own)
    # A sustained contact that closes in by more than d0 on the way to its bodies' first
    # impact (a corner of a spinning block that last step left approaching its ring) is
    # struck itself when it does (without bounce): waited for, the bodies would pass
    # through each other until then, and the position-level solve would push them out
    # with work p (overlap) (fuzz seed 2547: energy x 5 in a step). When it does is found
    # on the exact gap along the path, as an impact's time is: a light ring rising past
    # the heavy disk in its hole closes on it at the hole's curvature, which the start
    # frame misses; struck at the ring's later impact instead, deep inside the disk, the pair
    # was pushed apart with 3.7 kJ of work (fuzz seed 5061).
    rushing = c.valid & sustained & (t_hit > 0) & (gap_on_path(t_hit) < floor)
    t_rush = jnp.minimum(times[1], t_hit)
    striking, hits = striking | rushing, hits | rushing
    t_hit = timing(striking, jnp.where(rushing, t_rush, t_own))
    # One impact per pair of bodies and step: a later impact with another body is predicted
    # on the path before the first, which no longer holds after it (a light ring squeezed
    # between two heavy disks struck by a third body on its old path: an impulse on a
    # contact that never closes). The position-level solve takes it, on the path after the
    # first impact. A later impact of the same pair (a block's second corner landing on the
    # floor it struck with its first) stays in the impact solve, and so does one after a
    # touch that does not approach (B strikes A touching C: A-C "hits" at t = 0 with no
    # speed, and takes part in B's impact as a plain constraint). Whether a contact
    # approaches at t* is read on the exact path, as t* is: a rushing corner in a spinning
    # ring's hole has linear rate +0.85 m/s there but closes at -0.0125 m/s, and missed as
    # the ring's first impact it let a later block impact into the same solve (+1.4 kJ,
    # fuzz seed 6012).
    rate_hit = jax.jvp(gap_on_path, (t_hit,), (jnp.ones_like(t_hit),))[1]
    moving = striking & (rate_hit < -touch / dt)
    pair = jnp.minimum(c.a, c.b) * n + jnp.maximum(c.a, c.b)
    # A body's first impact is also one that reaches it through a carrying contact (taken at
    # t_hit > 0, the impact that reaches either of its bodies): a light ring pushed by its
    # neighbour's impact at 0.29 ms and struck itself at 1.14 ms took both impulses in one
    # solve, the second predicted on its old path and shifted as if the first came then too
    # (+0.0095 J against an allowance of 1e-4 J: fuzz seed 7168 with a third linearisation).
    carried = may_carry & ~striking & (t_hit > 0)
    t_str = jnp.where(moving | carried, t_hit, jnp.inf)
    t_first = jnp.minimum(jax.ops.segment_min(t_str, c.a, n), jax.ops.segment_min(t_str, c.b, n))
    free_first = jnp.where(model.fixed, jnp.inf, t_first)
    first = jnp.minimum(free_first[c.a], free_first[c.b])  # inf where neither free body strikes
    big = n * n
    first_pair = jnp.minimum(jax.ops.segment_min(jnp.where(t_str == t_first[c.a], pair, big), c.a, n),
                             jax.ops.segment_min(jnp.where(t_str == t_first[c.b], pair, big), c.b, n))
    same = (model.fixed[c.a] | (first_pair[c.a] == pair)) & (model.fixed[c.b] | (first_pair[c.b] == pair))
    second = striking & (t_hit > first) & ~same
    t_second = jnp.where(second, t_hit, -jnp.inf)
    striking, hits = striking & ~second, hits & ~second
    t_hit = jnp.minimum(t_hit, first)
    later = ~striking & (t_hit > 0)  # taken at a body's impact, later than the step's start
    (move_a, vel_a), (move_b, vel_b) = path(t_hit, 0), path(t_hit, 1)
    pose_a = (centroid[c.a] + move_a[0], state.rotation[c.a] + move_a[1])
    pose_b = (centroid[c.b] + move_b[0], state.rotation[c.b] + move_b[1])
    gap_hit, normal_hit, point_hit = gap_frame_at(c, pose_a, pose_b)
    jac_hit = jacobians_at(c, normal_hit, point_hit, gap_hit, pose_a[0], pose_b[0])
    v_hit = jnp.einsum("cij,cj->ci", jac_hit[:, 0], vel_a) + jnp.einsum("cij,cj->ci", jac_hit[:, 1], vel_b)
    # A closed contact (gap within the margin d0) that does not approach takes part as a
    # plain constraint, v+_n >= 0: an impulse passes through a touching chain (B hits A
    # touching C: with e = 0 all three move on at one speed) instead of A being driven
    # into C and pushed back out by the position-level solve. One that strikes nothing
    # itself is taken at its bodies' first impact: closed then, or still loaded.
    closed = jnp.where(later, gap_hit, gap0) <= params.margin
    approaching = hits & (v_hit[:, 0] < 0) & (closed | ~later)
    loaded = (p_prior[:, 0] > 0) | cemented
    impacting = c.valid & (approaching | loaded | closed)
    bounce = jnp.where(sustained | ~approaching, 0.0, restitution)
    op_m, diag_m = flexibility(jac_hit, c, m_inv)
    zero = jnp.zeros_like(gap0)
    imp_sets = sets._replace(enabled=impacting, cohesion=zero, tension=zero)
    def mid_frame(d, start=None):  # the frame half-way from ``start`` (default: the step's start) to d
        mid = 0.5 * d if start is None else 0.5 * (start + d)
        mid_centroid, mid_rotation = centroid + mid[:, :2], state.rotation + mid[:, 2]
        gap_mid, normal_mid, point_mid = gap_frame(c, mid_centroid, mid_rotation)
        return jacobians(c, normal_mid, point_mid, gap_mid, mid_centroid), normal_mid, point_mid

    # Stuck last step: its shear force inside the cone, and not exactly 0, which is where a
    # force that may not push along its start slip stops when the contact slides on
    # (``opposes``): taken at position level, the block that stopped on a slope and slipped
    # back under it would flip its velocity every step (d = 0 gives v+ = -v).
    def held_by(impulse):
        held = sticking(p0, sets) & (p0[:, 1] != 0.0) & ~((impulse[:, 0] > 0) & ~sticking(impulse, imp_sets))
        return held & _at_partner(held, sets.partner)  # an interface as one

    def kinds(end_velocity, held):
        """The shear and rolling rows' kinds: velocity level (G = J v+ times half the time
        span) or position level (G = the relative motion), and the signs their forces may
        not push along. A velocity-level row's force does work p (G + J (dt / 2) v*). Where
        last step's force already pushed along the slip (or roll) this step starts with, the
        row is taken at position level too (its work p G dissipates, and it can stick).
        Elsewhere the force may not push along that start slip: one that stops inside the
        step and would reverse ends it slipping back instead, by at most the drive over one
        step (docs/design.md, Energy). Slips within round-off of the coordinates are none.
        Both rules are taken in the frame the rows are (the work p (dt / 2) J v* is that
        frame's J). Returns the velocity part of the rows and ``opposes``."""
        along = p0[:, 1:] * end_velocity[:, 1:] > 0
        along = along | _at_partner(along, sets.partner)  # an interface as one
        positional = jnp.stack([held, jnp.zeros_like(held)], -1) | along
        end_velocity = end_velocity.at[:, 1:].set(jnp.where(positional, 0.0, end_velocity[:, 1:]))
        start = end_velocity[:, 1:] * jnp.stack([jnp.ones_like(touch), model.bound_radius[c.a] + model.bound_radius[c.b]], -1)
        return end_velocity, jnp.where(jnp.abs(start) > touch[:, None], jnp.sign(start), 0.0)

    # The impacts are solved twice: on the velocities of the free motion under last step's
    # forces, and again once the forces before them (1b below, which need the first
    # solve's impulses) are known. One Poisson solve in a loop of the two rounds, with
    # everything between them in the loop's first round (the solver is most of the step's
    # compiled code).
    def forces_before(imp):
        """What the first round's impulses ``imp`` decide: the windows, and the forces
        before an impact (1b), and the velocities at t* that the second round solves on."""
        flex = k_inv
        v_star = vel + respond(m_inv, jac_hit, c, imp.force)
        struck = c.valid & ((approaching & ~sustained) | rushing)
        clock = impact_clock(t_hit, struck, impacting & (imp.force[:, 0] > 0), c.a, c.b, model.fixed)
        clock = mesh_clock(model.mesh, clock)
        shift = -(v_star - vel) * clock[:, None]
        # A windowed contact: one closed by an impact at 0 < t* <= dt / 2 that is each of its
        # free bodies' only impact in the step, or a sustained contact of a body so struck
        # (its force before t* is solved for on its own, "forces before an impact" below).
        # Its force acts from t* on, over the rest h = dt - t*: the solve's q (a force over
        # the whole step) stands for p = q (dt / h)^2 over h, which moves the bodies as much. Its impulse p h = q dt (dt / h) is more than
        # the q dt of Newmark's velocity by q dt t* / h (``late``). Its rows are taken over the
        # bodies' motion after t* (the trapezoidal rule over h): the gap's discrete gradient
        # from the pose at t*, the slip from the velocity v*(t*). A body landing inside the step
        # then rests at once (with the force over the whole step it kept v = -g t* h / dt), and
        # a disk caught by a ring's inside while it slides along it does no work on it (fuzz
        # seeds 909, 1434, 1632, 2370, 2743, 3534). Cohesion, a force, scales as q does.
        # Only for impacts in the first half of the step (the kick q dt t* / h is at most q dt):
        # as h -> 0 it grows without bound, and a t* that the prediction misplaces (the first
        # step of a stack does not know its support yet: a block thrown onto it seemed to strike
        # at dt, h = 2e-18 s) turns a finite q into an unbounded kick. And only between loose
        # rigid bodies, where Newmark's flexibility is the mass's: a body with stiffness, in a
        # dof group (a mesh, connectors) or pinned keeps its forces over the whole step.
        loose = jnp.all(stiff == 0.0, (-2, -1)) & ~model.fixed
        members = model.group_members.reshape(-1)
        loose = loose.at[jnp.where(members >= 0, members, n)].set(False, mode="drop")
        loose = loose.at[model.pin_body].set(False, mode="drop") | model.fixed
        struck_at = jnp.maximum(jnp.where(struck, t_hit, -jnp.inf), t_second)
        last = jnp.maximum(jax.ops.segment_max(struck_at, c.a, n), jax.ops.segment_max(struck_at, c.b, n))
        own_clock = jnp.where(model.fixed, 0.0, clock)
        t_win = jnp.maximum(own_clock[c.a], own_clock[c.b])  # the impact the contact's window starts at
        eligible = c.valid & (struck | (sustained & ~cemented)) & (t_win > 0)

        def alone(candidate):  # the candidates that are each of their free bodies' one impact (or none)
            win_hi = jnp.maximum(jax.ops.segment_max(jnp.where(candidate, t_win, -jnp.inf), c.a, n),
                                 jax.ops.segment_max(jnp.where(candidate, t_win, -jnp.inf), c.b, n))
            win_lo = jnp.minimum(jax.ops.segment_min(jnp.where(candidate, t_win, jnp.inf), c.a, n),
                                 jax.ops.segment_min(jnp.where(candidate, t_win, jnp.inf), c.b, n))

            def once(body):  # its only impact at t* (a later one, left to the contact solve, counts too), or none
                first_only = ((clock[body] == t_win) | (clock[body] == 0.0)) & (last[body] <= t_win)
                return loose[body] & (model.fixed[body] | (first_only & (win_hi[body] == win_lo[body])))

            return candidate & once(c.a) & once(c.b)

        early = t_win <= 0.5 * dt
        window, window_late = alone(eligible & early), alone(eligible & ~early)

        # 2. Contact forces over the step (eq. 39); gap evaluated exactly at the predictor.
        # The force acts along the normal of the mid-step configuration: normal to the chord
        # of the motion, so a frictionless sustained contact does no work (energy is kept on
        # curved tracks; with the start normal it would do work p n.d every step).
        # The predictor is the free motion plus last step's contact forces (applied in the
        # mid-step frame of a first predictor): in a steady contact it is close to the
        # solution, so the frame holds no motion that the contacts cancel (a tilt predicted
        # from the free acceleration alone shifts every lever arm: 0.15 N in case 7.6).
        d_base = free_displacement(flex, mass, load, v_star, dt) + shift
        d_pred = d_base + respond(flex, mid_frame(d_base + push0)[0], c, p_prior)
        if pinned:
            # A pinned body turns about its pin with the lever of the mid-step configuration
            # (on the predictor's arc), as contact forces act in the mid-step frame: the torque
            # of its weight is then the midpoint rule's and a pendulum keeps its energy (with
            # the start lever it gains energy at first order, 1.5 % in 2 s at dt = 2 ms).
            maps_mid = pins.pin_maps(model, maps, pins.mid_centroid(model, centroid, d_pred))
            flex = groups.grouped(k_eff, proj, model, maps_mid, coupling)
            d_base = free_displacement(flex, mass, load, v_star, dt) + shift
            d_pred = d_base + respond(flex, mid_frame(d_base + push0)[0], c, p_prior)
        change_pred = gap_change_by(d_pred)
        gap_pred = gap0 + change_pred
        # ... and only where it is the only force on its free bodies: no other of their
        # contacts is loaded or may close in the step (a light ring struck while heavy bodies
        # squeeze it: the squeeze's forces act over the whole step, and the window's extra
        # impulse q dt t* / h on the ring, unbalanced, threw it at 200 m/s).
        def uncrowded(window):
            other = c.valid & ~window & (sustained | cemented | (gap_pred <= params.margin))
            others = other.astype(jnp.int32)
            crowded = (jax.ops.segment_sum(others, c.a, n) + jax.ops.segment_sum(others, c.b, n) > 0) & ~model.fixed
            return window & ~crowded[c.a] & ~crowded[c.b]

        windowed, lone_late = uncrowded(window), uncrowded(window_late)
        # Per body: the start of its window (its clock, or the impact on the other body of its
        # windowed contacts), 0 for bodies without one.
        def start_of(rows):  # per free body: the latest t_win of its ``rows``, 0 for none
            t = jnp.maximum(jax.ops.segment_max(jnp.where(rows, t_win, 0.0), c.a, n),
                            jax.ops.segment_max(jnp.where(rows, t_win, 0.0), c.b, n))
            return jnp.where(model.fixed, 0.0, jnp.maximum(t, 0.0))

        t_body = start_of(windowed)

        # 1b. Forces before an impact: a windowed sustained contact (a body resting on or
        # pressed against another when a third strikes it at t*) carries a force p over
        # [0, t*] that the impact does not see as an impulse, and that ends at t*, where the
        # window's force takes over. It is solved on its own: the contact problem over [0, t*]
        # (the gap at t* and the slip over [0, t*]; its unknown q = p (t* / dt)^2 moves the
        # bodies by K_eff^-1 q = M^-1 p t*^2 / 2), linearised at the motion to t* under last
        # step's forces. The impact is then solved again on the velocities at t* that p gives.
        # With p over the whole step instead, a force that drops at the impact (a light disk
        # squeezed by a heavy one, knocked off it by a third body) did work and made 10 J in a
        # step (fuzz seed 367). Its gap row asks only for the overlap the step starts with,
        # not more: pushing an overlap out is the window's work, bounded as any step's.
        # A late impact (t* > dt / 2, no window) on a body that is alone with it and with one
        # sustained contact sizes its impulse on the same forces before t*: solved so, they
        # set its velocity at t* only, and the contact's force still acts over the whole step.
        # Sized on last step's force instead (a ring pushed by the triangle in its hole with
        # 8.7 kN, 2.5 kN this step), the impulse was 3.4 times too large, and the impact with
        # e = 0.29 made 3.6 J (fuzz seed 16779).
        pre = (windowed | lone_late) & sustained & (t_win > SIMULTANEITY * dt)
        tau = t_body / dt
        t_pre = start_of(windowed | lone_late)  # the end of the span its forces before t* are solved over
        tau_pre = t_pre / dt
        share = jnp.where(pre, (t_win / dt) ** 2, 1.0)  # q = p share
        u_free = vel * t_pre[:, None] + (d_free - vel * dt) * (tau_pre ** 2)[:, None]  # to t*, no contact force
        u_lin = vel * t_pre[:, None] + 0.5 * accel * (t_pre ** 2)[:, None]  # to t*, last step's forces
        change_lin = gap_change_by(u_lin)
        jac_pre, normal_pre, _ = mid_frame(u_lin)
        jac_pre = discrete_gradient(jac_pre, c, u_lin, change_lin, model.bound_radius)
        end_pre, opposes_pre = kinds(apply_jacobian(jac_pre, c, 0.5 * vel * t_pre[:, None]), held_by(jnp.zeros_like(p0)))
        b_pre = apply_jacobian(jac_pre, c, u_free) - end_pre
        b_pre = b_pre.at[:, 0].set(gap0 + change_lin - apply_jacobian(jac_pre, c, u_lin - u_free)[:, 0] - jnp.minimum(gap0, 0.0))
        pre_sets = sets._replace(enabled=pre, opposes=opposes_pre, cohesion=sets.cohesion * share, tension=zero)
        op_pre, diag_pre = flexibility(jac_pre, c, flex)
        least = jnp.min(jnp.where(pre, share, 1.0), initial=1.0)
        before = fista_newton.solve(apply_w, op_pre, diag_pre, b_pre, pre_sets, p_prior * share[:, None], params.tol,
                          params.max_iter, least * momentum / dt)
        p_pre = jnp.where(pre[:, None], before.force / share[:, None], 0.0)
        # K_eff^-1 J^T p: the displacement p would give over the whole step (M^-1 p dt^2 / 2).
        by_pre = respond(flex, jac_pre, c, p_pre)
        by_prior = respond(flex, jac, c, jnp.where(pre[:, None], p_prior, 0.0))
        accel_pre = accel + 2.0 * (by_pre - by_prior) / dt ** 2
        p_pre = jnp.where(windowed[:, None], p_pre, 0.0)  # a late impact's: only for its velocity at t*
        by_pre = respond(flex, jac_pre, c, p_pre)
        (_, vel_a), (_, vel_b) = path(t_hit, 0, accel_pre), path(t_hit, 1, accel_pre)
        v_hit = jnp.einsum("cij,cj->ci", jac_hit[:, 0], vel_a) + jnp.einsum("cij,cj->ci", jac_hit[:, 1], vel_b)
        return _Ahead(v_hit=v_hit, accel=accel_pre, clock=clock, windowed=windowed, t_win=t_win, t_body=t_body,
                      tau=tau, p_pre=p_pre, by_pre=by_pre, normal_pre=normal_pre, before=before,
                      k_inv=flex if pinned else None)

    idle = _Ahead(v_hit=jnp.zeros_like(v_hit), accel=jnp.zeros_like(accel), clock=jnp.zeros_like(model.bound_radius),
                  windowed=jnp.zeros_like(c.valid), t_win=zero, t_body=jnp.zeros_like(model.bound_radius),
                  tau=jnp.zeros_like(model.bound_radius), p_pre=jnp.zeros_like(p0), by_pre=jnp.zeros_like(accel),
                  normal_pre=jnp.zeros_like(normal),
                  before=fista_newton.Solution(jnp.zeros_like(p0), jnp.zeros((), jnp.int32), jnp.zeros((), p0.dtype),
                                     jnp.ones((), bool)),
                  k_inv=k_inv if pinned else None)

    def impact_round(carry, again):
        v_hit, warm = carry
        imp, phases = _poisson_impact(op_m, diag_m, v_hit, imp_sets, bounce, params, momentum, warm=warm)
        ahead = jax.lax.cond(again, lambda _: idle, forces_before, imp)
        return (ahead.v_hit, phases), (imp, ahead)

    _, (rounds, aheads) = jax.lax.scan(impact_round, (v_hit, (jnp.zeros_like(v_hit), jnp.zeros_like(v_hit))),
                                       jnp.arange(2) > 0)
    imp_first, imp = (jax.tree.map(lambda x: x[i], rounds) for i in (0, 1))
    ahead = jax.tree.map(lambda x: x[0], aheads)
    accel, clock, windowed, t_win, t_body = ahead.accel, ahead.clock, ahead.windowed, ahead.t_win, ahead.t_body
    tau, p_pre, by_pre, normal_pre, before = ahead.tau, ahead.p_pre, ahead.by_pre, ahead.normal_pre, ahead.before
    if pinned:
        k_inv = ahead.k_inv
    v_star = vel + respond(m_inv, jac_hit, c, imp.force)
    # p acts until t*: the velocity changes by M^-1 p t* (= 2 by_pre tau / dt), the
    # displacement by M^-1 p (t* dt - t*^2 / 2) (= by_pre (2 tau - tau^2)).
    shift = -(v_star - vel) * clock[:, None] + by_pre * (tau * (1.0 - tau))[:, None]
    d_base = free_displacement(k_inv, mass, load, v_star, dt) + shift + by_pre * tau[:, None]
    carried = jnp.where(windowed[:, None], 0.0, p_prior)  # a windowed contact's force acts from t* only
    d_pred = d_base + respond(k_inv, mid_frame(d_base + push0)[0], c, carried)
    change_pred = gap_change_by(d_pred)
    rest = jnp.where(windowed, dt - t_win, dt)
    late = jnp.where(windowed, t_win * dt / rest, 0.0)
    u_clock = vel * t_body[:, None] + 0.5 * accel * (t_body ** 2)[:, None]  # each body's motion until its window
    v_clock = v_star + accel * t_body[:, None]
    held = held_by(imp.force)

    def linearised(d_lin, change_lin):
        """The contact problem linearised at the displacement d_lin (its gaps' exact change
        ``change_lin``): its frame, b and sets."""
        jac, nrm, pt = mid_frame(d_lin)
        # The normal row as the discrete gradient of the gap over the motion to d_lin: the
        # normal force then does no work on a closed contact (energy, see discrete_gradient).
        jac = discrete_gradient(jac, c, d_lin, change_lin, model.bound_radius)
        jac_win, nrm_win, pt_win = mid_frame(d_lin, u_clock)
        jac_win = discrete_gradient(jac_win, c, d_lin - u_clock, change_lin - gap_change_by(u_clock), model.bound_radius)
        jac = jnp.where(windowed[:, None, None, None], jac_win, jac)
        nrm = jnp.where(windowed[:, None], nrm_win, nrm)
        pt = jnp.where(windowed[:, None], pt_win, pt)
        # G(p) = W p + b: the gap at d_lin plus the linear change from it. The shear
        # gap is the paper's relative motion over the step, J_t (d - shift), on a contact that
        # stuck last step (and did not slide in this step's impacts): its shear force then does
        # no work while a body turns about it (the tipping block; with the velocity-level row
        # it does work p_t (dt / 2) J_t v*, where the lever's turn since the last step leaves
        # J_t v* = O(omega^2 r dt): energy grows at first order). Elsewhere, and on the rolling
        # row, it is taken at velocity level: (dt / 2) times the relative velocity at the
        # step's end, v+ = 2 (d - shift) / dt - v* (Moreau's Coulomb law). A contact that
        # starts to stick then ends the step at rest, not at -v: with the relative motion, a
        # block that stops by friction keeps a velocity that flips sign every step (d = 0
        # gives v+ = -v). The sign of the two agrees whenever the motion does not reverse
        # inside the step, so sliding is unchanged. A windowed contact's rows run over h from t*.
        end_velocity = jnp.where(windowed[:, None], 0.5 * rest[:, None] * apply_jacobian(jac, c, v_clock),
                                 apply_jacobian(jac, c, 0.5 * dt * v_star))
        end_velocity, opposes = kinds(end_velocity, held)
        since = jnp.where(windowed[:, None], apply_jacobian(jac, c, u_clock), apply_jacobian(jac, c, shift))
        b = apply_jacobian(jac, c, d_base) - since - end_velocity
        b = b.at[:, 0].set(gap0 + change_lin - apply_jacobian(jac, c, d_lin - d_base)[:, 0])
        con_sets = sets._replace(opposes=opposes, cohesion=sets.cohesion * (rest / dt) ** 2)
        return jac, nrm, pt, b, con_sets

    # The problem is linearised at the predictor, solved, and linearised again at each
    # solution's motion, and solved from its forces, LINEARISATIONS times: a linearisation
    # misplaces the end gap by the second-order change over the distance from where it
    # was taken to the solution (a block spun by its impacts into a corner: 0.1 of its size
    # inside it with one, fuzz seeds 656, 2519, 2686, 3901). One solve in a loop: the
    # solver is most of the step's compiled code.
    # A ring's hole holds its disk (or corner) in a convex set, which every linearisation of
    # the gap approximates from outside: at a normal off the solution's by phi the body
    # ends up to (clearance) phi^2 / 2 beyond the hole's edge, and linearising again need
    # not converge (a heavy disk squeezing a light ring against a wall: the ring's normal
    # swings with each linearisation; fuzz seed 7013, 0.37 of the disk's radius inside the
    # ring). Each solve's normal row is kept in the next as a cut (a frictionless row on
    # the same contact), so its solution satisfies both linearisations. The cut
    # allows an overlap of CUT_SLACK of the smaller body: where the normal barely swung, the
    # two rows are near-duplicates whose linearisations disagree by round-off (1e-12 m),
    # which a stiff contact turns into a conflict the solve stalls on (fuzz seed 58, step
    # 34: 239 iterations; 3 with the slack). The rows are 2C: the contacts', then the cuts'.
    force_scale = momentum / dt
    n_rows = gap0.shape[0]
    rows = jax.tree.map(lambda x: jnp.concatenate([x, x]), c)
    off = jnp.zeros_like(gap0)
    slack = CUT_SLACK * jnp.minimum(model.bound_radius[c.a], model.bound_radius[c.b])

    # The passes after LINEARISATIONS run only where the last solve's motion still overlaps
    # a contact by more than the cut's slack (a 3.6 kg ring reversed from -11 to +14 m/s
    # between a 41 t block and a 4.9 t disk ended 1.3e-4 m inside the block after two,
    # 2.35 times the second-order bound of its motion: fuzz seed 9853). Not in every step:
    # where the two rows of a hole are both active and near-parallel, a third solve can
    # stall on them (seed 567: 20 000 iterations, unconverged), while two had left no
    # overlap. A skipped pass keeps the last one's solution (a cond: the solver is traced once).
    def relinearise(carry, k):
        d_lin, warm, jac_cut, b_cut, last, nrm_before = carry
        change_lin = gap_change_by(d_lin)
        run = (k < LINEARISATIONS) | jnp.any(c.valid & (gap0 + change_lin < -slack))

        def solve_at(_):
            jac_l, nrm, pt, b_l, con_sets = linearised(d_lin, change_lin)
            cut = (k > 0) & con_sets.enabled & (c.btype == B_HOLE)
            two_sets = ContactSets(
                enabled=jnp.concatenate([con_sets.enabled, cut]),
                friction=jnp.concatenate([con_sets.friction, off]), cohesion=jnp.concatenate([con_sets.cohesion, off]),
                tension=jnp.concatenate([con_sets.tension, off]), rolling=jnp.concatenate([con_sets.rolling, off]),
                partner=jnp.concatenate([con_sets.partner, jnp.full_like(con_sets.partner, -1)]),
                opposes=jnp.concatenate([con_sets.opposes, jnp.zeros_like(con_sets.opposes)]))
            jac_two = jnp.concatenate([jac_l, jac_cut])
            op, diag = flexibility(jac_two, rows, k_inv)
            b_two = jnp.concatenate([b_l, b_cut.at[:, 0].add(slack)])
            sol = fista_newton.solve(apply_w, op, diag, b_two, two_sets, warm, params.tol, params.max_iter, force_scale)
            d_next = d_base + respond(k_inv, jac_two, rows, sol.force)
            warm_next = jnp.concatenate([sol.force[:n_rows], jnp.zeros_like(p0)])
            return (d_next, warm_next, jac_l, b_l, (jac_two, nrm, pt, b_l, con_sets, sol), last[1]), sol._replace(force=())

        skipped = fista_newton.Solution((), jnp.zeros((), jnp.int32), jnp.zeros((), p0.dtype), jnp.ones((), bool))
        return jax.lax.cond(run, solve_at, lambda _: (carry, skipped), None)

    none = (jnp.zeros((2 * n_rows,) + jac.shape[1:], jac.dtype), jnp.zeros_like(normal), jnp.zeros_like(point),
            jnp.zeros_like(p0), sets._replace(opposes=jnp.zeros(p0.shape[:1] + (2,), p0.dtype)),
            fista_newton.Solution(jnp.zeros((2 * n_rows, 3), p0.dtype), jnp.zeros((), jnp.int32), jnp.zeros((), p0.dtype),
                        jnp.ones((), bool)))
    start = (d_pred, jnp.concatenate([p0, jnp.zeros_like(p0)]), jnp.zeros_like(jac), jnp.zeros_like(p0), none,
             jnp.zeros_like(normal))
    (d_geo, _, _, _, last, normal_cut), passes = jax.lax.scan(
        relinearise, start, jnp.arange(LINEARISATIONS + EXTRA_LINEARISATIONS))
    jac_two, normal_mid, point_mid, b_con, con_sets, both = last
    op_k, diag_k = flexibility(jac_two, rows, k_inv)
    con, p_cut = both._replace(force=both.force[:n_rows]), both.force[n_rows:]

    # 4. Integrate: Newmark velocity from d; geometry from d plus the impact shift.
    v_newmark = newmark_velocity(d_geo - shift, v_star, dt, proj)
    # A windowed force's late impulse holds a body that its impact stopped at t*: it
    # cancels the approach Newmark's velocity leaves (a block landing inside the step
    # rests), and never opens a contact. Where the impact did not stop the body (a heavy
    # disk pressing a light ring against a wall: the ring squirts out of the impact along
    # the hole, and the solve stops the disk over h), the position-level stop leaves v+ =
    # v (2 t* / dt - 1), and the whole kick would reflect it to -v, out with its speed
    # (fuzz seed 598: energy +190 J in a step). Each row's kick is cut to what cancels its
    # approach, and the kicks of a cluster of bodies joined by kicked rows share the
    # smallest cut: they are internal forces, and a share of them alone would throw the
    # pinched ring (1e7 N on 0.27 kg).
    kick = both.force * jnp.concatenate([late, late])[:, None]
    kick_vel = matvec(proj, respond(m_inv, jac_two, rows, kick))
    rate, rate_kick = apply_jacobian(jac_two, rows, v_newmark)[:, 0], apply_jacobian(jac_two, rows, kick_vel)[:, 0]
    kicked = jnp.any(kick != 0.0, -1)
    cut_to = jnp.where(kicked & (rate_kick > 0), jnp.clip(-rate / jnp.where(rate_kick > 0, rate_kick, 1.0), 0.0, 1.0), 1.0)
    kick = kick * cluster_min(cut_to, kicked, rows.a, rows.b, model.fixed)[:, None]
    new_vel = v_newmark + matvec(proj, respond(m_inv, jac_two, rows, kick))

    gap_end = apply_w(op_k, both.force)[:n_rows, 0] + b_con[:, 0]
    rest_mean = (dt / rest)[:, None]  # a windowed force acts over h: its mean over the step
    parts = ((imp.force / dt, normal_hit), (con.force * rest_mean, normal_mid), (p_cut * rest_mean, normal_cut),
             (p_pre * (t_win / dt)[:, None], normal_pre))  # the force before an impact, over the step
    return Resolution(displacement=d_geo, velocity=new_vel,
                      memory=con.force.at[:, 0].add(p_cut[:, 0]),  # a contact's normal force: both rows'
                      force=con.force, gap_end=gap_end, w_nn=diag_k[:n_rows, 0], force_scale=force_scale,
                      point=point_mid, normal=normal_mid, parts=parts, solutions=(imp_first, before, imp, passes))
