"""Fixed points (``SceneBuilder.add_fixed_point``) against independent answers: a rigid
compound pendulum (pin, angle against RK4, energy), a pinned bar falling onto a block
(impact, rest, moment balance), immobile bodies, deformable bodies hung from one or two
pins in static analysis (closed-form stress, the constant-stress element's equilibrium),
a gradient through ``rollout``, padding, and bad input."""
import dataclasses
import math

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import jaxdda
from jaxdda.errors import SceneError

G = 9.81
W, L, RHO = 0.2, 1.0, 1000.0  # the pendulum: a W x L bar pinned on its axis, PIN_DEPTH below its top
PIN_DEPTH, ANGLE = 0.1, 1.0
ARM = L / 2 - PIN_DEPTH  # pin to centroid


def rotated(points, angle, about=(0.0, 0.0)):
    c, s = math.cos(angle), math.sin(angle)
    p = np.asarray(points, float) - about
    return p @ np.array([[c, -s], [s, c]]).T + about


def pendulum(dt: float, extra_disk: bool = False):
    """The bar hanging from the pin at the origin, turned by ANGLE, released at rest."""
    sb = jaxdda.SceneBuilder(dt=dt, gravity=(0.0, -G))
    local = np.array([(-W / 2, -L), (W / 2, -L), (W / 2, 0.0), (-W / 2, 0.0)]) + (0.0, PIN_DEPTH)
    bar = sb.add_polygon(rotated(local, ANGLE), density=RHO)
    sb.add_fixed_point(bar, (0.0, 0.0))
    if extra_disk:
        sb.add_disk((5.0, 0.0), 0.3, density=RHO, gravity=False)
    return sb.build()


def pendulum_constants():
    m = RHO * W * L
    i_pin = m * (W * W + L * L) / 12.0 + m * ARM ** 2
    return m, i_pin


def rk4_angle(t_end: float, n: int = 100_000) -> float:
    """The angle from the vertical of I_p phi'' = -m g d sin(phi), phi(0) = ANGLE, at rest."""
    m, i_pin = pendulum_constants()
    k = m * G * ARM / i_pin

    def f(y):
        return np.array([y[1], -k * math.sin(y[0])])

    y, h = np.array([ANGLE, 0.0]), t_end / n
    for _ in range(n):
        a = f(y)
        b = f(y + 0.5 * h * a)
        c = f(y + 0.5 * h * b)
        d = f(y + h * c)
        y = y + h / 6.0 * (a + 2 * b + 2 * c + d)
    return float(y[0])


T_END = 1.0


@pytest.fixture(scope="module")
def swings():
    """The pendulum over T_END at dt and dt / 2 (one compilation: dt is a parameter)."""
    out = {}
    for dt in (2e-3, 1e-3):
        scene = pendulum(dt)
        out[dt] = (scene, jaxdda.simulate(scene, round(T_END / dt), chunk=500))
    return out


def pin_path(traj, scene):
    """(S+1, 2) where the bar's material point that started at the pin is."""
    return traj.material_points([0], [-np.asarray(scene.state.origin[0])])[:, 0]


def test_pendulum_pin_stays_put(swings):
    for scene, traj in swings.values():
        assert np.all(traj.step_converged)
        assert np.max(np.abs(pin_path(traj, scene))) < 1e-12  # measured 8e-16 m


def test_pendulum_angle_matches_rk4_to_the_integrators_error(swings):
    exact = rk4_angle(T_END)
    phi = {dt: ANGLE + float(traj.rotation[-1, 0]) for dt, (_, traj) in swings.items()}
    coarse, fine = phi[2e-3] - exact, phi[1e-3] - exact
    estimate = abs(phi[1e-3] - phi[2e-3]) / 3.0  # Richardson, second order
    assert abs(fine) < 2.0 * estimate  # measured: error 2.89e-6 rad, estimate 2.87e-6 rad
    assert 3.0 < coarse / fine < 5.0  # second order in dt (measured 3.98)
    assert abs(fine) < 1e-5


def test_pendulum_keeps_its_energy(swings):
    m, i_pin = pendulum_constants()
    drift = {}
    for dt, (scene, traj) in swings.items():
        height = traj.centroid[:, 0, 1]
        energy = 0.5 * i_pin * traj.velocity[:, 0, 2] ** 2 + m * G * height
        drift[dt] = np.max(np.abs(energy - energy[0])) / (m * G * ARM)
    assert drift[1e-3] < 1e-6  # measured 1.3e-7 (with the start-of-step lever it gained 0.3 %)
    assert drift[2e-3] / drift[1e-3] > 3.0  # second order in dt (measured 3.8)


