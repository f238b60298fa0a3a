"""ntdda (DDA for Windows) import: the sample files in tests/data/ntdda follow the readers
of github.com/doolin/ntdda (see tests/data/ntdda/README.md). Dict-level checks only; no
simulation, no JAX compilation."""
import math
from pathlib import Path

import numpy as np
import pytest

from jaxdda.errors import SceneError
from jaxdda.scene.ntdda import read_ntdda

pytestmark = pytest.mark.smoke  # the whole module is cheap: `pytest -m smoke`

DATA = Path(__file__).parent / "data" / "ntdda"


def area(vertices):
    v = np.asarray(vertices, float)
    return 0.5 * float(np.sum(v[:, 0] * np.roll(v[:, 1], -1) - np.roll(v[:, 0], -1) * v[:, 1]))


def inside(vertices, p):
    v, (x, y), odd = np.asarray(vertices, float), p, False
    for a, b in zip(v, np.roll(v, -1, axis=0)):
        if (a[1] > y) != (b[1] > y) and x < a[0] + (y - a[1]) * (b[0] - a[0]) / (b[1] - a[1]):
            odd = not odd
    return odd


def edge_joint(body, p, q):
    """The joint name of the body's edge from p to q (either direction)."""
    v = np.asarray(body["vertices"], float)
    p, q = np.asarray(p, float), np.asarray(q, float)
    for k in range(len(v)):
        a, b = v[k], v[(k + 1) % len(v)]
        if (np.allclose(a, p) and np.allclose(b, q)) or (np.allclose(a, q) and np.allclose(b, p)):
            return body["joints"][k]
    raise AssertionError(f"no edge {p}-{q} in {v}")


@pytest.fixture(scope="module")
def square():
    return read_ntdda(DATA / "square.geo", DATA / "square.ana")


def test_square_cut_by_its_diagonal_gives_two_half_triangles(square):
    bodies = square["bodies"]
    assert len(bodies) == 2
    assert [b["type"] for b in bodies] == ["polygon", "polygon"]
    assert all(len(b["vertices"]) == 3 for b in bodies)
    assert [area(b["vertices"]) for b in bodies] == pytest.approx([0.5, 0.5])  # counter-clockwise, half each
    assert not any(b["fixed"] for b in bodies)


def test_square_joint_names_on_the_right_edges(square):
    lower = next(b for b in square["bodies"] if inside(b["vertices"], (0.9, 0.1)))
    upper = next(b for b in square["bodies"] if inside(b["vertices"], (0.1, 0.9)))
    assert edge_joint(lower, (0, 0), (1, 0)) == "joint1"
    assert edge_joint(lower, (1, 0), (1, 1)) == "joint1"
    assert edge_joint(lower, (1, 1), (0, 0)) == "joint2"  # the diagonal
    assert edge_joint(upper, (0, 0), (1, 1)) == "joint2"
    assert edge_joint(upper, (0, 1), (0, 0)) == "joint1"


def test_square_points_and_bolt_belong_to_the_blocks_holding_them(square):
    bodies = square["bodies"]
    lower = next(i for i, b in enumerate(bodies) if inside(b["vertices"], (0.9, 0.1)))
    upper = 1 - lower
    fixed = square["fixed_points"]
    # the point, then the fixed line y = 0.5 from x = 0.25 to 0.75 crosses the diagonal at
    # (0.5, 0.5): one point on each side, moved 0.005 w0 into its block (w0 = 0.51 * 1.02)
    assert fixed[0] == {"body": lower, "at": [0.9, 0.1]}
    assert len(fixed) == 3
    shift = 0.005 * 1.02 * 0.51
    by_body = {f["body"]: f["at"] for f in fixed[1:]}
    assert set(by_body) == {lower, upper}
    np.testing.assert_allclose(by_body[lower], [0.5 + shift / math.sqrt(2), 0.5 - shift / math.sqrt(2)], atol=1e-12)
    np.testing.assert_allclose(by_body[upper], [0.5 - shift / math.sqrt(2), 0.5 + shift / math.sqrt(2)], atol=1e-12)
    for f in fixed:
        assert inside(bodies[f["body"]]["vertices"], f["at"])
    assert square["loads"] == [{"body": upper, "at": [0.2, 0.8],
                                "history": [[0.0, 0.0, -100.0], [0.5, 10.0, -100.0], [1.0, 20.0, -100.0]]}]
    assert [p["body"] for p in square["measured_points"]] == [upper, lower]
    assert square["connectors"] == [{"type": "spring", "body_a": lower, "body_b": upper, "at_a": [0.8, 0.3],
                                     "at_b": [0.3, 0.8], "stiffness": 1e6, "pretension": 2000.0}]


