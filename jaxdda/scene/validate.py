"""Host-side (numpy) checks of a scene before it is built: finite fields, no initial overlap.

Shapes, in world coordinates:
``("disk", centre, radius)``, ``("ring", centre, outer, inner)`` (material between the
radii) and ``("polygon", vertices)`` ((n, 2), simple, possibly concave).
"""
from __future__ import annotations

import dataclasses

import jax
import numpy as np

from jaxdda.errors import SceneError

_REL_TOL = 1e-9  # "on the boundary", relative to the size of the pair


def check_finite(body: str, field: str, value) -> None:
    """Raise SceneError if ``value`` is not numeric (strings and booleans are not) or
    has a NaN or inf entry."""
    try:
        raw = np.asarray(value)
        arr = np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        raise SceneError(f"{body}: field '{field}' is not numeric: {value!r}") from None
    if raw.dtype.kind not in "iuf":
        raise SceneError(f"{body}: field '{field}' is not numeric: {value!r}")
    bad = np.argwhere(~np.isfinite(arr))
    if len(bad):
        where = f" entry {tuple(int(k) for k in bad[0])}" if arr.ndim else ""
        raise SceneError(f"{body}: field '{field}'{where} = {arr[tuple(bad[0])]} is not finite (NaN or inf)")


def check_flag(body: str, field: str, value) -> None:
    """Raise SceneError unless ``value`` is a boolean."""
    if not isinstance(value, (bool, np.bool_)):
        raise SceneError(f"{body}: field '{field}' must be true or false, got {value!r}")


def check_positive(body: str, field: str, value) -> None:
    """Raise SceneError unless every entry of ``value`` is finite and > 0."""
    check_finite(body, field, value)
    arr = np.asarray(value, dtype=float)
    if np.any(arr <= 0):
        raise SceneError(f"{body}: field '{field}' must be > 0, got {value}")


# ----------------------------------------------------------------------------- primitives
def _segment_distance(points, a, b) -> np.ndarray:
    """(k,) distance from each point to the nearest of the segments a[j]-b[j]."""
    ab = b - a
    ap = points[:, None, :] - a[None]
    t = np.clip((ap * ab).sum(-1) / np.maximum((ab * ab).sum(-1), 1e-300), 0.0, 1.0)
    return np.sqrt(((ap - t[..., None] * ab) ** 2).sum(-1)).min(axis=1)


def _inside(points, a, b) -> np.ndarray:
    """(k,) crossing-number point-in-polygon test (boundary points: either answer)."""
    px, py = points[:, 0:1], points[:, 1:2]
    straddle = (a[:, 1] > py) != (b[:, 1] > py)
    with np.errstate(divide="ignore", invalid="ignore"):
        x_cross = a[:, 0] + (py - a[:, 1]) * (b[:, 0] - a[:, 0]) / (b[:, 1] - a[:, 1])
    return (straddle & (px < x_cross)).sum(axis=1) % 2 == 1


def point_outside_by(point, shape) -> float:
    """How far ``point`` lies outside the material of a body's world ``shape`` (0: in it
    or on its boundary)."""
    p = np.asarray(point, float)
    if shape[0] == "polygon":
        a, b = _edges(shape[1])
        return 0.0 if _inside(p[None], a, b)[0] else float(_segment_distance(p[None], a, b)[0])
    r = float(np.linalg.norm(p - shape[1]))
    inner = shape[3] if shape[0] == "ring" else 0.0
    return max(r - shape[2], inner - r, 0.0)


def depth_inside(point, shape) -> float:
    """How deep ``point`` lies inside the material of a body's world ``shape`` (0 outside)."""
    p = np.asarray(point, float)
    if shape[0] == "polygon":
        return float(_point_depth(p[None], shape[1])[0])
    r = float(np.linalg.norm(p - shape[1]))
    inner = shape[3] if shape[0] == "ring" else 0.0
    return max(min(shape[2] - r, r - inner if inner else shape[2] - r), 0.0)


def _edges(v):
    return v, np.roll(v, -1, axis=0)


def _point_depth(points, v) -> np.ndarray:
    """(k,) distance of each point to the boundary of polygon v if inside it, else 0."""
    a, b = _edges(v)
    return np.where(_inside(points, a, b), _segment_distance(points, a, b), 0.0)


