"""Stage "report": the step's contact forces in the global frame and its diagnostics."""
from __future__ import annotations

import dataclasses
from typing import Sequence

import jax
import jax.numpy as jnp

from jaxdda.contact.kinematics import clockwise
from jaxdda.solver.fista_newton import Solution
from jaxdda.step.frame import ContactFrame
from jaxdda.types import NO_JOINT, ContactReport, Model, StepInfo


def to_global(p: jax.Array, normal: jax.Array) -> jax.Array:
    """(C, 2) the normal and shear parts of p (C, 3) in the global frame."""
    return p[:, :1] * normal + p[:, 1:2] * clockwise(normal)


def contact_report(frame: ContactFrame, point: jax.Array, normal: jax.Array,
                   parts: Sequence[tuple[jax.Array, jax.Array]]) -> ContactReport:
    """The report of each contact, its force the sum of ``parts``: (mean force (C, 3)
    over the step in its frame, that frame's normal (C, 2)), e.g. an impact's impulse
    over dt and the contact force; reported at ``point`` in the frame of ``normal``."""
    c = frame.contacts
    total = to_global(*parts[0])
    bearing, moment = parts[0][0][:, 0], parts[0][0][:, 2]
    for p, nrm in parts[1:]:
        total, bearing, moment = total + to_global(p, nrm), bearing + p[:, 0], moment + p[:, 2]
    force = jnp.where(c.valid[:, None], total, 0.0)
    return ContactReport(
        valid=c.valid, a=c.a, b=c.b, point=point, normal=normal,
        normal_force=jnp.sum(force * normal, -1), shear_force=jnp.sum(force * clockwise(normal), -1),
        force=force, moment=jnp.where(c.valid, moment, 0.0), cemented=frame.cemented, gap=frame.gap0,
        bearing=jnp.where(c.valid, bearing, 0.0))


def step_info(model: Model, frame: ContactFrame, solutions: Sequence[Solution], joint_integrity: jax.Array,
              joint_tension: jax.Array, connector_force: jax.Array, report: ContactReport) -> StepInfo:
    """The step's diagnostics: its solves (each possibly stacked over a loop) summed."""
    c = frame.contacts
    capacity = jnp.array(dataclasses.astuple(model.capacity), jnp.int32)
    return StepInfo(
        iterations=sum(jnp.sum(s.iterations, dtype=jnp.int32) for s in solutions),
        residual=jnp.max(jnp.stack([jnp.max(s.residual) for s in solutions])),
        converged=jnp.all(jnp.stack([jnp.all(s.converged) for s in solutions])),
        needed=frame.needed,
        overflow=jnp.any(frame.needed > capacity),
        n_contacts=jnp.sum(c.valid).astype(jnp.int32),
        max_penetration=jnp.maximum(0.0, -jnp.min(jnp.where(c.valid, frame.gap0, 0.0))),
        joint_tension=joint_tension,
        joint_broken=(joint_integrity <= 0) & (model.joint_key != NO_JOINT),
        connector_force=connector_force,
        contacts=report,
    )
