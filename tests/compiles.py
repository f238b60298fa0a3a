"""Counting XLA compilations from JAX's monitoring events (not from wall-clock time)."""
import contextlib
import dataclasses

from jax import monitoring

BACKEND_COMPILE = "/jax/core/compile/backend_compile_duration"  # a compilation or a cache load
REQUEST = "/jax/compilation_cache/compile_requests_use_cache"
HIT = "/jax/compilation_cache/cache_hits"


@dataclasses.dataclass
class Counts:
    compiles: int = 0  # programs that reached the backend (compiled or loaded from disk)
    requests: int = 0  # of them, looked up in the persistent cache
    hits: int = 0  # of them, found there
    seconds: float = 0.0  # spent in the backend (compiling or loading)

    @property
    def misses(self) -> int:
        return self.requests - self.hits


_active: list[Counts] = []


def _on_event(name, **_):
    for c in _active:
        c.requests += name == REQUEST
        c.hits += name == HIT


def _on_duration(name, seconds, **_):
    if name == BACKEND_COMPILE:
        for c in _active:
            c.compiles += 1
            c.seconds += seconds


monitoring.register_event_listener(_on_event)
monitoring.register_event_duration_secs_listener(_on_duration)


@contextlib.contextmanager
def counting():
    """``with counting() as c: ...``: the compilations inside the block, in ``c``."""
    c = Counts()
    _active.append(c)
    try:
        yield c
    finally:
        _active.remove(c)
