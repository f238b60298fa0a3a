"""Case 7.6: a block pulled over a base; cohesion shared by the two adjoint corner contacts."""
import numpy as np
import pytest

import jaxdda

MASS, G_ACC, F, D = 1000.0, 10.0, 1000.0, 0.7
WEIGHT = MASS * G_ACC
PAPER_ERROR = 1e-5  # N (Table 3)


def corner_forces(run, k=-1):
    """(rear, front) forces on the block (body 0) from the base at step k."""
    c = run.info.contacts
    sel = c.valid[k] & (c.a[k] == 0) & (c.b[k] == 1)
    pts, f = c.point[k][sel], c.force[k][sel]
    assert len(pts) == 2
    return f[np.argsort(pts[:, 0])]


def statics(shear):
    """Normal forces (rear, front) that keep a unit block sliding without rotation: the
    moments about the centroid of the pull (d - 1/2 above it) and of the shear (1/2 below)."""
    diff = 2.0 * (F * (D - 0.5) - shear * 0.5)  # N_front - N_rear (shear < 0 opposes the pull)
    return 0.5 * (WEIGHT - diff), 0.5 * (WEIGHT + diff)


@pytest.fixture(scope="module", params=[False, True], ids=["fixed-base", "heavy-base"])
def run(request):
    return jaxdda.simulate(jaxdda.examples.get("paper-7.6", heavy=request.param), 100)


def test_adjoint_contacts_share_the_cohesion(run):
    rear, front = corner_forces(run)
    assert abs(rear[1] - 4600.0) <= PAPER_ERROR
    assert abs(front[1] - 5400.0) <= PAPER_ERROR
    assert abs(rear[0] + front[0] + 400.0) <= PAPER_ERROR  # c = 400 in all, not 400 per corner


def test_slides_at_constant_acceleration_without_rotation(run):
    x = run.centroid[:, 0, 0] - run.centroid[0, 0, 0]
    np.testing.assert_allclose(x, 0.3 * run.time ** 2, atol=1e-9, rtol=0)  # a = (F - c) / m = 0.6
    assert np.abs(run.rotation[:, 0]).max() < 1e-9
    assert np.abs(run.centroid[:, 0, 1] - run.centroid[0, 0, 1]).max() < 1e-9
    assert run.info.converged.all()


def test_friction_and_cohesion_together():
    # mu = 0.05: the interface resists c + mu W = 900 N < F, so the block slides at 0.1 m/s^2.
    run = jaxdda.simulate(jaxdda.examples.get("paper-7.6", friction=0.05), 50)
    rear, front = corner_forces(run)
    shear = -(400.0 + 0.05 * WEIGHT)
    n_rear, n_front = statics(shear)
    assert abs(rear[0] + front[0] - shear) <= PAPER_ERROR
    assert abs(rear[1] - n_rear) <= PAPER_ERROR and abs(front[1] - n_front) <= PAPER_ERROR
    x = run.centroid[:, 0, 0] - run.centroid[0, 0, 0]
    np.testing.assert_allclose(x, 0.05 * run.time ** 2, atol=1e-9, rtol=0)


def test_cohesion_holds_a_smaller_pull():
    # F = 300 N < c: the block stays put and the interface carries exactly -F.
    run = jaxdda.simulate(jaxdda.examples.get("paper-7.6", force=300.0), 50)
    rear, front = corner_forces(run)
    assert abs(rear[0] + front[0] + 300.0) <= PAPER_ERROR
    assert np.abs(run.centroid - run.centroid[0]).max() < 1e-9
