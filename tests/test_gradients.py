"""Gradients through contact (issue 5): reverse mode (grad) and forward mode (jvp) of rollouts
against closed forms and central finite differences; finite at non-smooth events."""
import dataclasses
import functools
import math

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import jaxdda
from jaxdda._pytree import float0, int_zeros
from jaxdda.examples import practical
from jaxdda.scene.builder import SceneBuilder
from jaxdda.scene.padding import Shape, pad_scene
from jaxdda.types import Capacities

G = 10.0
FD_RTOL = 1e-5  # the bar for smooth regimes
pytestmark = pytest.mark.usefixtures("no_persistent_cache")
# The rollouts here are not checkpointed: the gradient is the same (remat recomputes the
# same step), and the program compiles in about half the time (value_and_grad of 5 steps
# of case 7.1: 256 -> 136 s); test_calibrate and the fixed-point pendulum differentiate
# the checkpointed rollout that calibration uses.
#
# Every case's scene is padded to one shape and run in chunks of CHUNK steps, so that all
# of them share three compiled programs (a chunk, its vjp and its jvp) and the chain rule
# joins the chunks: a gradient program compiles in minutes, one per case cost the suite's
# longest worker 18 of its 33 minutes.
CHUNK = 5
SHAPE = Shape(bodies=16, vertices=4, materials=4, loads=1, knots=2, joints=4, connectors=0, groups=0, group_size=0,
              group_dofs=1, pins=0, capacity=Capacities(candidates=64, pairs_pp=16, pairs_pb=16, pairs_bb=16,
                                                        contacts=32))


def _with(scene, tol=1e-14):
    """The scene solved to ``tol`` (finite differences need a solve far below their step)."""
    return dataclasses.replace(scene, params=dataclasses.replace(scene.params, tol=jnp.asarray(np.float64(tol))))


def _fits(shape, room):
    flat = jax.tree.leaves(dataclasses.astuple(shape)), jax.tree.leaves(dataclasses.astuple(room))
    return all(a <= b for a, b in zip(*flat))


def _chunk(model, state, params):
    """CHUNK steps: (end state, the steps' infos)."""
    end, (_, infos) = jaxdda.rollout(model, state, params, CHUNK, checkpoint=False)
    return end, infos


@jax.jit
def _chunk_vjp(model, state, params, cotangent):
    out, pull_back = jax.vjp(lambda s, p: _chunk(model, s, p), state, params)
    return int_zeros(pull_back(float0(cotangent)), (state, params))


@jax.jit
def _chunk_jvp(model, state, params, tangent):
    out, d_out = jax.jvp(lambda s, p: _chunk(model, s, p), (state, params), float0(tangent))
    return out, int_zeros(d_out, out)


_chunk_forward = jax.jit(_chunk)


class Case:
    """A scalar observable f(theta) = observe(end state, last chunk's infos) of a rollout,
    with its gradient by reverse mode (and its jvp by forward mode) through the shared chunk
    programs. f is NaN if a contact buffer overflowed."""

    def __init__(self, scene, steps, setup, observe):
        assert steps % CHUNK == 0 and _fits(Shape.covering([scene]), SHAPE)
        self.model, state, params = jax.tree.map(jnp.asarray, pad_scene(scene, SHAPE))
        self.start = functools.partial(setup, params, state)
        self.chunks, self.observe = steps // CHUNK, observe

    def _forward(self, theta):
        """(f, the chunks' start states, the last chunk's infos, the params)."""
        params, state = self.start(theta)
        starts, overflow = [], False
        for _ in range(self.chunks):
            starts.append(state)
            state, infos = _chunk_forward(self.model, state, params)
            overflow = overflow | jnp.any(infos.overflow)
        return state, infos, starts, params, jnp.where(overflow, jnp.nan, 0.0)

    def value(self, theta):
        end, infos, _, _, nan = self._forward(theta)
        return self.observe(end, infos) + nan

    def grad(self, theta):
        """Reverse mode: the observable's cotangent pulled back chunk by chunk, then
        through the setup."""
        end, infos, starts, params, _ = self._forward(theta)
        _, pull_back = jax.vjp(self.observe, end, infos)
        ct_state, ct_infos = int_zeros(pull_back(jnp.ones(())), (end, infos))
        ct_params = jax.tree.map(jnp.zeros_like, params)
        for state in reversed(starts):
            ct_state, ct_p = _chunk_vjp(self.model, state, params, (ct_state, ct_infos))
            ct_params = jax.tree.map(jnp.add, ct_params, ct_p)
            ct_infos = jax.tree.map(jnp.zeros_like, ct_infos)
        _, pull_setup = jax.vjp(self.start, theta)
        return pull_setup(float0((ct_params, ct_state)))[0]

    def jvp(self, theta, direction):
        """Forward mode: the setup's tangent pushed through the chunks."""
        (params, state), (d_params, d_state) = jax.jvp(self.start, (theta,), (direction,))
        d_params = int_zeros(d_params, params)
        for _ in range(self.chunks):
            (state, infos), (d_state, d_infos) = _chunk_jvp(self.model, state, params, (int_zeros(d_state, state),
                                                                                          d_params))
        return jax.jvp(self.observe, (state, infos), float0((d_state, d_infos)))

    def __call__(self, theta):
        value = float(self.value(_floats(theta)))
        assert np.isfinite(value)
        return value

    def gradient(self, theta):
        return {k: float(v) for k, v in self.grad(_floats(theta)).items()}

    def fd(self, theta, key, eps):
        up, down = dict(theta), dict(theta)
        up[key], down[key] = theta[key] + eps, theta[key] - eps
        return (self(up) - self(down)) / (2 * eps)

    def check(self, theta, eps, exact=None, forward=False):
        """The gradient equals central differences (and the closed form ``exact``); with
        ``forward``, the jvp along every unit direction too."""
        grad = self.gradient(theta)
        for key in eps:
            fd = self.fd(theta, key, eps[key])
            np.testing.assert_allclose(grad[key], fd, rtol=FD_RTOL, err_msg=key)
            if exact is not None:
                np.testing.assert_allclose(grad[key], exact[key], rtol=FD_RTOL, err_msg=key)
            if forward:
                unit = {k: jnp.asarray(float(k == key)) for k in theta}
                np.testing.assert_allclose(float(self.jvp(_floats(theta), unit)[1]), grad[key], rtol=1e-10)
        return grad


