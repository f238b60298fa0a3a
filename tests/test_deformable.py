"""Deformable particles and blocks (paper eqs. 4-7, 17-18, Appendix): closed-form statics."""
import math

import numpy as np
import pytest

import jaxdda
from jaxdda.errors import SceneError

RHO, G = 2000.0, 10.0


def settled(add_body, steps=200):
    """A deformable body dropped (at rest, touching) on a fixed frictionless base; DDA's
    Newmark (gamma = 1) damps the elastic vibration, leaving the static strain."""
    sb = jaxdda.SceneBuilder(dt=0.001, gravity=(0.0, -G))
    add_body(sb)
    sb.add_polygon(vertices=[(-3, -1), (5, -1), (5, 0), (-3, 0)], density=RHO, fixed=True)
    return jaxdda.simulate(sb.build(), steps)


@pytest.mark.parametrize("plane", ["stress", "strain"])
def test_block_under_its_weight_has_the_uniform_strain_of_the_6_dof_field(plane):
    # The bottom corners carry W/2 each; the uniform stress that balances them on the
    # strain dofs is the mean of the true linear one: sigma_y = -rho g h / 2, sigma_x = 0.
    e_mod, nu, w, h = 1e9, 0.3, 2.0, 1.0
    run = settled(lambda sb: sb.add_polygon(vertices=[(0, 0), (w, 0), (w, h), (0, h)], density=RHO,
                                            young=e_mod, poisson=nu, plane=plane))
    sy = -RHO * G * h / 2
    e_eff, nu_eff = (e_mod, nu) if plane == "stress" else (e_mod / (1 - nu ** 2), nu / (1 - nu))
    eps_y, eps_x = sy / e_eff, -nu_eff * sy / e_eff
    np.testing.assert_allclose(run.stress[-1, 0], [0.0, sy, 0.0], atol=1e-5 * abs(sy), rtol=0)
    stretch = np.asarray(run.final_state.stretch[0])
    np.testing.assert_allclose(stretch - np.eye(2), [[eps_x, 0.0], [0.0, eps_y]], atol=1e-5 * abs(eps_y), rtol=0)
    # The centroid sinks by the compression of the lower half; nothing slides or turns.
    np.testing.assert_allclose(run.centroid[-1, 0], [w / 2, h / 2 * (1 + eps_y)], atol=1e-5 * abs(eps_y), rtol=0)
    assert abs(run.rotation[-1, 0]) < 1e-12


def test_deformable_disk_has_the_particle_strain_of_the_appendix():
    # One dof eps (eq. 4); K = 2 A E / (1 - nu) (eqs. A.1-A.3): the contact force W at
    # (0, -R) loads it by -R W, so sigma_x = sigma_y = E eps / (1 - nu) = -rho g R / 2.
    e_mod, nu, r = 1e9, 0.25, 1.0
    run = settled(lambda sb: sb.add_disk(center=(0.0, r), radius=r, density=RHO, young=e_mod, poisson=nu))
    s = -RHO * G * r / 2
    np.testing.assert_allclose(run.stress[-1, 0], [s, s, 0.0], atol=1e-5 * abs(s), rtol=0)
    eps = s * (1 - nu) / e_mod
    stretch = np.asarray(run.final_state.stretch[0])
    np.testing.assert_allclose(stretch - np.eye(2), eps * np.eye(2), atol=1e-5 * abs(eps), rtol=0)
    np.testing.assert_allclose(run.centroid[-1, 0, 1], r * (1 + eps), atol=1e-5 * abs(eps), rtol=0)


def test_free_block_keeps_momentum_and_zero_stress():
    # No load, no contact: translation and spin are exact, the strain stays zero.
    sb = jaxdda.SceneBuilder(dt=0.01, gravity=(0.0, 0.0))
    sb.add_polygon(vertices=[(0, 0), (2, 0), (2, 1), (0, 1)], density=RHO, young=1e8, poisson=0.2,
                   velocity=(1.0, -2.0))
    run = jaxdda.simulate(sb.build(), 50)
    np.testing.assert_allclose(run.centroid[:, 0] - run.centroid[0, 0], np.outer(run.time, [1.0, -2.0]), atol=1e-12, rtol=0)
    assert np.abs(run.stress).max() == 0.0


@pytest.mark.smoke
@pytest.mark.parametrize("kwargs, words", [
    ({"young": 0.0}, ["young", "> 0"]),
    ({"young": -1e9}, ["young"]),
    ({"young": 1e9, "poisson": 0.5}, ["poisson", "(-1, 0.5)"]),
    ({"young": 1e9, "poisson": -1.0}, ["poisson"]),
    ({"young": 1e9, "poisson": math.nan}, ["poisson", "not finite"]),
    ({"young": 1e9, "plane": "shell"}, ["plane", "shell"]),
    ({"stress": (1.0, 0.0, 0.0)}, ["stress", "young"]),
    ({"young": 1e9, "stress": (1.0, 0.0)}, ["stress"]),
])
def test_bad_elastic_constants_are_named(kwargs, words):
    sb = jaxdda.SceneBuilder(dt=0.01)
    with pytest.raises(SceneError) as err:
        sb.add_polygon(vertices=[(0, 0), (1, 0), (0, 1)], density=1.0, **kwargs)
    for w in ["body 0 (polygon)"] + words:
        assert w in str(err.value)


def test_initial_stress_relaxes_into_the_strain_it_implies():
    # A free block with an initial tension sigma_0 in x (eq. A.11) settles where the total
    # stress vanishes: eps = -D^-1 sigma_0 = (-s/E, nu s/E, 0) in plane stress.
    e_mod, nu, s0 = 1e9, 0.3, 1e5
    sb = jaxdda.SceneBuilder(dt=0.001, gravity=(0.0, 0.0))
    sb.add_polygon(vertices=[(0, 0), (2, 0), (2, 1), (0, 1)], density=RHO, young=e_mod, poisson=nu,
                   stress=(s0, 0.0, 0.0))
    run = jaxdda.simulate(sb.build(), 300)
    np.testing.assert_allclose(run.stress[-1, 0], 0.0, atol=1e-5 * s0, rtol=0)
    stretch = np.asarray(run.final_state.stretch[0])
    np.testing.assert_allclose(stretch - np.eye(2), np.diag([-s0 / e_mod, nu * s0 / e_mod]),
                               atol=1e-5 * s0 / e_mod, rtol=0)
