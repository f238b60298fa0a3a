"""Scenes from JSON files: ``load_scene(path)`` and ``scene_from_dict(data)``.

The format is described in docs/scene-format.md. The loader only checks the structure
(known keys, required fields, JSON types the builder cannot check); every value goes
to SceneBuilder, which validates it. Every error is a SceneError that names its source
and where in it the problem is, e.g. ``run.json: body 3 (disk): unknown field 'radious'``.
"""
from __future__ import annotations

import difflib
import json
from pathlib import Path
from typing import Any

from jaxdda.errors import SceneError
from jaxdda.scene.builder import CONTACT_LAW, Scene, SceneBuilder

TOP_KEYS = ("name", "dt", "gravity", "steps", "solver", "materials", "interfaces", "bodies", "meshes", "loads",
            "connectors")
SOLVER_KEYS = ("tol", "max_iter", "margin", "dynamic")
MATERIAL_KEYS = tuple(CONTACT_LAW)
INTERFACE_KEYS = ("materials",) + MATERIAL_KEYS
LOAD_KEYS = ("body", "force", "at", "rate")

# type -> (SceneBuilder method, required fields); every type also takes BODY_OPTIONAL.
BODY_TYPES = {
    "disk": ("add_disk", ("center", "radius", "density")),
    "ring": ("add_ring", ("center", "inner_radius", "outer_radius", "density")),
    "polygon": ("add_polygon", ("vertices", "density")),
}
BODY_OPTIONAL = ("velocity", "angular_velocity", "fixed", "material", "gravity", "young", "poisson", "plane", "stress")
# type -> (SceneBuilder method, required fields, optional fields); all take the ends below.
CONNECTOR_ENDS = ("body_a", "body_b", "at_a", "at_b")
CONNECTOR_TYPES = {
    "spring": ("add_spring", ("stiffness",), ("rest_length", "pretension")),
    "bolt": ("add_bolt", ("young", "area"), ("pretension",)),
    "beam": ("add_beam", ("young", "area", "inertia"), ("shear_modulus", "section")),
}
BOOLEAN_FIELDS = ("fixed", "gravity")  # bool("false") is True: insist on JSON true/false
# A meshed block: given "nodes" and "triangles", or a polygon's "vertices" for the built-in mesher.
MESH_REQUIRED = ("density", "young")
MESH_OPTIONAL = ("nodes", "triangles", "vertices", "max_edge", "poisson", "plane", "fixed_nodes", "velocity",
                 "angular_velocity", "fixed", "material", "gravity", "stress")


def load_scene(path) -> tuple[Scene, int | None]:
    """Read a JSON scene file: the scene, and the file's "steps" (None if absent).
    The scene's name defaults to the file name without its extension."""
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8")
    except FileNotFoundError:
        raise SceneError(f"{path}: no such scene file") from None
    except (OSError, UnicodeDecodeError) as err:
        raise SceneError(f"{path}: cannot read the scene file ({getattr(err, 'strerror', None) or err})") from None
    try:
        data = json.loads(text)
    except json.JSONDecodeError as err:
        raise SceneError(f"{path}: invalid JSON at line {err.lineno}, column {err.colno}: {err.msg}") from None
    if isinstance(data, dict) and "name" not in data:
        data = {**data, "name": path.stem}
    return scene_from_dict(data, source=str(path))


def scene_from_dict(data: Any, source: str = "scene file") -> tuple[Scene, int | None]:
    """Build the scene described by ``data`` (the parsed JSON): the scene and its "steps"."""
    try:
        return _build(data)
    except SceneError as err:
        raise SceneError(f"{source}: {err}") from None


