"""Bad input gets a clear SceneError naming the body and the field."""
import math

import numpy as np
import pytest

import jaxdda
from jaxdda import SceneError

pytestmark = pytest.mark.smoke  # the whole module is cheap: `pytest -m smoke`


def builder():
    return jaxdda.SceneBuilder(dt=0.01, gravity=(0.0, -10.0))


def square(x=0.0, y=0.0, s=1.0):
    return [(x, y), (x + s, y), (x + s, y + s), (x, y + s)]


@pytest.mark.parametrize("call, words", [
    (lambda sb: sb.add_disk(center=(0, 0), radius=-1.0, density=1.0), ["body 0 (disk)", "radius", "> 0"]),
    (lambda sb: sb.add_disk(center=(0, 0), radius=0.0, density=1.0), ["body 0 (disk)", "radius"]),
    (lambda sb: sb.add_disk(center=(0, 0), radius=1.0, density=0.0), ["body 0 (disk)", "density"]),
    (lambda sb: sb.add_disk(center=(0, 0), radius=1.0, density=-5.0), ["body 0 (disk)", "density"]),
    (lambda sb: sb.add_disk(center=(math.nan, 0), radius=1.0, density=1.0), ["body 0 (disk)", "center", "not finite"]),
    (lambda sb: sb.add_disk(center=(0, 0), radius=1.0, density=1.0, velocity=(0, math.inf)),
     ["body 0 (disk)", "velocity", "not finite"]),
    (lambda sb: sb.add_disk(center=(0, 0), radius="1", density=1.0), ["body 0 (disk)", "radius", "not numeric"]),
    (lambda sb: sb.add_disk(center=(0, 0), radius=1.0, density=1.0, fixed="no"), ["body 0 (disk)", "fixed"]),
    (lambda sb: sb.add_disk(center=(0, 0), radius=1.0, density=1.0, material="steel"),
     ["body 0 (disk)", "material", "steel"]),
    (lambda sb: sb.add_disk(center=(0, 0), radius=1.0, density=1.0, fixed=True, velocity=(1, 0)),
     ["body 0 (disk)", "fixed", "velocity"]),
    (lambda sb: sb.add_ring(center=(0, 0), inner_radius=2.0, outer_radius=2.0, density=1.0),
     ["body 0 (ring)", "inner_radius", "outer_radius"]),
    (lambda sb: sb.add_ring(center=(0, 0), inner_radius=0.0, outer_radius=2.0, density=1.0),
     ["body 0 (ring)", "inner_radius"]),
    (lambda sb: sb.add_polygon(vertices=[(0, 0), (1, 0)], density=1.0), ["body 0 (polygon)", "vertices", "fewer than 3"]),
    (lambda sb: sb.add_polygon(vertices=[(0, 0), (1, 1), (1, 0), (0, 1)], density=1.0),
     ["body 0 (polygon)", "vertices", "self-intersecting"]),
    (lambda sb: sb.add_polygon(vertices=[(0, 0), (1, 1), (2, 2)], density=1.0), ["body 0 (polygon)", "vertices", "zero area"]),
    (lambda sb: sb.add_polygon(vertices=[(0, 0), (1, 0), (math.nan, 1)], density=1.0),
     ["body 0 (polygon)", "vertices", "not finite"]),
    (lambda sb: sb.add_polygon(vertices=[(0, 0), (1, 0), (1, 1)], density=1.0, angular_velocity=math.nan),
     ["body 0 (polygon)", "angular_velocity"]),
    (lambda sb: sb.add_material("rock", friction=-0.1), ["rock", "friction"]),
    (lambda sb: sb.add_material("rock", restitution=1.5), ["rock", "restitution"]),
    (lambda sb: sb.add_material("rock", cohesion=-1.0), ["rock", "cohesion", ">= 0"]),
    (lambda sb: sb.add_material("rock", rolling=-0.01), ["rock", "rolling", ">= 0"]),
    (lambda sb: sb.add_material("rock", tensile=-5.0), ["rock", "tensile", ">= 0"]),
    (lambda sb: sb.add_material("rock", tensile=math.nan), ["rock", "tensile", "not finite"]),
    (lambda sb: sb.set_interface("default", "default", cohesion=-1.0), ["interface", "cohesion"]),
    (lambda sb: sb.set_interface("default", "default", stickiness=1.0), ["interface", "stickiness"]),
    (lambda sb: sb.add_load(0, force=(1.0, 0.0)), ["load 0", "body"]),
])
def test_bad_body_or_material_is_named(call, words):
    with pytest.raises(SceneError) as err:
        call(builder())
    for w in words:
        assert w in str(err.value)


def test_the_index_in_messages_is_the_offending_body():
    sb = builder()
    sb.add_disk(center=(0, 0), radius=1.0, density=1.0)
    sb.add_disk(center=(5, 0), radius=1.0, density=1.0)
    with pytest.raises(SceneError, match=r"body 2 \(polygon\).*vertices"):
        sb.add_polygon(vertices=[(0, 0), (1, 0)], density=1.0)


@pytest.mark.parametrize("second, words", [
    (lambda sb: sb.add_disk(center=(1.5, 0), radius=1.0, density=1.0), ["body 0 (disk)", "body 1 (disk)", "interpenetrate"]),
    (lambda sb: sb.add_polygon(vertices=square(0.5, -0.5), density=1.0), ["body 0 (disk)", "body 1 (polygon)"]),
    (lambda sb: sb.add_ring(center=(0, 0), inner_radius=0.5, outer_radius=3.0, density=1.0),
     ["body 0 (disk)", "body 1 (ring)"]),
])
def test_interpenetration_at_start_is_refused(second, words):
    sb = builder()
    sb.add_disk(center=(0, 0), radius=1.0, density=1.0)
    second(sb)
    with pytest.raises(SceneError) as err:
        sb.build()
    for w in words:
        assert w in str(err.value)


