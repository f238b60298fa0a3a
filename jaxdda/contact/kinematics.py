"""Contact gaps, frames and Jacobians (paper eqs. 10, 29-38).

A contact pairs a point feature of body ``a`` (a disk centre with its radius, or a polygon
vertex) with a feature of body ``b``: a point with a radius (outside it), the hole of a
ring (inside it), or an edge line. Its unit normal ``n`` points from b towards a, the
shear direction ``tau`` is ``n`` rotated clockwise (paper Section 3), and the contact
point is the midpoint of the two surface points.
"""
from __future__ import annotations

import jax
import jax.numpy as jnp

from jaxdda.bodies.elastic import strain_tensor
from jaxdda.bodies.shape import shape_function, to_world
from jaxdda.types import B_HOLE, B_LINE, Contacts

_TINY = 1e-300


def _safe_unit(v: jax.Array) -> tuple[jax.Array, jax.Array]:
    """Unit vector and length of v (..., 2); (1, 0) where v vanishes (no NaN gradient).

    The length comes from hypot, not sqrt: under jit XLA turns ``v / sqrt(s)`` into
    ``v * rsqrt(s)``, which makes axis-aligned normals inexact by one ulp; one ulp of a
    normal is an error of 1e-3 N in the contact force of a 1e7 N body (case 7.1).
    """
    ok = jnp.sum(v * v, -1) > _TINY
    safe = jnp.where(ok[..., None], v, 1.0)
    length = jnp.hypot(safe[..., 0], safe[..., 1])
    unit = jnp.where(ok[..., None], safe / length[..., None], jnp.array([1.0, 0.0]))
    return unit, jnp.where(ok, length, 0.0)


def clockwise(n: jax.Array) -> jax.Array:
    """tau: n rotated clockwise by 90 degrees."""
    return jnp.stack([n[..., 1], -n[..., 0]], -1)


def _feature_points(c: Contacts, pose_a, pose_b):
    """World positions of a's point, and of b's point (or edge start) and edge end, with
    each side's (centroid, rotation) given per contact ((C, 2), (C,))."""
    xa = to_world(*pose_a, c.pa)
    xq = to_world(*pose_b, c.qb)
    xe = to_world(*pose_b, c.eb)
    return xa, xq, xe


def gap_frame(c: Contacts, centroid: jax.Array, rotation: jax.Array):
    """Signed gap (C,), unit normal (C, 2) and contact point (C, 2) at the given poses.

    ``centroid`` (N, 2) and ``rotation`` (N,) may be any configuration: the gap is exact
    (nonlinear) in the poses, which the step uses to evaluate it at the predictor.
    """
    return gap_frame_at(c, (centroid[c.a], rotation[c.a]), (centroid[c.b], rotation[c.b]))


def gap_frame_at(c: Contacts, pose_a, pose_b):
    """``gap_frame`` with each contact's own poses of its two bodies (centroid (C, 2),
    rotation (C,)): e.g. the configuration at each contact's impact time."""
    xa, xq, xe = _feature_points(c, pose_a, pose_b)

    d_unit, dist = _safe_unit(xa - xq)
    t_unit, _ = _safe_unit(xe - xq)
    line_n = clockwise(t_unit)  # outward normal of a counter-clockwise edge

    is_line = c.btype == B_LINE
    is_hole = c.btype == B_HOLE
    normal = jnp.where(is_line[:, None], line_n, jnp.where(is_hole[:, None], -d_unit, d_unit))
    gap = jnp.where(
        is_line,
        jnp.sum(line_n * (xa - xq), -1) - c.ra,
        jnp.where(is_hole, c.rb - c.ra - dist, dist - c.ra - c.rb),
    )
    point = xa - (c.ra + 0.5 * gap)[:, None] * normal
    return gap, normal, point


def _rotation_increment(theta: jax.Array, dtheta: jax.Array, local: jax.Array) -> jax.Array:
    """R(theta) (R(dtheta) - I) local, with cos - 1 = -2 sin^2(dtheta / 2): no cancellation."""
    cm1 = -2.0 * jnp.sin(0.5 * dtheta) ** 2
    sn = jnp.sin(dtheta)
    inc = jnp.stack([cm1 * local[..., 0] - sn * local[..., 1], sn * local[..., 0] + cm1 * local[..., 1]], -1)
    return to_world(jnp.zeros_like(inc), theta, inc)


