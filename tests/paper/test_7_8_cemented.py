"""Case 7.8: a block pulled off a cemented interface; tensions shared by the adjoint joints."""
import numpy as np
import pytest

import jaxdda

H, F, STRENGTH, MASS, DT = 1.0, 1000.0, 2000.0, 4000.0, 0.01
PAPER_ERROR = 1e-5  # N (Table 6)


@pytest.mark.parametrize("h", [0.0, 0.5, 1.0])
def test_joint_tensions(h):
    scene = jaxdda.examples.get("paper-7.8", height=h)
    np.testing.assert_allclose(np.sort(np.asarray(scene.model.joint_point)[:, 1]), [-H, H], atol=1e-12, rtol=0)
    run = jaxdda.simulate(scene, 50)
    top = np.argmax(np.asarray(scene.model.joint_point)[:, 1])
    p1, p2 = run.joint_tension[-1, top], run.joint_tension[-1, 1 - top]
    assert abs(p1 - F * (H + h) / (2 * H)) <= PAPER_ERROR
    assert abs(p2 - F * (H - h) / (2 * H)) <= PAPER_ERROR
    assert not run.joint_broken.any()
    assert np.abs(run.centroid - run.centroid[0]).max() < 1e-9
    assert np.abs(run.rotation).max() < 1e-9


def test_overload_breaks_the_interface_at_once():
    run = jaxdda.simulate(jaxdda.examples.get("paper-7.8", force=2500.0), 30)
    assert run.joint_broken.all()  # broken at the end of step 1, for good
    np.testing.assert_allclose(run.joint_tension[0].sum(), STRENGTH, atol=PAPER_ERROR, rtol=0)
    assert (run.joint_tension[1:] == 0).all()
    accel = np.diff(run.velocity[:, 0, 0]) / DT
    np.testing.assert_allclose(accel[0], (2500.0 - STRENGTH) / MASS, atol=1e-9, rtol=0)
    np.testing.assert_allclose(accel[1:], 2500.0 / MASS, atol=1e-9, rtol=0)


def test_ramped_pull_breaks_when_it_exceeds_the_strength():
    rate = 900.0  # N/s; the load of step k is F(k dt): the first to exceed t is k = 223
    run = jaxdda.simulate(jaxdda.examples.get("paper-7.8", force=0.0, rate=rate), 260)
    first = int(np.ceil(STRENGTH / (rate * DT) + 1e-9))
    broken_at = np.argmax(run.joint_broken.all(1)) + 1
    assert broken_at == first
    assert not run.joint_broken[: first - 1].any()
    np.testing.assert_allclose(run.joint_tension[first - 2].sum(), rate * DT * (first - 1), atol=PAPER_ERROR, rtol=0)


def test_broken_joint_still_carries_compression():
    # F(t) = 2500 - 10000 t: the interface breaks at once, B2 flies off, comes back at
    # t = 0.75 s (x(t) = (1250 t^2 - 5000 t^3 / 3) / m) and is then pressed against B1.
    run = jaxdda.simulate(jaxdda.examples.get("paper-7.8", force=2500.0, rate=-10000.0), 100)
    assert run.joint_broken[-1].all()
    c = run.info.contacts
    k = -1
    sel = c.valid[k] & (c.a[k] == 0) & (c.b[k] == 1)
    push = -(2500.0 - 10000.0 * run.time[-1])  # 7500 N towards B1
    np.testing.assert_allclose(c.force[k][sel][:, 0].sum(), push, rtol=1e-9)
    assert (run.joint_tension[-1] == 0).all()
    assert abs(run.centroid[-1, 0, 0] - run.centroid[0, 0, 0]) < 1e-9
