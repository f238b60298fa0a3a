"""Dof groups: bodies that share dofs or stiffness are solved together (the composite
matrices of paper Section 6); independent bodies keep their own 6x6 inverse.

A group has R reduced dofs q. Each member body's 6 generalised dofs are ``map @ q_slot``
where ``q_slot`` are the (up to 6) reduced dofs listed in its slot of ``group_dofs``:

* a body tied by connectors (eqs. 106-112) owns 6 reduced dofs, its map an orthonormal
  basis of its active subspace (``Model.dof_basis``);
* a 3-node triangle of a meshed block (eqs. 93-105) maps its three nodes' displacements
  to its affine dofs (``mesh_maps``): elements sharing a node share its dofs, so the
  group's K_eff is the assembled finite element matrix sum A^T K_e A.
* a body with fixed points (``pins.py``) maps the null space of its pins' constraints,
  rebuilt each step from its lever, so its pins never move.

``Flexibility`` applies K_eff^-1 to per-body dof vectors, so contacts, loads and
integration stay per body and W = J K_eff^-1 J^T is never formed (eqs. 105, 112).
"""
from __future__ import annotations

import jax
import jax.numpy as jnp

from jaxdda._pytree import pytree_dataclass
from jaxdda.bodies.mass import inverse_on_subspace, spd_inverse
from jaxdda.types import NDOF


@pytree_dataclass
class Flexibility:
    """An inverse on per-body dofs: ``single`` (N, 6, 6) for independent bodies (zero for
    grouped ones) and, per group, ``group`` (G, R + 1, R + 1) on its reduced dofs (the
    last row and column are zero: the index R stands for "no dof"). ``members`` (G, S)
    lists each group's bodies (-1: empty slot), ``dofs`` (G, S, 6) and ``maps``
    (G, S, 6, 6) tie each member's dofs to the reduced ones; ``body_group``,
    ``body_slot`` (N,) locate a body in its group (-1: independent)."""

    single: jax.Array
    group: jax.Array
    members: jax.Array
    dofs: jax.Array
    maps: jax.Array
    body_group: jax.Array
    body_slot: jax.Array

    @property
    def n_groups(self) -> int:
        return self.members.shape[0]


def independent(inv: jax.Array) -> Flexibility:
    """A per-body inverse (N, 6, 6) with no groups."""
    n = inv.shape[0]
    none = -jnp.ones((n,), jnp.int32)
    return Flexibility(inv, jnp.zeros((0, 1, 1), inv.dtype), jnp.zeros((0, 0), jnp.int32),
                       jnp.zeros((0, 0, NDOF), jnp.int32), jnp.zeros((0, 0, NDOF, NDOF), inv.dtype), none, none)


def scaled(flex: Flexibility, factor: jax.Array) -> Flexibility:
    """The same inverse times ``factor``."""
    return Flexibility(flex.single * factor, flex.group * factor, flex.members, flex.dofs, flex.maps,
                       flex.body_group, flex.body_slot)


def mesh_maps(vertices: jax.Array) -> jax.Array:
    """(N, 6, 6) A with d = A q: the affine dofs [u0, v0, theta, eps_x, eps_y, gamma_xy] of
    a triangle's linear (CST) field from its nodal displacements q = [u1, v1, u2, v2, u3,
    v3], for triangles with world ``vertices`` (N, >= 3, 2) counter-clockwise (eqs. 93-94:
    the area coordinates' gradients give the strains; the centroid moves by their mean)."""
    x = vertices[:, :3]
    nxt, prv = jnp.roll(x, -1, axis=1), jnp.roll(x, 1, axis=1)
    edge = prv - nxt  # opposite edge of each node (from the next node to the previous one)
    d1, d2 = x[:, 1] - x[:, 0], x[:, 2] - x[:, 0]
    area2 = d1[:, 0] * d2[:, 1] - d1[:, 1] * d2[:, 0]
    gx, gy = -edge[..., 1] / area2[:, None], edge[..., 0] / area2[:, None]  # grad of area coordinates (N, 3)
    z, third = jnp.zeros_like(gx), jnp.full_like(gx, 1.0 / 3.0)
    rows = [  # per node (u, v) columns, stacked over the 3 nodes
        (third, z), (z, third), (-0.5 * gy, 0.5 * gx), (gx, z), (z, gy), (gy, gx)]
    return jnp.stack([jnp.stack([u, v], -1).reshape(x.shape[0], 6) for u, v in rows], 1)


