"""Fixed-capacity buffers report overflow; the driver regrows them and loses nothing."""
import dataclasses

import jax
import numpy as np

import jaxdda
from jaxdda.simulate import with_capacity
from jaxdda.types import Capacities


def pile():
    sb = jaxdda.SceneBuilder(dt=0.01, gravity=(0.0, -10.0))
    for k in range(6):
        sb.add_disk(center=(2.0 * k, 1.0), radius=1.0, density=1.0)
        sb.add_polygon(vertices=[(2 * k - 1, 2), (2 * k + 1, 2), (2 * k + 1, 3), (2 * k - 1, 3)], density=1.0)
    sb.add_polygon(vertices=[(-5, -1), (15, -1), (15, 0), (-5, 0)], density=1.0, fixed=True)
    return sb.build()


def test_undersized_buffers_report_overflow():
    scene = pile()
    tiny = Capacities(sweep=2, pairs_pp=1, pairs_pb=1, pairs_bb=1, contacts=2)
    model, state = with_capacity(scene.model, scene.state, tiny)
    _, info = jax.jit(jaxdda.step)(model, state, scene.params)
    assert bool(info.overflow)
    # the first buffer counts all it needed; later ones count what reached them
    assert np.asarray(info.needed)[0] > tiny.sweep


def test_driver_regrows_and_matches_a_roomy_run():
    scene = pile()
    reference = jaxdda.simulate(scene, 30)
    assert not reference.info.overflow.any()
    tiny = Capacities(sweep=2, pairs_pp=1, pairs_pb=1, pairs_bb=1, contacts=2)
    model, state = with_capacity(scene.model, scene.state, tiny)
    regrown = jaxdda.simulate(dataclasses.replace(scene, model=model, state=state), 30)
    assert not regrown.info.overflow.any()
    np.testing.assert_allclose(regrown.centroid, reference.centroid, atol=1e-12)
    assert regrown.info.n_contacts.max() == reference.info.n_contacts.max() > 6
