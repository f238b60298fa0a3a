"""JSON scene files: a valid file builds the scene it describes; every mistake is a
SceneError that names where it is."""
import copy
import json

import numpy as np
import pytest

from jaxdda import SceneError
from jaxdda.scene.loader import load_scene, scene_from_dict
from jaxdda.types import DISK, POLYGON, RING

SCENE = {
    "name": "mixed",
    "dt": 0.001,
    "gravity": [0.0, -9.81],
    "steps": 3,
    "solver": {"tol": 1e-10, "max_iter": 300, "margin": None},
    "materials": {"rock": {"friction": 0.5, "restitution": 0.2, "cohesion": 100.0, "tensile": 50.0},
                  "steel": {"friction": 0.3, "rolling": 0.01}},
    "interfaces": [{"materials": ["rock", "steel"], "friction": 0.4, "restitution": 0.1}],
    "bodies": [
        {"type": "polygon", "vertices": [[-10, -1], [10, -1], [10, 0], [-10, 0]], "density": 2000,
         "fixed": True, "material": "rock"},
        {"type": "disk", "center": [-4, 1.5], "radius": 1.0, "density": 1000, "velocity": [1.0, 0.0],
         "angular_velocity": 0.5, "material": "steel"},
        {"type": "ring", "center": [0, 2], "inner_radius": 0.5, "outer_radius": 1.5, "density": 1500},
        {"type": "polygon", "vertices": [[3, 0.5], [5, 0.5], [4, 2]], "density": 2500, "gravity": False,
         "young": 1e9, "poisson": 0.2, "plane": "strain"},
    ],
    "loads": [{"body": 1, "force": [10.0, 0.0], "at": [-4, 2.5], "rate": [0.0, 1.0]}],
}


def with_change(edit):
    data = copy.deepcopy(SCENE)
    edit(data)
    return data


def test_round_trip(tmp_path):
    path = tmp_path / "mixed.json"
    path.write_text(json.dumps(SCENE))
    scene, steps = load_scene(path)
    assert steps == 3
    assert scene.name == "mixed"
    assert scene.n_bodies == 4
    assert np.asarray(scene.model.kind).tolist() == [POLYGON, DISK, RING, POLYGON]
    assert np.asarray(scene.model.fixed).tolist() == [True, False, False, False]
    assert np.asarray(scene.model.gravity_scale).tolist() == [1.0, 1.0, 1.0, 0.0]
    mat = {m: k for k, m in enumerate(scene.materials)}
    friction = np.asarray(scene.params.friction)
    assert friction[mat["rock"], mat["rock"]] == 0.5
    assert friction[mat["steel"], mat["steel"]] == 0.3
    assert friction[mat["rock"], mat["steel"]] == friction[mat["steel"], mat["rock"]] == 0.4
    assert np.asarray(scene.params.restitution)[mat["rock"], mat["steel"]] == 0.1
    assert float(scene.params.dt) == 0.001 and float(scene.params.tol) == 1e-10
    np.testing.assert_allclose(np.asarray(scene.state.velocity)[1, :3], [1.0, 0.0, 0.5])
    np.testing.assert_allclose(np.asarray(scene.model.inner_radius)[2], 0.5)
    assert np.asarray(scene.params.cohesion)[mat["rock"], mat["rock"]] == 100.0
    assert np.asarray(scene.params.tensile)[mat["rock"], mat["rock"]] == 50.0
    assert np.asarray(scene.params.rolling)[mat["steel"], mat["steel"]] == 0.01
    assert float(scene.params.young[3]) == 1e9 and bool(scene.model.plane_strain[3])
    np.testing.assert_allclose(np.asarray(scene.model.load_point), [[0.0, 1.0]])
    np.testing.assert_allclose(np.asarray(scene.params.load_rate), [[0.0, 1.0]])


