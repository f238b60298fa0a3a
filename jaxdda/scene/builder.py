"""SceneBuilder: bodies and materials in, a validated (Model, State, Params) out."""
from __future__ import annotations

import copy
import dataclasses
import functools
import inspect
from typing import NamedTuple, Sequence

import jax.numpy as jnp
import numpy as np

from jaxdda.bodies import geometry
from jaxdda.connectors import BEAM, BOLT, SHEAR_FACTOR, SPRING, beam_coefficients
from jaxdda.errors import SceneError
from jaxdda.scene import cement, validate
from jaxdda.scene import mesh as mesh_lib
from jaxdda.scene.capacity import initial_capacities
from jaxdda.types import (DISK, KIND_NAMES, NDOF, NO_JOINT, POLYGON, RING, Capacities, Model, Params, State,
                          zeros_contact_memory)

RIGID_PROJECTOR = np.diag([1.0, 1.0, 1.0, 0.0, 0.0, 0.0])
# A deformable particle: eps_x = eps_y (eq. 4), the dofs span e0, e1, e2 and (e3 + e4) / sqrt 2.
PARTICLE_PROJECTOR = RIGID_PROJECTOR + 0.5 * np.outer([0, 0, 0, 1, 1, 0], [0, 0, 0, 1, 1, 0])
# The contact law of a material pair, with the defaults of the "default" material.
CONTACT_LAW = {"friction": 0.0, "restitution": 1.0, "cohesion": 0.0, "rolling": 0.0, "tensile": 0.0}


@dataclasses.dataclass(frozen=True)
class Scene:
    """A ready-to-run scene: ``step(scene.model, scene.state, scene.params)``."""

    model: Model
    state: State
    params: Params
    labels: tuple[str, ...]  # "body 3 (disk)" etc., used in messages and plots
    materials: tuple[str, ...]
    name: str = "scene"
    # How it was built: the builder's settings and its recorded calls (scene.io writes them
    # out as a scene file that reads back to this scene).
    recipe: tuple = dataclasses.field(default=(), repr=False, compare=False)
    # Measured points: (body, point) with the point body-local at rotation 0 (see
    # Trajectory.measured_points).
    measured: tuple = ()

    @property
    def n_bodies(self) -> int:
        return self.model.n_bodies

    def with_options(self, **changes) -> "Scene":
        """This scene with some of the step's refinements switched (``StepOptions``): e.g.
        ``scene.with_options(newton_finish=False)``."""
        options = dataclasses.replace(self.model.options, **changes)
        return dataclasses.replace(self, model=dataclasses.replace(self.model, options=options))


@dataclasses.dataclass(frozen=True)
class Mesh:
    """A meshed block as added: its index, element bodies (one per triangle), nodes (n, 2),
    triangles (l, 3), which nodes are fixed, and for each node one element body that holds
    it (for loads or connectors at a node: ``add_load(mesh.holder[k], f, at=mesh.nodes[k])``)."""

    index: int
    bodies: tuple[int, ...]
    nodes: np.ndarray
    triangles: np.ndarray
    fixed_nodes: np.ndarray
    holder: np.ndarray


@dataclasses.dataclass
class _Body:
    kind: int
    center: np.ndarray
    radius: float
    inner_radius: float
    local: np.ndarray  # (n, 2) counter-clockwise, relative to the centroid
    area: float
    polar: float
    density: float
    velocity: np.ndarray
    omega: float
    fixed: bool
    material: str
    gravity: bool
    moments: np.ndarray = None  # [int x^2, int y^2, int xy] dA about the centroid
    young: float = 0.0  # 0: rigid
    poisson: float = 0.0
    plane_strain: bool = False
    stress: np.ndarray = None  # initial [sigma_x, sigma_y, tau_xy]
    mesh: int = -1  # the meshed block of a triangle element
    nodes: np.ndarray = None  # an element's node indices in its mesh, in vertex order
    edges: np.ndarray = None  # an element's edges that lie on its mesh's boundary (contact surfaces)
    element: int = -1  # its index among the mesh's triangles
    pinned: np.ndarray = None  # which of an element's nodes are fixed
    edge_materials: list | None = None  # per edge (counter-clockwise order): a joint material or None
    pins: list = dataclasses.field(default_factory=list)  # world points of its fixed points (add_fixed_point)


def _scalar(x) -> jnp.ndarray:
    """A scalar of the scene (dt, tol, ...): float64, not weakly typed, so that a value the
    user sets (a float64 array) keeps the compiled program."""
    return jnp.asarray(np.float64(x))


def _recorded(method):
    """Record a successful call of a builder method (all its arguments, defaults filled
    in) in the builder's recipe, so that the scene can be written out as a scene file.
    Only methods that add one thing directly are recorded (add_blocks and
    add_meshed_polygon are recorded as the add_polygon and add_mesh calls they make)."""
    signature = inspect.signature(method)

    @functools.wraps(method)
    def wrapper(self, *args, **kwargs):
        bound = signature.bind(self, *args, **kwargs)
        bound.apply_defaults()
        arguments = copy.deepcopy({k: v for k, v in bound.arguments.items() if k != "self"})
        result = method(self, *args, **kwargs)
        self._recipe.append((method.__name__, arguments))
        return result

    return wrapper


class _BodyArrays(NamedTuple):
    """The added bodies' per-body arrays that the model and the start state share."""

    n: int
    kinds: np.ndarray  # (N,) int32
    fixed: np.ndarray  # (N,) bool
    bound: np.ndarray  # (N,) bounding radius
    centers: np.ndarray  # (N, 2)
    velocity: np.ndarray  # (N, 6)
    local: np.ndarray  # (N, V, 2) polygon vertices about the centroid (padded)
    mask: np.ndarray  # (N, V) real vertices
    edges: np.ndarray  # (N, V) edges that are contact surfaces
    edge_material: np.ndarray  # (N, V) an edge's joint material (index into names), -1 for none


def _body_arrays(bodies: list, names: list[str]) -> _BodyArrays:
    n = len(bodies)
    v_max = max([len(b.local) for b in bodies] + [1])
    local = np.zeros((n, v_max, 2))
    mask = np.zeros((n, v_max), bool)
    edges = np.zeros((n, v_max), bool)
    edge_material = -np.ones((n, v_max), np.int32)
    for i, b in enumerate(bodies):
        local[i, : len(b.local)] = b.local
        mask[i, : len(b.local)] = True
        edges[i, : len(b.local)] = True if b.edges is None else b.edges
        for k, m in enumerate(b.edge_materials or []):
            edge_material[i, k] = -1 if m is None else names.index(m)
    velocity = np.zeros((n, NDOF))
    velocity[:, :2] = [b.velocity for b in bodies]
    velocity[:, 2] = [b.omega for b in bodies]
    return _BodyArrays(n=n, kinds=np.array([b.kind for b in bodies], np.int32),
                       fixed=np.array([b.fixed for b in bodies], bool), bound=np.array([_body_size(b) for b in bodies]),
                       centers=np.array([b.center for b in bodies]), velocity=velocity, local=local, mask=mask,
                       edges=edges, edge_material=edge_material)


