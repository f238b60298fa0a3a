"""Case 7.10: a chain of 9 disks and 2 concave star blocks joined by 10 springs, dropped
on a fixed disk: first touch at t = sqrt(2H/g) (step 155), no interpenetration, springs
intact, the chain drapes over the disk and the part lying on it comes to rest. The two
ends (a disk and a star on each side) hang past the disk and keep swinging as a double
pendulum: nothing in the model damps them but the integrator (docs/design.md)."""
import math

import numpy as np
import pytest

import jaxdda

H, G, DT, STEPS = 3.0, 10.0, 0.005, 800
FIXED = 11  # the fixed disk


@pytest.fixture(scope="module")
def run():
    return jaxdda.simulate(jaxdda.examples.get("paper-7.10"), STEPS, chunk=400)


def test_first_touch_at_the_free_fall_time(run):
    loaded = np.abs(run.force_between(FIXED, 5)).sum(1) > 0
    first = int(np.argmax(loaded)) + 1  # step k ends at index k
    assert loaded.any()
    assert first == math.ceil(math.sqrt(2 * H / G) / DT) == 155
    # until then the chain falls freely, as one body
    before = run.centroid[: first, :11, 1] - run.centroid[0, :11, 1]
    np.testing.assert_allclose(before, np.broadcast_to(-0.5 * G * run.time[:first, None] ** 2, before.shape),
                               atol=1e-9)


def test_no_interpenetration_and_springs_intact(run):
    scene = run.scene
    size = 2.0
    assert run.info.max_penetration.max() <= 1e-6 * size
    assert run.info.converged.all()
    k = float(scene.params.connector_axial[0])
    stretch = run.connector_force[:, :, 0] / k
    # energy bound: no spring stores more than the chain's kinetic energy at impact
    chain_mass = float(np.sum(np.asarray(scene.params.density[:11] * scene.model.area[:11])))
    fall_speed = G * math.sqrt(2 * H / G)
    assert np.abs(stretch).max() <= fall_speed * math.sqrt(chain_mass / k)


def test_chain_comes_to_rest_draped_over_the_disk(run):
    speed = np.linalg.norm(run.velocity[-1, 2:9, :2], axis=1)  # the seven disks lying on it
    fall_speed = G * math.sqrt(2 * H / G)
    assert speed.max() < 1e-3 * fall_speed
    y = run.centroid[-1, :11, 1]
    assert np.all(np.diff(y[:6]) > 0) and np.all(np.diff(y[5:]) < 0)  # hangs down both sides
    np.testing.assert_allclose(y[:5], y[10:5:-1], atol=1e-6)  # symmetric: body k mirrors body 10 - k
