"""Connectors alone against closed forms: a mass on a spring or bolt (static extension,
period), a pendulum on a stiff bolt, a cantilevered beam (tip deflection and rotation,
with and without shear deformation), and the errors of bad connectors."""
import math

import numpy as np
import pytest

import jaxdda
from jaxdda.connectors import attachment_points

G = 9.81
CEILING = [(-0.5, 1.0), (0.5, 1.0), (0.5, 2.0), (-0.5, 2.0)]  # a fixed block; its bottom edge holds the connector


def hanging(kind: str, k: float, *, dynamic: float, dt: float, x0: float = 0.0, density: float = 1000.0):
    """A disk of radius 0.1 at (x0, 0) hung from the ceiling's point (0, 1) by a spring or
    a bolt of axial stiffness k, at rest at the connector's rest length."""
    sb = jaxdda.SceneBuilder(dt=dt, gravity=(0.0, -G), dynamic=dynamic)
    top = sb.add_polygon(CEILING, density=1.0, fixed=True)
    disk = sb.add_disk(center=(x0, 0.0), radius=0.1, density=density)
    length = math.hypot(x0, 1.0)
    if kind == "spring":
        sb.add_spring(top, disk, (0.0, 1.0), (x0, 0.0), stiffness=k)
    else:
        area = 1e-4
        sb.add_bolt(top, disk, (0.0, 1.0), (x0, 0.0), young=k * length / area, area=area)
    return sb.build()


def newmark_period(omega: float, dt: float) -> float:
    """The period of DDA's time stepping (K_eff = K + 2M/dt^2, v+ = 2d/dt - v) on x'' = -omega^2 x:
    x1 (1 + h^2 / 2) = x0 + v0 dt, v1 = v0 - omega^2 x1 dt, with h = omega dt."""
    h2 = (omega * dt) ** 2
    s = 1.0 / (1.0 + h2 / 2.0)
    step = np.array([[s, s * dt], [-omega ** 2 * dt * s, 1.0 - omega ** 2 * dt ** 2 * s]])
    lam = np.linalg.eigvals(step)
    return 2.0 * math.pi * dt / abs(np.angle(lam[0]))


def up_crossings(t, x):
    """Times at which x crosses 0 upwards (linear interpolation)."""
    i = np.flatnonzero((x[:-1] < 0) & (x[1:] >= 0))
    return t[i] - x[i] * (t[i + 1] - t[i]) / (x[i + 1] - x[i])


@pytest.mark.parametrize("kind", ["spring", "bolt"])
def test_mass_on_a_connector_settles_at_the_static_extension(kind):
    k = 4000.0
    scene = hanging(kind, k, dynamic=0.0, dt=1.0)  # static: each step removes all but 2M/dt^2 / (k + 2M/dt^2) ~ 2 %
    run = jaxdda.simulate(scene, 40)
    m = float(scene.params.density[1] * scene.model.area[1])
    np.testing.assert_allclose(run.centroid[-1, 1, 1], -m * G / k, rtol=1e-9)  # extension m g / k
    np.testing.assert_allclose(run.connector_force[-1, 0, 0], m * G, rtol=1e-9)  # axial force = weight
    np.testing.assert_allclose(run.connector_force[-1, 0, 1:], 0.0, atol=1e-9 * m * G)  # no shear or moment


@pytest.mark.parametrize("kind", ["spring", "bolt"])
def test_mass_on_a_connector_oscillates_with_its_period(kind):
    m = 1000.0 * math.pi * 0.01
    k = m * (2.0 * math.pi) ** 2  # period 1 s
    dt = 1e-3
    scene = hanging(kind, k, dynamic=1.0, dt=dt)
    run = jaxdda.simulate(scene, 3300)
    y = run.centroid[:, 1, 1] + m * G / k  # about the static equilibrium
    crossings = up_crossings(run.time, y)
    assert len(crossings) == 3
    period = np.diff(crossings)
    omega = math.sqrt(k / m)
    # the scheme's own period, and its O((omega dt)^2) departure from 2 pi sqrt(m / k)
    np.testing.assert_allclose(period, newmark_period(omega, dt), rtol=1e-6)
    assert abs(newmark_period(omega, dt) - 2 * math.pi / omega) <= (omega * dt) ** 2 * 2 * math.pi / omega
    assert np.all(np.abs(run.centroid[:, 1, 0]) < 1e-12)  # it stays on the vertical