# -- a pinned bar falling onto a fixed block --------------------------------------------
TILT, PIN, APEX = 0.2, np.array([0.05, 0.05]), 0.9


@pytest.fixture(scope="module")
def bar_on_block():
    """A 1 x 0.1 bar pinned near its left end, tilted up by TILT, falls (e = 0, no
    friction) onto the apex of a fixed wedge, level with the bar's bottom at rest (one
    contact: on a face, two contacts on the bar's one dof leave their split open)."""
    sb = jaxdda.SceneBuilder(dt=1e-3, gravity=(0.0, -G))
    sb.add_material("dead", friction=0.0, restitution=0.0)
    block = sb.add_polygon([(0.8, -0.4), (1.0, -0.4), (APEX, 0.0)], density=RHO, fixed=True, material="dead")
    bar = sb.add_polygon(rotated([(0, 0), (1, 0), (1, 0.1), (0, 0.1)], TILT, PIN), density=RHO, material="dead")
    sb.add_fixed_point(bar, PIN)
    scene = sb.build()
    return scene, block, bar, jaxdda.simulate(scene, 700)


def test_pinned_bar_strikes_and_rests_on_a_block(bar_on_block):
    scene, block, bar, traj = bar_on_block
    assert np.all(traj.step_converged)
    pin = traj.material_points([bar], [PIN - np.asarray(scene.state.origin[bar])])[:, 0]
    assert np.max(np.abs(pin - PIN)) < 1e-12
    assert np.max(traj.info.max_penetration) < 1e-9
    # it struck: the fall takes a while, then the bar lies level and still on the block
    touching = np.flatnonzero(np.asarray(traj.info.n_contacts) > 0)
    assert 50 < touching[0] < 600
    assert abs(traj.rotation[-1, bar] + TILT) < 1e-9
    assert abs(traj.velocity[-1, bar, 2]) < 1e-9
    # at rest the apex holds the weight's moment about the pin: F (APEX - x_pin) = m g (x_c - x_pin)
    m = RHO * 0.1
    np.testing.assert_allclose(traj.force_between(block, bar)[-1], [0.0, m * G * 0.45 / (APEX - PIN[0])],
                               rtol=1e-10, atol=1e-10 * m * G)


# -- static analysis: deformable bodies hung from pins, and immobile bodies ---------------
E, NU, TOP = 1e9, 0.25, 0.0  # every block spans y in [-1, 0]


def block(x0, half=0.2):
    return [(x0 - half, -1.0), (x0 + half, -1.0), (x0 + half, TOP), (x0 - half, TOP)]


@pytest.fixture(scope="module")
def hung():
    sb = jaxdda.SceneBuilder(dt=0.01, gravity=(0.0, -G), dynamic=0.0)
    one = sb.add_polygon(block(0.0), density=RHO, young=E, poisson=NU)
    sb.add_fixed_point(one, (0.0, -0.1))  # above the centroid: it hangs still
    two = sb.add_polygon(block(2.0, 0.4), density=RHO, young=E, poisson=NU)
    sb.add_fixed_point(two, (1.7, -0.1))
    sb.add_fixed_point(two, (2.2, -0.1))  # two pins on a level line
    rigid = sb.add_polygon(block(4.0), density=RHO)
    sb.add_fixed_point(rigid, (3.9, -0.5))
    sb.add_fixed_point(rigid, (4.1, -0.2))
    sb.add_load(rigid, (300.0, -500.0), at=(4.0, -0.9))
    tri = sb.add_polygon(block(6.0), density=RHO, young=E, poisson=NU)
    for p in [(5.9, -0.1), (6.1, -0.1), (6.0, -0.9)]:
        sb.add_fixed_point(tri, p)
    sb.add_load(tri, (1e4, 0.0), at=(6.0, -0.5))
    scene = sb.build()
    return scene, (one, two, rigid, tri), jaxdda.simulate(scene, 30)


def current(scene, traj, body):
    """Mass, volume and centroid height of a body at the end of the run."""
    volume = float(scene.model.area[body]) * abs(np.linalg.det(traj.stretch[-1, body]))
    return RHO * float(scene.model.area[body]), volume, traj.centroid[-1, body, 1]


