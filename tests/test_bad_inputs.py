"""The catalogue of bad inputs (docs/bad-inputs.md): each one, given through the Python API
and through a scene file, is refused with an error that names the body or key and the
field. Cheap: nothing is simulated (the simulate and monte_carlo cases fail before
anything is compiled).

``python tests/test_bad_inputs.py`` rewrites docs/bad-inputs.md from this table with the
messages the engine gives now; ``test_the_doc_lists_every_case`` keeps the two in step.
"""
from __future__ import annotations

import dataclasses
import math
import re
import sys
from pathlib import Path
from typing import Callable

import numpy as np
import pytest

import jaxdda
from jaxdda import SceneBuilder, SceneError
from jaxdda.scene import cutting
from jaxdda.scene.io import toml_text
from jaxdda.scene.loader import load_scene

pytestmark = pytest.mark.smoke  # the whole module is cheap: `pytest -m smoke`

NAN, INF = math.nan, math.inf
DOC = Path(__file__).resolve().parents[1] / "docs" / "bad-inputs.md"

# ------------------------------------------------------------------------------ the base scene
# Body 0: a fixed ground slab, body 1: a ball above it (a gap of 0.5 m). A case adds to it.
GROUND = [(-5.0, -1.0), (5.0, -1.0), (5.0, 0.0), (-5.0, 0.0)]
NODES = [(2.0, 0.0), (3.0, 0.0), (3.0, 1.0), (2.0, 1.0)]  # a meshed block on the ground, x in [2, 3]
TRIANGLES = [(0, 1, 2), (0, 2, 3)]
ROCK = [(10.0, 0.0), (14.0, 0.0), (14.0, 3.0), (10.0, 3.0)]  # a rock mass's boundary, apart from the rest


def sb0(**settings) -> SceneBuilder:
    """The base scene through the API: ground (body 0) and ball (body 1)."""
    sb = SceneBuilder(dt=settings.pop("dt", 1e-3), **settings)
    sb.add_polygon(GROUND, density=2600.0, fixed=True)
    sb.add_disk((0.0, 1.0), 0.5, 2600.0)
    return sb


def sb_mesh(**kwargs) -> tuple[SceneBuilder, jaxdda.scene.builder.Mesh]:
    sb = sb0()
    return sb, sb.add_mesh(NODES, TRIANGLES, 2600.0, 1e9, 0.25, **kwargs)


def sb_rock(**material) -> SceneBuilder:
    sb = sb0()
    sb.add_material("rock", **material)
    return sb


def scene_data(*bodies, settings=None, **top) -> dict:
    """The base scene as scene-file data, with ``bodies`` after its two and other keys."""
    base = [{"type": "polygon", "vertices": [list(p) for p in GROUND], "density": 2600.0, "fixed": True},
            {"type": "disk", "center": [0.0, 1.0], "radius": 0.5, "density": 2600.0}]
    return {"settings": {"dt": 1e-3, **(settings or {})}, "bodies": base + list(bodies), **top}


def disk(**fields) -> dict:
    return {"type": "disk", "center": [3.0, 3.0], "radius": 0.5, "density": 2600.0, **fields}


def ring(**fields) -> dict:
    return {"type": "ring", "center": [3.0, 3.0], "inner_radius": 0.5, "outer_radius": 1.0, "density": 2600.0, **fields}


def polygon(vertices, **fields) -> dict:
    return {"type": "polygon", "vertices": [list(p) for p in vertices], "density": 2600.0, **fields}


def mesh(**fields) -> dict:
    return {"nodes": [list(p) for p in NODES], "triangles": [list(t) for t in TRIANGLES], "density": 2600.0,
            "young": 1e9, "poisson": 0.25, **fields}


def rock_mass_data(**fields) -> dict:
    """A rock mass takes its density from a material."""
    return scene_data(materials={"granite": {"density": 2600.0}},
                      rock_masses=[{"boundary": [list(p) for p in ROCK], "material": "granite", **fields}])


def spring(**fields) -> dict:
    return {"type": "spring", "body_a": 0, "body_b": 1, "at_a": [0.0, 0.0], "at_b": [0.0, 1.0], "stiffness": 1e4,
            **fields}


def _with(*, polygon=None, polygon_at_x5=False, ring=None, disk=None) -> SceneBuilder:
    """The base scene with more bodies (bodies 2, 3, ...), in this order."""
    sb = sb0()
    if polygon is not None:
        sb.add_polygon(polygon, 2600.0)
    if polygon_at_x5:
        sb.add_polygon([(5, -1), (6, -1), (6, 0), (5, 0)], 2600.0)
    if ring is not None:
        sb.add_ring(*ring, 2600.0)
    if disk is not None:
        sb.add_disk(*disk, 2600.0)
    return sb


def _load_at(body: int, at) -> SceneBuilder:
    sb = sb0()
    sb.add_load(body, force=(1.0, 0.0), at=at)
    return sb


def simulate_scene():
    return sb0().build()


def _params(**change):
    """The base scene's params with fields changed: {field: old value -> new value}."""
    p = simulate_scene().params
    return dataclasses.replace(p, **{k: f(getattr(p, k)) for k, f in change.items()})


# ------------------------------------------------------------------------------ the catalogue
@dataclasses.dataclass(frozen=True)
class Case:
    """A bad input. ``api`` raises through the Python API, its message containing every
    string of ``api_says``; ``file`` is the same input as a scene file (scene data written
    as TOML, or ``(suffix, text)`` for a file that is not valid TOML data), its message
    containing every string of ``file_says``. Either route may be None (no equivalent)."""

    id: str
    input: str
    api: Callable[[], object] | None
    api_says: tuple[str, ...]
    file: dict | tuple[str, str] | None = None
    file_says: tuple[str, ...] = ()
    error: type = SceneError


