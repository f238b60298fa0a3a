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

from jaxdda._fusion import materialize
from jaxdda.types import B_HOLE, B_LINE, Contacts

_TINY = 1e-300

# Geometry is written on coordinates (x, y) as separate (C,) arrays and reads each
# contact's two bodies in one gather: XLA then compiles an evaluation as a few kernels,
# where 2-vector products (dots), sums over the 2-axis (reductions) and gathers of one
# side's row split it into dozens (docs/design.md, "Kernels are the compile cost").


def _packed(*columns: jax.Array) -> jax.Array:
    """Several results (C,) as the columns of one array, behind an optimisation barrier:
    without it XLA's simplifier splits the stack back into one kernel per result."""
    return jax.lax.optimization_barrier(jnp.stack(columns, -1))


@jax.custom_jvp
def _unit(x: jax.Array, y: jax.Array):
    """Unit vector (x, y) and length of (x, y); (1, 0) and 0 where it vanishes.

    The length comes from hypot, not sqrt: under jit XLA turns ``v / sqrt(s)`` into
    ``v * rsqrt(s)``, which makes axis-aligned normals inexact by one ulp; one ulp of a
    normal is an error of 1e-3 N in the contact force of a 1e7 N body (case 7.1).
    """
    ok = x * x + y * y > _TINY
    x, y = jnp.where(ok, x, 1.0), jnp.where(ok, y, 1.0)
    length = jnp.hypot(x, y)
    return jnp.where(ok, x / length, 1.0), jnp.where(ok, y / length, 0.0), jnp.where(ok, length, 0.0)


@_unit.defjvp
def _unit_jvp(primals, tangents):
    """d|v| = u.dv and du = (dv - u (u.dv)) / |v| (0 where v vanishes): a few products,
    where the derivative of hypot's scaled form is dozens of kernels once transposed."""
    ux, uy, length = out = _unit(*primals)
    dx, dy = tangents
    along = ux * dx + uy * dy
    inv = jnp.where(length > 0, 1.0 / jnp.where(length > 0, length, 1.0), 0.0)
    return out, ((dx - ux * along) * inv, (dy - uy * along) * inv, jnp.where(length > 0, along, 0.0))


def _rotate(cos: jax.Array, sin: jax.Array, x: jax.Array, y: jax.Array):
    """R(theta) (x, y), given cos theta and sin theta."""
    return cos * x - sin * y, sin * x + cos * y


def clockwise(n: jax.Array) -> jax.Array:
    """tau: n rotated clockwise by 90 degrees."""
    return jnp.stack([n[..., 1], -n[..., 0]], -1)


def _ends(c: Contacts, per_body: jax.Array) -> jax.Array:
    """Rows (N, k) of each contact's two bodies, in one gather: (C, 2, k), a then b (read
    as ``both[:, side, columns]``: XLA fuses those slices, not ones of a side's row)."""
    return per_body[jnp.stack([c.a, c.b], -1)]


def _poses(c: Contacts, centroid: jax.Array, rotation: jax.Array):
    """Each side's pose (centroid (C, 2), rotation (C,)) from the bodies' (N, 2), (N,)."""
    pose = _ends(c, jnp.concatenate([centroid, rotation[:, None]], -1))
    return (pose[:, 0, :2], pose[:, 0, 2]), (pose[:, 1, :2], pose[:, 1, 2])


def _feature_points(c: Contacts, pose_a, pose_b):
    """World (x, y) of a's point, and of b's point (or edge start) and edge end, with each
    side's (centroid (C, 2), rotation (C,)); and each side's (cos, sin) of its rotation."""
    (cen_a, th_a), (cen_b, th_b) = pose_a, pose_b
    turn_a, turn_b = (jnp.cos(th_a), jnp.sin(th_a)), (jnp.cos(th_b), jnp.sin(th_b))

    def world(cen, turn, local):
        x, y = _rotate(*turn, local[:, 0], local[:, 1])
        return cen[:, 0] + x, cen[:, 1] + y

    return world(cen_a, turn_a, c.pa), world(cen_b, turn_b, c.qb), world(cen_b, turn_b, c.eb), turn_a, turn_b