def test_enough_pins_fix_a_body(hung):
    scene, (one, two, rigid, tri), traj = hung
    assert list(np.asarray(scene.model.fixed)) == [False, False, True, True]
    for b in (rigid, tri):
        np.testing.assert_array_equal(traj.centroid[-1, b], traj.centroid[0, b])
        assert traj.rotation[-1, b] == 0.0 and np.all(traj.stress[-1, b] == 0.0)


def test_deformable_hung_from_one_pin(hung):
    """The constant-stress element's equilibrium with the weight at the centroid and the
    reaction R = (0, m g) at the pin, a height h above it: V sigma = (p - c) (x) R, so
    sigma = (0, m g h / V, 0)."""
    scene, (one, *_), traj = hung
    assert np.all(traj.step_converged)
    m, volume, cy = current(scene, traj, one)
    sigma = traj.stress[-1, one]
    expect = m * G * (-0.1 - cy) / volume
    np.testing.assert_allclose(sigma, [0.0, expect, 0.0], atol=1e-9 * expect)
    pin = traj.material_points([one], [np.array([0.0, -0.1]) - np.asarray(scene.state.origin[one])])[:, 0]
    assert np.max(np.abs(pin - (0.0, -0.1))) < 1e-12


def test_deformable_hung_from_two_pins(hung):
    """Two pins on a level line a height h above the centroid allow G = a (0, 1)^T only:
    eps_x = 0, and the energy V eps D eps / 2 - m g h a_y is least at sigma_y = m g h / V,
    sigma_x = nu sigma_y, tau = 0 (plane stress). The reactions R1, R2 at the pins then
    solve the element's six equilibrium equations (forces, moment, V sigma = sum r (x) R)."""
    scene, (_, two, *_), traj = hung
    m, volume, cy = current(scene, traj, two)
    sigma = traj.stress[-1, two]
    sy = m * G * (-0.1 - cy) / volume
    np.testing.assert_allclose(sigma, [NU * sy, sy, 0.0], atol=1e-9 * sy)
    c = traj.centroid[-1, two]
    rows = []
    for p in ((1.7, -0.1), (2.2, -0.1)):
        rx, ry = np.subtract(p, c)
        rows.append(np.array([[1, 0], [0, 1], [-ry, rx], [rx, 0], [0, ry], [ry / 2, rx / 2]]))  # T(p)^T
    a = np.concatenate(rows, 1)  # (6, 4): the pins' reactions to the generalised force
    rhs = np.array([0.0, m * G, 0.0, volume * sigma[0], volume * sigma[1], volume * sigma[2]])
    reactions, *_ = np.linalg.lstsq(a, rhs, rcond=None)
    assert np.max(np.abs(a @ reactions - rhs)) < 1e-9 * m * G
    np.testing.assert_allclose(reactions[1] + reactions[3], m * G, rtol=1e-12)
    pins = np.array([(1.7, -0.1), (2.2, -0.1)])
    path = traj.material_points([two, two], pins - np.asarray(scene.state.origin[two]))
    assert np.max(np.abs(path - pins)) < 1e-12


# -- gradients, padding -----------------------------------------------------------------
def test_gradient_of_the_pendulum_angle_matches_finite_differences():
    scene = pendulum(2e-3)

    @jax.jit
    def angle(g):
        params = dataclasses.replace(scene.params, gravity=jnp.stack([0.0 * g, -g]))
        end, _ = jaxdda.rollout(scene.model, scene.state, params, 150)
        return end.rotation[0]

    def both(g):
        return jax.jvp(angle, (g,), (jnp.ones_like(g),))

    value, slope = both(jnp.asarray(G))
    h = 1e-3 * G
    fd = (both(jnp.asarray(G + h))[0] - both(jnp.asarray(G - h))[0]) / (2 * h)
    assert float(slope) < 0  # it swings further down with more gravity
    np.testing.assert_allclose(float(slope), float(fd), rtol=1e-6)


def test_padded_pendulum_swings_the_same(swings):
    small, large = pendulum(2e-3), pendulum(2e-3, extra_disk=True)
    mc = jaxdda.monte_carlo([small, large], 60, chunk=60, progress=False, observe=("final_rotation",))
    alone = swings[2e-3][1]  # the same pendulum run alone
    np.testing.assert_allclose(mc["final_rotation"][:, 0], alone.rotation[60, 0], rtol=1e-12)


