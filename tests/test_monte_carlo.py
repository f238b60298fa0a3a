"""jaxdda.monte_carlo: batched scenarios against closed forms and against single runs.

Compiled programs are shared: one batch shape per scene kind.
"""
import dataclasses
import math
import os
import subprocess
import sys
import textwrap

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import jaxdda
from tests.compiles import counting
from jaxdda.observe import Observable
from jaxdda.step import step
from jaxdda.simulate import with_capacity
from jaxdda.types import Capacities

G = 10.0
ANGLE = math.radians(30.0)
SLOPE = np.array([math.cos(ANGLE), -math.sin(ANGLE)])
V0 = np.array([0.0, 0.5, 1.0, 2.0])
MU = np.array([0.1, 0.2, 0.3, 0.4])  # all below tan 30 = 0.577: every block slides
STEPS = 100


@pytest.fixture(scope="module")
def incline():
    return jaxdda.examples.get("incline")


# one dict for every run, so the runs share one compiled program (observables key it)
OBSERVE = {"final_centroid": jaxdda.observe.BUILTIN["final_centroid"],
           "max_speed": jaxdda.observe.BUILTIN["max_speed"], "runout": jaxdda.observe.BUILTIN["runout"],
           "mean_x": Observable(lambda s, s0: s.centroid[:, 0], "mean")}


def _incline_run(scene, params=None):
    return jaxdda.monte_carlo(scene, STEPS, velocity=V0[:, None] * SLOPE,
                              params={"friction": MU} if params is None else params,
                              observe=OBSERVE, trajectories=True, progress=False)


@pytest.fixture(scope="module")
def sliding(incline):
    return _incline_run(incline)


def test_each_scenario_slides_as_the_closed_form(incline, sliding):
    t = STEPS * 0.01
    accel = G * (math.sin(ANGLE) - MU * math.cos(ANGLE))
    travel = V0 * t + 0.5 * accel * t * t
    start = np.asarray(incline.state.centroid)[0]
    moved = sliding["final_centroid"][:, 0] - start
    np.testing.assert_allclose(moved @ SLOPE, travel, rtol=0, atol=1e-9)
    np.testing.assert_allclose(moved @ np.array([math.sin(ANGLE), math.cos(ANGLE)]), 0.0, atol=1e-9)
    np.testing.assert_allclose(sliding["max_speed"][:, 0], V0 + accel * t, rtol=0, atol=1e-9)
    np.testing.assert_allclose(sliding["runout"][:, 0], travel * math.cos(ANGLE), rtol=0, atol=1e-9)
    assert sliding.converged.all() and len(sliding) == 4


def test_observables_agree_with_the_kept_trajectory(sliding):
    traj = sliding.trajectory
    assert traj["centroid"].shape == (4, STEPS + 1, 2, 2) and sliding.time.shape == (STEPS + 1,)
    np.testing.assert_array_equal(traj["centroid"][:, -1], sliding["final_centroid"])
    np.testing.assert_allclose(sliding["mean_x"][:, 0], traj["centroid"][:, 1:, 0, 0].mean(1), rtol=1e-14)
    speed = np.linalg.norm(traj["velocity"][..., :2], axis=-1).max(1)
    # the same norm of the same velocities: XLA's square root may round 1 ulp from numpy's
    np.testing.assert_allclose(sliding["max_speed"], speed, rtol=2 * np.finfo(float).eps, atol=0)


def test_a_scenario_matches_a_single_run(incline, sliding):
    k = 2
    params = dataclasses.replace(incline.params, friction=jnp.full_like(incline.params.friction, MU[k]))
    state = dataclasses.replace(incline.state, velocity=incline.state.velocity.at[0, :2].set(V0[k] * SLOPE))
    run = jaxdda.simulate(dataclasses.replace(incline, state=state), STEPS, params=params)
    # equal up to the contact solve's tolerance (1e-12 relative): a batch takes other iterates
    np.testing.assert_allclose(sliding.trajectory["centroid"][k], run.centroid, rtol=0, atol=1e-9)
    np.testing.assert_allclose(sliding.trajectory["velocity"][k], run.velocity, rtol=0, atol=1e-9)


