"""Size classes: ``simulate`` runs a scene padded to its size class, so that scenes of
similar size share one compiled program. Padding must change nothing but round-off."""
import dataclasses

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import jaxdda
from jaxdda.contact.detect import detect
from jaxdda.contact.keys import renumber
from jaxdda.scene.capacity import size_class
from jaxdda.scene.padding import Shape, pad_scene
from jaxdda.simulate import _run_chunk_jit


def mixed_scene():
    """Every narrow-phase kernel: polygon-polygon (block and pentagon on the floor),
    particle-polygon (a disk on the floor, a ring on it), particle-particle (a disk in
    the ring's hole, a disk against the ring's outside)."""
    sb = jaxdda.SceneBuilder(dt=1e-3, gravity=(0.0, -9.81))
    sb.add_polygon([(-6, -1), (6, -1), (6, 0), (-6, 0)], density=1.0, fixed=True)
    sb.add_polygon([(0, 0), (1, 0), (1, 1), (0, 1)], density=1.0)
    sb.add_polygon([(1.05, 0), (1.8, 0), (2.0, 0.5), (1.5, 0.9), (1.1, 0.5)], density=1.0)
    sb.add_disk(center=(-1.0, 0.5), radius=0.5, density=1.0)
    sb.add_ring(center=(3.5, 1.2), inner_radius=1.0, outer_radius=1.2, density=1.0)
    sb.add_disk(center=(3.5, 0.45), radius=0.25, density=1.0)
    sb.add_disk(center=(5.1, 0.42), radius=0.4, density=1.0)
    return sb.build()


def keys_of(model, state):
    n = model.n_bodies
    reach = jnp.full((n,), 0.3)
    c, needed = jax.jit(detect)(model, state.centroid, state.rotation, reach, jnp.zeros(n), 1e-3)
    assert np.all(np.asarray(needed) <= np.asarray(dataclasses.astuple(model.capacity)))
    return np.asarray(c.key)[np.asarray(c.valid)], c


def test_padding_renumbers_contact_keys_as_detection_numbers_them():
    scene = mixed_scene()
    own, c = keys_of(scene.model, scene.state)
    polygons = (np.asarray(scene.model.kind) == jaxdda.types.POLYGON)
    a, b = np.asarray(c.a)[np.asarray(c.valid)], np.asarray(c.b)[np.asarray(c.valid)]
    kernels = set((polygons[a].astype(int) + polygons[b].astype(int)).tolist())
    assert kernels == {0, 1, 2}, kernels  # all three kernels have contacts
    shape = dataclasses.replace(Shape.covering([scene]), bodies=scene.model.n_bodies + 5, vertices=9)
    model, state, _ = jax.tree.map(jnp.asarray, pad_scene(scene, shape))
    padded, _ = keys_of(model, state)
    n, v = scene.model.n_bodies, scene.model.max_vertices
    assert sorted(renumber(own, scene.model.kind, n, v, shape.bodies, shape.vertices).tolist()) == sorted(padded.tolist())
    kind = scene.model.kind
    assert sorted(renumber(padded, kind, shape.bodies, shape.vertices, n, v).tolist()) == sorted(own.tolist())
    assert np.array_equal(renumber(np.array([-1, -2]), kind, shape.bodies, shape.vertices, n, v), [-1, -2])


def test_a_padded_run_is_the_run_of_the_scene():
    """simulate (padded to 16 bodies, whose void bodies sit at the origin, which a disk
    rolls across) against the scene's own step, unpadded: the same to round-off."""
    sb = jaxdda.SceneBuilder(dt=2e-3, gravity=(0.0, -9.81))
    sb.add_material("rock", friction=0.4, restitution=0.3)
    sb.add_polygon([(-3, -1), (3, -1), (3, 0), (-3, 0)], density=1.0, fixed=True, material="rock")
    sb.add_disk(center=(-0.5, 0.3), radius=0.3, density=2.0, velocity=(3.0, 0.0), angular_velocity=-4.0,
                material="rock")
    sb.add_polygon([(0.5, 0.2), (1.0, 0.2), (1.0, 0.6), (0.5, 0.6)], density=1.0, velocity=(-1.0, 0.0),
                   material="rock")
    scene = sb.build()
    steps = 150
    run = jaxdda.simulate(scene, steps)
    _, (states, infos) = jax.jit(jaxdda.rollout, static_argnames=("steps", "checkpoint"))(
        scene.model, scene.state, scene.params, steps=steps, checkpoint=False)
    assert not np.asarray(infos.overflow).any()
    assert run.centroid.shape == (steps + 1, 3, 2) and run.final_state.centroid.shape == (3, 2)
    np.testing.assert_allclose(run.centroid[1:], np.asarray(states.centroid), rtol=0, atol=1e-12)
    np.testing.assert_allclose(run.velocity[1:], np.asarray(states.velocity)[..., :3], rtol=0, atol=1e-9)
    assert run.info.n_contacts.max() >= 2  # the disk and the block meet, both on the floor
    np.testing.assert_array_equal(run.info.n_contacts, np.asarray(infos.n_contacts))


def test_scenes_of_one_size_class_share_one_program():
    def heap(n):
        sb = jaxdda.SceneBuilder(dt=1e-3, gravity=(0.0, -9.81))
        sb.add_polygon([(-10, -1), (10, -1), (10, 0), (-10, 0)], density=1.0, fixed=True)
        for k in range(n):
            sb.add_disk(center=(-8.0 + 3.0 * k, 0.6), radius=0.5, density=1.0)
        return sb.build()

    jaxdda.simulate(heap(1), 3)
    before = _run_chunk_jit._cache_size()
    runs = [jaxdda.simulate(heap(n), 3) for n in (2, 5)]
    assert _run_chunk_jit._cache_size() == before
    for n, run in zip((2, 5), runs):
        assert run.centroid.shape == (4, n + 1, 2)


@pytest.mark.smoke
def test_size_classes_round_up_by_at_most_a_quarter():
    xs = np.arange(1, 5000)
    classes = np.array([size_class(x) for x in xs])
    assert np.all(classes >= xs) and np.all(classes <= 1.25 * xs) and np.all(np.diff(classes) >= 0)
    assert all(size_class(c) == c for c in set(classes.tolist()))  # a class is its own class
    assert size_class(3, 16) == 16
