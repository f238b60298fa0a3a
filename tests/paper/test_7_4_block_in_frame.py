"""Case 7.4: a square block bouncing in a frame: billiard path, no rotation, speed kept.

Besides the paper's start velocity (2.5, 5.0), vy = 1, 2, 3 (issue 40's contract): the
block's faces meet the y walls, 50 from its start, at t = 50 / vy (+ 100 / vy k): on a
step boundary for vy = 1, 2 and two thirds of the way into a step for vy = 3 (t = 16.67);
a face lands flat, both corners at one instant. The four runs share one compiled scene."""
import numpy as np
import pytest

from tests.paper.billiard import assert_billiard, runs_from_starts

STARTS = [(2.5, 5.0), (2.5, 1.0), (2.5, 2.0), (2.5, 3.0)]
HALF = 60.0 - 10.0


@pytest.fixture(scope="module")
def runs():
    return runs_from_starts("paper-7.4", STARTS, 10_000)


@pytest.mark.parametrize("v0", STARTS)
def test_follows_billiard_path_without_rotation(runs, v0):
    run = runs[v0]
    assert_billiard(run, v0, HALF, least_hits=1)
    assert np.abs(run.rotation[:, 0]).max() < 1e-9


@pytest.mark.parametrize("v0", STARTS)
def test_speed_and_momentum_magnitude_kept(runs, v0):
    run = runs[v0]
    speed = np.linalg.norm(run.velocity[:, 0, :2], axis=1)
    np.testing.assert_allclose(speed, np.linalg.norm(v0), rtol=1e-9)
    assert np.abs(run.velocity[:, 0, 2]).max() < 1e-9
