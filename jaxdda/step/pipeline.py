"""One PB-DDA time step as a pipeline of stages (paper Section 4), and its rollout.

    assemble -> detect (contact frame) -> predict -> impacts -> contact VI -> end -> rupture
    -> update -> report
"""
from __future__ import annotations

import jax
import jax.numpy as jnp

from jaxdda.connectors import connector_forces
from jaxdda.solver import fista_newton
from jaxdda.step.frame import contact_frame
from jaxdda.step.operators import assemble
from jaxdda.step.report import contact_report, step_info
from jaxdda.step.jump import impact_rows
from jaxdda.step.predict import predict
from jaxdda.step.resolve import impacts_then_contacts, step_end
from jaxdda.step.rupture import rupture
from jaxdda.step.update import update
from jaxdda.types import Model, Params, State, StepInfo


def step(model: Model, state: State, params: Params) -> tuple[State, StepInfo]:
    """Advance one step of length params.dt. Pure: jit, vmap and scan apply."""
    base = model
    with jax.named_scope("assemble"):
        model, ops = assemble(base, state, params)
    with jax.named_scope("detect"):
        frame = contact_frame(model, state, params)
    with jax.named_scope("predict"):
        pred = predict(model, state, params, ops, frame)
    with jax.named_scope("impacts"):
        rows = impact_rows(model, state, params, ops, frame, pred)
    with jax.named_scope("solves"):
        solved = impacts_then_contacts(model, state, params, ops, frame, pred, rows)
    with jax.named_scope("end"):
        res = step_end(model, params, ops, frame, rows, solved)
    with jax.named_scope("rupture"):
        integrity, tension = rupture(model, state, params, frame.cemented, frame.joint, res.force, res.gap_end,
                                     res.w_nn, res.force_scale)
    with jax.named_scope("update"):
        new_state = update(base, model, state, params, ops, res.displacement, res.velocity, frame.contacts.key,
                           res.memory, integrity)
    with jax.named_scope("report"):
        report = contact_report(frame, res.point, res.normal, res.parts)
        info = step_info(model, frame, res.solutions, integrity, tension, connector_forces(base, params, new_state),
                         report)
    return new_state, info


_traced_step = jax.jit(step)  # a nested jit: its trace is cached, so step_if traces the step once


def step_if(run: jax.Array, model: Model, state: State, params: Params) -> tuple[State, StepInfo]:
    """``step`` where ``run`` (a traced bool), else (``state``, a zero info), for a scan
    whose tail is padding. The info's shapes and the step share one trace (the step's
    trace is seconds: a second one, for its shapes alone, doubled it)."""
    info = jax.eval_shape(_traced_step, model, state, params)[1]

    def skip(s):
        return s, jax.tree.map(lambda x: jnp.zeros(x.shape, x.dtype), info)

    return jax.lax.cond(run, lambda s: _traced_step(model, s, params), skip, state)


def rollout(model: Model, state: State, params: Params, steps: int, *, checkpoint: bool = True):
    """Scan ``step`` ``steps`` times. Returns (final state, (states, infos)) where
    ``states`` stacks the state after each step.

    Differentiable in ``params`` and ``state`` (forward and reverse mode). With
    ``checkpoint`` each step is recomputed in the reverse pass (``jax.checkpoint``) but
    its contact solves, whose results are kept (``fista_newton.SOLUTION``): reverse-mode
    memory grows with the number of steps only, not with the solver's work, and the
    reverse pass runs no solver loop.
    """
    def body(s, _):
        s2, info = step(model, s, params)
        return s2, (s2, info)

    if checkpoint:
        body = jax.checkpoint(body, policy=jax.checkpoint_policies.save_only_these_names(fista_newton.SOLUTION))
    return jax.lax.scan(body, state, None, length=steps)