def test_pendulum_on_a_stiff_bolt_has_the_pendulum_period():
    # Geometric stiffness of a loaded connector: a disk on a 1 m bolt, released at
    # 0.05 rad, swings with 2 pi sqrt(L / g) (1 + theta0^2 / 16).
    theta0, length, dt = 0.05, 1.0, 1e-3
    x0 = length * math.sin(theta0)
    sb = jaxdda.SceneBuilder(dt=dt, gravity=(0.0, -G))
    top = sb.add_polygon(CEILING, density=1.0, fixed=True)
    disk = sb.add_disk(center=(x0, 1.0 - length * math.cos(theta0)), radius=0.02, density=1000.0)
    sb.add_bolt(top, disk, (0.0, 1.0), (x0, 1.0 - length * math.cos(theta0)), young=2e11, area=1e-4)
    run = jaxdda.simulate(sb.build(), 4300)
    x = run.centroid[:, 1, 0]
    crossings = up_crossings(run.time, x)
    omega = math.sqrt(G / length)
    # the scheme's small-swing period (within (omega dt)^2 of 2 pi / omega, test above),
    # times the finite-swing factor; the scheme's damping (|lambda|^2 = 1 / (1 + h^2 / 2)
    # per step) shrinks the swing by < 2 % over the run: < 5e-6 change of that factor.
    expected = newmark_period(omega, dt) * (1 + theta0 ** 2 / 16)
    period = np.diff(crossings)
    assert len(period) >= 1
    np.testing.assert_allclose(period, expected, rtol=5e-6)
    stretch = np.hypot(x, 1.0 - run.centroid[:, 1, 1]) - length
    assert np.all(np.abs(stretch) < 1e-5)  # the bolt keeps its length (m g / k ~ 1e-8 m)


def cantilever(shear_modulus):
    """A beam of length 1 m from a fixed block to a free block, a load P down at its tip."""
    length, young, area, inertia, load = 1.0, 2e11, 1e-3, 1e-6, 6.0
    sb = jaxdda.SceneBuilder(dt=1.0, gravity=(0.0, 0.0), dynamic=0.0)
    wall = sb.add_polygon([(-1.0, -0.5), (0.0, -0.5), (0.0, 0.5), (-1.0, 0.5)], density=1.0, fixed=True)
    tip = sb.add_polygon([(length, -0.05), (length + 0.1, -0.05), (length + 0.1, 0.05), (length, 0.05)],
                         density=2700.0)
    sb.add_beam(wall, tip, (0.0, 0.0), (length, 0.0), young=young, area=area, inertia=inertia,
                shear_modulus=shear_modulus, section="rectangular")
    sb.add_load(tip, (0.0, -load), at=(length, 0.0))
    return sb.build(), (length, young, area, inertia, load)


@pytest.mark.parametrize("shear_modulus", [None, 2e11 / 2.6])
def test_cantilevered_beam_deflects_as_a_timoshenko_beam(shear_modulus):
    scene, (length, young, area, inertia, load) = cantilever(shear_modulus)
    run = jaxdda.simulate(scene, 30)
    ei = young * inertia
    b = 0.0 if shear_modulus is None else 12 * 1.2 * young / shear_modulus * inertia / area / length ** 2
    deflection = load * length ** 3 / (3 * ei) * (1 + b / 4)  # = P L^3 / 3EI + k P L / (G A)
    tip = np.asarray(attachment_points(scene.model, run.final_state))[0, 1]
    # geometric nonlinearity is O((deflection / L)^2) ~ 1e-10 here
    np.testing.assert_allclose(tip[1], -deflection, rtol=1e-7)
    np.testing.assert_allclose(run.rotation[-1, 1], -load * length ** 2 / (2 * ei), rtol=1e-7)
    axial, shear, m_a, m_b = run.connector_force[-1, 0]
    np.testing.assert_allclose(abs(shear), load, rtol=1e-7)
    np.testing.assert_allclose(abs(m_a), load * length, rtol=1e-7)  # the clamped end carries P L
    assert abs(m_b) < 1e-7 * load * length
    assert abs(axial) < 2 * load * deflection / length  # the load's share along the turned chord


