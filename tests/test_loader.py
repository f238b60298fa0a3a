"""Scene files (TOML and JSON): a valid file builds the scene it describes, every built-in
example is written out and read back to the same scene, and every mistake is a
SceneError that names the key path."""
import copy
import json
import tomllib

import jax
import numpy as np
import pytest

from jaxdda import SceneError, examples
from jaxdda.scene.io import save_scene, scene_to_dict, toml_text
from jaxdda.scene.loader import load_scene, scene_from_dict
from jaxdda.types import DISK, POLYGON, RING

pytestmark = pytest.mark.smoke  # the whole module is cheap: `pytest -m smoke`

SCENE_TOML = """
name = "everything"

[settings]
dt = 0.001
steps = 3
gravity = [0.0, -9.81]
tol = 1e-10
max_iter = 300
capacities = { contacts = 500 }

[materials.granite]        # a block material: density, elasticity and its contact law
density = 2600
young = 5e9
poisson = 0.25
friction = 0.6

[materials.steel]
density = 7800
friction = 0.3
rolling = 0.01

[joints.bedding]           # joint properties, for the edges a joint line made
friction = 0.2
cohesion = 100.0
tensile = 50.0

[[interfaces]]
materials = ["granite", "steel"]
friction = 0.4
restitution = 0.1

[[bodies]]
type = "polygon"
vertices = [[-10, -1], [10, -1], [10, 0], [-10, 0]]
density = 2000
fixed = true
joints = ["", "", "bedding", ""]

[[bodies]]
type = "disk"
center = [-4, 1.5]
radius = 1.0
material = "steel"
velocity = [1.0, 0.0]
angular_velocity = 0.5

[[bodies]]
type = "ring"
center = [0, 2]
inner_radius = 0.5
outer_radius = 1.5
density = 1500

[[bodies]]
type = "polygon"
vertices = [[3, 0.5], [5, 0.5], [4, 2]]
material = "granite"
gravity = false
plane = "strain"

[[bodies]]
type = "mesh"
vertices = [[6, 0], [8, 0], [8, 1], [6, 1]]
max_edge = 1.2
material = "granite"

[[rock_masses]]            # a slope of blocks cut by a joint set and a line
boundary = [[12, 0], [20, 0], [20, 4], [12, 4]]
material = "granite"
joint_sets = [{ dip = 0, spacing = 1.0, offset = 0.5, joint = "bedding" }]
lines = [{ from = [16, -1], to = [16, 5] }]
regions = [{ polygon = [[11, -1], [21, -1], [21, 1.2], [11, 1.2]], fixed = true }]
material_lines = [{ from = [13, 3.5], to = [15, 3.5], material = "steel" }]
holes = [[19, 3.5]]

[[loads]]
body = 1
force = [10.0, 0.0]
at = [-4, 2.5]
rate = [0.0, 1.0]

[[loads]]
at = [4, 1]                # no body: the one the point lies in
history = [[0, 0, 0], [1, 0, -5], [2, 0, -5]]

[[measured_points]]
at = [-4, 1.5]

[[measured_points]]
body = 3
at = [4, 2]

[[fixed_points]]
at = [3, 0.5]              # a corner of body 3

[[connectors]]
type = "spring"
body_a = 1
body_b = 2
at_a = [-4, 1.5]
at_b = [0, 1]
stiffness = 1e5
"""


@pytest.fixture(scope="module")
def everything(tmp_path_factory):
    path = tmp_path_factory.mktemp("scenes") / "everything.toml"
    path.write_text(SCENE_TOML)
    return load_scene(path)


def material(scene, name):
    return scene.materials.index(name)