class SceneBuilder:
    """Collects bodies and materials; ``build()`` validates them and returns a Scene.

    Units are SI (m, kg, s). Gravity acts on every body unless it is added with
    ``gravity=False``. A contact between two bodies of one material uses that material's
    contact law (friction, restitution, cohesion, rolling, tensile); a mixed pair uses the
    smaller of the two values of each unless an interface is declared with ``set_interface``.
    """

    def __init__(self, dt: float, gravity: Sequence[float] = (0.0, -9.81), *, tol: float = 1e-12,
                 max_iter: int = 20000, margin: float | None = None, dynamic: float = 1.0, name: str = "scene",
                 capacities: dict | None = None):
        self.dt, self.gravity, self.tol, self.max_iter, self.margin, self.name = dt, gravity, tol, max_iter, margin, name
        self.dynamic = dynamic
        unknown = sorted(set(capacities or {}) - {f.name for f in dataclasses.fields(Capacities)})
        if unknown:
            raise SceneError(f"settings: field 'capacities' has unknown buffer '{unknown[0]}' "
                             f"(known: {', '.join(f.name for f in dataclasses.fields(Capacities))})")
        for key, value in (capacities or {}).items():
            if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < 1:
                raise SceneError(f"settings: field 'capacities' entry '{key}' must be a positive integer, "
                                 f"got {value!r}")
        self.capacities = dict(capacities or {})
        self._measured: list[tuple[int, np.ndarray]] = []
        self._fixed_points: list[tuple[int, np.ndarray]] = []
        self._bodies: list[_Body] = []
        self._materials: dict[str, dict[str, float]] = {"default": dict(CONTACT_LAW)}
        self._loads: list[tuple[int, np.ndarray, np.ndarray, np.ndarray, np.ndarray]] = []
        self._interfaces: dict[tuple[str, str], dict[str, float]] = {}
        self._connectors: list[_Connector] = []
        self._meshes: list[Mesh] = []
        self._recipe: list[tuple[str, dict]] = []

    # -- materials ---------------------------------------------------------------------
    @_recorded
    def add_material(self, name: str, friction: float = 0.0, restitution: float = 1.0, *, cohesion: float = 0.0,
                     rolling: float = 0.0, tensile: float = 0.0) -> str:
        """Declare (or redefine) a material and its contact law with itself.

        friction: Coulomb coefficient mu >= 0 (eq. 19). restitution: Newton's e in [0, 1].
        cohesion: c >= 0 (N), the cohesive shear strength of one contact interface, shared by
        the two adjoint contacts of an edge-edge interface (eqs. 19, 42-45).
        rolling: rolling resistance coefficient delta >= 0 (m) of contacts with a particle:
        the rolling moment is bounded by delta times the normal force (eq. 55).
        tensile: tensile strength t >= 0 (N) of a cemented interface: bodies of this material
        touching at t = 0 are cemented; the joints of one interface share t (eqs. 63-73).
        The built-in "default" material is frictionless, perfectly elastic (e = 1) and has
        no cohesion, rolling resistance or cement.
        """
        if not isinstance(name, str) or not name:
            raise SceneError(f"material {name!r}: a material name must be a non-empty string")
        law = {"friction": friction, "restitution": restitution, "cohesion": cohesion, "rolling": rolling,
               "tensile": tensile}
        _check_contact_law(f"material '{name}'", law)
        self._materials[name] = {k: float(v) for k, v in law.items()}
        return name

    @_recorded
    def set_interface(self, material_a: str, material_b: str, **law: float) -> None:
        """Contact law between two different materials (overrides the smaller-value rule).
        Keywords: any of friction, restitution, cohesion, rolling, tensile."""
        for m in (material_a, material_b):
            if m not in self._materials:
                raise SceneError(f"interface ({material_a}, {material_b}): unknown material '{m}'")
        unknown = sorted(set(law) - set(CONTACT_LAW))
        if unknown:
            raise SceneError(f"interface ({material_a}, {material_b}): unknown field '{unknown[0]}' "
                             f"(known: {', '.join(CONTACT_LAW)})")
        law = {k: v for k, v in law.items() if v is not None}
        _check_contact_law(f"interface ({material_a}, {material_b})", law)
        self._interfaces[tuple(sorted((material_a, material_b)))] = {k: float(v) for k, v in law.items()}

    # -- loads -------------------------------------------------------------------------
    @_recorded
    def add_load(self, body: int, force=(0.0, 0.0), at=None, rate=(0.0, 0.0), history=None) -> int:
        """A point load on ``body``: F(t) = force + rate * t + h(t) (N, world frame), applied
        at the material point that is at ``at`` at t = 0 (default: the centroid); the point
        moves with the body, the direction stays fixed (eqs. 2, 13). ``history``: rows
        (t, fx, fy) with non-decreasing t, a load history h(t) linear between its rows and
        held at its first and last values outside them (a step: two rows at one time).
        Returns the load index."""
        label = f"load {len(self._loads)}"
        b = self._body_of(label, body)
        point = b.center if at is None else self._point(label, "at", at)
        rows = np.zeros((1, 3))
        if history is not None:
            try:
                rows = np.asarray(history, dtype=float)
            except (TypeError, ValueError):
                raise SceneError(f"{label}: field 'history' must be rows (t, fx, fy), got {history!r}") from None
            if rows.ndim != 2 or rows.shape[1] != 3 or len(rows) == 0:
                raise SceneError(f"{label}: field 'history' must be rows (t, fx, fy), got shape {rows.shape}")
            validate.check_finite(label, "history", rows)
            back = np.flatnonzero(np.diff(rows[:, 0]) < 0)
            if len(back):
                raise SceneError(f"{label}: field 'history': the times must not decrease (row {back[0] + 1} at "
                                 f"t = {rows[back[0] + 1, 0]} follows t = {rows[back[0], 0]})")
        self._loads.append((int(body), point - b.center, self._point(label, "force", force),
                            self._point(label, "rate", rate), rows))
        return len(self._loads) - 1

    @_recorded
    def add_measured_point(self, body: int, at) -> int:
        """A measured point: the material point of ``body`` that is at ``at`` at t = 0,
        whose path ``Trajectory.measured_points()`` gives (and the CSV output writes).
        Returns its index."""
        label = f"measured point {len(self._measured)}"
        b = self._body_of(label, body)
        point = self._point(label, "at", at)
        self._check_on_body(label, "at", point, body)
        self._measured.append((int(body), point - b.center))
        return len(self._measured) - 1

    def body_at(self, point) -> int:
        """The index of the body whose material contains ``point`` (for points given
        without a body, the DDA way). On the common boundary of two bodies it is ambiguous
        (an error), except between elements of one meshed block (the field is continuous)."""
        p = self._point("point", "at", point)
        if not self._bodies:
            raise SceneError(f"the point {tuple(p.tolist())} lies in no body (no bodies were added before it)")
        shapes = [self._world_shape(b) for b in self._bodies]
        tol = 1e-9 * _scene_size(shapes)
        near = [i for i, shape in enumerate(shapes) if validate.point_outside_by(p, shape) <= tol]
        if not near:
            raise SceneError(f"the point {tuple(p.tolist())} lies in no body (give 'body')")
        inside = [i for i in near if validate.depth_inside(p, shapes[i]) > tol] or near
        meshes = {self._bodies[i].mesh for i in inside}
        if len(inside) > 1 and not (len(meshes) == 1 and -1 not in meshes):
            raise SceneError(f"the point {tuple(p.tolist())} lies on the boundary of bodies "
                             f"{', '.join(map(str, inside))} (give 'body')")
        return inside[0]

    @_recorded
    def add_fixed_point(self, body: int, at) -> int:
        """A fixed point (Shi's DDA): the material point of ``body`` that is at ``at`` (world,
        t = 0) never moves. Exact: the body's dofs are those that keep the point's
        displacement zero (eq. 7), rebuilt every step, and it turns about the point by
        the exact finite rotation. Enough points make it immobile, and it is then fixed:
        two distinct ones on a rigid body or a deformable disk or ring, three not on one
        line on a deformable polygon. On a meshed block the point must be a node, which
        is fixed (as ``add_mesh``'s ``fixed_nodes``). The body's initial velocity must be
        zero at the point (a spin about it is allowed). A point on a fixed body is allowed
        and changes nothing. Returns the fixed point's index."""
        label = f"fixed point {len(self._fixed_points)}"
        b = self._body_of(label, body)
        point = self._point(label, "at", at)
        self._check_on_body(label, "at", point, body)
        size = _body_size(b)
        if b.mesh >= 0:
            self._pin_mesh_node(label, b, point, size)
        elif not b.fixed:
            r = point - b.center
            moving = b.velocity + b.omega * np.array([-r[1], r[0]])
            if np.linalg.norm(moving) > 1e-9 * (np.linalg.norm(b.velocity) + abs(b.omega) * size):
                raise SceneError(f"{label}: {_body_label(b, body)} moves at {tuple(point.tolist())} at t = 0 "
                                 f"(velocity {tuple(moving.tolist())}): its fields 'velocity' and "
                                 f"'angular_velocity' must give zero velocity at a fixed point (a spin about it)")
            b.pins.append(point)
            if _immobile(b, size):
                b.fixed, b.velocity, b.omega = True, np.zeros(2), 0.0
        self._fixed_points.append((int(body), point))
        return len(self._fixed_points) - 1

    def _pin_mesh_node(self, label: str, b: "_Body", point: np.ndarray, size: float) -> None:
        """A fixed point on an element of a meshed block: it must be one of its nodes, which
        is then fixed in every element around it."""
        mesh = self._meshes[b.mesh]
        dist = np.linalg.norm(mesh.nodes[b.nodes] - point, axis=1)
        k = int(np.argmin(dist))
        node = int(b.nodes[k])
        if dist[k] > 1e-9 * size:
            raise SceneError(f"{label}: field 'at' {tuple(point.tolist())} is not a node of mesh {b.mesh}: a fixed "
                             f"point on a meshed block must be at one of its nodes (nearest in this element: node "
                             f"{node} at {tuple(mesh.nodes[node].tolist())})")
        elements = [self._bodies[i] for i in mesh.bodies]
        if any(np.any(e.velocity != 0) or e.omega != 0 for e in elements):
            raise SceneError(f"{label}: a block with fixed nodes cannot have a velocity (mesh {b.mesh}'s fields "
                             f"'velocity', 'angular_velocity')")
        mesh.fixed_nodes[node] = True
        for e in elements:
            if node in e.nodes:
                e.pinned = e.pinned | (e.nodes == node)
                e.fixed = bool(e.pinned.all())

    # -- connectors (paper section 5) --------------------------------------------------
    @_recorded
    def add_spring(self, body_a: int, body_b: int, at_a, at_b, stiffness: float, *, rest_length: float | None = None,
                   pretension: float = 0.0) -> int:
        """A spring of axial ``stiffness`` k (N/m) between the material points that are at
        ``at_a`` on body_a and ``at_b`` on body_b at t = 0 (eqs. 85-86). Its force is
        k (l - rest_length) + pretension along the line of the two points (tension +);
        ``rest_length`` defaults to the initial distance. Returns the connector index."""
        label = f"connector {len(self._connectors)} (spring)"
        validate.check_positive(label, "stiffness", stiffness)
        self._connector_length(label, at_a, at_b)
        return self._connect(_Connector(SPRING, label, body_a, body_b, at_a, at_b, float(stiffness), 0.0, 0.0,
                                        pretension, rest_length))

    @_recorded
    def add_bolt(self, body_a: int, body_b: int, at_a, at_b, young: float, area: float, *,
                 pretension: float = 0.0) -> int:
        """A rock bolt (link element, eqs. 74-84) of Young's modulus ``young`` (Pa) and
        cross-section ``area`` (m^2) between the material points at ``at_a`` on body_a and
        ``at_b`` on body_b at t = 0: axial stiffness E A / l, with l the initial length,
        and an initial axial force ``pretension`` (N, tension +). Returns the connector index."""
        label = f"connector {len(self._connectors)} (bolt)"
        validate.check_positive(label, "young", young)
        validate.check_positive(label, "area", area)
        length = self._connector_length(label, at_a, at_b)
        return self._connect(_Connector(BOLT, label, body_a, body_b, at_a, at_b, float(young) * float(area) / length,
                                        0.0, 0.0, pretension, None))

    @_recorded
    def add_beam(self, body_a: int, body_b: int, at_a, at_b, young: float, area: float, inertia: float, *,
                 shear_modulus: float | None = None, section: str = "rectangular") -> int:
        """An elastic beam (eqs. 87-92) clamped to body_a at ``at_a`` and to body_b at
        ``at_b`` (points at t = 0): Young's modulus ``young``, cross-section ``area``, second
        moment of area ``inertia`` (m^4); with a ``shear_modulus`` G its shear deformation
        enters through b = 12 k E / G (r / l)^2 (eq. 89; k = 1.2 for a "rectangular",
        10/9 for a "circular" ``section``), without one it is an Euler-Bernoulli beam.
        Each end turns with its body (eq. 90). Returns the connector index."""
        label = f"connector {len(self._connectors)} (beam)"
        for field, value in (("young", young), ("area", area), ("inertia", inertia)):
            validate.check_positive(label, field, value)
        if shear_modulus is not None:
            validate.check_positive(label, "shear_modulus", shear_modulus)
        if section not in SHEAR_FACTOR:
            raise SceneError(f"{label}: field 'section' must be one of {sorted(SHEAR_FACTOR)}, got {section!r}")
        length = self._connector_length(label, at_a, at_b)
        axial, bending, b = beam_coefficients(float(young), float(area), float(inertia),
                                              None if shear_modulus is None else float(shear_modulus),
                                              SHEAR_FACTOR[section], length)
        return self._connect(_Connector(BEAM, label, body_a, body_b, at_a, at_b, axial, bending, b, 0.0, None))

    # -- bodies ------------------------------------------------------------------------
    @_recorded
    def add_disk(self, center, radius, density, velocity=(0.0, 0.0), angular_velocity=0.0, fixed=False,
                 material="default", gravity=True, young=None, poisson=0.0, plane="stress", stress=None) -> int:
        """A disk (rigid: eq. 3; deformable: 4 dofs, eqs. 4-5). Returns its body index.
        Deformable with ``young`` (E > 0, Pa) and ``poisson`` (-1 < nu < 0.5), in
        ``plane`` "stress" (default) or "strain", with an initial ``stress`` (sigma_x, sigma_y,
        tau_xy) (eq. A.11, default 0); rigid when ``young`` is None.
        """
        label = self._label(DISK)
        validate.check_positive(label, "radius", radius)
        r = float(radius)
        return self._add(_Body(DISK, self._point(label, "center", center), r, 0.0, np.zeros((0, 2)),
                               geometry.disk_area(r), geometry.disk_polar_moment(r), 0.0,
                               np.zeros(2), 0.0, fixed, material, gravity, geometry.round_second_moments(r)),
                         density, velocity, angular_velocity, (young, poisson, plane, stress))

    @_recorded
    def add_ring(self, center, inner_radius, outer_radius, density, velocity=(0.0, 0.0), angular_velocity=0.0,
                 fixed=False, material="default", gravity=True, young=None, poisson=0.0, plane="stress", stress=None) -> int:
        """A ring: material between ``inner_radius`` > 0 and ``outer_radius`` (a particle).
        Deformable with ``young`` (E > 0, Pa) and ``poisson`` (-1 < nu < 0.5), in
        ``plane`` "stress" (default) or "strain", with an initial ``stress`` (sigma_x, sigma_y,
        tau_xy) (eq. A.11, default 0); rigid when ``young`` is None.
        """
        label = self._label(RING)
        validate.check_positive(label, "inner_radius", inner_radius)
        validate.check_positive(label, "outer_radius", outer_radius)
        ri, ro = float(inner_radius), float(outer_radius)
        if ri >= ro:
            raise SceneError(f"{label}: field 'inner_radius' ({ri}) must be smaller than 'outer_radius' ({ro})")
        return self._add(_Body(RING, self._point(label, "center", center), ro, ri, np.zeros((0, 2)),
                               geometry.ring_area(ro, ri), geometry.ring_polar_moment(ro, ri), 0.0,
                               np.zeros(2), 0.0, fixed, material, gravity, geometry.round_second_moments(ro, ri)),
                         density, velocity, angular_velocity, (young, poisson, plane, stress))

    @_recorded
    def add_polygon(self, vertices, density, velocity=(0.0, 0.0), angular_velocity=0.0, fixed=False,
                    material="default", gravity=True, young=None, poisson=0.0, plane="stress", stress=None,
                    edge_materials=None) -> int:
        """A simple polygon (convex or concave, either orientation; rigid: eq. 3, deformable:
        6 dofs, eqs. 6-7). ``velocity`` is that of its centroid. Returns its body index.
        Deformable with ``young`` (E > 0, Pa) and ``poisson`` (-1 < nu < 0.5), in
        ``plane`` "stress" (default) or "strain", with an initial ``stress`` (sigma_x, sigma_y,
        tau_xy) (eq. A.11, default 0); rigid when ``young`` is None. ``edge_materials``: per
        edge (vertex k to k + 1, in the order given) a material whose contact law governs
        contacts on that edge (a joint's properties), or None for the bodies' own.
        """
        label = self._label(POLYGON)
        try:
            verts = np.asarray(vertices, dtype=float)
        except (TypeError, ValueError) as err:
            raise SceneError(f"{label}: field 'vertices' is not a list of (x, y) points ({err})") from None
        if verts.ndim != 2 or verts.shape[1] != 2:
            raise SceneError(f"{label}: field 'vertices' must be a list of (x, y) points, got shape {verts.shape}")
        validate.check_finite(label, "vertices", verts)
        problem = geometry.simple_polygon_problem(verts)
        if problem is not None:
            raise SceneError(f"{label}: field 'vertices' is not a valid polygon: {problem}")
        if edge_materials is not None:
            edge_materials = list(edge_materials)
            if len(edge_materials) != len(verts):
                raise SceneError(f"{label}: field 'edge_materials' needs one entry per edge ({len(verts)}), "
                                 f"got {len(edge_materials)}")
            for k, m in enumerate(edge_materials):
                if m is not None and m not in self._materials:
                    raise SceneError(f"{label}: field 'edge_materials' names unknown material {m!r} for edge {k}")
        ccw = geometry.counter_clockwise(verts)
        if edge_materials is not None and not np.array_equal(ccw, verts):  # reversed: edge k runs k+1 -> k
            edge_materials = [edge_materials[(len(verts) - 2 - j) % len(verts)] for j in range(len(verts))]
        verts = ccw
        area, centroid, polar = geometry.polygon_properties(verts)
        local = verts - centroid
        return self._add(_Body(POLYGON, np.asarray(centroid, float), 0.0, 0.0, local, float(area),
                               float(polar), 0.0, np.zeros(2), 0.0, fixed, material, gravity,
                               geometry.polygon_second_moments(local), edge_materials=edge_materials),
                         density, velocity, angular_velocity, (young, poisson, plane, stress))

    def add_blocks(self, blocks, density, *, joints=None, fixed=(), **kwargs) -> list[int]:
        """Blocks from ``scene.cutting.cut_blocks``: each a polygon whose edges cut by joint
        line k take the contact law of material ``joints[k]`` (a dict, or one name for every
        joint; boundary edges and lines not named keep the bodies' law). ``fixed``: indices
        into ``blocks`` of fixed blocks. Other keywords go to ``add_polygon``."""
        fixed = set(int(k) for k in fixed)
        out = []
        for k, block in enumerate(blocks):
            names = [None if line < 0 else (joints if isinstance(joints, str) else (joints or {}).get(int(line)))
                     for line in block.edge_lines]
            out.append(self.add_polygon(block.vertices, density, fixed=k in fixed, edge_materials=names, **kwargs))
        return out

    # -- meshed blocks (paper section 6.1) ----------------------------------------------
    @_recorded
    def add_mesh(self, nodes, triangles, density, young, poisson=0.0, *, plane="stress", fixed_nodes=(),
                 velocity=(0.0, 0.0), angular_velocity=0.0, fixed=False, material="default", gravity=True,
                 stress=None) -> "Mesh":
        """A deformable block meshed into 3-node triangles (counter-clockwise node triples
        into ``nodes``) whose unknowns are the nodal displacements (eqs. 93-96): each
        triangle is a body whose linear field is set by its three nodes, so contacts on the
        block's boundary act through the area coordinates (eqs. 98-105). ``fixed_nodes``
        (indices) do not move; ``fixed=True`` fixes them all. The block moves at
        ``velocity`` and spins at ``angular_velocity`` about its centroid at t = 0.
        Returns a ``Mesh``: its element bodies, and an element holding each node (for loads
        and connectors at a node)."""
        label = f"mesh {len(self._meshes)}"
        nodes, triangles = mesh_lib.check_mesh(label, nodes, triangles)
        validate.check_positive(label, "density", density)
        validate.check_positive(label, "young", young)
        validate.check_flag(label, "fixed", fixed)
        try:
            pinned = np.unique(np.asarray(fixed_nodes, dtype=np.int64).reshape(-1))
        except (TypeError, ValueError):
            raise SceneError(f"{label}: field 'fixed_nodes' must be a list of node indices, got {fixed_nodes!r}") from None
        if len(pinned) and (pinned.min() < 0 or pinned.max() >= len(nodes)):
            bad = pinned[(pinned < 0) | (pinned >= len(nodes))][0]
            raise SceneError(f"{label}: field 'fixed_nodes' names node {int(bad)} outside 0..{len(nodes) - 1}")
        pinned_mask = np.zeros(len(nodes), bool)
        pinned_mask[pinned] = True
        pinned_mask |= bool(fixed)
        v = self._point(label, "velocity", velocity)
        validate.check_finite(label, "angular_velocity", angular_velocity)
        omega = float(angular_velocity)
        if pinned_mask.any() and (np.any(v != 0) or omega != 0):
            raise SceneError(f"{label}: a block with fixed nodes cannot have a velocity (fields 'velocity', "
                             f"'angular_velocity')")
        d1, d2 = nodes[triangles[:, 1]] - nodes[triangles[:, 0]], nodes[triangles[:, 2]] - nodes[triangles[:, 0]]
        area2 = d1[:, 0] * d2[:, 1] - d1[:, 1] * d2[:, 0]
        centroids = nodes[triangles].mean(1)
        center = (area2[:, None] * centroids).sum(0) / area2.sum()
        count: dict[tuple[int, int], int] = {}
        for tri in triangles.tolist():
            for i, j in zip(tri, tri[1:] + tri[:1]):
                count[(min(i, j), max(i, j))] = count.get((min(i, j), max(i, j)), 0) + 1
        index = len(self._meshes)
        bodies = []
        for k, tri in enumerate(triangles.tolist()):
            local = nodes[tri] - centroids[k]
            spin = omega * np.array([-(centroids[k][1] - center[1]), centroids[k][0] - center[0]])
            body = _Body(POLYGON, centroids[k].copy(), 0.0, 0.0, local, 0.5 * float(area2[k]),
                         *geometry.polygon_properties(nodes[tri])[2:], 0.0, np.zeros(2), 0.0,
                         bool(pinned_mask[tri].all()), material, gravity, geometry.polygon_second_moments(local),
                         mesh=index, nodes=np.asarray(tri), element=k, pinned=pinned_mask[tri],
                         edges=np.array([count[(min(i, j), max(i, j))] == 1 for i, j in zip(tri, tri[1:] + tri[:1])]))
            moving = not body.fixed
            bodies.append(self._add(body, density, v + spin if moving else (0.0, 0.0), omega if moving else 0.0,
                                    (young, poisson, plane, stress)))
        holder = np.zeros(len(nodes), np.int64)
        for k, tri in enumerate(triangles.tolist()):
            holder[tri] = bodies[k]
        mesh = Mesh(index, tuple(bodies), nodes, triangles, pinned_mask, holder)
        self._meshes.append(mesh)
        return mesh

    def add_meshed_polygon(self, vertices, density, young, poisson=0.0, *, max_edge=None, **kwargs) -> "Mesh":
        """``add_mesh`` of a simple polygon meshed by the built-in mesher (ear clipping,
        then midpoint refinement until no edge is longer than ``max_edge``)."""
        nodes, triangles = mesh_lib.mesh_polygon(vertices, max_edge, label=f"mesh {len(self._meshes)}")
        return self.add_mesh(nodes, triangles, density, young, poisson, **kwargs)

    # -- build -------------------------------------------------------------------------
    def _check_settings(self) -> None:
        """Raise SceneError (labelled "settings") for a bad dt, gravity, tol, max_iter,
        dynamic or margin; ``build`` calls it, a scene file's reader before its bodies."""
        for field in ("dt", "tol", "max_iter", "dynamic", "margin"):
            value = getattr(self, field)
            if value is not None:
                validate.check_finite("settings", field, value)
                if np.ndim(value) != 0:
                    raise SceneError(f"settings: field '{field}' must be a number, got {value!r}")
        validate.check_positive("settings", "dt", self.dt)
        validate.check_finite("settings", "gravity", self.gravity)
        if np.shape(self.gravity) != (2,):
            raise SceneError(f"settings: field 'gravity' must be (gx, gy), got {self.gravity!r}")
        validate.check_positive("settings", "tol", self.tol)
        if isinstance(self.max_iter, bool) or self.max_iter < 1 or not float(self.max_iter).is_integer():
            raise SceneError(f"settings: field 'max_iter' must be a positive integer, got {self.max_iter!r}")
        if not 0.0 <= self.dynamic <= 1.0:
            raise SceneError(f"settings: field 'dynamic' must be in [0, 1], got {self.dynamic}")
        if self.margin is not None and self.margin < 0:
            raise SceneError(f"settings: field 'margin' must be >= 0, got {self.margin}")

    def build(self) -> "Scene":
        """Validate everything and assemble the scene."""
        labels, size, margin = self._validated()
        names = list(self._materials)
        tables = self._contact_tables(names)
        g = np.asarray(self.gravity, float)
        body = _body_arrays(self._bodies, names)
        knots = _load_knots([ld[4] for ld in self._loads])
        model = self._model(body, names, knots, g, margin)
        key, force = zeros_contact_memory(model.capacity.contacts)
        state = State(time=_scalar(0.0), origin=jnp.asarray(body.centers), displacement=jnp.zeros((body.n, 2)),
                      rotation=jnp.zeros(body.n), stretch=jnp.broadcast_to(jnp.eye(2), (body.n, 2, 2)),
                      stress=jnp.asarray(np.array([b.stress for b in self._bodies])),
                      velocity=jnp.asarray(body.velocity), contact_key=key, contact_force=force,
                      joint_integrity=jnp.zeros((1,)))
        params = self._params(knots, g, tables, margin)
        if np.any(tables["tensile"] > 0):
            model, state = cement.with_joints(model, state, params, tol=1e-9 * size)
        settings = {"dt": self.dt, "gravity": tuple(g.tolist()), "tol": self.tol,
                    "max_iter": self.max_iter, "margin": self.margin, "dynamic": self.dynamic,
                    "capacities": dict(self.capacities)}
        return Scene(model, state, params, tuple(labels), tuple(names), self.name,
                     recipe=(copy.deepcopy(settings), tuple(self._recipe)), measured=tuple(self._measured))

    def _validated(self) -> tuple[list[str], float, float]:
        """Check the scene as a whole (bodies, settings, no overlap at the start, loads on
        their bodies); its bodies' labels, its size and the contact margin d0."""
        if not self._bodies:
            raise SceneError("scene: no bodies were added")
        self._check_settings()
        labels = [_body_label(b, i) for i, b in enumerate(self._bodies)]
        shapes = [self._world_shape(b) for b in self._bodies]
        size = _scene_size(shapes)
        validate.check_no_interpenetration(shapes, labels, tol=1e-9 * size, adjacent=self._adjacent_elements())
        for k, (body, offset, *_) in enumerate(self._loads):  # a point given away from the centroid: on the body
            if np.any(offset != 0):
                self._check_on_body(f"load {k}", "at", self._bodies[body].center + offset, body)
        return labels, size, 1e-6 * size if self.margin is None else float(self.margin)

    def _model(self, body: "_BodyArrays", names: list[str], knots: np.ndarray, g: np.ndarray,
               margin: float) -> Model:
        """The scene's Model: body geometry and kinds, loads (``knots``: their history's
        knots), connectors, pins, dof groups, and the buffers' first capacities."""
        bodies = self._bodies
        index = {m: k for k, m in enumerate(names)}
        capacity = initial_capacities(body.kinds, body.fixed, body.centers, body.local, body.mask, body.bound,
                                      body.velocity, self.dt, g, margin)
        capacity = dataclasses.replace(capacity, **{k: max(int(v), getattr(capacity, k))
                                                    for k, v in self.capacities.items()})
        return Model(
            kind=jnp.asarray(body.kinds), fixed=jnp.asarray(body.fixed),
            radius=jnp.asarray([b.radius for b in bodies], float),
            inner_radius=jnp.asarray([b.inner_radius for b in bodies], float),
            local_vertices=jnp.asarray(body.local), vertex_mask=jnp.asarray(body.mask),
            edge_mask=jnp.asarray(body.edges), edge_material=jnp.asarray(body.edge_material),
            n_vertices=jnp.asarray(body.mask.sum(1).astype(np.int32)),
            area=jnp.asarray([b.area for b in bodies]), polar_moment=jnp.asarray([b.polar for b in bodies]),
            bound_radius=jnp.asarray(body.bound),
            gravity_scale=jnp.asarray([1.0 if b.gravity else 0.0 for b in bodies]),
            material=jnp.asarray([index[b.material] for b in bodies], jnp.int32),
            second_moment=jnp.asarray(np.array([b.moments for b in bodies])),
            plane_strain=jnp.asarray([b.plane_strain for b in bodies]),
            dof_projector=jnp.asarray(np.array([_projector(b) for b in bodies])),
            dof_basis=jnp.asarray(np.array([_basis(b) for b in bodies])),
            mesh=jnp.asarray(np.array([b.mesh for b in bodies], np.int32)),
            load_body=jnp.asarray([ld[0] for ld in self._loads], jnp.int32),
            load_point=jnp.asarray(np.reshape([ld[1] for ld in self._loads], (-1, 2))),
            load_times=jnp.asarray(knots[..., 0]),
            joint_key=jnp.full((1,), NO_JOINT, jnp.int64), joint_a=jnp.zeros((1,), jnp.int32),
            joint_b=jnp.zeros((1,), jnp.int32), joint_point=jnp.zeros((1, 2)),
            **connector_model(self._connectors, body.centers),
            **pin_model(bodies),
            **dof_groups(bodies, self._connectors),
            capacity=capacity, n_bodies=body.n, max_vertices=body.local.shape[1])

    def _params(self, knots: np.ndarray, g: np.ndarray, tables: dict, margin: float) -> Params:
        """The scene's Params: materials, contact laws, loads and solver settings."""
        bodies = self._bodies
        return Params(dt=_scalar(self.dt), gravity=jnp.asarray(g),
                      density=jnp.asarray([b.density for b in bodies]),
                      young=jnp.asarray([b.young for b in bodies]),
                      poisson=jnp.asarray([b.poisson for b in bodies]),
                      **{field: jnp.asarray(table) for field, table in tables.items()},
                      load_force=jnp.asarray(np.reshape([ld[2] for ld in self._loads], (-1, 2))),
                      load_rate=jnp.asarray(np.reshape([ld[3] for ld in self._loads], (-1, 2))),
                      load_history=jnp.asarray(knots[..., 1:]),
                      dynamic=_scalar(self.dynamic),
                      tol=_scalar(self.tol), max_iter=_scalar(self.max_iter),
                      margin=_scalar(margin), rupture_width=_scalar(0.0),
                      **connector_params(self._connectors))

    # -- helpers -----------------------------------------------------------------------
    def _body_of(self, label: str, body, field: str = "body") -> "_Body":
        """The added body that index ``body`` names (an error naming ``field`` otherwise)."""
        if isinstance(body, bool) or not isinstance(body, (int, np.integer)) or not 0 <= body < len(self._bodies):
            raise SceneError(f"{label}: field '{field}' must be the index of an added body, got {body!r}")
        return self._bodies[body]

    def _check_on_body(self, label: str, field: str, point: np.ndarray, body: int) -> None:
        """``point`` must lie in or on ``body`` (to round-off of its size)."""
        b = self._bodies[body]
        size = _body_size(b)
        outside = validate.point_outside_by(point, self._world_shape(b))
        if outside > 1e-9 * size:
            raise SceneError(f"{label}: field '{field}' {tuple(point.tolist())} lies {outside:.3g} m outside "
                             f"{_body_label(b, body)}")

    def _connector_length(self, label: str, at_a, at_b) -> float:
        """The distance of the two attachment points (an error if they coincide)."""
        length = float(np.linalg.norm(self._point(label, "at_b", at_b) - self._point(label, "at_a", at_a)))
        if length == 0.0:
            raise SceneError(f"{label}: zero length (fields 'at_a' and 'at_b' are the same point)")
        return length

    def _connect(self, conn: "_Connector") -> int:
        """Validate a connector's bodies, points and numbers, and keep it."""
        label = conn.label
        for field in ("body_a", "body_b"):
            self._body_of(label, getattr(conn, field), field)
        if conn.body_a == conn.body_b:
            raise SceneError(f"{label}: fields 'body_a' and 'body_b' name the same body {conn.body_a}")
        conn.at_a, conn.at_b = self._point(label, "at_a", conn.at_a), self._point(label, "at_b", conn.at_b)
        for field, body, point in (("at_a", conn.body_a, conn.at_a), ("at_b", conn.body_b, conn.at_b)):
            self._check_on_body(label, field, point, body)
        validate.check_finite(label, "pretension", conn.pretension)
        conn.pretension = float(conn.pretension)
        if conn.rest_length is not None:
            validate.check_finite(label, "rest_length", conn.rest_length)
            if conn.rest_length < 0:
                raise SceneError(f"{label}: field 'rest_length' must be >= 0, got {conn.rest_length}")
        self._connectors.append(conn)
        return len(self._connectors) - 1

    def _adjacent_elements(self) -> set[tuple[int, int]]:
        """Pairs of element bodies of one mesh that share a node (they touch by construction)."""
        by_node: dict[tuple[int, int], list[int]] = {}
        for i, b in enumerate(self._bodies):
            if b.mesh >= 0:
                for node in b.nodes.tolist():
                    by_node.setdefault((b.mesh, node), []).append(i)
        return {(i, j) for group in by_node.values() for i in group for j in group if i < j}

    def _label(self, kind: int, index: int | None = None) -> str:
        return f"body {len(self._bodies) if index is None else index} ({KIND_NAMES[kind]})"

    @staticmethod
    def _point(label: str, field: str, value) -> np.ndarray:
        try:
            p = np.asarray(value, dtype=float)
        except (TypeError, ValueError):
            raise SceneError(f"{label}: field '{field}' must be a pair of numbers, got {value!r}") from None
        if p.shape != (2,):
            raise SceneError(f"{label}: field '{field}' must be a pair of numbers, got {value!r}")
        validate.check_finite(label, field, p)
        return p

    def _add(self, body: _Body, density, velocity, omega, elastic) -> int:
        label = _body_label(body, len(self._bodies))
        validate.check_positive(label, "density", density)
        young, poisson, plane, stress = elastic
        body.stress = np.zeros(3)
        if stress is not None:
            if young is None:
                raise SceneError(f"{label}: field 'stress' needs a deformable body (give 'young')")
            body.stress = np.asarray(stress, float) if np.shape(stress) == (3,) else None
            if body.stress is None:
                raise SceneError(f"{label}: field 'stress' must be (sigma_x, sigma_y, tau_xy), got {stress!r}")
            validate.check_finite(label, "stress", body.stress)
        if young is not None:
            validate.check_positive(label, "young", young)
            validate.check_finite(label, "poisson", poisson)
            if not -1.0 < poisson < 0.5:
                raise SceneError(f"{label}: field 'poisson' must be in (-1, 0.5), got {poisson}")
            if plane not in ("stress", "strain"):
                raise SceneError(f"{label}: field 'plane' must be \"stress\" or \"strain\", got {plane!r}")
            body.young, body.poisson, body.plane_strain = float(young), float(poisson), plane == "strain"
        body.density = float(density)
        body.velocity = self._point(label, "velocity", velocity)
        validate.check_finite(label, "angular_velocity", omega)
        body.omega = float(omega)
        validate.check_flag(label, "fixed", body.fixed)
        validate.check_flag(label, "gravity", body.gravity)
        if not isinstance(body.material, str) or body.material not in self._materials:
            raise SceneError(f"{label}: field 'material' names unknown material '{body.material}' "
                             f"(known: {', '.join(self._materials)}); declare it with add_material")
        if body.fixed and (np.any(body.velocity != 0) or body.omega != 0):
            raise SceneError(f"{label}: a fixed body cannot have a velocity (fields 'velocity', 'angular_velocity')")
        body.fixed, body.gravity = bool(body.fixed), bool(body.gravity)
        self._bodies.append(body)
        return len(self._bodies) - 1

    def _contact_tables(self, names: list[str]) -> dict[str, np.ndarray]:
        """(M, M) table per field of the contact law."""
        m = len(names)
        tables = {field: np.zeros((m, m)) for field in CONTACT_LAW}
        for i, a in enumerate(names):
            for j, b in enumerate(names):
                law = self._interfaces.get(tuple(sorted((a, b))), {})
                for field, table in tables.items():
                    table[i, j] = law.get(field, min(self._materials[a][field], self._materials[b][field]))
        return tables

    @staticmethod
    def _world_shape(b: _Body):
        if b.kind == DISK:
            return ("disk", b.center, b.radius)
        if b.kind == RING:
            return ("ring", b.center, b.radius, b.inner_radius)
        return ("polygon", b.local + b.center)