MESHED = {
    "dt": 0.01,
    "bodies": [{"type": "polygon", "vertices": [[0, 3], [1, 3], [1, 4], [0, 4]], "density": 1, "fixed": True}],
    "meshes": [{"nodes": [[0, 0], [1, 0], [1, 1], [0, 1]], "triangles": [[0, 1, 2], [0, 2, 3]], "density": 2000,
                "young": 1e9, "poisson": 0.2, "fixed_nodes": [0, 1]},
               {"vertices": [[3, 0], [5, 0], [5, 1], [3, 1]], "max_edge": 1.2, "density": 2000, "young": 1e8}],
    "loads": [{"body": {"mesh": 0, "node": 2}, "force": [5.0, 0.0]}],
    "connectors": [{"type": "spring", "body_a": 0, "body_b": {"mesh": 0, "node": 3}, "at_a": [0, 3],
                    "stiffness": 1e5}],
}


def test_meshes_and_their_nodes(tmp_path):
    path = tmp_path / "meshed.json"
    path.write_text(json.dumps(MESHED))
    scene, _ = load_scene(path)
    mesh = np.asarray(scene.model.mesh)
    assert mesh[0] == -1 and (mesh[1:3] == 0).all() and (mesh[3:] == 1).all()
    assert np.asarray(scene.model.fixed).tolist()[:3] == [True, False, False]
    # the load at node 2 acts on an element holding it, at the node
    body = int(scene.model.load_body[0])
    np.testing.assert_allclose(np.asarray(scene.state.origin)[body] + np.asarray(scene.model.load_point)[0], [1, 1])
    b = int(scene.model.connector_b[0])
    np.testing.assert_allclose(np.asarray(scene.state.origin)[b] + np.asarray(scene.model.connector_pb)[0], [0, 1])
    assert "element 0 of mesh 1" in " ".join(scene.labels)


@pytest.mark.parametrize("edit, expected", [
    (lambda d: d["meshes"][0].update(nodez=1), "mesh 0: unknown field 'nodez'"),
    (lambda d: d["meshes"][0].pop("young"), "mesh 0: missing field 'young'"),
    (lambda d: d["meshes"][0].pop("triangles"), "mesh 0: fields 'nodes' and 'triangles' go together"),
    (lambda d: d["meshes"][1].update(nodes=[[0, 0]]), "mesh 1: give either 'nodes' and 'triangles' or"),
    (lambda d: d["meshes"][0].update(triangles=[[0, 2, 1], [0, 2, 3]]), "mesh 0: triangle 0 [0, 2, 1] is inverted"),
    (lambda d: d["meshes"][0].update(fixed="yes"), "mesh 0: field 'fixed' must be true or false"),
    (lambda d: d["meshes"][0].update(density="1"), "mesh 0: field 'density' must be a number"),
    (lambda d: d["loads"][0].update(body={"mesh": 4, "node": 0}), "load 0: field 'body' names mesh 4"),
    (lambda d: d["loads"][0].update(body={"mesh": 0, "node": 9}), "load 0: field 'body' names node 9"),
    (lambda d: d["loads"][0].update(body={"mesh": 0}), "load 0: field 'body': missing field 'node'"),
    (lambda d: d["connectors"][0].update(body_b={"mesh": 0, "nod": 1}), "connector 0 (spring): field 'body_b': unknown"),
])
def test_mesh_errors_name_where(edit, expected):
    data = copy.deepcopy(MESHED)
    edit(data)
    with pytest.raises(SceneError) as err:
        scene_from_dict(data)
    assert expected in str(err.value)


def test_defaults_and_name_from_file(tmp_path):
    path = tmp_path / "tiny.json"
    path.write_text(json.dumps({"dt": 0.01, "bodies": [{"type": "disk", "center": [0, 0], "radius": 1,
                                                        "density": 1}]}))
    scene, steps = load_scene(path)
    assert steps is None and scene.name == "tiny"
    np.testing.assert_allclose(np.asarray(scene.params.gravity), [0.0, -9.81])


