"""Joint-line block cutting, the way DDA users describe rock: a boundary polygon cut by
joint lines into polygonal blocks (Shi's "line and block cutting"), host-side numpy.

The boundary's edges and the joint segments form a planar graph: every crossing splits
both lines, dangling pieces (joints that end inside a block) are pruned, and the faces
of what remains, traced with the interior on the left, are the blocks. Each block edge
keeps the index of the line that made it (``BOUNDARY`` for the boundary), so joint
properties can be given to the interfaces.
"""
from __future__ import annotations

import dataclasses
import math

import numpy as np

from jaxdda.bodies import geometry
from jaxdda.errors import SceneError

BOUNDARY = -1  # the edge tag of the boundary polygon


@dataclasses.dataclass(frozen=True)
class JointSet:
    """Parallel joints: ``dip`` (degrees counter-clockwise from the x axis), normal
    ``spacing``, and optionally a finite ``trace`` length with rock ``bridge`` between
    traces along a line (each line's traces shifted by ``stagger`` x (trace + bridge));
    ``offset`` moves the set along its normal."""

    dip: float
    spacing: float
    trace: float | None = None
    bridge: float = 0.0
    stagger: float = 0.5
    offset: float = 0.0

    def lines(self, boundary: np.ndarray) -> np.ndarray:
        """Segments (k, 2, 2) of this set over the boundary's extent."""
        for field in ("dip", "spacing", "bridge", "stagger", "offset"):
            if not math.isfinite(getattr(self, field)):
                raise SceneError(f"joint set: field '{field}' must be finite, got {getattr(self, field)}")
        if not self.spacing > 0:
            raise SceneError(f"joint set: field 'spacing' must be > 0, got {self.spacing}")
        if self.trace is not None and not (math.isfinite(self.trace) and self.trace > 0):
            raise SceneError(f"joint set: field 'trace' must be > 0, got {self.trace}")
        if self.bridge < 0:
            raise SceneError(f"joint set: field 'bridge' must be >= 0, got {self.bridge}")
        angle = math.radians(self.dip)
        along, normal = np.array([math.cos(angle), math.sin(angle)]), np.array([-math.sin(angle), math.cos(angle)])
        centre = 0.5 * (boundary.min(0) + boundary.max(0))
        reach = float(np.linalg.norm(boundary - centre, axis=1).max()) * 1.01
        first = math.ceil((-reach - self.offset) / self.spacing)
        out = []
        for k in range(first, math.floor((reach - self.offset) / self.spacing) + 1):
            base = centre + (self.offset + k * self.spacing) * normal
            if self.trace is None:
                out.append([base - reach * along, base + reach * along])
                continue
            period = self.trace + self.bridge
            start = -reach - period + ((k * self.stagger) % 1.0) * period
            while start < reach:
                out.append([base + start * along, base + (start + self.trace) * along])
                start += period
        return np.asarray(out, float).reshape(-1, 2, 2)


@dataclasses.dataclass(frozen=True)
class Block:
    """A cut block: counter-clockwise ``vertices`` (n, 2) and, per edge (vertex k to k + 1),
    the index of the joint line that made it (``BOUNDARY``: the boundary)."""

    vertices: np.ndarray
    edge_lines: np.ndarray

    @property
    def area(self) -> float:
        return geometry.polygon_properties(self.vertices)[0]


def cut_blocks(boundary, lines, *, min_area: float = 0.0) -> list[Block]:
    """Cut the simple polygon ``boundary`` by joint ``lines`` (segments (k, 2, 2) or a
    list of pairs of points; lines may reach outside the boundary and end anywhere).
    Returns the blocks, largest first; slivers under ``min_area`` are an error (a mesh of
    joints finer than the model should be), not dropped."""
    boundary = np.asarray(boundary, float)
    problem = geometry.simple_polygon_problem(boundary)
    if problem is not None:
        raise SceneError(f"block cutting: the boundary is not a valid polygon: {problem}")
    boundary = geometry.counter_clockwise(boundary)
    lines = np.asarray(lines, float).reshape(-1, 2, 2)
    bad = np.flatnonzero(~np.isfinite(lines).all(axis=(1, 2)))
    if len(bad):
        raise SceneError(f"block cutting: joint line {int(bad[0])} is not finite")
    short = np.flatnonzero(np.linalg.norm(lines[:, 1] - lines[:, 0], axis=1) == 0)
    if len(short):
        raise SceneError(f"block cutting: joint line {int(short[0])} has zero length")
    size = float(np.ptp(boundary, axis=0).max())
    tol = 1e-9 * size
    segments = [(boundary[k], boundary[(k + 1) % len(boundary)], BOUNDARY) for k in range(len(boundary))]
    segments += [(a, b, k) for k, (a, b) in enumerate(lines)]
    points, edges = _arrangement(segments, tol)
    edges = _prune_dangling(edges)
    blocks = []
    for loop in _faces(points, edges):
        verts = points[[u for u, _, _ in loop]]
        area = geometry.polygon_properties(verts)[0] if len(verts) >= 3 else 0.0
        if area <= 0:
            continue  # the outer face (clockwise)
        if geometry.simple_polygon_problem(verts) is not None or not _inside(_interior_point(verts), boundary):
            continue
        blocks.append(_simplified(Block(verts, np.array([tag for _, _, tag in loop]))))
    tiny = [b for b in blocks if b.area < min_area]
    if tiny:
        raise SceneError(f"block cutting: a block of area {tiny[0].area:.3g} near {tiny[0].vertices.mean(0).tolist()} "
                         f"is smaller than min_area {min_area}")
    return sorted(blocks, key=lambda b: -b.area)


