"""Energy of a run: ``energy(traj)`` gives the kinetic, gravitational, strain and connector
energy of every saved state of a Trajectory, and their sum.

What each term is (all in J per unit thickness, summed over the bodies):

* ``kinetic``: 1/2 m |v|^2 + 1/2 I omega^2 per free body, with m = rho A and I = rho
  (Ixx + Iyy) of the *current* shape about the centroid (the (3, 3) entry of the consistent
  mass matrix, Appendix A.5; rho J for a rigid body, J its polar moment). This is the
  rigid part of 1/2 v^T M v only: a Trajectory keeps (vx, vy, omega) per body, not the
  strain rates of a deformable body (``State.velocity[:, 3:]``), so the kinetic energy of
  a deformable body's strain rate (its breathing and shearing, and their coupling to
  omega) is left out, also for each element of a meshed block. For rigid bodies it is
  the whole kinetic energy.
* ``potential``: the work gravity would give back, -m s g . (c - c0) per free body, with
  s its gravity flag (``Model.gravity_scale``, 0 for ``gravity=False``) and c0 its centroid
  at the first saved state; zero at the start. Point loads (``add_load``) are not
  conservative in general and are left out, as is any work done on fixed bodies.
* ``strain``: 1/2 V sigma : eps of each deformable body, the uniform stress sigma of
  eq. 7's linear field with eps = D^-1 sigma from the body's elastic law (eq. A.3, plane
  stress or strain) and V its current area A |det S|, the volume the step integrates its
  stress load over (eq. A.11). The engine accumulates stress incrementally (sigma += D
  d_eps, turned with the body), so this is the energy of the stress it actually carries.
* ``connector``: per bolt, spring or beam, k (l - l0)^2 / 2 + P (l - l0) + 1/2 phi^T
  [[A4, A5], [A5, A4]] phi: the co-rotational energy that connectors.py differentiates for
  the connector loads (eqs. 76, 85, 89), with the pretension term P l shifted by the
  constant P l0 so that a connector at its rest length holds none.
* ``elastic`` = strain + connector; ``total`` = kinetic + potential + elastic.

Not included: contacts store no energy (they are hard constraints solved as a
variational inequality, no penalty springs), friction, rolling resistance and
restitution e < 1 dissipate without a record, cemented joints are rigid, and the work
of point loads is not tracked (so with loads the total is not conserved).

Newmark with gamma = 1, beta = 1/2 (eq. 8) is exact for constant forces (free fall keeps
kinetic + potential to round-off) and dissipates under elastic forces: for a linear
spring, each step loses exactly k (dl)^2 / 2, dl the step's change of length, i.e. a
relative energy loss of about omega^2 dt t / 2 after a time t (first order in dt).
"""
from __future__ import annotations

import numpy as np

from jaxdda.bodies.elastic import elastic_matrix
from jaxdda.connectors import _stiffness

KEYS = ("kinetic", "potential", "strain", "connector", "elastic", "total")


def _params(traj, params):
    """The Params of the run: those given, else the trajectory's, else the scene's."""
    if params is not None:
        return params
    return traj.scene.params if traj.params is None else traj.params


def _rotation(theta: np.ndarray) -> np.ndarray:
    c, s = np.cos(theta), np.sin(theta)
    return np.stack([np.stack([c, -s], -1), np.stack([s, c], -1)], -2)


def _stretch(traj) -> np.ndarray:
    if traj.stretch is not None:
        return np.asarray(traj.stretch, float)
    return np.broadcast_to(np.eye(2), np.shape(traj.rotation) + (2, 2))


def kinetic_energy(traj, params=None) -> np.ndarray:
    """(S+1, N) rigid-body kinetic energy per body (see the module docstring)."""
    model = traj.scene.model
    params = _params(traj, params)
    density = np.asarray(params.density, float)
    free = ~np.asarray(model.fixed, bool)
    mass = density * np.asarray(model.area, float)
    ixx, iyy, ixy = np.asarray(model.second_moment, float).T
    ref = np.stack([np.stack([ixx, ixy], -1), np.stack([ixy, iyy], -1)], -2)  # (N, 2, 2)
    a = _rotation(np.asarray(traj.rotation, float)) @ _stretch(traj)  # (S+1, N, 2, 2)
    moments = a @ ref @ np.swapaxes(a, -1, -2)
    inertia = density * (moments[..., 0, 0] + moments[..., 1, 1])  # rho J for a rigid body
    v = np.asarray(traj.velocity, float)
    e = 0.5 * mass * (v[..., 0] ** 2 + v[..., 1] ** 2) + 0.5 * inertia * v[..., 2] ** 2
    return np.where(free, e, 0.0)