def test_settings_materials_and_bodies(everything):
    scene, steps = everything
    assert steps == 3 and scene.name == "everything"
    assert float(scene.params.dt) == 0.001 and float(scene.params.tol) == 1e-10
    assert scene.model.capacity.contacts >= 500
    kinds = np.asarray(scene.model.kind)
    assert kinds[:4].tolist() == [POLYGON, DISK, RING, POLYGON]
    # a body's density and elasticity come from its material unless it gives its own
    density, young = np.asarray(scene.params.density), np.asarray(scene.params.young)
    assert density[1] == 7800 and young[1] == 0 and density[3] == 2600 and young[3] == 5e9
    assert bool(scene.model.plane_strain[3]) and float(scene.params.poisson[3]) == 0.25
    meshed = np.flatnonzero(np.asarray(scene.model.mesh) == 0)
    assert len(meshed) >= 2 and np.all(young[meshed] == 5e9)
    f = np.asarray(scene.params.friction)
    g, s, b = material(scene, "granite"), material(scene, "steel"), material(scene, "bedding")
    assert f[g, g] == 0.6 and f[s, s] == 0.3 and f[g, s] == f[s, g] == 0.4 and f[b, b] == 0.2
    assert np.asarray(scene.params.cohesion)[b, b] == 100.0
    # the floor's top edge (vertex 2 -> 3) takes the joint's law
    assert np.asarray(scene.model.edge_material)[0, :4].tolist() == [-1, -1, b, -1]


def test_rock_mass_cut_by_joints(everything):
    scene, _ = everything
    first = int(np.flatnonzero(np.asarray(scene.model.mesh) == 0).max()) + 1
    blocks = range(first, scene.n_bodies)
    # 8 x 4 boundary, horizontal joints at y = 0.5 + k (k = 0..3) and x = 16: 5 layers x 2 = 10
    # blocks, less the one holding the hole point
    assert len(blocks) == 9
    area = np.asarray(scene.model.area)[list(blocks)]
    np.testing.assert_allclose(area.sum(), 32.0 - 2.0, rtol=1e-12)  # the hole's block is 4 x 0.5
    origin, fixed = np.asarray(scene.state.origin), np.asarray(scene.model.fixed)
    for i in blocks:
        assert fixed[i] == (origin[i, 1] < 1.2), i  # the region fixes the two lowest layers' blocks
    mats = np.asarray(scene.model.material)
    crossed = [i for i in blocks if origin[i, 1] > 3.5 and origin[i, 0] < 16]
    assert len(crossed) == 1 and mats[crossed[0]] == material(scene, "steel")
    # inner horizontal edges carry the bedding joint; the vertical cut x = 16 has no joint
    b = material(scene, "bedding")
    edge = np.asarray(scene.model.edge_material)
    assert all((edge[i] == b).any() for i in blocks)


def test_points_loads_and_connectors(everything):
    scene, _ = everything
    model, origin = scene.model, np.asarray(scene.state.origin)
    assert np.asarray(model.load_body).tolist() == [1, 3]
    np.testing.assert_allclose(origin[3] + np.asarray(model.load_point)[1], [4, 1])
    times, history = np.asarray(model.load_times), np.asarray(scene.params.load_history)
    np.testing.assert_array_equal(times[1], [0, 1, 2])
    np.testing.assert_array_equal(history[1], [[0, 0], [0, -5], [0, -5]])
    np.testing.assert_array_equal(times[0], [0, 0, 0])  # no history: h = 0
    np.testing.assert_array_equal(history[0], 0.0)
    assert [b for b, _ in scene.measured] == [1, 3]
    np.testing.assert_allclose(origin[3] + scene.measured[1][1], [4, 2])
    assert int(model.connector_a[0]) == 1 and int(model.connector_b[0]) == 2
    assert np.asarray(model.pin_body).tolist() == [3]
    np.testing.assert_allclose(np.asarray(model.pin_point), [[3, 0.5]])


def test_a_scene_file_writes_back_to_itself(everything, tmp_path):
    """Rock masses, meshes, fixed, load and measured points and histories survive a write
    and a read (as the polygons, meshes and points they became)."""
    scene, steps = everything
    again, _ = load_scene(save_scene(scene, tmp_path / "again.toml", steps=steps))
    assert again.measured[1][0] == scene.measured[1][0] and np.array_equal(again.measured[1][1], scene.measured[1][1])
    for part in ("model", "state", "params"):
        for x, y in zip(jax.tree.leaves(getattr(scene, part)), jax.tree.leaves(getattr(again, part))):
            assert np.array_equal(np.asarray(x), np.asarray(y))


