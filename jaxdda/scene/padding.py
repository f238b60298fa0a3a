"""Pad scenes of different sizes to one shape, so that ``vmap`` can batch them.

A padding body is void (``types.VOID``: the broad phase never pairs it), fixed and
weightless; padding polygon vertices are masked out; padding materials, loads and joints
are inert (zero tables, zero forces, no joint key). Contact keys, which encode the body
count and the vertex slots, are renumbered (``keys.renumber``), so a state after some
steps (its contact memory) pads as well as one as built.
"""
from __future__ import annotations

import dataclasses
from typing import Sequence

import jax
import jax.numpy as jnp
import numpy as np

from jaxdda.contact.keys import renumber
from jaxdda.scene.capacity import capacity_class, size_class
from jaxdda.scene.builder import Scene
from jaxdda.types import NO_JOINT, VOID, Capacities, Model, Params, State


@dataclasses.dataclass(frozen=True)
class Shape:
    """The padded sizes: bodies, polygon vertices, materials, loads, joints, buffers."""

    bodies: int
    vertices: int
    materials: int
    loads: int
    knots: int
    joints: int
    connectors: int
    groups: int
    group_size: int
    group_dofs: int
    pins: int
    capacity: Capacities

    @staticmethod
    def covering(scenes: Sequence[Scene]) -> "Shape":
        def most(f):
            return max(f(s) for s in scenes)

        caps = [dataclasses.astuple(s.model.capacity) for s in scenes]
        return Shape(most(lambda s: s.model.n_bodies), most(lambda s: s.model.max_vertices),
                     most(lambda s: s.params.friction.shape[0]), most(lambda s: s.model.load_body.shape[0]),
                     most(lambda s: s.model.load_times.shape[1]),
                     most(lambda s: s.model.joint_key.shape[0]), most(lambda s: s.model.connector_a.shape[0]),
                     most(lambda s: s.model.group_members.shape[0]), most(lambda s: s.model.group_members.shape[1]),
                     most(lambda s: s.model.group_free.shape[1]),
                     most(lambda s: s.model.pin_body.shape[0]),
                     Capacities(*np.max(caps, 0).tolist()))

    def bucket(self) -> "Shape":
        """The size class of this shape: each size rounded up to a number of 3 significant
        bits (16, 20, 24, 28, 32, 40, ...: at most 1/4 more) and to a small least size, so
        that scenes of similar size share one compiled program (``simulate``). Buffer
        capacities have no least size (the builder's first guesses are classes already).
        Connectors, pins and dof groups keep their sizes: their presence changes the step's
        program, and a group's reduced system is solved densely."""
        return dataclasses.replace(
            self, bodies=size_class(self.bodies, 16), vertices=size_class(self.vertices, 4),
            materials=size_class(self.materials, 4), loads=size_class(self.loads, 0), knots=size_class(self.knots, 2),
            joints=size_class(self.joints, 4), capacity=capacity_class(self.capacity))


def _pad(x, size: int, fill, axis: int = 0):
    x = np.asarray(x)
    extra = size - x.shape[axis]
    if extra == 0:
        return x
    shape = list(x.shape)
    shape[axis] = extra
    return np.concatenate([x, np.full(shape, fill, x.dtype)], axis)


def _pad_knots(x, size: int):
    """Pad a load history's knots (axis 1) by repeating the last: the same history."""
    x = np.asarray(x)
    extra = size - x.shape[1]
    return x if extra == 0 else np.concatenate([x, np.repeat(x[:, -1:], extra, 1)], 1)


