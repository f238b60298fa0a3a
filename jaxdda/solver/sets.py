"""The constraint set X(p) of the contact (quasi)variational inequality, and its projection.

Per contact the unknowns are p = (p_n, p_t, m_r): normal force, shear force and rolling
resistance moment. The set (frozen at a normal force p_n^0, see ``project``) is

    p_n >= -t_k                    (eqs. 63-69: tension only at an intact cemented joint)
    |p_t| <= c_k + mu p_n^0+       (eq. 19: Mohr-Coulomb with cohesion)
    |m_r| <= delta p_n^0+          (eqs. 55-62: rolling resistance of a particle)

and, where ``opposes`` gives the sign s of a row's slip (or roll) at the step's start,
s p_t <= 0 (s m_r <= 0): a velocity-level row's force may not push along that slip (see
``ContactSets.opposes``).

Adjoint contacts (two vertex-edge contacts of one edge-edge interface) share one cohesion
c = c_1 + c_2 (eqs. 42-45) and one tensile strength t = t_1 + t_2 (eqs. 70-73). The paper
fixes the ratio k = c_1 / c_2 at 1 and lets it settle over the compatibility iteration;
here the shares are unknowns of the set itself: a pair may use any split, i.e.

    max(|p_t1| - mu p_n1, 0) + max(|p_t2| - mu p_n2, 0) <= c,
    max(-p_n1, 0) + max(-p_n2, 0) <= t,

which is convex, so the fixed point of the projected iteration (paper eq. 40) is the
compatible state with the split the paper's iteration converges to (k_t = |p_1| / |p_2|).
"""
from __future__ import annotations

from typing import NamedTuple

import jax
import jax.numpy as jnp


class ContactSets(NamedTuple):
    """Per-contact data of X(p); shared budgets are given once per pair, on both contacts."""

    enabled: jax.Array  # (C,) bool
    friction: jax.Array  # (C,) mu
    cohesion: jax.Array  # (C,) c of the interface (shared with ``partner``)
    tension: jax.Array  # (C,) t of the interface, 0 unless an intact cemented joint (shared)
    rolling: jax.Array  # (C,) delta, 0 for contacts without a particle
    partner: jax.Array  # (C,) int32 adjoint contact, -1 for none (a symmetric relation)
    # (C, 2) sign (-1, 0, 1) of the shear slip and the roll at the step's start that the
    # shear force and rolling moment must not push along, 0 for no restriction; None: none.
    # On a velocity-level row (G = dt/2 J v+) the force does work p (G + dt/2 J v*); the
    # restriction makes the second part dissipate too (docs/design.md, Energy).
    opposes: jax.Array | None = None


def _share(excess, s, excess_p, s_p, budget):
    """The contact's excess after the Euclidean projection of the pair's excesses (scaled
    units) onto {s excess + s_p excess_p <= budget}: both shrink by lambda times their
    scale, lambda >= 0 the root of sum_pair s max(excess - lambda s, 0) = budget.
    Symmetric in (self, partner), so both contacts of a pair find the same lambda.
    """
    bp = excess / jnp.where(s > 0, s, 1.0)
    bp_p = jnp.where(s_p > 0, excess_p / jnp.where(s_p > 0, s_p, 1.0), 0.0)
    total = s * excess + s_p * excess_p
    both = (total - budget) / jnp.maximum(s * s + s_p * s_p, 1e-300)
    # Otherwise only the contact with the larger breakpoint is still shrinking.
    self_big = bp > bp_p
    e1, s1 = jnp.where(self_big, excess, excess_p), jnp.where(self_big, s, s_p)
    one = (s1 * e1 - budget) / jnp.maximum(s1 * s1, 1e-300)
    lam = jnp.where(both <= jnp.minimum(bp, bp_p), both, one)
    shrunk = jnp.where(budget > 0, jnp.maximum(excess - jnp.maximum(lam, 0.0) * s, 0.0), 0.0)
    return jnp.where(total > budget, shrunk, excess)


def _clip(y: jax.Array, bound: jax.Array, opposes: jax.Array | None) -> jax.Array:
    """y within [-bound, bound], and of the sign opposite to ``opposes`` where it is not 0."""
    if opposes is None:
        return jnp.clip(y, -bound, bound)
    return jnp.clip(y, jnp.where(opposes < 0, 0.0, -bound), jnp.where(opposes > 0, 0.0, bound))


def project(y: jax.Array, scale: jax.Array, sets: ContactSets, normal: jax.Array | None = None) -> jax.Array:
    """Euclidean projection of scaled unknowns y (C, 3) (p = scale * y) onto X.

    With ``normal`` (C,) given (a physical normal force), the friction and rolling bounds
    use it instead of the projected normal: X(p) frozen at that force, a convex set. Without
    it the bounds use the projected normal of the same contact, so a fixed point
    p = P(p - beta G(p)) solves the QVI of eqs. 26, 28, 57 and 64.
    """
    has_p = sets.partner >= 0
    part = jnp.where(has_p, sets.partner, 0)

    def pair(v, budget=None):
        """The partner's value; zero without a partner or, given ``budget``, where the
        partner has no share of it (a broken joint next to an intact one)."""
        ok = has_p if budget is None else has_p & (budget[part] > 0)
        return jnp.where(ok, v[part], 0.0)

    s_n, s_t, s_m = scale[:, 0], scale[:, 1], scale[:, 2]
    # Normal: tension up to the shared budget t.
    ten = jnp.maximum(-y[:, 0], 0.0)
    y_n = jnp.where(y[:, 0] >= 0, y[:, 0], -_share(ten, s_n, pair(ten, sets.tension), pair(s_n), sets.tension))
    p_n = jnp.maximum(s_n * y_n if normal is None else normal, 0.0)
    # Shear: friction bound of its own, plus the shared cohesion.
    fric = sets.friction * p_n / jnp.where(s_t > 0, s_t, 1.0)
    over = jnp.maximum(jnp.abs(y[:, 1]) - fric, 0.0)
    bound_t = fric + _share(over, s_t, pair(over, sets.cohesion), pair(s_t), sets.cohesion)
    y_t = _clip(y[:, 1], bound_t, None if sets.opposes is None else sets.opposes[:, 0])
    # Rolling moment.
    bound_m = sets.rolling * p_n / jnp.where(s_m > 0, s_m, 1.0)
    y_m = _clip(y[:, 2], bound_m, None if sets.opposes is None else sets.opposes[:, 1])
    return jnp.where(sets.enabled[:, None], jnp.stack([y_n, y_t, y_m], -1), 0.0)


# A shear force within this fraction of its bound is on the bound (the solver's iterates
# are projections, so a sliding contact sits on its bound to a few ulp).
ON_BOUND = 1e-9


def sticking(p: jax.Array, sets: ContactSets) -> jax.Array:
    """(C,) bool: the shear force of p (C, 3) (forces or impulses) strictly inside its
    bound c + mu p_n (the cohesion the partner leaves), i.e. the contact sticks (G_t = 0)."""
    part = jnp.where(sets.partner >= 0, sets.partner, 0)
    p_n = jnp.maximum(p[:, 0], 0.0)
    excess = jnp.maximum(jnp.abs(p[:, 1]) - sets.friction * p_n, 0.0)
    left = jnp.maximum(sets.cohesion - jnp.where(sets.partner >= 0, excess[part], 0.0), 0.0)
    bound = sets.friction * p_n + left
    return sets.enabled & (bound > 0) & (jnp.abs(p[:, 1]) < (1.0 - ON_BOUND) * bound)