C = Case
CASES = [
    # -- disks and rings -------------------------------------------------------------------
    C("disk-radius-negative", "a disk of radius -1",
      lambda: sb0().add_disk((3, 3), -1.0, 2600.0), ("body 2 (disk)", "'radius' must be > 0"),
      scene_data(disk(radius=-1.0)), ("bodies[2]", "'radius' must be > 0")),
    C("disk-radius-zero", "a disk of radius 0",
      lambda: sb0().add_disk((3, 3), 0.0, 2600.0), ("body 2 (disk)", "'radius' must be > 0"),
      scene_data(disk(radius=0.0)), ("bodies[2]", "'radius' must be > 0")),
    C("disk-center-nan", "a disk centred at (NaN, 3)",
      lambda: sb0().add_disk((NAN, 3), 0.5, 2600.0), ("body 2 (disk)", "'center'", "not finite"),
      scene_data(disk(center=[NAN, 3.0])), ("bodies[2]", "'center'", "not finite")),
    C("disk-center-one-number", "a disk centred at (3,): one coordinate",
      lambda: sb0().add_disk((3,), 0.5, 2600.0), ("body 2 (disk)", "'center' must be a pair of numbers"),
      scene_data(disk(center=[3.0])), ("bodies[2]", "'center' must be a pair of numbers")),
    C("density-zero", "a body of density 0",
      lambda: sb0().add_disk((3, 3), 0.5, 0.0), ("body 2 (disk)", "'density' must be > 0"),
      scene_data(disk(density=0.0)), ("bodies[2]", "'density' must be > 0")),
    C("density-negative", "a body of density -2600",
      lambda: sb0().add_ring((3, 3), 0.5, 1.0, -2600.0), ("body 2 (ring)", "'density' must be > 0"),
      scene_data(ring(density=-2600.0)), ("bodies[2]", "'density' must be > 0")),
    C("density-missing", "a body with no density, from itself or its material",
      None, (),
      scene_data({"type": "disk", "center": [3.0, 3.0], "radius": 0.5}), ("bodies[2].density", "missing")),
    C("ring-inner-above-outer", "a ring whose inner radius 1 exceeds its outer radius 0.5",
      lambda: sb0().add_ring((3, 3), 1.0, 0.5, 2600.0), ("body 2 (ring)", "'inner_radius'", "'outer_radius'"),
      scene_data(ring(inner_radius=1.0, outer_radius=0.5)), ("bodies[2]", "'inner_radius'", "'outer_radius'")),
    C("ring-inner-equal-outer", "a ring of zero width (inner radius = outer radius)",
      lambda: sb0().add_ring((3, 3), 1.0, 1.0, 2600.0), ("body 2 (ring)", "'inner_radius'", "'outer_radius'"),
      scene_data(ring(inner_radius=1.0)), ("bodies[2]", "'inner_radius'", "'outer_radius'")),
    C("ring-inner-zero", "a ring of inner radius 0 (a disk: use one)",
      lambda: sb0().add_ring((3, 3), 0.0, 1.0, 2600.0), ("body 2 (ring)", "'inner_radius' must be > 0"),
      scene_data(ring(inner_radius=0.0)), ("bodies[2]", "'inner_radius' must be > 0")),
    # -- polygons -----------------------------------------------------------------------------
    C("polygon-two-vertices", "a polygon of 2 vertices",
      lambda: sb0().add_polygon([(3, 3), (4, 3)], 2600.0), ("body 2 (polygon)", "'vertices'", "fewer than 3"),
      scene_data(polygon([(3, 3), (4, 3)])), ("bodies[2]", "'vertices'", "fewer than 3")),
    C("polygon-repeated-vertex", "a polygon with a vertex given twice in a row",
      lambda: sb0().add_polygon([(3, 3), (4, 3), (4, 3), (4, 4)], 2600.0),
      ("body 2 (polygon)", "'vertices'", "repeated vertex"),
      scene_data(polygon([(3, 3), (4, 3), (4, 3), (4, 4)])), ("bodies[2]", "'vertices'", "repeated vertex")),
    C("polygon-bow-tie", "a self-intersecting (bow-tie) polygon",
      lambda: sb0().add_polygon([(3, 3), (4, 4), (4, 3), (3, 4)], 2600.0),
      ("body 2 (polygon)", "'vertices'", "self-intersecting"),
      scene_data(polygon([(3, 3), (4, 4), (4, 3), (3, 4)])), ("bodies[2]", "'vertices'", "self-intersecting")),
    C("polygon-collinear", "a polygon whose vertices lie on one line (zero area)",
      lambda: sb0().add_polygon([(3, 3), (4, 4), (5, 5)], 2600.0), ("body 2 (polygon)", "'vertices'", "zero area"),
      scene_data(polygon([(3, 3), (4, 4), (5, 5)])), ("bodies[2]", "'vertices'", "zero area")),
    C("polygon-inf-vertex", "a polygon with an infinite coordinate",
      lambda: sb0().add_polygon([(3, 3), (4, 3), (INF, 4)], 2600.0), ("body 2 (polygon)", "'vertices'", "not finite"),
      scene_data(polygon([(3, 3), (4, 3), (INF, 4)])), ("bodies[2]", "'vertices'", "not finite")),
    C("polygon-3d-vertices", "a polygon of (x, y, z) points",
      lambda: sb0().add_polygon([(3, 3, 0), (4, 3, 0), (4, 4, 0)], 2600.0),
      ("body 2 (polygon)", "'vertices' must be a list of (x, y) points"),
      scene_data(polygon([(3, 3, 0), (4, 3, 0), (4, 4, 0)])), ("bodies[2]", "'vertices' must be a list of (x, y)")),
    C("polygon-joints-count", "a polygon with 2 edge joints for its 4 edges",
      lambda: sb0().add_polygon([(3, 3), (4, 3), (4, 4), (3, 4)], 2600.0, edge_materials=[None, None]),
      ("body 2 (polygon)", "'edge_materials' needs one entry per edge"),
      scene_data(polygon([(3, 3), (4, 3), (4, 4), (3, 4)], joints=["", ""])),
      ("bodies[2]", "'edge_materials' needs one entry per edge")),
    # -- motion, elasticity, material of a body ----------------------------------------------
    C("velocity-nan", "a body moving at (NaN, 0)",
      lambda: sb0().add_disk((3, 3), 0.5, 2600.0, velocity=(NAN, 0)), ("body 2 (disk)", "'velocity'", "not finite"),
      scene_data(disk(velocity=[NAN, 0.0])), ("bodies[2]", "'velocity'", "not finite")),
    C("angular-velocity-inf", "a body spinning at inf rad/s",
      lambda: sb0().add_disk((3, 3), 0.5, 2600.0, angular_velocity=INF),
      ("body 2 (disk)", "'angular_velocity'", "not finite"),
      scene_data(disk(angular_velocity=INF)), ("bodies[2]", "'angular_velocity'", "not finite")),
    C("fixed-with-velocity", "a fixed body given a velocity",
      lambda: sb0().add_disk((3, 3), 0.5, 2600.0, fixed=True, velocity=(1, 0)),
      ("body 2 (disk)", "fixed body cannot have a velocity", "'velocity'"),
      scene_data(disk(fixed=True, velocity=[1.0, 0.0])), ("bodies[2]", "fixed body cannot have a velocity")),
    C("fixed-not-boolean", "fixed given as the string \"false\"",
      lambda: sb0().add_disk((3, 3), 0.5, 2600.0, fixed="false"), ("body 2 (disk)", "'fixed' must be true or false"),
      scene_data(disk(fixed="false")), ("bodies[2].fixed", "must be true or false")),
    C("young-negative", "a deformable body of Young's modulus -1e9",
      lambda: sb0().add_disk((3, 3), 0.5, 2600.0, young=-1e9), ("body 2 (disk)", "'young' must be > 0"),
      scene_data(disk(young=-1e9)), ("bodies[2]", "'young' must be > 0")),
    C("poisson-half", "Poisson's ratio 0.5 (incompressible)",
      lambda: sb0().add_disk((3, 3), 0.5, 2600.0, young=1e9, poisson=0.5), ("body 2 (disk)", "'poisson'", "(-1, 0.5)"),
      scene_data(disk(young=1e9, poisson=0.5)), ("bodies[2]", "'poisson'", "(-1, 0.5)")),
    C("plane-misspelt", "plane = \"strian\"",
      lambda: sb0().add_disk((3, 3), 0.5, 2600.0, young=1e9, plane="strian"), ("body 2 (disk)", "'plane'", "strian"),
      scene_data(disk(young=1e9, plane="strian")), ("bodies[2]", "'plane'", "strian")),
    C("stress-on-rigid", "an initial stress on a rigid body",
      lambda: sb0().add_disk((3, 3), 0.5, 2600.0, stress=(1e5, 0, 0)), ("body 2 (disk)", "'stress'", "'young'"),
      scene_data(disk(stress=[1e5, 0.0, 0.0])), ("bodies[2]", "'stress'", "'young'")),
    C("material-unknown", "a body of material \"granit\", never declared",
      lambda: sb0().add_disk((3, 3), 0.5, 2600.0, material="granit"), ("body 2 (disk)", "'material'", "granit"),
      scene_data(disk(material="granit")), ("bodies[2].material", "unknown material 'granit'")),
    # -- meshed blocks ------------------------------------------------------------------------
    C("mesh-inverted-triangle", "a mesh triangle whose nodes run clockwise",
      lambda: sb0().add_mesh(NODES, [(0, 2, 1), (0, 2, 3)], 2600.0, 1e9), ("mesh 0", "triangle 0", "inverted"),
      scene_data(meshes=[mesh(triangles=[[0, 2, 1], [0, 2, 3]])]), ("meshes[0]", "triangle 0", "inverted")),
    C("mesh-degenerate-triangle", "a mesh triangle of three collinear nodes",
      lambda: sb0().add_mesh([*NODES, (2.5, 0.0)], [(0, 4, 1), (0, 1, 2), (0, 2, 3)], 2600.0, 1e9),
      ("mesh 0", "triangle 0", "degenerate"),
      scene_data(meshes=[mesh(nodes=[*map(list, NODES), [2.5, 0.0]], triangles=[[0, 4, 1], [0, 1, 2], [0, 2, 3]])]),
      ("meshes[0]", "triangle 0", "degenerate")),
    C("mesh-node-out-of-range", "a mesh triangle naming node 7 of 4",
      lambda: sb0().add_mesh(NODES, [(0, 1, 7), (0, 2, 3)], 2600.0, 1e9), ("mesh 0", "triangle 0", "outside 0..3"),
      scene_data(meshes=[mesh(triangles=[[0, 1, 7], [0, 2, 3]])]), ("meshes[0]", "triangle 0", "outside 0..3")),
    C("mesh-node-nan", "a mesh node at (NaN, 0)",
      lambda: sb0().add_mesh([(NAN, 0.0), *NODES[1:]], TRIANGLES, 2600.0, 1e9), ("mesh 0", "node 0", "not finite"),
      scene_data(meshes=[mesh(nodes=[[NAN, 0.0], *map(list, NODES[1:])])]), ("meshes[0]", "node 0", "not finite")),
    C("mesh-unused-node", "a mesh node that no triangle uses",
      lambda: sb0().add_mesh([*NODES, (2.5, 0.5)], TRIANGLES, 2600.0, 1e9), ("mesh 0", "node 4", "no triangle"),
      scene_data(meshes=[mesh(nodes=[*map(list, NODES), [2.5, 0.5]])]), ("meshes[0]", "node 4", "no triangle")),
    C("mesh-young-zero", "a meshed block of Young's modulus 0 (rigid: not a mesh)",
      lambda: sb0().add_mesh(NODES, TRIANGLES, 2600.0, 0.0), ("mesh 0", "'young' must be > 0"),
      scene_data(meshes=[mesh(young=0.0)]), ("meshes[0]", "'young' must be > 0")),
    C("mesh-young-missing", "a meshed block without Young's modulus",
      None, (),
      scene_data(meshes=[{k: v for k, v in mesh().items() if k != "young"}]), ("meshes[0].young", "missing")),
    C("mesh-fixed-node-out-of-range", "fixed_nodes naming node 9 of 4",
      lambda: sb0().add_mesh(NODES, TRIANGLES, 2600.0, 1e9, fixed_nodes=[9]), ("mesh 0", "'fixed_nodes'", "node 9"),
      scene_data(meshes=[mesh(fixed_nodes=[9])]), ("meshes[0]", "'fixed_nodes'", "node 9")),
    C("mesher-max-edge-zero", "the built-in mesher with max_edge = 0",
      lambda: sb0().add_meshed_polygon(NODES, 2600.0, 1e9, max_edge=0.0), ("mesh 0", "'max_edge'"),
      scene_data(meshes=[{"vertices": [list(p) for p in NODES], "max_edge": 0.0, "density": 2600.0, "young": 1e9}]),
      ("meshes[0]", "'max_edge'")),
    C("mesher-bow-tie", "the built-in mesher given a self-intersecting polygon",
      lambda: sb0().add_meshed_polygon([(3, 3), (4, 4), (4, 3), (3, 4)], 2600.0, 1e9),
      ("mesh 0", "'vertices'", "self-intersecting"),
      scene_data(meshes=[{"vertices": [[3, 3], [4, 4], [4, 3], [3, 4]], "density": 2600.0, "young": 1e9}]),
      ("meshes[0]", "'vertices'", "self-intersecting")),
    # -- rock masses (block cutting) -------------------------------------------------------------
    C("rock-boundary-degenerate", "a rock mass whose boundary has zero area",
      lambda: cutting.cut_blocks([(10, 0), (12, 0), (14, 0)], []), ("block cutting", "boundary", "zero area"),
      rock_mass_data(boundary=[[10, 0], [12, 0], [14, 0]]), ("rock_masses[0]", "boundary", "zero area")),
    C("rock-joint-zero-length", "a joint line from a point to itself",
      lambda: cutting.cut_blocks(ROCK, [[(12, 1), (12, 1)]]), ("block cutting", "joint line 0", "zero length"),
      rock_mass_data(lines=[{"from": [12, 1], "to": [12, 1]}]), ("rock_masses[0].lines[0]", "zero length")),
    C("rock-joint-nan", "a joint line to (NaN, 3)",
      lambda: cutting.cut_blocks(ROCK, [[(12, 0), (NAN, 3)]]), ("block cutting", "joint line 0", "not finite"),
      rock_mass_data(lines=[{"from": [12, 0], "to": [NAN, 3]}]), ("rock_masses[0].lines[0]", "must be finite")),
    C("joint-set-spacing-zero", "a joint set of spacing 0",
      lambda: cutting.JointSet(dip=30, spacing=0.0).lines(np.array(ROCK)), ("joint set", "'spacing' must be > 0"),
      rock_mass_data(joint_sets=[{"dip": 30, "spacing": 0.0}]), ("rock_masses[0].joint_sets[0]", "'spacing'")),
    C("joint-set-dip-nan", "a joint set dipping NaN degrees",
      lambda: cutting.JointSet(dip=NAN, spacing=1.0).lines(np.array(ROCK)), ("joint set", "'dip'", "finite"),
      rock_mass_data(joint_sets=[{"dip": NAN, "spacing": 1.0}]), ("rock_masses[0].joint_sets[0]", "'dip'")),
    C("joint-unknown", "a joint line of joint \"fault\", never declared",
      None, (),
      rock_mass_data(lines=[{"from": [12, -1], "to": [12, 4], "joint": "fault"}]),
      ("rock_masses[0].lines[0].joint", "unknown joint 'fault'")),
    C("rock-hole-outside", "a hole at a point outside every block",
      None, (),
      rock_mass_data(holes=[[50, 50]]), ("rock_masses[0].holes[0]", "lies in no block")),
    C("rock-sliver", "a joint line cutting a sliver smaller than min_area",
      lambda: cutting.cut_blocks(ROCK, [[(10.001, -1), (10.001, 4)]], min_area=0.01), ("block cutting", "min_area"),
      rock_mass_data(lines=[{"from": [10.001, -1], "to": [10.001, 4]}], min_area=0.01),
      ("rock_masses[0]", "min_area")),
    # -- connectors ----------------------------------------------------------------------------
    C("connector-outside-body", "a spring attached 8 m away from its body",
      lambda: sb0().add_spring(0, 1, (0, 0), (0, 9), 1e4), ("connector 0 (spring)", "'at_b'", "outside body 1 (disk)"),
      scene_data(connectors=[spring(at_b=[0.0, 9.0])]), ("connectors[0]", "'at_b'", "outside body 1 (disk)")),
    C("connector-same-body", "a bolt from the ball to itself",
      lambda: sb0().add_bolt(1, 1, (0, 1), (0, 1.2), 2e11, 1e-4), ("connector 0 (bolt)", "'body_a' and 'body_b'"),
      scene_data(connectors=[{"type": "bolt", "body_a": 1, "body_b": 1, "at_a": [0, 1], "at_b": [0, 1.2],
                              "young": 2e11, "area": 1e-4}]), ("connectors[0]", "'body_a' and 'body_b'")),
    C("connector-zero-length", "a beam whose two ends are one point",
      lambda: sb_mesh()[0].add_beam(1, 2, (2, 0.5), (2, 0.5), 2e11, 1e-3, 1e-6),
      ("connector 0 (beam)", "zero length", "'at_a' and 'at_b'"),
      scene_data(connectors=[{"type": "beam", "body_a": 0, "body_b": 1, "at_a": [0, 0.5], "at_b": [0, 0.5],
                              "young": 2e11, "area": 1e-3, "inertia": 1e-6}]),
      ("connectors[0]", "zero length", "'at_a' and 'at_b'")),
    C("spring-stiffness-negative", "a spring of stiffness -1e4",
      lambda: sb0().add_spring(0, 1, (0, 0), (0, 1), -1e4), ("connector 0 (spring)", "'stiffness' must be > 0"),
      scene_data(connectors=[spring(stiffness=-1e4)]), ("connectors[0]", "'stiffness' must be > 0")),
    C("spring-rest-length-negative", "a spring of rest length -1",
      lambda: sb0().add_spring(0, 1, (0, 0), (0, 1), 1e4, rest_length=-1.0),
      ("connector 0 (spring)", "'rest_length' must be >= 0"),
      scene_data(connectors=[spring(rest_length=-1.0)]), ("connectors[0]", "'rest_length' must be >= 0")),
    C("bolt-area-zero", "a bolt of cross-section 0",
      lambda: sb0().add_bolt(0, 1, (0, 0), (0, 1), 2e11, 0.0), ("connector 0 (bolt)", "'area' must be > 0"),
      scene_data(connectors=[{"type": "bolt", "body_a": 0, "body_b": 1, "at_a": [0, 0], "at_b": [0, 1],
                              "young": 2e11, "area": 0.0}]), ("connectors[0]", "'area' must be > 0")),
    C("beam-section-unknown", "a beam of section \"square\"",
      lambda: sb0().add_beam(0, 1, (0, 0), (0, 1), 2e11, 1e-3, 1e-6, section="square"),
      ("connector 0 (beam)", "'section'", "square"),
      scene_data(connectors=[{"type": "beam", "body_a": 0, "body_b": 1, "at_a": [0, 0], "at_b": [0, 1],
                              "young": 2e11, "area": 1e-3, "inertia": 1e-6, "section": "square"}]),
      ("connectors[0]", "'section'", "square")),
    C("connector-body-missing", "a spring to body 5 of 2",
      lambda: sb0().add_spring(0, 5, (0, 0), (0, 1), 1e4), ("connector 0 (spring)", "'body_b'", "5"),
      scene_data(connectors=[spring(body_b=5)]), ("connectors[0]", "'body_b'", "5")),
    # -- loads ----------------------------------------------------------------------------------
    C("load-force-nan", "a load of force (0, NaN)",
      lambda: sb0().add_load(1, force=(0, NAN)), ("load 0", "'force'", "not finite"),
      scene_data(loads=[{"body": 1, "force": [0.0, NAN]}]), ("loads[0]", "'force'", "not finite")),
    C("load-history-decreasing", "a load history whose times go back (t = 2, then 1)",
      lambda: sb0().add_load(1, history=[(0, 0, 0), (2, 1, 0), (1, 0, 0)]),
      ("load 0", "'history'", "must not decrease"),
      scene_data(loads=[{"body": 1, "history": [[0, 0, 0], [2, 1, 0], [1, 0, 0]]}]),
      ("loads[0]", "'history'", "must not decrease")),
    C("load-history-shape", "a load history of (t, f) rows",
      lambda: sb0().add_load(1, history=[(0, 0), (1, 1)]), ("load 0", "'history' must be rows (t, fx, fy)"),
      scene_data(loads=[{"body": 1, "history": [[0, 0], [1, 1]]}]), ("loads[0]", "'history' must be rows")),
    C("load-outside-body", "a load on the ball at a point 8 m away from it",
      lambda: _load_at(1, (0, 9)).build(), ("load 0", "'at'", "outside body 1 (disk)"),
      scene_data(loads=[{"body": 1, "at": [0.0, 9.0], "force": [1.0, 0.0]}]), ("load 0", "'at'", "outside body 1")),
    C("load-in-no-body", "a load without a body at a point in no body",
      None, (),
      scene_data(loads=[{"at": [0.0, 9.0], "force": [1.0, 0.0]}]), ("loads[0]", "lies in no body", "'body'")),
    C("load-body-missing", "a load on body 7 of 2",
      lambda: sb0().add_load(7, force=(1, 0)), ("load 0", "'body'", "7"),
      scene_data(loads=[{"body": 7, "force": [1.0, 0.0]}]), ("loads[0]", "'body'", "7")),
    # -- fixed and measured points -------------------------------------------------------------
    C("fixed-point-outside", "a fixed point of the ball 8 m away from it",
      lambda: sb0().add_fixed_point(1, (0, 9)), ("fixed point 0", "'at'", "outside body 1 (disk)"),
      scene_data(fixed_points=[{"body": 1, "at": [0.0, 9.0]}]), ("fixed_points[0]", "'at'", "outside body 1")),
    C("fixed-point-moving", "a fixed point where the body moves at t = 0",
      lambda: (sb := SceneBuilder(1e-3)).add_disk((0, 1), 0.5, 2600.0, velocity=(1, 0)) + sb.add_fixed_point(0, (0, 1)),
      ("fixed point 0", "body 0 (disk)", "'velocity'"),
      {"settings": {"dt": 1e-3}, "bodies": [disk(center=[0.0, 1.0], velocity=[1.0, 0.0])],
       "fixed_points": [{"body": 0, "at": [0.0, 1.0]}]}, ("fixed_points[0]", "body 0 (disk)", "'velocity'")),
    C("fixed-point-mesh-not-node", "a fixed point on a meshed block, not at a node",
      lambda: sb_mesh()[0].add_fixed_point(2, (2.6, 0.3)), ("fixed point 0", "'at'", "not a node of mesh 0"),
      scene_data(meshes=[mesh()], fixed_points=[{"body": 2, "at": [2.6, 0.3]}]),
      ("fixed_points[0]", "'at'", "not a node of mesh 0")),
    C("mesh-node-missing", "a fixed point at node 9 of a 4-node mesh",
      None, (),
      scene_data(meshes=[mesh()], fixed_points=[{"body": {"mesh": 0, "node": 9}}]),
      ("fixed_points[0].body.node", "9")),
    C("point-in-empty-scene", "a fixed point without a body in a scene with no bodies",
      lambda: SceneBuilder(1e-3).body_at((0, 0)), ("(0.0, 0.0)", "lies in no body", "no bodies"),
      {"settings": {"dt": 1e-3}, "fixed_points": [{"at": [0.0, 0.0]}]}, ("fixed_points[0]", "no bodies")),
    C("measured-point-outside", "a measured point of the ball 8 m away from it",
      lambda: sb0().add_measured_point(1, (0, 9)), ("measured point 0", "'at'", "outside body 1 (disk)"),
      scene_data(measured_points=[{"body": 1, "at": [0.0, 9.0]}]),
      ("measured_points[0]", "'at'", "outside body 1")),
    C("point-on-two-bodies", "a measured point without a body, on the boundary of two",
      lambda: _with(polygon_at_x5=True).body_at((5, -0.5)), ("(5.0, -0.5)", "boundary of bodies 0, 2", "'body'"),
      scene_data(polygon([(5, -1), (6, -1), (6, 0), (5, 0)]), measured_points=[{"at": [5.0, -0.5]}]),
      ("measured_points[0]", "boundary of bodies 0, 2", "'body'")),
    # -- materials and interfaces ----------------------------------------------------------------
    C("friction-negative", "a material of friction -0.1",
      lambda: sb_rock(friction=-0.1), ("material 'rock'", "'friction' must be >= 0"),
      scene_data(materials={"rock": {"friction": -0.1}}), ("materials.rock", "'friction' must be >= 0")),
    C("restitution-above-one", "a material of restitution 1.5",
      lambda: sb_rock(restitution=1.5), ("material 'rock'", "'restitution' must be in [0, 1]"),
      scene_data(materials={"rock": {"restitution": 1.5}}), ("materials.rock", "'restitution' must be in [0, 1]")),
    C("cohesion-nan", "a material of cohesion NaN",
      lambda: sb_rock(cohesion=NAN), ("material 'rock'", "'cohesion'", "not finite"),
      scene_data(materials={"rock": {"cohesion": NAN}}), ("materials.rock", "'cohesion'", "not finite")),
    C("tensile-negative", "a joint of tensile strength -1e4",
      lambda: sb_rock(tensile=-1e4), ("material 'rock'", "'tensile' must be >= 0"),
      scene_data(joints={"bedding": {"tensile": -1e4}}), ("joints.bedding", "'tensile' must be >= 0")),
    C("material-density-zero", "a material of density 0 given to a body",
      None, (),
      scene_data({"type": "disk", "center": [3.0, 3.0], "radius": 0.5, "material": "rock"},
                 materials={"rock": {"density": 0.0}}), ("bodies[2]", "'density' must be > 0")),
    C("interface-unknown-material", "an interface between rock and \"sand\", never declared",
      lambda: sb_rock().set_interface("rock", "sand", friction=0.3), ("interface (rock, sand)", "'sand'"),
      scene_data(materials={"rock": {}}, interfaces=[{"materials": ["rock", "sand"], "friction": 0.3}]),
      ("interfaces[0]", "unknown material 'sand'")),
    C("interface-friction-negative", "an interface of friction -1",
      lambda: sb_rock().set_interface("rock", "default", friction=-1.0),
      ("interface (rock, default)", "'friction' must be >= 0"),
      scene_data(materials={"rock": {}}, interfaces=[{"materials": ["rock", "default"], "friction": -1.0}]),
      ("interfaces[0]", "'friction' must be >= 0")),
    # -- settings ------------------------------------------------------------------------------
    C("dt-zero", "a time step of 0",
      lambda: sb0(dt=0.0).build(), ("settings", "'dt' must be > 0"),
      scene_data(settings={"dt": 0.0}), ("settings", "'dt' must be > 0")),
    C("dt-negative", "a time step of -0.001",
      lambda: sb0(dt=-1e-3).build(), ("settings", "'dt' must be > 0"),
      scene_data(settings={"dt": -1e-3}), ("settings", "'dt' must be > 0")),
    C("gravity-nan", "gravity (0, NaN)",
      lambda: sb0(gravity=(0, NAN)).build(), ("settings", "'gravity'", "not finite"),
      scene_data(settings={"gravity": [0.0, NAN]}), ("settings", "'gravity'", "not finite")),
    C("gravity-scalar", "gravity given as one number",
      lambda: sb0(gravity=-9.81).build(), ("settings", "'gravity' must be (gx, gy)"),
      scene_data(settings={"gravity": -9.81}), ("settings", "'gravity' must be (gx, gy)")),
    C("tol-zero", "a contact tolerance of 0",
      lambda: sb0(tol=0.0).build(), ("settings", "'tol' must be > 0"),
      scene_data(settings={"tol": 0.0}), ("settings", "'tol' must be > 0")),
    C("max-iter-zero", "max_iter = 0",
      lambda: sb0(max_iter=0).build(), ("settings", "'max_iter'"),
      scene_data(settings={"max_iter": 0}), ("settings", "'max_iter'")),
    C("max-iter-fraction", "max_iter = 2.5",
      lambda: sb0(max_iter=2.5).build(), ("settings", "'max_iter'", "integer"),
      scene_data(settings={"max_iter": 2.5}), ("settings", "'max_iter'", "integer")),
    C("dynamic-above-one", "dynamic = 1.5 (outside [0, 1])",
      lambda: sb0(dynamic=1.5).build(), ("settings", "'dynamic' must be in [0, 1]"),
      scene_data(settings={"dynamic": 1.5}), ("settings", "'dynamic' must be in [0, 1]")),
    C("margin-negative", "a contact margin of -1e-6",
      lambda: sb0(margin=-1e-6).build(), ("settings", "'margin' must be >= 0"),
      scene_data(settings={"margin": -1e-6}), ("settings", "'margin' must be >= 0")),
    C("capacity-zero", "a contact buffer of capacity 0",
      lambda: sb0(capacities={"contacts": 0}), ("'capacities'", "contacts", "positive integer"),
      scene_data(settings={"capacities": {"contacts": 0}}), ("settings.capacities.contacts", "positive integer")),
    C("capacity-unknown", "a capacity for an unknown buffer \"contact\"",
      lambda: sb0(capacities={"contact": 100}), ("'capacities'", "'contact'"),
      scene_data(settings={"capacities": {"contact": 100}}), ("settings.capacities.contact", "unknown key")),
    C("steps-zero", "settings.steps = 0",
      None, (),
      scene_data(settings={"steps": 0}), ("settings.steps", "positive integer")),
    # -- the scene as a whole --------------------------------------------------------------------
    C("no-bodies", "a scene with no bodies",
      lambda: SceneBuilder(1e-3).build(), ("scene", "no bodies"),
      {"settings": {"dt": 1e-3}}, ("scene", "no bodies")),
    C("overlap-disk-polygon", "a ball sunk 0.3 m into the ground at the start",
      lambda: _with(disk=((3, 0.2), 0.5)).build(), ("body 0 (polygon)", "body 2 (disk)", "interpenetrate", "0.3"),
      scene_data(disk(center=[3.0, 0.2])), ("scene", "body 0 (polygon)", "body 2 (disk)", "interpenetrate")),
    C("overlap-polygons", "two blocks overlapping at the start",
      lambda: _with(polygon=[(3, -0.5), (4, -0.5), (4, 1), (3, 1)]).build(),
      ("body 0 (polygon)", "body 2 (polygon)", "interpenetrate"),
      scene_data(polygon([(3, -0.5), (4, -0.5), (4, 1), (3, 1)])),
      ("scene", "body 0 (polygon)", "body 2 (polygon)", "interpenetrate")),
    C("overlap-ring-disk", "a disk across the material of a ring",
      lambda: _with(ring=((3, 3), 0.5, 1.0), disk=((3.75, 3), 0.2)).build(),
      ("body 2 (ring)", "body 3 (disk)", "interpenetrate"),
      scene_data(ring(), disk(center=[3.75, 3.0], radius=0.2)), ("scene", "body 2 (ring)", "body 3 (disk)")),
    # -- the file itself -------------------------------------------------------------------------
    C("unknown-key", "a misspelt key (radious)",
      None, (),
      scene_data(disk(radious=0.5)), ("bodies[2].radious", "unknown key", "did you mean 'radius'")),
    C("unknown-top-key", "an unknown top-level key (body)",
      None, (),
      {**scene_data(), "body": []}, ("body: unknown key", "did you mean 'bodies'")),
    C("wrong-type-number", "radius = \"0.5\" (a string)",
      lambda: sb0().add_disk((3, 3), "0.5", 2600.0), ("body 2 (disk)", "'radius'", "not numeric"),
      scene_data(disk(radius="0.5")), ("bodies[2].radius", "must be a number")),
    C("wrong-type-list", "bodies given as a table, not a list",
      None, (),
      {"settings": {"dt": 1e-3}, "bodies": {"ball": disk()}}, ("bodies", "must be a list")),
    C("missing-field", "a disk without a radius",
      None, (),
      scene_data({k: v for k, v in disk().items() if k != "radius"}), ("bodies[2].radius", "missing")),
    C("unknown-body-type", "a body of type \"circle\"",
      None, (),
      scene_data(disk(type="circle")), ("bodies[2].type", "unknown type \"circle\"")),
    C("settings-missing", "a file without settings",
      None, (),
      {"bodies": scene_data()["bodies"]}, ("settings", "missing")),
    C("dt-missing", "settings without dt",
      None, (),
      {**scene_data(), "settings": {"steps": 10}}, ("settings.dt", "missing")),
    C("invalid-toml", "a file that is not TOML",
      None, (),
      (".toml", "[settings]\ndt = \n"), ("invalid TOML", "line 2")),
    C("json-list", "a JSON file holding a list",
      None, (),
      (".json", "[{\"settings\": {\"dt\": 0.001}}]"), ("the scene", "must be a table")),
    C("invalid-json", "a JSON file with a syntax error",
      None, (),
      (".json", "{\"settings\": {\"dt\": 0.001,}}"), ("invalid JSON", "line 1")),
    # -- run arguments ---------------------------------------------------------------------------
    C("simulate-steps-zero", "simulate(scene, steps=0)",
      lambda: jaxdda.simulate(simulate_scene(), 0), ("steps", "positive integer"), error=ValueError),
    C("simulate-chunk-zero", "simulate(scene, 10, chunk=0)",
      lambda: jaxdda.simulate(simulate_scene(), 10, chunk=0), ("chunk", "positive integer"), error=ValueError),
    C("simulate-save-every-zero", "simulate(scene, 10, save_every=0)",
      lambda: jaxdda.simulate(simulate_scene(), 10, save_every=0), ("save_every", "positive integer"),
      error=ValueError),
    C("simulate-steps-fraction", "simulate(scene, 2.5)",
      lambda: jaxdda.simulate(simulate_scene(), 2.5), ("steps", "positive integer"), error=ValueError),
    C("simulate-params-nan", "simulate(scene, 10, params=...) with a NaN in the friction table",
      lambda: jaxdda.simulate(simulate_scene(), 10, params=_params(friction=lambda f: f.at[0, 0].set(NAN))),
      ("params", "'friction'", "entry (0, 0)", "not finite"), error=ValueError),
    C("simulate-params-dt-negative", "simulate(scene, 10, params=...) with dt = -1e-3",
      lambda: jaxdda.simulate(simulate_scene(), 10, params=_params(dt=lambda v: -v)), ("params", "'dt'", "> 0"),
      error=ValueError),
    C("simulate-params-restitution", "simulate(scene, 10, params=...) with a restitution of 1.5",
      lambda: jaxdda.simulate(simulate_scene(), 10, params=_params(restitution=lambda r: r + 0.5)),
      ("params", "'restitution'", "in [0, 1]"), error=ValueError),
    C("monte-carlo-params-nan", "monte_carlo with a NaN friction in scenario 1",
      lambda: jaxdda.monte_carlo(simulate_scene(), 10, params={"friction": [0.3, NAN]}, progress=False),
      ("params['friction']", "scenario 1", "not finite"), error=ValueError),
    C("monte-carlo-velocity-inf", "monte_carlo with an infinite initial velocity",
      lambda: jaxdda.monte_carlo(simulate_scene(), 10, velocity=[[1.0, 0.0], [INF, 0.0]], body=1, progress=False),
      ("velocity", "scenario 1", "not finite"), error=ValueError),
    C("monte-carlo-steps-zero", "monte_carlo(scene, 0)",
      lambda: jaxdda.monte_carlo(simulate_scene(), 0, progress=False), ("steps", "positive integer"), error=ValueError),
]

