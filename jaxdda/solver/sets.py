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

from typing import Callable, NamedTuple

import jax
import jax.numpy as jnp

from jaxdda._fusion import materialize


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


def _inverse(s):
    """1 / s where s > 0, else 0."""
    return jnp.where(s > 0, 1.0 / jnp.where(s > 0, s, 1.0), 0.0)


def _share(excess, s, inv_s, excess_p, s_p, inv_p, budget):
    """The contact's excess after the Euclidean projection of the pair's excesses (scaled
    units) onto {s excess + s_p excess_p <= budget}: both shrink by lambda times their
    scale, lambda >= 0 the root of sum_pair s max(excess - lambda s, 0) = budget.
    Symmetric in (self, partner), so both contacts of a pair find the same lambda.
    ``inv_s``, ``inv_p``: the scales' inverses. (Divisions only by functions of the scales,
    which are fixed over a solve: a quotient of the iterate read twice would be a kernel of
    its own where XLA compiles the iteration.)
    """
    bp, bp_p = excess * inv_s, excess_p * inv_p
    total = s * excess + s_p * excess_p
    both = (total - budget) * (1.0 / jnp.maximum(s * s + s_p * s_p, 1e-300))
    # Otherwise only the contact with the larger breakpoint is still shrinking.
    self_big = bp > bp_p
    e1, s1 = jnp.where(self_big, excess, excess_p), jnp.where(self_big, s, s_p)
    one = (s1 * e1 - budget) * jnp.where(self_big, inv_s, inv_p) ** 2
    lam = jnp.where(both <= jnp.minimum(bp, bp_p), both, one)
    shrunk = jnp.where(budget > 0, jnp.maximum(excess - jnp.maximum(lam, 0.0) * s, 0.0), 0.0)
    return jnp.where(total > budget, shrunk, excess)


def _clip(y: jax.Array, bound: jax.Array, opposes: jax.Array | None) -> jax.Array:
    """y within [-bound, bound], and of the sign opposite to ``opposes`` where it is not 0."""
    if opposes is None:
        return jnp.clip(y, -bound, bound)
    return jnp.clip(y, jnp.where(opposes < 0, 0.0, -bound), jnp.where(opposes > 0, 0.0, bound))


def _normal(y_n, s_n, inv_n, ten_p, s_p, inv_p, tension):
    """The projected normal y_n (scaled): tension up to the budget the pair shares."""
    ten = jnp.maximum(-y_n, 0.0)
    return jnp.where(y_n >= 0, y_n, -_share(ten, s_n, inv_n, ten_p, s_p, inv_p, tension))


def _partner(x: jax.Array, partner: jax.Array) -> jax.Array:
    """Each contact's partner's row of x (C, k); zero where it has none."""
    has_p = partner >= 0
    return jnp.where(has_p[:, None], x[jnp.where(has_p, partner, 0)], 0.0)


def _paired(y: jax.Array, scale: jax.Array, sets: ContactSets) -> tuple[jax.Array, jax.Array]:
    """The partner's unknowns y_q (C, 3) and its data (C, 6): scale, friction, tension,
    cohesion; one gather."""
    data = jnp.concatenate([scale, jnp.stack([sets.friction, sets.tension, sets.cohesion], -1)], -1)
    theirs = _partner(jnp.concatenate([y, data], -1), sets.partner)
    return theirs[:, :3], theirs[:, 3:]


def _projection(y, y_q, scale, data_q, sets: ContactSets) -> jax.Array:
    """P(y) (C, 3), each contact from its own row and its partner's (y_q, data_q of
    ``_paired``): the partner's normal is projected here too (the relation is symmetric),
    so the map is elementwise over contacts."""
    s_q, friction_q, tension_q, cohesion_q = data_q[:, :3], data_q[:, 3], data_q[:, 4], data_q[:, 5]
    inv, inv_q = _inverse(scale), _inverse(s_q)

    def bound(y_n, s, inv, coef, i=1):  # the friction (rolling) bound of a normal force, in row i's units
        return coef * jnp.maximum(s[:, 0] * y_n, 0.0) * inv[:, i]

    # Normal: tension up to the shared budget t (a partner with no share of it counts none).
    ten, ten_q = jnp.maximum(-y[:, 0], 0.0), jnp.maximum(-y_q[:, 0], 0.0)
    y_n = _normal(y[:, 0], scale[:, 0], inv[:, 0], jnp.where(tension_q > 0, ten_q, 0.0), s_q[:, 0], inv_q[:, 0],
                  sets.tension)
    y_n_q = _normal(y_q[:, 0], s_q[:, 0], inv_q[:, 0], jnp.where(sets.tension > 0, ten, 0.0), scale[:, 0], inv[:, 0],
                    tension_q)
    # Shear: friction bound of its own, plus the shared cohesion.
    fric = bound(y_n, scale, inv, sets.friction)
    over = jnp.maximum(jnp.abs(y[:, 1]) - fric, 0.0)
    over_q = jnp.where(cohesion_q > 0, jnp.maximum(jnp.abs(y_q[:, 1]) - bound(y_n_q, s_q, inv_q, friction_q), 0.0), 0.0)
    bound_t = fric + _share(over, scale[:, 1], inv[:, 1], over_q, s_q[:, 1], inv_q[:, 1], sets.cohesion)
    y_t = _clip(y[:, 1], bound_t, None if sets.opposes is None else sets.opposes[:, 0])
    # Rolling moment.
    bound_m = bound(y_n, scale, inv, sets.rolling, 2)
    y_m = _clip(y[:, 2], bound_m, None if sets.opposes is None else sets.opposes[:, 1])
    return jnp.where(sets.enabled[:, None], jnp.stack([y_n, y_t, y_m], -1), 0.0)


@jax.jit
def project(y: jax.Array, scale: jax.Array, sets: ContactSets) -> jax.Array:
    """Euclidean projection of scaled unknowns y (C, 3) (p = scale * y) onto X(p).

    The friction and rolling bounds use the projected normal of the same contact, so a
    fixed point p = P(p - beta G(p)) solves the QVI of eqs. 26, 28, 57 and 64. One gather
    (the partners' rows) and elementwise work.
    """
    y_q, data_q = _paired(y, scale, sets)
    return materialize(_projection(y, y_q, scale, data_q, sets))


def linearize(y: jax.Array, scale: jax.Array, sets: ContactSets) -> tuple[jax.Array, Callable[[jax.Array], jax.Array]]:
    """P(y) and its derivative at y as a linear map v -> D v: per contact a 3 x 3 block on
    its own row and one on its partner's (``_projection`` is elementwise over contacts, so
    six tangents, three per side, give the blocks). The map is a gather and elementwise
    work, transposable (the adjoint solve of ``fista_newton._implicit`` transposes it)."""
    y_q, data_q = _paired(y, scale, sets)

    def column(e):  # the derivative along one of the six components of (y, y_q)
        return jax.jvp(lambda a, b: _projection(a, b, scale, data_q, sets), (y, y_q),
                       (jnp.broadcast_to(e[:3], y.shape), jnp.broadcast_to(e[3:], y.shape)))[1]

    both = jax.vmap(column, out_axes=-1)(jnp.eye(6, dtype=y.dtype))  # (C, 3 out, 6 in)
    own, theirs = both[..., :3], both[..., 3:]

    def derivative(v):
        return jnp.einsum("cij,cj->ci", own, v) + jnp.einsum("cij,cj->ci", theirs, _partner(v, sets.partner))

    return project(y, scale, sets), derivative  # its trace is the solver's own (a nested jit)


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
