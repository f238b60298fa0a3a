"""energy(): each term against closed forms. Free fall and an elastic bounce keep the total
to round-off (DDA's step is exact for constant acceleration, impacts are resolved at the
instant they happen); a mass on a spring loses exactly k (dl)^2 / 2 per step (Newmark
gamma = 1, beta = 1/2), a first-order drift. Strain and connector energies are checked on
hand-made trajectories."""
import dataclasses

import numpy as np
import pytest

import jaxdda
from jaxdda import SceneBuilder, Trajectory
from jaxdda.energy import connector_energy, energy, kinetic_energy, potential_energy, strain_energy

G = 9.81
DT, STEPS = 0.01, 300
RHO, R = 2.0, 0.5
MASS, INERTIA = RHO * np.pi * R ** 2, RHO * np.pi * R ** 4 / 2
VX, OMEGA = 1.5, 3.0  # the falling disk's horizontal and angular velocity
DROP = 0.5  # the bouncing disk starts 0.5 m above the block


@pytest.fixture(scope="module")
def falls():
    """One scene, three independent disks: one bouncing on a fixed block (frictionless,
    e = 1: the default material), one in free fall with spin, one weightless (gravity=False)
    moving up; 3 s."""
    sb = SceneBuilder(dt=DT, gravity=(0.0, -G), name="falls")
    sb.add_polygon(vertices=[(-5, -1), (5, -1), (5, 0), (-5, 0)], density=1.0, fixed=True)
    sb.add_disk(center=(0, R + DROP), radius=R, density=RHO, velocity=(0.3, 0.0))
    sb.add_disk(center=(20, 0), radius=R, density=RHO, velocity=(VX, 0.0), angular_velocity=OMEGA)
    sb.add_disk(center=(30, 0), radius=R, density=RHO, velocity=(0.0, 1.0), gravity=False)
    return jaxdda.simulate(sb.build(), STEPS)


K_SPRING, T_SPRING = 10.0, 2.0  # N/m, s; the disk's mass is 1 kg: omega = sqrt(10) rad/s


def spring_run(dt):
    """A 1 kg disk on a spring to a fixed block, gravity off, pushed along the spring at 1 m/s."""
    sb = SceneBuilder(dt=dt, gravity=(0.0, 0.0), name="spring")
    block = sb.add_polygon(vertices=[(-1, -0.5), (0, -0.5), (0, 0.5), (-1, 0.5)], density=1.0, fixed=True)
    disk = sb.add_disk(center=(2, 0), radius=0.5, density=1.0 / (np.pi * 0.25), velocity=(1.0, 0.0))
    sb.add_spring(block, disk, (-0.5, 0.0), (2.0, 0.0), K_SPRING)
    return jaxdda.simulate(sb.build(), int(round(T_SPRING / dt)))


@pytest.fixture(scope="module")
def springs():
    """The spring run at dt and dt / 2 (dt is a parameter: one compilation). At dt / 4 (not
    run here) the loss is 0.02485 of E0, a ratio 1.975 to dt / 2: the order tends to 1."""
    return {dt: spring_run(dt) for dt in (0.01, 0.005)}


def test_free_fall_closed_form(falls):
    t = falls.time
    ke, pe = kinetic_energy(falls)[:, 2], potential_energy(falls)[:, 2]
    closed_ke = 0.5 * MASS * (VX ** 2 + (G * t) ** 2) + 0.5 * INERTIA * OMEGA ** 2
    scale = closed_ke[-1]  # 683 J
    # 300 steps, each rounding positions and velocities by a few ulps: 300 * 4 * eps = 3e-13
    # of the scale; measured 3.5e-11 J of 683 J (5e-14).
    assert np.abs(ke - closed_ke).max() <= 1e-12 * scale
    assert np.abs(pe - (-0.5 * MASS * G ** 2 * t ** 2)).max() <= 1e-12 * scale
    assert np.abs((ke + pe) - (ke + pe)[0]).max() <= 1e-12 * scale