# Inputs that look odd but are fine: each builds, through both routes (``api`` returns a
# SceneBuilder, which the test builds).
ACCEPTED = [
    ("clockwise-polygon", "a polygon given clockwise (either orientation is fine)",
     lambda: _with(polygon=[(3, 3), (3, 4), (4, 4), (4, 3)]),
     scene_data(polygon([(3, 3), (3, 4), (4, 4), (4, 3)]))),
    ("touching-at-start", "a ball resting on the ground at t = 0 (touching is not overlapping)",
     lambda: _with(disk=((3, 0.5), 0.5)), scene_data(disk(center=[3.0, 0.5]))),
    ("disk-in-ring-hole", "a disk loose in a ring's hole",
     lambda: _with(ring=((3, 3), 0.5, 1.0), disk=((3, 3), 0.3)), scene_data(ring(), disk(radius=0.3))),
    ("poisson-negative", "a negative Poisson's ratio (auxetic, > -1)",
     lambda: _then(sb0(), "add_disk", (3, 3), 0.5, 2600.0, young=1e9, poisson=-0.5),
     scene_data(disk(young=1e9, poisson=-0.5))),
    ("history-jump", "a load history with two rows at one time (a step)",
     lambda: _then(sb0(), "add_load", 1, history=[(0, 0, 0), (1, 0, 0), (1, 5, 0)]),
     scene_data(loads=[{"body": 1, "history": [[0, 0, 0], [1, 0, 0], [1, 5, 0]]}])),
    ("load-at-ring-centre", "a load on a ring without 'at': at its centroid, in the hole",
     lambda: _then(_with(ring=((3, 3), 0.5, 1.0)), "add_load", 2, force=(1, 0)),
     scene_data(ring(), loads=[{"body": 2, "force": [1.0, 0.0]}])),
    ("pin-on-fixed-body", "a fixed point on a fixed body (changes nothing)",
     lambda: _then(sb0(), "add_fixed_point", 0, (0, -0.5)), scene_data(fixed_points=[{"body": 0, "at": [0.0, -0.5]}])),
]


