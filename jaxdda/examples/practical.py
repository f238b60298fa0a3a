"""Practical scenes beyond the paper: the calibration and Monte Carlo workhorses.

Each has a closed form in its smooth regime (see the docstrings), which the tests use.
Body 0 is always the moving body; the supports are fixed (or, with ``heavy=True``, the
paper's stand-in: free, 1e11 times denser, weightless).
"""
from __future__ import annotations

import math
from typing import Sequence

import numpy as np

from jaxdda.examples.paper import G, _support
from jaxdda.scene.builder import Scene, SceneBuilder


def _slab(a: np.ndarray, b: np.ndarray, depth: float) -> list[tuple[float, float]]:
    """The polygon under the surface segment a -> b (left to right), ``depth`` thick,
    counter-clockwise."""
    return [tuple(a - (0.0, depth)), tuple(b - (0.0, depth)), tuple(b), tuple(a)]


def incline(heavy: bool = False, *, angle: float = 30.0, friction: float = 0.3, velocity: float = 0.0,
            size: float = 1.0, dt: float = 0.01) -> Scene:
    """A ``size`` x ``size`` block (density 1000) on a fixed plane inclined at ``angle``
    degrees, released with speed ``velocity`` down the slope. Sliding (tan angle >
    ``friction``), it accelerates at g (sin a - mu cos a) along the slope; otherwise it
    sticks. The slope runs down to the right from the origin; the block's uphill corner
    starts 1 m down the slope from it."""
    a = math.radians(angle)
    t, n = np.array([math.cos(a), -math.sin(a)]), np.array([math.sin(a), math.cos(a)])
    sb = SceneBuilder(dt=dt, gravity=(0.0, -G), name="incline")
    sb.add_material("rock", friction=friction, restitution=0.0)
    s0 = 1.0
    corners = [s0 * t, (s0 + size) * t, (s0 + size) * t + size * n, s0 * t + size * n]
    sb.add_polygon(vertices=[tuple(c) for c in corners], density=1000.0, material="rock",
                   velocity=tuple(velocity * t))
    length = 100.0 + 10.0 * size
    plane = [tuple(-5.0 * t - 2.0 * n), tuple(length * t - 2.0 * n), tuple(length * t), tuple(-5.0 * t)]
    _support(sb, heavy, 1000.0, vertices=plane, material="rock")
    return sb.build()


def rolling_disk(heavy: bool = False, *, rolling: float = 0.01, friction: float = 1.0, velocity: float = 2.0,
                 radius: float = 0.5, dt: float = 0.01) -> Scene:
    """A disk (density 1000) rolling without slip at ``velocity`` over a flat fixed base,
    slowed by rolling resistance ``rolling`` (delta, m; eqs. 55-57). The resisting moment
    delta N decelerates a solid disk at delta g / (1.5 R) until it rests at
    x = 0.75 R v^2 / (delta g)."""
    sb = SceneBuilder(dt=dt, gravity=(0.0, -G), name="rolling-disk")
    sb.add_material("ground", friction=friction, rolling=rolling, restitution=0.0)
    sb.add_disk(center=(0.0, radius), radius=radius, density=1000.0, material="ground",
                velocity=(velocity, 0.0), angular_velocity=-velocity / radius)
    _support(sb, heavy, 1000.0, vertices=[(-5.0, -1.0), (60.0, -1.0), (60.0, 0.0), (-5.0, 0.0)],
             material="ground")
    return sb.build()


def rockfall(heavy: bool = False, *, profile: Sequence[Sequence[float]] = ((0.0, 10.0), (6.0, 0.0), (60.0, 0.0)),
             friction: float = 0.3, rolling: float = 0.1, restitution: float = 0.0, radius: float = 0.5,
             velocity: Sequence[float] = (0.0, 0.0), start: float = 1.0, dt: float = 0.01) -> Scene:
    """A rock (a disk of ``radius``, density 2650) released on a slope ``profile``: the
    surface as a polyline of (x, y) points running left to right, by default a 59 degree
    face 10 m high onto a flat run-out. On the face the rock slides as well as rolls
    unless friction >= tan(angle) / 3 (a solid disk). Each segment is a fixed slab 2 m thick under
    it. The rock starts touching the first segment at ``start`` m along it, with
    ``velocity`` (vx, vy); ``friction``, ``rolling`` (delta, m) and ``restitution``
    are those of the rock-slope contact."""
    pts = np.asarray(profile, float)
    if pts.ndim != 2 or pts.shape[1] != 2 or len(pts) < 2 or np.any(np.diff(pts[:, 0]) <= 0):
        raise ValueError(f"rockfall profile must be >= 2 points (x, y) with increasing x, got {profile!r}")
    sb = SceneBuilder(dt=dt, gravity=(0.0, -G), name="rockfall")
    sb.add_material("rock", friction=friction, rolling=rolling, restitution=restitution)
    seg = pts[1] - pts[0]
    tangent = seg / np.linalg.norm(seg)
    normal = np.array([-tangent[1], tangent[0]])
    center = pts[0] + start * tangent + radius * normal
    sb.add_disk(center=tuple(center), radius=radius, density=2650.0, material="rock", velocity=tuple(velocity))
    for a, b in zip(pts[:-1], pts[1:]):
        _support(sb, heavy, 2650.0, vertices=_slab(a, b, 2.0), material="rock")
    return sb.build()


