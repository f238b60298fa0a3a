"""The examples of the paper's Section 7, with the geometry of validation-cases.md.

``heavy=True`` builds every fixed body the paper's way: free, with a density 1e11
times larger and no weight of its own.
"""
from __future__ import annotations

import numpy as np

from jaxdda.scene.builder import Scene, SceneBuilder
from jaxdda.scene.mesh import rectangle_mesh

G = 10.0
HEAVY = 1e11


def _support(sb: SceneBuilder, heavy: bool, density: float, **shape) -> int:
    """A fixed polygon (``vertices=``) or ring (``center=, inner_radius=, outer_radius=``),
    or, with ``heavy``, the paper's stand-in for one: free, 1e11 times denser, weightless."""
    add = sb.add_polygon if "vertices" in shape else sb.add_ring
    if heavy:
        return add(density=HEAVY * density, gravity=False, **shape)
    return add(density=density, fixed=True, **shape)


def _rect(x0, y0, x1, y1):
    return [(x0, y0), (x1, y0), (x1, y1), (x0, y1)]


def _frame(sb: SceneBuilder, half: float, thickness: float, heavy: bool, density: float) -> None:
    """Four walls around the square [-half, half]^2."""
    h, t = half, thickness
    for rect in (_rect(-h - t, -h - t, -h, h + t), _rect(h, -h - t, h + t, h + t),
                 _rect(-h, -h - t, h, -h), _rect(-h, h, h, h + t)):
        _support(sb, heavy, density, vertices=rect)


def disk_heap(heavy: bool = False) -> Scene:
    """7.1: three disks R = 10 stacked on a base; F = G, 2G, 3G. Solver tolerance 1e-14: a
    heavy base (1e11 times denser) amplifies the residual, and at 1e-12 its reactions wander
    by 7e-3 N, above the paper's 2.2e-3."""
    sb = SceneBuilder(dt=0.001, gravity=(0.0, -G), tol=1e-14, name="paper-7.1")
    for y in (10.0, 30.0, 50.0):
        sb.add_disk(center=(0.0, y), radius=10.0, density=2500.0)
    _support(sb, heavy, 2500.0, vertices=_rect(-40.0, -10.0, 40.0, 0.0))
    return sb.build()


def block_stair(heavy: bool = False, *, young: float | None = None, poisson: float = 0.45) -> Scene:
    """7.2: four 20 x 10 blocks as a staircase; base reactions W/2 and 7W/2. Rigid blocks,
    or deformable ones with ``young`` (the paper: E = 1e14 Pa, nu = 0.45, plane stress),
    which are run as a static analysis (``dynamic=0``, see docs/design.md).

    The solver tolerance is 1e-14: the sub-stack's centroid is exactly above a corner, a
    knife edge that amplifies the residual of a heavy base by ~1e4 (at 1e-12 the base
    reactions wander by 0.1 N from step to step)."""
    sb = SceneBuilder(dt=0.001, gravity=(0.0, -G), tol=1e-14, dynamic=1.0 if young is None else 0.0,
                      name="paper-7.2")
    for k, x0 in enumerate((15.0, 10.0, 5.0, 0.0)):  # B1 (top) ... B4 (bottom)
        y0 = 10.0 * (3 - k)
        sb.add_polygon(vertices=_rect(x0, y0, x0 + 20.0, y0 + 10.0), density=2000.0, young=young, poisson=poisson)
    _support(sb, heavy, 2000.0, vertices=_rect(-20.0, -10.0, 60.0, 0.0))
    return sb.build()


def ring_in_frame(heavy: bool = False) -> Scene:
    """7.3: a ring (radii 1, 3) bouncing in a square frame of inner side 40, no gravity."""
    sb = SceneBuilder(dt=0.05, gravity=(0.0, 0.0), name="paper-7.3")
    sb.add_ring(center=(0.0, 0.0), inner_radius=1.0, outer_radius=3.0, density=2500.0, velocity=(2.5, 5.0))
    _frame(sb, 20.0, 5.0, heavy, 2500.0)
    return sb.build()


