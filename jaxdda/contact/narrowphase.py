"""Narrow phase: one vectorised kernel per pair kind (paper Section 3).

Each kernel maps a batch of candidate pairs to fixed slots of contact records plus a
geometric admissibility mask; the gap test against the detection distance is applied
afterwards for all slots at once (``detect``). Kinds:

* particle-particle (PP I outside, PP II inside a ring): one slot per pair;
* particle-polygon: one slot per edge (PB I, and II for hollow shapes) and one per
  vertex (PB III from outside, PB IV: a vertex of a polygon inside a ring's hole);
* polygon-polygon: vertex-edge slots in both directions. Edge-edge contact emerges as
  two vertex-edge contacts; vertex-vertex contact is reduced to the one vertex-edge pair
  (out of four) whose edge line best separates the two corners (Shi's rule).

Features are a polygon's contact surfaces (``Model.edge_mask``) and their start vertices:
the inside edges of a meshed block are none, and each boundary node counts once.
"""
from __future__ import annotations

import jax
import jax.numpy as jnp

from jaxdda.types import B_HOLE, B_LINE, B_POINT, RING, Contacts, Model

# A vertex's wedge may cross an edge line by this much (sine of the angle), plus the angle
# the two bodies can turn in the step, and still count as touching it from outside: a
# block tilted by 0.002 rad and spinning must keep both corners of the face it lands on.
WEDGE_TOL = 1e-7
# A polygon vertex may lie this fraction of the smaller body's size behind an edge and
# still be held by it (recovers from small penetrations without catching back edges).
PENETRATION_FRACTION = 0.1
# A vertex behind an edge's line by more than the margin d0 (or this fraction of the
# smaller body's size, if larger) is held by that edge only if it lies inside the edge's
# polygon and that edge is (one of) the nearest to it. Behind the line but outside the
# polygon (beside the edge's extension past a corner) is no overlap at all, and inside,
# the overlap is the distance to the nearest edge: a constraint on any other edge would
# throw the vertex out by its distance to that edge's line.
TOUCH_FRACTION = 1e-9


def _cyclic(n_vertices: jax.Array, v_max: int):
    idx = jnp.arange(v_max)
    n = n_vertices[..., None]
    return jnp.where(idx + 1 < n, idx + 1, 0), jnp.where(idx > 0, idx - 1, n - 1)


def _take(x: jax.Array, index: jax.Array) -> jax.Array:
    """x (P, V, 2) gathered along V with index (P, V)."""
    return jnp.take_along_axis(x, index[..., None], axis=1)


def _take1(x: jax.Array, index: jax.Array) -> jax.Array:
    """x (P, V) gathered along V with index (P, V)."""
    return jnp.take_along_axis(x, index, axis=1)


def _record(a, b, ra, pa, btype, rb, qb, eb, key, edge=-1) -> Contacts:
    shape = jnp.broadcast_shapes(*(jnp.shape(x) for x in (a, b, ra, btype, rb, key)),
                                 *(jnp.shape(x)[:-1] for x in (pa, qb, eb)))
    bc = lambda x: jnp.broadcast_to(x, shape)
    bc2 = lambda x: jnp.broadcast_to(x, shape + (2,))
    return Contacts(
        valid=jnp.zeros(shape, bool), a=bc(a).astype(jnp.int32), b=bc(b).astype(jnp.int32),
        ra=bc(ra), pa=bc2(pa), btype=bc(btype).astype(jnp.int32), rb=bc(rb), qb=bc2(qb),
        eb=bc2(eb), key=bc(key).astype(jnp.int64), edge=bc(edge).astype(jnp.int32))