def pile(heavy: bool = False, *, n: int = 100, friction: float = 0.0, restitution: float = 0.0, radius: float = 0.5,
         columns: int | None = None, seed: int = 0, tol: float = 1e-8, dt: float = 0.01) -> Scene:
    """``n`` disks (density 1000, radii uniform in [0.8, 1] x ``radius``, seeded) released
    at rest from a square-ish grid (``columns`` wide, spacing 2.2 ``radius``) into a box
    of fixed walls just wider than the grid: they fall and settle into a pile. The
    benchmark scene (``experiments/``): at rest, the floor carries the total weight."""
    if n < 1:
        raise ValueError(f"pile needs n >= 1 disks, got {n}")
    cols = columns or max(1, int(math.ceil(math.sqrt(n))))
    rows = int(math.ceil(n / cols))
    pitch = 2.2 * radius
    width, height = cols * pitch, (rows + 1) * pitch
    sb = SceneBuilder(dt=dt, gravity=(0.0, -G), tol=tol, name="pile")
    sb.add_material("grain", friction=friction, restitution=restitution)
    wall = 2.0 * radius
    for rect in ([(-wall, -wall), (width + wall, -wall), (width + wall, 0.0), (-wall, 0.0)],
                 [(-wall, 0.0), (0.0, 0.0), (0.0, height), (-wall, height)],
                 [(width, 0.0), (width + wall, 0.0), (width + wall, height), (width, height)]):
        _support(sb, heavy, 1000.0, vertices=rect, material="grain")
    radii = radius * np.random.default_rng(seed).uniform(0.8, 1.0, n)
    for k in range(n):
        i, j = k % cols, k // cols
        sb.add_disk(center=((i + 0.5) * pitch, (j + 0.5) * pitch), radius=float(radii[k]), density=1000.0,
                    material="grain")
    return sb.build()


def bolted_slope(heavy: bool = False, *, bolts: bool = True, angle: float = 35.0, friction: float = 0.5,
                 blocks: int = 3, dt: float = 0.01) -> Scene:
    """A jointed rock slope: ``blocks`` 2 x 1 m blocks (density 2600) in a row on a fixed
    rock mass whose face dips at ``angle`` degrees, on a joint of ``friction``. Each
    block is held by a rock bolt (E = 200 GPa, 25 mm: A = 4.9e-4 m^2) from the middle of
    its top face 3 m into the rock mass, inclined 45 degrees against sliding. Without
    ``bolts`` the blocks slide together at g (sin a - mu cos a) once tan a > mu; with them
    they stay put. Bodies 0 .. blocks-1 are the blocks (the lowest first), the last is
    the rock mass."""
    a = math.radians(angle)
    down, out = np.array([math.cos(a), -math.sin(a)]), np.array([math.sin(a), math.cos(a)])
    length = 2.0 * blocks + 4.0
    sb = SceneBuilder(dt=dt, gravity=(0.0, -G), name="bolted-slope")
    sb.add_material("rock", friction=friction, restitution=0.0)
    tops, ids = [], []
    for k in range(blocks):
        s0, s1 = length - 2.0 - 2.0 * (k + 1), length - 2.0 - 2.0 * k  # the lowest block first
        corners = [s0 * down, s1 * down, s1 * down + out, s0 * down + out]
        ids.append(sb.add_polygon([tuple(c) for c in corners], density=2600.0, material="rock"))
        tops.append(0.5 * (s0 + s1) * down + out)
    bottom = -length * math.sin(a) - 6.0
    mass = sb.add_polygon([(0.0, 0.0), (0.0, bottom), (length * math.cos(a), bottom), tuple(length * down)],
                          density=2600.0, fixed=True, material="rock")
    if bolts:
        into = -(out + down) / math.sqrt(2.0)  # 45 degrees into the rock, up the slope
        for body, top in zip(ids, tops):
            sb.add_bolt(body, mass, tuple(top), tuple(top + 3.0 * into), young=2e11, area=math.pi * 0.0125 ** 2)
    return sb.build()
