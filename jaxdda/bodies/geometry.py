"""Host-side (numpy) geometry of body shapes: areas, centroids, polar moments, validity."""
from __future__ import annotations

import math

import numpy as np

# Relative tolerance of the orientation test, scaled by the squared polygon size.
_REL_TOL = 1e-12


def polygon_properties(vertices) -> tuple[float, np.ndarray, float]:
    """``(signed_area, centroid, polar_moment)`` of a simple polygon (either orientation).

    ``signed_area > 0`` for counter-clockwise order; ``polar_moment`` is the integral of
    ``|x - centroid|^2 dA`` (>= 0). Exact triangle-fan formulas, valid for concave polygons.
    Raises ValueError on a zero-area polygon.
    """
    v = np.asarray(vertices, dtype=float)
    origin = v.mean(axis=0)
    p = v - origin  # shift for accuracy far from the origin
    q = np.roll(p, -1, axis=0)
    cross = p[:, 0] * q[:, 1] - q[:, 0] * p[:, 1]
    area = cross.sum() / 2.0
    if area == 0.0:
        raise ValueError("polygon has zero area")
    first = (cross[:, None] * (p + q)).sum(axis=0) / (6.0 * area)
    second = (cross * ((p * p).sum(1) + (p * q).sum(1) + (q * q).sum(1))).sum() / 12.0
    polar = abs(second - area * (first @ first))  # parallel axis theorem, signs cancel
    return float(area), origin + first, float(polar)


def counter_clockwise(vertices) -> np.ndarray:
    """A copy of ``vertices`` ordered counter-clockwise."""
    v = np.array(vertices, dtype=float)
    p = v - v.mean(axis=0)
    q = np.roll(p, -1, axis=0)
    return v[::-1].copy() if (p[:, 0] * q[:, 1] - q[:, 0] * p[:, 1]).sum() < 0 else v


def _orient(a, b, c) -> np.ndarray:
    """Twice the signed area of triangles (a, b, c); broadcasts over leading axes."""
    return (b[..., 0] - a[..., 0]) * (c[..., 1] - a[..., 1]) - (b[..., 1] - a[..., 1]) * (c[..., 0] - a[..., 0])


def _on_segment(a, b, p, eps) -> np.ndarray:
    """Whether p, known to be collinear with segment ab, lies within its bounding box."""
    lo, hi = np.minimum(a, b) - eps, np.maximum(a, b) + eps
    return np.all((p >= lo) & (p <= hi), axis=-1)


def simple_polygon_problem(vertices) -> str | None:
    """None for a valid simple polygon, else a short reason why it is not one."""
    v = np.asarray(vertices, dtype=float)
    if v.ndim != 2 or v.shape[1] != 2 or len(v) < 3:
        return "fewer than 3 vertices"
    bad = np.flatnonzero(~np.isfinite(v).all(axis=1))
    if bad.size:
        return f"non-finite coordinate at vertex {bad[0]}"
    n = len(v)
    nxt = np.roll(v, -1, axis=0)
    rep = np.flatnonzero(np.all(v == nxt, axis=1))
    if rep.size:
        return f"repeated vertex {min(rep[0] + 1, n - 1)}"  # last == first names the last

    p = v - v.mean(axis=0)
    size = float(np.abs(p).max())
    tol = _REL_TOL * size * size  # tolerance on an orientation (an area)
    eps = _REL_TOL * size  # tolerance on a coordinate
    far = p[np.argmax((p * p).sum(1))]
    if np.abs(_orient(np.zeros(2), far, p)).max() <= tol * 4:
        return "zero area"

    a, b = p, np.roll(p, -1, axis=0)
    # Adjacent edges (i, i+1) folding back onto each other.
    c = np.roll(p, -2, axis=0)
    fold = (np.abs(_orient(a, b, c)) <= tol) & (((b - a) * (c - b)).sum(1) < 0)
    if fold.any():
        i = int(np.flatnonzero(fold)[0])
        return f"self-intersecting (edges {i} and {(i + 1) % n} cross)"
    # Non-adjacent edges: any contact counts.
    for i in range(n - 2):
        j = np.arange(i + 2, n if i > 0 else n - 1)
        if j.size == 0:
            continue
        d1, d2 = _orient(a[j], b[j], a[i]), _orient(a[j], b[j], b[i])
        d3, d4 = _orient(a[i], b[i], a[j]), _orient(a[i], b[i], b[j])
        s1, s2, s3, s4 = (np.where(np.abs(d) <= tol, 0, np.sign(d)) for d in (d1, d2, d3, d4))
        hit = (s1 * s2 < 0) & (s3 * s4 < 0)
        hit |= (s1 == 0) & _on_segment(a[j], b[j], a[i], eps)
        hit |= (s2 == 0) & _on_segment(a[j], b[j], b[i], eps)
        hit |= (s3 == 0) & _on_segment(a[i], b[i], a[j], eps)
        hit |= (s4 == 0) & _on_segment(a[i], b[i], b[j], eps)
        if hit.any():
            return f"self-intersecting (edges {i} and {int(j[np.argmax(hit)])} cross)"
    return None


def disk_area(radius: float) -> float:
    """Area of a disk."""
    return float(np.pi * radius**2)


def ring_area(outer: float, inner: float) -> float:
    """Area of an annulus."""
    return float(np.pi * (outer**2 - inner**2))


def disk_polar_moment(radius: float) -> float:
    """Integral of r^2 dA over a disk about its centre: pi R^4 / 2."""
    return float(np.pi * radius**4 / 2.0)


def ring_polar_moment(outer: float, inner: float) -> float:
    """Integral of r^2 dA over an annulus about its centre: pi (Ro^4 - Ri^4) / 2."""
    return float(np.pi * (outer**4 - inner**4) / 2.0)


def polygon_second_moments(local: np.ndarray) -> np.ndarray:
    """[int x^2, int y^2, int xy] dA of a counter-clockwise polygon whose vertices ``local``
    (n, 2) are relative to its centroid (Green's theorem, edge by edge)."""
    x, y = local[:, 0], local[:, 1]
    xn, yn = np.roll(x, -1), np.roll(y, -1)
    cross = x * yn - xn * y
    ixx = np.sum(cross * (x * x + x * xn + xn * xn)) / 12.0
    iyy = np.sum(cross * (y * y + y * yn + yn * yn)) / 12.0
    ixy = np.sum(cross * (x * yn + 2 * x * y + 2 * xn * yn + xn * y)) / 24.0
    return np.array([ixx, iyy, ixy])


def round_second_moments(outer: float, inner: float = 0.0) -> np.ndarray:
    """[int x^2, int y^2, int xy] dA of a disk (inner = 0) or ring about its centre."""
    i = 0.25 * math.pi * (outer ** 4 - inner ** 4)
    return np.array([i, i, 0.0])
