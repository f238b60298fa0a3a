"""Triangle meshes of blocks (the 3-node elements of paper Section 6.1), host-side numpy.

``mesh_polygon`` meshes a simple polygon (convex or concave) by ear clipping, then splits
every triangle into four at its edge midpoints until no edge is longer than ``max_edge``
(the mesh stays conforming: a shared edge is split once for both of its triangles).
``rectangle_mesh`` is a structured mesh of a rectangle. ``check_mesh`` validates a mesh
given by the user: every error names the triangle or node.
"""
from __future__ import annotations

import numpy as np

from jaxdda.bodies import geometry
from jaxdda.errors import SceneError


def _cross(o, a, b) -> float:
    return float((a[0] - o[0]) * (b[1] - o[1]) - (a[1] - o[1]) * (b[0] - o[0]))


def _inside_or_on(p, a, b, c) -> bool:
    """p in the closed counter-clockwise triangle abc."""
    return _cross(a, b, p) >= 0 and _cross(b, c, p) >= 0 and _cross(c, a, p) >= 0


def triangulate(vertices) -> np.ndarray:
    """Triangles (n - 2, 3) over the vertices of a simple counter-clockwise polygon, by
    ear clipping (a convex corner whose triangle holds no other vertex)."""
    v = np.asarray(vertices, float)
    left = list(range(len(v)))
    triangles = []
    while len(left) > 3:
        for k in range(len(left)):
            i, j, m = left[k - 1], left[k], left[(k + 1) % len(left)]
            if _cross(v[i], v[j], v[m]) <= 0:
                continue  # reflex or flat corner
            if any(_inside_or_on(v[q], v[i], v[j], v[m]) for q in left if q not in (i, j, m)):
                continue
            triangles.append((i, j, m))
            left.pop(k)
            break
        else:
            raise SceneError("the polygon could not be triangulated (is it simple?)")
    triangles.append(tuple(left))
    return np.asarray(triangles, np.int32)


def refine(nodes: np.ndarray, triangles: np.ndarray, max_edge: float) -> tuple[np.ndarray, np.ndarray]:
    """Split every triangle into four at its edge midpoints until no edge exceeds ``max_edge``."""
    nodes, triangles = np.asarray(nodes, float), np.asarray(triangles, np.int32)
    while _edge_lengths(nodes, triangles).max() > max_edge:
        midpoint: dict[tuple[int, int], int] = {}
        points = list(nodes)

        def mid(i, j):
            key = (min(i, j), max(i, j))
            if key not in midpoint:
                midpoint[key] = len(points)
                points.append(0.5 * (nodes[i] + nodes[j]))
            return midpoint[key]

        out = []
        for a, b, c in triangles.tolist():
            ab, bc, ca = mid(a, b), mid(b, c), mid(c, a)
            out += [(a, ab, ca), (ab, b, bc), (ca, bc, c), (ab, bc, ca)]
        nodes, triangles = np.asarray(points), np.asarray(out, np.int32)
    return nodes, triangles


def _edge_lengths(nodes, triangles) -> np.ndarray:
    p = nodes[triangles]
    return np.linalg.norm(p - np.roll(p, -1, axis=1), axis=-1)


def mesh_polygon(vertices, max_edge: float | None = None, *, label: str = "mesh") -> tuple[np.ndarray, np.ndarray]:
    """(nodes (n, 2), triangles (t, 3), counter-clockwise) meshing a simple polygon;
    with ``max_edge``, refined until no edge is longer. Errors start with ``label``."""
    try:
        v = np.asarray(vertices, float)
    except (TypeError, ValueError) as err:
        raise SceneError(f"{label}: field 'vertices' is not a list of (x, y) points ({err})") from None
    problem = geometry.simple_polygon_problem(v)
    if problem is not None:
        raise SceneError(f"{label}: field 'vertices' is not valid: {problem}")
    v = geometry.counter_clockwise(v)
    if max_edge is not None and (isinstance(max_edge, bool) or not np.isfinite(max_edge) or max_edge <= 0):
        raise SceneError(f"{label}: field 'max_edge' must be a positive number, got {max_edge!r}")
    nodes, triangles = v, triangulate(v)
    if max_edge is not None:
        nodes, triangles = refine(nodes, triangles, float(max_edge))
    return nodes, triangles


