"""The impact stage (jaxdda/step/impacts.py) on its own: impulses of two rows between
three bodies against Newton's and Poisson's closed forms, and the energy bound on random
frictional impacts."""
import math

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from jaxdda.solver.sets import ContactSets
from jaxdda.step.impacts import energy_scale, impact

TOL = 1e-13


def _apply_w(w, p):
    return (w @ p.reshape(-1)).reshape(p.shape)


def _jacobian(bodies, rows):
    """J (2 rows x 3, 3 bodies x 3): normal, shear (the normal turned clockwise) and rolling
    rows of the relative velocity of a with respect to b at each row's point."""
    jac = np.zeros((2 * 3, 3 * 3))
    for k, (a, b, point, normal) in enumerate(rows):
        n = np.asarray(normal, float) / np.linalg.norm(normal)
        t = np.array([n[1], -n[0]])
        for body, sign in ((a, 1.0), (b, -1.0)):
            r = np.asarray(point, float) - np.asarray(bodies[body]["pos"], float)
            for i, d in enumerate((n, t)):
                jac[3 * k + i, 3 * body:3 * body + 3] += sign * np.array([d[0], d[1], r[0] * d[1] - r[1] * d[0]])
            jac[3 * k + 2, 3 * body + 2] += sign
    return jac


def _problem(bodies, rows, velocity, mu=0.0, delta=0.0, e=(1.0, 1.0), struck=(True, True), enabled=(True, True)):
    jac = _jacobian(bodies, rows)
    m_inv = np.zeros((9, 9))
    for i, body in enumerate(bodies):
        if not body.get("fixed", False):
            m_inv[3 * i:3 * i + 3, 3 * i:3 * i + 3] = np.diag([1 / body["m"], 1 / body["m"], 1 / body["i"]])
    w = jac @ m_inv @ jac.T
    v = np.asarray(velocity, float).reshape(-1)
    sets = ContactSets(enabled=jnp.asarray(enabled), friction=jnp.full(2, mu), cohesion=jnp.zeros(2),
                       tension=jnp.zeros(2), rolling=jnp.full(2, delta), partner=jnp.full(2, -1, jnp.int32))
    args = dict(w=jnp.asarray(w), v_minus=jnp.asarray((jac @ v).reshape(2, 3)), sets=sets, e=jnp.asarray(e, float),
                struck=jnp.asarray(struck), a=jnp.asarray([r[0] for r in rows]), b=jnp.asarray([r[1] for r in rows]),
                fixed=jnp.asarray([b.get("fixed", False) for b in bodies]))
    return args, jac, m_inv, v


@jax.jit
def _solve(args):
    w = args["w"]
    return impact(_apply_w, w, jnp.diagonal(w).reshape(2, 3), args["v_minus"], args["sets"], args["e"],
                  args["struck"], args["a"], args["b"], args["fixed"], jnp.zeros((2, 3)), jnp.asarray(TOL),
                  jnp.asarray(5000.0), jnp.asarray(1.0))


def _after(problem):
    args, jac, m_inv, v = problem
    out = _solve(args)
    return (v + m_inv @ jac.T @ np.asarray(out.impulse).reshape(-1)).reshape(3, 3), out


def _disk(x, y=0.0, m=1.0, r=1.0, fixed=False):
    return {"pos": (x, y), "m": m, "i": 0.5 * m * r * r, "fixed": fixed}


def test_head_on_impact_of_unequal_masses_is_newtons():
    m1, m2, v1, e = 1.0, 4.0, 3.0, 0.6
    bodies = [_disk(0.0, m=m1), _disk(2.0, m=m2), _disk(9.0, fixed=True)]
    rows = [(1, 0, (1.0, 0.0), (1.0, 0.0)), (1, 2, (3.0, 0.0), (-1.0, 0.0))]
    vel, out = _after(_problem(bodies, rows, [[v1, 0, 0], [0, 0, 0], [0, 0, 0]], e=(e, e), struck=(True, False),
                               enabled=(True, False)))
    mu = m1 * m2 / (m1 + m2)
    np.testing.assert_allclose(vel[:2, 0], [v1 - (1 + e) * mu * v1 / m1, (1 + e) * mu * v1 / m2], atol=1e-11)
    np.testing.assert_allclose(np.asarray(out.scale)[0], 1.0)


@pytest.mark.parametrize("e", [1.0, 0.5, 0.0])
def test_impact_on_a_touching_pair_passes_through_it(e):
    # B (body 0) strikes A (1) touching C (2), unit masses: (1 - 2 (1 + e) / 3, (1 + e) / 3 + ...) as Newton's law
    bodies = [_disk(0.0), _disk(2.0), _disk(4.0)]
    rows = [(1, 0, (1.0, 0.0), (1.0, 0.0)), (2, 1, (3.0, 0.0), (1.0, 0.0))]
    vel, _ = _after(_problem(bodies, rows, [[1, 0, 0], [0, 0, 0], [0, 0, 0]], e=(e, 0.3), struck=(True, False)))
    expect = {1.0: [-1 / 3, 2 / 3, 2 / 3], 0.5: [0.0, 0.5, 0.5], 0.0: [1 / 3, 1 / 3, 1 / 3]}[e]
    np.testing.assert_allclose(vel[:, 0], expect, atol=1e-11)