@jax.jit
def gap_frame(c: Contacts, centroid: jax.Array, rotation: jax.Array):
    """Signed gap (C,), unit normal (C, 2) and contact point (C, 2) at the given poses.

    ``centroid`` (N, 2) and ``rotation`` (N,) may be any configuration: the gap is exact
    (nonlinear) in the poses, which the step uses to evaluate it at the predictor.
    """
    return gap_frame_at(c, *_poses(c, centroid, rotation))


@jax.jit
def gap_frame_at(c: Contacts, pose_a, pose_b):
    """``gap_frame`` with each contact's own poses of its two bodies (centroid (C, 2),
    rotation (C,)): e.g. the configuration at each contact's impact time."""
    (ax, ay), (qx, qy), (ex, ey), _, _ = _feature_points(c, pose_a, pose_b)
    dx, dy = ax - qx, ay - qy
    ux, uy, dist = _unit(dx, dy)
    tx, ty, _ = _unit(ex - qx, ey - qy)
    lx, ly = ty, -tx  # the outward normal of a counter-clockwise edge: its direction turned clockwise

    is_line, is_hole = c.btype == B_LINE, c.btype == B_HOLE
    nx = jnp.where(is_line, lx, jnp.where(is_hole, -ux, ux))
    ny = jnp.where(is_line, ly, jnp.where(is_hole, -uy, uy))
    gap = jnp.where(is_line, lx * dx + ly * dy - c.ra, jnp.where(is_hole, c.rb - c.ra - dist, dist - c.ra - c.rb))
    lift = c.ra + 0.5 * gap
    out = _packed(gap, nx, ny, ax - lift * nx, ay - lift * ny)
    return out[:, 0], out[:, 1:3], out[:, 3:5]


def _increment(cos: jax.Array, sin: jax.Array, turn: jax.Array, x: jax.Array, y: jax.Array):
    """R(theta) (R(turn) - I) (x, y), cos - 1 = -2 sin^2(turn / 2): no cancellation."""
    cm1, sn = -2.0 * jnp.sin(0.5 * turn) ** 2, jnp.sin(turn)
    return _rotate(cos, sin, cm1 * x - sn * y, sn * x + cm1 * y)


def _radius_change(radius: jax.Array, turn: jax.Array, strain: jax.Array) -> jax.Array:
    """Change of a particle's radius when x - c -> (R(turn) + eps I)(x - c) (eq. 17)."""
    eps = 0.5 * (strain[:, 0] + strain[:, 1])
    scale = _unit(jnp.cos(turn) + eps, jnp.sin(turn))[2] - 1.0
    return jnp.where(eps == 0, 0.0, radius * scale)


def _strained(strain: jax.Array, x: jax.Array, y: jax.Array):
    """E (x, y), E = [[eps_x, gamma / 2], [gamma / 2, eps_y]] of strain dofs (C, 3)."""
    half = 0.5 * strain[:, 2]
    return strain[:, 0] * x + half * y, half * x + strain[:, 1] * y


@jax.jit
def gap_change(c: Contacts, centroid: jax.Array, rotation: jax.Array, shift: jax.Array,
               turn: jax.Array, strain: jax.Array | None = None) -> jax.Array:
    """Exact change of the gap (C,) when every body moves by ``shift`` (N, 2), turns by
    ``turn`` (N,) and strains by ``strain`` (N, 3) from (centroid, rotation): a point at
    offset r from its centroid moves to (R(turn) + E) r (post-adjusted field, eqs. 16-18).

    Computed from relative quantities only, so a gap change of 1e-20 m is resolved next
    to coordinates of 1e2 m (the contact stage multiplies gaps by 2 M / dt^2).
    """
    strain = jnp.zeros(turn.shape + (3,)) if strain is None else strain
    m = _ends(c, jnp.concatenate([shift, turn[:, None], strain], -1))
    return gap_change_at(c, centroid, rotation, (m[:, 0, :2], m[:, 0, 2], m[:, 0, 3:]),
                         (m[:, 1, :2], m[:, 1, 2], m[:, 1, 3:]))