def _arrangement(segments, tol: float):
    """Split every segment at every crossing; returns node points (P, 2) and edges
    {(u, v): tag} with u < v (a joint on the boundary keeps the boundary's tag)."""
    n = len(segments)
    cuts = [[0.0, 1.0] for _ in range(n)]
    for i in range(n):
        p, r = segments[i][0], segments[i][1] - segments[i][0]
        for j in range(i + 1, n):
            q, s = segments[j][0], segments[j][1] - segments[j][0]
            denom = r[0] * s[1] - r[1] * s[0]
            qp = q - p
            if abs(denom) > tol * max(np.linalg.norm(r), np.linalg.norm(s)):
                t = (qp[0] * s[1] - qp[1] * s[0]) / denom
                u = (qp[0] * r[1] - qp[1] * r[0]) / denom
                ei, ej = tol / np.linalg.norm(r), tol / np.linalg.norm(s)
                if -ei <= t <= 1 + ei and -ej <= u <= 1 + ej:
                    cuts[i].append(min(max(t, 0.0), 1.0))
                    cuts[j].append(min(max(u, 0.0), 1.0))
            elif abs(qp[0] * r[1] - qp[1] * r[0]) <= tol * np.linalg.norm(r):  # collinear: split at the ends
                for end, target, base, direction in ((q, i, p, r), (q + s, i, p, r), (p, j, q, s), (p + r, j, q, s)):
                    t = float(np.dot(end - base, direction) / np.dot(direction, direction))
                    if 0.0 < t < 1.0:
                        cuts[target].append(t)
    points: list[np.ndarray] = []
    index: dict[tuple[int, int], int] = {}

    def node(x):
        key = (round(x[0] / tol), round(x[1] / tol))
        for dx in (-1, 0, 1):  # a point within tol of a grid line may round either way
            for dy in (-1, 0, 1):
                if (key[0] + dx, key[1] + dy) in index:
                    return index[(key[0] + dx, key[1] + dy)]
        index[key] = len(points)
        points.append(x)
        return index[key]

    edges: dict[tuple[int, int], int] = {}
    for (a, b, tag), ts in zip(segments, cuts):
        ts = np.unique(ts)
        ids = [node(a + t * (b - a)) for t in ts]
        for u, v in zip(ids, ids[1:]):
            if u != v:
                key = (min(u, v), max(u, v))
                edges[key] = tag if edges.get(key, tag) != BOUNDARY else BOUNDARY
    return np.asarray(points), edges


def _prune_dangling(edges: dict) -> dict:
    """Drop edges with a free end until none is left (joints ending inside a block)."""
    edges = dict(edges)
    while True:
        degree: dict[int, int] = {}
        for u, v in edges:
            degree[u] = degree.get(u, 0) + 1
            degree[v] = degree.get(v, 0) + 1
        loose = [e for e in edges if degree[e[0]] == 1 or degree[e[1]] == 1]
        if not loose:
            return edges
        for e in loose:
            del edges[e]


def _faces(points: np.ndarray, edges: dict) -> list[list[tuple[int, int, int]]]:
    """Every face of the planar graph as a loop of half-edges (u, v, tag), interior on the
    left (counter-clockwise for bounded faces)."""
    out: dict[int, list[int]] = {}
    tag = {}
    for (u, v), t in edges.items():
        out.setdefault(u, []).append(v)
        out.setdefault(v, []).append(u)
        tag[(u, v)] = tag[(v, u)] = t
    for u, nbrs in out.items():
        d = points[nbrs] - points[u]
        out[u] = [nbrs[k] for k in np.argsort(np.arctan2(d[:, 1], d[:, 0]))]
    seen, faces = set(), []
    for start in tag:
        if start in seen:
            continue
        loop, (u, v) = [], start
        while (u, v) not in seen:
            seen.add((u, v))
            loop.append((u, v, tag[(u, v)]))
            around = out[v]
            w = around[(around.index(u) - 1) % len(around)]  # the next edge clockwise from v -> u
            u, v = v, w
        faces.append(loop)
    return faces


