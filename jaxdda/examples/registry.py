"""Name -> scene factory table of the built-in examples."""
from __future__ import annotations

from jaxdda.examples import paper, practical
from jaxdda.scene.builder import Scene

_EXAMPLES = {
    "paper-7.1": (paper.disk_heap, 100, "three disks stacked on a fixed base (static contact forces)"),
    "paper-7.2": (paper.block_stair, 100, "four blocks as a staircase (edge-edge contacts, statics)"),
    "paper-7.3": (paper.ring_in_frame, 2050, "a ring bouncing in a square frame (impacts, no lag)"),
    "paper-7.4": (paper.block_in_frame, 10000, "a block bouncing in a square frame (no rotation)"),
    "paper-7.5": (paper.disk_in_ring, 4000, "a disk sliding inside a ring: a frictionless pendulum"),
    "paper-7.6": (paper.block_pull, 100, "a block pulled over a base with cohesion shared by two corners"),
    "paper-7.7": (paper.disk_pull, 500, "a disk pulled over a frictional surface (rolling, slip)"),
    "paper-7.8": (paper.cemented_pull, 100, "a block pulled off a cemented interface"),
    "paper-7.9": (paper.disk_between_blocks, 20, "a disk bouncing between a block and a meshed block (vy=)"),
    "paper-7.10": (paper.particle_chain, 1000, "a chain of disks and star blocks joined by springs, dropped on a disk"),
    "incline": (practical.incline, 100, "a block sliding down a 30 degree incline (friction)"),
    "rolling-disk": (practical.rolling_disk, 300, "a disk rolling to rest against rolling resistance"),
    "rockfall": (practical.rockfall, 600, "a rock rolling and sliding down a slope onto a flat run-out"),
    "bolted-slope": (practical.bolted_slope, 300, "rock blocks on a joint steeper than its friction angle, held by bolts (bolts=False: they slide)"),
    "pile": (practical.pile, 300, "disks settling in a box (n=, friction=): the benchmark scene"),
}


def names() -> list[str]:
    """Names of the built-in examples."""
    return list(_EXAMPLES)


def _entry(name: str):
    if name not in _EXAMPLES:
        raise KeyError(f"unknown example {name!r}; known: {', '.join(_EXAMPLES)}")
    return _EXAMPLES[name]


def get(name: str, *, heavy: bool = False, **options) -> Scene:
    """The example scene ``name``. ``heavy=True``: fixed bodies as the paper built them
    (free, 1e11 times denser, weightless) instead of with zero flexibility. ``options``
    go to the example's factory (e.g. ``height=``, ``friction=``, ``rolling=`` of 7.7)."""
    return _entry(name)[0](heavy=heavy, **options)


def default_steps(name: str) -> int:
    """The number of steps the example runs for by default (the paper's, for its cases)."""
    return _entry(name)[1]


def describe(name: str) -> str:
    return _entry(name)[2]