def test_gravity_flag_and_fixed_bodies(falls):
    pe, ke = potential_energy(falls), kinetic_energy(falls)
    assert falls.centroid[-1, 3, 1] - falls.centroid[0, 3, 1] == pytest.approx(3.0, rel=1e-12)  # it rose 3 m
    assert np.all(pe[:, 3] == 0.0)  # but gravity=False: no potential energy
    np.testing.assert_allclose(ke[:, 3], 0.5 * MASS, rtol=1e-13)
    assert np.all(pe[:, 0] == 0.0) and np.all(ke[:, 0] == 0.0)  # the fixed block


def test_elastic_bounce_keeps_energy(falls):
    """Frictionless, e = 1: after about five bounces the disk's energy is that of the start.
    Measured: |E - E0| <= 2.4e-13 J. The bound: each bounce's impact solve stops at a
    relative residual tol = 1e-12 (the builder's default), which may leave a relative
    error of 2 tol in the kinetic energy at impact (m g h + E0 = 7.8 J), plus the free
    flight's round-off."""
    vy = falls.velocity[:, 1, 1]
    bounces = int(np.sum((vy[:-1] < 0) & (vy[1:] > 0)))
    assert bounces >= 4
    e = kinetic_energy(falls)[:, 1] + potential_energy(falls)[:, 1]
    at_impact = MASS * G * DROP + e[0]
    assert np.abs(e - e[0]).max() <= bounces * 2 * 1e-12 * at_impact + 1e-12 * at_impact
    # and the whole scene's energy() total is the sum of the three conserved ones
    total = energy(falls)["total"]
    assert np.abs(total - total[0]).max() <= 1e-12 * kinetic_energy(falls)[-1].sum()


def test_spring_loses_exactly_newmarks_dissipation(springs):
    """For a linear spring, Newmark gamma = 1, beta = 1/2 (m a_{n+1} = -k x_{n+1},
    dx = dt v_n + dt^2 a_{n+1} / 2, dv = dt a_{n+1}) gives, exactly,
    E_{n+1} - E_n = -k (x_{n+1} - x_n)^2 / 2. Measured: holds to 1.8e-15 J per step."""
    for dt, traj in springs.items():
        e = energy(traj)
        assert e["potential"].max() == 0.0 and e["strain"].max() == 0.0
        length = np.linalg.norm(traj.centroid[:, 1] - np.array([-0.5, 0.0]), axis=-1)
        np.testing.assert_allclose(e["connector"], 0.5 * K_SPRING * (length - 2.5) ** 2, rtol=0, atol=1e-15)
        assert e["total"][0] == pytest.approx(0.5)
        # rounding of positions (ulp of 2.5 m) times the spring force (<= 3.2 N) and of the
        # velocities: a few 1e-15 J per step
        np.testing.assert_allclose(np.diff(e["total"]), -0.5 * K_SPRING * np.diff(length) ** 2, rtol=0, atol=1e-14)


def test_spring_drift_is_first_order(springs):
    """Summed, the loss is about k dt int v^2 dt, i.e. E(t) = E0 exp(-omega^2 dt t / 2):
    0.0952 and 0.0488 of E0 at dt = 0.01 and 0.005 (T = 2 s). Measured: 0.0957 and 0.0491,
    a ratio 1.950 (closed form 1 + exp(-omega^2 dt T / 4) = 1.975): first order. The
    tolerances (3 %) cover the O(omega dt) = 3 % terms left out of the closed form."""
    omega2 = K_SPRING / 1.0
    loss = {}
    for dt, traj in springs.items():
        total = energy(traj)["total"]
        loss[dt] = (total[0] - total[-1]) / total[0]
        assert loss[dt] == pytest.approx(1.0 - np.exp(-omega2 * dt * T_SPRING / 2), rel=0.03)
    ratio = loss[0.01] / loss[0.005]
    assert ratio == pytest.approx(1.0 + np.exp(-omega2 * 0.01 * T_SPRING / 4), rel=0.03)
    assert np.log2(ratio) == pytest.approx(1.0, abs=0.05)


# ---------------------------------------------------------------- hand-made trajectories


E1, NU1 = 1e6, 0.25  # the deformable disk, plane stress
E2, NU2 = 2e6, 0.3  # the deformable square, plane strain
K, P = 100.0, 5.0  # the spring's stiffness and pretension
EB, AB, IB = 1e5, 0.01, 1e-4  # the beam's Young's modulus, area and second moment