def test_touching_is_allowed():
    sb = builder()
    sb.add_disk(center=(0, 1), radius=1.0, density=1.0)  # on the block
    sb.add_disk(center=(0, 3), radius=1.0, density=1.0)  # on the disk
    sb.add_ring(center=(5, 3), inner_radius=1.0, outer_radius=3.0, density=1.0)  # on the block
    sb.add_disk(center=(5, 2.5), radius=0.5, density=1.0)  # inside the ring's hole, touching it
    sb.add_polygon(vertices=[(-10, -1), (10, -1), (10, 0), (-10, 0)], density=1.0, fixed=True)
    sb.add_polygon(vertices=square(10.0, -1.0), density=1.0)  # shares an edge with the block
    scene = sb.build()
    assert scene.n_bodies == 6


def test_scene_level_errors():
    with pytest.raises(SceneError, match="no bodies"):
        builder().build()
    sb = jaxdda.SceneBuilder(dt=-0.1)
    sb.add_disk(center=(0, 0), radius=1.0, density=1.0)
    with pytest.raises(SceneError, match="dt"):
        sb.build()
    sb = jaxdda.SceneBuilder(dt=0.1, gravity=(0.0, math.nan))
    sb.add_disk(center=(0, 0), radius=1.0, density=1.0)
    with pytest.raises(SceneError, match="gravity"):
        sb.build()


def test_mixed_materials_use_the_smaller_value_unless_an_interface_is_set():
    sb = builder()
    sb.add_material("rock", friction=0.6, restitution=0.3)
    sb.add_material("ice", friction=0.05, restitution=0.9)
    sb.add_material("steel", friction=0.4, restitution=0.8)
    sb.set_interface("rock", "steel", friction=0.5)
    sb.add_disk(center=(0, 0), radius=1.0, density=1.0, material="rock")
    scene = sb.build()
    idx = {m: k for k, m in enumerate(scene.materials)}
    f, e = np.asarray(scene.params.friction), np.asarray(scene.params.restitution)
    assert f[idx["rock"], idx["rock"]] == 0.6
    assert f[idx["rock"], idx["ice"]] == f[idx["ice"], idx["rock"]] == 0.05
    assert e[idx["rock"], idx["ice"]] == 0.3
    assert f[idx["rock"], idx["steel"]] == 0.5 and e[idx["rock"], idx["steel"]] == 0.3
    with pytest.raises(SceneError, match="granite"):
        sb.set_interface("rock", "granite", friction=0.1)


def test_contact_law_tables_cover_every_field():
    sb = builder()
    sb.add_material("rock", friction=0.6, cohesion=50.0, rolling=0.01, tensile=200.0)
    sb.add_material("sand", cohesion=10.0, rolling=0.02)
    sb.set_interface("rock", "sand", tensile=30.0)
    sb.add_disk(center=(0, 0), radius=1.0, density=1.0, material="rock")
    scene = sb.build()
    idx = {m: k for k, m in enumerate(scene.materials)}
    r, s = idx["rock"], idx["sand"]
    p = scene.params
    assert (p.cohesion[r, r], p.rolling[r, r], p.tensile[r, r]) == (50.0, 0.01, 200.0)
    assert (p.cohesion[r, s], p.rolling[r, s], p.tensile[r, s]) == (10.0, 0.01, 30.0)


def test_point_loads():
    sb = builder()
    sb.add_disk(center=(1.0, 2.0), radius=1.0, density=1.0)
    sb.add_load(0, force=(3.0, 0.0), at=(1.0, 3.0), rate=(0.0, -1.0))
    scene = sb.build()
    np.testing.assert_allclose(scene.model.load_point, [[0.0, 1.0]])  # body-local
    np.testing.assert_allclose(scene.params.load_force, [[3.0, 0.0]])
    np.testing.assert_allclose(scene.params.load_rate, [[0.0, -1.0]])
    with pytest.raises(SceneError, match="load 1.*force.*not finite"):
        sb.add_load(0, force=(math.inf, 0.0))


def test_polygon_is_stored_counter_clockwise_about_its_centroid():
    sb = builder()
    sb.add_polygon(vertices=[(0, 0), (0, 2), (4, 2), (4, 0)], density=3.0)  # clockwise
    scene = sb.build()
    np.testing.assert_allclose(scene.state.centroid[0], [2.0, 1.0])
    local = np.asarray(scene.model.local_vertices[0])
    area2 = np.sum(local[:, 0] * np.roll(local[:, 1], -1) - np.roll(local[:, 0], -1) * local[:, 1])
    assert area2 > 0
    np.testing.assert_allclose(scene.model.area[0], 8.0)
    np.testing.assert_allclose(scene.model.polar_moment[0], 8.0 * (16 + 4) / 12)


def test_scalars_are_strongly_typed_float64():
    """A weakly typed scalar (dt, tol, ...) is another jit signature than the float64 a user
    sets, so every change of it would compile the step again."""
    import jax

    sb = builder()
    sb.add_disk(center=(0, 0), radius=1.0, density=1.0)
    scene = sb.build()
    for tree in (scene.model, scene.state, scene.params):
        for path, leaf in jax.tree_util.tree_flatten_with_path(tree)[0]:
            assert not getattr(leaf, "weak_type", False), jax.tree_util.keystr(path)
    assert scene.params.dt.dtype == np.float64