@dataclasses.dataclass
class _Connector:
    kind: int
    label: str
    body_a: int
    body_b: int
    at_a: np.ndarray  # world points at t = 0
    at_b: np.ndarray
    axial: float  # N/m
    bending: float  # E I
    shear: float  # b of eq. 89
    pretension: float
    rest_length: float | None  # None: the initial length


def connector_model(connectors: list[_Connector], centers: np.ndarray) -> dict:
    """The Model fields of the connectors."""
    k = len(connectors)
    a = np.array([c.body_a for c in connectors], np.int32)
    b = np.array([c.body_b for c in connectors], np.int32)
    pa = np.reshape([c.at_a - centers[c.body_a] for c in connectors], (k, 2))
    pb = np.reshape([c.at_b - centers[c.body_b] for c in connectors], (k, 2))
    chord = np.reshape([c.at_b - c.at_a for c in connectors], (k, 2))
    length = np.linalg.norm(chord, axis=1)
    rest = np.array([length[i] if c.rest_length is None else c.rest_length for i, c in enumerate(connectors)])
    return dict(connector_kind=jnp.asarray([c.kind for c in connectors], jnp.int32).reshape(k),
                connector_a=jnp.asarray(a), connector_b=jnp.asarray(b), connector_pa=jnp.asarray(pa),
                connector_pb=jnp.asarray(pb), connector_length=jnp.asarray(rest.reshape(k)),
                connector_chord0=jnp.asarray(chord / np.where(length > 0, length, 1.0)[:, None]))


