"""Contact identity across steps: lookups of int64 feature-pair keys by binary search."""
from __future__ import annotations

import jax
import jax.numpy as jnp


def lookup(keys: jax.Array, queries: jax.Array) -> tuple[jax.Array, jax.Array]:
    """For each query key, the index of an equal entry of ``keys`` and whether one exists.

    Negative queries never match. Sort plus binary search: O((K + Q) log K).
    """
    order = jnp.argsort(keys)
    sorted_keys = keys[order]
    pos = jnp.clip(jnp.searchsorted(sorted_keys, queries), 0, keys.shape[0] - 1)
    found = (sorted_keys[pos] == queries) & (queries >= 0)
    return order[pos], found