def grouped(matrix: jax.Array, projector: jax.Array, model, maps: jax.Array | None = None,
            coupling=None) -> Flexibility:
    """The inverse of ``matrix`` (N, 6, 6 per body) on each body's active dofs
    (``projector``), with the bodies of each group of ``model`` inverted together on
    their reduced dofs (``maps`` (N, 6, 6) per body, default ``model.dof_basis``) and
    coupled by ``coupling``: (connector index pairs (K, 2), their stiffness (K, 12, 12))
    or None."""
    members = model.group_members
    single = inverse_on_subspace(matrix, projector)
    if members.shape[0] == 0:
        return independent(single)
    single = jnp.where((model.body_group >= 0)[:, None, None], 0.0, single)
    maps = model.dof_basis if maps is None else maps
    g, s = members.shape
    r = model.group_free.shape[1]
    ok = members >= 0
    idx = jnp.maximum(members, 0)
    slot_maps = jnp.where(ok[..., None, None], maps[idx], 0.0)
    dofs = jnp.where(model.group_dofs >= 0, model.group_dofs, r)
    gi = jnp.arange(g)[:, None, None, None]
    blocks = jnp.einsum("gsia,gsij,gsjb->gsab", slot_maps, matrix[idx], slot_maps)
    k = jnp.zeros((g, r + 1, r + 1), matrix.dtype).at[gi, dofs[..., :, None], dofs[..., None, :]].add(blocks)
    if coupling is not None:
        bodies, stiff = coupling
        cg = model.body_group[bodies[:, 0]]
        cg = jnp.where(cg >= 0, cg, g)  # an inert padding connector: dropped
        slot = jnp.maximum(model.body_slot[bodies], 0)
        end_dofs = dofs[jnp.minimum(cg, g - 1)[:, None], slot]  # (K, 2, 6)
        end_maps = maps[bodies]  # (K, 2, 6, 6)
        kk = stiff.reshape(-1, 2, NDOF, 2, NDOF)
        for i in range(2):
            for j in range(2):
                blk = jnp.einsum("kia,kij,kjb->kab", end_maps[:, i], kk[:, i, :, j, :], end_maps[:, j])
                k = k.at[cg[:, None, None], end_dofs[:, i, :, None], end_dofs[:, j, None, :]].add(blk, mode="drop")
    free = model.group_free
    inv = spd_inverse(k[:, :r, :r] + jax.vmap(jnp.diag)((~free).astype(matrix.dtype)))
    inv = inv * (free[:, :, None] & free[:, None, :])
    inv = jnp.zeros_like(k).at[:, :r, :r].set(inv)
    return Flexibility(single, inv, members, dofs, slot_maps, model.body_group, model.body_slot)


def _slots(flex: Flexibility, x: jax.Array) -> jax.Array:
    """(N, 6) per body -> (G, S, 6) per group slot (zero in empty slots)."""
    return jnp.where((flex.members >= 0)[..., None], x[jnp.maximum(flex.members, 0)], 0.0)


def apply(flex: Flexibility, x: jax.Array) -> jax.Array:
    """(N, 6) -> (N, 6): the inverse applied to per-body generalised forces."""
    y = jnp.sum(flex.single * x[:, None, :], -1)
    if flex.n_groups == 0:
        return y
    g, s = flex.members.shape
    gi = jnp.arange(g)[:, None, None]
    reduced = jnp.zeros(flex.group.shape[:2], x.dtype).at[gi, flex.dofs].add(
        jnp.einsum("gsij,gsi->gsj", flex.maps, _slots(flex, x)))
    z = jnp.einsum("gij,gj->gi", flex.group, reduced)
    yg = jnp.einsum("gsij,gsj->gsi", flex.maps, z[gi, flex.dofs]).reshape(g * s, NDOF)
    target = jnp.where(flex.members >= 0, flex.members, x.shape[0]).reshape(-1)
    return y.at[target].add(yg, mode="drop")


def contact_diagonal(flex: Flexibility, jac: jax.Array, a: jax.Array, b: jax.Array) -> jax.Array:
    """(C, 3): the diagonal of J D J^T for contact rows ``jac`` (C, 2, 3, 6) on bodies a, b,
    D the inverse: each side's own block, and twice the coupling of the two sides where
    they share a dof group (eq. 112). A group's block maps_x G maps_y^T is not formed:
    each side's rows are mapped to its group's dofs once, L = J maps, and the diagonal is
    that of L_x G L_y^T (a fifth of the products)."""
    def own(rows, blocks):
        return jnp.einsum("cij,cjk,cik->ci", rows, blocks, rows)

    diag = own(jac[:, 0], flex.single[a]) + own(jac[:, 1], flex.single[b])
    if flex.n_groups == 0:
        return diag

    def mapped(rows, body):  # the side's group, its dofs there (C, 6) and L (C, 3, 6)
        g, slot = jnp.maximum(flex.body_group[body], 0), jnp.maximum(flex.body_slot[body], 0)
        return g, flex.dofs[g, slot], jnp.einsum("cri,cia->cra", rows, flex.maps[g, slot])

    def quadratic(g, dofs_x, l_x, dofs_y, l_y):  # diag(L_x G[dofs_x, dofs_y] L_y^T)
        inner = flex.group[g[:, None, None], dofs_x[:, :, None], dofs_y[:, None, :]]
        return jnp.einsum("cra,cab,crb->cr", l_x, inner, l_y)

    (g_a, dofs_a, l_a), (g_b, dofs_b, l_b) = mapped(jac[:, 0], a), mapped(jac[:, 1], b)
    in_a, in_b = flex.body_group[a] >= 0, flex.body_group[b] >= 0
    shared = in_a & (flex.body_group[a] == flex.body_group[b])
    return (diag + jnp.where(in_a[:, None], quadratic(g_a, dofs_a, l_a, dofs_a, l_a), 0.0)
            + jnp.where(in_b[:, None], quadratic(g_b, dofs_b, l_b, dofs_b, l_b), 0.0)
            + 2.0 * jnp.where(shared[:, None], quadratic(g_a, dofs_a, l_a, dofs_b, l_b), 0.0))
