"""Case 7.3: a ring bouncing in a square frame keeps the billiard path and its speed.

Besides the paper's start velocity (2.5, 5.0), vy = 1, 2, 3 (issue 40's contract): the
ring reaches a wall 17 from the centre at t = 17 / vy, on a step boundary for vy = 1, 2
(340 dt, 170 dt) and a third of the way into a step for vy = 3 (113.33 dt); the x walls at
t = 6.8 + 13.6 k, 0.8 of the way into step 135. The four runs share one compiled scene."""
import numpy as np
import pytest

from tests.paper.billiard import assert_billiard, runs_from_starts

STARTS = [(2.5, 5.0), (2.5, 1.0), (2.5, 2.0), (2.5, 3.0)]
HALF = 20.0 - 3.0  # the centre touches a wall when it is 3 from it


@pytest.fixture(scope="module")
def runs():
    return runs_from_starts("paper-7.3", STARTS, 2050)


@pytest.mark.parametrize("v0", STARTS)
def test_follows_billiard_path(runs, v0):
    run = runs[v0]
    assert_billiard(run, v0, HALF, least_hits=3)


@pytest.mark.parametrize("v0", STARTS)
def test_speed_kept_through_every_impact(runs, v0):
    run = runs[v0]
    speed = np.linalg.norm(run.velocity[:, 0, :2], axis=1)
    np.testing.assert_allclose(speed, np.linalg.norm(v0), rtol=1e-9)
    assert np.abs(run.velocity[:, 0, 2]).max() == 0.0  # frictionless: no spin