def test_undersized_buffers_are_regrown_to_the_same_result(incline, sliding):
    model, state = with_capacity(incline.model, incline.state, Capacities(1, 1, 1, 1, 1))
    small = _incline_run(dataclasses.replace(incline, model=model, state=state))
    # The same run up to the contact solve's tolerance, as a batch matches a single run
    # (above). Not bit for bit: XLA:CPU compiles an operation over the contact axis
    # differently by its length (the incline's step at 4 and at 128 contact rows differs
    # in the last bit of a centroid at its sixth step, on every engine since the first),
    # so buffers of other sizes round differently, and the solve then stops at other
    # iterates within its tolerance. A lost contact would move the block by its whole
    # motion (metres), not by 1e-10 m.
    for name in ("centroid", "rotation", "velocity"):
        np.testing.assert_allclose(small.trajectory[name], sliding.trajectory[name], rtol=0, atol=1e-9, err_msg=name)
    for name in sliding.observables:
        np.testing.assert_allclose(small[name], sliding[name], rtol=0, atol=1e-9, err_msg=name)
    np.testing.assert_array_equal(small.converged, sliding.converged)
    assert np.all(small.residual <= incline.params.tol) and np.all(sliding.residual <= incline.params.tol)
    np.testing.assert_allclose(small.max_penetration, sliding.max_penetration, rtol=0, atol=1e-9)


def test_batched_params_give_the_same_runs(incline, sliding):
    table = np.broadcast_to(np.asarray(incline.params.friction), (4,) + incline.params.friction.shape)
    params = jax.tree.map(lambda x: np.broadcast_to(np.asarray(x), (4,) + np.shape(x)), incline.params)
    params = dataclasses.replace(params, friction=MU[:, None, None] * np.ones_like(table))
    again = _incline_run(incline, params)
    np.testing.assert_array_equal(again.trajectory["centroid"], sliding.trajectory["centroid"])
    with pytest.raises(ValueError, match=r"params\.friction has shape"):
        jaxdda.monte_carlo(incline, 10, params=dataclasses.replace(params, friction=np.ones((4, 7, 7))),
                           progress=False)


def test_a_second_study_of_the_batch_size_compiles_nothing_and_shows_progress(incline, sliding, capsys):
    with counting() as compiled:
        again = jaxdda.monte_carlo(incline, STEPS, velocity=V0[::-1, None] * SLOPE, params={"friction": MU[::-1]},
                                   observe=OBSERVE, trajectories=True)
    assert compiled.compiles == 0
    np.testing.assert_allclose(again["runout"][::-1], sliding["runout"], rtol=1e-12, atol=1e-12)
    bar = capsys.readouterr().err
    assert f"{4 * STEPS}/{4 * STEPS}" in bar and "scenario-steps" in bar and "scenarios 4/4 done" in bar


def test_exceedance_curve(sliding):
    x, p = sliding.exceedance("runout")
    assert np.all(np.diff(x) >= 0) and p[0] == 1.0 and p[-1] == 0.25
    for xi, pi in zip(x, p):
        assert pi == np.mean(sliding["runout"][:, 0] >= xi)


def test_scenes_of_different_sizes_batch_by_padding():
    """A rockfall (3 bodies: a disk, two slabs) and the cemented pull of case 7.8 (2
    polygons, a load, joints) padded together match each one run alone."""
    scenes = [jaxdda.examples.get("rockfall"), jaxdda.examples.get("paper-7.8")]
    steps = 100
    mc = jaxdda.monte_carlo(scenes, steps, observe=("final_centroid", "final_rotation"), progress=False)
    np.testing.assert_array_equal(mc.n_bodies, [3, 2])
    assert mc["final_centroid"].shape == (2, 3, 2)
    for k, scene in enumerate(scenes):
        run = jaxdda.simulate(scene, steps)
        n = scene.n_bodies
        np.testing.assert_allclose(mc["final_centroid"][k, :n], run.centroid[-1], rtol=0, atol=1e-9)
        np.testing.assert_allclose(mc["final_rotation"][k, :n], run.rotation[-1], rtol=0, atol=1e-9)
    # 7.8's joint (strength 2000 N) holds the block against the 1000 N pull: padding kept
    # the joint (without it the block would have moved F t^2 / 2m = 0.125 m)
    pulled = mc["final_centroid"][1, 0] - np.asarray(scenes[1].state.centroid)[0]
    assert np.linalg.norm(pulled) < 1e-9