# -- bad input ----------------------------------------------------------------------------
def builder_with_bodies():
    sb = jaxdda.SceneBuilder(dt=1e-3)
    sb.add_polygon([(0, 0), (1, 0), (1, 1), (0, 1)], density=1.0)
    sb.add_polygon([(2, 0), (3, 0), (3, 1), (2, 1)], density=1.0, velocity=(1.0, 0.0))
    sb.add_polygon([(4, 0), (5, 0), (5, 1), (4, 1)], density=1.0, fixed=True)
    return sb


@pytest.mark.smoke
@pytest.mark.parametrize("body, at, match", [
    (7, (0.5, 0.5), r"fixed point 0: field 'body' must be the index of an added body"),
    (True, (0.5, 0.5), r"fixed point 0: field 'body'"),
    (0, (2.5, 0.5), r"fixed point 0: field 'at' \(2.5, 0.5\) lies 1.5 m outside body 0"),
    (0, (math.nan, 0.5), r"fixed point 0: field 'at'.* not finite"),
    (0, (0.5,), r"fixed point 0: field 'at' must be a pair of numbers"),
    (1, (2.5, 0.5), r"fixed point 0: body 1 \(polygon\) moves at .*'velocity' and 'angular_velocity'"),
])
def test_bad_fixed_points(body, at, match):
    with pytest.raises(SceneError, match=match):
        builder_with_bodies().add_fixed_point(body, at)


@pytest.mark.smoke
def test_allowed_fixed_points():
    sb = builder_with_bodies()
    assert sb.add_fixed_point(2, (4.5, 0.5)) == 0  # on a fixed body: allowed, changes nothing
    spin = sb.add_polygon([(6, 0), (7, 0), (7, 1), (6, 1)], density=1.0, velocity=(-0.5, 0.5),
                          angular_velocity=1.0)  # spins about its corner (6, 0)
    assert sb.add_fixed_point(spin, (6.0, 0.0)) == 1
    sb.add_fixed_point(0, (0.5, 0.5))
    sb.add_fixed_point(0, (0.5, 0.5))  # the same point twice: one pin
    scene = sb.build()
    assert list(np.asarray(scene.model.fixed)) == [False, False, True, False]
    assert list(np.asarray(scene.model.pin_body)) == [0, 3] and list(np.asarray(scene.model.pin_role)) == [0, 0]
    assert [name for name, _ in scene.recipe[1] if name == "add_fixed_point"] == ["add_fixed_point"] * 4
    sb.add_fixed_point(0, (0.9, 0.1))  # a second distinct pin fixes a rigid body
    assert list(np.asarray(sb.build().model.fixed)) == [True, False, True, False]


@pytest.mark.smoke
def test_fixed_point_on_a_mesh_is_a_fixed_node():
    nodes = [(0, 0), (1, 0), (1, 1), (0, 1)]
    triangles = [(0, 1, 2), (0, 2, 3)]

    def build(pin):
        sb = jaxdda.SceneBuilder(dt=1e-3)
        mesh = sb.add_mesh(nodes, triangles, density=1.0, young=1e6, fixed_nodes=() if pin else (2,))
        if pin:
            sb.add_fixed_point(mesh.bodies[0], (1.0, 1.0))
        return sb, mesh, sb.build()

    sb, mesh, pinned = build(True)
    _, _, reference = build(False)
    assert list(mesh.fixed_nodes) == [False, False, True, False]
    for field in ("group_dofs", "group_free", "fixed"):
        np.testing.assert_array_equal(getattr(pinned.model, field), getattr(reference.model, field))
    with pytest.raises(SceneError, match=r"fixed point 1: field 'at' \(0.5, 0.25\) is not a node of mesh 0"):
        sb.add_fixed_point(mesh.bodies[0], (0.5, 0.25))
    sb2 = jaxdda.SceneBuilder(dt=1e-3)
    moving = sb2.add_mesh(nodes, triangles, density=1.0, young=1e6, velocity=(1.0, 0.0))
    with pytest.raises(SceneError, match=r"fixed point 0: a block with fixed nodes cannot have a velocity"):
        sb2.add_fixed_point(moving.bodies[0], (0.0, 0.0))