def connector_params(connectors: list[_Connector]) -> dict:
    def field(name):
        return jnp.asarray(np.array([getattr(c, name) for c in connectors], float).reshape(len(connectors)))

    return dict(connector_axial=field("axial"), connector_bending=field("bending"), connector_shear=field("shear"),
                connector_pretension=field("pretension"))


def dof_groups(bodies: list[_Body], connectors: list[_Connector]) -> dict:
    """The Model fields of the dof groups (groups.py): bodies tied by connectors, directly
    or through others, and the elements of a meshed block share one group. A body tied by
    connectors owns 6 reduced dofs (those of its active subspace); an element's are its
    three nodes' (u, v), shared with the elements around each node; fixed nodes have none."""
    n = len(bodies)
    parent = np.arange(n)

    def root(i):
        while parent[i] != i:
            parent[i] = parent[parent[i]]
            i = parent[i]
        return i

    ties = [(c.body_a, c.body_b) for c in connectors]
    first: dict[int, int] = {}
    for i, b in enumerate(bodies):
        if b.mesh >= 0:
            ties.append((first.setdefault(b.mesh, i), i))
    tied = np.array([bool(_pin_records(b)) for b in bodies], bool).reshape(n)  # a pinned body: a group of its own
    for i, j in ties:
        parent[root(i)] = root(j)
        tied[[i, j]] = True
    comps: dict[int, list[int]] = {}
    for i in np.flatnonzero(tied).tolist():
        comps.setdefault(root(i), []).append(i)
    groups = list(comps.values())
    size = max([len(g) for g in groups], default=0)
    members = -np.ones((len(groups), size), np.int32)
    dofs = -np.ones((len(groups), size, NDOF), np.int32)
    count = np.zeros(len(groups), np.int64)
    body_group, body_slot = -np.ones(n, np.int32), -np.ones(n, np.int32)
    for g, group in enumerate(groups):
        members[g, : len(group)] = group
        body_group[group], body_slot[group] = g, np.arange(len(group))
        node_dof: dict[tuple[int, int], int] = {}
        for s, i in enumerate(group):
            b = bodies[i]
            if b.mesh >= 0:
                for k, node in enumerate(b.nodes.tolist()):
                    if b.pinned[k]:
                        continue
                    if (b.mesh, node) not in node_dof:
                        node_dof[(b.mesh, node)] = count[g]
                        count[g] += 2
                    dofs[g, s, 2 * k: 2 * k + 2] = node_dof[(b.mesh, node)] + np.arange(2)
            else:
                active = np.flatnonzero(np.abs(_basis(b)).sum(0) > 0)
                roles = [role for _, role in _pin_records(b)]
                if roles:  # the pin keeps u0, v0 (its map's first columns are zero); two pins: 2 dofs
                    active = np.array([2, 3]) if 1 in roles else active[active >= 2]
                dofs[g, s, active] = count[g] + np.arange(len(active))
                count[g] += len(active)
    r = int(max(count.max(initial=0), 1))
    free = np.arange(r)[None, :] < count[:, None]
    return dict(group_members=jnp.asarray(members), group_dofs=jnp.asarray(dofs), group_free=jnp.asarray(free),
                body_group=jnp.asarray(body_group), body_slot=jnp.asarray(body_slot))


