"""Deformable bodies: consistent mass, stiffness and stress of the linear displacement
field (paper eqs. 4-7, 17-18, Appendix A).

A body's current shape is the affine image ``x = c + R(theta) S X`` of its reference shape
X (centroid at 0, rotation 0): ``S`` (2 x 2) is the accumulated stretch, I for a rigid
body. A deformable particle keeps eps_x = eps_y (eq. 4): its dof projector is onto span(e0,
e1, e2, (e3 + e4)/sqrt 2), so one 6-dof code path gives the paper's 4-dof matrices.
Strains are [eps_x, eps_y, gamma_xy] (engineering shear), stresses [s_x, s_y, t_xy].
"""
from __future__ import annotations

import dataclasses

import jax
import jax.numpy as jnp

from jaxdda.bodies.shape import rotation_matrix


def elastic_matrix(young: jax.Array, poisson: jax.Array, plane_strain: jax.Array) -> jax.Array:
    """(N, 3, 3) D with stress = D strain: plane stress E/(1-v^2)[[1,v,0],[v,1,0],[0,0,(1-v)/2]]
    (eq. A.3) or plane strain E/((1+v)(1-2v))[[1-v,v,0],[v,1-v,0],[0,0,(1-2v)/2]]."""
    v = poisson
    strain_ = plane_strain.astype(young.dtype)
    # Plane strain is plane stress with E' = E / (1 - v^2) and v' = v / (1 - v).
    e = young / jnp.where(strain_ > 0, 1.0 - v * v, 1.0)
    v = jnp.where(strain_ > 0, v / (1.0 - v), v)
    c = e / (1.0 - v * v)
    zero = jnp.zeros_like(c)
    rows = [jnp.stack([c, c * v, zero], -1), jnp.stack([c * v, c, zero], -1),
            jnp.stack([zero, zero, 0.5 * c * (1.0 - v)], -1)]
    return jnp.stack(rows, -2)


def current_moments(second_moment: jax.Array, rotation: jax.Array, stretch: jax.Array) -> jax.Array:
    """(N, 2, 2) [[Ixx, Ixy], [Ixy, Iyy]] of the current shape (integrals of x x^T dA over the
    reference area, i.e. per unit mass / density), from the reference ones (N, 3)."""
    ixx, iyy, ixy = second_moment[:, 0], second_moment[:, 1], second_moment[:, 2]
    ref = jnp.stack([jnp.stack([ixx, ixy], -1), jnp.stack([ixy, iyy], -1)], -2)
    a = rotation_matrix(rotation) @ stretch
    return a @ ref @ jnp.swapaxes(a, -1, -2)


def consistent_mass(density: jax.Array, area: jax.Array, moments: jax.Array) -> jax.Array:
    """(N, 6, 6) integral of rho T^T T dA with T of eq. 7 about the centroid (Appendix A.5).

    For a rigid body (dofs 0-2) it is diag(m, m, I); for a particle on its 4-dof subspace
    it is the matrix of eqs. A.9-A.10.
    """
    ixx, iyy, ixy = moments[:, 0, 0], moments[:, 1, 1], moments[:, 0, 1]
    z = jnp.zeros_like(area)
    rows = [
        [area, z, z, z, z, z],
        [z, area, z, z, z, z],
        [z, z, ixx + iyy, -ixy, ixy, 0.5 * (ixx - iyy)],
        [z, z, -ixy, ixx, z, 0.5 * ixy],
        [z, z, ixy, z, iyy, 0.5 * ixy],
        [z, z, 0.5 * (ixx - iyy), 0.5 * ixy, 0.5 * ixy, 0.25 * (ixx + iyy)],
    ]
    m = jnp.stack([jnp.stack(r, -1) for r in rows], -2)
    return density[:, None, None] * m


def stiffness(d_matrix: jax.Array, volume: jax.Array) -> jax.Array:
    """(N, 6, 6) integral of B^T D B dA: V D on the strain dofs (eq. A.1; B is constant)."""
    k = jnp.zeros(d_matrix.shape[:-2] + (6, 6))
    return k.at[:, 3:, 3:].set(volume[:, None, None] * d_matrix)


def stress_load(stress: jax.Array, volume: jax.Array) -> jax.Array:
    """(N, 6) -integral of B^T sigma dA: the load of the stress already carried (eq. A.11)."""
    return jnp.concatenate([jnp.zeros(stress.shape[:-1] + (3,)), -volume[:, None] * stress], -1)


def rotated_stress(stress: jax.Array, turn: jax.Array) -> jax.Array:
    """(N, 3) stress [s_x, s_y, t_xy] carried along by a rotation ``turn`` (N,): R s R^T,
    so a stressed body that turns keeps its stress in its own frame (objectivity)."""
    c, s = jnp.cos(turn), jnp.sin(turn)
    sx, sy, t = stress[:, 0], stress[:, 1], stress[:, 2]
    mean, half, rot = 0.5 * (sx + sy), 0.5 * (sx - sy), c * c - s * s
    sin2 = 2.0 * s * c
    return jnp.stack([mean + half * rot - t * sin2, mean - half * rot + t * sin2, half * sin2 + t * rot], -1)