@pytest.mark.parametrize("mu", [0.1, 2.0])
def test_oblique_disk_on_a_rough_floor_follows_poissons_law(mu):
    # a disk (m = 2, r = 0.5) strikes a fixed floor at (1, -3) m/s spinning at 1 rad/s, e = 0.5
    m, r, e = 2.0, 0.5, 0.5
    bodies = [_disk(0.0, r, m=m, r=r), _disk(0.0, -5.0, fixed=True), _disk(9.0, fixed=True)]
    rows = [(0, 1, (0.0, 0.0), (0.0, 1.0)), (0, 2, (0.5, 0.0), (-1.0, 0.0))]
    u, v, w = 1.0, -3.0, 1.0
    vel, out = _after(_problem(bodies, rows, [[u, v, w], [0, 0, 0], [0, 0, 0]], mu=mu, e=(e, e),
                               struck=(True, False), enabled=(True, False)))
    p_n = -(1 + e) * m * v
    slip = u + w * r  # the contact point's velocity along +x (the shear axis is -x)
    stop = slip / (1 / m + r * r / (0.5 * m * r * r))  # the shear impulse that ends the slip
    if mu * p_n / (1 + e) < abs(stop):  # slides through compression (and restitution)
        p_t = mu * p_n
        assert not np.isclose(vel[0, 0] + vel[0, 2] * r, 0.0)
    else:  # sticks: the contact point leaves without slip (Poisson; no normal-shear coupling on a disk)
        p_t = stop
        np.testing.assert_allclose(vel[0, 0] + vel[0, 2] * r, 0.0, atol=1e-11)
    np.testing.assert_allclose(vel[0], [u - p_t / m, v + p_n / m, w - p_t * r / (0.5 * m * r * r)], atol=1e-11)


def _random_problem(seed):
    """Two rows: a rod (length 2 L) striking a floor with one or both ends, or a disk, with
    friction, rolling resistance and restitution drawn at random."""
    rng = np.random.default_rng(seed)
    L, m = rng.uniform(0.2, 2.0), rng.uniform(0.1, 10.0)
    tilt = rng.uniform(-0.6, 0.6)
    ends = [(L * math.cos(tilt) * s, L * math.sin(tilt) * s) for s in (-1.0, 1.0)]
    floor = min(ends[0][1], ends[1][1])
    bodies = [{"pos": (0.0, 0.0), "m": m, "i": m * L * L / 3}, _disk(0.0, floor - 5.0, fixed=True),
              _disk(0.0, rng.uniform(-3, 3), m=rng.uniform(0.1, 10.0))]
    second = rng.integers(0, 2)
    rows = [(0, 1, ends[0], (rng.normal() * 0.2, 1.0)),
            (0, 1, ends[1], (rng.normal() * 0.2, 1.0)) if second else (2, 0, (0.0, 0.0), (rng.normal(), rng.normal()))]
    velocity = rng.normal(size=(3, 3)) * [2.0, 2.0, 5.0]
    velocity[1] = 0.0
    return _problem(bodies, rows, velocity, mu=rng.uniform(0.0, 1.5), delta=rng.uniform(0.0, 0.1),
                    e=tuple(rng.uniform(0.0, 1.0, 2)), struck=(True, bool(rng.integers(0, 2))))


def _kinetic_energies(problem):
    """The impact's result, and the kinetic energy before and after it."""
    _, _, m_inv, v = problem
    vel, out = _after(problem)
    mass = np.linalg.pinv(m_inv)
    return out, 0.5 * v @ mass @ v, 0.5 * vel.reshape(-1) @ mass @ vel.reshape(-1)


def test_no_impact_makes_energy():
    gained = []
    for seed in range(40):
        out, before, after = _kinetic_energies(_random_problem(seed))
        gained.append((after - before) / max(before, 1e-300))
        # the rows never pull, nor approach after the impact (to the solve's tolerance)
        assert np.all(np.asarray(out.impulse)[:, 0] >= -1e-12 * np.abs(out.impulse).max())
    assert max(gained) <= 1e-10, max(gained)


def _rod_corner(seed):
    """A spinning rod (length 2, unit mass) striking a rough floor with one end, e = 1:
    where the end sticks, Newton's restitution on its normal impulse alone turns the rod
    faster than it came (Kane's paradox)."""
    rng = np.random.default_rng(seed)
    tilt = rng.uniform(-1.4, 1.4)
    end = (math.cos(tilt), math.sin(tilt))
    bodies = [{"pos": (0.0, 0.0), "m": 1.0, "i": 1.0 / 3}, _disk(0.0, -5.0, fixed=True), _disk(0.0, 9.0, fixed=True)]
    rows = [(0, 1, end, (0.0, 1.0)), (0, 2, (0.0, 3.0), (0.0, -1.0))]
    velocity = np.zeros((3, 3))
    velocity[0] = [rng.normal() * 2, -abs(rng.normal()) * 2 - 0.1, rng.normal() * 6]
    return _problem(bodies, rows, velocity, mu=rng.uniform(0.2, 3.0), e=(1.0, 1.0), struck=(True, False),
                    enabled=(True, False))


