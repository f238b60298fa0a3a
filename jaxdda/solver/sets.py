"""The constraint sets X(p) of the contact (quasi)variational inequality (eqs. 26, 28, 39)."""
from __future__ import annotations

import jax
import jax.numpy as jnp


def coulomb_projection(z: jax.Array, bound_ratio: jax.Array, enabled: jax.Array,
                       normal: jax.Array | None = None) -> jax.Array:
    """Project (normal, shear) pairs z (C, 2) onto X = {p_n >= 0, |p_t| <= ratio * p_n}.

    The shear bound uses the projected normal of the same pair, so a fixed point
    ``p = P(p - beta G(p))`` is exactly a solution of the QVI of eqs. 26 and 28 with
    tau(p_n) = mu p_n (eq. 19; ``bound_ratio`` carries mu in scaled variables).
    Disabled contacts project to zero. With ``normal`` given, the shear bound is
    ratio * normal instead (the set X(p) frozen at that normal force: a convex box).
    """
    pn = jnp.maximum(z[:, 0], 0.0)
    bound = bound_ratio * (pn if normal is None else jnp.maximum(normal, 0.0))
    pt = jnp.clip(z[:, 1], -bound, bound)
    return jnp.where(enabled[:, None], jnp.stack([pn, pt], -1), 0.0)
