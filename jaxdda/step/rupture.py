"""Stage "rupture": cemented joints that fail this step (paper eqs. 63-65, hypotheses
ii and iv of Section 5.3).

An inextensible joint that still opens under its full share of the strength has failed;
it never heals. The opening over W_nn is the force e it lacks to stay closed; a smoothed
rupture (width w > 0) keeps 1 - e / w of the joint's strength instead of none.
"""
from __future__ import annotations

import jax
import jax.numpy as jnp

from jaxdda.types import Model, Params, State


def rupture(model: Model, state: State, params: Params, cemented: jax.Array, joint: jax.Array, force: jax.Array,
            gap_end: jax.Array, w_nn: jax.Array, force_scale: jax.Array) -> tuple[jax.Array, jax.Array]:
    """The joints' integrity (J,) after the step, and the tension (J,) each carried.

    ``force`` (C, 3) the contact forces, ``gap_end`` (C,) their end gaps, ``w_nn`` (C,)
    W's normal diagonal; a tension below 10 tol of the step's force scale is round-off.
    """
    size = jax.lax.stop_gradient(jnp.maximum(jnp.max(jnp.abs(force), initial=0.0), force_scale))
    lacking = jnp.where(cemented & (force[:, 0] < 0),
                        gap_end / jnp.where(w_nn > 0, w_nn, 1.0) - 10.0 * params.tol * size, 0.0)
    width = params.rupture_width
    keep = jnp.where(width > 0, jnp.clip(1.0 - jnp.maximum(lacking, 0.0) / jnp.where(width > 0, width, 1.0), 0.0, 1.0),
                     (lacking <= 0).astype(lacking.dtype))
    n_joints = model.joint_key.shape[0]
    joint_slot = jnp.where(cemented, joint, n_joints)  # out of range: dropped by segment ops
    joint_integrity = state.joint_integrity * jnp.minimum(jax.ops.segment_min(keep, joint_slot, n_joints), 1.0)
    tension = jax.ops.segment_sum(jnp.maximum(-force[:, 0], 0.0), joint_slot, n_joints)
    return joint_integrity, tension