@pytest.mark.parametrize("name", examples.names())
def test_every_example_writes_and_reads_back_the_same_scene(name, tmp_path):
    scene = examples.get(name)
    for suffix in (".toml", ".json"):
        again, steps = load_scene(save_scene(scene, tmp_path / f"{name}{suffix}", steps=7))
        assert steps == 7 and again.name == scene.name
        assert again.labels == scene.labels and again.materials == scene.materials
        for part in ("model", "state", "params"):
            a, b = getattr(scene, part), getattr(again, part)
            assert jax.tree.structure(a) == jax.tree.structure(b)
            for (path, x), y in zip(jax.tree_util.tree_leaves_with_path(a), jax.tree.leaves(b)):
                assert np.shape(x) == np.shape(y) and np.array_equal(np.asarray(x), np.asarray(y), equal_nan=True), \
                    f"{name}{suffix}: {part}{jax.tree_util.keystr(path)}"


def test_written_file_is_the_documented_format(tmp_path):
    """Floats are written to the last bit, and the writer's TOML is what tomllib reads."""
    data = {"name": "x", "settings": {"dt": 0.1 + 0.2, "gravity": [1e-300, -9.81], "capacities": {"contacts": 9}},
            "materials": {"rock": {"friction": 1 / 3}, "odd name": {"tensile": 2.5e7}},
            "bodies": [{"type": "disk", "center": [0.1, 0.7], "radius": 1, "fixed": True, "material": "rock",
                        "joints": ["", "a\"b"]}]}
    assert tomllib.loads(toml_text(data)) == data


def test_names_come_from_the_file(tmp_path):
    path = tmp_path / "tiny.toml"
    path.write_text('[settings]\ndt = 0.01\n[[bodies]]\ntype = "disk"\ncenter = [0, 0]\nradius = 1\ndensity = 1\n')
    scene, steps = load_scene(path)
    assert steps is None and scene.name == "tiny"
    np.testing.assert_allclose(np.asarray(scene.params.gravity), [0.0, -9.81])


BASE = tomllib.loads(SCENE_TOML)


