"""Case 7.7: a disk pulled over a frictional surface: pure rolling, rolling resistance, slip."""
import math

import numpy as np
import pytest

import jaxdda

R, MASS, F = 1.0, 1000.0 * math.pi, 1000.0
WEIGHT = 10.0 * MASS
INERTIA = 0.5 * MASS * R * R
PAPER_NORMAL_ERROR, PAPER_SHEAR_ERROR = 0.00361, 1e-5  # N (Table 4)
PAPER_MOMENT_ERROR = 2000.0 - 1999.99914  # N m (Table 5)
HEIGHTS = (0.0, 0.5, 1.0, 1.5, 2.0)


def disk_contact(run, k):
    c = run.info.contacts
    sel = c.valid[k] & (c.a[k] == 0)
    assert sel.sum() == 1
    return c.force[k][sel][0], c.moment[k][sel][0]


@pytest.mark.parametrize("d", HEIGHTS)
def test_pure_rolling_forces(d):
    run = jaxdda.simulate(jaxdda.examples.get("paper-7.7", height=d), 20)
    for k in range(run.steps):
        force, moment = disk_contact(run, k)
        # The pull acts at a material point of the disk, d above the contact point at
        # t = 0; its lever arm about the centre turns with the disk (the load of step k is
        # placed in the configuration at its start).
        lever = 1.0 + (d - 1.0) * math.cos(run.rotation[k, 0])
        assert abs(force[1] - WEIGHT) <= PAPER_NORMAL_ERROR
        assert abs(force[0] - F * (lever - 1.5) / 1.5) <= PAPER_SHEAR_ERROR
        assert moment == 0.0
    # No slip: the contact point does not move, so x = -R theta.
    np.testing.assert_allclose(run.centroid[:, 0, 0], -R * run.rotation[:, 0], atol=1e-12, rtol=0)
    if d == 1.0:
        np.testing.assert_allclose(run.centroid[:, 0, 0], 0.5 * F * d / (1.5 * MASS) * run.time ** 2, atol=1e-12, rtol=0)


@pytest.mark.parametrize("d", HEIGHTS)
def test_rolling_resistance_holds_the_disk(d):
    run = jaxdda.simulate(jaxdda.examples.get("paper-7.7", height=d, rolling=1.0), 20)
    force, moment = disk_contact(run, -1)
    assert abs(moment - F * d) <= PAPER_MOMENT_ERROR  # M_r = F d, within its capacity delta G
    assert abs(force[0] + F) <= PAPER_SHEAR_ERROR and abs(force[1] - WEIGHT) <= PAPER_NORMAL_ERROR
    assert np.abs(run.centroid - run.centroid[0]).max() < 1e-9  # centre O and point A stay put
    assert np.abs(run.rotation).max() < 1e-9


# d = 1 for 500 steps (t = 5 s): (mu, delta) -> (acceleration, angular acceleration)
MOTION = {
    "I-rolling": (10.0, 0.0, F / (1.5 * MASS), -F / (1.5 * MASS) / R),
    "II-resisted": (0.005, 0.005, (F - 0.005 * WEIGHT) / MASS, 0.0),
    "II-half": (0.005, 0.0025, (F - 0.005 * WEIGHT) / MASS, -(0.005 - 0.0025) * WEIGHT / INERTIA),
    "III-sliding": (0.005, 0.0, (F - 0.005 * WEIGHT) / MASS, -0.005 * WEIGHT * R / INERTIA),
}


@pytest.mark.parametrize("case", MOTION)
def test_motion_cases(case):
    mu, delta, accel, alpha = MOTION[case]
    run = jaxdda.simulate(jaxdda.examples.get("paper-7.7", height=1.0, friction=mu, rolling=delta), 500)
    t = run.time
    np.testing.assert_allclose(run.centroid[:, 0, 0], 0.5 * accel * t ** 2, atol=1e-9, rtol=0)
    np.testing.assert_allclose(run.velocity[:, 0, 2], alpha * t, atol=1e-9, rtol=0)
    assert np.abs(run.centroid[:, 0, 1] - R).max() < 1e-9
    assert run.info.converged.all()


def test_paper_figures_of_the_motion_cases():
    # validation-cases.md: x(5) = 2.652582 m rolling, 3.353874 m sliding; alpha = 0.1 rad/s^2.
    assert abs(0.5 * MOTION["I-rolling"][2] * 25 - 2.652582) < 1e-6
    assert abs(0.5 * MOTION["III-sliding"][2] * 25 - 3.353874) < 1e-6
    assert abs(MOTION["III-sliding"][3] + 0.1) < 1e-12