def particle_particle(model: Model, centroid: jax.Array, i: jax.Array, j: jax.Array):
    """PP I (outside) and PP II (inside a ring's hole); one slot per pair (P,)."""
    dist = jnp.linalg.norm(centroid[i] - centroid[j], axis=-1)
    r_i, r_j = model.radius[i], model.radius[j]
    i_in_j = (model.kind[j] == RING) & (dist < model.inner_radius[j]) & (r_i < model.inner_radius[j])
    j_in_i = (model.kind[i] == RING) & (dist < model.inner_radius[i]) & (r_j < model.inner_radius[i]) & ~i_in_j
    a = jnp.where(j_in_i, j, i)
    b = jnp.where(j_in_i, i, j)
    ra = jnp.where(j_in_i, r_j, r_i)
    hole = i_in_j | j_in_i
    rb = jnp.where(i_in_j, model.inner_radius[j], jnp.where(j_in_i, model.inner_radius[i], r_j))
    zero = jnp.zeros(i.shape + (2,))
    rec = _record(a, b, ra, zero, jnp.where(hole, B_HOLE, B_POINT), rb, zero, zero, 0)
    return jax.tree.map(lambda x: x[:, None], rec), jnp.ones(i.shape + (1,), bool)


def particle_polygon(model: Model, centroid: jax.Array, verts: jax.Array, p: jax.Array, q: jax.Array):
    """Particle p against polygon q: slots (P, 2V) = V edge slots then V vertex slots."""
    v_max = model.max_vertices
    c = centroid[p][:, None, :]  # (P, 1, 2)
    radius = model.radius[p][:, None]
    inner = model.inner_radius[p][:, None]
    v = verts[q]  # (P, V, 2)
    mask = model.edge_mask[q]  # contact surfaces, and their start vertices
    nxt, prv = _cyclic(model.n_vertices[q], v_max)
    vn, vp = _take(v, nxt), _take(v, prv)
    inside_ring = ((model.kind[p] == RING)
                   & (jnp.linalg.norm(centroid[q] - centroid[p], axis=-1) < model.inner_radius[p]))[:, None]

    # Edges (PB I): the centre projects onto the edge, from its outer side.
    e = vn - v
    t = jnp.sum((c - v) * e, -1) / jnp.maximum(jnp.sum(e * e, -1), 1e-300)
    out_n = jnp.stack([e[..., 1], -e[..., 0]], -1)
    s = jnp.sum(out_n * (c - v), -1)
    edge_ok = mask & ~inside_ring & (t >= 0) & (t <= 1) & (s >= 0)
    local = model.local_vertices[q]
    edge = _record(p[:, None], q[:, None], radius, jnp.zeros(2), B_LINE, 0.0, local, _take(local, nxt),
                   jnp.arange(v_max)[None, :], jnp.arange(v_max)[None, :])

    # Vertices: PB III (a convex corner touched from outside, centre in its normal cone)
    # or PB IV (a vertex inside a ring's hole).
    convex = (vp[..., 0] - v[..., 0]) * (vn[..., 1] - v[..., 1]) - (vp[..., 1] - v[..., 1]) * (vn[..., 0] - v[..., 0]) < 0
    cone = (jnp.sum((c - v) * (v - vp), -1) > 0) & (jnp.sum((c - v) * (vn - v), -1) < 0)
    corner_ok = mask & ~inside_ring & convex & cone
    hole_ok = mask & inside_ring
    ring_is_a = ~inside_ring
    vert = _record(
        jnp.where(ring_is_a, p[:, None], q[:, None]), jnp.where(ring_is_a, q[:, None], p[:, None]),
        jnp.where(ring_is_a, radius, 0.0), jnp.where(ring_is_a[..., None], 0.0, local),
        jnp.where(ring_is_a, B_POINT, B_HOLE), jnp.where(ring_is_a, 0.0, inner),
        jnp.where(ring_is_a[..., None], local, 0.0), jnp.zeros(2), v_max + jnp.arange(v_max)[None, :])
    records = jax.tree.map(lambda x, y: jnp.concatenate([x, y], 1), edge, vert)
    return records, jnp.concatenate([edge_ok, corner_ok | hole_ok], 1)


