"""Solve of the contact VI (paper eqs. 39-41) by accelerated projected gradient and
semismooth Newton.

The paper iterates projection-contraction (He & Liao 2002); its fixed point is the same,
y = P(y - F(y)), which ``_iterate`` reaches with Nesterov momentum and adaptive restart
(FISTA), about ten times fewer iterations on piles (see ``_iterate``). Where redundant
contacts stall it, ``_newton`` finishes the solve.

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
from jax.ad_checkpoint import checkpoint_name

from jaxdda.solver.sets import ContactSets, linearize, project

# The checkpoint name of a solve's result (``jax.ad_checkpoint.checkpoint_name``).
SOLUTION = "contact_vi_solution"


class Solution(NamedTuple):
    force: jax.Array  # (C, 3) normal force, shear force, rolling moment (or their impulses)
    iterations: jax.Array  # () int32 products with W: one per FISTA iteration, m + 1 per Newton step
    residual: jax.Array  # () max |p - P(p - G/diag W)| relative to max |p|
    converged: jax.Array  # () bool


class Problem(NamedTuple):
    """One contact solve's data: ``solve``'s arguments but the map and the tolerances."""

    operand: Any  # W's data, for apply_w
    w_diag: jax.Array  # (C, 3)
    b: jax.Array  # (C, 3)
    sets: ContactSets
    warm: jax.Array  # (C, 3) the warm start
    force_scale: jax.Array  # ()


def solve(apply_w: Callable[[Any, jax.Array], jax.Array], operand: Any, w_diag: jax.Array, b: jax.Array,
          sets: ContactSets, p0: jax.Array, tol: jax.Array,
          max_iter: jax.Array, force_scale: jax.Array = 0.0, newton: bool = True) -> Solution:
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
      newton: (static) finish a stalled FISTA by semismooth Newton; False: FISTA alone,
        until converged or ``max_iter``.
    """
    w_diag, p0, tol, max_iter, force_scale = jax.lax.stop_gradient((w_diag, p0, tol, max_iter, force_scale))
    enabled = sets.enabled & jnp.all(w_diag[:, :2] > 0, -1)
    rolls = enabled & (w_diag[:, 2] > 0) & (sets.rolling > 0)
    sets = sets._replace(enabled=enabled, rolling=jnp.where(rolls, sets.rolling, 0.0))
    # A zero scale takes a component out of the iteration altogether (a moment that must
    # stay 0 would otherwise distort the step length through its field entries).
    active = jnp.stack([enabled, enabled, rolls], -1)
    scale = jnp.where(active, 1.0 / jnp.sqrt(jnp.where(w_diag > 0, w_diag, 1.0)), 0.0)

    args = (apply_w, *jax.lax.stop_gradient((operand, b, sets)), scale)

    y0 = p0 / jnp.where(scale > 0, scale, 1.0)
    # Named: a rematerialising reverse pass (``rollout``) keeps the solve's result rather
    # than running its loops again.
    y, k, res = checkpoint_name(_fista_newton(args, y0, tol, max_iter, force_scale, newton), SOLUTION)
    y = _implicit(apply_w, operand, b, sets, scale, y)
    return Solution(scale * y, k, res, res <= tol)


def _fista_newton(args, y0, tol, max_iter, force_scale, newton):
    """FISTA until converged or stalled; then semismooth Newton from its best point (a
    stalled solve: a near-redundant contact set); and again, with FISTA's patience doubled
    at each hand-over, so Newton costs a bounded share. FISTA starts afresh from a Newton
    point better than its own best; otherwise its momentum is left as it was. (One start,
    in the loop: each call site of a function is its own code.) Without ``newton``
    (static), FISTA alone. Returns the scaled solution, the iterations and the residual."""
    one, zero, inf = jnp.ones_like(tol), jnp.int32(0), jnp.full_like(tol, jnp.inf)
    if not newton:
        fista = _iterate(*args, _fista_start(*args, y0, zero, one, force_scale), tol, max_iter, force_scale,
                         jnp.iinfo(jnp.int32).max)
        return fista.y_best, fista.k, fista.res_best

    def cond(carry):
        fista, _, _, res, _ = carry
        return (res > tol) & (fista.k < max_iter)

    def body(carry):
        fista, stall, y, _, restart = carry
        fresh = _fista_start(*args, y, fista.k, fista.lip, force_scale)
        fista = jax.tree.map(lambda a, b: jnp.where(restart, a, b), fresh, fista)
        fista = _iterate(*args, fista, tol, max_iter, force_scale, stall)
        y, k, res = _newton(*args, fista.y_best, fista.ay_best, fista.k, fista.res_best, tol, max_iter, force_scale)
        better = res < fista.res_best
        return fista._replace(k=k, k_mark=k), 2 * stall, y, jnp.minimum(res, fista.res_best), better

    blank = FistaState(y0, y0, y0, y0, one, one, y0, y0, zero, inf, zero, inf)
    fista, _, y, res, better = jax.lax.while_loop(cond, body, (blank, jnp.int32(STALL), y0, inf, jnp.array(True)))
    return jnp.where(better, y, fista.y_best), fista.k, jnp.where(better, res, fista.res_best)


