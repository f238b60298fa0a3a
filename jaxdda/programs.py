"""Room for compiled programs in one process.

XLA on CPU (jaxlib 0.10.2) maps three memory regions per compiled kernel (code, constants,
data): about 5 300 for one step program, more for a gradient's. Linux lets a process hold
``vm.max_map_count`` maps (65 530 by default), and the compilation that passes it dies
with a segmentation fault, taking the run with it (a test process holding seven gradient
programs crashed at 65 531). The drivers call ``make_room`` before each chunk: past half
the limit it drops every compiled program (they compile again when next used) and says so.
"""
from __future__ import annotations

import warnings

import jax

_caches = []  # the drivers' own program caches (functools.lru_cache), cleared with jax's


def holds_programs(cached):
    """Register a driver's ``functools.lru_cache``-wrapped program factory; returns it."""
    _caches.append(cached)
    return cached


def memory_maps() -> tuple[int, int]:
    """(memory maps this process holds, the limit vm.max_map_count); (0, 0) where the
    system does not tell (no /proc)."""
    try:
        with open("/proc/self/maps") as maps, open("/proc/sys/vm/max_map_count") as limit:
            return sum(1 for _ in maps), int(limit.read())
    except (OSError, ValueError):
        return 0, 0


def make_room(fraction: float = 0.5) -> bool:
    """Drop all compiled programs if the process holds more than ``fraction`` of its
    memory-map limit; returns whether it did."""
    count, limit = memory_maps()
    if not limit or count <= fraction * limit:
        return False
    warnings.warn(f"the process holds {count} of its {limit} memory maps (vm.max_map_count), mostly compiled XLA "
                  "programs; dropping them all so the next compilation cannot exhaust the limit (they compile "
                  "again when next used). Raise vm.max_map_count to keep more programs.", RuntimeWarning,
                  stacklevel=2)
    jax.clear_caches()
    for cached in _caches:
        cached.cache_clear()
    return True
