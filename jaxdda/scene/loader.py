"""Scene files: ``load_scene(path)`` reads TOML (standard library ``tomllib``) or JSON,
``scene_from_dict(data)`` builds already-parsed data. Both give ``(scene, steps)``.

The format is described in docs/scene-format.md; ``scene.io.save_scene`` writes it. The
loader checks the structure (known keys, required fields, types the builder cannot
check), resolves names (materials, joints) and points (the body a point lies in), and
hands every value to SceneBuilder, which validates it. Every error is a SceneError that
names the file and the key path, e.g. ``run.toml: bodies[3].radious: unknown key``.
"""
from __future__ import annotations

import difflib
import json
import tomllib
from pathlib import Path
from typing import Any

import numpy as np

from jaxdda.errors import SceneError
from jaxdda.scene import cutting
from jaxdda.scene.builder import CONTACT_LAW, Scene, SceneBuilder

TOP_KEYS = ("name", "settings", "materials", "joints", "interfaces", "bodies", "meshes", "rock_masses",
            "fixed_points", "loads", "measured_points", "connectors")
SETTINGS_KEYS = ("dt", "steps", "gravity", "tol", "max_iter", "margin", "dynamic", "capacities")
CAPACITY_KEYS = ("candidates", "pairs_pp", "pairs_pb", "pairs_bb", "contacts")
ELASTIC_KEYS = ("density", "young", "poisson", "plane")  # what a material gives its bodies
MATERIAL_KEYS = ELASTIC_KEYS + tuple(CONTACT_LAW)
JOINT_KEYS = tuple(CONTACT_LAW)
INTERFACE_KEYS = ("materials",) + JOINT_KEYS
MOTION_KEYS = ("velocity", "angular_velocity", "fixed", "material", "gravity", "stress") + ELASTIC_KEYS

# type -> (SceneBuilder method, required fields, optional fields beyond MOTION_KEYS)
BODY_TYPES = {
    "disk": ("add_disk", ("center", "radius"), ()),
    "ring": ("add_ring", ("center", "inner_radius", "outer_radius"), ()),
    "polygon": ("add_polygon", ("vertices",), ("joints",)),
    "mesh": ("add_mesh", (), ("nodes", "triangles", "vertices", "max_edge", "fixed_nodes")),
}
CONNECTOR_ENDS = ("body_a", "body_b", "at_a", "at_b")
CONNECTOR_TYPES = {
    "spring": ("add_spring", ("stiffness",), ("rest_length", "pretension")),
    "bolt": ("add_bolt", ("young", "area"), ("pretension",)),
    "beam": ("add_beam", ("young", "area", "inertia"), ("shear_modulus", "section")),
}
POINT_KEYS = ("body", "at")
LOAD_KEYS = POINT_KEYS + ("force", "rate", "history")
ROCK_KEYS = ("boundary", "lines", "joint_sets", "material", "regions", "material_lines", "holes", "min_area",
             "velocity", "gravity", "stress", "joint")
LINE_KEYS = ("from", "to", "joint")
JOINT_SET_KEYS = ("dip", "spacing", "trace", "bridge", "stagger", "offset", "joint")
REGION_KEYS = ("polygon", "material", "fixed")
MATERIAL_LINE_KEYS = ("from", "to", "material")
NUMBER_FIELDS = {"radius", "inner_radius", "outer_radius", "density", "young", "poisson", "angular_velocity",
                 "max_edge", "stiffness", "rest_length", "pretension", "area", "inertia", "shear_modulus",
                 "dt", "tol", "max_iter", "margin", "dynamic", "dip", "spacing", "trace", "bridge", "stagger",
                 "offset", "min_area", *CONTACT_LAW}
BOOLEAN_FIELDS = {"fixed", "gravity"}
STRING_FIELDS = {"material", "joint", "plane", "section", "name", "type"}