def potential_energy(traj, params=None) -> np.ndarray:
    """(S+1, N) gravitational potential energy per body, -m s g . (c - c0) (zero at the
    first saved state; fixed bodies zero)."""
    model = traj.scene.model
    params = _params(traj, params)
    weight = (np.asarray(params.density, float) * np.asarray(model.area, float)
              * np.asarray(model.gravity_scale, float) * ~np.asarray(model.fixed, bool))
    c = np.asarray(traj.centroid, float)
    return -weight * ((c - c[:1]) @ np.asarray(params.gravity, float))


def strain_energy(traj, params=None) -> np.ndarray:
    """(S+1, N) 1/2 V sigma . D^-1 sigma of each deformable body (zero for rigid ones)."""
    model = traj.scene.model
    params = _params(traj, params)
    young = np.asarray(params.young, float)
    deformable = (young > 0) & ~np.asarray(model.fixed, bool)
    safe = np.where(deformable, young, 1.0)
    d = np.asarray(elastic_matrix(safe, np.asarray(params.poisson, float), np.asarray(model.plane_strain)))
    sigma = np.asarray(traj.stress, float)  # (S+1, N, 3)
    eps = np.linalg.solve(d, sigma[..., None])[..., 0]  # engineering shear strain in slot 2
    volume = np.asarray(model.area, float) * np.abs(np.linalg.det(_stretch(traj)))
    return np.where(deformable, 0.5 * volume * np.sum(sigma * eps, -1), 0.0)


def connector_lengths(traj) -> tuple[np.ndarray, np.ndarray]:
    """(S+1, K) length of each connector's chord, and (S+1, K, 2) the end rotations phi of
    its two bodies against the chord (as connectors._chord)."""
    model = traj.scene.model
    a, b = np.asarray(model.connector_a), np.asarray(model.connector_b)
    centroid, rotation = np.asarray(traj.centroid, float), np.asarray(traj.rotation, float)
    stretch = _stretch(traj)

    def point(body, local):
        offset = np.einsum("skij,kj->ski", stretch[:, body], np.asarray(local, float))
        return centroid[:, body] + np.einsum("skij,skj->ski", _rotation(rotation[:, body]), offset)

    chord = point(b, model.connector_pb) - point(a, model.connector_pa)
    length = np.linalg.norm(chord, axis=-1)
    chord0 = np.asarray(model.connector_chord0, float)
    turned = np.arctan2(chord0[:, 0] * chord[..., 1] - chord0[:, 1] * chord[..., 0],
                        np.sum(chord0 * chord, -1))
    phi = np.stack([rotation[:, a] - turned, rotation[:, b] - turned], -1)
    return length, np.arctan2(np.sin(phi), np.cos(phi))


def connector_energy(traj, params=None) -> np.ndarray:
    """(S+1, K) energy held by each connector: k (l - l0)^2 / 2 + P (l - l0) plus a beam's
    bending energy (eqs. 76, 85, 89; the energy connectors.py derives its loads from)."""
    model = traj.scene.model
    params = _params(traj, params)
    if np.asarray(model.connector_a).shape[0] == 0:
        return np.zeros((len(traj.time), 0))
    k, l0, pre, a4, a5 = (np.asarray(x, float) for x in _stiffness(model, params))
    length, phi = connector_lengths(traj)
    stretch = length - l0
    bend = 0.5 * (a4 * (phi[..., 0] ** 2 + phi[..., 1] ** 2) + 2.0 * a5 * phi[..., 0] * phi[..., 1])
    return 0.5 * k * stretch ** 2 + pre * stretch + bend


def energy(traj, params=None) -> dict[str, np.ndarray]:
    """Energy terms of every saved state of ``traj``: a dict of (S+1,) arrays ``kinetic``,
    ``potential``, ``strain``, ``connector``, ``elastic`` (strain + connector) and
    ``total``, in J per unit thickness (module docstring: what each includes).

    ``params``: the Params the run used (default: ``traj.params`` where the Trajectory
    keeps them, else ``traj.scene.params``).
    """
    kinetic = kinetic_energy(traj, params).sum(-1)
    potential = potential_energy(traj, params).sum(-1)
    strain = strain_energy(traj, params).sum(-1)
    connector = connector_energy(traj, params).sum(-1)
    elastic = strain + connector
    return {"kinetic": kinetic, "potential": potential, "strain": strain, "connector": connector,
            "elastic": elastic, "total": kinetic + potential + elastic}