def _then(sb: SceneBuilder, method: str, *args, **kwargs) -> SceneBuilder:
    getattr(sb, method)(*args, **kwargs)
    return sb


# ------------------------------------------------------------------------------ the tests
def api_error(case: Case) -> BaseException:
    with pytest.raises(case.error) as err:
        case.api()
    return err.value


def file_error(case: Case, folder: Path) -> BaseException:
    suffix, text = case.file if isinstance(case.file, tuple) else (".toml", toml_text(case.file))
    path = folder / f"scene{suffix}"
    path.write_text(text, encoding="utf-8")
    with pytest.raises(SceneError) as err:
        load_scene(path)
    assert str(err.value).startswith(f"{path}: "), "a file's error starts with the file name"
    return err.value


@pytest.mark.parametrize("case", [c for c in CASES if c.api is not None], ids=lambda c: c.id)
def test_the_api_refuses(case):
    message = str(api_error(case))
    missing = [s for s in case.api_says if s not in message]
    assert not missing, f"{case.id}: {message!r} lacks {missing}"


@pytest.mark.parametrize("case", [c for c in CASES if c.file is not None], ids=lambda c: c.id)
def test_the_scene_file_refuses(case, tmp_path):
    message = str(file_error(case, tmp_path))
    missing = [s for s in case.file_says if s not in message]
    assert not missing, f"{case.id}: {message!r} lacks {missing}"


