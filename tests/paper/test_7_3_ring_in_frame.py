"""Case 7.3: a ring bouncing in a square frame keeps the billiard path and its speed."""
import numpy as np
import pytest

import jaxdda
from tests.paper.billiard import billiard

V0 = np.array([2.5, 5.0])


@pytest.fixture(scope="module")
def run():
    return jaxdda.simulate(jaxdda.examples.get("paper-7.3"), 2050)


def test_follows_billiard_path(run):
    half = 20.0 - 3.0  # the centre touches a wall when it is 3 from it
    exact = np.stack([billiard(0.0, V0[0], run.time, half), billiard(0.0, V0[1], run.time, half)], -1)
    assert np.linalg.norm(run.centroid[:, 0] - exact, axis=1).max() < 1e-6
    # it really bounced: both walls were hit several times
    assert (np.diff(np.sign(run.velocity[:, 0, 0])) != 0).sum() >= 3
    assert (np.diff(np.sign(run.velocity[:, 0, 1])) != 0).sum() >= 6


def test_speed_kept_through_every_impact(run):
    speed = np.linalg.norm(run.velocity[:, 0, :2], axis=1)
    np.testing.assert_allclose(speed, np.linalg.norm(V0), rtol=1e-9)
    assert np.abs(run.velocity[:, 0, 2]).max() == 0.0  # frictionless: no spin