def _run_fresh(code, timeout):
    """Run ``code`` in a fresh Python (XLA_FLAGS unset); it must print "ok"."""
    env = dict(os.environ)
    env.pop("XLA_FLAGS", None)
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env, timeout=timeout)
    assert out.returncode == 0, out.stderr[-3000:]
    assert out.stdout.strip().endswith("ok")


def test_sharded_over_forced_host_devices_matches_one_device():
    code = textwrap.dedent("""
        import os
        os.environ["XLA_FLAGS"] = "--xla_force_host_platform_device_count=4"
        import jax, numpy as np, jaxdda
        assert len(jax.local_devices()) == 4
        scene = jaxdda.examples.get("rockfall")
        v = np.random.default_rng(1).normal(0.0, 1.0, (6, 2))  # 6 scenarios: padded to 8 = 2 per device
        four = jaxdda.monte_carlo(scene, 60, velocity=v, progress=False)
        one = jaxdda.monte_carlo(scene, 60, velocity=v, progress=False, devices=jax.local_devices()[:1])
        assert four.devices == 4 and one.devices == 1 and len(four) == 6
        for k in four.observables:
            np.testing.assert_allclose(four[k], one[k], rtol=0, atol=1e-9)
        print("ok")
    """)
    _run_fresh(code, timeout=600)


def test_a_batch_of_1024_scenarios_runs_to_the_end():
    # Two batched LAPACK kernels side by side stalled such a batch for good on 2 cores
    # (docs/design.md, "No LAPACK in the step"). In a fresh process, as a user would run
    # it, under a time limit.
    code = textwrap.dedent("""
        import numpy as np, jaxdda
        v = np.stack([np.linspace(0.5, 3.0, 1024), np.zeros(1024)], 1)
        mc = jaxdda.monte_carlo(jaxdda.examples.get("rockfall"), 20, velocity=v, batch_size=1024, progress=False)
        assert len(mc) == 1024 and mc.converged.all() and np.isfinite(mc["runout"]).all()
        print("ok")
    """)
    _run_fresh(code, timeout=300)


def test_the_step_calls_no_lapack_kernel():
    # Batched LAPACK kernels wait on XLA:CPU's thread pool and deadlock side by side.
    scene = jaxdda.examples.get("rockfall")
    batch = jax.tree.map(lambda x: jnp.stack([x, x]), scene.state)
    text = jax.jit(jax.vmap(lambda s: step(scene.model, s, scene.params))).lower(batch).as_text()
    assert "custom_call" not in text


@pytest.mark.smoke
@pytest.mark.parametrize("kwargs, message", [
    (dict(velocity=np.zeros((3, 5))), "velocity must be"),
    (dict(velocity=np.full((2, 2), np.nan)), "not finite"),
    (dict(velocity=np.zeros((2, 2)), body=1), "is fixed"),
    (dict(velocity=np.zeros((2, 2)), body=7), "body must be"),
    (dict(velocity=np.zeros((2, 2)), params={"friction": np.ones(3)}), "batch sizes disagree"),
    (dict(params={"friction": 0.3}), "leading batch axis"),
    (dict(params={"stiffness": np.ones(2)}), "cannot fit 'stiffness'"),
    (dict(params={"friction:granite": np.ones(2)}), "unknown material"),
    (dict(observe=("runout", "speed")), "unknown observable 'speed'"),
    (dict(velocity=np.zeros((0, 2))), "empty"),
    (dict(chunk=0), "chunk must be"),
])
def test_bad_input_is_named(incline, kwargs, message):
    with pytest.raises(ValueError, match=message):
        jaxdda.monte_carlo(incline, 10, progress=False, **kwargs)
