"""Stage "assemble": the step's per-body operators (paper eqs. 20-24), and the contact
operators built on them.

K_eff = K + 2 M / dt^2 (Newmark, gamma = 1, beta = 1/2), its inverse over each body's
(or dof group's) active dofs, and M_imp^-1 = (2 / dt^2) K_eff^-1, the flexibility an
impulse sees (M^-1 for a rigid body). ``respond`` is K^-1 J^T p: the bodies' response to
contact forces p, the one operator the step's rows are made of (W = J K^-1 J^T).
"""
from __future__ import annotations

from typing import Any, NamedTuple

import jax
import jax.numpy as jnp

from jaxdda import groups, pins
from jaxdda.bodies.elastic import current_shape, elastic_matrix, stiffness, stress_load
from jaxdda.bodies.mass import external_load, mass_matrix
from jaxdda.connectors import connector_terms
from jaxdda.contact.detect import world_vertices
from jaxdda.contact.kinematics import apply_jacobian, apply_jacobian_t
from jaxdda.groups import Flexibility
from jaxdda.integrate import matvec
from jaxdda.types import Contacts, Model, Params, State


class Operators(NamedTuple):
    """The step's per-body operators at its start configuration."""

    volume: jax.Array  # (N,) current area of each body
    mass: jax.Array  # (N, 6, 6) M
    stiff: jax.Array  # (N, 6, 6) K (0 for a rigid body)
    load: jax.Array  # (N, 6) f: external, initial-stress and connector loads at t + dt
    k_eff: jax.Array  # (N, 6, 6) K + 2 M / dt^2
    k_inv: Flexibility  # K_eff^-1 over the active dofs (dof groups and pins included)
    m_inv: Flexibility  # (2 / dt^2) K_eff^-1: the flexibility an impulse sees
    vel: jax.Array  # (N, 6) the start velocity on the active dofs (0 in a static analysis)
    maps: Any  # (N, 6, d) or None: each group member's dofs from its group's
    coupling: Any  # (ends (K, 2), stiffness) of the connectors, or None
    momentum: jax.Array  # () force scale of the step: max |M v| + |f| dt


def assemble(base: Model, state: State, params: Params) -> tuple[Model, Operators]:
    """The model in each body's current shape, and the step's operators (eqs. 20-24, 80-92)."""
    n, dt = base.n_bodies, params.dt
    proj = base.dof_projector
    model = current_shape(base, state.stretch)  # local geometry in each body's current shape
    volume = base.area * jnp.abs(jnp.linalg.det(state.stretch))
    mass = mass_matrix(base, params, state)
    stiff = stiffness(elastic_matrix(params.young, params.poisson, base.plane_strain), volume)  # rigid: 0
    centroid = state.centroid
    load = (external_load(model, params, centroid, state.rotation, state.time + dt)
            + stress_load(state.stress, volume))
    coupling = None
    if model.connector_a.shape[0]:  # connectors: their load, and their stiffness in K_eff (eqs. 80-92)
        conn_load, conn_stiff = connector_terms(base, params, state)
        ends = jnp.stack([model.connector_a, model.connector_b], 1)
        load = load + jax.ops.segment_sum(conn_load.reshape(-1, conn_load.shape[-1]), ends.reshape(-1), n)
        coupling = (ends, conn_stiff)
    maps = None
    if model.group_members.shape[0]:  # each group member's dofs from the group's reduced ones
        verts = world_vertices(model, centroid, state.rotation)
        maps = jnp.where((model.mesh >= 0)[:, None, None], groups.mesh_maps(verts), model.dof_basis)
        if is_pinned(model):  # a pinned body's dofs: the null space of its pins' constraints (at the start)
            maps = pins.pin_maps(model, maps, centroid)
    k_eff = stiff + 2.0 * mass / dt ** 2
    k_inv = groups.grouped(k_eff, proj, model, maps, coupling)
    # Impacts see the step's flexibility: (M + K dt^2 / 2)^-1 = (2 / dt^2) K_eff^-1, which is
    # M^-1 for rigid bodies; a stiff mode (omega dt >> 1: a meshed block of E = 1e14, a
    # stiff bolt) takes an impulse as the structure it is over a step, not as loose masses.
    m_inv = groups.scaled(k_inv, 2.0 / dt ** 2)
    vel = params.dynamic * matvec(proj, state.velocity)  # static analysis: each step starts at rest
    # Force scale of the scene this step: residuals far below it are round-off.
    momentum = jnp.max(jnp.abs(matvec(mass, vel)) + jnp.abs(load) * dt, initial=0.0)
    return model, Operators(volume=volume, mass=mass, stiff=stiff, load=load, k_eff=k_eff, k_inv=k_inv,
                            m_inv=m_inv, vel=vel, maps=maps, coupling=coupling, momentum=momentum)


def is_pinned(model: Model) -> bool:
    """Whether fixed points constrain a movable body (pins.py): static."""
    return model.pin_body.shape[0] > 0


@jax.jit
def respond(flex: Flexibility, jac: jax.Array, c: Contacts, p: jax.Array) -> jax.Array:
    """K^-1 J^T p (N, 6): the bodies' displacement under contact forces p (C, 3) over the
    step (or, with M_imp^-1 and impulses, their change of velocity)."""
    return groups.apply(flex, apply_jacobian_t(jac, c, p, flex.single.shape[0]))


class WOperand(NamedTuple):
    """W = J inv J^T's data (``apply_w``'s operand)."""

    jac: jax.Array  # (C, 2, 3, 6) the rows
    contacts: Contacts
    inv: Flexibility  # K^-1 (forces over the step) or M_imp^-1 (impulses)


def apply_w(operand: WOperand, p: jax.Array) -> jax.Array:
    """W p = J K^-1 J^T p: the contact flexibility (eq. 39)."""
    jac, c, inv = operand
    return apply_jacobian(jac, c, respond(inv, jac, c, p))


def flexibility(jac: jax.Array, c: Contacts, inv: Flexibility) -> tuple[WOperand, jax.Array]:
    """The operand of ``apply_w`` for W = J inv J^T, and W's diagonal (C, 3) (with the
    coupling of a contact's two bodies where they share a dof group, eq. 112)."""
    return WOperand(jac, c, inv), groups.contact_diagonal(inv, jac, c.a, c.b)
