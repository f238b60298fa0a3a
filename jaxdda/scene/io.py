"""Writing scenes out: ``scene_to_dict(scene)`` gives the scene-file description of a
built scene (from the builder calls it recorded), ``save_scene(scene, path)`` writes it
as TOML (or JSON for a ``.json`` path); ``loader.load_scene`` reads it back to the same
scene. ``toml_text`` is a small TOML writer for this data (the standard library reads
TOML but does not write it).
"""
from __future__ import annotations

import inspect
import json
import math
import re
from pathlib import Path

import numpy as np

from jaxdda.errors import SceneError
from jaxdda.scene.builder import SceneBuilder

# builder method -> (scene-file list, body type or connector type)
BODY_METHODS = {"add_disk": "disk", "add_ring": "ring", "add_polygon": "polygon", "add_mesh": "mesh"}
CONNECTOR_METHODS = {"add_spring": "spring", "add_bolt": "bolt", "add_beam": "beam"}
POINT_METHODS = {"add_fixed_point": "fixed_points", "add_measured_point": "measured_points"}


def _plain(value):
    """numpy and tuples -> JSON/TOML-ready Python values."""
    if isinstance(value, np.ndarray):
        return _plain(value.tolist())
    if isinstance(value, (list, tuple)):
        return [_plain(v) for v in value]
    if isinstance(value, dict):
        return {k: _plain(v) for k, v in value.items()}
    if isinstance(value, (bool, np.bool_)):
        return bool(value)
    if isinstance(value, (int, np.integer)):
        return int(value)
    if isinstance(value, (float, np.floating)):
        return float(value)
    return value


def _fields(args: dict, drop=(), method: str | None = None) -> dict:
    """Recorded arguments without those that are None (TOML has no null: absent means
    the default), equal to the builder method's default, or dropped."""
    defaults = {}
    if method is not None:
        defaults = {k: p.default for k, p in inspect.signature(getattr(SceneBuilder, method)).parameters.items()
                    if p.default is not inspect.Parameter.empty}
    return {k: _plain(v) for k, v in args.items()
            if v is not None and k not in drop and not (k in defaults and _plain(v) == _plain(defaults[k]))}


def scene_to_dict(scene, steps: int | None = None) -> dict:
    """The scene-file description (docs/scene-format.md) of a scene made by SceneBuilder."""
    if not scene.recipe:
        raise SceneError(f"scene {scene.name!r}: it carries no recipe (it was not made by SceneBuilder.build), "
                         "so it cannot be written as a scene file")
    settings, calls = scene.recipe
    out: dict = {"name": scene.name}
    out["settings"] = _fields({**settings, "steps": steps, "capacities": settings.get("capacities") or None})
    for method, args in calls:
        if method == "add_material":
            out.setdefault("materials", {})[args["name"]] = _fields(args, drop=("name",), method=method)
        elif method == "set_interface":
            out.setdefault("interfaces", []).append(
                {"materials": [args["material_a"], args["material_b"]], **_fields(args["law"])})
        elif method in BODY_METHODS:
            body = {"type": BODY_METHODS[method], **_fields(args, drop=("edge_materials",), method=method)}
            if args.get("edge_materials") is not None:
                body["joints"] = ["" if m is None else m for m in args["edge_materials"]]
            out.setdefault("bodies", []).append(body)
        elif method in CONNECTOR_METHODS:
            out.setdefault("connectors", []).append({"type": CONNECTOR_METHODS[method], **_fields(args, method=method)})
        elif method == "add_load":
            out.setdefault("loads", []).append(_fields(args, method=method))
        elif method in POINT_METHODS:
            out.setdefault(POINT_METHODS[method], []).append(_fields(args, method=method))
        else:
            raise SceneError(f"scene {scene.name!r}: the builder call {method} has no scene-file form")
    return out


def save_scene(scene, path, *, steps: int | None = None) -> Path:
    """Write ``scene`` as a scene file: TOML, or JSON when ``path`` ends in .json."""
    path = Path(path)
    data = scene_to_dict(scene, steps)
    if path.suffix.lower() == ".json":
        path.write_text(json.dumps(data, indent=1) + "\n", encoding="utf-8")
    else:
        path.write_text(toml_text(data), encoding="utf-8")
    return path


# ----------------------------------------------------------------------------- TOML
_BARE = re.compile(r"^[A-Za-z0-9_-]+$")


def _key(k: str) -> str:
    return k if _BARE.match(k) else json.dumps(k)


def _toml_value(v, indent: str = "") -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, int):
        return str(v)
    if isinstance(v, float):
        if math.isnan(v):
            return "nan"
        if math.isinf(v):
            return "inf" if v > 0 else "-inf"
        return repr(v)  # shortest repr that reads back to the same float
    if isinstance(v, str):
        return json.dumps(v, ensure_ascii=False)
    if isinstance(v, dict):
        return "{ " + ", ".join(f"{_key(k)} = {_toml_value(x)}" for k, x in v.items()) + " }"
    if isinstance(v, list):
        items = [_toml_value(x) for x in v]
        if len(items) > 4 and all(isinstance(x, list) for x in v):  # a list of points: one per line
            return "[\n" + "".join(f"{indent}  {x},\n" for x in items) + f"{indent}]"
        return "[" + ", ".join(items) + "]"
    raise TypeError(f"cannot write {type(v).__name__} to TOML")


def _table(data: dict) -> str:
    return "".join(f"{_key(k)} = {_toml_value(v)}\n" for k, v in data.items())


def toml_text(data: dict) -> str:
    """TOML for scene data: scalars and arrays at the top, then tables (``[settings]``),
    tables of tables (``[materials.rock]``) and arrays of tables (``[[bodies]]``)."""
    scalars = {k: v for k, v in data.items() if not isinstance(v, dict)
               and not (isinstance(v, list) and v and all(isinstance(x, dict) for x in v))}
    parts = [_table(scalars)]
    for k, v in data.items():
        if isinstance(v, dict) and all(isinstance(x, dict) for x in v.values()) and v:
            parts += [f"\n[{_key(k)}.{_key(name)}]\n{_table(table)}" for name, table in v.items()]
        elif isinstance(v, dict):
            parts.append(f"\n[{_key(k)}]\n{_table(v)}")
        elif k not in scalars:
            parts += [f"\n[[{_key(k)}]]\n{_table(item)}" for item in v]
    return "".join(parts)
