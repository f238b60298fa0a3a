"""Broad phase: a sorted cell grid into a fixed-capacity pair buffer.

Bodies no larger than twice the median size are binned into square cells of side h
(the largest such body); two of them can touch only if their cells are neighbours, so
each looks up the 3 x 3 cells around its own by binary search in the sorted cell ids.
Larger bodies (walls, bases) are paired with every body. The candidate count is thus
about 9 x (bodies per cell) x N + (large bodies) x N: linear in N for a scene of fixed
density. The buffer reports how many slots it needed; nothing is dropped silently.
Void bodies (the padding of a scene brought to a larger shape, which come last) take no
part: they are not binned, count in no median, and no large body is paired with them.
"""
from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np

from jaxdda.contact.keys import SEARCH

_OFFSET = 2 ** 30  # cell coordinates are shifted to be non-negative before packing
_NEIGHBOURS = np.array([(dx, dy) for dx in (-1, 0, 1) for dy in (-1, 0, 1)])


def _cells(lo, hi, void, xp):
    """Cell side h, cell coordinates (N, 2) and the 'large body' flag, for numpy or jax."""
    extent = xp.max(hi - lo, axis=1)
    large = ~void & (extent > 2.0 * xp.nanmedian(xp.where(void, xp.nan, extent)))
    h = xp.max(xp.where(large | void, 0.0, extent))
    h = xp.where(h > 0, h, 1.0)
    centre = 0.5 * (lo + hi)
    return xp.floor(centre / h).astype(xp.int64), large


def _pack(ij, xp):
    return (ij[..., 0] + _OFFSET) * (2 * _OFFSET) + (ij[..., 1] + _OFFSET)


def grid_pairs(lo: jax.Array, hi: jax.Array, capacity: int, void: jax.Array | None = None):
    """All pairs i < j whose boxes [lo, hi] (N, 2) overlap, of bodies not ``void`` (N,)
    bool (the void ones must be the last).

    Returns ``(pairs (capacity, 2) int32, valid (capacity,) bool, needed () int32)``;
    ``needed`` counts the candidates examined, so ``needed > capacity`` means overflow.
    """
    n = lo.shape[0]
    void = jnp.zeros(n, bool) if void is None else void
    n_live = n - jnp.sum(void)
    ij, large = _cells(lo, hi, void, jnp)
    sentinel = jnp.iinfo(jnp.int64).max
    cell = jnp.where(large | void, sentinel, _pack(ij, jnp))
    order = jnp.argsort(cell)
    sorted_cell = cell[order]

    # Small bodies: ranges of the sorted list in the 9 cells around each one.
    target = _pack(ij[:, None, :] + _NEIGHBOURS[None], jnp)  # (N, 9)
    start = jnp.searchsorted(sorted_cell, target, side="left", method=SEARCH)
    stop = jnp.searchsorted(sorted_cell, target, side="right", method=SEARCH)
    count_small = jnp.where((large | void)[:, None], 0, stop - start).reshape(-1)
    # Large bodies: every other body (but the void ones, which come last).
    count_large = jnp.where(large, n_live, 0)
    counts = jnp.concatenate([count_small, count_large])
    cum = jnp.cumsum(counts)
    needed = cum[-1].astype(jnp.int32)

    slot = jnp.arange(capacity)
    row = jnp.minimum(jnp.searchsorted(cum, slot, side="right", method=SEARCH), counts.shape[0] - 1)
    within = slot - (cum[row] - counts[row])
    is_small = row < 9 * n
    small_row = jnp.minimum(row, 9 * n - 1)
    i_small = small_row // 9
    j_small = order[jnp.clip(start.reshape(-1)[small_row] + within, 0, n - 1)]
    i_large = jnp.clip(row - 9 * n, 0, n - 1)
    j_large = jnp.clip(within, 0, n - 1)
    i = jnp.where(is_small, i_small, i_large)
    j = jnp.where(is_small, j_small, j_large)

    # Each pair once: small-small with i < j; a large body takes every small one and
    # the large ones of higher index.
    once = jnp.where(is_small, i < j, ~large[j] | (i < j))
    overlap = jnp.all((lo[i] <= hi[j]) & (lo[j] <= hi[i]), -1)
    valid = (slot < needed) & once & overlap & (i != j)
    pairs = jnp.stack([jnp.minimum(i, j), jnp.maximum(i, j)], -1).astype(jnp.int32)
    return pairs, valid, needed


def candidate_count(lo: np.ndarray, hi: np.ndarray) -> tuple[int, np.ndarray, np.ndarray]:
    """Host (numpy) twin of ``grid_pairs``: the count it needs and the overlapping pairs."""
    n = len(lo)
    ij, large = _cells(lo, hi, np.zeros(n, bool), np)
    cell = np.where(large, np.iinfo(np.int64).max, _pack(ij, np))
    order = np.argsort(cell, kind="stable")
    sorted_cell = cell[order]
    target = _pack(ij[:, None, :] + _NEIGHBOURS[None], np)
    start = np.searchsorted(sorted_cell, target, side="left")
    stop = np.where(large[:, None], start, np.searchsorted(sorted_cell, target, side="right"))
    count = stop - start
    needed = int(count.sum() + large.sum() * n)
    i = np.repeat(np.repeat(np.arange(n), 9), count.reshape(-1))
    j = order[np.concatenate([np.arange(a, b) for a, b in zip(start.reshape(-1), stop.reshape(-1))] or [[]]).astype(int)]
    big = np.flatnonzero(large)
    i = np.concatenate([i, np.repeat(big, n)])
    j = np.concatenate([j, np.tile(np.arange(n), len(big))])
    keep = (i != j) & np.where(large[i], ~large[j] | (i < j), (i < j) & ~large[j])
    i, j = i[keep], j[keep]
    overlap = np.all((lo[i] <= hi[j]) & (lo[j] <= hi[i]), axis=1)
    return needed, i[overlap], j[overlap]


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
