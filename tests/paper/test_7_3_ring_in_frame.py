"""Case 7.3: a ring bouncing in a square frame keeps the billiard path and its speed.

Besides the paper's start velocity (2.5, 5.0), vy = 1, 2, 3 (issue 40's contract): the
ring reaches a wall 17 from the centre at t = 17 / vy, on a step boundary for vy = 1, 2
(340 dt, 170 dt) and a third of the way into a step for vy = 3 (113.33 dt); the x walls at
t = 6.8 + 13.6 k, 0.8 of the way into step 135. The four runs share one compiled scene."""
import dataclasses

import numpy as np
import pytest

import jaxdda
from tests.paper.billiard import billiard, wall_hits

STARTS = [(2.5, 5.0), (2.5, 1.0), (2.5, 2.0), (2.5, 3.0)]
HALF = 20.0 - 3.0  # the centre touches a wall when it is 3 from it


@pytest.fixture(scope="module")
def runs():
    scene = jaxdda.examples.get("paper-7.3")
    out = {}
    for v0 in STARTS:
        velocity = np.asarray(scene.state.velocity).copy()
        velocity[0, :2] = v0
        out[v0] = jaxdda.simulate(dataclasses.replace(scene, state=dataclasses.replace(scene.state, velocity=velocity)),
                                  2050)
    return out


@pytest.mark.parametrize("v0", STARTS)
def test_follows_billiard_path(runs, v0):
    run = runs[v0]
    exact = np.stack([billiard(0.0, v0[0], run.time, HALF), billiard(0.0, v0[1], run.time, HALF)], -1)
    assert np.linalg.norm(run.centroid[:, 0] - exact, axis=1).max() < 1e-6
    # it really bounced: every wall hit of the analytic path, one velocity reversal each
    for axis in (0, 1):
        hits = wall_hits(v0[axis], run.time[-1], HALF)
        assert hits >= 3
        assert (np.diff(np.sign(run.velocity[:, 0, axis])) != 0).sum() == hits


@pytest.mark.parametrize("v0", STARTS)
def test_speed_kept_through_every_impact(runs, v0):
    run = runs[v0]
    speed = np.linalg.norm(run.velocity[:, 0, :2], axis=1)
    np.testing.assert_allclose(speed, np.linalg.norm(v0), rtol=1e-9)
    assert np.abs(run.velocity[:, 0, 2]).max() == 0.0  # frictionless: no spin