# FISTA hands over to Newton when its least residual has not halved in STALL iterations
# (doubling at each hand-over); Newton hands back when its least residual has not fallen
# in NEWTON_PATIENCE steps.
STALL = 50
# Semismooth Newton steps per hand-over, each one GMRES cycle of at most NEWTON_KRYLOV products.
NEWTON_STEPS, NEWTON_KRYLOV, NEWTON_PATIENCE = 24, 60, 6
# A Newton system whose least-squares residual exceeds this part of its right side has no solution.
NULL_GATE = 1e-8


def _maps(apply_w, operand, b, sets, scale, force_scale):
    """The projection, S W S, S b and the relative natural residual of the scaled VI."""
    def proj(z):
        return project(z, scale, sets)

    def amul(y):  # S W S y
        return scale * apply_w(operand, scale * y)

    def residual(y, fy):
        r = scale * (y - proj(y - fy))
        size = jnp.maximum(jnp.max(jnp.abs(scale * y), initial=0.0), force_scale)
        return jnp.max(jnp.abs(r), initial=0.0) / jnp.where(size > 0, size, 1.0)

    return proj, amul, scale * b, residual


class FistaState(NamedTuple):
    """The iterate of ``_iterate`` (scaled unknowns y = p / scale)."""

    y: jax.Array  # (C, 3) the iterate
    ay: jax.Array  # S W S y
    y_prev: jax.Array  # the previous iterate (momentum)
    ay_prev: jax.Array  # S W S y_prev
    t: jax.Array  # () Nesterov's momentum parameter
    lip: jax.Array  # () L, the step's curvature bound
    y_best: jax.Array  # the iterate of least residual
    ay_best: jax.Array  # S W S y_best
    k: jax.Array  # () int32 iterations so far (products with W)
    res_best: jax.Array  # () the least residual
    k_mark: jax.Array  # () the iteration at which res_best last halved
    res_mark: jax.Array  # () res_best then


def _fista_start(apply_w, operand, b, sets, scale, y0, k0, lip0, force_scale) -> FistaState:
    """The state of ``_iterate`` starting at P(y0) after k0 iterations, with L = lip0."""
    proj, amul, c, residual = _maps(apply_w, operand, b, sets, scale, force_scale)
    y0 = proj(jnp.where(sets.enabled[:, None], y0, 0.0))
    a0 = amul(y0)
    res0 = residual(y0, a0 + c)
    return FistaState(y0, a0, y0, a0, jnp.ones_like(lip0), lip0, y0, a0, k0, res0, k0, res0)


def _iterate(apply_w, operand, b, sets, scale, state, tol, max_iter, force_scale, stall):
    """Accelerated projected gradient on the scaled unknowns y = p / scale, from ``state``.

    FISTA (Beck & Teboulle 2009): y+ = P(z - F(z) / L) from the extrapolated point
    z = y + theta (y - y_prev), with the adaptive restart of O'Donoghue & Candes (2015):
    the momentum is dropped when the step goes against it, (z - y+).(y+ - y) > 0. With
    the friction and rolling bounds frozen at the normal forces the problem is the convex
    QP min 1/2 y^T (S W S) y + (S b)^T y over X (S W S has unit diagonal, its condition
    number grows as the square of a force chain's length, so the momentum's square root
    of it is what counts on piles: ~10x fewer iterations than projection-contraction).
    P bounds them by the projected normal of the same point, so every iterate lies in
    X(y) and a fixed point solves the QVI. L (the largest eigenvalue of S W S, >= 1) is
    found by backtracking: a step whose curvature d^T (S W S) d exceeds
    L |d|^2 is redone with a larger L. S W S y is carried along (one product per
    iteration; the extrapolation's by linearity), so the residual costs no extra product.

    Redundant contacts (two corners on one face, an adjoint pair) give S W S null
    modes: self-equilibrated forces that move nothing. Where S b has a component along
    one (the contacts' kinematics disagree, by as little as 1e-8), no force sticks both
    contacts, and the solution lies where the mode meets a friction cone; along the mode
    the residual is flat and the iterates crawl towards it. So the loop also stops when
    its least residual has not halved in ``stall`` iterations (``_newton`` takes over).
    Returns the state: y_best is the iterate of least residual, res_best that residual.
    """
    proj, amul, c, residual = _maps(apply_w, operand, b, sets, scale, force_scale)

    def cond(s: FistaState):
        return (s.res_best > tol) & (s.k < max_iter) & (s.k - s.k_mark <= stall)

    def body(carry):
        y, ay, y_prev, ay_prev, t, lip, y_best, ay_best, k, res_best, k_mark, res_mark = carry
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
        res_best = jnp.where(better, res, res_best)
        halved = res_best <= 0.5 * res_mark
        return FistaState(y, ay, y_prev, ay_prev, t, lip, jnp.where(better, y, y_best), jnp.where(better, ay, ay_best),
                          k + 1, res_best,
                          jnp.where(halved, k + 1, k_mark), jnp.where(halved, res_best, res_mark))

    return jax.lax.while_loop(cond, body, state)