def load_scene(path) -> tuple[Scene, int | None]:
    """Read a ``.toml`` or ``.json`` scene file: the scene, and its settings' ``steps``
    (None if absent). The scene's name defaults to the file name without its extension."""
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8")
    except FileNotFoundError:
        raise SceneError(f"{path}: no such scene file") from None
    except (OSError, UnicodeDecodeError) as err:
        raise SceneError(f"{path}: cannot read the scene file ({getattr(err, 'strerror', None) or err})") from None
    if path.suffix.lower() == ".json":
        try:
            data = json.loads(text)
        except json.JSONDecodeError as err:
            raise SceneError(f"{path}: invalid JSON at line {err.lineno}, column {err.colno}: {err.msg}") from None
    else:
        try:
            data = tomllib.loads(text)
        except tomllib.TOMLDecodeError as err:
            raise SceneError(f"{path}: invalid TOML: {err}") from None
    if isinstance(data, dict) and "name" not in data:
        data = {**data, "name": path.stem}
    return scene_from_dict(data, source=str(path))


def scene_from_dict(data: Any, source: str = "scene file") -> tuple[Scene, int | None]:
    """Build the scene described by ``data`` (a parsed scene file): the scene and its steps."""
    try:
        return _Reader(data).build()
    except SceneError as err:
        raise SceneError(f"{source}: {err}") from None


# ------------------------------------------------------------------------------- internals
def _show(value) -> str:
    text = json.dumps(value, default=repr)
    return text if len(text) <= 60 else text[:57] + "..."


def _check_keys(path: str, obj: Any, known, required=(), booleans=BOOLEAN_FIELDS) -> dict:
    """``obj`` must be a table with only ``known`` keys and every ``required`` one; scalar
    fields must have their type. Returns obj."""
    if not isinstance(obj, dict):
        raise SceneError(f"{path or 'the scene'}: must be a table (an object), got {_show(obj)}")
    for key in obj:
        if key not in known:
            close = difflib.get_close_matches(str(key), known, n=1)
            hint = f"did you mean '{close[0]}'? " if close else ""
            raise SceneError(f"{_join(path, key)}: unknown key ({hint}known: {', '.join(known)})")
    for key in required:
        if key not in obj:
            raise SceneError(f"{_join(path, key)}: missing (required in {path or 'the scene'})")
    for key, value in obj.items():
        where = _join(path, key)
        if key in NUMBER_FIELDS and value is not None and (isinstance(value, bool) or not isinstance(value, (int, float))):
            raise SceneError(f"{where}: must be a number, got {_show(value)}")
        if key in booleans and not isinstance(value, bool):
            raise SceneError(f"{where}: must be true or false, got {_show(value)}")
        if key in STRING_FIELDS and not isinstance(value, str):
            raise SceneError(f"{where}: must be a string, got {_show(value)}")
    return obj


def _join(path: str, key) -> str:
    return f"{path}.{key}" if path else str(key)


def _list(path: str, value: Any) -> list:
    if not isinstance(value, list):
        raise SceneError(f"{path}: must be a list (an array), got {_show(value)}")
    return value


def _typed(path: str, obj: Any, types: dict):
    """``obj``'s "type" and its entry in ``types`` (an error naming the path if either is
    missing or unknown)."""
    if not isinstance(obj, dict):
        raise SceneError(f"{path}: must be a table (an object), got {_show(obj)}")
    kind = obj.get("type")
    if not isinstance(kind, str) or kind not in types:
        what = "missing" if kind is None else f"unknown type {_show(kind)}"
        raise SceneError(f"{path}.type: {what} (known: {', '.join(types)})")
    return kind, types[kind]


def _call(path: str, fn, *args, **kwargs):
    """Call a builder method; its errors (and a stray TypeError/ValueError from a badly
    typed value) are reported under the key path."""
    try:
        return fn(*args, **kwargs)
    except SceneError as err:
        message = str(err)  # a builder message that starts with the path already ("scene: ...") keeps one
        raise SceneError(message if message.startswith(f"{path}: ") else f"{path}: {message}") from None
    except (TypeError, ValueError) as err:
        raise SceneError(f"{path}: invalid value ({err})") from None


