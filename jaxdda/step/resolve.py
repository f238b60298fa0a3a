"""The step's two contact solves through one jitted solver, and its end (docs/design.md,
"The step"): the impacts' compression P1 (stage "impacts"), then the contact VI from the
velocity jump it gives (stage "contact VI"); the end displacement and velocity."""
from __future__ import annotations

from typing import NamedTuple

import jax
import jax.numpy as jnp

from jaxdda.contact.kinematics import apply_jacobian
from jaxdda.integrate import matvec, newmark_velocity
from jaxdda.solver import fista_newton
from jaxdda.solver.fista_newton import Problem
from jaxdda.step.contact_vi import Linearised, contact_problem
from jaxdda.step.frame import ContactFrame
from jaxdda.step.impacts import cluster_min
from jaxdda.step.jump import ImpactRows, Jump, Window, velocity_jump
from jaxdda.step.operators import Operators, apply_w, flexibility, respond
from jaxdda.step.predict import Prediction
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


class Solved(NamedTuple):
    """The two solves: the velocity jump, the contact VI and its solution."""

    jump: Jump
    problem: Problem
    linearised: Linearised
    solutions: fista_newton.Solution  # stacked: [impacts, contact VI]


# The solver, jitted: traced once per problem size, one function of the step's program.
_solve = jax.jit(fista_newton.solve, static_argnums=(0, 9))


def impacts_then_contacts(model: Model, state: State, params: Params, ops: Operators, frame: ContactFrame,
                          pred: Prediction, rows: ImpactRows) -> Solved:
    """The impact solve (compression P1 on ``rows``), then the contact VI built from its
    velocity jump. Run as two phases of one loop around one solve, so the solver is in the
    program once (XLA inlines a function at each call: two calls were two copies); its
    derivative is that of the two solves in turn (a loop's derivative keeps each phase's
    intermediates of both problems: a 10-step incline's value_and_grad was 9 596 kernels,
    4 662 in turn)."""
    return _two_solves(model, state, params, ops, frame, pred, rows)


def _phases(model: Model, state: State, params: Params, ops: Operators, frame: ContactFrame, pred: Prediction,
            rows: ImpactRows):
    """The impact problem, the contact problem from the compression P1, and the solve."""
    op_m, diag_m = flexibility(rows.jac, frame.contacts, ops.m_inv)
    impacts = Problem(op_m, diag_m, rows.v_minus, rows.sets, jnp.zeros_like(frame.p0), ops.momentum)

    @jax.jit  # traced once, however often it is called
    def contacts(p1):
        jump = velocity_jump(model, params, ops, frame, pred, rows, op_m, p1)
        return (jump, *contact_problem(model, state, params, ops, frame, pred, rows, jump))

    def solve(problem):
        return _solve(apply_w, problem.operand, problem.w_diag, problem.b, problem.sets, problem.warm, params.tol,
                      params.max_iter, problem.force_scale, model.options.newton_finish)

    return impacts, contacts, solve


def _in_turn(*args) -> Solved:
    impacts, contacts, solve = _phases(*args)
    first = solve(impacts)
    jump, problem, lin = contacts(first.force)
    sols = jax.tree.map(lambda a, b: jnp.stack([a, b]), first, solve(problem))
    return Solved(jump=jump, problem=problem, linearised=lin, solutions=sols)


def _in_one_loop(*args) -> Solved:
    impacts, contacts, solve = _phases(*args)
    none = jax.tree.map(jnp.zeros_like, jax.eval_shape(contacts, impacts.warm))

    def phase(i, carry):
        sols, _, _, _ = carry
        jump, problem, lin = jax.lax.cond(i == 0, lambda: (none[0], impacts, none[2]),
                                          lambda: contacts(sols.force[0]))
        sol = solve(problem)
        return jax.tree.map(lambda s, x: s.at[i].set(x), sols, sol), jump, problem, lin

    sols = jax.tree.map(lambda a: jnp.zeros((2,) + a.shape, a.dtype), jax.eval_shape(solve, impacts))
    sols, jump, problem, lin = jax.lax.fori_loop(0, 2, phase, (sols, none[0], impacts, none[2]))
    return Solved(jump=jump, problem=problem, linearised=lin, solutions=sols)


_two_solves = jax.custom_jvp(_in_one_loop)
_two_solves.defjvp(lambda primals, tangents: jax.jvp(_in_turn, primals, tangents))


def step_end(model: Model, params: Params, ops: Operators, frame: ContactFrame, rows: ImpactRows,
             solved: Solved) -> Resolution:
    """d = d_base + K^-1 J^T p (eq. 41), the Newmark velocity from it (with each windowed
    force's late impulse), and what rupture and the report read."""
    c, dt, proj = frame.contacts, params.dt, model.dof_projector
    jump, problem, lin = solved.jump, solved.problem, solved.linearised
    jac, flex = problem.operand.jac, problem.operand.inv
    con = solved.solutions.force[1]
    d = lin.d_base + respond(flex, jac, c, con)
    v_newmark = newmark_velocity(d - jump.shift, jump.v_star, dt, proj)
    new_vel = v_newmark
    if model.options.windows:
        kick = late_kick(model, c, jac, ops, jump.win, con, v_newmark, params)
        new_vel = new_vel + matvec(proj, respond(ops.m_inv, jac, c, kick))
    rest_mean = (dt / jump.win.rest)[:, None]  # a windowed force acts over h: its mean over the step
    return Resolution(displacement=d, velocity=new_vel, memory=con, force=con,
                      gap_end=apply_w(problem.operand, con)[:, 0] + problem.b[:, 0], w_nn=problem.w_diag[:, 0],
                      force_scale=problem.force_scale, point=lin.point, normal=lin.normal,
                      parts=((jump.impulse / dt, rows.normal), (con * rest_mean, lin.normal)),
                      solutions=(solved.solutions,))


def late_kick(model: Model, c, jac: jax.Array, ops: Operators, win: Window, con: jax.Array, v_newmark: jax.Array,
              params: Params) -> jax.Array:
    """A windowed force's late impulse q dt t* / h: it holds a body its impact stopped at t*
    (cancels the approach Newmark's velocity leaves; a block landing inside the step rests),
    and never opens a contact. Each row's kick is cut to what cancels its approach, and a
    cluster of bodies joined by kicked rows shares the smallest cut (internal forces)."""
    late = jnp.where(win.windowed, win.t_win * params.dt / win.rest, 0.0)
    kick = con * late[:, None]
    kick_vel = matvec(model.dof_projector, respond(ops.m_inv, jac, c, kick))
    rate, rate_kick = apply_jacobian(jac, c, v_newmark)[:, 0], apply_jacobian(jac, c, kick_vel)[:, 0]
    kicked = jnp.any(kick != 0.0, -1)
    cut_to = jnp.where(kicked & (rate_kick > 0), jnp.clip(-rate / jnp.where(rate_kick > 0, rate_kick, 1.0), 0.0, 1.0),
                       1.0)
    return kick * cluster_min(cut_to, kicked, c.a, c.b, model.fixed)[:, None]
