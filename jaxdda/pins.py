"""Fixed points: material points of a body pinned to the ground, exactly (a constraint on
the body's dofs, not a penalty spring; ``SceneBuilder.add_fixed_point``).

A pin at the world point p constrains the body's displacement there: T(p) d = 0 (eq. 7).
A movable pinned body is solved through the dof groups (groups.py): its 6 dofs are
``map @ q`` with the map's columns a basis of the constraints' null space in its active
subspace, rebuilt each step from the current geometry:

* one pin (the *centre*): d = A(r) d' with A(r) = I - E T(r) (E puts a 2-vector on
  u0, v0; r = p - c): the body turns and strains about the pin, its centroid moves by
  -(theta J + strain) r, and the pin's displacement is zero whatever d' is;
* two distinct pins p1, p2 (a deformable polygon with collinear pins): the displacement
  gradient G = [[eps_x, gamma/2 - theta], [gamma/2 + theta, eps_y]] must also satisfy
  G s = 0, s = p2 - p1, so G = a s_perp^T: two dofs a.

Bodies with enough independent pins to be immobile (rigid: 2, a deformable particle: 2,
a deformable polygon: 3 not on a line) are made fixed by the builder and have no record.
Records are per pin: ``Model.pin_body`` (P,), ``pin_point`` (P, 2) world, ``pin_role`` (P,)
(0: the centre, 1: a second pin, -1: inert padding).
"""
from __future__ import annotations

import jax
import jax.numpy as jnp

from jaxdda.bodies.elastic import finite_rotation_shift
from jaxdda.bodies.mass import inverse_on_subspace, spd_inverse
from jaxdda.bodies.shape import shape_function
from jaxdda.types import NDOF


def pin_frame(model):
    """Per body (N,): its pin mode (0: none, 1: one centre, 2: two pins), centre (N, 2) and
    second pin (N, 2) (zero where there is none)."""
    n = model.n_bodies
    role, body = model.pin_role, model.pin_body
    mode = jnp.maximum(jax.ops.segment_max(role + 1, body, n), 0)
    centre = jax.ops.segment_sum(jnp.where((role == 0)[:, None], model.pin_point, 0.0), body, n)
    second = jax.ops.segment_sum(jnp.where((role == 1)[:, None], model.pin_point, 0.0), body, n)
    return mode, centre, second


def pin_maps(model, maps: jax.Array, centroid: jax.Array) -> jax.Array:
    """(N, 6, 6): ``maps`` with each pinned body's map replaced by the null space of its
    pins' constraints, for the body at ``centroid`` (N, 2) (zero columns pad)."""
    mode, centre, second = pin_frame(model)
    t = shape_function(centre, centroid)  # (N, 2, 6): T(p) about the centroid
    a = jnp.eye(NDOF) - jnp.zeros((model.n_bodies, NDOF, NDOF)).at[:, :2, :].set(t)
    s = second - centre
    two = mode == 2
    s = jnp.where(two[:, None], s, 1.0)
    s = s / jnp.hypot(s[:, 0], s[:, 1])[:, None]
    sx, sy, z = s[:, 0], s[:, 1], jnp.zeros_like(s[:, 0])
    # columns 2 and 3: G = e_x s_perp^T and e_y s_perp^T as (theta, eps_x, eps_y, gamma)
    col_x = jnp.stack([z, z, -0.5 * sx, -sy, z, sx], -1)
    col_y = jnp.stack([z, z, -0.5 * sy, z, sx, -sy], -1)
    null2 = jnp.zeros_like(a).at[:, :, 2].set(col_x).at[:, :, 3].set(col_y)
    own = jnp.where(two[:, None, None], null2, model.dof_basis)
    return jnp.where((mode > 0)[:, None, None], a @ own, maps)


def centroid_step(model, centroid: jax.Array, d: jax.Array) -> jax.Array:
    """(N, 2): each centroid's displacement over a step whose dofs are d (N, 6). A pinned
    body's is recomputed from its turn and strain about the pin at the step's start: the
    linear field's -(theta J + E) r plus, for one pin, the finite rotation about it, so the
    pin stays exactly where it is (d's own translation is that of the mid-step lever,
    which differs at second order). Others: d's translation."""
    mode, centre, _ = pin_frame(model)
    held = d[:, :2] - jnp.einsum("nij,nj->ni", shape_function(centre, centroid), d)
    held = held + jnp.where((mode == 1)[:, None], finite_rotation_shift(d[:, 2], centroid - centre), 0.0)
    return jnp.where((mode > 0)[:, None], held, d[:, :2])


def mid_centroid(model, centroid: jax.Array, d: jax.Array) -> jax.Array:
    """(N, 2) the centroids halfway through a step's displacement d (N, 6): on the arc
    about the pin for a body with one pin (the lever of the mid-step map)."""
    return centroid + centroid_step(model, centroid, 0.5 * d)


def pin_turn(model, turn_ref: jax.Array) -> jax.Array:
    """The finite rotation of the step (N,) (``mesh_rotation``'s), zero for a body with two
    pins: it moves by its linear field, which keeps both pins exactly (its turn is of the
    order of its strain). A body with one pin turns by its own turn (``centroid_step``
    places its centroid on the arc about the pin)."""
    mode, _, _ = pin_frame(model)
    return jnp.where(mode == 2, 0.0, turn_ref)


def held_velocity(model, mass: jax.Array, projector: jax.Array, centroid: jax.Array, velocity: jax.Array):
    """(N, 6): ``velocity`` less the impulse at the pins that brings them to rest in the
    configuration with ``centroid`` (N, 2) (the velocity step of RATTLE: the M-orthogonal
    projection onto the motions that keep the pins still). Newmark's v+ = 2 d / dt - v
    leaves a part that the turned lever no longer holds; it would flip sign every step,
    unseen by the dynamics, forever. Both the projection and Newmark's unprojected
    velocity keep the mid-step lever's second order; a kinematic projection (the
    centroid's velocity from the spin) does not. Unpinned bodies: unchanged."""
    mode, centre, second = pin_frame(model)
    t = jnp.concatenate([shape_function(centre, centroid),
                         shape_function(second, centroid) * (mode == 2)[:, None, None]], 1)  # (N, 4, 6)
    flex = inverse_on_subspace(mass, projector)
    s = t @ flex @ jnp.swapaxes(t, -1, -2)
    s = s + jnp.where((mode == 2)[:, None, None], 0.0, jnp.diag(jnp.array([0.0, 0.0, 1.0, 1.0])))
    s = jnp.where((mode > 0)[:, None, None], s, jnp.eye(4))  # unpinned or fixed: a harmless identity
    impulse = jnp.einsum("nij,nj->ni", spd_inverse(s), jnp.einsum("nij,nj->ni", t, velocity))
    held = velocity - jnp.einsum("nij,nkj,nk->ni", flex, t, impulse)
    return jnp.where((mode > 0)[:, None], held, velocity)