def test_the_energy_bound_holds_a_sticking_corner_to_its_energy():
    bounded = 0
    for seed in range(60):
        problem = _rod_corner(seed)
        _, jac, m_inv, v = problem
        out, before, after = _kinetic_energies(problem)
        assert after - before <= 1e-12 * before
        if float(out.scale[0]) < 1.0:  # the full restitution would have made energy
            bounded += 1
            free = np.asarray(out.compression) + np.asarray(out.restitution) / float(out.scale[0])
            v_full = v + m_inv @ jac.T @ free.reshape(-1)
            assert 0.5 * v_full @ np.linalg.pinv(m_inv) @ v_full > before
            np.testing.assert_allclose(after, before, rtol=1e-9)  # it keeps all it can
    assert bounded > 0


@pytest.mark.smoke
def test_energy_bound_has_a_finite_derivative_where_it_is_idle():
    # Rows with no compression and no kick (a = b = c = 0: the bound's discriminant is 0)
    # take s = 1; reverse mode through them must stay finite (sqrt'(0) is infinite).
    def total(v):
        zero = jnp.zeros((2, 3))
        return jnp.sum(energy_scale(zero, zero, v, zero, zero, jnp.array([0, 0]), 1))

    grad = jax.grad(total)(jnp.ones((2, 3)))
    assert np.all(np.isfinite(grad))


@pytest.mark.smoke
def test_refits_find_the_root_of_a_gap_the_quadratic_misses_and_then_settle():
    # g(t) = g0 + v t + a t^2 / 2 + j t^3: the start frame's quadratic misses the cubic
    # term; the refits converge to the exact root, stop once a pass changes nothing (more
    # passes allowed give the same bits), and the root's derivative is the implicit one.
    from jaxdda.integrate import exact_impact_time
    g0, v, a, j, dt = 2e-3, -0.5, -10.0, 400.0, 0.01
    coef = jnp.asarray([j, 0.5 * a, v])

    def root(g, passes):
        gap_at = lambda t: g + t * (coef[2] + t * (coef[1] + t * coef[0]))  # noqa: E731
        t, hits, rate = exact_impact_time(g, jnp.full_like(g, v), jnp.full_like(g, a), jnp.asarray(dt),
                                          jnp.zeros_like(g), gap_at, passes)
        return t, (hits, rate)

    g = jnp.asarray([g0, 0.5 * g0])
    exact = [min(r.real for r in np.roots([j, 0.5 * a, v, x]) if abs(r.imag) < 1e-12 and r.real > 0) for x in g]
    for passes in (6, 20, 60):  # each pass gains two digits here: settled after 8
        t, (hits, rate) = jax.jit(root, static_argnums=1)(g, passes)
        np.testing.assert_allclose(np.asarray(t), exact, rtol=1e-12)
        assert np.all(np.asarray(hits)) and np.all(np.asarray(rate) < 0)
    assert np.array_equal(np.asarray(t), np.asarray(jax.jit(root, static_argnums=1)(g, 20)[0]))
    t, dt_dg = jax.jvp(lambda x: root(x, 6)[0], (g,), (jnp.ones_like(g),))
    slope = v + t * (a + 3.0 * j * t)
    np.testing.assert_allclose(np.asarray(dt_dg), -1.0 / np.asarray(slope), rtol=1e-10)


def test_a_batch_of_refits_settles_once_its_roots_move_by_round_off_only():
    # 256 cubic gaps refitted as one vector (as a vmapped batch is): each pass gains about
    # two digits, so the roots settle in about 10 of the 20 passes allowed. Settling on
    # bit-equality never happened here (some root flips an ulp): all 20 ran.
    from jaxdda.integrate import exact_impact_time
    v, a, dt, allowed = -0.5, -10.0, 0.01, 20
    rng = np.random.default_rng(1)
    g, j = jnp.asarray(rng.uniform(1e-4, 4e-3, 256)), jnp.asarray(rng.uniform(-400.0, 400.0, 256))
    calls = []

    def roots(g, j):
        def gap_at(t):
            jax.debug.callback(lambda _: calls.append(1), t)
            return g + t * (v + t * (0.5 * a + t * j))
        return exact_impact_time(g, jnp.full_like(g, v), jnp.full_like(g, a), jnp.asarray(dt), jnp.zeros_like(g),
                                 gap_at, allowed)[0]

    t = np.asarray(jax.jit(roots)(g, j))
    passes = len(calls) - 2  # less the pass that reads the rate, and the root's value
    assert passes <= allowed // 2 + 2
    exact = [min(r.real for r in np.roots([jk, 0.5 * a, v, gk]) if abs(r.imag) < 1e-12 and r.real > 0)
             for gk, jk in zip(np.asarray(g), np.asarray(j))]
    np.testing.assert_allclose(t, exact, rtol=1e-12)
