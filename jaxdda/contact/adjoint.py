"""Adjoint vertex-edge contacts: the two contacts of one edge-edge interface (paper Fig. 11).

An edge-edge contact between polygons A and B appears as two vertex-edge contacts at the
ends of the overlap: either two vertices of one body on the same edge of the other, or one
vertex of each on the other's edge. They share one cohesion and one tensile strength
(eqs. 42-45, 70-73). The partner is found from the contact keys (which encode the body
pair, the vertex and the edge, see ``narrowphase.polygon_polygon``) by binary search
among this step's contacts, so the lookup is O(C log C) array code.
"""
from __future__ import annotations

import jax
import jax.numpy as jnp

from jaxdda.contact.keys import lookup, slots_per_pair
from jaxdda.types import B_LINE, POLYGON, Contacts, Model

# Two vertex-edge contacts form one edge-edge interface when their edges are parallel
# within this angle (rad).
ADJOINT_ANGLE = 0.01


def adjoint_partner(model: Model, c: Contacts, normal: jax.Array) -> jax.Array:
    """(C,) int32 index of each contact's adjoint contact, or -1. The relation is symmetric."""
    n, v = model.n_bodies, model.max_vertices
    slots = slots_per_pair(v)
    key = jnp.maximum(c.key, 0)
    local = key % slots
    base = key - local
    pi = (key // slots) // n
    pj = (key // slots) % n
    reverse = local >= v * v  # B's vertex on A's edge (A = pi, B = pj)
    vtx = (local % (v * v)) // v
    edge = local % v
    owner_v = jnp.where(reverse, pj, pi)
    owner_e = jnp.where(reverse, pi, pj)
    nv, ne = model.n_vertices[owner_v], model.n_vertices[owner_e]
    same, other = jnp.where(reverse, v * v, 0), jnp.where(reverse, 0, v * v)
    cands = jnp.stack([
        same + ((vtx + 1) % nv) * v + edge,  # the next vertex on the same edge
        same + ((vtx - 1) % nv) * v + edge,  # the previous vertex on the same edge
        other + edge * v + (vtx - 1) % nv,  # the edge's start vertex on the edge ending at vtx
        other + edge * v + vtx,  # ... on the edge starting at vtx
        other + ((edge + 1) % ne) * v + (vtx - 1) % nv,  # the edge's end vertex
        other + ((edge + 1) % ne) * v + vtx,
    ], -1) + base[:, None]  # (C, 6)
    polys = (model.kind[c.a] == POLYGON) & (model.kind[c.b] == POLYGON) & (c.btype == B_LINE) & c.valid
    idx, found = lookup(jnp.where(c.valid, c.key, -1), cands.reshape(-1))
    idx, found = idx.reshape(cands.shape), found.reshape(cands.shape)
    parallel = jnp.abs(jnp.einsum("ck,cjk->cj", normal, normal[idx])) >= jnp.cos(ADJOINT_ANGLE)
    ok = found & parallel & polys[:, None] & polys[idx]
    first = jnp.argmax(ok, -1)
    partner = jnp.where(jnp.any(ok, -1), jnp.take_along_axis(idx, first[:, None], 1)[:, 0], -1)
    # Keep mutual choices only (three collinear contacts on one edge pair up two of them).
    back = partner[jnp.maximum(partner, 0)]
    return jnp.where((partner >= 0) & (back == jnp.arange(c.key.shape[0])), partner, -1).astype(jnp.int32)