# ------------------------------------------------------------------------------- internals
def _build(data: Any) -> tuple[Scene, int | None]:
    _expect(data, dict, "the scene", "an object")
    _check_keys("", data, TOP_KEYS, ("dt",), what="key")
    solver = data.get("solver", {})
    _expect(solver, dict, "field 'solver'", "an object")
    _check_keys("solver", solver, SOLVER_KEYS)
    _check_numbers("solver", solver, allow_null=("margin",))
    name = data.get("name", "scene")
    _expect(name, str, "field 'name'", "a string")
    steps = data.get("steps")
    if steps is not None and (not isinstance(steps, int) or isinstance(steps, bool) or steps < 1):
        raise SceneError(f"field 'steps' must be a positive integer, got {steps!r}")

    sb = SceneBuilder(data["dt"], data.get("gravity", (0.0, -9.81)), name=name, **solver)

    materials = data.get("materials", {})
    _expect(materials, dict, "field 'materials'", "an object (name -> {friction, restitution})")
    for mat, law in materials.items():
        where = f"material '{mat}'"
        _expect(law, dict, where, "an object")
        _check_keys(where, law, MATERIAL_KEYS)
        _check_numbers(where, law)
        _call(where, sb.add_material, mat, **law)

    interfaces = data.get("interfaces", [])
    _expect(interfaces, list, "field 'interfaces'", "a list")
    for k, law in enumerate(interfaces):
        where = f"interface {k}"
        _expect(law, dict, where, "an object")
        _check_keys(where, law, INTERFACE_KEYS, ("materials",))
        _check_numbers(where, {key: v for key, v in law.items() if key != "materials"})
        pair = law["materials"]
        if not (isinstance(pair, list) and len(pair) == 2 and all(isinstance(m, str) for m in pair)):
            raise SceneError(f"{where}: field 'materials' must be a list of two material names, got {pair!r}")
        _call(where, sb.set_interface, *pair, **{key: v for key, v in law.items() if key != "materials"})

    bodies = data.get("bodies", [])
    _expect(bodies, list, "field 'bodies'", "a list")
    for i, body in enumerate(bodies):
        _add_body(sb, i, body)

    meshes = data.get("meshes", [])
    _expect(meshes, list, "field 'meshes'", "a list")
    added = [_add_mesh(sb, m, mesh) for m, mesh in enumerate(meshes)]

    loads = data.get("loads", [])
    _expect(loads, list, "field 'loads'", "a list")
    for k, load in enumerate(loads):
        where = f"load {k}"
        _expect(load, dict, where, "an object")
        _check_keys(where, load, LOAD_KEYS, ("body", "force"))
        load = dict(load)
        load["body"], load["at"] = _end(where, "body", load["body"], load.get("at"), added)
        _call(where, sb.add_load, **load)

    connectors = data.get("connectors", [])
    _expect(connectors, list, "field 'connectors'", "a list")
    for k, conn in enumerate(connectors):
        _add_connector(sb, k, conn, added)
    return _call("scene", sb.build), steps


def _add_mesh(sb: SceneBuilder, m: int, mesh: Any):
    where = f"mesh {m}"
    _expect(mesh, dict, where, "an object")
    _check_keys(where, mesh, MESH_REQUIRED + MESH_OPTIONAL, MESH_REQUIRED)
    given = [k for k in ("nodes", "vertices") if k in mesh]
    if len(given) != 1:
        raise SceneError(f"{where}: give either 'nodes' and 'triangles' or a polygon's 'vertices'")
    if ("triangles" in mesh) != ("nodes" in mesh):
        raise SceneError(f"{where}: fields 'nodes' and 'triangles' go together")
    if "max_edge" in mesh and "vertices" not in mesh:
        raise SceneError(f"{where}: field 'max_edge' is for the built-in mesher (with 'vertices')")
    _check_numbers(where, {k: v for k, v in mesh.items() if k in ("density", "young", "poisson", "max_edge",
                                                                 "angular_velocity")}, allow_null=("max_edge",))
    for field in BOOLEAN_FIELDS:
        if field in mesh:
            _expect(mesh[field], bool, f"{where}: field '{field}'", "true or false")
    options = {k: v for k, v in mesh.items() if k not in ("nodes", "triangles", "vertices", "max_edge")}
    if "vertices" in mesh:
        return _call(where, sb.add_meshed_polygon, mesh["vertices"], max_edge=mesh.get("max_edge"), **options)
    return _call(where, sb.add_mesh, mesh["nodes"], mesh["triangles"], **options)


def _end(where: str, field: str, body: Any, at: Any, meshes: list):
    """A body index, or {"mesh": m, "node": k}: the element holding that node, with ``at``
    defaulting to the node's position."""
    if not isinstance(body, dict):
        return body, at
    _check_keys(f"{where}: field '{field}'", body, ("mesh", "node"), ("mesh", "node"))
    m, k = body["mesh"], body["node"]
    if isinstance(m, bool) or not isinstance(m, int) or not 0 <= m < len(meshes):
        raise SceneError(f"{where}: field '{field}' names mesh {m!r}, not one of the {len(meshes)} in 'meshes'")
    mesh = meshes[m]
    if isinstance(k, bool) or not isinstance(k, int) or not 0 <= k < len(mesh.nodes):
        raise SceneError(f"{where}: field '{field}' names node {k!r}, not one of mesh {m}'s {len(mesh.nodes)}")
    return int(mesh.holder[k]), (mesh.nodes[k].tolist() if at is None else at)