def _vertex_edge_terms(vx, nx, px, vy, ny):
    """For vertices of X (P, V, 2) against edges of Y: signed distance s, projection t and
    clearance (how far X's corner wedge stays outside the edge line), each (P, Vx, Vy)."""
    e = ny - vy
    length = jnp.sqrt(jnp.maximum(jnp.sum(e * e, -1), 1e-300))
    out_n = jnp.stack([e[..., 1], -e[..., 0]], -1) / length[..., None]  # (P, Vy, 2)
    rel = vx[:, :, None, :] - vy[:, None, :, :]  # (P, Vx, Vy, 2)
    s = jnp.sum(rel * out_n[:, None], -1)
    t = jnp.sum(rel * e[:, None], -1) / (length * length)[:, None, :]

    def unit(w):
        return w / jnp.sqrt(jnp.maximum(jnp.sum(w * w, -1), 1e-300))[..., None]

    u_prev, u_next = unit(px - vx), unit(nx - vx)  # (P, Vx, 2)
    clear = jnp.minimum(jnp.einsum("pvk,pek->pve", u_prev, out_n), jnp.einsum("pvk,pek->pve", u_next, out_n))
    return s, t, clear


def _inside(vx, vy, vyn, mask_y):
    """Whether each vertex of X (P, Vx, 2) lies inside polygon Y (edges vy -> vyn (P, Vy, 2),
    real where mask_y (P, Vy)): the parity of a horizontal ray's crossings, (P, Vx)."""
    px, py = vx[:, :, None, 0], vx[:, :, None, 1]
    ax, ay, bx, by = vy[:, None, :, 0], vy[:, None, :, 1], vyn[:, None, :, 0], vyn[:, None, :, 1]
    straddle = (ay > py) != (by > py)
    x_cross = ax + (py - ay) * (bx - ax) / jnp.where(straddle, by - ay, 1.0)
    crossings = jnp.sum(straddle & (px < x_cross) & mask_y[:, None, :], -1)
    return crossings % 2 == 1


def _reflex(prev, v, nxt):
    """Reflex vertices (turn right by more than 1e-9 rad on a counter-clockwise outline)."""
    d0, d1 = v - prev, nxt - v
    cross = d0[..., 0] * d1[..., 1] - d0[..., 1] * d1[..., 0]
    return cross < -1e-9 * jnp.linalg.norm(d0, axis=-1) * jnp.linalg.norm(d1, axis=-1)


def _held(s, t, edge_len, inside, real_edges, touch):
    """Which vertex-edge pairs (P, Vx, Ey) may hold the vertex: in front of the edge's
    line (to ``touch``), or inside the polygon with this among its nearest edges (by
    distance to the segment)."""
    beyond = jnp.maximum(jnp.maximum(-t, t - 1.0), 0.0) * edge_len[:, None, :]
    dist = jnp.where(real_edges[:, None, :], jnp.sqrt(s * s + beyond * beyond), jnp.inf)
    nearest = dist <= jnp.min(dist, -1, keepdims=True) * (1.0 + 1e-9) + touch
    return (s >= -touch) | (inside[:, :, None] & nearest)