def _newton(apply_w, operand, b, sets, scale, y0, ay0, k0, res0, tol, max_iter, force_scale):
    """Semismooth Newton on the natural map R(y) = y - P(y - F(y)), from a stalled FISTA.

    Each step solves (I - D (I - S W S)) delta = -R(y) in the least-squares sense (one
    GMRES cycle), D the Jacobian of P at y - F(y) (the matrix of ``_implicit``): on a
    face of X the step is exact, whatever the conditioning. Where the face holds a null
    mode with S b along it, the system has no solution and what GMRES leaves, e, lies
    along the mode; the step then goes on along e to the first bound it meets
    (``_ratio``), the face the solution lies on, and the next step solves that face. A
    stalled two-corner landing converges in 2 to 4 steps to a residual of 1e-14. The
    steps are not monotone in the residual: the least one is kept. A step counts as the
    m + 1 iterations its products with W cost (m those of the GMRES cycle; ``ay0`` is
    S W S y0, and each step's product gives the next one's).
    """
    proj, amul, c, residual = _maps(apply_w, operand, b, sets, scale, force_scale)
    m = min(NEWTON_KRYLOV, y0.size)

    def cond(carry):
        _, _, _, res, j, k, j_best = carry
        return (res > tol) & (j < NEWTON_STEPS) & (k < max_iter) & (j - j_best <= NEWTON_PATIENCE)

    def body(carry):
        y, ay, y_best, res_best, j, k, j_best = carry
        r, d_proj = linearize(y - (ay + c), scale, sets)
        rhs = r - y
        delta, left = _krylov(lambda v: v - d_proj(v - amul(v)), rhs, m)
        inconsistent = jnp.sum(left * left) > NULL_GATE ** 2 * jnp.sum(rhs * rhs)
        y = y + delta
        y = proj(y + jnp.where(inconsistent, _ratio(y, left, scale, sets), 0.0) * left)
        ay = amul(y)
        res = residual(y, ay + c)
        better = res < res_best
        return (y, ay, jnp.where(better, y, y_best), jnp.where(better, res, res_best), j + 1, k + m + 1,
                jnp.where(better, j + 1, j_best))

    _, _, y, res, _, k, _ = jax.lax.while_loop(cond, body, (y0, ay0, y0, res0, jnp.int32(0), k0, jnp.int32(0)))
    return y, k, res


def _ratio(y, u, scale, sets):
    """The largest s >= 0 with y + s u inside the bounds of X that y does not touch:
    p_n >= 0, |p_t| <= mu p_n, |m_r| <= delta p_n, linear in s (cohesion and tension,
    which only widen them, are left out: the step may stop short, never beyond)."""
    s_n = scale[:, 0]
    ratios = [jnp.where((u[:, 0] < 0) & (y[:, 0] > 0), -y[:, 0] / jnp.where(u[:, 0] < 0, u[:, 0], -1.0), jnp.inf)]
    for i, coef in ((1, sets.friction), (2, sets.rolling)):
        slope = coef * s_n / jnp.where(scale[:, i] > 0, scale[:, i], 1.0)  # bound on y_i per unit of y_n
        for sign in (1.0, -1.0):
            slack, rate = slope * y[:, 0] - sign * y[:, i], sign * u[:, i] - slope * u[:, 0]
            ok = (rate > 0) & (slack > 0) & (scale[:, i] > 0)
            ratios.append(jnp.where(ok, slack / jnp.where(ok, rate, 1.0), jnp.inf))
    s = jnp.min(jnp.where(sets.enabled, jnp.min(jnp.stack(ratios), 0), jnp.inf), initial=jnp.inf)
    return jnp.where(jnp.isfinite(s), s, 0.0)