class _Reader:
    def __init__(self, data: Any):
        self.data = _check_keys("", data, TOP_KEYS)
        self.block_materials: dict[str, dict] = {}
        self.meshes: list = []

    def build(self) -> tuple[Scene, int | None]:
        data = self.data
        if "settings" not in data:
            raise SceneError("settings: missing (a scene file needs at least settings.dt)")
        settings = _check_keys("settings", data["settings"], SETTINGS_KEYS, ("dt",), booleans=())
        steps = settings.get("steps")
        if steps is not None and (not isinstance(steps, int) or isinstance(steps, bool) or steps < 1):
            raise SceneError(f"settings.steps: must be a positive integer, got {_show(steps)}")
        name = data.get("name", "scene")
        if not isinstance(name, str):
            raise SceneError(f"name: must be a string, got {_show(name)}")
        options = {k: settings[k] for k in ("tol", "max_iter", "margin", "dynamic") if k in settings}
        if "capacities" in settings:
            caps = _check_keys("settings.capacities", settings["capacities"], CAPACITY_KEYS)
            for key, value in caps.items():
                if isinstance(value, bool) or not isinstance(value, int) or value < 1:
                    raise SceneError(f"settings.capacities.{key}: must be a positive integer, got {_show(value)}")
            options["capacities"] = caps
        self.sb = sb = _call("settings", SceneBuilder, settings["dt"], settings.get("gravity", (0.0, -9.81)),
                             name=name, **options)
        _call("settings", sb._check_settings)

        materials = data.get("materials", {})
        if not isinstance(materials, dict):
            raise SceneError(f"materials: must be a table (name -> material), got {_show(materials)}")
        for mat, fields in materials.items():
            path = f"materials.{mat}"
            _check_keys(path, fields, MATERIAL_KEYS)
            self.block_materials[mat] = {k: v for k, v in fields.items() if k in ELASTIC_KEYS}
            _call(path, sb.add_material, mat, **{k: v for k, v in fields.items() if k in CONTACT_LAW})
        joints = data.get("joints", {})
        if not isinstance(joints, dict):
            raise SceneError(f"joints: must be a table (name -> joint properties), got {_show(joints)}")
        for joint, fields in joints.items():
            path = f"joints.{joint}"
            if joint in materials:
                raise SceneError(f"{path}: the name is also a material's (materials and joints share one namespace)")
            _check_keys(path, fields, JOINT_KEYS)
            _call(path, sb.add_material, joint, **fields)
        for k, law in enumerate(_list("interfaces", data.get("interfaces", []))):
            path = f"interfaces[{k}]"
            _check_keys(path, law, INTERFACE_KEYS, ("materials",))
            pair = law["materials"]
            if not (isinstance(pair, list) and len(pair) == 2 and all(isinstance(m, str) for m in pair)):
                raise SceneError(f"{path}.materials: must be a list of two material or joint names, got {_show(pair)}")
            _call(path, sb.set_interface, *pair, **{key: v for key, v in law.items() if key != "materials"})

        for i, body in enumerate(_list("bodies", data.get("bodies", []))):
            self._body(f"bodies[{i}]", body)
        for m, mesh in enumerate(_list("meshes", data.get("meshes", []))):
            self._body(f"meshes[{m}]", {"type": "mesh", **mesh} if isinstance(mesh, dict) else mesh)
        for r, mass in enumerate(_list("rock_masses", data.get("rock_masses", []))):
            self._rock_mass(f"rock_masses[{r}]", mass)

        for k, point in enumerate(_list("fixed_points", data.get("fixed_points", []))):
            path = f"fixed_points[{k}]"
            _check_keys(path, point, POINT_KEYS, () if isinstance(point, dict) and isinstance(point.get("body"), dict)
                        else ("at",))
            body, at = self._end(path, "body", point.get("body"), point.get("at"))
            _call(path, sb.add_fixed_point, body, at)
        for k, load in enumerate(_list("loads", data.get("loads", []))):
            path = f"loads[{k}]"
            _check_keys(path, load, LOAD_KEYS, ("body",) if "at" not in load else ())
            body, at = self._end(path, "body", load.get("body"), load.get("at"))
            _call(path, sb.add_load, body, **{f: load[f] for f in ("force", "rate", "history") if f in load}, at=at)
        for k, point in enumerate(_list("measured_points", data.get("measured_points", []))):
            path = f"measured_points[{k}]"
            _check_keys(path, point, POINT_KEYS, ("body",) if "at" not in point else ())
            body, at = self._end(path, "body", point.get("body"), point.get("at"))
            _call(path, sb.add_measured_point, body, at)
        for k, conn in enumerate(_list("connectors", data.get("connectors", []))):
            self._connector(f"connectors[{k}]", conn)
        return _call("scene", sb.build), steps

    # -- bodies ----------------------------------------------------------------------
    def _elastic(self, path: str, fields: dict) -> dict:
        """A body's density, young, poisson, plane: its own, else its material's."""
        mat = fields.get("material")
        if mat is not None and mat not in self.block_materials and mat not in self.sb._materials:
            raise SceneError(f"{path}.material: unknown material {mat!r} (known: {', '.join(self.sb._materials)})")
        given = {**self.block_materials.get(mat, {}), **{k: fields[k] for k in ELASTIC_KEYS if k in fields}}
        if "density" not in given:
            source = f" (nor does material '{mat}')" if mat else ""
            raise SceneError(f"{path}.density: missing: the body gives no density{source}")
        return given

    def _body(self, path: str, body: Any) -> None:
        kind, (method, required, optional) = _typed(path, body, BODY_TYPES)
        _check_keys(path, body, ("type",) + required + optional + MOTION_KEYS, required)
        fields = {k: v for k, v in body.items() if k != "type" and k not in ELASTIC_KEYS}
        fields.update(self._elastic(path, body))
        if kind == "polygon" and "joints" in fields:
            fields["edge_materials"] = self._edge_joints(f"{path}.joints", fields.pop("joints"))
        if kind != "mesh":
            _call(path, getattr(self.sb, method), **fields)
            return
        given = [k for k in ("nodes", "vertices") if k in fields]
        if len(given) != 1:
            raise SceneError(f"{path}: give either 'nodes' and 'triangles' or a polygon's 'vertices'")
        if ("triangles" in fields) != ("nodes" in fields):
            raise SceneError(f"{path}: keys 'nodes' and 'triangles' go together")
        if "max_edge" in fields and "vertices" not in fields:
            raise SceneError(f"{path}.max_edge: is for the built-in mesher (with 'vertices')")
        if "young" not in fields:
            raise SceneError(f"{path}.young: missing: a meshed block is deformable")
        if "vertices" in fields:
            self.meshes.append(_call(path, self.sb.add_meshed_polygon, **fields))
        else:
            self.meshes.append(_call(path, self.sb.add_mesh, **fields))

    def _edge_joints(self, path: str, names: Any) -> list:
        names = _list(path, names)
        for k, n in enumerate(names):
            if not isinstance(n, str):
                raise SceneError(f"{path}[{k}]: must be a joint name or \"\" (the body's own law), got {_show(n)}")
        return [n or None for n in names]

    def _joint(self, path: str, name: Any):
        if name is None:
            return None
        if name not in self.sb._materials:
            raise SceneError(f"{path}: unknown joint {name!r} (known: {', '.join(self.sb._materials)})")
        return name

    def _rock_mass(self, path: str, mass: Any) -> None:
        """A boundary polygon cut by joint lines and sets into blocks (scene.cutting); each
        block edge takes the joint of the line that made it."""
        _check_keys(path, mass, ROCK_KEYS, ("boundary",))
        segments, joints = [], []
        for k, line in enumerate(_list(f"{path}.lines", mass.get("lines", []))):
            where = f"{path}.lines[{k}]"
            _check_keys(where, line, LINE_KEYS, ("from", "to"))
            ends = _call(where, np.asarray, [line["from"], line["to"]], dtype=float)
            if ends.shape != (2, 2) or not np.isfinite(ends).all():
                raise SceneError(f"{where}: fields 'from' and 'to' must be finite (x, y) points, got "
                                 f"{_show(line['from'])} and {_show(line['to'])}")
            if np.array_equal(ends[0], ends[1]):
                raise SceneError(f"{where}: zero length (fields 'from' and 'to' are the same point)")
            segments.append([line["from"], line["to"]])
            joints.append(self._joint(f"{where}.joint", line.get("joint", mass.get("joint"))))
        boundary = _call(f"{path}.boundary", np.asarray, mass["boundary"], dtype=float)
        for k, spec in enumerate(_list(f"{path}.joint_sets", mass.get("joint_sets", []))):
            where = f"{path}.joint_sets[{k}]"
            _check_keys(where, spec, JOINT_SET_KEYS, ("dip", "spacing"))
            joint = self._joint(f"{where}.joint", spec.get("joint", mass.get("joint")))
            lines = _call(where, cutting.JointSet(**{f: v for f, v in spec.items() if f != "joint"}).lines, boundary)
            segments += lines.tolist()
            joints += [joint] * len(lines)
        blocks = _call(path, cutting.cut_blocks, boundary, np.reshape(segments, (-1, 2, 2)),
                       min_area=mass.get("min_area", 0.0))
        keep = list(range(len(blocks)))
        for k, hole in enumerate(_list(f"{path}.holes", mass.get("holes", []))):
            inside = _call(f"{path}.holes[{k}]", cutting.blocks_containing, blocks, hole)
            if not inside:
                raise SceneError(f"{path}.holes[{k}]: the point {_show(hole)} lies in no block")
            keep = [b for b in keep if b not in inside]
        material = {b: mass.get("material") for b in keep}
        fixed = {b: False for b in keep}
        for k, region in enumerate(_list(f"{path}.regions", mass.get("regions", []))):
            where = f"{path}.regions[{k}]"
            _check_keys(where, region, REGION_KEYS, ("polygon",))
            for b in _call(where, cutting.blocks_inside, blocks, region["polygon"]):
                if b in material:
                    material[b] = region.get("material", material[b])
                    fixed[b] = region.get("fixed", fixed[b])
        for k, line in enumerate(_list(f"{path}.material_lines", mass.get("material_lines", []))):
            where = f"{path}.material_lines[{k}]"
            _check_keys(where, line, MATERIAL_LINE_KEYS, ("from", "to", "material"))
            for b in _call(where, cutting.blocks_crossed, blocks, line["from"], line["to"]):
                if b in material:
                    material[b] = line["material"]
        common = {k: mass[k] for k in ("velocity", "gravity", "stress") if k in mass}
        for b in keep:
            fields = {"material": material[b]} if material[b] is not None else {}
            elastic = self._elastic(f"{path} (block {b})", fields)
            edges = [None if line < 0 else joints[line] for line in blocks[b].edge_lines]
            _call(f"{path} (block {b})", self.sb.add_polygon, blocks[b].vertices, fixed=fixed[b],
                  edge_materials=edges, **fields, **elastic, **common)

    # -- points, connectors ------------------------------------------------------------
    def _end(self, path: str, field: str, body: Any, at: Any):
        """The body named by ``field``: an index, {mesh, node}, or (when absent) the body
        that contains the point ``at``; and the point (a node's position by default)."""
        if isinstance(body, dict):
            _check_keys(f"{path}.{field}", body, ("mesh", "node"), ("mesh", "node"))
            m, k = body["mesh"], body["node"]
            if isinstance(m, bool) or not isinstance(m, int) or not 0 <= m < len(self.meshes):
                raise SceneError(f"{path}.{field}.mesh: {_show(m)} is not one of the {len(self.meshes)} meshed blocks")
            mesh = self.meshes[m]
            if isinstance(k, bool) or not isinstance(k, int) or not 0 <= k < len(mesh.nodes):
                raise SceneError(f"{path}.{field}.node: {_show(k)} is not one of mesh {m}'s {len(mesh.nodes)} nodes")
            return int(mesh.holder[k]), (mesh.nodes[k].tolist() if at is None else at)
        if body is None:
            if at is None:
                raise SceneError(f"{path}.{field}: missing: give the body or the point")
            return _call(path, self.sb.body_at, at), at
        return body, at

    def _connector(self, path: str, conn: Any) -> None:
        _, (method, required, optional) = _typed(path, conn, CONNECTOR_TYPES)
        _check_keys(path, conn, ("type",) + CONNECTOR_ENDS + required + optional, required)
        fields = {k: v for k, v in conn.items() if k != "type"}
        for side in ("a", "b"):
            fields[f"body_{side}"], fields[f"at_{side}"] = self._end(path, f"body_{side}", conn.get(f"body_{side}"),
                                                                    conn.get(f"at_{side}"))
            if fields[f"at_{side}"] is None:
                raise SceneError(f"{path}.at_{side}: missing")
        _call(path, getattr(self.sb, method), **fields)