def test_square_materials_settings_and_conversions(square):
    bodies = square["bodies"]
    upper = next(b for b in bodies if inside(b["vertices"], (0.1, 0.9)))
    lower = next(b for b in bodies if inside(b["vertices"], (0.9, 0.1)))
    assert upper["material"] == "material2"  # the material line lies inside it (dc13)
    assert lower["material"] == "material1"  # the default
    assert square["name"] == "square"
    settings = square["settings"]
    assert settings["dt"] == 0.01 and settings["steps"] == 100 and settings["dynamic"] == 1.0
    np.testing.assert_allclose(settings["gravity"], [0.0, -9.81])  # unit weight / unit mass
    assert square["materials"] == {"material1": {"density": 2600.0, "young": 5e9, "poisson": 0.25, "restitution": 0.0},
                                   "material2": {"density": 1000.0, "young": 1e9, "poisson": 0.3, "restitution": 0.0}}
    assert upper["stress"] == [-1000.0, -2000.0, 0.0]
    assert "stress" not in lower and "velocity" not in upper and "angular_velocity" not in upper
    joints = square["joints"]
    assert joints["joint1"] == {"friction": pytest.approx(math.tan(math.radians(30))), "cohesion": 0.0,
                                "tensile": 0.0, "restitution": 0.0}
    # cohesion 100 (stress) x the diagonal interface's length sqrt(2); tensile ignored as ntdda does
    assert joints["joint2"]["friction"] == pytest.approx(1.0)
    assert joints["joint2"]["cohesion"] == pytest.approx(100 * math.sqrt(2))
    assert joints["joint2"]["tensile"] == 0.0
    with_tension = read_ntdda(DATA / "square.geo", DATA / "square.ana", tensile=True)
    assert with_tension["joints"]["joint2"]["tensile"] == pytest.approx(50 * math.sqrt(2))


def test_initial_velocity_and_ignored_fields(tmp_path):
    ana = tmp_path / "moving.ana"
    ana.write_text((DATA / "square.ana").read_text()
                   .replace("<Ivelocity> 0 0 0 </Ivelocity>\n    <Istrain> 0 0 0 </Istrain>\n  </Blockmaterial>\n"
                            "  <Jointproperties",
                            "<Ivelocity> 0.5 0 0.1 </Ivelocity>\n    <Istrain> 0 0 0 </Istrain>\n  </Blockmaterial>\n"
                            "  <Jointproperties")
                   .replace("<Damping>0.0</Damping>", "<Damping>0.2</Damping>", 1))
    with pytest.warns(UserWarning, match=r"moving.ana, line \d+: <Blockmaterial>: damping 0.2 is not imported"):
        scene = read_ntdda(DATA / "square.geo", ana)
    upper = next(b for b in scene["bodies"] if inside(b["vertices"], (0.1, 0.9)))
    assert upper["velocity"] == [0.5, 0.0] and upper["angular_velocity"] == 0.1


def test_geometry_only(square):
    geo = read_ntdda(DATA / "square.geo")
    assert "settings" not in geo and geo["materials"] == {} and geo["joints"] == {}
    assert [b["vertices"] for b in geo["bodies"]] == [b["vertices"] for b in square["bodies"]]
    assert "stiffness" not in geo["connectors"][0] and "history" not in geo["loads"][0]