def block_in_frame(heavy: bool = False) -> Scene:
    """7.4: a 20 x 20 block bouncing in a square frame of inner side 120, no gravity."""
    sb = SceneBuilder(dt=0.01, gravity=(0.0, 0.0), name="paper-7.4")
    sb.add_polygon(vertices=_rect(-10.0, -10.0, 10.0, 10.0), density=2300.0, velocity=(2.5, 5.0))
    _frame(sb, 60.0, 10.0, heavy, 2300.0)
    return sb.build()


def disk_in_ring(heavy: bool = False) -> Scene:
    """7.5: a disk R = 40 released inside a fixed ring of inner radius 100 (a pendulum)."""
    sb = SceneBuilder(dt=0.005, gravity=(0.0, -G), name="paper-7.5")
    sb.add_disk(center=(-60.0, 0.0), radius=40.0, density=1.0)
    _support(sb, heavy, 1.0, center=(0.0, 0.0), inner_radius=100.0, outer_radius=110.0)
    return sb.build()


def block_pull(heavy: bool = False, *, cohesion: float = 400.0, friction: float = 0.0,
               height: float = 0.7, force: float = 1000.0) -> Scene:
    """7.6: a unit block on a fixed base pulled by F = ``force`` (1000 N) whose line of action is
    ``height`` above the interface; cohesion c shared by the two adjoint corner contacts.
    Body 0 is the block, load 0 the pull."""
    sb = SceneBuilder(dt=0.01, gravity=(0.0, -G), name="paper-7.6")
    sb.add_material("interface", friction=friction, cohesion=cohesion)
    block = sb.add_polygon(vertices=_rect(0.0, 0.0, 1.0, 1.0), density=1000.0, material="interface")
    _support(sb, heavy, 1000.0, vertices=_rect(-5.0, -1.0, 10.0, 0.0), material="interface")
    sb.add_load(block, force=(force, 0.0), at=(0.0, height))
    return sb.build()


def disk_pull(heavy: bool = False, *, height: float = 1.0, friction: float = 10.0,
              rolling: float = 0.0) -> Scene:
    """7.7: a disk R = 1 on a fixed base pulled by F = 1000 N whose line of action is
    ``height`` above the contact point; rolling resistance coefficient ``rolling`` (m).
    Body 0 is the disk, load 0 the pull."""
    sb = SceneBuilder(dt=0.01, gravity=(0.0, -G), name="paper-7.7")
    sb.add_material("surface", friction=friction, rolling=rolling, restitution=0.0)
    disk = sb.add_disk(center=(0.0, 1.0), radius=1.0, density=1000.0, material="surface")
    _support(sb, heavy, 1000.0, vertices=_rect(-10.0, -1.0, 30.0, 0.0), material="surface")
    sb.add_load(disk, force=(1000.0, 0.0), at=(0.0, height))
    return sb.build()


def cemented_pull(heavy: bool = False, *, height: float = 0.0, force: float = 1000.0, rate: float = 0.0,
                  tensile: float = 2000.0) -> Scene:
    """7.8: a 2 x 2 block B2 cemented along its left side to a fixed block B1 and pulled
    away by F(t) = force + rate t on its vertical centre line, ``height`` above its middle.
    No gravity. Body 0 is B2, body 1 is B1; load 0 the pull."""
    sb = SceneBuilder(dt=0.01, gravity=(0.0, 0.0), name="paper-7.8")
    sb.add_material("cement", tensile=tensile, restitution=0.0)
    b2 = sb.add_polygon(vertices=_rect(0.0, -1.0, 2.0, 1.0), density=1000.0, material="cement")
    _support(sb, heavy, 1000.0, vertices=_rect(-2.0, -2.0, 0.0, 2.0), material="cement")
    sb.add_load(b2, force=(force, 0.0), at=(1.0, height), rate=(rate, 0.0))
    return sb.build()