@jax.jit
def gap_change_at(c: Contacts, centroid: jax.Array, rotation: jax.Array, motion_a, motion_b) -> jax.Array:
    """``gap_change`` with each contact's own motion of its two bodies from (centroid,
    rotation) (N, ...): (shift (C, 2), turn (C,), strain (C, 3)) per side, e.g. each body's
    free motion up to the contact's own impact time."""
    (ax, ay), (qx, qy), (ex, ey), turn_a, turn_b = _feature_points(c, *_poses(c, centroid, rotation))

    def moved(turned, local, motion):
        shift, turn, strain = motion
        lx, ly = local[:, 0], local[:, 1]
        ix, iy = _increment(*turned, turn, lx, ly)
        sx, sy = _strained(strain, *_rotate(*turned, lx, ly))
        return shift[:, 0] + ix + sx, shift[:, 1] + iy + sy

    (uax, uay), (uqx, uqy) = moved(turn_a, c.pa, motion_a), moved(turn_b, c.qb, motion_b)
    rx, ry, dx, dy = ax - qx, ay - qy, uax - uqx, uay - uqy
    d_ra = _radius_change(c.ra, motion_a[1], motion_a[2])
    d_rb = _radius_change(c.rb, motion_b[1], motion_b[2])

    # Points: |r + dr| - |r| = (2 r.dr + |dr|^2) / (|r + dr| + |r|).
    den = _unit(rx, ry)[2] + _unit(rx + dx, ry + dy)[2]
    dist_change = (2.0 * (rx * dx + ry * dy) + (dx * dx + dy * dy)) / jnp.where(den > 0, den, 1.0)
    # Lines: n' . (r + dr) - n . r with n' = R(turn_b) n (rigid b), or the normal of the
    # strained edge (R(turn_b) + E_b) t.
    turn, strain = motion_b[1], motion_b[2]
    tx, ty, _ = _unit(ex - qx, ey - qy)
    nx, ny = ty, -tx
    dnx, dny = _increment(1.0, 0.0, turn, nx, ny)
    sx, sy = _strained(strain, tx, ty)
    ux, uy, _ = _unit(-(ny + dny) + sx, (nx + dnx) + sy)  # the strained edge's direction
    strained = jnp.any(strain != 0, -1)
    dnx, dny = jnp.where(strained, uy - nx, dnx), jnp.where(strained, -ux - ny, dny)
    line_change = dnx * (rx + dx) + dny * (ry + dy) + (nx * dx + ny * dy) - d_ra
    return materialize(jnp.where(c.btype == B_LINE, line_change,
                                 jnp.where(c.btype == B_HOLE, d_rb - d_ra - dist_change, dist_change - d_ra - d_rb)))


@jax.jit
def jacobians(c: Contacts, normal: jax.Array, point: jax.Array, gap: jax.Array, centroid: jax.Array) -> jax.Array:
    """Contact Jacobians at the bodies' centroids (N, 2): ``jacobians_at`` of centroid[a], centroid[b]."""
    cen = _ends(c, centroid)
    return jacobians_at(c, normal, point, gap, cen[:, 0], cen[:, 1])


