"""SceneBuilder: bodies and materials in, a validated (Model, State, Params) out."""
from __future__ import annotations

import dataclasses
import math
from typing import Sequence

import jax.numpy as jnp
import numpy as np

from jaxdda.bodies import geometry
from jaxdda.errors import SceneError
from jaxdda.scene import validate
from jaxdda.scene.capacity import initial_capacities
from jaxdda.types import DISK, KIND_NAMES, NDOF, POLYGON, RING, Model, Params, State, zeros_contact_memory

RIGID_PROJECTOR = np.diag([1.0, 1.0, 1.0, 0.0, 0.0, 0.0])


@dataclasses.dataclass(frozen=True)
class Scene:
    """A ready-to-run scene: ``step(scene.model, scene.state, scene.params)``."""

    model: Model
    state: State
    params: Params
    labels: tuple[str, ...]  # "body 3 (disk)" etc., used in messages and plots
    materials: tuple[str, ...]
    name: str = "scene"

    @property
    def n_bodies(self) -> int:
        return self.model.n_bodies


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


class SceneBuilder:
    """Collects bodies and materials; ``build()`` validates them and returns a Scene.

    Units are SI (m, kg, s). Gravity acts on every body unless it is added with
    ``gravity=False``. A contact between two bodies of one material uses that material's
    friction and restitution; a mixed pair uses the smaller of the two values unless an
    interface is declared with ``set_interface``.
    """

    def __init__(self, dt: float, gravity: Sequence[float] = (0.0, -9.81), *, tol: float = 1e-12,
                 max_iter: int = 5000, margin: float | None = None, name: str = "scene"):
        self.dt, self.gravity, self.tol, self.max_iter, self.margin, self.name = dt, gravity, tol, max_iter, margin, name
        self._bodies: list[_Body] = []
        self._materials: dict[str, dict[str, float]] = {"default": {"friction": 0.0, "restitution": 1.0}}
        self._interfaces: dict[tuple[str, str], dict[str, float]] = {}

    # -- materials ---------------------------------------------------------------------
    def add_material(self, name: str, friction: float = 0.0, restitution: float = 1.0) -> str:
        """Declare (or redefine) a material: Coulomb friction mu >= 0, restitution e in [0, 1].

        The built-in "default" material is frictionless and perfectly elastic (e = 1).
        """
        if not isinstance(name, str) or not name:
            raise SceneError(f"material {name!r}: a material name must be a non-empty string")
        _check_contact_law(f"material '{name}'", friction, restitution)
        self._materials[name] = {"friction": float(friction), "restitution": float(restitution)}
        return name

    def set_interface(self, material_a: str, material_b: str, *, friction: float | None = None,
                      restitution: float | None = None) -> None:
        """Contact law between two different materials (overrides the smaller-value rule)."""
        for m in (material_a, material_b):
            if m not in self._materials:
                raise SceneError(f"interface ({material_a}, {material_b}): unknown material '{m}'")
        law = {k: v for k, v in (("friction", friction), ("restitution", restitution)) if v is not None}
        _check_contact_law(f"interface ({material_a}, {material_b})", law.get("friction", 0.0),
                           law.get("restitution", 1.0))
        self._interfaces[tuple(sorted((material_a, material_b)))] = law

    # -- bodies ------------------------------------------------------------------------
    def add_disk(self, center, radius, density, velocity=(0.0, 0.0), angular_velocity=0.0, fixed=False,
                 material="default", gravity=True) -> int:
        """A rigid disk (paper Section 2, eq. 3). Returns its body index."""
        label = self._label(DISK)
        validate.check_positive(label, "radius", radius)
        r = float(radius)
        return self._add(_Body(DISK, self._point(label, "center", center), r, 0.0, np.zeros((0, 2)),
                               geometry.disk_area(r), geometry.disk_polar_moment(r), 0.0,
                               np.zeros(2), 0.0, fixed, material, gravity), density, velocity, angular_velocity)

    def add_ring(self, center, inner_radius, outer_radius, density, velocity=(0.0, 0.0), angular_velocity=0.0,
                 fixed=False, material="default", gravity=True) -> int:
        """A rigid ring: material between ``inner_radius`` > 0 and ``outer_radius``."""
        label = self._label(RING)
        validate.check_positive(label, "inner_radius", inner_radius)
        validate.check_positive(label, "outer_radius", outer_radius)
        ri, ro = float(inner_radius), float(outer_radius)
        if ri >= ro:
            raise SceneError(f"{label}: field 'inner_radius' ({ri}) must be smaller than 'outer_radius' ({ro})")
        return self._add(_Body(RING, self._point(label, "center", center), ro, ri, np.zeros((0, 2)),
                               geometry.ring_area(ro, ri), geometry.ring_polar_moment(ro, ri), 0.0,
                               np.zeros(2), 0.0, fixed, material, gravity), density, velocity, angular_velocity)

    def add_polygon(self, vertices, density, velocity=(0.0, 0.0), angular_velocity=0.0, fixed=False,
                    material="default", gravity=True) -> int:
        """A rigid simple polygon (convex or concave, either orientation). ``velocity`` is
        that of its centroid. Returns its body index."""
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
        verts = geometry.counter_clockwise(verts)
        area, centroid, polar = geometry.polygon_properties(verts)
        return self._add(_Body(POLYGON, np.asarray(centroid, float), 0.0, 0.0, verts - centroid, float(area),
                               float(polar), 0.0, np.zeros(2), 0.0, fixed, material, gravity),
                         density, velocity, angular_velocity)

    # -- build -------------------------------------------------------------------------
    def build(self) -> "Scene":
        """Validate everything and assemble the scene."""
        if not self._bodies:
            raise SceneError("scene: no bodies were added")
        validate.check_positive("scene", "dt", self.dt)
        g = np.asarray(self.gravity, float)
        if g.shape != (2,):
            raise SceneError(f"scene: field 'gravity' must be (gx, gy), got {self.gravity!r}")
        validate.check_finite("scene", "gravity", g)
        validate.check_positive("scene", "tol", self.tol)
        validate.check_positive("scene", "max_iter", self.max_iter)
        labels = [self._label(b.kind, i) for i, b in enumerate(self._bodies)]
        shapes = [self._world_shape(b) for b in self._bodies]
        size = _scene_size(shapes)
        validate.check_no_interpenetration(shapes, labels, tol=1e-9 * size)
        if self.margin is not None:
            validate.check_finite("scene", "margin", self.margin)
            if self.margin < 0:
                raise SceneError(f"scene: field 'margin' must be >= 0, got {self.margin}")
        margin = 1e-6 * size if self.margin is None else float(self.margin)

        names = list(self._materials)
        mat_index = {m: k for k, m in enumerate(names)}
        friction, restitution = self._contact_tables(names)
        n = len(self._bodies)
        v_max = max([len(b.local) for b in self._bodies] + [1])
        local = np.zeros((n, v_max, 2))
        mask = np.zeros((n, v_max), bool)
        for i, b in enumerate(self._bodies):
            local[i, : len(b.local)] = b.local
            mask[i, : len(b.local)] = True
        kinds = np.array([b.kind for b in self._bodies], np.int32)
        bound = np.array([b.radius if b.kind != POLYGON else np.max(np.linalg.norm(b.local, axis=1))
                          for b in self._bodies])
        fixed = np.array([b.fixed for b in self._bodies], bool)
        centers = np.array([b.center for b in self._bodies])
        velocity = np.zeros((n, NDOF))
        velocity[:, :2] = [b.velocity for b in self._bodies]
        velocity[:, 2] = [b.omega for b in self._bodies]
        capacity = initial_capacities(kinds, fixed, centers, local, mask, bound, velocity, self.dt, g, margin)
        model = Model(
            kind=jnp.asarray(kinds), fixed=jnp.asarray(fixed),
            radius=jnp.asarray([b.radius for b in self._bodies], float),
            inner_radius=jnp.asarray([b.inner_radius for b in self._bodies], float),
            local_vertices=jnp.asarray(local), vertex_mask=jnp.asarray(mask),
            n_vertices=jnp.asarray(mask.sum(1).astype(np.int32)),
            area=jnp.asarray([b.area for b in self._bodies]), polar_moment=jnp.asarray([b.polar for b in self._bodies]),
            bound_radius=jnp.asarray(bound),
            gravity_scale=jnp.asarray([1.0 if b.gravity else 0.0 for b in self._bodies]),
            material=jnp.asarray([mat_index[b.material] for b in self._bodies], jnp.int32),
            dof_projector=jnp.asarray(np.where(fixed[:, None, None], 0.0, RIGID_PROJECTOR)),
            capacity=capacity, n_bodies=n, max_vertices=v_max)
        key, force = zeros_contact_memory(capacity.contacts)
        state = State(time=jnp.asarray(0.0), origin=jnp.asarray(centers), displacement=jnp.zeros((n, 2)),
                      rotation=jnp.zeros(n),
                      velocity=jnp.asarray(velocity), contact_key=key, contact_force=force)
        params = Params(dt=jnp.asarray(float(self.dt)), gravity=jnp.asarray(g),
                        density=jnp.asarray([b.density for b in self._bodies]), friction=jnp.asarray(friction),
                        restitution=jnp.asarray(restitution), tol=jnp.asarray(float(self.tol)),
                        max_iter=jnp.asarray(float(self.max_iter)), margin=jnp.asarray(margin))
        return Scene(model, state, params, tuple(labels), tuple(names), self.name)

    # -- helpers -----------------------------------------------------------------------
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

    def _add(self, body: _Body, density, velocity, omega) -> int:
        label = self._label(body.kind)
        validate.check_positive(label, "density", density)
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

    def _contact_tables(self, names: list[str]):
        m = len(names)
        friction, restitution = np.zeros((m, m)), np.zeros((m, m))
        for i, a in enumerate(names):
            for j, b in enumerate(names):
                law = self._interfaces.get(tuple(sorted((a, b))), {})
                ma, mb = self._materials[a], self._materials[b]
                friction[i, j] = law.get("friction", min(ma["friction"], mb["friction"]))
                restitution[i, j] = law.get("restitution", min(ma["restitution"], mb["restitution"]))
        return friction, restitution

    @staticmethod
    def _world_shape(b: _Body):
        if b.kind == DISK:
            return ("disk", b.center, b.radius)
        if b.kind == RING:
            return ("ring", b.center, b.radius, b.inner_radius)
        return ("polygon", b.local + b.center)


def _check_contact_law(label: str, friction: float, restitution: float) -> None:
    for field, value in (("friction", friction), ("restitution", restitution)):
        validate.check_finite(label, field, value)
        if np.ndim(value) != 0:
            raise SceneError(f"{label}: field '{field}' must be a number, got {value!r}")
    if friction < 0:
        raise SceneError(f"{label}: field 'friction' must be >= 0, got {friction}")
    if not 0.0 <= restitution <= 1.0:
        raise SceneError(f"{label}: field 'restitution' must be in [0, 1], got {restitution}")


def _scene_size(shapes) -> float:
    """Largest extent of the scene's bounding box (1 for a single point)."""
    pts = [s[1] if s[0] == "polygon" else np.asarray(s[1]) + np.array([[s[2], s[2]], [-s[2], -s[2]]])
           for s in shapes]
    extent = float(np.max(np.ptp(np.concatenate(pts), axis=0)))
    return extent if extent > 0 else 1.0
