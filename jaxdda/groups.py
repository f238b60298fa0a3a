"""Dof groups: bodies tied by connectors share one K_eff, inverted once per step (the
particle/block-based composite matrix, eqs. 106-112); independent bodies keep their own
6x6 inverse. ``Flexibility`` applies the result to per-body dof vectors, so contacts,
loads and integration stay per body: W = J K_eff^-1 J^T is never formed (eq. 112).
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
    grouped ones) and ``group`` (G, 6S, 6S) for groups of up to S bodies listed in
    ``members`` (G, S) (-1: an empty slot); ``body_group``, ``body_slot`` (N,) locate each
    body in its group (-1: independent)."""

    single: jax.Array
    group: jax.Array
    members: jax.Array
    body_group: jax.Array
    body_slot: jax.Array

    @property
    def n_groups(self) -> int:
        return self.members.shape[0]


def independent(inv: jax.Array) -> Flexibility:
    """A per-body inverse (N, 6, 6) with no groups."""
    n = inv.shape[0]
    none = -jnp.ones((n,), jnp.int32)
    return Flexibility(inv, jnp.zeros((0, 0, 0), inv.dtype), jnp.zeros((0, 0), jnp.int32), none, none)


def _block_diag(blocks: jax.Array) -> jax.Array:
    """(G, S, 6, 6) -> (G, 6S, 6S)."""
    g, s = blocks.shape[:2]
    full = jnp.einsum("gsij,st->gsitj", blocks, jnp.eye(s, dtype=blocks.dtype))
    return full.reshape(g, s * NDOF, s * NDOF)


def grouped(matrix: jax.Array, projector: jax.Array, model, coupling=None) -> Flexibility:
    """The inverse of ``matrix`` (N, 6, 6 per body) on each body's active dofs (``projector``),
    with the bodies of each group of ``model`` inverted together and coupled by
    ``coupling``: (connector index pairs (K, 2), their stiffness (K, 12, 12)) or None."""
    members = model.group_members
    single = inverse_on_subspace(matrix, projector)
    if members.shape[0] == 0:
        return independent(single)
    single = jnp.where((model.body_group >= 0)[:, None, None], 0.0, single)
    slot_ok = (members >= 0)[..., None, None]
    idx = jnp.maximum(members, 0)
    big = _block_diag(jnp.where(slot_ok, matrix[idx], 0.0))
    proj = _block_diag(jnp.where(slot_ok, projector[idx], 0.0))
    if coupling is not None:
        bodies, stiff = coupling
        g = model.body_group[bodies[:, 0]]
        g = jnp.where(g >= 0, g, members.shape[0])  # an inert padding connector: dropped
        s, d = members.shape[1], NDOF
        big5 = big.reshape(-1, s, d, s, d)
        k = stiff.reshape(-1, 2, d, 2, d)
        for i in range(2):
            for j in range(2):
                big5 = big5.at[g, model.body_slot[bodies[:, i]], :, model.body_slot[bodies[:, j]], :].add(k[:, i, :, j, :], mode="drop")
        big = big5.reshape(big.shape)
    eye = jnp.eye(big.shape[-1], dtype=big.dtype)
    inv = proj @ spd_inverse(proj @ big @ proj + eye - proj) @ proj
    return Flexibility(single, inv, members, model.body_group, model.body_slot)


def apply(flex: Flexibility, x: jax.Array) -> jax.Array:
    """(N, 6) -> (N, 6): the inverse applied to per-body generalised forces."""
    y = jnp.einsum("nij,nj->ni", flex.single, x)
    if flex.n_groups == 0:
        return y
    members = flex.members
    g, s = members.shape
    xg = jnp.where((members >= 0)[..., None], x[jnp.maximum(members, 0)], 0.0).reshape(g, s * NDOF)
    yg = jnp.einsum("gij,gj->gi", flex.group, xg).reshape(g * s, NDOF)
    target = jnp.where(members >= 0, members, x.shape[0]).reshape(-1)
    return y.at[target].add(yg, mode="drop")


def diagonal(flex: Flexibility, a: jax.Array) -> jax.Array:
    """(C, 6, 6): the diagonal block of the inverse for bodies ``a``."""
    out = flex.single[a]
    if flex.n_groups == 0:
        return out
    return out + _group_block(flex, a, a, flex.body_group[a] >= 0)


def coupling(flex: Flexibility, a: jax.Array, b: jax.Array) -> jax.Array | None:
    """(C, 6, 6): the block coupling body a's dofs to body b's (a != b), nonzero only
    within a group; None when there are no groups."""
    if flex.n_groups == 0:
        return None
    ga = flex.body_group[a]
    return _group_block(flex, a, b, (ga >= 0) & (ga == flex.body_group[b]))


def _group_block(flex: Flexibility, a, b, where):
    g, s = flex.members.shape
    inv5 = flex.group.reshape(g, s, NDOF, s, NDOF)
    ga = jnp.maximum(flex.body_group[a], 0)
    block = inv5[ga, jnp.maximum(flex.body_slot[a], 0), :, jnp.maximum(flex.body_slot[b], 0), :]
    return jnp.where(where[:, None, None], block, 0.0)