@pytest.mark.parametrize("edit, expected", [
    (lambda d: d.update(gravty=[0, -1]), "scene file: unknown key 'gravty' (did you mean 'gravity'?"),
    (lambda d: d.pop("dt"), "missing key 'dt'"),
    (lambda d: d.update(steps=2.5), "field 'steps' must be a positive integer"),
    (lambda d: d["bodies"][3].update(radious=1), "body 3 (polygon): unknown field 'radious'"),
    (lambda d: d["bodies"][1].pop("radius"), "body 1 (disk): missing field 'radius'"),
    (lambda d: d["bodies"][3].pop("density"), "body 3 (polygon): missing field 'density'"),
    (lambda d: d["bodies"][2].pop("inner_radius"), "body 2 (ring): missing field 'inner_radius'"),
    (lambda d: d["bodies"][2].update(type="circle"), "body 2: unknown type 'circle'"),
    (lambda d: d["bodies"][2].pop("type"), "body 2: missing field 'type'"),
    (lambda d: d["bodies"][1].update(fixed="false"), "body 1 (disk): field 'fixed' must be true or false"),
    (lambda d: d["bodies"][1].update(material=["rock"]), "body 1 (disk): field 'material' must be"),
    (lambda d: d["bodies"][1].update(material="wood"), "body 1 (disk): field 'material' names unknown material"),
    (lambda d: d["bodies"][1].update(radius=-1), "body 1 (disk): field 'radius' must be > 0"),
    (lambda d: d["bodies"][2].update(inner_radius=2), "body 2 (ring): field 'inner_radius'"),
    (lambda d: d["bodies"][3].update(vertices=[[0, 0], [1, 1]]), "body 3 (polygon): field 'vertices'"),
    (lambda d: d["bodies"][1].update(center=[0, 0.5]), "body 1 (disk)"),  # overlaps the floor
    (lambda d: d["bodies"].__setitem__(1, 7), "body 1 must be an object"),
    (lambda d: d["materials"]["rock"].update(frction=1), "material 'rock': unknown field 'frction'"),
    (lambda d: d["materials"]["rock"].update(friction="0.5"), "material 'rock': field 'friction' must be a number"),
    (lambda d: d["materials"]["rock"].update(restitution=2), "material 'rock': field 'restitution'"),
    (lambda d: d["interfaces"][0].update(mu=1), "interface 0: unknown field 'mu'"),
    (lambda d: d["interfaces"][0].pop("materials"), "interface 0: missing field 'materials'"),
    (lambda d: d["interfaces"][0].update(materials=["rock"]), "interface 0: field 'materials'"),
    (lambda d: d["interfaces"][0].update(materials=["rock", "wood"]), "unknown material 'wood'"),
    (lambda d: d["solver"].update(tolerance=1), "solver: unknown field 'tolerance'"),
    (lambda d: d["solver"].update(margin="x"), "solver: field 'margin' must be a number or null"),
    (lambda d: d["interfaces"][0].update(restitution=True), "interface 0: field 'restitution' must be a number"),
    (lambda d: d.update(dt=0), "field 'dt' must be > 0"),
    (lambda d: d.update(bodies=[], loads=[]), "no bodies"),
    (lambda d: d["materials"]["rock"].update(cohesion=-1), "material 'rock': field 'cohesion' must be >= 0"),
    (lambda d: d["bodies"][3].update(poisson=0.5), "body 3 (polygon): field 'poisson'"),
    (lambda d: d["bodies"][3].update(young=0), "body 3 (polygon): field 'young' must be > 0"),
    (lambda d: d["loads"][0].update(point=[0, 0]), "load 0: unknown field 'point'"),
    (lambda d: d["loads"][0].update(body=9), "load 0: field 'body'"),
    (lambda d: d["loads"][0].pop("force"), "load 0: missing field 'force'"),
])
def test_errors_name_where(edit, expected):
    with pytest.raises(SceneError) as err:
        scene_from_dict(with_change(edit))
    assert expected in str(err.value)
    assert str(err.value).startswith("scene file: ")


def test_file_errors(tmp_path):
    with pytest.raises(SceneError, match="no such scene file"):
        load_scene(tmp_path / "absent.json")
    bad = tmp_path / "bad.json"
    bad.write_text('{"dt": 0.001,\n "bodies": [}\n')
    with pytest.raises(SceneError, match=r"bad\.json: invalid JSON at line 2, column 13"):
        load_scene(bad)
    odd = tmp_path / "odd.json"
    odd.write_text(json.dumps(with_change(lambda d: d["bodies"][0].update(densty=1))))
    with pytest.raises(SceneError, match=r"odd\.json: body 0 \(polygon\): unknown field 'densty'"):
        load_scene(odd)
    with pytest.raises(SceneError, match="the scene must be an object"):
        scene_from_dict([1, 2])
