"""Solve of the contact VI (paper eqs. 39-41) by accelerated projected gradient.

The paper iterates projection-contraction (He & Liao 2002); its fixed point is the same,
y = P(y - F(y)), which ``_iterate`` reaches with Nesterov momentum and adaptive restart
(FISTA), about ten times fewer iterations on piles (see ``_iterate``).

Find p in X(p) with (q - p)^T G(p) >= 0 for all q in X(p), where G(p) = W p + b is the
gap (or velocity) function, W = J K^-1 J^T the contact flexibility. W is never formed:
``apply_w`` scatters J^T p to bodies, applies K^-1 per body and gathers J back.
The unknowns are scaled by 1/sqrt(diag W) (Jacobi), which leaves the solution of a
box-constrained VI unchanged and makes one step length fit contacts of any stiffness.

Derivatives are implicit: the iterations run on stopped values and the converged point
y* = P(y* - F(y*)) is differentiated through that fixed-point equation alone (see
``_implicit``), so ``jvp``, ``grad`` and ``vmap`` never see the ``while_loop``.
"""
from __future__ import annotations

from functools import partial
from typing import Any, Callable, NamedTuple

import jax
import jax.numpy as jnp

from jaxdda.solver.sets import ContactSets, project

class Solution(NamedTuple):
    force: jax.Array  # (C, 3) normal force, shear force, rolling moment (or their impulses)
    iterations: jax.Array  # () int32
    residual: jax.Array  # () max |p - P(p - G/diag W)| relative to max |p|
    converged: jax.Array  # () bool


def solve(apply_w: Callable[[Any, jax.Array], jax.Array], operand: Any, w_diag: jax.Array, b: jax.Array,
          sets: ContactSets, p0: jax.Array, tol: jax.Array,
          max_iter: jax.Array, force_scale: jax.Array = 0.0) -> Solution:
    """Solve the contact QVI over the sets X(p) of ``solver.sets`` (eqs. 39, 58, 65).

    Differentiable in ``operand``, ``b`` and the float fields of ``sets`` (implicitly, at
    the solution); the warm start, tolerances and the scaling carry no derivative.

    Args:
      apply_w: (operand, p (C, 3)) -> W p (C, 3), linear in p; a pure function (no
        closure over traced values), ``operand`` a pytree holding W's data.
      w_diag: (C, 3) diagonal of W; contacts with a zero normal or shear entry are disabled.
      b: (C, 3) constant part of G (gaps or velocities without contact forces).
      sets: the constraint data; p0: (C, 3) warm start.
      tol: relative tolerance on the natural residual; max_iter: iteration cap.
      force_scale: the residual is measured relative to max(max |p|, force_scale), so
        forces far below the scene's own scale (round-off) need no iterations.
    """
    w_diag, p0, tol, max_iter, force_scale = jax.lax.stop_gradient((w_diag, p0, tol, max_iter, force_scale))
    enabled = sets.enabled & jnp.all(w_diag[:, :2] > 0, -1)
    rolls = enabled & (w_diag[:, 2] > 0) & (sets.rolling > 0)
    sets = sets._replace(enabled=enabled, rolling=jnp.where(rolls, sets.rolling, 0.0))
    # A zero scale takes a component out of the iteration altogether (a moment that must
    # stay 0 would otherwise distort the step length through its field entries).
    active = jnp.stack([enabled, enabled, rolls], -1)
    scale = jnp.where(active, 1.0 / jnp.sqrt(jnp.where(w_diag > 0, w_diag, 1.0)), 0.0)

    y, k, res = _iterate(apply_w, *jax.lax.stop_gradient((operand, b, sets)), scale, p0, tol, max_iter, force_scale)
    y = _implicit(apply_w, operand, b, sets, scale, y)
    return Solution(scale * y, k, res, res <= tol)