@pytest.mark.parametrize("case_id, text, api, data", ACCEPTED, ids=[a[0] for a in ACCEPTED])
def test_not_errors(case_id, text, api, data, tmp_path):
    api().build()
    (tmp_path / "scene.toml").write_text(toml_text(data), encoding="utf-8")
    load_scene(tmp_path / "scene.toml")


def test_the_catalogue():
    ids = [c.id for c in CASES] + [a[0] for a in ACCEPTED]
    assert len(set(ids)) == len(ids), "case ids are unique"
    assert all(re.fullmatch(r"[a-z0-9-]+", i) for i in ids)
    assert len(CASES) >= 30
    for c in CASES:
        assert c.api is not None or c.file is not None
        assert (c.api is None) == (not c.api_says) and (c.file is None) == (not c.file_says), c.id


def test_the_doc_lists_every_case():
    listed = set(re.findall(r"^\| `([a-z0-9-]+)` \|", DOC.read_text(encoding="utf-8"), re.M))
    ids = {c.id for c in CASES} | {a[0] for a in ACCEPTED}
    assert not ids - listed, f"not in {DOC.name} (run python tests/test_bad_inputs.py): {sorted(ids - listed)}"
    assert not listed - ids, f"in {DOC.name} but not in the tests: {sorted(listed - ids)}"


