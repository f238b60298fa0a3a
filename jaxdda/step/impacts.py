"""Stage "impacts": the velocity jumps of the step's impacts, in one contact solve.

The impact law (Moreau's impact VI with Newton's restitution, taken along Poisson's
regimes and bounded by the energy the compression took):

1. Compression: P1 solves the plastic VI on the impact rows, G1 = W P1 + v- (v+_n >= 0,
   Coulomb's law on the shear impulse, the rolling bound on the moment; eqs. 26-28 at
   velocity level), W = J M_imp^-1 J^T.
2. Restitution: K = e P1 along the regime each row ended compression in: every normal
   impulse, and the shear (rolling) impulse of a row that slid (rolled) on its bound, which
   keeps |K_t| = mu K_n on it; a row that stuck takes no restitution shear. e is one value
   per impact cluster (the rows joined through free bodies): its struck rows' least.
3. Energy bound: P = P1 + s K with the largest s in [0, 1] at which no cluster gains
   kinetic energy, dT(s) = a + s b + s^2 c / 2 with a = P1 . (v- + W P1 / 2) (<= 0: the
   compression is a projection), b = K . G1 and c = K . W K.

Exact cases. One frictionless contact, or any frictionless cluster of one e: P = (1 + e) P1
is Newton's law v+_n = -e v-_n on every active row (w = v- + W P / (1 + e) solves the
plastic VI), its energy loss (1 - e^2) of the compression's (so s = 1): a bounce apex is
e^2 h; a disk striking a touching pair with e = 1 leaves them at (-1/3, 2/3, 2/3) v. One
frictional contact without normal-shear coupling (a disk): Poisson's law, sliding
throughout (P_t = mu P_n) or sticking (the contact point leaves without slip). Where a
stuck row couples shear and normal (a turning corner, Kane's paradox), Newton's law would
gain energy; the bound caps the restitution at what keeps the cluster's energy.
"""
from __future__ import annotations

from typing import Any, Callable, NamedTuple

import jax
import jax.numpy as jnp

from jaxdda.solver import fista_newton
from jaxdda.solver.sets import ON_BOUND, ContactSets, sticking


class Impulses(NamedTuple):
    """An impact solve's result."""

    impulse: jax.Array  # (C, 3) P = P1 + s K
    compression: jax.Array  # (C, 3) P1
    restitution: jax.Array  # (C, 3) s K
    scale: jax.Array  # (C,) s of each row's cluster
    solution: fista_newton.Solution  # the compression's solve


@jax.jit
def cluster_labels(joined: jax.Array, a: jax.Array, b: jax.Array, fixed: jax.Array) -> jax.Array:
    """Per row (C,): the least free body of its cluster (free bodies joined by the ``joined``
    rows; fixed bodies join nothing), n for a row that joins nothing. On integers, so no
    derivative flows through it."""
    n = fixed.shape[0]

    def of_rows(label):  # a joined row's label: the smaller of its free bodies' labels (n: none)
        la, lb = jnp.where(fixed[a], n, label[a]), jnp.where(fixed[b], n, label[b])
        return jnp.where(joined, jnp.minimum(la, lb), n)

    def spread(carry):
        label, _ = carry
        row = of_rows(label)
        new = jnp.minimum(label, jnp.minimum(jax.ops.segment_min(row, a, n), jax.ops.segment_min(row, b, n)))
        return new, jnp.any(new != label)

    return of_rows(jax.lax.while_loop(lambda c: c[1], spread, (jnp.arange(n), jnp.array(True)))[0])


def cluster_restitution(e: jax.Array, struck: jax.Array, label: jax.Array, n: int) -> jax.Array:
    """Per row: the least e of its cluster's struck rows (0 where it has none)."""
    least = jax.ops.segment_min(jnp.where(struck, e, jnp.inf), label, n + 1)
    own = least[label]
    return jnp.where(jnp.isfinite(own) & (label < n), own, 0.0)


