"""Contact identity across steps: int64 feature-pair keys, looked up by binary search.

A key is ``(i N + j) S + local`` for bodies i, j of a scene of N bodies, with S slots per
pair (``slots_per_pair``) and the narrow-phase kernel's local slot: 0 for two particles;
edge k or V + vertex k of the polygon for a particle and a polygon; ``x V + y`` (vertex
x of i on edge y of j) or ``V^2 + x V + y`` (vertex x of j on edge y of i) for two
polygons, V being the scene's ``max_vertices``.
"""
from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np

from jaxdda.types import POLYGON

# jnp.searchsorted's method in the step: log2 n rounds unrolled, which fuse into a kernel
# or two. The default runs them as a while loop, a few kernels launched per round: on a
# 3-body rockfall the step's six searches were 97 of its ~1 570 launches a step, and 51
# copies of their loop state.
SEARCH = "scan_unrolled"


def slots_per_pair(v_max: int) -> int:
    """Key slots reserved per body pair (the most any narrow-phase kernel uses)."""
    return 2 * v_max * v_max + 2 * v_max + 1


def renumber(key, kind, n_from: int, v_from: int, n_to: int, v_to: int) -> np.ndarray:
    """Keys of a scene of ``n_from`` bodies and ``v_from`` vertices per polygon as the same
    contacts' keys with ``n_to`` bodies and ``v_to`` vertices (a scene padded with bodies
    after its own, or with vertex slots after each polygon's: ``scene.padding``). Host
    side (numpy); ``kind`` (of the bodies the keys name: padding bodies are never in a
    key) tells each pair's kernel; keys < 0 (none, or a padding joint's) are kept."""
    key = np.asarray(key, np.int64)
    kind = np.asarray(kind)
    k = np.maximum(key, 0)
    pair, local = np.divmod(k, slots_per_pair(v_from))
    i, j = np.divmod(pair, n_from)
    polygons = (kind[i] == POLYGON).astype(int) + (kind[j] == POLYGON).astype(int)
    block, rest = np.divmod(local, np.where(polygons == 2, v_from * v_from, v_from))
    x, y = np.divmod(rest, v_from)
    local_to = np.where(polygons == 2, block * v_to * v_to + x * v_to + y, np.where(polygons == 1, block * v_to + rest, 0))
    return np.where(key >= 0, (i * n_to + j) * slots_per_pair(v_to) + local_to, key)


def lookup(keys: jax.Array, queries: jax.Array) -> tuple[jax.Array, jax.Array]:
    """For each query key, the index of an equal entry of ``keys`` and whether one exists.

    Negative queries never match. Sort plus binary search: O((K + Q) log K).
    """
    order = jnp.argsort(keys)
    sorted_keys = keys[order]
    pos = jnp.clip(jnp.searchsorted(sorted_keys, queries, method=SEARCH), 0, keys.shape[0] - 1)
    found = (sorted_keys[pos] == queries) & (queries >= 0)
    return order[pos], found