def _radius_change(radius: jax.Array, turn: jax.Array, strain: jax.Array) -> jax.Array:
    """Change of a particle's radius when x - c -> (R(turn) + eps I)(x - c) (eq. 17)."""
    eps = 0.5 * (strain[:, 0] + strain[:, 1])
    scale = jnp.hypot(jnp.cos(turn) + eps, jnp.sin(turn)) - 1.0
    return jnp.where(eps == 0, 0.0, radius * scale)


def gap_change(c: Contacts, centroid: jax.Array, rotation: jax.Array, shift: jax.Array,
               turn: jax.Array, strain: jax.Array | None = None) -> jax.Array:
    """Exact change of the gap (C,) when every body moves by ``shift`` (N, 2), turns by
    ``turn`` (N,) and strains by ``strain`` (N, 3) from (centroid, rotation): a point at
    offset r from its centroid moves to (R(turn) + E) r (post-adjusted field, eqs. 16-18).

    Computed from relative quantities only, so a gap change of 1e-20 m is resolved next
    to coordinates of 1e2 m (the contact stage multiplies gaps by 2 M / dt^2).
    """
    strain = jnp.zeros(turn.shape + (3,)) if strain is None else strain
    return gap_change_at(c, centroid, rotation, (shift[c.a], turn[c.a], strain[c.a]),
                         (shift[c.b], turn[c.b], strain[c.b]))


def gap_change_at(c: Contacts, centroid: jax.Array, rotation: jax.Array, motion_a, motion_b) -> jax.Array:
    """``gap_change`` with each contact's own motion of its two bodies from (centroid,
    rotation) (N, ...): (shift (C, 2), turn (C,), strain (C, 3)) per side, e.g. each body's
    free motion up to the contact's own impact time."""
    def moved(body, local, motion):
        shift, turn, strain = motion
        offset = to_world(jnp.zeros_like(local), rotation[body], local)
        stretch = jnp.einsum("cij,cj->ci", strain_tensor(strain), offset)
        return shift + _rotation_increment(rotation[body], turn, local) + stretch

    ua, uq = moved(c.a, c.pa, motion_a), moved(c.b, c.qb, motion_b)
    xa, xq, xe = _feature_points(c, (centroid[c.a], rotation[c.a]), (centroid[c.b], rotation[c.b]))
    r, dr = xa - xq, ua - uq
    d_ra = _radius_change(c.ra, motion_a[1], motion_a[2])
    d_rb = _radius_change(c.rb, motion_b[1], motion_b[2])

    # Points: |r + dr| - |r| = (2 r.dr + |dr|^2) / (|r + dr| + |r|).
    rr, rn = _safe_unit(r)[1], _safe_unit(r + dr)[1]
    den = rr + rn
    dist_change = (2.0 * jnp.sum(r * dr, -1) + jnp.sum(dr * dr, -1)) / jnp.where(den > 0, den, 1.0)
    # Lines: n' . (r + dr) - n . r with n' = R(turn_b) n (rigid b), or the normal of the
    # strained edge (R(turn_b) + E_b) t.
    turn_b, strain_b = motion_b[1], motion_b[2]
    t_unit, _ = _safe_unit(xe - xq)
    n = clockwise(t_unit)
    dn = _rotation_increment(jnp.zeros_like(turn_b), turn_b, n)
    t_new = clockwise(n + dn) * -1.0 + jnp.einsum("cij,cj->ci", strain_tensor(strain_b), t_unit)
    dn = jnp.where(jnp.any(strain_b != 0, -1)[:, None], clockwise(_safe_unit(t_new)[0]) - n, dn)
    line_change = jnp.sum(dn * (r + dr), -1) + jnp.sum(n * dr, -1) - d_ra
    return jnp.where(c.btype == B_LINE, line_change,
                     jnp.where(c.btype == B_HOLE, d_rb - d_ra - dist_change, dist_change - d_ra - d_rb))


def jacobians(c: Contacts, normal: jax.Array, point: jax.Array, gap: jax.Array, centroid: jax.Array) -> jax.Array:
    """Contact Jacobians at the bodies' centroids (N, 2): ``jacobians_at`` of centroid[a], centroid[b]."""
    return jacobians_at(c, normal, point, gap, centroid[c.a], centroid[c.b])


