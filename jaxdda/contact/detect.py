"""Contact detection for one step: broad phase, narrow phase by pair kind, compaction."""
from __future__ import annotations

import dataclasses

import jax
import jax.numpy as jnp

from jaxdda.bodies.shape import to_world
from jaxdda.contact.broadphase import compact, grid_pairs
from jaxdda.contact.keys import slots_per_pair
from jaxdda.contact.kinematics import gap_frame
from jaxdda.contact.narrowphase import particle_particle, particle_polygon, polygon_polygon
from jaxdda.types import POLYGON, VOID, Model


def world_vertices(model: Model, centroid: jax.Array, rotation: jax.Array) -> jax.Array:
    """(N, V, 2) polygon vertices in world coordinates (padding entries are meaningless)."""
    return to_world(centroid[:, None, :], rotation[:, None], model.local_vertices)


def bounding_boxes(model: Model, centroid: jax.Array, verts: jax.Array, reach: jax.Array):
    """Axis-aligned boxes (lo, hi) of every body, grown by its detection reach."""
    is_poly = (model.kind == POLYGON)[:, None]
    big = jnp.finfo(verts.dtype).max
    m = model.vertex_mask[..., None]
    v_lo = jnp.min(jnp.where(m, verts, big), 1)
    v_hi = jnp.max(jnp.where(m, verts, -big), 1)
    r = model.radius[:, None]
    lo = jnp.where(is_poly, v_lo, centroid - r) - reach[:, None]
    hi = jnp.where(is_poly, v_hi, centroid + r) + reach[:, None]
    return lo, hi


def detect(model: Model, centroid: jax.Array, rotation: jax.Array, reach: jax.Array, turn: jax.Array,
           margin: jax.Array):
    """Contacts whose gap is below the pair's detection distance ``reach[a] + reach[b]``.

    ``turn`` (N,) is the angle each body may turn in the step (widens corner tests);
    ``margin`` () the gap d0 within which a contact is closed (a vertex this little behind
    an edge's line touches it, wherever it is).

    Returns ``(contacts (C,), needed (5,) int32)``: the slots each buffer needed (candidates,
    pp, pb, bb pairs, contacts); any ``needed > capacity`` means the result is incomplete.
    """
    cap = model.capacity
    n, v_max = model.n_bodies, model.max_vertices
    verts = world_vertices(model, centroid, rotation)
    lo, hi = bounding_boxes(model, centroid, verts, reach)
    pairs, ok, need_candidates = grid_pairs(lo, hi, cap.candidates, model.kind == VOID)
    i, j = pairs[:, 0], pairs[:, 1]
    ok = ok & ~(model.fixed[i] & model.fixed[j]) & ~((model.mesh[i] >= 0) & (model.mesh[i] == model.mesh[j]))
    poly_i, poly_j = model.kind[i] == POLYGON, model.kind[j] == POLYGON

    def select(mask, capacity):
        idx, valid, needed = compact(mask, capacity)
        return i[idx], j[idx], valid, needed

    pp_i, pp_j, pp_ok, need_pp = select(ok & ~poly_i & ~poly_j, cap.pairs_pp)
    pb_i, pb_j, pb_ok, need_pb = select(ok & (poly_i != poly_j), cap.pairs_pb)
    bb_i, bb_j, bb_ok, need_bb = select(ok & poly_i & poly_j, cap.pairs_bb)
    pb_poly_first = model.kind[pb_i] == POLYGON
    particle = jnp.where(pb_poly_first, pb_j, pb_i)
    polygon = jnp.where(pb_poly_first, pb_i, pb_j)

    slots = slots_per_pair(v_max)
    groups = []
    rec, geo = particle_particle(model, centroid, pp_i, pp_j)
    groups.append((rec, geo & pp_ok[:, None], pp_i, pp_j))
    rec, geo = particle_polygon(model, centroid, verts, particle, polygon)
    groups.append((rec, geo & pb_ok[:, None], pb_i, pb_j))
    rec, geo = polygon_polygon(model, verts, bb_i, bb_j, reach[bb_i] + reach[bb_j], turn[bb_i] + turn[bb_j],
                               margin)
    groups.append((rec, geo & bb_ok[:, None], bb_i, bb_j))

    def flatten(rec, geo, pi, pj):
        pair_key = (pi.astype(jnp.int64) * n + pj)[:, None] * slots
        rec = dataclasses.replace(rec, key=rec.key + pair_key)
        return jax.tree.map(lambda x: x.reshape((-1,) + x.shape[2:]), rec), geo.reshape(-1)

    flat = [flatten(*g) for g in groups]
    slots = jax.tree.map(lambda *xs: jnp.concatenate(xs, 0), *[f[0] for f in flat])
    geo_ok = jnp.concatenate([f[1] for f in flat], 0)
    gap, _, _ = gap_frame(slots, centroid, rotation)
    hit = geo_ok & (gap <= reach[slots.a] + reach[slots.b])

    idx, valid, need_c = compact(hit, cap.contacts)
    contacts = jax.tree.map(lambda x: x[idx], slots)
    contacts = dataclasses.replace(contacts, valid=valid, key=jnp.where(valid, contacts.key, -1))
    needed = jnp.stack([need_candidates, need_pp, need_pb, need_bb, need_c]).astype(jnp.int32)
    return contacts, needed


def contact_materials(model: Model, c) -> tuple[jax.Array, jax.Array]:
    """The material pair (C,), (C,) whose contact law a contact uses: a joint material
    on b's edge (``Model.edge_material``, e.g. the joint set that cut two blocks apart)
    governs both sides; otherwise the two bodies' materials."""
    joint = jnp.where(c.edge >= 0, model.edge_material[c.b, jnp.maximum(c.edge, 0)], -1)
    return jnp.where(joint >= 0, joint, model.material[c.a]), jnp.where(joint >= 0, joint, model.material[c.b])