@pytest.fixture(scope="module")
def handmade():
    sb = SceneBuilder(dt=0.01, name="handmade")
    sb.add_polygon(vertices=[(-1, -0.5), (0, -0.5), (0, 0.5), (-1, 0.5)], density=1.0, fixed=True)
    sb.add_disk(center=(2, 0), radius=R, density=RHO, young=E1, poisson=NU1)
    sb.add_polygon(vertices=[(4, -1), (6, -1), (6, 1), (4, 1)], density=1.0, young=E2, poisson=NU2, plane="strain")
    sb.add_disk(center=(8, 0), radius=R, density=RHO)
    sb.add_disk(center=(11, 0), radius=R, density=RHO)
    sb.add_spring(0, 3, (-0.5, 0.0), (8.0, 0.0), K, pretension=P)  # rest length 8.5 m
    sb.add_beam(3, 4, (8.0, 0.0), (11.0, 0.0), EB, AB, IB)  # 3 m, at the centroids
    return sb.build()


@pytest.mark.smoke
def test_strain_and_connector_energy(handmade):
    n, s, tau, delta, phi = handmade.n_bodies, 2e3, 1e3, 0.1, 0.05
    centroid = np.repeat(np.asarray(handmade.state.centroid)[None], 3, 0)
    rotation, velocity = np.zeros((3, n)), np.zeros((3, n, 3))
    stress, stretch = np.zeros((3, n, 3)), np.repeat(np.eye(2)[None, None], 3, 0).repeat(n, 1)
    stress[1, 1] = (s, 0, 0)  # uniaxial, on the disk grown by 10 %
    stretch[1, 1] = 1.1 * np.eye(2)
    velocity[1, 1] = (0, 0, 2.0)
    stress[1, 2] = (0, 0, tau)  # pure shear, on the square stretched 10 % along x
    stretch[1, 2] = np.diag([1.1, 1.0])
    stress[2, 2] = (s, s, 0)  # plane strain, biaxial
    centroid[2, 3, 0] += delta  # spring longer by delta, beam shorter by delta
    rotation[2, 4] = phi  # beam end b turned by phi against the chord
    traj = Trajectory(handmade, np.arange(3) * 0.01, centroid, rotation, velocity, stress, None,
                      handmade.state, stretch)
    area1, area2 = np.pi * R ** 2, 4.0
    u = strain_energy(traj)
    assert u[0].max() == 0.0 and u[:, [0, 3, 4]].max() == 0.0
    assert u[1, 1] == pytest.approx(1.21 * area1 * s ** 2 / (2 * E1), rel=1e-12)
    assert u[1, 2] == pytest.approx(1.1 * area2 * tau ** 2 * (1 + NU2) / E2, rel=1e-12)  # tau^2 / (2 G) V
    assert u[2, 2] == pytest.approx(area2 * s ** 2 * (1 + NU2) * (1 - 2 * NU2) / E2, rel=1e-12)
    c = connector_energy(traj)
    assert np.all(c[0] == 0.0)
    assert c[2, 0] == pytest.approx(0.5 * K * delta ** 2 + P * delta, rel=1e-12)
    assert c[2, 1] == pytest.approx(0.5 * EB * AB / 3.0 * delta ** 2 + 0.5 * (4 * EB * IB / 3.0) * phi ** 2, rel=1e-12)
    ke = kinetic_energy(traj)
    assert ke[1, 1] == pytest.approx(0.5 * 1.21 * INERTIA * 4.0, rel=1e-12)  # I of the grown disk
    e = energy(traj)
    np.testing.assert_allclose(e["elastic"], u.sum(1) + c.sum(1), rtol=1e-15)
    np.testing.assert_allclose(e["total"], e["kinetic"] + e["potential"] + e["elastic"], rtol=1e-15)
    # the run's own Params when given: twice the density, twice the kinetic energy
    heavy = dataclasses.replace(handmade.params, density=2 * handmade.params.density)
    np.testing.assert_allclose(energy(traj, heavy)["kinetic"], 2 * e["kinetic"], rtol=1e-15)