def jacobians_at(c: Contacts, normal: jax.Array, point: jax.Array, gap: jax.Array, centroid_a: jax.Array,
                 centroid_b: jax.Array) -> jax.Array:
    """Contact Jacobians (C, 2 sides, 3, 6): rows (n, tau) of s * [n, tau]^T T(x) (eq. 10),
    and the rolling row: the rotation dof theta (eqs. 13-15, 54).

    Side a gets +, side b gets -, so that J d is the relative displacement of a against
    b at the contact, in the (normal, shear) frame (eqs. 31, 36-38), and the relative
    rotation (the rolling gap of eq. 54). Each side uses its own surface point (the
    midpoint -/+ gap/2 along n), so a lever arm is the body's true radius even where the
    configuration used overlaps (as a predictor does).
    """
    frame = jnp.stack([normal, clockwise(normal)], -2)  # (C, 2, 2) rows n, tau
    half = (0.5 * gap)[:, None] * normal
    ta = shape_function(point + half, centroid_a)
    tb = shape_function(point - half, centroid_b)
    roll = jnp.broadcast_to(jnp.eye(ta.shape[-1])[2], ta.shape[:1] + (1, ta.shape[-1]))
    return jnp.stack([jnp.concatenate([frame @ ta, roll], 1), -jnp.concatenate([frame @ tb, roll], 1)], 1)


def discrete_gradient(jac: jax.Array, c: Contacts, d: jax.Array, change: jax.Array, reach: jax.Array) -> jax.Array:
    """The Jacobian with its normal row made a discrete gradient (Gonzalez 1996) of the
    gap over the motion d (N, 6): J_n d = ``change``, the exact gap change, not its
    linearisation in the mid-step frame.

    Adds (rho / |D|^2) D to the normal row, rho = change - J_n d, D the motion in
    coordinates the gap depends on: the relative translation d_a - d_b, and each side's
    turn and strains weighted by its ``reach`` (N,) squared (metres). The normal force
    then does work p_n J_n d = p_n (exact gap change), which the position-level row makes
    -p_n g0: nothing on a closed contact, where the mid-step chord leaves O(dtheta^3 r)
    of work per step (energy drifts at second order, either way). The translational
    parts of the correction are equal and opposite: linear momentum is kept.

    A side whose feature is its centroid (a disk's centre, a ring's hole) does not move
    it by turning: its turn is not in D, so the normal force keeps no moment on a round
    body. With it in D, a light ring pinched under 3e6 N between a heavy disk in its hole
    and a wall was spun to 1 800 rad/s in one step (fuzz seed 598).
    """
    da, db = d[c.a], d[c.b]
    u = da[:, :2] - db[:, :2]
    turns_a = jnp.any(c.pa != 0.0, -1)  # a polygon's vertex
    turns_b = (c.btype == B_LINE) | jnp.any(c.qb != 0.0, -1)  # an edge, or a vertex
    da = da.at[:, 2].multiply(turns_a)
    db = db.at[:, 2].multiply(turns_b)
    wa, wb = reach[c.a][:, None] ** 2 * da[:, 2:], reach[c.b][:, None] ** 2 * db[:, 2:]
    size = jnp.sum(u * u, -1) + jnp.sum(wa * da[:, 2:], -1) + jnp.sum(wb * db[:, 2:], -1)
    # rho is the gap's curvature over the motion, at most ~|D|^2 / (the smaller reach): a
    # larger value is round-off of a motion near zero (or of coordinates far larger than
    # it), and is clipped to that bound so that the correction stays of the order of the
    # motion relative to the Jacobian (1e-6 of a contact force from 1e-22 m of noise).
    bound = 4.0 * size / jnp.minimum(reach[c.a], reach[c.b])
    rho = jnp.clip(change - apply_jacobian(jac, c, d)[:, 0], -bound, bound)
    k = jnp.where(size > 0, rho / jnp.where(size > 0, size, 1.0), 0.0)[:, None]
    return (jac.at[:, 0, 0].add(k * jnp.concatenate([u, wa], -1))
               .at[:, 1, 0].add(k * jnp.concatenate([-u, wb], -1)))


def apply_jacobian(jac: jax.Array, c: Contacts, dofs: jax.Array) -> jax.Array:
    """(C, 2) = J d: relative (normal, shear) motion at each contact from body dofs (N, 6)."""
    return jnp.einsum("cij,cj->ci", jac[:, 0], dofs[c.a]) + jnp.einsum("cij,cj->ci", jac[:, 1], dofs[c.b])


def apply_jacobian_t(jac: jax.Array, c: Contacts, forces: jax.Array, n_bodies: int) -> jax.Array:
    """(N, 6) = J^T p: generalised forces on bodies from contact forces (C, 2) (eq. 9)."""
    fa = jnp.einsum("cij,ci->cj", jac[:, 0], forces)
    fb = jnp.einsum("cij,ci->cj", jac[:, 1], forces)
    return jax.ops.segment_sum(fa, c.a, n_bodies) + jax.ops.segment_sum(fb, c.b, n_bodies)