def _simplified(block: Block) -> Block:
    """Drop vertices where two edges of the same line meet in a straight line."""
    v, tags = block.vertices, block.edge_lines
    keep = []
    for k in range(len(v)):
        prev, nxt = v[k - 1], v[(k + 1) % len(v)]
        cross = (v[k][0] - prev[0]) * (nxt[1] - prev[1]) - (v[k][1] - prev[1]) * (nxt[0] - prev[0])
        scale = np.linalg.norm(nxt - prev) ** 2
        if not (abs(cross) <= 1e-12 * scale and tags[k - 1] == tags[k]):
            keep.append(k)
    return Block(v[keep], tags[keep])


def _interior_point(verts: np.ndarray) -> np.ndarray:
    """A point strictly inside a counter-clockwise simple polygon: just left of the middle
    of its longest edge."""
    e = np.roll(verts, -1, axis=0) - verts
    k = int(np.argmax(np.linalg.norm(e, axis=1)))
    mid = verts[k] + 0.5 * e[k]
    inward = np.array([-e[k][1], e[k][0]]) / np.linalg.norm(e[k])
    depth = np.inf
    for a, b in zip(verts, np.roll(verts, -1, axis=0)):  # stay closer than any other edge
        d = _segment_distance(mid, a, b)
        if d > 0:
            depth = min(depth, d)
    return mid + 0.5 * min(depth, np.linalg.norm(e[k])) * inward * 1e-3


def _segment_distance(p, a, b) -> float:
    ab = b - a
    t = np.clip(np.dot(p - a, ab) / np.dot(ab, ab), 0.0, 1.0)
    return float(np.linalg.norm(p - (a + t * ab)))


def _inside(p: np.ndarray, poly: np.ndarray) -> bool:
    """Even-odd test."""
    x, y = p
    inside = False
    for a, b in zip(poly, np.roll(poly, -1, axis=0)):
        if (a[1] > y) != (b[1] > y):
            cross_x = a[0] + (y - a[1]) * (b[0] - a[0]) / (b[1] - a[1])
            if x < cross_x:
                inside = not inside
    return inside


# -- assigning blocks: holes, regions and material lines (DDA's hole and material lines)
def _point(value, what: str) -> np.ndarray:
    p = np.asarray(value, float)
    if p.shape != (2,) or not np.isfinite(p).all():
        raise SceneError(f"{what} must be a finite point (x, y), got {value!r}")
    return p


def blocks_containing(blocks: list[Block], point) -> list[int]:
    """Indices of the blocks whose interior contains ``point`` (a hole point)."""
    p = _point(point, "a hole point")
    return [k for k, b in enumerate(blocks) if _inside(p, b.vertices)]


def blocks_inside(blocks: list[Block], polygon) -> list[int]:
    """Indices of the blocks whose centroid lies in the simple polygon ``polygon``."""
    poly = np.asarray(polygon, float)
    problem = geometry.simple_polygon_problem(poly) if poly.ndim == 2 and poly.shape[1:] == (2,) else "not points"
    if problem is not None:
        raise SceneError(f"the region is not a valid polygon: {problem}")
    return [k for k, b in enumerate(blocks) if _inside(np.asarray(geometry.polygon_properties(b.vertices)[1]), poly)]


def blocks_crossed(blocks: list[Block], start, end) -> list[int]:
    """Indices of the blocks whose interior the segment start-end passes through (a
    material line)."""
    a, b = _point(start, "a material line's 'from'"), _point(end, "a material line's 'to'")
    d = b - a
    out = []
    for k, block in enumerate(blocks):
        v, w = block.vertices, np.roll(block.vertices, -1, axis=0)
        cuts = [0.0, 1.0]
        for p, q in zip(v, w):
            e = q - p
            den = d[0] * e[1] - d[1] * e[0]
            if den != 0:
                t = ((p[0] - a[0]) * e[1] - (p[1] - a[1]) * e[0]) / den
                s = ((p[0] - a[0]) * d[1] - (p[1] - a[1]) * d[0]) / den
                if 0 <= t <= 1 and 0 <= s <= 1:
                    cuts.append(float(t))
        cuts = np.unique(cuts)
        if any(_inside(a + 0.5 * (t0 + t1) * d, v) for t0, t1 in zip(cuts[:-1], cuts[1:])):
            out.append(k)
    return out
