"""The step's refinements switched off (``StepOptions``): the step is then Moreau's scheme
with the position-level contact VI and FISTA alone, and must still be right to first order.

One compiled program (every refinement off) serves all the runs here: dt is a parameter."""
import dataclasses
import math

import jax.numpy as jnp
import numpy as np
import pytest

import jaxdda
from jaxdda.types import StepOptions

G, E, R, DT = 10.0, 0.5, 0.5, 0.01
OFF = dict(impact_instants=False, impact_refits=0, windows=False, discrete_gradient=False, linearisation_cut=False,
           newton_finish=False)


def _drop_and_block(height: float):
    """A disk (restitution E, frictionless) dropped from rest ``height`` above a fixed
    floor, and a block resting on that floor 3 m away."""
    sb = jaxdda.SceneBuilder(dt=DT, gravity=(0.0, -G))
    sb.add_material("ball", restitution=E, friction=0.0)
    sb.add_polygon(vertices=[(-5.0, -1.0), (5.0, -1.0), (5.0, 0.0), (-5.0, 0.0)], density=1.0, fixed=True,
                   material="ball")
    sb.add_disk(center=(0.0, R + height), radius=R, density=2.0, material="ball")
    sb.add_polygon(vertices=[(2.5, 0.0), (3.5, 0.0), (3.5, 1.0), (2.5, 1.0)], density=2.0, material="ball")
    return sb.build().with_options(**OFF)


@pytest.mark.smoke
def test_options_are_static_and_checked():
    scene = _drop_and_block(0.45)
    assert scene.model.options == StepOptions(**OFF)
    assert StepOptions() == StepOptions(True, 6, True, True, True, True)
    with pytest.raises(ValueError, match="impact_refits"):
        StepOptions(impact_refits=-1)
    with pytest.raises(ValueError, match="newton_finish"):
        StepOptions(newton_finish=1)


@pytest.mark.parametrize("phase", [0.2, 0.45, 0.7])  # inside a step at dt and at dt / 2
def test_moreau_bounce_is_first_order_in_closed_form(phase):
    """Moreau's impact at the start of the step whose free path closes the gap: the disk,
    at t_k = k dt with gap g0 and speed g t_k, leaves with e g t_k and flies freely: its
    apex is g0 + e^2 g t_k^2 / 2 = h - (1 - e^2) g t_k^2 / 2, against the exact e^2 h:
    an error (1 - e^2) g0 with 0 < g0 < g t_hit dt, first order in dt. Read from the
    energy of the free flight after the bounce (exact under Newmark), at dt and dt / 2."""
    t_hit = (30 + phase) * DT
    h = 0.5 * G * t_hit ** 2
    scene = _drop_and_block(h)
    errors = []
    for dt in (DT, DT / 2):
        steps = int(round(0.5 / dt))  # past the apex (t = 0.46 s at most), before the next bounce
        params = dataclasses.replace(scene.params, dt=jnp.asarray(dt))
        run = jaxdda.simulate(dataclasses.replace(scene, params=params), steps)
        y, vy = run.centroid[-1, 1, 1] - R, run.velocity[-1, 1, 1]
        assert vy < 0 < y  # past the apex, in flight
        apex = y + vy ** 2 / (2 * G)
        t_k = math.floor(t_hit / dt) * dt
        g0 = h - 0.5 * G * t_k ** 2
        np.testing.assert_allclose(apex, h - (1 - E ** 2) * 0.5 * G * t_k ** 2, rtol=1e-9)
        assert 0 < g0 < G * t_hit * dt
        errors.append(apex - E ** 2 * h)
        # never more energy than it started with, and never below the floor
        energy = G * (run.centroid[:, 1, 1] - R) + 0.5 * run.velocity[:, 1, 1] ** 2
        assert energy.max() <= G * h * (1 + 1e-12)
        assert run.info.max_penetration.max() <= 1e-9
        # the block stays at rest on the floor, its solve converged without Newton
        assert np.abs(run.centroid[:, 2] - run.centroid[0, 2]).max() < 1e-9
        assert run.info.converged.all()
    assert all(0 < err < (1 - E ** 2) * G * t_hit * dt for err, dt in zip(errors, (DT, DT / 2)))