def _boundary_samples(v, w, eps) -> np.ndarray:
    """Vertices of polygon v plus the midpoints of its edges cut at every contact with w.

    Between two consecutive cuts an edge piece lies wholly inside, outside or on the
    boundary of w, so these points see any part of v's boundary inside w.
    """
    p, q = _edges(v)
    a, b = _edges(w)
    d = q - p  # (n, 2)
    e = b - a  # (m, 2)
    r = a[None] - p[:, None]  # (n, m, 2)
    den = d[:, None, 0] * e[None, :, 1] - d[:, None, 1] * e[None, :, 0]
    with np.errstate(divide="ignore", invalid="ignore"):
        t = (r[..., 0] * e[None, :, 1] - r[..., 1] * e[None, :, 0]) / den
        u = (r[..., 0] * d[:, None, 1] - r[..., 1] * d[:, None, 0]) / den
    tol = 1e-9
    t = np.where((t >= -tol) & (t <= 1 + tol) & (u >= -tol) & (u <= 1 + tol), t, np.nan)
    # Vertices of w lying on an edge of v (collinear overlaps, vertex contacts).
    dd = np.maximum((d * d).sum(-1), 1e-300)[:, None]
    s = (r * d[:, None, :]).sum(-1) / dd
    off = np.abs(r[..., 0] * d[:, None, 1] - r[..., 1] * d[:, None, 0]) / np.sqrt(dd)
    s = np.where((off <= eps) & (s >= 0) & (s <= 1), s, np.nan)
    n = len(v)
    cuts = np.sort(np.concatenate([np.zeros((n, 1)), np.ones((n, 1)), np.clip(t, 0, 1), s], axis=1), axis=1)
    mid = (cuts[:, :-1] + cuts[:, 1:]) / 2  # NaN wherever a cut is missing
    pts = p[:, None, :] + mid[..., None] * d[:, None, :]
    pts = pts[np.isfinite(mid)]
    return np.concatenate([v, pts])


# ----------------------------------------------------------------------------- pair depths
def _radial(c_disk, r_disk, c_ring, outer, inner) -> float:
    """Overlap of the distance ranges from c_ring covered by a disk and by an annulus."""
    d = float(np.hypot(*(np.asarray(c_disk, float) - np.asarray(c_ring, float))))
    return min(d + r_disk, outer) - max(d - r_disk, inner)


def _circles_depth(c1, ro1, ri1, c2, ro2, ri2) -> float:
    """Depth between two annuli (a disk has inner radius 0).

    Their materials overlap iff each one's outer disk overlaps the other's annulus;
    the depth is the smaller radial overlap.
    """
    if ri1 == 0 and ri2 == 0:
        d = float(np.hypot(*(np.asarray(c1, float) - np.asarray(c2, float))))
        return max(0.0, ro1 + ro2 - d)
    return max(0.0, min(_radial(c1, ro1, c2, ro2, ri2), _radial(c2, ro2, c1, ro1, ri1)))


def _polygon_circle_depth(v, c, outer, inner) -> float:
    """Depth of polygon v in a disk (inner == 0) or annulus centred at c."""
    a, b = _edges(v)
    c = np.asarray(c, float)
    dist = float(_segment_distance(c[None], a, b)[0])
    into_disk = outer + dist if _inside(c[None], a, b)[0] else outer - dist
    if inner == 0:
        return max(0.0, into_disk)
    out_of_hole = float(np.sqrt(((v - c) ** 2).sum(1)).max()) - inner  # farthest point is a vertex
    return max(0.0, min(into_disk, out_of_hole))


def _polygons_depth(v, w) -> float:
    """Largest depth of a boundary sample of one polygon inside the other (0 if disjoint)."""
    size = float(np.ptp(np.concatenate([v, w]), axis=0).max())
    eps = _REL_TOL * size
    sv, sw = _boundary_samples(v, w, eps), _boundary_samples(w, v, eps)
    depth = max(_point_depth(sv, w).max(), _point_depth(sw, v).max())
    if depth <= eps:
        a, b = _edges(w)
        if _segment_distance(sv, a, b).max() <= eps:
            # The boundary of v lies on that of w: the polygons coincide.
            p, q = _edges(v)
            return 0.5 * np.sqrt(0.5 * abs((p[:, 0] * q[:, 1] - q[:, 0] * p[:, 1]).sum()))
    return float(depth)


def _as_circle(shape):
    if shape[0] == "disk":
        return np.asarray(shape[1], float), float(shape[2]), 0.0
    return np.asarray(shape[1], float), float(shape[2]), float(shape[3])


