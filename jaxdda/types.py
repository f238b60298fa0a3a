"""The data of a simulation: Model (static), State (evolves), Params (differentiable).

Every body carries 6 generalised dof slots ``[u0, v0, theta, eps_x, eps_y, gamma_xy]``
(paper eq. 6); a per-body projector selects the active subspace (rigid: the first 3,
eq. 1; fixed: none), so one batched 6x6 code path serves every kind of body.
"""
from __future__ import annotations

import dataclasses

import jax
import jax.numpy as jnp

from jaxdda._pytree import pytree_dataclass, static_field

DISK, RING, POLYGON = 0, 1, 2
VOID = 3  # a padding body (scene.padding): never detected, never moved
KIND_NAMES = {DISK: "disk", RING: "ring", POLYGON: "polygon", VOID: "padding"}
NDOF = 6

# Contact "b-side" feature types (the a-side is always a point with a radius).
B_POINT, B_HOLE, B_LINE = 0, 1, 2


@dataclasses.dataclass(frozen=True)
class Capacities:
    """Static sizes of the padded buffers. Each reports overflow; the driver regrows."""

    candidates: int  # broad-phase candidates (bodies in neighbouring grid cells, and large bodies' partners)
    pairs_pp: int  # particle-particle candidate pairs
    pairs_pb: int  # particle-polygon candidate pairs
    pairs_bb: int  # polygon-polygon candidate pairs
    contacts: int  # contacts after the narrow phase

    def grown(self, needed: "Capacities") -> "Capacities":
        """Capacities large enough for ``needed`` with head-room (x1.5, at least x2 of a full one).

        A buffer counts only what the buffers before it kept (candidates -> pairs ->
        contacts): behind one that overflowed by a factor f its count is scaled by f, so
        that one regrowth usually suffices (each one costs a compilation)."""
        def grow(cap: int, need: float) -> int:
            return cap if need <= cap else max(2 * cap, int(need * 1.5) + 1)

        def lost(cap: int, need: int) -> float:  # the factor by which a buffer fell short
            return need / cap if need > cap > 0 else 1.0

        f_cand = lost(self.candidates, needed.candidates)
        caps, needs = (self.pairs_pp, self.pairs_pb, self.pairs_bb), (needed.pairs_pp, needed.pairs_pb, needed.pairs_bb)
        pairs = [grow(c, min(n * f_cand, needed.candidates)) for c, n in zip(caps, needs)]
        f_pairs = max(lost(c, n) for c, n in zip(caps, needs))
        return Capacities(grow(self.candidates, needed.candidates), *pairs,
                          grow(self.contacts, needed.contacts * f_cand * f_pairs))


@dataclasses.dataclass(frozen=True)
class StepOptions:
    """The step's refinements of Moreau's scheme (docs/design.md, "The step"), each one
    switchable so that its cost and its gain can be measured (``experiments/step_options.py``).
    Static: each set of options is its own compiled program. All on by default.
    """

    impact_instants: bool = True  # an impact at its instant t* inside the step; off: at the step's start (Moreau)
    # most refits of t* to the exact gap on the free path, fewer once they settle (0: the start
    # frame's quadratic): six bring a disk crossing a ring's hole (test_physics) to 1e-12 m/s, four left 9e-10
    impact_refits: int = 6
    windows: bool = True  # an isolated pair's force acts from its t* only (windows and late kicks)
    discrete_gradient: bool = True  # the normal row is the discrete gradient of the gap (no work when closed)
    linearisation_cut: bool = True  # linearise where the predictor first overlaps a contact, not at its end
    newton_finish: bool = True  # semismooth Newton finishes a stalled FISTA solve; off: FISTA to max_iter

    def __post_init__(self):
        if not isinstance(self.impact_refits, int) or self.impact_refits < 0:
            raise ValueError(f"StepOptions.impact_refits must be an int >= 0, got {self.impact_refits!r}")
        for f in dataclasses.fields(self):
            if f.type == "bool" and not isinstance(getattr(self, f.name), bool):
                raise ValueError(f"StepOptions.{f.name} must be True or False, got {getattr(self, f.name)!r}")


