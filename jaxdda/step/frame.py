"""Stage "detect": this step's contacts, their frame at the start (gap, normal, point,
Jacobian; paper eqs. 9-19, 93-105) and their constraint data (friction, cohesion,
cement, rolling; eqs. 58-65), with last step's forces of the same feature pairs.
"""
from __future__ import annotations

from typing import NamedTuple

import jax
import jax.numpy as jnp

from jaxdda import pins
from jaxdda.contact.adjoint import adjoint_partner
from jaxdda.contact.detect import contact_materials, detect
from jaxdda.contact.keys import lookup
from jaxdda.contact.kinematics import gap_change, gap_frame, jacobians
from jaxdda.solver.sets import ContactSets
from jaxdda.step.operators import is_pinned
from jaxdda.types import POLYGON, Contacts, Model, Params, State


class ContactFrame(NamedTuple):
    """The step's contacts at its start."""

    contacts: Contacts
    needed: jax.Array  # (5,) int32 buffer slots the detection needed
    gap0: jax.Array  # (C,) gap at the start, exact to the displacement since the origin
    normal: jax.Array  # (C, 2)
    point: jax.Array  # (C, 2)
    jac: jax.Array  # (C, 2, 3, 6) the rows of each contact's two bodies (eq. 9)
    sets: ContactSets  # friction, cohesion, cement tension, rolling, adjoint partner
    cemented: jax.Array  # (C,) bool: an intact cemented joint
    joint: jax.Array  # (C,) int index of its joint (where cemented)
    restitution: jax.Array  # (C,) e of the pair's materials
    p0: jax.Array  # (C, 3) last step's force of the same feature pair (0 for a new contact)
    touch: jax.Array  # (C,) a gap within round-off of the coordinates it comes from (64 ulp)


def detection_reach(model: Model, state: State, params: Params) -> tuple[jax.Array, jax.Array]:
    """Per body: the distance (N,) it may travel this step plus half the margin d0, and
    the angle (N,) it may turn.

    Twice the velocity terms: an impact may reverse a body, and a pair is checked with
    the sum of its two reaches, so impacts falling anywhere inside the step are found.
    """
    spin = jnp.abs(state.velocity[:, 2])
    speed = jnp.linalg.norm(state.velocity[:, :2], axis=-1) + spin * model.bound_radius
    accel = jnp.linalg.norm(params.gravity) * model.gravity_scale
    reach = 2.0 * params.dt * speed + params.dt ** 2 * accel + 0.5 * params.margin
    turn = 2.0 * params.dt * spin
    return jnp.where(model.fixed, 0.5 * params.margin, reach), jnp.where(model.fixed, 0.0, turn)


def warm_start(prev_key: jax.Array, prev_force: jax.Array, key: jax.Array) -> jax.Array:
    """Last step's force of the same feature pair, else zero."""
    idx, found = lookup(prev_key, key)
    return jnp.where(found[:, None], prev_force[idx], 0.0)


def contact_sets(model: Model, state: State, params: Params, c: Contacts, normal: jax.Array):
    """The constraint data of this step's contacts, and which are cemented joints (not
    broken). A joint's strength is t times its integrity; adjoint joints share the
    smaller of their two integrities (one budget per pair, as ``solver.sets`` needs)."""
    mat_a, mat_b = contact_materials(model, c)
    joint, is_joint = lookup(model.joint_key, c.key)
    integrity = jnp.where(c.valid & is_joint, state.joint_integrity[joint], 0.0)
    cemented = integrity > 0
    partner = adjoint_partner(model, c, normal)
    with_partner = (partner >= 0) & cemented[jnp.maximum(partner, 0)]
    integrity = jnp.where(with_partner, jnp.minimum(integrity, integrity[jnp.maximum(partner, 0)]), integrity)
    particle = (model.kind[c.a] != POLYGON) | (model.kind[c.b] != POLYGON)
    sets = ContactSets(
        enabled=c.valid,
        friction=params.friction[mat_a, mat_b],
        cohesion=params.cohesion[mat_a, mat_b],
        tension=params.tensile[mat_a, mat_b] * integrity,
        rolling=jnp.where(particle, params.rolling[mat_a, mat_b], 0.0),
        partner=partner,
    )
    return sets, cemented, joint


def contact_frame(model: Model, state: State, params: Params) -> ContactFrame:
    """Detect the step's contacts and take their frame at the start. Detection is
    discrete (which pairs to test): no derivative flows through it."""
    centroid = state.centroid
    c, needed = detect(model, *jax.lax.stop_gradient(
        (centroid, state.rotation, *detection_reach(model, state, params), params.margin)))
    gap_now, normal, point = gap_frame(c, centroid, state.rotation)
    jac = jacobians(c, normal, point, gap_now, centroid)
    # Gaps as (gap at the origin) + (exact change over the displacement since): a body
    # at 50 m that moved 1e-13 m keeps its gaps exact, not rounded to ulp(50 m).
    gap_ref = gap_frame(c, state.origin, jnp.zeros_like(state.rotation))[0]
    gap0 = gap_ref + gap_change(c, state.origin, jnp.zeros_like(state.rotation), state.displacement, state.rotation)
    sets, cemented, joint = contact_sets(model, state, params, c, normal)
    restitution = params.restitution[contact_materials(model, c)]
    p0 = warm_start(state.contact_key, state.contact_force, c.key)
    reach = jnp.maximum(jnp.max(jnp.abs(state.origin[c.a]), -1), jnp.max(jnp.abs(state.origin[c.b]), -1))
    touch = 64.0 * jnp.finfo(gap0.dtype).eps * (reach + model.bound_radius[c.a] + model.bound_radius[c.b])
    return ContactFrame(contacts=c, needed=needed, gap0=gap0, normal=normal, point=point, jac=jac, sets=sets,
                        cemented=cemented, joint=joint, restitution=restitution, p0=p0, touch=touch)


def gap_change_by(model: Model, state: State, c: Contacts, d: jax.Array) -> jax.Array:
    """The exact change (C,) of the gaps over the step's displacement d (N, 6); a pinned
    body moves on the arc about its pin."""
    centroid = state.centroid
    d_c = pins.centroid_step(model, centroid, d) if is_pinned(model) else d[:, :2]
    return gap_change(c, centroid, state.rotation, d_c, d[:, 2], d[:, 3:])