def disk_between_blocks(heavy: bool = False, *, vy: float = 1.0, cells: tuple[int, int] = (12, 2), young: float = 1e14,
                        poisson: float = 0.45) -> Scene:
    """7.9: a rigid disk r = 0.5 (density 2500, no gravity) starts at (0, 0) with velocity
    (1, ``vy``) between a fixed rigid block whose bottom face is y = 0.75 and a block of
    height 0.5 whose top face is y = -0.75, meshed into 3-node triangles (``cells`` = nx by ny
    rectangles, two triangles each; E = ``young``, nu = ``poisson``) and held by its bottom nodes. Elastic
    frictionless impacts: 2 vy collisions and back at (1, 0) at t = 1 s (20 steps of 0.05).
    The paper gives no widths or density of the blocks: both span x = -1 .. 2, density
    2500. Bodies: 0 the disk, 1 the upper block, then the elements of the lower one."""
    sb = SceneBuilder(dt=0.05, gravity=(0.0, 0.0), name="paper-7.9")
    sb.add_disk(center=(0.0, 0.0), radius=0.5, density=2500.0, velocity=(1.0, vy))
    _support(sb, heavy, 2500.0, vertices=_rect(-1.0, 0.75, 2.0, 1.25))
    nodes, triangles = rectangle_mesh(-1.0, -1.25, 2.0, -0.75, *cells)
    sb.add_mesh(nodes, triangles, 2500.0, young, poisson, fixed_nodes=np.flatnonzero(nodes[:, 1] == -1.25))
    return sb.build()


def _star(center, outer: float, inner: float, points: int = 5):
    """A concave star polygon with ``points`` tips at ``outer``, one pointing up."""
    angle = np.pi / 2 + np.pi * np.arange(2 * points) / points
    radius = np.where(np.arange(2 * points) % 2 == 0, outer, inner)
    return np.stack([center[0] + radius * np.cos(angle), center[1] + radius * np.sin(angle)], -1)


def particle_chain(heavy: bool = False, *, height: float = 3.0, stiffness: float = 0.5e10,
                   friction: float = 0.5, restitution: float = 0.0) -> Scene:
    """7.10: a star block, 9 disks r = 2 and a star block in a horizontal line, joined
    centre to centre by 10 springs of ``stiffness``, released with the middle disk
    ``height`` above a fixed disk R = 8; first touch at t = sqrt(2 H / g) (step 155).
    The paper gives no spacing, density or contact law: centres 4.5 apart, density 2500,
    ``friction`` 0.5 and ``restitution`` 0 (so the part lying on the disk comes to rest;
    the ends hanging past it keep swinging). Body 5 is the
    middle disk, body 11 the fixed disk."""
    sb = SceneBuilder(dt=0.005, gravity=(0.0, -G), name="paper-7.10")
    sb.add_material("chain", friction=friction, restitution=restitution)
    y = 8.0 + height + 2.0
    xs = 4.5 * (np.arange(11) - 5.0)
    bodies = []
    for k, x in enumerate(xs):
        if k in (0, 10):
            bodies.append(sb.add_polygon(_star((x, y), 2.0, 0.9), density=2500.0, material="chain"))
        else:
            bodies.append(sb.add_disk(center=(x, y), radius=2.0, density=2500.0, material="chain"))
    for k in range(10):
        sb.add_spring(bodies[k], bodies[k + 1], (xs[k], y), (xs[k + 1], y), stiffness=stiffness)
    if heavy:
        sb.add_disk(center=(0.0, 0.0), radius=8.0, density=HEAVY * 2500.0, gravity=False, material="chain")
    else:
        sb.add_disk(center=(0.0, 0.0), radius=8.0, density=2500.0, fixed=True, material="chain")
    return sb.build()
