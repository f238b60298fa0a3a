"""Stage "update": the state at the step's end from its displacement d (paper eqs.
1-8, 47-52): rigid motion with the finite rotation's shift, strain and stress of
deformable bodies, pinned bodies turned exactly about their pins."""
from __future__ import annotations

import jax
import jax.numpy as jnp

from jaxdda import pins
from jaxdda.bodies.elastic import (elastic_matrix, finite_rotation_shift, mesh_rotation, rotated_stress,
                                   updated_stretch)
from jaxdda.step.operators import Operators, is_pinned
from jaxdda.types import Model, Params, State


def update(base: Model, model: Model, state: State, params: Params, ops: Operators, d: jax.Array,
           velocity: jax.Array, contact_key: jax.Array, contact_force: jax.Array,
           joint_integrity: jax.Array) -> State:
    """The end state for the step's displacement ``d`` (N, 6) and end ``velocity`` (N, 6);
    ``base`` the model as built, ``model`` in the bodies' current shape."""
    strain = d[:, 3:]
    centroid = state.centroid
    turn_ref, offset = mesh_rotation(base, ops.volume, centroid, d[:, 2])
    moved = d[:, :2]
    if is_pinned(model):  # a pinned body turns exactly about its pin, which stays where it is
        turn_ref, moved = pins.pin_turn(model, turn_ref), pins.centroid_step(model, centroid, d)
    displacement = state.displacement + moved + finite_rotation_shift(turn_ref, offset)
    if is_pinned(model):  # the pins at rest at the step's end (the velocity of a turned lever)
        velocity = pins.held_velocity(model, ops.mass, model.dof_projector, state.origin + displacement, velocity)
    elastic = elastic_matrix(params.young, params.poisson, base.plane_strain)
    return State(
        time=state.time + params.dt,
        origin=state.origin,
        displacement=displacement,
        rotation=state.rotation + d[:, 2],
        velocity=velocity,
        stretch=updated_stretch(state.stretch, state.rotation, d[:, 2], strain, turn_ref),
        stress=rotated_stress(state.stress, d[:, 2]) + jnp.einsum("nij,nj->ni", elastic, strain),
        contact_key=contact_key,
        contact_force=contact_force,
        joint_integrity=joint_integrity,
    )