def pad_scene(scene: Scene, shape: Shape) -> tuple[Model, State, Params]:
    """(model, state, params) of ``scene`` padded to ``shape`` (numpy leaves)."""
    m, s, p = scene.model, scene.state, scene.params
    n, extra = m.n_bodies, shape.bodies - m.n_bodies
    size = float(np.median(np.asarray(m.bound_radius)))  # a padding body's (inert) size

    def bodies(x, fill):
        return _pad(x, shape.bodies, fill)

    verts = _pad(np.asarray(m.local_vertices), shape.vertices, 0.0, axis=1)
    model = dataclasses.replace(
        m,
        kind=bodies(m.kind, VOID), fixed=bodies(m.fixed, True), radius=bodies(m.radius, size),
        inner_radius=bodies(m.inner_radius, 0.0), local_vertices=bodies(verts, 0.0),
        vertex_mask=bodies(_pad(np.asarray(m.vertex_mask), shape.vertices, False, axis=1), False),
        edge_mask=bodies(_pad(np.asarray(m.edge_mask), shape.vertices, False, axis=1), False),
        edge_material=bodies(_pad(np.asarray(m.edge_material), shape.vertices, -1, axis=1), -1),
        n_vertices=bodies(m.n_vertices, 0), area=bodies(m.area, np.pi * size ** 2),
        polar_moment=bodies(m.polar_moment, 0.5 * np.pi * size ** 4),
        second_moment=bodies(m.second_moment, 0.0), plane_strain=bodies(m.plane_strain, False),
        bound_radius=bodies(m.bound_radius, size), gravity_scale=bodies(m.gravity_scale, 0.0),
        material=bodies(m.material, 0), dof_projector=bodies(m.dof_projector, 0.0),
        dof_basis=bodies(m.dof_basis, 0.0), mesh=bodies(m.mesh, -1),
        load_body=_pad(m.load_body, shape.loads, 0), load_point=_pad(m.load_point, shape.loads, 0.0),
        load_times=_pad(_pad_knots(m.load_times, shape.knots), shape.loads, 0.0),
        joint_key=renumber(_pad(m.joint_key, shape.joints, NO_JOINT), m.kind, n, m.max_vertices, shape.bodies,
                           shape.vertices),
        joint_a=_pad(m.joint_a, shape.joints, 0),
        joint_b=_pad(m.joint_b, shape.joints, 0), joint_point=_pad(m.joint_point, shape.joints, 0.0),
        **{f: _pad(getattr(m, f), shape.connectors, fill)  # inert padding connectors: zero stiffness
           for f, fill in (("connector_kind", 0), ("connector_a", 0), ("connector_b", 1), ("connector_pa", 0.0),
                           ("connector_pb", 0.0), ("connector_length", 1.0), ("connector_chord0", 1.0))},
        pin_body=_pad(m.pin_body, shape.pins, 0), pin_point=_pad(m.pin_point, shape.pins, 0.0),
        pin_role=_pad(m.pin_role, shape.pins, -1),  # inert padding pins
        group_members=_pad(_pad(np.asarray(m.group_members), shape.group_size, -1, axis=1), shape.groups, -1),
        group_dofs=_pad(_pad(np.asarray(m.group_dofs), shape.group_size, -1, axis=1), shape.groups, -1),
        group_free=_pad(_pad(np.asarray(m.group_free), shape.group_dofs, False, axis=1), shape.groups, False),
        body_group=bodies(m.body_group, -1), body_slot=bodies(m.body_slot, -1),
        capacity=shape.capacity, n_bodies=shape.bodies, max_vertices=shape.vertices)

    def table(x):
        return _pad(_pad(x, shape.materials, 0.0, 0), shape.materials, 0.0, 1)

    params = dataclasses.replace(
        p, density=bodies(p.density, 1.0), young=bodies(p.young, 0.0), poisson=bodies(p.poisson, 0.0),
        friction=table(p.friction), restitution=table(p.restitution), cohesion=table(p.cohesion),
        rolling=table(p.rolling), tensile=table(p.tensile),
        load_force=_pad(p.load_force, shape.loads, 0.0), load_rate=_pad(p.load_rate, shape.loads, 0.0),
        load_history=_pad(_pad_knots(p.load_history, shape.knots), shape.loads, 0.0),
        **{f: _pad(getattr(p, f), shape.connectors, 0.0)
           for f in ("connector_axial", "connector_bending", "connector_shear", "connector_pretension")})
    c = shape.capacity.contacts
    state = dataclasses.replace(
        s, origin=bodies(s.origin, 0.0), displacement=bodies(s.displacement, 0.0),
        rotation=bodies(s.rotation, 0.0), velocity=bodies(s.velocity, 0.0),
        stretch=bodies(s.stretch, 0.0) + np.concatenate([np.zeros((n, 2, 2)), np.tile(np.eye(2), (extra, 1, 1))]),
        stress=bodies(s.stress, 0.0), contact_force=_pad(s.contact_force, c, 0.0),
        contact_key=_pad(renumber(s.contact_key, m.kind, n, m.max_vertices, shape.bodies, shape.vertices), c, -1),
        joint_integrity=_pad(s.joint_integrity, shape.joints, 0.0))
    return model, state, params


def unpad_state(state: State, scene: Scene, shape: Shape, leading: int = 0, keys: bool = True) -> State:
    """A state of ``scene`` padded to ``shape`` (``pad_scene``) brought back to the scene's
    own shape: its bodies and joints, and its contact memory renumbered (the contact
    capacity is kept). ``leading``: axes before the body axis (stacked states); without
    ``keys`` the contact keys are left as they are (a tangent's integer zeros)."""
    m, n = scene.model, scene.model.n_bodies
    lead = (slice(None),) * leading
    per_body = ("origin", "displacement", "rotation", "velocity", "stretch", "stress")
    key = state.contact_key
    return dataclasses.replace(
        state, **{f: np.asarray(getattr(state, f))[lead + (slice(n),)] for f in per_body},
        joint_integrity=np.asarray(state.joint_integrity)[lead + (slice(m.joint_key.shape[0]),)],
        contact_key=renumber(key, m.kind, shape.bodies, shape.vertices, n, m.max_vertices) if keys else key)


def stack_scenes(scenes: Sequence[Scene]) -> tuple[Model, State, Params]:
    """Every scene padded to a common shape and stacked on a leading batch axis."""
    shape = Shape.covering(scenes)
    padded = [pad_scene(s, shape) for s in scenes]
    return jax.tree.map(lambda *xs: jnp.asarray(np.stack(xs)), *padded)
