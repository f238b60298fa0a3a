"""Case 7.4: a square block bouncing in a frame: billiard path, no rotation, speed kept."""
import numpy as np
import pytest

import jaxdda
from tests.paper.billiard import billiard

V0 = np.array([2.5, 5.0])


@pytest.fixture(scope="module")
def run():
    return jaxdda.simulate(jaxdda.examples.get("paper-7.4"), 10_000)


def test_follows_billiard_path_without_rotation(run):
    half = 60.0 - 10.0
    exact = np.stack([billiard(0.0, V0[0], run.time, half), billiard(0.0, V0[1], run.time, half)], -1)
    assert np.linalg.norm(run.centroid[:, 0] - exact, axis=1).max() < 1e-6
    assert np.abs(run.rotation[:, 0]).max() < 1e-9
    assert (np.diff(np.sign(run.velocity[:, 0, 1])) != 0).sum() == 5  # walls y = +-60 hit at t = 10, 30, .., 90
    assert (np.diff(np.sign(run.velocity[:, 0, 0])) != 0).sum() == 3  # walls x = +-60 hit at t = 20, 60, 100


def test_speed_and_momentum_magnitude_kept(run):
    speed = np.linalg.norm(run.velocity[:, 0, :2], axis=1)
    np.testing.assert_allclose(speed, np.linalg.norm(V0), rtol=1e-9)
    assert np.abs(run.velocity[:, 0, 2]).max() < 1e-9