def overlap_depth(shape_a, shape_b) -> float:
    """Penetration depth between two shapes (0.0 when apart or just touching)."""
    kinds = (shape_a[0], shape_b[0])
    for k in kinds:
        if k not in ("disk", "ring", "polygon"):
            raise ValueError(f"unknown shape kind {k!r}")
    if kinds == ("polygon", "polygon"):
        return _polygons_depth(np.asarray(shape_a[1], float), np.asarray(shape_b[1], float))
    if kinds[0] == "polygon":
        return _polygon_circle_depth(np.asarray(shape_a[1], float), *_as_circle(shape_b))
    if kinds[1] == "polygon":
        return _polygon_circle_depth(np.asarray(shape_b[1], float), *_as_circle(shape_a))
    return _circles_depth(*_as_circle(shape_a), *_as_circle(shape_b))


# ----------------------------------------------------------------------------- scene check
def _bounding_boxes(shapes) -> np.ndarray:
    """(n, 4) boxes [xmin, ymin, xmax, ymax]."""
    boxes = np.empty((len(shapes), 4))
    for k, s in enumerate(shapes):
        if s[0] == "polygon":
            v = np.asarray(s[1], float)
            boxes[k] = [*v.min(axis=0), *v.max(axis=0)]
        else:
            c, r = np.asarray(s[1], float), float(s[2])
            boxes[k] = [*(c - r), *(c + r)]
    return boxes


def check_no_interpenetration(shapes: list, labels: list[str], tol: float, adjacent=frozenset()) -> None:
    """Raise SceneError for the first pair of shapes overlapping by more than ``tol``;
    pairs (i < j) in ``adjacent`` (elements of one mesh sharing a node) are not checked."""
    boxes = _bounding_boxes(shapes)
    for i in range(len(shapes) - 1):
        rest = boxes[i + 1:]
        gap = np.maximum(rest[:, :2] - boxes[i, 2:], boxes[i, :2] - rest[:, 2:]).max(axis=1)
        for j in i + 1 + np.flatnonzero(gap <= tol):
            if (i, int(j)) in adjacent:
                continue
            depth = overlap_depth(shapes[i], shapes[j])
            if depth > tol:
                raise SceneError(
                    f"{labels[i]} and {labels[j]} interpenetrate at the start (overlap {depth:.3g})"
                )


# Params fields and the lower bound of their values: (bound, whether it is allowed).
_PARAM_RANGES = {
    "dt": (0.0, False), "tol": (0.0, False), "max_iter": (1.0, True), "density": (0.0, False),
    "young": (0.0, True), "friction": (0.0, True), "cohesion": (0.0, True), "rolling": (0.0, True),
    "tensile": (0.0, True), "margin": (0.0, True), "rupture_width": (0.0, True),
    "connector_axial": (0.0, True), "connector_bending": (0.0, True), "connector_shear": (0.0, True),
}


def check_counts(**counts) -> None:
    """Each named count (``steps=``, ``chunk=``, ...) is a positive integer, else a
    ValueError naming it."""
    for name, value in counts.items():
        if isinstance(value, bool) or int(value) != value or value < 1:
            raise ValueError(f"{name} must be a positive integer, got {value!r}")


def check_params(params, where: str = "params") -> None:
    """Raise SceneError naming the field and entry of ``params`` (a Params, possibly with a
    leading batch axis) that is NaN or inf, or out of its range (dt, tol > 0; restitution
    in [0, 1]; strengths, moduli and stiffnesses >= 0; ...). Traced values are skipped."""
    for f in dataclasses.fields(params):
        value = getattr(params, f.name)
        if isinstance(value, jax.core.Tracer):
            continue
        arr = np.asarray(value)
        if arr.dtype.kind not in "iuf":
            continue
        check_finite(where, f.name, arr)
        if f.name == "restitution":
            bad, rule = np.argwhere((arr < 0) | (arr > 1)), "in [0, 1]"
        else:
            lo, closed = _PARAM_RANGES.get(f.name, (-np.inf, True))
            bad, rule = np.argwhere((arr < lo) if closed else (arr <= lo)), f">= {lo:g}" if closed else f"> {lo:g}"
        if len(bad):
            at = tuple(int(k) for k in bad[0])
            entry = f" entry {at}" if arr.ndim else ""
            raise SceneError(f"{where}: field '{f.name}'{entry} = {arr[at]} must be {rule}")