@pytest.mark.parametrize("edit, expected", [
    (lambda d: d.update(gravity=[0, -1]), "gravity: unknown key"),
    (lambda d: d["settings"].update(gravty=[0, -1]), "settings.gravty: unknown key (did you mean 'gravity'?"),
    (lambda d: d["settings"].pop("dt"), "settings.dt: missing"),
    (lambda d: d.pop("settings"), "settings: missing"),
    (lambda d: d["settings"].update(steps=2.5), "settings.steps: must be a positive integer"),
    (lambda d: d["settings"].update(tol="small"), "settings.tol: must be a number"),
    (lambda d: d["settings"]["capacities"].update(contacs=1), "settings.capacities.contacs: unknown key"),
    (lambda d: d["settings"]["capacities"].update(contacts=0), "settings.capacities.contacts: must be a positive"),
    (lambda d: d["settings"].update(dt=0), "field 'dt' must be > 0"),
    (lambda d: d["bodies"][3].update(radious=1), "bodies[3].radious: unknown key"),
    (lambda d: d["bodies"][1].pop("radius"), "bodies[1].radius: missing"),
    (lambda d: d["bodies"][2].pop("density"), "bodies[2].density: missing: the body gives no density"),
    (lambda d: d["bodies"][2].update(type="circle"), "bodies[2].type: unknown type \"circle\""),
    (lambda d: d["bodies"][2].pop("type"), "bodies[2].type: missing"),
    (lambda d: d["bodies"][1].update(fixed="false"), "bodies[1].fixed: must be true or false"),
    (lambda d: d["bodies"][1].update(material=["rock"]), "bodies[1].material: must be a string"),
    (lambda d: d["bodies"][1].update(material="wood"), "bodies[1].material: unknown material 'wood'"),
    (lambda d: d["bodies"][1].update(radius=-1), "bodies[1]: body 1 (disk): field 'radius' must be > 0"),
    (lambda d: d["bodies"][1].update(center=[-4, 0.5]), "interpenetrate"),
    (lambda d: d["bodies"].__setitem__(1, 7), "bodies[1]: must be a table"),
    (lambda d: d["bodies"][0].update(joints=["", "", "bedrock", ""]), "names unknown material 'bedrock'"),
    (lambda d: d["bodies"][0].update(joints=["", ""]), "one entry per edge"),
    (lambda d: d["bodies"][4].pop("material"), "bodies[4].density: missing"),
    (lambda d: d["bodies"][4].update(nodes=[[0, 0]]), "bodies[4]: give either 'nodes' and 'triangles' or"),
    (lambda d: d["materials"]["granite"].update(frction=1), "materials.granite.frction: unknown key"),
    (lambda d: d["materials"]["granite"].update(friction="0.5"), "materials.granite.friction: must be a number"),
    (lambda d: d["materials"]["granite"].update(restitution=2), "materials.granite: material 'granite': field "
                                                                "'restitution' must be in [0, 1]"),
    (lambda d: d["joints"]["bedding"].update(density=1), "joints.bedding.density: unknown key"),
    (lambda d: d["joints"].update(granite={}), "joints.granite: the name is also a material's"),
    (lambda d: d["interfaces"][0].update(mu=1), "interfaces[0].mu: unknown key"),
    (lambda d: d["interfaces"][0].update(materials=["granite"]), "interfaces[0].materials: must be a list of two"),
    (lambda d: d["interfaces"][0].update(materials=["granite", "wood"]), "unknown material 'wood'"),
    (lambda d: d["rock_masses"][0]["joint_sets"][0].update(spacing=-1), "rock_masses[0].joint_sets[0]: joint set: "
                                                                      "field 'spacing' must be > 0"),
    (lambda d: d["rock_masses"][0]["joint_sets"][0].update(joint="fault"), "joint_sets[0].joint: unknown joint"),
    (lambda d: d["rock_masses"][0]["lines"][0].update(to=[16, "x"]), "rock_masses[0]"),
    (lambda d: d["rock_masses"][0].update(holes=[[50, 50]]), "rock_masses[0].holes[0]: the point [50, 50] lies in no"),
    (lambda d: d["rock_masses"][0]["regions"][0].update(polygon=[[0, 0], [1, 1]]), "rock_masses[0].regions[0]"),
    (lambda d: d["rock_masses"][0].pop("boundary"), "rock_masses[0].boundary: missing"),
    (lambda d: d["loads"][0].update(point=[0, 0]), "loads[0].point: unknown key"),
    (lambda d: d["loads"][0].update(body=99), "loads[0]: load 0: field 'body'"),
    (lambda d: d["loads"][1].update(at=[50, 50]), "loads[1]: the point (50.0, 50.0) lies in no body"),
    (lambda d: d["loads"][1].update(history=[[1, 0, 0], [0, 0, 1]]), "the times must not decrease"),
    (lambda d: d["loads"][1].update(history=[[1, 0]]), "loads[1]: load 1: field 'history' must be rows (t, fx, fy)"),
    (lambda d: d["measured_points"][1].update(at=[9, 9]), "measured_points[1]: measured point 1: field 'at'"),
    (lambda d: d["measured_points"][0].update(at=[7, 0]), "lies on the boundary of bodies"),
    (lambda d: d["connectors"][0].update(stifness=1), "connectors[0].stifness: unknown key"),
    (lambda d: d["connectors"][0].update(type="rope"), "connectors[0].type: unknown type \"rope\""),
    (lambda d: d["connectors"][0].pop("at_b"), "connectors[0].at_b: missing"),
    (lambda d: [d["connectors"][0].pop(k) for k in ("at_b", "body_b")], "connectors[0].body_b: missing: give"),
    (lambda d: d.update(bodies=[], meshes=[], rock_masses=[], loads=[], measured_points=[], connectors=[]),
     "no bodies"),
])
def test_errors_name_the_key_path(edit, expected):
    message = error_of(BASE, edit)
    assert expected in message and message.startswith("scene file: ")


def error_of(data, edit) -> str:
    """The message of the SceneError that ``data`` edited by ``edit`` raises."""
    data = copy.deepcopy(data)
    edit(data)
    with pytest.raises(SceneError) as err:
        scene_from_dict(data)
    return str(err.value)