def polygon_polygon(model: Model, verts: jax.Array, i: jax.Array, j: jax.Array, near_dist: jax.Array,
                    turn: jax.Array, margin: jax.Array):
    """Polygons i (A) and j (B): slots (P, 2 V^2): A's vertices on B's edges, then B's on A's.

    ``near_dist`` (P,): two vertices closer than this form a vertex-vertex contact, and a
    vertex may project this far beyond an edge's end (it can slide onto the edge in the
    step). ``turn`` (P,): the angle the pair can turn relative to each other in the step.
    ``margin`` (): the gap d0 within which a contact counts as closed.
    """
    v_max = model.max_vertices
    va, vb = verts[i], verts[j]
    # Features: the edges that are contact surfaces and their start vertices (in a meshed
    # block, its boundary edges, and each boundary node once).
    ea, eb = model.edge_mask[i], model.edge_mask[j]
    na, pa = _cyclic(model.n_vertices[i], v_max)
    nb, pb = _cyclic(model.n_vertices[j], v_max)
    van, vap, vbn, vbp = _take(va, na), _take(va, pa), _take(vb, nb), _take(vb, pb)
    # Corners that can touch: not reflex. Near a reflex vertex a polygon covers more than
    # a half-plane, so no body touches it there without overlap; a corner entering the
    # notch meets its two edges (two vertex-edge contacts), not the vertex.
    ma, mb = ea & ~_reflex(vap, va, van), eb & ~_reflex(vbp, vb, vbn)
    s_ab, t_ab, c_ab = _vertex_edge_terms(va, van, vap, vb, vbn)  # (P, Va, Eb)
    s_ba, t_ba, c_ba = _vertex_edge_terms(vb, vbn, vbp, va, van)  # (P, Vb, Ea)

    size = jnp.minimum(model.bound_radius[i], model.bound_radius[j])[:, None, None]
    pen = -PENETRATION_FRACTION * size
    len_b = jnp.linalg.norm(vbn - vb, axis=-1) + 1e-300
    len_a = jnp.linalg.norm(van - va, axis=-1) + 1e-300
    real_a, real_b = model.vertex_mask[i], model.vertex_mask[j]
    touch = jnp.maximum(TOUCH_FRACTION * size, margin)
    front_ab = _held(s_ab, t_ab, len_b, _inside(va, vb, vbn, real_b), real_b, touch)  # (P, Va, Eb)
    front_ba = _held(s_ba, t_ba, len_a, _inside(vb, va, van, real_a), real_a, touch)  # (P, Vb, Ea)
    # Corners closer than the detection distance, or overlapping (then they may be farther
    # apart, each just past the end of the other's edge), form a vertex-vertex contact.
    near = (ma[:, :, None] & mb[:, None, :]
            & (jnp.linalg.norm(va[:, :, None] - vb[:, None, :], axis=-1) <= near_dist[:, None, None] - pen))
    winner = _vertex_vertex_winner(ea, eb, pa, pb, front_ab, front_ba, c_ab, c_ba)

    wedge_tol = (jnp.sin(jnp.minimum(turn, 0.5 * jnp.pi)) + WEDGE_TOL)[:, None, None]

    def interior(s, t, clear, front, near_start, near_end, mask, edge_len):
        # A vertex near an edge's end is left to the vertex-vertex rule unless it lies
        # along the edge from that end (within 45 degrees of it, over the segment): then
        # the two edges overlap, and it is one of an edge-to-edge contact's two vertices
        # (fuzz seed 1643: two spinning blocks' faces met across a detection distance
        # longer than their overlap, and the rule kept one corner; the other went 15 mm in).
        along = t * edge_len[:, None, :]
        off = jnp.abs(s)
        from_start, from_end = (along > off) & (t <= 1), (edge_len[:, None, :] - along > off) & (t >= 0)
        slack = (near_dist[:, None] / edge_len)[:, None, :]
        return (mask & (~near_start | from_start) & (~near_end | from_end) & (t >= -slack) & (t <= 1 + slack)
                & (s >= pen) & front & (clear >= -wedge_tol))

    # A's vertex a on B's edge e = (b_e -> b_{e+1}).
    near_end_ab = _gather_e(near, nb)
    win_end_ab = _gather_e(winner, nb)
    vv_ab = (near & (winner == 1)) | (near_end_ab & (win_end_ab == 0))
    mask_ab = ma[:, :, None] & eb[:, None, :]
    ok_ab = interior(s_ab, t_ab, c_ab, front_ab, near, near_end_ab, mask_ab, len_b) | (vv_ab & mask_ab)
    # B's vertex b on A's edge f = (a_f -> a_{f+1}).
    near_t, win_t = jnp.swapaxes(near, 1, 2), jnp.swapaxes(winner, 1, 2)  # (P, Vb, Va)
    near_end_ba = _gather_e(near_t, na)
    win_end_ba = _gather_e(win_t, na)
    mask_ba = mb[:, :, None] & ea[:, None, :]
    vv_ba = (near_t & (win_t == 3)) | (near_end_ba & (win_end_ba == 2))
    ok_ba = interior(s_ba, t_ba, c_ba, front_ba, near_t, near_end_ba, mask_ba, len_a) | (vv_ba & mask_ba)
    return _polygon_records(model, i, j, na, nb, ok_ab, ok_ba)