def test_plain_format_pushblock():
    scene = read_ntdda(DATA / "pushblock.geo", DATA / "pushblock.ana")
    bodies = scene["bodies"]
    # base 40 x 10 cut at x = 30 and 40, the block [40, 50] removed by the hole point,
    # and the 5 x 5 block on top
    assert len(bodies) == 3
    assert sorted(area(b["vertices"]) for b in bodies) == pytest.approx([25.0, 100.0, 200.0])
    assert sum(area(b["vertices"]) for b in bodies) == pytest.approx(400 - 100 + 25)
    top = next(b for b in bodies if inside(b["vertices"], (17.5, 22.5)))
    assert top["material"] == "material2"
    assert edge_joint(top, (20, 20), (15, 20)) == "joint1"  # lies on the base's top line
    assert edge_joint(top, (20, 25), (15, 25)) == "joint2"
    assert all(b["material"] == "material1" for b in bodies if b is not top)
    assert scene["settings"] == {"dt": 0.005, "steps": 200, "gravity": [0.0, pytest.approx(-9.81)], "dynamic": 1.0}
    assert scene["materials"]["material2"] == {"density": 9.0, "young": 1e6, "poisson": 0.3, "restitution": 0.0}
    assert scene["joints"]["joint1"]["friction"] == pytest.approx(math.tan(math.radians(35)))
    # joint2's edges (the top block's sides and top) meet no other block at t = 0, so its
    # cohesion 10 is taken times their mean length, 5
    assert scene["joints"]["joint2"]["cohesion"] == pytest.approx(10 * 5)
    # the fixed line y = 12 from x = 12 to 48 crosses x = 30 (both blocks) and x = 40
    w0 = 1.02 * (50.01 - 9.98) / 2 / 1.3
    fixed = sorted(f["at"][0] for f in scene["fixed_points"])
    np.testing.assert_allclose(fixed, [30 - 0.005 * w0, 30 + 0.005 * w0, 40 - 0.005 * w0])
    [measured] = scene["measured_points"]
    assert bodies[measured["body"]] is top


def test_errors_name_file_line_and_field(tmp_path):
    text = (DATA / "square.geo").read_text()
    bad = tmp_path / "bad.geo"
    bad.write_text(text.replace("<Point> 0.2 0.8 </Point>", "<Point> 2.0 0.8 </Point>"))
    with pytest.raises(SceneError, match=r"bad.geo, line 2\d: <Point>: the load point \[2.0, 0.8\] lies in no block"):
        read_ntdda(bad)
    bad.write_text(text.replace("<Joint type=\"2\"> -0.01 -0.01 1.01 1.01 </Joint>",
                                "<Joint type=\"2\"> -0.01 -0.01 1.01 </Joint>"))
    with pytest.raises(SceneError, match=r"bad.geo, line 1\d: <Joint>: a joint \(x1 y1 x2 y2\) needs 4 numbers, got 3"):
        read_ntdda(bad)
    bad.write_text(text.replace("type=\"2\"> -0.01 -0.01", "type=\"3\"> -0.01 -0.01"))
    with pytest.raises(SceneError, match=r"<Joint>: joint type 3 is not defined in .*square.ana"):
        read_ntdda(bad, DATA / "square.ana")
    plain = tmp_path / "bad_plain.geo"
    plain.write_text((DATA / "pushblock.geo").read_text().replace("50 20.01 50 9.98 1", "50 20.01 5O 9.98 1"))
    with pytest.raises(SceneError, match=r"bad_plain.geo, line 11: field 'x2' of joint 3 must be a number, got '5O'"):
        read_ntdda(plain)
    ana = tmp_path / "bad.ana"
    ana.write_text((DATA / "square.ana").read_text().replace("<Unitweight> 9810 </Unitweight>",
                                                             "<Unitweight> 5000 </Unitweight>"))
    with pytest.raises(SceneError, match=r"bad.ana, line \d+: <Blockmaterial>: unit weight / unit mass"):
        read_ntdda(DATA / "square.geo", ana)


@pytest.mark.parametrize("name, bodies, steps", [("square", 2, 100), ("pushblock", 3, 200)])
def test_imported_dict_builds(name, bodies, steps):
    """The dict is a scene description scene_from_dict builds (no simulation)."""
    from jaxdda.scene.loader import scene_from_dict

    scene, n = scene_from_dict(read_ntdda(DATA / f"{name}.geo", DATA / f"{name}.ana"))
    assert (scene.model.n_bodies, n) == (bodies, steps)
