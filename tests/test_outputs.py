"""Load histories, measured points and the run's files (CSV, npz), against closed forms."""
import numpy as np
import pytest

import jaxdda
from jaxdda.export import save_npz, write_csv

DT, STEPS, OMEGA = 0.01, 120, 1.5
HISTORY = [[0.0, 0.0, 0.0], [0.5, 4.0, -2.0], [0.5, 1.0, 0.0], [0.9, 1.0, 0.0]]  # ramp, step down, hold


@pytest.fixture(scope="module")
def run():
    """A weightless square spinning freely at OMEGA, pushed through its centroid by a load
    history; one corner is a measured point."""
    sb = jaxdda.SceneBuilder(DT, (0.0, 0.0))
    square = sb.add_polygon([(0, 0), (2, 0), (2, 2), (0, 2)], density=0.25, angular_velocity=OMEGA)  # m = 1
    sb.add_measured_point(square, (2, 2))
    sb.add_load(square, history=HISTORY)
    return jaxdda.simulate(sb.build(), STEPS, progress=False)


def history(t):
    t = np.asarray(t, float)
    fx = np.where(t < 0.5, 8.0 * t, 1.0)
    return np.stack([fx, np.where(t < 0.5, -4.0 * t, 0.0)], -1)


def test_load_history_is_the_force_of_each_step(run):
    """Each step applies the history at its end time (DDA's end-of-step equilibrium), so
    the velocity is the sum of F(t_k) dt / m over the steps: the closed form of this
    discrete rule, which tends to the integral of F as dt -> 0."""
    t = run.time
    np.testing.assert_allclose(run.load_forces()[:, 0], history(t), rtol=0, atol=1e-12)
    impulse = np.concatenate([[[0.0, 0.0]], np.cumsum(history(t[1:]) * DT, 0)])
    np.testing.assert_allclose(run.velocity[:, 0, :2], impulse, rtol=0, atol=1e-11)
    exact = np.array([8.0 * 0.5 ** 2 / 2 + 1.0 * (STEPS * DT - 0.5), -4.0 * 0.5 ** 2 / 2])  # the integral
    assert np.abs(run.velocity[-1, 0, :2] - exact).max() < 4.0 * DT  # the rule's O(dt) error (the step at t = 0.5)


def test_measured_point_rides_the_body(run):
    """The corner of a body spinning at OMEGA about its centroid c(t)."""
    c, t = run.centroid[:, 0], run.time
    angle = OMEGA * t
    arm = np.stack([np.cos(angle) - np.sin(angle), np.sin(angle) + np.cos(angle)], -1)  # R(angle) (1, 1)
    np.testing.assert_allclose(run.measured_points()[:, 0], c + arm, rtol=0, atol=1e-12)
    np.testing.assert_allclose(run.load_points()[:, 0], c, rtol=0, atol=1e-12)  # at the centroid


def test_csv_and_npz_hold_the_histories(run, tmp_path):
    measured, loads = write_csv(run, tmp_path, name="spin")
    assert measured.name == "spin_measured.csv" and loads.name == "spin_loads.csv"
    table = np.genfromtxt(measured, delimiter=",", names=True)
    assert table.dtype.names == ("step", "time", "p0_x", "p0_y", "p0_dx", "p0_dy")
    np.testing.assert_array_equal(table["step"], np.arange(STEPS + 1))
    np.testing.assert_array_equal(table["p0_x"], run.measured_points()[:, 0, 0])  # written to the last bit
    np.testing.assert_array_equal(table["p0_dy"], run.measured_points()[:, 0, 1] - 2.0)
    table = np.genfromtxt(loads, delimiter=",", names=True)
    np.testing.assert_array_equal(table["load0_fx"], run.load_forces()[:, 0, 0])
    data = np.load(save_npz(run, tmp_path / "run.npz"))
    np.testing.assert_array_equal(data["measured_points"], run.measured_points())
    np.testing.assert_array_equal(data["load_forces"], run.load_forces())