# ------------------------------------------------------------------------------ the doc
def _cell(text: str) -> str:
    return text.replace("|", "\\|").replace("\n", " ")


def write_doc(path: Path = DOC) -> None:
    """docs/bad-inputs.md: the catalogue with the messages the engine gives now."""
    import tempfile

    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        for c in CASES:
            api = f"`{_cell(str(api_error(c)))}`" if c.api is not None else ""
            if c.error is not SceneError and api:
                api = f"{c.error.__name__}: {api}"
            text = str(file_error(c, folder)).replace(f"{folder}{'/'}", "") if c.file is not None else ""
            rows.append(f"| `{c.id}` | {_cell(c.input)} | {api} | {f'`{_cell(text)}`' if text else ''} |")
    accepted = [f"| `{i}` | {_cell(text)} |" for i, text, _, _ in ACCEPTED]
    path.write_text(HEAD.format(n=len(CASES)) + "\n".join(rows) + "\n" + ACCEPTED_HEAD + "\n".join(accepted) + "\n",
                    encoding="utf-8")


HEAD = """# Bad inputs and their errors

Every bad input is refused before anything runs, with a `jaxdda.SceneError` (a
`ValueError`) whose message names the body or key and the field. A scene file's errors
start with the file name and the key path (`bodies[2]`, `settings.dt`); bodies are
numbered from 0 (`body 2 (disk)`), as in [the scene format](scene-format.md#bodies).
The arguments of `simulate` and `monte_carlo` raise a plain `ValueError`.

The {n} cases below are checked by `tests/test_bad_inputs.py`, each through the Python
API and through a scene file where both exist (an empty cell: that route has no such
input). The messages are the engine's own; `python tests/test_bad_inputs.py` rewrites
this page from the test's table. In every case the scene builds a fixed ground slab
(body 0) and a ball above it (body 1), then adds the bad input (bodies 2, 3, ...).

| case | input | Python API | scene file |
| --- | --- | --- | --- |
"""

ACCEPTED_HEAD = """
## Not errors

These look suspicious but are accepted (also checked by the test):

| case | input |
| --- | --- |
"""


if __name__ == "__main__":
    sys.exit(write_doc())