@pytest.mark.smoke
@pytest.mark.parametrize("call, message", [
    (lambda sb: sb.add_spring(0, 1, (0.0, 1.0), (0.5, 0.0), stiffness=10.0), "at_b"),
    (lambda sb: sb.add_spring(0, 1, (0.0, 3.0), (0.0, 0.0), stiffness=10.0), "at_a"),
    (lambda sb: sb.add_spring(0, 1, (0.0, 1.0), (0.0, 0.0), stiffness=0.0), "stiffness"),
    (lambda sb: sb.add_spring(0, 1, (0.0, 1.0), (0.0, 0.0), stiffness=-1.0), "stiffness"),
    (lambda sb: sb.add_spring(0, 0, (0.0, 1.0), (0.0, 1.5), stiffness=10.0), "same body"),
    (lambda sb: sb.add_spring(0, 5, (0.0, 1.0), (0.0, 0.0), stiffness=10.0), "body_b"),
    (lambda sb: sb.add_bolt(0, 1, (0.0, 1.0), (0.0, 0.0), young=2e11, area=0.0), "area"),
    (lambda sb: sb.add_bolt(0, 1, (0.0, 1.0), (0.0, 1.0), young=2e11, area=1e-4), "zero length"),
    (lambda sb: sb.add_spring(0, 1, (0.0, 1.0), (0.0, 1.0), stiffness=10.0), "zero length"),
    (lambda sb: sb.add_beam(0, 1, (0.0, 1.0), (0.0, 0.0), young=2e11, area=1e-4, inertia=-1.0), "inertia"),
    (lambda sb: sb.add_beam(0, 1, (0.0, 1.0), (0.0, 0.0), young=2e11, area=1e-4, inertia=1e-8, section="oval"),
     "section"),
    (lambda sb: sb.add_spring(0, 1, (0.0, 1.0), (0.0, 0.0), stiffness=10.0, rest_length=-1.0), "rest_length"),
    (lambda sb: sb.add_spring(0, 1, (0.0, 1.0), (float("nan"), 0.0), stiffness=10.0), "at_b"),
])
def test_bad_connectors_are_named(call, message):
    sb = jaxdda.SceneBuilder(dt=0.01)
    sb.add_polygon(CEILING, density=1.0, fixed=True)
    sb.add_disk(center=(0.0, 0.0), radius=0.1, density=1000.0)
    with pytest.raises(jaxdda.SceneError, match=message) as err:
        call(sb)
    assert "connector 0" in str(err.value)


@pytest.mark.parametrize("bolts", [True, False])
def test_bolted_slope_stands_with_its_bolts_and_slides_without(bolts):
    angle, friction, steps = 35.0, 0.5, 150
    scene = jaxdda.examples.get("bolted-slope", bolts=bolts, angle=angle, friction=friction)
    run = jaxdda.simulate(scene, steps)
    a = math.radians(angle)
    down = np.array([math.cos(a), -math.sin(a)])
    slid = (run.centroid[:, :3] - run.centroid[0, :3]) @ down  # (S+1, 3) along the slope
    if bolts:
        assert np.abs(slid).max() < 1e-3  # held within a millimetre
        assert np.abs(run.velocity[-1, :3, :2]).max() < 1e-3
        assert np.all(run.connector_force[-1, :, 0] > 0)  # the bolts are in tension
    else:
        g = -float(scene.params.gravity[1])
        expected = 0.5 * g * (math.sin(a) - friction * math.cos(a)) * run.time ** 2
        np.testing.assert_allclose(slid, np.broadcast_to(expected[:, None], slid.shape), atol=1e-9)