def strain_tensor(strain: jax.Array) -> jax.Array:
    """(N, 2, 2) [[eps_x, gamma/2], [gamma/2, eps_y]] from (N, 3) strain dofs."""
    ex, ey, g = strain[..., 0], strain[..., 1], 0.5 * strain[..., 2]
    return jnp.stack([jnp.stack([ex, g], -1), jnp.stack([g, ey], -1)], -2)


def updated_stretch(stretch: jax.Array, rotation: jax.Array, turn: jax.Array, strain: jax.Array,
                    turn_ref: jax.Array | None = None) -> jax.Array:
    """S after a step: x - c -> (R(turn) + E)(x - c) (post-adjusted field, eqs. 17-18), so
    R(theta + turn) S' = (R(turn) + E) R(theta) S.

    An element of a meshed block turns with its mesh instead (``turn_ref``, see
    ``mesh_rotation``): x - c -> (R(turn_ref) + (turn - turn_ref) [[0, -1], [1, 0]] + E)(x - c),
    linear in its nodal displacements, so elements that share a node keep sharing it."""
    e = strain_tensor(strain)
    if turn_ref is not None:
        dt = (turn - turn_ref)[..., None, None]
        e = e + rotation_matrix(turn_ref) - rotation_matrix(turn) + dt * jnp.array([[0.0, -1.0], [1.0, 0.0]])
    back = rotation_matrix(-(rotation + turn))
    return stretch + back @ e @ rotation_matrix(rotation) @ stretch


def mesh_rotation(model, volume: jax.Array, centroid: jax.Array, turn: jax.Array):
    """Per body, the finite rotation of the step (N,) and the offset (N, 2) of its centroid
    from the centre it turns about: its own turn and zero, except for the elements of a
    meshed block, which all turn by their mesh's area-weighted mean rotation about the
    mesh's centroid. So a meshed block in rigid motion turns exactly, like a block (eq.
    16), while its nodes move by the finite element field plus one common correction."""
    n = turn.shape[0]
    element = model.mesh >= 0
    seg = jnp.where(element, model.mesh, n)
    weight = jnp.where(element, volume, 0.0)
    total = jax.ops.segment_sum(weight, seg, n + 1)
    total = jnp.where(total > 0, total, 1.0)
    mean_turn = jax.ops.segment_sum(weight * turn, seg, n + 1) / total
    centre = jax.ops.segment_sum(weight[:, None] * centroid, seg, n + 1) / total[:, None]
    turn_ref = jnp.where(element, mean_turn[seg], turn)
    offset = jnp.where(element[:, None], centroid - centre[seg], 0.0)
    return turn_ref, offset


def finite_rotation_shift(turn: jax.Array, offset: jax.Array) -> jax.Array:
    """(R(turn) - I - turn [[0, -1], [1, 0]]) offset: where a point at ``offset`` from the
    centre of rotation goes beyond the linear field's turn (cancellation-free: sin(turn) -
    turn is formed before it multiplies the offset; built from kinematics' rotation
    increment minus the linear turn, a spinning mesh's centre of mass drifts by 1e-12 m)."""
    c1 = -2.0 * jnp.sin(0.5 * turn) ** 2
    s1 = jnp.sin(turn) - turn
    return jnp.stack([c1 * offset[:, 0] - s1 * offset[:, 1], s1 * offset[:, 0] + c1 * offset[:, 1]], -1)


def spectral_norm_2x2(a: jax.Array, det: jax.Array) -> jax.Array:
    """Largest singular value of each 2x2 matrix in closed form (no LAPACK SVD):
    s^2 = (F + sqrt(F^2 - 4 det^2)) / 2 with F the squared Frobenius norm."""
    f = jnp.sum(a * a, axis=(-2, -1))
    return jnp.sqrt(0.5 * (f + jnp.sqrt(jnp.maximum(f * f - 4.0 * det * det, 0.0))))


def current_shape(model, stretch: jax.Array):
    """The model with each body's local geometry in its current shape S X (vertices, load
    points, radii): contacts found in it move rigidly plus the step's strain increment.
    Exact (unchanged) for rigid bodies, whose S is I."""
    det = jnp.linalg.det(stretch)
    scale = jnp.sqrt(jnp.abs(det))  # a particle's S is a rotation-scaling
    # Only detection reads the bound radius (no derivative: it is not smooth at S = I).
    norm = jax.lax.stop_gradient(spectral_norm_2x2(stretch, det))
    return dataclasses.replace(
        model,
        local_vertices=jnp.einsum("nij,nvj->nvi", stretch, model.local_vertices),
        load_point=jnp.einsum("lij,lj->li", stretch[model.load_body], model.load_point),
        radius=model.radius * scale, inner_radius=model.inner_radius * scale,
        bound_radius=model.bound_radius * jnp.maximum(norm, 1.0))