def test_file_errors(tmp_path):
    with pytest.raises(SceneError, match="no such scene file"):
        load_scene(tmp_path / "absent.toml")
    bad = tmp_path / "bad.toml"
    bad.write_text('[settings]\ndt = 0.001\nsteps = = 2\n[[bodies]]\n')
    with pytest.raises(SceneError, match=r"bad\.toml: invalid TOML: .*line 3"):
        load_scene(bad)
    bad = tmp_path / "bad.json"
    bad.write_text('{"settings": {"dt": 0.001},\n "bodies": [}\n')
    with pytest.raises(SceneError, match=r"bad\.json: invalid JSON at line 2, column 13"):
        load_scene(bad)
    with pytest.raises(SceneError, match="the scene: must be a table"):
        scene_from_dict([1, 2])


def test_a_scene_not_made_by_the_builder_cannot_be_written():
    import dataclasses

    scene = dataclasses.replace(examples.get("paper-7.5"), recipe=())
    with pytest.raises(SceneError, match="carries no recipe"):
        scene_to_dict(scene)


MESHED = {
    "settings": {"dt": 0.01},
    "bodies": [{"type": "polygon", "vertices": [[0, 3], [1, 3], [1, 4], [0, 4]], "density": 1, "fixed": True}],
    "meshes": [{"nodes": [[0, 0], [1, 0], [1, 1], [0, 1]], "triangles": [[0, 1, 2], [0, 2, 3]], "density": 2000,
                "young": 1e9, "poisson": 0.2, "fixed_nodes": [0, 1]}],
    "loads": [{"body": {"mesh": 0, "node": 2}, "force": [5.0, 0.0]}],
    "connectors": [{"type": "spring", "body_a": 0, "body_b": {"mesh": 0, "node": 3}, "at_a": [0, 3],
                    "stiffness": 1e5}],
}


def test_meshes_and_their_nodes():
    scene, _ = scene_from_dict(MESHED)
    mesh = np.asarray(scene.model.mesh)
    assert mesh.tolist() == [-1, 0, 0]
    body = int(scene.model.load_body[0])
    np.testing.assert_allclose(np.asarray(scene.state.origin)[body] + np.asarray(scene.model.load_point)[0], [1, 1])
    b = int(scene.model.connector_b[0])
    np.testing.assert_allclose(np.asarray(scene.state.origin)[b] + np.asarray(scene.model.connector_pb)[0], [0, 1])


@pytest.mark.parametrize("edit, expected", [
    (lambda d: d["meshes"][0].update(nodez=1), "meshes[0].nodez: unknown key"),
    (lambda d: d["meshes"][0].pop("young"), "meshes[0].young: missing"),
    (lambda d: d["meshes"][0].pop("triangles"), "meshes[0]: keys 'nodes' and 'triangles' go together"),
    (lambda d: d["meshes"][0].update(triangles=[[0, 2, 1], [0, 2, 3]]), "triangle 0 [0, 2, 1] is inverted"),
    (lambda d: d["loads"][0].update(body={"mesh": 4, "node": 0}), "loads[0].body.mesh: 4 is not one of the 1"),
    (lambda d: d["loads"][0].update(body={"mesh": 0, "node": 9}), "loads[0].body.node: 9 is not one of mesh 0's"),
    (lambda d: d["loads"][0].update(body={"mesh": 0}), "loads[0].body.node: missing"),
    (lambda d: d["connectors"][0].update(body_b={"mesh": 0, "nod": 1}), "connectors[0].body_b.nod: unknown"),
])
def test_mesh_errors_name_the_key_path(edit, expected):
    assert expected in error_of(MESHED, edit)


def test_the_documented_example_builds():
    """The example at the top of docs/scene-format.md is a valid scene."""
    import pathlib
    import re

    text = (pathlib.Path(__file__).parent.parent / "docs" / "scene-format.md").read_text()
    example = re.search(r"```toml\n(.*?)```", text, re.S).group(1)
    scene, steps = scene_from_dict(tomllib.loads(example))
    assert steps == 2000 and scene.name == "slope" and scene.n_bodies > 10