def _load_knots(histories: list[np.ndarray]) -> np.ndarray:
    """(L, K, 3) load histories padded to a common K by repeating each one's last row."""
    k = max([len(h) for h in histories] + [1])
    return np.reshape([np.concatenate([h, np.repeat(h[-1:], k - len(h), 0)]) for h in histories], (-1, k, 3))


def _check_contact_law(label: str, law: dict) -> None:
    for field, value in law.items():
        validate.check_finite(label, field, value)
        if np.ndim(value) != 0:
            raise SceneError(f"{label}: field '{field}' must be a number, got {value!r}")
        if value < 0:
            raise SceneError(f"{label}: field '{field}' must be >= 0, got {value}")
    if law.get("restitution", 0.0) > 1.0:
        raise SceneError(f"{label}: field 'restitution' must be in [0, 1], got {law['restitution']}")


def _body_size(b: _Body) -> float:
    """The largest distance from the centroid to the boundary (the bound radius)."""
    return b.radius if b.kind != POLYGON else float(np.max(np.linalg.norm(b.local, axis=1)))


def _immobile(b: _Body, size: float) -> bool:
    """Whether the body's fixed points leave it no motion: two distinct ones on a rigid
    body or a particle, three not on one line on a deformable polygon."""
    first = b.pins[0]
    far = max(b.pins, key=lambda p: float(np.linalg.norm(p - first)))
    span = float(np.linalg.norm(far - first))
    if span <= 1e-9 * size:
        return False
    if b.young == 0.0 or b.kind != POLYGON:
        return True
    axis = (far - first) / span
    return any(abs(axis[0] * (p - first)[1] - axis[1] * (p - first)[0]) > 1e-9 * size for p in b.pins)