@pytree_dataclass
class Model:
    """Geometry and topology of a scene: what does not change in a step, and no gradient.

    Arrays are per body (N,) unless noted. Polygons are padded to ``max_vertices`` and
    stored counter-clockwise, relative to their centroid, at rotation 0.
    """

    kind: jax.Array  # (N,) int32: DISK, RING or POLYGON
    fixed: jax.Array  # (N,) bool: zero flexibility
    radius: jax.Array  # (N,) outer radius of a disk or ring, 0 for polygons
    inner_radius: jax.Array  # (N,) inner radius of a ring, 0 otherwise
    local_vertices: jax.Array  # (N, V, 2)
    vertex_mask: jax.Array  # (N, V) bool
    edge_mask: jax.Array  # (N, V) bool: edge v (vertex v to v + 1) is a contact surface (not inside a mesh)
    edge_material: jax.Array  # (N, V) int32 material whose law governs contacts on edge v (-1: the bodies')
    n_vertices: jax.Array  # (N,) int32
    area: jax.Array  # (N,)
    polar_moment: jax.Array  # (N,) integral of r^2 dA about the centroid
    second_moment: jax.Array  # (N, 3) integrals of x^2, y^2, xy dA about the centroid, at rotation 0
    plane_strain: jax.Array  # (N,) bool: a deformable body in plane strain (else plane stress)
    bound_radius: jax.Array  # (N,) largest distance from the centroid to the boundary
    gravity_scale: jax.Array  # (N,) 1.0 where gravity acts, 0.0 where it is ignored
    material: jax.Array  # (N,) int32 index into the material tables of Params
    dof_projector: jax.Array  # (N, 6, 6) projector onto the active dof subspace
    dof_basis: jax.Array  # (N, 6, 6) its orthonormal basis as columns (zero columns pad)
    mesh: jax.Array  # (N,) int32 the meshed block a triangle element belongs to (-1: not an element)
    load_body: jax.Array  # (L,) int32 body of each point load
    load_point: jax.Array  # (L, 2) its point of application, body-local (moves with the body)
    load_times: jax.Array  # (L, K) knot times of each load's history (non-decreasing; padding repeats the last)
    joint_key: jax.Array  # (J,) int64 contact key of each cemented joint found at t = 0 (-2: padding)
    joint_a: jax.Array  # (J,) int32 the joint's two bodies (for reports)
    joint_b: jax.Array  # (J,) int32
    joint_point: jax.Array  # (J, 2) where the joint was at t = 0
    connector_kind: jax.Array  # (K,) int32 BOLT, SPRING or BEAM (connectors.py)
    connector_a: jax.Array  # (K,) int32 the two bodies a connector ties
    connector_b: jax.Array  # (K,) int32
    connector_pa: jax.Array  # (K, 2) attachment point on body a, body-local (moves with it)
    connector_pb: jax.Array  # (K, 2) attachment point on body b, body-local
    connector_length: jax.Array  # (K,) rest length l0
    connector_chord0: jax.Array  # (K, 2) unit direction from a's to b's attachment point at t = 0
    pin_body: jax.Array  # (P,) int32 body of each fixed point that constrains a movable body (pins.py)
    pin_point: jax.Array  # (P, 2) its world position (it never moves)
    pin_role: jax.Array  # (P,) int32 0: the centre the body turns about, 1: a second pin, -1: inert (padding)
    group_members: jax.Array  # (G, S) int32 bodies of each dof group (meshed or tied by connectors; -1: empty)
    group_dofs: jax.Array  # (G, S, 6) int32 the group's reduced dofs behind each member's 6 (-1: none; groups.py)
    group_free: jax.Array  # (G, R) bool: a reduced dof that exists and is not fixed
    body_group: jax.Array  # (N,) int32 a body's dof group (-1: independent)
    body_slot: jax.Array  # (N,) int32 its slot in that group
    capacity: Capacities = static_field()
    n_bodies: int = static_field()
    max_vertices: int = static_field()
    options: StepOptions = static_field(default=StepOptions())  # the step's refinements (static)


@pytree_dataclass
class Params:
    """Every float a gradient can reach: time step, loads, material and solver settings."""

    dt: jax.Array  # ()
    gravity: jax.Array  # (2,)
    density: jax.Array  # (N,)
    young: jax.Array  # (N,) Young's modulus E of a deformable body (0: rigid)
    poisson: jax.Array  # (N,) Poisson's ratio
    friction: jax.Array  # (M, M) Coulomb coefficient per material pair (eq. 19)
    restitution: jax.Array  # (M, M) Newton restitution per material pair
    cohesion: jax.Array  # (M, M) cohesion c of an interface, a force shared by adjoint contacts (eqs. 19, 42-45)
    rolling: jax.Array  # (M, M) rolling resistance coefficient delta, a length (eq. 55)
    tensile: jax.Array  # (M, M) tensile strength t of a cemented interface, a force shared by its joints (eq. 70)
    load_force: jax.Array  # (L, 2) point load at t = 0 (world frame)
    load_rate: jax.Array  # (L, 2) its rate of change: F(t) = load_force + load_rate * t + history(t)
    load_history: jax.Array  # (L, K, 2) force at each knot time, linear in between, held outside
    dynamic: jax.Array  # () share of the velocity carried into the next step: 1 dynamic, 0 static (Shi's k01)
    tol: jax.Array  # () relative tolerance of the contact solve
    max_iter: jax.Array  # () iteration cap of the contact solve (a float, so grad ignores it)
    margin: jax.Array  # () base contact detection distance d0 (added to the swept distance)
    rupture_width: jax.Array  # () 0: a joint breaks outright; w > 0: smoothed rupture for calibration
    # (the joint keeps 1 - e / w of its strength when it lacks a force e to stay closed; docs/design.md)
    connector_axial: jax.Array  # (K,) axial stiffness: a spring's k, a bolt's or beam's E A / l0 (N/m)
    connector_bending: jax.Array  # (K,) a beam's bending stiffness E I (N m^2; 0: no bending)
    connector_shear: jax.Array  # (K,) a beam's shear deformation term b of eq. 89 (0: Euler-Bernoulli)
    connector_pretension: jax.Array  # (K,) axial force at the rest length (N, tension +)