def _floats(theta):
    return {k: jnp.asarray(v, jnp.float64) for k, v in theta.items()}


def _set_table(params, name, value):
    return dataclasses.replace(params, **{name: jnp.full_like(getattr(params, name), value)})


# -- a block sliding down a 30 degree incline ---------------------------------------------
ANGLE, T_INCLINE = math.radians(30.0), 0.5
DOWN = np.array([math.cos(ANGLE), -math.sin(ANGLE)])


def _incline_setup(params, state, theta):
    velocity = state.velocity.at[0, :2].set(theta["v0"] * jnp.asarray(DOWN))
    return _set_table(params, "friction", theta["mu"]), dataclasses.replace(state, velocity=velocity)


@functools.cache
def incline():
    scene = _with(practical.incline())
    return Case(scene, round(T_INCLINE / 0.01), _incline_setup,
                lambda end, infos: end.displacement[0] @ jnp.asarray(DOWN))


def test_incline_gradient_vs_friction_and_initial_velocity():
    # s(T) = v0 T + g (sin a - mu cos a) T^2 / 2 while sliding (the step is exact for it)
    exact = {"mu": -0.5 * G * math.cos(ANGLE) * T_INCLINE ** 2, "v0": T_INCLINE}
    incline().check({"mu": 0.3, "v0": 0.5}, {"mu": 1e-4, "v0": 1e-4}, exact, forward=True)


def test_gradient_at_stick_and_at_zero_relative_velocity_is_finite():
    # Stuck (mu > tan 30): the block stays put for every nearby mu, so ds/dmu = 0; at
    # v0 = 0 the sliding starts from rest (zero relative velocity) and is still smooth in mu.
    stuck = incline().gradient({"mu": 0.8, "v0": 0.0})
    assert abs(stuck["mu"]) < 1e-9 and np.isfinite(stuck["v0"])
    rest = incline().gradient({"mu": 0.3, "v0": 0.0})
    np.testing.assert_allclose(rest["mu"], -0.5 * G * math.cos(ANGLE) * T_INCLINE ** 2, rtol=FD_RTOL)
    assert np.isfinite(rest["v0"])


# -- a disk rolling to rest against rolling resistance ------------------------------------
T_ROLL, RADIUS = 1.0, 0.5


@functools.cache
def rolling():
    scene = _with(practical.rolling_disk(radius=RADIUS))
    return Case(scene, round(T_ROLL / 0.01), lambda p, s, th: (_set_table(p, "rolling", th["delta"]), s),
                lambda end, infos: end.displacement[0, 0])


def test_rolling_disk_gradient_vs_rolling_coefficient():
    # x(T) = v0 T - delta g T^2 / (3 R) while it rolls (I = m R^2 / 2)
    rolling().check({"delta": 0.01}, {"delta": 1e-6}, {"delta": -G * T_ROLL ** 2 / (3 * RADIUS)})