# Arnoldi's breakdown: a new direction whose part outside the basis is below this share of
# it is round-off, and the basis is complete.
BREAKDOWN = 1e-10


def _krylov(matvec, rhs, m):
    """One GMRES(m) cycle for matvec(x) = rhs: Arnoldi with twice-repeated classical
    Gram-Schmidt, then the least-squares problem of the Hessenberg matrix. Returns the
    solution x (without its null modes) and what it leaves, rhs - matvec(x).

    The Krylov space of a Newton system has the dimension of its few active rows, far
    below m: once it is spanned (``BREAKDOWN``), the basis stops growing. Normalising the
    round-off that orthogonalisation leaves instead filled the basis with vectors that were
    not orthogonal to it, and the solution and its residual with their noise: on a light
    ring pinched by a 22 t disk (fuzz seed 598) every Newton step "left" 0.8-1.4 of its
    right side and the solve took 7 560 iterations; it now takes 2 Newton steps, 188."""
    shape, beta = rhs.shape, jnp.sqrt(jnp.sum(rhs * rhs))
    basis = jnp.zeros((m + 1, rhs.size), rhs.dtype).at[0].set(rhs.ravel() / jnp.where(beta > 0, beta, 1.0))
    rows = jnp.arange(m + 1)

    def arnoldi(j, carry):
        basis, hess = carry
        w = matvec(basis[j].reshape(shape)).ravel()
        size = jnp.sqrt(jnp.sum(w * w))
        h = jnp.where(rows <= j, basis @ w, 0.0)
        w = w - h @ basis
        h2 = jnp.where(rows <= j, basis @ w, 0.0)
        w, h = w - h2 @ basis, h + h2
        norm = jnp.sqrt(jnp.sum(w * w))
        norm = jnp.where(norm > BREAKDOWN * size, norm, 0.0)  # the space is spanned: stop adding to it
        basis = basis.at[j + 1].set(jnp.where(norm > 0, w / jnp.where(norm > 0, norm, 1.0), 0.0))
        return basis, hess.at[:, j].set(h.at[j + 1].set(norm))

    basis, hess = jax.lax.fori_loop(0, m, arnoldi, (basis, jnp.zeros((m + 1, m), rhs.dtype)))
    e1 = jnp.zeros(m + 1, rhs.dtype).at[0].set(beta)
    coef = _least_squares(hess, e1)
    return (coef @ basis[:m]).reshape(shape), ((e1 - hess @ coef) @ basis).reshape(shape)


def _least_squares(a, g):
    """min |a c - g|^2 + (1e-8 |a|)^2 |c|^2 for a small (r, m) matrix, by Householder QR of
    a over the scaled identity and back substitution, in plain array code: batched LAPACK
    kernels deadlock on XLA:CPU's thread pool (docs/design.md, "No LAPACK in the step").
    The damping drops singular values below 1e-8 |a| (null modes) and keeps the rest."""
    r, m = a.shape
    damp = 1e-8 * jnp.sqrt(jnp.sum(a * a))
    a = jnp.concatenate([a, damp * jnp.eye(m, dtype=a.dtype)])
    g = jnp.concatenate([g, jnp.zeros(m, g.dtype)])
    rows = jnp.arange(r + m)

    def reflect(j, carry):
        a, g = carry
        x = jnp.where(rows >= j, a[:, j], 0.0)
        norm = jnp.sqrt(jnp.sum(x * x))
        v = x.at[j].add(jnp.where(x[j] < 0, -norm, norm))  # x + sign(x_j) |x| e_j
        vv = jnp.sum(v * v)
        k = jnp.where(vv > 0, 2.0 / jnp.where(vv > 0, vv, 1.0), 0.0)
        return a - k * jnp.outer(v, v @ a), g - k * v * (v @ g)

    a, g = jax.lax.fori_loop(0, m, reflect, (a, g))
    diag = jnp.diagonal(a[:m])

    def substitute(i, c):
        j = m - 1 - i
        return c.at[j].set(jnp.where(diag[j] != 0, (g[j] - a[j, :m] @ c) / jnp.where(diag[j] != 0, diag[j], 1.0), 0.0))

    return jax.lax.fori_loop(0, m, substitute, jnp.zeros(m, a.dtype))


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
    _, d_proj = linearize(z, scale, sets)

    def matvec(v):
        return v - d_proj(v - scale * apply_w(operand, scale * v))

    return y, jax.lax.custom_linear_solve(matvec, -r_dot, _gmres, _gmres)