def rectangle_mesh(x0: float, y0: float, x1: float, y1: float, nx: int, ny: int) -> tuple[np.ndarray, np.ndarray]:
    """A structured mesh of the rectangle [x0, x1] x [y0, y1]: nx by ny cells, each cut
    into two counter-clockwise triangles along alternating diagonals. Nodes row by row
    from (x0, y0)."""
    for field, value in (("nx", nx), ("ny", ny)):
        if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < 1:
            raise SceneError(f"mesh: field '{field}' must be a positive integer, got {value!r}")
    if not (np.isfinite([x0, y0, x1, y1]).all() and x1 > x0 and y1 > y0):
        raise SceneError(f"mesh: the rectangle ({x0}, {y0}) - ({x1}, {y1}) is empty or not finite")
    xs, ys = np.linspace(x0, x1, nx + 1), np.linspace(y0, y1, ny + 1)
    nodes = np.stack(np.meshgrid(xs, ys), -1).reshape(-1, 2)
    triangles = []
    for j in range(ny):
        for i in range(nx):
            a, b = j * (nx + 1) + i, j * (nx + 1) + i + 1
            c, d = b + nx + 1, a + nx + 1
            triangles += [(a, b, c), (a, c, d)] if (i + j) % 2 == 0 else [(a, b, d), (b, c, d)]
    return nodes, np.asarray(triangles, np.int32)


def check_mesh(label: str, nodes, triangles) -> tuple[np.ndarray, np.ndarray]:
    """Validate a user's mesh; returns it as arrays. Errors name the node or triangle:
    non-finite nodes, indices out of range, repeated nodes in a triangle, inverted
    (clockwise) or degenerate triangles, an edge shared by more than two triangles,
    nodes no triangle uses."""
    try:
        nodes = np.asarray(nodes, float)
        triangles = np.asarray(triangles)
    except (TypeError, ValueError) as err:
        raise SceneError(f"{label}: the mesh is not numeric ({err})") from None
    if nodes.ndim != 2 or nodes.shape[1] != 2 or len(nodes) < 3:
        raise SceneError(f"{label}: field 'nodes' must be a list of at least 3 (x, y) points, got shape {nodes.shape}")
    if triangles.ndim != 2 or triangles.shape[1] != 3 or len(triangles) < 1:
        raise SceneError(f"{label}: field 'triangles' must be a list of (i, j, k) node triples, got shape "
                         f"{triangles.shape}")
    bad = np.flatnonzero(~np.isfinite(nodes).all(1))
    if len(bad):
        raise SceneError(f"{label}: node {int(bad[0])} is not finite: {nodes[bad[0]].tolist()}")
    if not np.issubdtype(triangles.dtype, np.integer):
        raise SceneError(f"{label}: field 'triangles' must hold node indices (integers)")
    out = np.flatnonzero(((triangles < 0) | (triangles >= len(nodes))).any(1))
    if len(out):
        raise SceneError(f"{label}: triangle {int(out[0])} {triangles[out[0]].tolist()} names a node outside "
                         f"0..{len(nodes) - 1}")
    for k, (a, b, c) in enumerate(triangles.tolist()):
        if len({a, b, c}) < 3:
            raise SceneError(f"{label}: triangle {k} {[a, b, c]} repeats a node")
    p = nodes[triangles]
    area2 = ((p[:, 1, 0] - p[:, 0, 0]) * (p[:, 2, 1] - p[:, 0, 1]) - (p[:, 1, 1] - p[:, 0, 1]) * (p[:, 2, 0] - p[:, 0, 0]))
    scale = np.max(_edge_lengths(nodes, triangles), axis=1) ** 2
    flat = np.flatnonzero(np.abs(area2) <= 1e-12 * scale)
    if len(flat):
        raise SceneError(f"{label}: triangle {int(flat[0])} {triangles[flat[0]].tolist()} is degenerate (zero area)")
    inverted = np.flatnonzero(area2 < 0)
    if len(inverted):
        raise SceneError(f"{label}: triangle {int(inverted[0])} {triangles[inverted[0]].tolist()} is inverted "
                         f"(its nodes run clockwise)")
    edges: dict[tuple[int, int], int] = {}
    for k, tri in enumerate(triangles.tolist()):
        for i, j in ((tri[0], tri[1]), (tri[1], tri[2]), (tri[2], tri[0])):
            key = (min(i, j), max(i, j))
            edges[key] = edges.get(key, 0) + 1
            if edges[key] > 2:
                raise SceneError(f"{label}: edge {list(key)} of triangle {k} is shared by more than two triangles")
    unused = np.setdiff1d(np.arange(len(nodes)), triangles.ravel())
    if len(unused):
        raise SceneError(f"{label}: node {int(unused[0])} belongs to no triangle")
    return nodes, triangles.astype(np.int32)
