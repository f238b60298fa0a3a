"""Broad phase: sort-and-sweep over axis-aligned boxes, into a fixed-capacity pair buffer.

Bodies are sorted along the axis of larger spread; each body's candidates are the
bodies that start inside its extent on that axis, so the number of candidates grows
linearly with the number of bodies for any scene that is not a single column along the
sweep axis. The buffer reports how many slots it needed; nothing is dropped silently.
"""
from __future__ import annotations

import jax
import jax.numpy as jnp


def sweep_and_prune(lo: jax.Array, hi: jax.Array, capacity: int):
    """All pairs i < j whose boxes [lo, hi] (N, 2) overlap.

    Returns ``(pairs (capacity, 2) int32, valid (capacity,) bool, needed () int32)``;
    ``needed`` counts the sweep candidates, so ``needed > capacity`` means overflow.
    """
    n = lo.shape[0]
    centre = 0.5 * (lo + hi)
    spread = jnp.max(centre, 0) - jnp.min(centre, 0)
    axis = jnp.where(spread[1] > spread[0], 1, 0)
    lo_s, hi_s = lo[:, axis], hi[:, axis]

    order = jnp.argsort(lo_s)
    lo_sorted, hi_sorted = lo_s[order], hi_s[order]
    ends = jnp.searchsorted(lo_sorted, hi_sorted, side="right")  # first body starting beyond
    count = jnp.maximum(ends - jnp.arange(n) - 1, 0)
    cum = jnp.cumsum(count)
    needed = cum[-1].astype(jnp.int32) if n else jnp.int32(0)

    slot = jnp.arange(capacity)
    k = jnp.minimum(jnp.searchsorted(cum, slot, side="right"), n - 1)
    partner = jnp.minimum(k + 1 + slot - (cum[k] - count[k]), n - 1)
    i, j = order[k], order[partner]
    overlap = jnp.all((lo[i] <= hi[j]) & (lo[j] <= hi[i]), -1)
    valid = (slot < needed) & overlap & (i != j)
    pairs = jnp.stack([jnp.minimum(i, j), jnp.maximum(i, j)], -1).astype(jnp.int32)
    return pairs, valid, needed


def compact(mask: jax.Array, capacity: int):
    """Indices of the True entries of ``mask`` packed into ``capacity`` slots.

    Returns ``(index (capacity,) int32, valid (capacity,) bool, needed () int32)``.
    """
    pos = jnp.cumsum(mask) - 1
    target = jnp.where(mask, pos, capacity)  # out of range: dropped by the scatter, counted
    index = jnp.zeros((capacity,), jnp.int32).at[target].set(
        jnp.arange(mask.shape[0], dtype=jnp.int32), mode="drop")
    needed = jnp.sum(mask).astype(jnp.int32)
    return index, jnp.arange(capacity) < needed, needed
