"""The contact solve (solver/fista_newton.py) on its own: random frictional contact problems of a
rigid block landing on two corners (a redundant pair: one self-equilibrated force mode),
checked against the VI's own conditions (Signorini and Coulomb, eqs. 19 and 26-28), not
against the solver's residual."""
from __future__ import annotations

import re

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from jaxdda.solver import fista_newton
from jaxdda.solver.sets import ContactSets

C = 2  # contacts per problem
BATCH = 96


def _apply_w(w, p):
    return (w @ p.reshape(-1)).reshape(p.shape)


def _problems(seed: int):
    """A block (mass m, inertia I) touching a fixed face at C points of its bottom edge,
    each normal tilted by at most 0.003 rad (near-parallel shear rows: W is singular),
    moving with a random velocity v into the face: b = J v plus a disagreement of
    relative size 10^-9..10^-3 (impacts at different instants of a step, or a mixed
    gap- and velocity-level b, leave one), which no force that sticks both contacts can
    absorb: the solution slides one of them, a null mode's length away. FISTA alone
    left 13 of these 96 above tolerance after 5000 iterations."""
    rng = np.random.default_rng(seed)
    ws, bs, mus = [], [], []
    for _ in range(BATCH):
        m, inertia = rng.uniform(0.5, 2.0), rng.uniform(0.05, 0.5)
        x = np.sort(rng.uniform(-0.5, 0.5, C))
        tilt = rng.uniform(-0.003, 0.003, C)
        n = np.stack([np.sin(tilt), np.cos(tilt)], 1)
        t = np.stack([n[:, 1], -n[:, 0]], 1)
        r = np.stack([x, np.full(C, -0.5)], 1)
        cross = lambda a: r[:, 0] * a[:, 1] - r[:, 1] * a[:, 0]
        jac = np.zeros((C, 3, 3))
        jac[:, 0] = np.concatenate([n, cross(n)[:, None]], 1)
        jac[:, 1] = np.concatenate([t, cross(t)[:, None]], 1)
        jac = jac.reshape(3 * C, 3)
        ws.append(jac @ np.diag([1 / m, 1 / m, 1 / inertia]) @ jac.T)
        v = np.array([rng.normal(), -rng.uniform(0.5, 3.0), rng.normal()])
        b = (jac @ v).reshape(C, 3)
        b[:, :2] += 10.0 ** rng.uniform(-9, -3) * rng.normal(size=(C, 2)) * np.abs(b[:, :2]).max()
        b[:, 2] = 0.0
        bs.append(b)
        mus.append(rng.uniform(0.1, 1.0))
    return np.array(ws), np.array(bs), np.array(mus)


@jax.jit
@jax.vmap
def _solve(w, b, mu):
    sets = ContactSets(enabled=jnp.ones(C, bool), friction=jnp.full(C, mu), cohesion=jnp.zeros(C),
                       tension=jnp.zeros(C), rolling=jnp.zeros(C), partner=jnp.full(C, -1, jnp.int32))
    diag = jnp.diagonal(w).reshape(C, 3)
    return fista_newton.solve(_apply_w, w, diag, b, sets, jnp.zeros_like(b), jnp.asarray(1e-12), jnp.asarray(5000.0))


@pytest.fixture(scope="module")
def solved():
    w, b, mu = _problems(0)
    return w, b, mu, _solve(w, b, mu)


def test_redundant_contacts_converge(solved):
    *_, out = solved
    assert np.asarray(out.converged).all(), np.asarray(out.residual).max()


def test_solutions_meet_signorini_and_coulomb(solved):
    w, b, mu, out = solved
    p = np.asarray(out.force)
    g = np.einsum("kij,kj->ki", w, p.reshape(BATCH, -1)).reshape(p.shape) + b
    scale = np.abs(p).max((1, 2))[:, None]
    tol = 1e-9 * scale
    force_of = g[..., :2] / np.diagonal(w, axis1=1, axis2=2).reshape(p.shape)[..., :2]  # a gap as the force closing it
    pn, pt, gn, gt = p[..., 0], p[..., 1], force_of[..., 0], force_of[..., 1]
    assert (pn >= -tol).all() and (gn >= -tol).all()
    assert (np.minimum(pn, gn) <= tol).all()  # open or closed, never both
    bound = mu[:, None] * pn
    assert (np.abs(pt) <= bound + tol).all()
    sticks = np.abs(pt) < bound - tol
    assert (np.abs(gt)[sticks] <= tol.repeat(C, 1)[sticks]).all()  # sticking: no slip
    assert (pt * gt <= tol * np.abs(pt) + 1e-300).all()  # sliding: the force opposes the slip


def _solver_loops(fun, *args) -> int:
    """While loops in the contact solve's functions of ``fun``'s lowered program."""
    loops, name = 0, ""
    for line in jax.jit(fun).lower(*args).as_text().splitlines():
        head = re.match(r"\s*func\.func (?:private |public )?@([\w.]+)", line)
        name = head.group(1) if head else name
        loops += name.startswith("solve") and "stablehlo.while" in line
    return loops


def test_the_reverse_pass_of_a_checkpointed_rollout_reruns_no_solve():
    # rollout(checkpoint=True) recomputes each step in the reverse pass but keeps the
    # results of its contact solves: its gradient holds no solver loop beyond those of
    # the gradient that keeps every intermediate (rerunning them cost 12 more loops).
    import jaxdda
    from jaxdda.examples import practical
    scene = practical.incline()

    def slide(mu, checkpoint):
        params = scene.params.replace(friction=jnp.full_like(scene.params.friction, mu))
        end, _ = jaxdda.rollout(scene.model, scene.state, params, 2, checkpoint=checkpoint)
        return end.displacement[0, 0]

    mu = jnp.asarray(0.3)
    kept = _solver_loops(jax.grad(lambda m: slide(m, False)), mu)
    assert kept >= _solver_loops(lambda m: slide(m, True), mu) > 0
    assert _solver_loops(jax.grad(lambda m: slide(m, True)), mu) <= kept