def _gather_e(x: jax.Array, idx: jax.Array) -> jax.Array:
    """x (P, V, E): column idx (P, E) of each row, (P, V, E)."""
    return jnp.take_along_axis(x, jnp.broadcast_to(idx[:, None, :], x.shape), axis=2)


def _vertex_vertex_winner(ea, eb, pa, pb, front_ab, front_ba, c_ab, c_ba) -> jax.Array:
    """(P, Va, Vb): of two corners a of A and b of B, which of the four vertex-edge
    candidates is kept (Shi's rule made explicit: the edge line that best separates the two
    wedges, largest clearance ``c``; ties to the first): 0, a on B's edge ending at b; 1,
    a on B's edge starting at b; 2, b on A's edge ending at a; 3, b on A's edge starting at
    a; -1, none. An edge inside a meshed block is no candidate, nor one whose line the
    vertex is behind from outside its polygon (not ``front``: then it is in front of the
    other edge at the corner)."""
    def swap(x):
        return jnp.swapaxes(x, 1, 2)

    cand = jnp.stack([
        jnp.where(_take1(eb, pb)[:, None, :] & _gather_e(front_ab, pb), _gather_e(c_ab, pb), -jnp.inf),
        jnp.where(eb[:, None, :] & front_ab, c_ab, -jnp.inf),
        jnp.where(_take1(ea, pa)[:, :, None] & swap(_gather_e(front_ba, pa)), swap(_gather_e(c_ba, pa)), -jnp.inf),
        jnp.where(ea[:, :, None] & swap(front_ba), swap(c_ba), -jnp.inf),
    ], -1)  # (P, Va, Vb, 4)
    return jnp.where(jnp.max(cand, -1) > -jnp.inf, jnp.argmax(cand, -1), -1)


def _polygon_records(model: Model, i, j, na, nb, ok_ab, ok_ba):
    """The slots (P, 2 V^2) of polygons i (A) and j (B): A's vertices on B's edges, then
    B's on A's, and which hold a contact (``ok_ab`` (P, Va, Eb), ``ok_ba`` (P, Vb, Ea))."""
    v_max = model.max_vertices
    la, lb = model.local_vertices[i], model.local_vertices[j]
    vi = jnp.arange(v_max)
    rec_ab = _record(i[:, None, None], j[:, None, None], 0.0, la[:, :, None, :], B_LINE, 0.0,
                     lb[:, None, :, :], _take(lb, nb)[:, None, :, :], vi[:, None] * v_max + vi[None, :], vi[None, :])
    rec_ba = _record(j[:, None, None], i[:, None, None], 0.0, lb[:, :, None, :], B_LINE, 0.0,
                     la[:, None, :, :], _take(la, na)[:, None, :, :], v_max * v_max + vi[:, None] * v_max + vi[None, :],
                     vi[None, :])
    flat = lambda x: x.reshape((x.shape[0], v_max * v_max) + x.shape[3:])  # noqa: E731
    records = jax.tree.map(lambda x, y: jnp.concatenate([flat(x), flat(y)], 1), rec_ab, rec_ba)
    return records, jnp.concatenate([flat(ok_ab), flat(ok_ba)], 1)