@jax.jit
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
    nx, ny = normal[:, 0], normal[:, 1]
    zero, one = jnp.zeros_like(nx), jnp.ones_like(nx)

    def rows(side: float, centroid: jax.Array, round_: jax.Array) -> jax.Array:
        """(C, 3, 6): n.T(x), tau.T(x) (tau = (ny, -nx)) and the rolling row at a side's
        surface point x, T of eq. 7 (rigid bodies use its first three columns)."""
        dx = point[:, 0] + side * 0.5 * gap * nx - centroid[:, 0]
        dy = point[:, 1] + side * 0.5 * gap * ny - centroid[:, 1]
        row_n = [nx, ny, jnp.where(round_, 0.0, ny * dx - nx * dy), nx * dx, ny * dy, 0.5 * (nx * dy + ny * dx)]
        row_t = [ny, -nx, -(nx * dx + ny * dy), ny * dx, -nx * dy, 0.5 * (ny * dy - nx * dx)]
        row_r = [zero, zero, one, zero, zero, zero]
        return side * jnp.stack([jnp.stack(r, -1) for r in (row_n, row_t, row_r)], -2)

    # A side whose feature is its centroid (a disk's centre, a ring's hole) has its normal
    # through it: the normal force has no moment about it, exactly (the lever arm, -r n up
    # to round-off, would leave one of eps r p_n).
    round_a = jnp.all(c.pa == 0.0, -1)
    round_b = (c.btype != B_LINE) & jnp.all(c.qb == 0.0, -1)
    return jnp.stack([rows(1.0, centroid_a, round_a), rows(-1.0, centroid_b, round_b)], 1)


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
    both = _ends(c, jnp.concatenate([d, reach[:, None]], -1))  # (C, 2, 7): motion, reach
    motion, reach_a, reach_b = both[:, :, :6], both[:, 0, 6], both[:, 1, 6]
    u = motion[:, 0, :2] - motion[:, 1, :2]
    turns_a = jnp.any(c.pa != 0.0, -1)  # a polygon's vertex
    turns_b = (c.btype == B_LINE) | jnp.any(c.qb != 0.0, -1)  # an edge, or a vertex
    da = jnp.concatenate([motion[:, 0, 2:3] * turns_a[:, None], motion[:, 0, 3:]], -1)
    db = jnp.concatenate([motion[:, 1, 2:3] * turns_b[:, None], motion[:, 1, 3:]], -1)
    wa, wb = reach_a[:, None] ** 2 * da, reach_b[:, None] ** 2 * db
    size = jnp.sum(u * u, -1) + jnp.sum(wa * da, -1) + jnp.sum(wb * db, -1)
    # rho is the gap's curvature over the motion, at most ~|D|^2 / (the smaller reach): a
    # larger value is round-off of a motion near zero (or of coordinates far larger than
    # it), and is clipped to that bound so that the correction stays of the order of the
    # motion relative to the Jacobian (1e-6 of a contact force from 1e-22 m of noise).
    bound = 4.0 * size / jnp.minimum(reach_a, reach_b)
    linear = jnp.einsum("ckj,ckj->c", jac[:, :, 0], motion)
    rho = jnp.clip(change - linear, -bound, bound)
    k = jnp.where(size > 0, rho / jnp.where(size > 0, size, 1.0), 0.0)[:, None, None]
    along = jnp.stack([jnp.concatenate([u, wa], -1), jnp.concatenate([-u, wb], -1)], 1)
    return jac.at[:, :, 0].add(k * along)


@jax.jit
def apply_jacobian(jac: jax.Array, c: Contacts, dofs: jax.Array) -> jax.Array:
    """(C, 3) = J d: relative (normal, shear, rolling) motion at each contact from body dofs
    (N, 6). Both sides in one gather and one product (each is a kernel of its own)."""
    return jnp.sum(jac * _ends(c, dofs)[:, :, None, :], axis=(1, 3))


def apply_jacobian_t(jac: jax.Array, c: Contacts, forces: jax.Array, n_bodies: int) -> jax.Array:
    """(N, 6) = J^T p: generalised forces on bodies from contact forces (C, 3) (eq. 9),
    both sides in one product and one scatter."""
    f = jnp.sum(jac * forces[:, None, :, None], axis=2)
    return jax.ops.segment_sum(f.reshape(-1, f.shape[-1]), jnp.stack([c.a, c.b], -1).reshape(-1), n_bodies)
