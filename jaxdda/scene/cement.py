"""Cemented joints: the contacts between touching bodies at t = 0 (hypothesis i, Section 4.5)."""
from __future__ import annotations

import dataclasses

import jax
import jax.numpy as jnp
import numpy as np

from jaxdda.contact.detect import contact_materials, detect
from jaxdda.contact.kinematics import gap_frame
from jaxdda.errors import CapacityError
from jaxdda.types import Model, Params, State


@jax.jit
def initial_contacts(model: Model, state: State, params: Params):
    n = model.n_bodies
    c, needed = detect(model, state.centroid, state.rotation, jnp.full((n,), 0.5 * params.margin), jnp.zeros(n),
                  params.margin)
    gap, _, point = gap_frame(c, state.centroid, state.rotation)
    return c, gap, point, needed


def with_joints(model: Model, state: State, params: Params, tol: float) -> tuple[Model, State]:
    """The model with a joint for every contact whose gap is within ``tol`` at t = 0 and
    whose material pair has a tensile strength, all intact."""
    c, gap, point, needed = initial_contacts(model, state, params)
    if np.any(np.asarray(needed) > np.asarray(dataclasses.astuple(model.capacity))):
        raise CapacityError(f"initial contact detection overflowed (needed {np.asarray(needed).tolist()}, "
                            f"capacity {model.capacity})")
    tensile = np.asarray(params.tensile[contact_materials(model, c)])
    sel = np.asarray(c.valid) & (np.abs(np.asarray(gap)) <= tol) & (tensile > 0)
    if not sel.any():
        return model, state
    model = dataclasses.replace(model, joint_key=jnp.asarray(np.asarray(c.key)[sel]),
                                joint_a=jnp.asarray(np.asarray(c.a)[sel]), joint_b=jnp.asarray(np.asarray(c.b)[sel]),
                                joint_point=jnp.asarray(np.asarray(point)[sel]))
    return model, dataclasses.replace(state, joint_integrity=jnp.ones((int(sel.sum()),)))
