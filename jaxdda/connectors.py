"""Connectors between two bodies: rock bolt (link element, eqs. 74-84), spring (eqs. 85-86)
and beam (eqs. 87-92), each attached at one material point of each body.

Every connector is an elastic energy U of its two bodies' 6 dofs, in the co-rotational
form that stays exact under large motion:

    U = k (l - l0)^2 / 2 + P l + [phi_a, phi_b] [[A4, A5], [A5, A4]] [phi_a, phi_b]^T / 2

with l the current distance of the attachment points, l0 the rest length, P a pretension,
k the axial stiffness (a spring's k, a bolt's or beam's EA / l0, eqs. 76, 85, 89), and
phi the end rotations of a beam against its chord (A4, A5 of eq. 89; zero for bolts and
springs). For small motion the step's tangent of U is the paper's stiffness (eqs. 80-83,
86, 92: T^T k L T, with E selecting the rotation dof for a beam's end moments); at finite
motion it adds the geometric stiffness of the loaded connector (a hanging mass swings as a
pendulum). The load is -dU/dd and the tangent d2U/dd2 at the step's start, both by autodiff.
"""
from __future__ import annotations

import jax
import jax.numpy as jnp

from jaxdda.bodies.shape import rotation_matrix
from jaxdda.types import NDOF

BOLT, SPRING, BEAM = 0, 1, 2
SHEAR_FACTOR = {"rectangular": 1.2, "circular": 10.0 / 9.0}  # k_Be of eq. 89


def beam_coefficients(young, area, inertia, shear_modulus, shear_factor, length):
    """(axial stiffness E A / l, bending stiffness E I, b) of a beam of length l (eq. 89):
    b = 12 k E / G (r / l)^2 with r^2 = I / A the radius of gyration (G = None: b = 0,
    no shear deformation, Euler-Bernoulli)."""
    b = 0.0 if shear_modulus is None else 12.0 * shear_factor * young / shear_modulus * inertia / area / length ** 2
    return young * area / length, young * inertia, b


def _wrap(angle):
    return jnp.arctan2(jnp.sin(angle), jnp.cos(angle))


def _chord(point, angle, chord0):
    """Length of the chord between the two attachment points (2, 2), and the end rotations
    phi (2,) of the bodies (angles ``angle``) against it, from its direction ``chord0`` at
    t = 0 (no NaN, nor NaN derivative, where the points coincide)."""
    chord = point[1] - point[0]
    apart = jnp.sum(chord ** 2) > 0
    safe = jnp.where(apart, chord, chord0)
    length = jnp.where(apart, jnp.sqrt(jnp.sum(safe ** 2)), 0.0)
    turned = jnp.arctan2(chord0[0] * safe[1] - chord0[1] * safe[0], chord0 @ safe)  # chord rotation
    return length, _wrap(angle - turned)


def _energy(geometry, stiffness, d):
    """U of one connector after the dof increments d (2, 6) of its two bodies.

    geometry: centroids (2, 2), current attachment offsets from them (2, 2), rotation
    angles (2,), reference chord direction (2,); stiffness: k, l0, P, A4, A5.
    The attachment points move by the post-adjusted field of eqs. 16-18: rigidly with
    (u0, v0, r0), plus the strain increment of a deformable body."""
    centroid, offset, angle, chord0 = geometry
    k, l0, pre, a4, a5 = stiffness
    strain = jnp.stack([jnp.stack([d[:, 3], d[:, 5] / 2], -1), jnp.stack([d[:, 5] / 2, d[:, 4]], -1)], -2)
    moved = jnp.einsum("sij,sj->si", rotation_matrix(d[:, 2]) + strain, offset)
    length, phi = _chord(centroid + d[:, :2] + moved, angle + d[:, 2], chord0)
    bend = 0.5 * (a4 * (phi[0] ** 2 + phi[1] ** 2) + 2.0 * a5 * phi[0] * phi[1])
    return 0.5 * k * (length - l0) ** 2 + pre * length + bend


def _geometry(model, state):
    a, b = model.connector_a, model.connector_b
    centroid = jnp.stack([state.centroid[a], state.centroid[b]], 1)
    local = jnp.stack([jnp.einsum("kij,kj->ki", state.stretch[a], model.connector_pa),
                       jnp.einsum("kij,kj->ki", state.stretch[b], model.connector_pb)], 1)
    angle = jnp.stack([state.rotation[a], state.rotation[b]], 1)
    offset = jnp.einsum("ksij,ksj->ksi", rotation_matrix(angle), local)
    return centroid, offset, angle, model.connector_chord0


def _stiffness(model, params):
    """(k, l0, P, A4, A5) per connector; A4 = (4 + b) EI / ((1 + b) l), A5 = (2 - b) EI / ((1 + b) l) (eq. 89)."""
    length, b = model.connector_length, params.connector_shear
    ei = params.connector_bending / ((1.0 + b) * length)
    return (params.connector_axial, length, params.connector_pretension, (4.0 + b) * ei, (2.0 - b) * ei)


def connector_terms(model, params, state):
    """Per connector at the step's start: the generalised load on its two bodies (K, 2, 6)
    (-dU/dd, eqs. 84, 86, 92) and the tangent stiffness (K, 12, 12) (d2U/dd2, eqs. 80-83,
    86, 92), in the order [body a dofs, body b dofs]."""
    geometry, stiffness = _geometry(model, state), _stiffness(model, params)
    zero = jnp.zeros((2, NDOF))

    def one(geom, stiff):
        u = lambda d: _energy(geom, stiff, d)
        return -jax.grad(u)(zero), jax.hessian(u)(zero).reshape(2 * NDOF, 2 * NDOF)

    return jax.vmap(one)(geometry, stiffness)


def connector_forces(model, params, state):
    """(K, 4) per connector in ``state``: axial force (tension +), shear force, and the
    bending moments at ends a and b (counter-clockwise on the beam's end; 0 unless a beam)."""
    centroid, offset, angle, chord0 = _geometry(model, state)
    length, phi = jax.vmap(_chord)(centroid + offset, angle, chord0)
    _, _, _, a4, a5 = _stiffness(model, params)
    m_a, m_b = a4 * phi[:, 0] + a5 * phi[:, 1], a5 * phi[:, 0] + a4 * phi[:, 1]
    axial = params.connector_axial * (length - model.connector_length) + params.connector_pretension
    shear = (m_a + m_b) / jnp.where(length > 0, length, 1.0)
    return jnp.stack([axial, shear, m_a, m_b], -1)


def attachment_points(model, state):
    """(K, 2, 2) world positions of each connector's two attachment points."""
    centroid, offset, _, _ = _geometry(model, state)
    return centroid + offset