# -- contact forces of a static stack -------------------------------------------------------
def _base_reaction(end, infos):
    c = infos.contacts
    on_base = c.valid[-1] & ((c.a[-1] == 3) | (c.b[-1] == 3))
    return jnp.sum(jnp.where(on_base, c.normal_force[-1], 0.0))


@functools.cache
def stack():
    scene = jaxdda.examples.get("paper-7.1")  # tol 1e-14 already
    return Case(scene, 5, lambda p, s, th: (dataclasses.replace(p, density=p.density.at[:3].set(th["rho"])), s),
                _base_reaction)


def test_static_stack_reaction_vs_density():
    # the base carries the three disks: 3 rho pi R^2 g
    stack().check({"rho": 2500.0}, {"rho": 1e-2}, {"rho": 3 * math.pi * 100.0 * G})


# -- a deformable block ----------------------------------------------------------------------
@functools.cache
def deformable():
    sb = SceneBuilder(dt=0.002, gravity=(0.0, -G), tol=1e-14)
    sb.add_material("m", friction=0.5, restitution=0.0)
    sb.add_polygon(vertices=[(0, 0), (1, 0), (1, 1), (0, 1)], density=1000.0, young=1e6, poisson=0.25,
                   material="m", velocity=(0.3, 0.0))
    sb.add_polygon(vertices=[(-2, -1), (5, -1), (5, 0), (-2, 0)], density=1000.0, fixed=True, material="m")
    scene = sb.build()
    return Case(scene, 40, lambda p, s, th: (dataclasses.replace(p, young=p.young.at[0].set(th["E"])), s),
                lambda end, infos: end.displacement[0, 1] + end.stretch[0, 0, 0])


def test_deformable_block_gradient_vs_young_modulus():
    grad = deformable().check({"E": 1e6}, {"E": 1.0})
    assert grad["E"] != 0.0


# -- cemented interface: broken joints and the smoothed rupture ------------------------------
STEPS_PULL = 40


def _pull_setup(params, state, theta):
    params = _set_table(params, "tensile", theta["t"])
    return dataclasses.replace(params, load_force=params.load_force.at[0, 0].set(theta["F"]),
                               load_rate=params.load_rate.at[0, 0].set(theta["rate"]),
                               rupture_width=theta["w"]), state


@functools.cache
def pull():
    return Case(_with(jaxdda.examples.get("paper-7.8")), STEPS_PULL, _pull_setup,
                lambda end, infos: end.displacement[0, 0])


def test_gradient_after_the_joints_break():
    # F = 2500 > t breaks the joints in step 1, which carry t meanwhile: a = (F - t) / m
    # for one step, then F / m. Smooth in F and t (the break step does not move).
    grad = pull().check({"t": 2000.0, "F": 2500.0, "rate": 0.0, "w": 0.0}, {"t": 1e-2, "F": 1e-2})
    assert all(np.isfinite(v) for v in grad.values())


def test_smoothed_rupture_makes_the_strength_informative():
    # Under a ramped pull F = 900 t the joints break in the first step whose load exceeds t
    # (step 23 of 40 for t = 200 N, dt = 0.01 s): the end position depends on t through
    # that step, a staircase in t of treads 9 N wide.
    hard = {"t": 200.0, "F": 0.0, "rate": 900.0, "w": 0.0}
    trend = pull().fd(hard, "t", 50.0)  # the staircase's slope over +-50 N
    assert trend < 0  # a stronger cement holds the block longer
    # The sharp model's slope is local only: the joints' t acts in the break step alone, so
    # dx/dt = -dt (T - t_b) / m against the trend's dx/dt_b dt_b/dt = -(t / R) (T - t_b) / m,
    # a ratio of one step's load to t (R dt / t = 1 / 22). Within 25 %: the staircase's
    # quantisation (a tread in 11) and its curvature over +-50 N (3 %).
    ratio = pull().gradient(hard)["t"] / trend
    np.testing.assert_allclose(ratio, hard["rate"] * 0.01 / hard["t"], rtol=0.25)
    # A width far below the load increments is the sharp model.
    narrow = dict(hard, w=1e-6)
    assert pull()(narrow) == pull()(hard)
    assert pull().gradient(narrow)["t"] == pull().gradient(hard)["t"]
    # A width of two treads (10 % of t): a differentiable model whose gradient follows the trend.
    smooth = dict(hard, w=20.0)
    grad = pull().check(smooth, {"t": 1e-3})["t"]
    assert 0.1 * trend > grad > 10.0 * trend