def _iterate(apply_w, operand, b, sets, scale, p0, tol, max_iter, force_scale):
    """Accelerated projected gradient on the scaled unknowns y = p / scale.

    FISTA (Beck & Teboulle 2009): y+ = P(z - F(z) / L) from the extrapolated point
    z = y + theta (y - y_prev), with the adaptive restart of O'Donoghue & Candes (2015):
    the momentum is dropped when the step goes against it, (z - y+).(y+ - y) > 0. With
    the friction and rolling bounds frozen at the normal forces the problem is the convex
    QP min 1/2 y^T (S W S) y + (S b)^T y over X (S W S has unit diagonal, its condition
    number grows as the square of a force chain's length, so the momentum's square root
    of it is what counts on piles: ~10x fewer iterations than projection-contraction).
    P bounds them by the projected normal of the same point, so every iterate lies in
    X(y) and a fixed point solves the QVI. L (the largest eigenvalue of S W S, >= 1) is
    found by backtracking: a step whose curvature d^T (S W S) d exceeds L |d|^2 is redone
    with a larger L. S W S y is carried along (one product per iteration; the
    extrapolation's by linearity), so the residual costs no extra product.

    With friction the QVI is not monotone: a self-equilibrated force mode (S W S v = 0,
    from redundant contacts) whose sliding contacts stay on their cone edges leaves G
    unchanged, so along it the residual is flat; momentum crosses such valleys where a
    plain projection method crawls, but where the face of X holding the iterate has no
    solution (a frictional wedge: the mode's equations are inconsistent) the residual has
    a floor that no iteration goes below. The iterate of least residual is returned.
    """
    def proj(z):
        return project(z, scale, sets)

    def amul(y):  # S W S y
        return scale * apply_w(operand, scale * y)

    c = scale * b

    def residual(y, fy):
        r = scale * (y - proj(y - fy))
        size = jnp.maximum(jnp.max(jnp.abs(scale * y), initial=0.0), force_scale)
        return jnp.max(jnp.abs(r), initial=0.0) / jnp.where(size > 0, size, 1.0)

    y0 = proj(jnp.where(sets.enabled[:, None], p0 / jnp.where(scale > 0, scale, 1.0), 0.0))
    a0 = amul(y0)

    def cond(carry):
        k, res = carry[-2], carry[-1]
        return (res > tol) & (k < max_iter)

    def body(carry):
        y, ay, y_prev, ay_prev, t, lip, y_best, k, res_best = carry
        t_next = 0.5 * (1.0 + jnp.sqrt(1.0 + 4.0 * t * t))
        theta = (t - 1.0) / t_next
        z, az = y + theta * (y - y_prev), ay + theta * (ay - ay_prev)
        y_new = proj(z - (az + c) / lip)
        ay_new = amul(y_new)
        d, ad = y_new - z, ay_new - az
        dd, dad = jnp.sum(d * d), jnp.sum(d * ad)
        # Round-off in d^T S W S d (S W S z is extrapolated, not recomputed) is no curvature.
        ok = dad <= lip * dd * (1.0 + 1e-10) + 1e-13 * jnp.sqrt(dd * jnp.sum(ay_new * ay_new))
        restart = jnp.sum((z - y_new) * (y_new - y)) > 0
        lip = jnp.where(ok, lip, jnp.maximum(1.5 * lip, 1.1 * dad / jnp.where(dd > 0, dd, 1.0)))
        y_prev = jnp.where(ok, jnp.where(restart, y_new, y), y_prev)
        ay_prev = jnp.where(ok, jnp.where(restart, ay_new, ay), ay_prev)
        y, ay = jnp.where(ok, y_new, y), jnp.where(ok, ay_new, ay)
        t = jnp.where(ok, jnp.where(restart, 1.0, t_next), t)
        res = residual(y, ay + c)
        better = res < res_best
        return (y, ay, y_prev, ay_prev, t, lip, jnp.where(better, y, y_best), k + 1,
                jnp.where(better, res, res_best))

    one = jnp.asarray(1.0, b.dtype)
    init = (y0, a0, y0, a0, one, one, y0, jnp.int32(0), residual(y0, a0 + c))
    *_, y_best, k, res = jax.lax.while_loop(cond, body, init)
    return y_best, k, res


# The adjoint linear solves: GMRES, restarted (the system is square, not symmetric where
# a contact slides, and singular where the contact forces are indeterminate).
GMRES_TOL, GMRES_RESTART, GMRES_CYCLES = 1e-13, 60, 20


def _gmres(matvec, rhs):
    return jax.scipy.sparse.linalg.gmres(matvec, rhs, tol=GMRES_TOL, atol=0.0, restart=GMRES_RESTART,
                                         maxiter=GMRES_CYCLES, solve_method="incremental")[0]


@partial(jax.custom_jvp, nondiff_argnums=(0,))
def _implicit(apply_w, operand, b, sets, scale, y):
    """The solution y* itself; its derivative comes from the fixed-point equation

        R(y, theta) = y - P(y - F(y, theta), theta) = 0,   F(y) = S (W S y + b),

    (the natural map of the VI, any step length: eq. 40 at beta = 1). Differentiating,
    (I - D (I - S W S)) dy = -dR/dtheta dtheta, with D the Jacobian of the projection at
    y* - F(y*) (the active set: 1 on free components, 0 on bounds, -mu-type entries where
    friction, rolling or a shared budget couples components). A linear solve that JAX
    can transpose (``custom_linear_solve``), so reverse mode gets the adjoint solve.
    """
    return y


@_implicit.defjvp
def _implicit_jvp(apply_w, primals, tangents):
    operand, b, sets, scale, y = primals
    d_operand, d_b, d_sets, _, _ = tangents

    def residual(operand, b, sets):
        z = y - scale * (apply_w(operand, scale * y) + b)
        return y - project(z, scale, sets)

    _, r_dot = jax.jvp(residual, (operand, b, sets), (d_operand, d_b, d_sets))
    z = y - scale * (apply_w(operand, scale * y) + b)
    _, d_proj = jax.linearize(lambda z: project(z, scale, sets), z)

    def matvec(v):
        return v - d_proj(v - scale * apply_w(operand, scale * v))

    return y, jax.lax.custom_linear_solve(matvec, -r_dot, _gmres, _gmres)