def _add_connector(sb: SceneBuilder, k: int, conn: Any, meshes: list) -> None:
    _expect(conn, dict, f"connector {k}", "an object")
    kind = conn.get("type")
    if not isinstance(kind, str) or kind not in CONNECTOR_TYPES:
        raise SceneError(f"connector {k}: {'missing field' if kind is None else 'unknown type'} "
                         f"{'type' if kind is None else repr(kind)} (known: {', '.join(CONNECTOR_TYPES)})")
    method, required, optional = CONNECTOR_TYPES[kind]
    where = f"connector {k} ({kind})"
    _check_keys(where, conn, ("type",) + CONNECTOR_ENDS + required + optional, ("body_a", "body_b") + required)
    _check_numbers(where, {f: v for f, v in conn.items() if f in required + optional and f != "section"},
                   allow_null=("rest_length", "shear_modulus"))
    conn = dict(conn)
    for side in ("a", "b"):
        conn[f"body_{side}"], conn[f"at_{side}"] = _end(where, f"body_{side}", conn[f"body_{side}"],
                                                      conn.get(f"at_{side}"), meshes)
        if conn[f"at_{side}"] is None:
            raise SceneError(f"{where}: missing field 'at_{side}'")
    _call(where, getattr(sb, method), **{f: v for f, v in conn.items() if f != "type"})


def _add_body(sb: SceneBuilder, i: int, body: Any) -> None:
    _expect(body, dict, f"body {i}", "an object")
    kind = body.get("type")
    if kind is None:
        raise SceneError(f"body {i}: missing field 'type' (one of: {', '.join(BODY_TYPES)})")
    if not isinstance(kind, str) or kind not in BODY_TYPES:
        raise SceneError(f"body {i}: unknown type {kind!r} (known: {', '.join(BODY_TYPES)})")
    method, required = BODY_TYPES[kind]
    where = f"body {i} ({kind})"
    _check_keys(where, body, ("type",) + required + BODY_OPTIONAL, required)
    for field in BOOLEAN_FIELDS:
        if field in body:
            _expect(body[field], bool, f"{where}: field '{field}'", "true or false")
    if "material" in body:
        _expect(body["material"], str, f"{where}: field 'material'", "a material name")
    _call(where, getattr(sb, method), **{k: v for k, v in body.items() if k != "type"})


def _check_keys(where: str, obj: dict, known, required=(), what: str = "field") -> None:
    prefix = f"{where}: " if where else ""
    for key in obj:
        if key not in known:
            close = difflib.get_close_matches(str(key), known, n=1)
            hint = f"did you mean '{close[0]}'? " if close else ""
            raise SceneError(f"{prefix}unknown {what} {key!r} ({hint}known: {', '.join(known)})")
    for key in required:
        if key not in obj:
            raise SceneError(f"{prefix}missing {what} '{key}'")


def _check_numbers(where: str, obj: dict, allow_null=()) -> None:
    """Scalar settings must be JSON numbers (the builder would accept "0.5" or true)."""
    for key, value in obj.items():
        if value is None and key in allow_null:
            continue
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            kind = "a number or null" if key in allow_null else "a number"
            raise SceneError(f"{where}: field '{key}' must be {kind}, got {json.dumps(value, default=repr)[:60]}")


def _expect(value, kind: type, where: str, description: str) -> None:
    if not isinstance(value, kind):
        raise SceneError(f"{where} must be {description}, got {json.dumps(value, default=repr)[:60]}")


def _call(where: str, fn, *args, **kwargs):
    """Call a builder method; a stray TypeError/ValueError from a badly typed value
    becomes a SceneError naming ``where`` (the builder's own SceneErrors pass through)."""
    try:
        return fn(*args, **kwargs)
    except SceneError:
        raise
    except (TypeError, ValueError) as err:
        raise SceneError(f"{where}: invalid value ({err})") from None
