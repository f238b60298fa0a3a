"""Projection-contraction solve of the contact VI (He & Liao 2002; paper eqs. 39-41).

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

NU = 0.9  # accept a prediction when beta |F(y) - F(y~)| <= NU |y - y~|
GROW = 0.3  # grow beta when that ratio falls below GROW
GAMMA = 1.9  # relaxation of the correction step, in (0, 2)


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
    """The projection-contraction iteration on scaled unknowns y = p / scale."""
    enabled = sets.enabled

    def proj(z, normal=None):
        return project(z, scale, sets, None if normal is None else scale[:, 0] * normal)

    def field(y):  # F(y) = S (W S y + b)
        return scale * (apply_w(operand, scale * y) + b)

    def residual(y, fy):
        r = scale * (y - proj(y - fy))
        size = jnp.maximum(jnp.max(jnp.abs(scale * y), initial=0.0), force_scale)
        return jnp.max(jnp.abs(r), initial=0.0) / jnp.where(size > 0, size, 1.0)

    y0 = proj(jnp.where(enabled[:, None], p0 / jnp.where(scale > 0, scale, 1.0), 0.0))
    f0 = field(y0)

    def cond(carry):
        _, _, _, k, res = carry
        return (res > tol) & (k < max_iter)

    def body(carry):
        y, fy, beta, k, _ = carry
        # X(p) is frozen at the current iterate's normal force for this iteration, so
        # the prediction and the correction project onto one convex set.
        yt = proj(y - beta * fy, y[:, 0])
        ft = field(yt)
        dy, df = y - yt, fy - ft
        ny = jnp.sqrt(jnp.sum(dy * dy))
        ratio_r = beta * jnp.sqrt(jnp.sum(df * df)) / jnp.where(ny > 0, ny, 1.0)
        accept = ratio_r <= NU
        d = dy - beta * df
        dd = jnp.sum(d * d)
        alpha = jnp.sum(dy * d) / jnp.where(dd > 0, dd, 1.0)
        y_new = proj(y - GAMMA * alpha * beta * ft, y[:, 0])
        y_new = jnp.where(accept, y_new, y)
        f_new = jnp.where(accept, field(y_new), fy)
        beta = jnp.where(accept, jnp.where(ratio_r < GROW, beta * 1.5, beta),
                         beta * 0.7 * jnp.minimum(1.0, 1.0 / jnp.maximum(ratio_r, 1e-300)))
        return y_new, f_new, beta, k + 1, residual(y_new, f_new)

    init = (y0, f0, jnp.asarray(1.0, b.dtype), jnp.int32(0), residual(y0, f0))
    y, _, _, k, res = jax.lax.while_loop(cond, body, init)
    return y, k, res


# The adjoint linear solves: GMRES, restarted (the system is square, not symmetric where
# a contact slides, and singular where the contact forces are indeterminate).
GMRES_TOL, GMRES_RESTART, GMRES_CYCLES = 1e-13, 60, 20


def _gmres(matvec, rhs):
    return jax.scipy.sparse.linalg.gmres(matvec, rhs, tol=GMRES_TOL, atol=0.0, restart=GMRES_RESTART,
                                         maxiter=GMRES_CYCLES)[0]


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
