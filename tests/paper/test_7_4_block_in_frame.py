"""Case 7.4: a square block bouncing in a frame: billiard path, no rotation, speed kept.

Besides the paper's start velocity (2.5, 5.0), vy = 1, 2, 3 (issue 40's contract): the
block's faces meet the y walls, 50 from its start, at t = 50 / vy (+ 100 / vy k): on a
step boundary for vy = 1, 2 and two thirds of the way into a step for vy = 3 (t = 16.67);
a face lands flat, both corners at one instant. The four runs share one compiled scene."""
import dataclasses

import numpy as np
import pytest

import jaxdda
from tests.paper.billiard import billiard, wall_hits

STARTS = [(2.5, 5.0), (2.5, 1.0), (2.5, 2.0), (2.5, 3.0)]
HALF = 60.0 - 10.0


@pytest.fixture(scope="module")
def runs():
    scene = jaxdda.examples.get("paper-7.4")
    out = {}
    for v0 in STARTS:
        velocity = np.asarray(scene.state.velocity).copy()
        velocity[0, :2] = v0
        out[v0] = jaxdda.simulate(dataclasses.replace(scene, state=dataclasses.replace(scene.state, velocity=velocity)),
                                  10_000)
    return out


@pytest.mark.parametrize("v0", STARTS)
def test_follows_billiard_path_without_rotation(runs, v0):
    run = runs[v0]
    exact = np.stack([billiard(0.0, v0[0], run.time, HALF), billiard(0.0, v0[1], run.time, HALF)], -1)
    assert np.linalg.norm(run.centroid[:, 0] - exact, axis=1).max() < 1e-6
    assert np.abs(run.rotation[:, 0]).max() < 1e-9
    for axis in (0, 1):  # every wall hit of the analytic path (y: t = 10, 30, .., 90 for vy = 5), one reversal each
        hits = wall_hits(v0[axis], run.time[-1], HALF)
        assert hits >= 1
        assert (np.diff(np.sign(run.velocity[:, 0, axis])) != 0).sum() == hits


@pytest.mark.parametrize("v0", STARTS)
def test_speed_and_momentum_magnitude_kept(runs, v0):
    run = runs[v0]
    speed = np.linalg.norm(run.velocity[:, 0, :2], axis=1)
    np.testing.assert_allclose(speed, np.linalg.norm(v0), rtol=1e-9)
    assert np.abs(run.velocity[:, 0, 2]).max() < 1e-9