def _pin_records(b: _Body) -> list[tuple[np.ndarray, int]]:
    """The fixed points that constrain a movable body (pins.py): the centre it turns about
    (role 0) and, on a deformable polygon whose points are on one line, the farthest
    distinct one (role 1); the others are redundant."""
    if b.fixed or b.mesh >= 0 or not b.pins:
        return []
    first = b.pins[0]
    far = max(b.pins, key=lambda p: float(np.linalg.norm(p - first)))
    if np.linalg.norm(far - first) <= 1e-9 * _body_size(b):
        return [(first, 0)]
    return [(first, 0), (far, 1)]


def pin_model(bodies: list[_Body]) -> dict:
    """The Model fields of the fixed points (per record: body, world point, role)."""
    records = [(i, p, role) for i, b in enumerate(bodies) for p, role in _pin_records(b)]
    return dict(pin_body=jnp.asarray(np.array([r[0] for r in records], np.int32).reshape(-1)),
                pin_point=jnp.asarray(np.reshape([r[1] for r in records], (-1, 2)).astype(float)),
                pin_role=jnp.asarray(np.array([r[2] for r in records], np.int32).reshape(-1)))


def _basis(b: _Body) -> np.ndarray:
    """An orthonormal basis of the body's active dof subspace as columns (zero columns pad)."""
    p = _projector(b)
    basis = p.copy()
    if np.allclose(p, PARTICLE_PROJECTOR):  # e0, e1, e2, (e3 + e4) / sqrt 2
        basis = RIGID_PROJECTOR.copy()
        basis[3:5, 3] = np.sqrt(0.5)
    return basis


def _body_label(b: _Body, index: int) -> str:
    if b.mesh >= 0:
        return f"body {index} (element {b.element} of mesh {b.mesh})"
    return f"body {index} ({KIND_NAMES[b.kind]})"


def _projector(b: _Body) -> np.ndarray:
    """The body's active dof subspace: none when fixed, 3 rigid, 4 a deformable particle, 6
    a deformable polygon."""
    if b.fixed:
        return np.zeros((NDOF, NDOF))
    if b.young == 0.0:
        return RIGID_PROJECTOR
    return PARTICLE_PROJECTOR if b.kind != POLYGON else np.eye(NDOF)


def _scene_size(shapes) -> float:
    """Largest extent of the scene's bounding box (1 for a single point)."""
    pts = [s[1] if s[0] == "polygon" else np.asarray(s[1]) + np.array([[s[2], s[2]], [-s[2], -s[2]]])
           for s in shapes]
    extent = float(np.max(np.ptp(np.concatenate(pts), axis=0)))
    return extent if extent > 0 else 1.0