@pytree_dataclass
class State:
    """What evolves: time, pose and velocity per body, and contact memory (warm start)."""


    time: jax.Array  # ()
    origin: jax.Array  # (N, 2) centroid at the start (a fixed reference)
    displacement: jax.Array  # (N, 2) centroid displacement since the start
    rotation: jax.Array  # (N,) total rotation angle since the start (counter-clockwise)
    velocity: jax.Array  # (N, 6) generalised velocity; rigid: [vx, vy, omega, 0, 0, 0]
    stretch: jax.Array  # (N, 2, 2) S: the current shape is x = c + R(rotation) S X (I when rigid)
    stress: jax.Array  # (N, 3) [sigma_x, sigma_y, tau_xy] of a deformable body (uniform, eq. 7)
    contact_key: jax.Array  # (C,) int64 keys of last step's contacts (-1 = empty)
    contact_force: jax.Array  # (C, 3) last step's (normal, shear, rolling moment) for warm start
    joint_integrity: jax.Array  # (J,) share of the strength a cemented joint keeps: 1 intact, 0 broken
    # (hypothesis iv: it never heals); values in between only under a smoothed rupture

    @property
    def centroid(self) -> jax.Array:
        """(N, 2) current centroids. Kept as origin + displacement so that gaps can be
        computed from the small displacement at full precision (see kinematics.gap_change)."""
        return self.origin + self.displacement


@pytree_dataclass
class Contacts:
    """Contacts found by the narrow phase: a point feature of body ``a`` against body ``b``.

    Side a is a point with a radius: a disk centre (radius R) or a polygon vertex (0).
    Side b is a point with a radius (B_POINT: outside it), the hole of a ring (B_HOLE:
    inside it), or an edge line (B_LINE, from qb to eb, outward normal on the right).
    Coordinates are local to each body (relative to the centroid, rotation 0).
    """

    valid: jax.Array  # (C,) bool
    a: jax.Array  # (C,) int32
    b: jax.Array  # (C,) int32
    ra: jax.Array  # (C,)
    pa: jax.Array  # (C, 2)
    btype: jax.Array  # (C,) int32
    rb: jax.Array  # (C,)
    qb: jax.Array  # (C, 2)
    eb: jax.Array  # (C, 2)
    key: jax.Array  # (C,) int64 identity of the feature pair, for warm start
    edge: jax.Array  # (C,) int32 b's edge of a B_LINE contact (-1: none), for its joint material


@pytree_dataclass
class ContactReport:
    """Per-step contact output. ``force`` is the resultant on body ``a`` from body ``b``
    (global frame), averaged over the step: impact impulse / dt plus the contact force."""

    valid: jax.Array  # (C,) bool
    a: jax.Array  # (C,) int32
    b: jax.Array  # (C,) int32
    point: jax.Array  # (C, 2)
    normal: jax.Array  # (C, 2) unit normal, from b towards a
    normal_force: jax.Array  # (C,)
    shear_force: jax.Array  # (C,) along tau = normal rotated clockwise
    force: jax.Array  # (C, 2)
    moment: jax.Array  # (C,) rolling resistance moment on a from b (counter-clockwise +)
    cemented: jax.Array  # (C,) bool: an intact cemented joint (its normal force may be a tension)
    gap: jax.Array  # (C,) gap at the start of the step
    # (C,) the contact's normal forces of the step's parts (impact and contact VI) summed,
    # each in its own frame (mean over the step): what presses the bodies together
    bearing: jax.Array


@pytree_dataclass
class StepInfo:
    """Diagnostics of one step."""

    iterations: jax.Array  # () int32 solver iterations, products with W, of all the step's solves
    residual: jax.Array  # () largest relative VI residual of the step's solves
    converged: jax.Array  # () bool
    needed: jax.Array  # (5,) int32 slots needed per buffer, in the order of Capacities
    overflow: jax.Array  # () bool: some buffer was too small (results incomplete)
    n_contacts: jax.Array  # () int32
    max_penetration: jax.Array  # () largest overlap at the start of the step (>= 0)
    joint_tension: jax.Array  # (J,) tension carried by each cemented joint (0 once broken or apart)
    joint_broken: jax.Array  # (J,) bool: broken at the end of this step
    connector_force: jax.Array  # (K, 4) axial (tension +), shear, moment at end a, at end b, at the step's end
    contacts: ContactReport


NCOMP = 3  # unknowns per contact: normal force, shear force, rolling moment
NO_JOINT = -2  # joint_key of a padding joint (contact keys are >= -1)


def zeros_contact_memory(capacity: int) -> tuple[jax.Array, jax.Array]:
    return -jnp.ones((capacity,), jnp.int64), jnp.zeros((capacity, NCOMP))