def restitution_kick(p1: jax.Array, sets: ContactSets, e: jax.Array) -> jax.Array:
    """K = e P1 (C, 3) along the compression's regime: the normal impulse, and the shear
    (rolling) impulse where the row ended on its bound."""
    p_n = jnp.maximum(p1[:, 0], 0.0)
    slid = sets.enabled & (p_n > 0) & ~sticking(p1, sets)
    rolled = sets.enabled & (sets.rolling > 0) & (jnp.abs(p1[:, 2]) >= (1.0 - ON_BOUND) * sets.rolling * p_n)
    kept = jnp.stack([sets.enabled, slid, rolled], -1)
    return jnp.where(kept & (p_n > 0)[:, None], e[:, None] * p1, 0.0)


def energy_scale(p1: jax.Array, kick: jax.Array, v_minus: jax.Array, w_p1: jax.Array, w_kick: jax.Array,
                 label: jax.Array, n: int) -> jax.Array:
    """Per row: the largest s in [0, 1] at which its cluster's kinetic energy does not
    grow under P1 + s K: dT(s) = a + s b + s^2 c / 2 (sums over the cluster's rows)."""
    def total(x):
        return jax.ops.segment_sum(jnp.sum(x, -1), label, n + 1)[label]

    a = total(p1 * (v_minus + 0.5 * w_p1))
    b = total(kick * (v_minus + w_p1))
    c = total(kick * w_kick)
    gains = a + b + 0.5 * c > 0
    disc = b * b - 2.0 * a * c
    real = disc > 0  # (sqrt's derivative at 0 is infinite: it would poison reverse mode)
    root = (jnp.where(real, jnp.sqrt(jnp.where(real, disc, 1.0)), 0.0) - b) / jnp.where(c > 0, c, 1.0)
    return jnp.where(gains & (c > 0), jnp.clip(root, 0.0, 1.0), 1.0)


def cluster_min(x: jax.Array, joined: jax.Array, a: jax.Array, b: jax.Array, fixed: jax.Array) -> jax.Array:
    """Per row: the least ``x`` over the rows of its cluster (``cluster_labels``); a row that
    joins nothing keeps its own."""
    n = fixed.shape[0]
    label = cluster_labels(joined, a, b, fixed)
    least = jax.ops.segment_min(jnp.where(label < n, x, jnp.inf), label, n + 1)
    return jnp.where(label < n, least[label], x)


def impact_law(apply_w: Callable[[Any, jax.Array], jax.Array], operand: Any, v_minus: jax.Array, sets: ContactSets,
               e: jax.Array, struck: jax.Array, a: jax.Array, b: jax.Array, fixed: jax.Array,
               p1: jax.Array) -> tuple[jax.Array, jax.Array, jax.Array]:
    """From the compression P1 (C, 3) of the impact rows ``sets.enabled`` on the relative
    velocities ``v_minus``: the impulse P = P1 + s K, the restitution s K and s (C,).
    ``e`` (C,) the restitution of the rows ``struck`` (the others are constraints of the
    cluster, v+_n >= 0); rows join bodies ``a``, ``b``."""
    n = fixed.shape[0]
    label = cluster_labels(sets.enabled & (p1[:, 0] > 0), a, b, fixed)
    e_row = cluster_restitution(e, struck & sets.enabled, label, n)
    kick = restitution_kick(p1, sets, e_row)
    w_p1, w_kick = apply_w(operand, p1), apply_w(operand, kick)
    s = energy_scale(p1, kick, v_minus, w_p1, w_kick, label, n)
    return p1 + s[:, None] * kick, s[:, None] * kick, s


def impact(apply_w: Callable[[Any, jax.Array], jax.Array], operand: Any, w_diag: jax.Array, v_minus: jax.Array,
           sets: ContactSets, e: jax.Array, struck: jax.Array, a: jax.Array, b: jax.Array, fixed: jax.Array,
           warm: jax.Array, tol: jax.Array, max_iter: jax.Array, force_scale: jax.Array) -> Impulses:
    """The compression's solve and ``impact_law``."""
    sol = fista_newton.solve(apply_w, operand, w_diag, v_minus, sets, warm, tol, max_iter, force_scale)
    impulse, restitution, s = impact_law(apply_w, operand, v_minus, sets, e, struck, a, b, fixed, sol.force)
    return Impulses(impulse=impulse, compression=sol.force, restitution=restitution, scale=s, solution=sol)
