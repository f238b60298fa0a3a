"""First guess of buffer capacities from the initial configuration (host side, numpy)."""
from __future__ import annotations

import dataclasses

import numpy as np

from jaxdda.contact.broadphase import candidate_count
from jaxdda.types import POLYGON, Capacities

HEADROOM = 2  # room for the scene to rearrange before the driver has to regrow a buffer
# The least first guesses: small scenes share their buffer sizes, and so their compiled program.
LEAST = Capacities(candidates=64, pairs_pp=16, pairs_pb=16, pairs_bb=16, contacts=32)


def size_class(x: int, least: int = 1) -> int:
    """``x`` rounded up to ``least`` and to a number of 3 significant bits (at most 1/4 more)."""
    x = max(int(x), least)
    unit = 2 ** max(x.bit_length() - 3, 0)
    return -(-x // unit) * unit


def capacity_class(c: Capacities, least: Capacities | None = None) -> Capacities:
    """Buffer capacities rounded up to their size classes (``size_class``)."""
    floors = (1,) * 5 if least is None else dataclasses.astuple(least)
    return Capacities(*(size_class(x, f) for x, f in zip(dataclasses.astuple(c), floors)))


def initial_capacities(kind, fixed, centers, local, mask, bound, velocity, dt, gravity, margin) -> Capacities:
    """Count the candidates of the first step (same boxes as the step's broad phase), with
    boxes grown by a quarter of the median body size: bodies released a little apart (a
    pile about to settle) get room for the contacts they will make, not one regrowth each."""
    reach = 2 * dt * (np.linalg.norm(velocity[:, :2], axis=1) + np.abs(velocity[:, 2]) * bound)
    reach = np.where(fixed, 0.0, reach + dt ** 2 * np.linalg.norm(gravity)) + 0.5 * margin
    poly = kind == POLYGON
    world = local + centers[:, None, :]
    big = np.finfo(float).max
    lo = np.where(poly[:, None], np.min(np.where(mask[..., None], world, big), 1), centers - bound[:, None])
    hi = np.where(poly[:, None], np.max(np.where(mask[..., None], world, -big), 1), centers + bound[:, None])
    settle = 0.25 * np.median(bound[~fixed]) if np.any(~fixed) else 0.0
    lo, hi = lo - reach[:, None] - settle, hi + reach[:, None] + settle

    candidates, i, j = candidate_count(lo, hi)
    ok = ~(fixed[i] & fixed[j])
    n_poly = poly[i].astype(int) + poly[j].astype(int)
    pp, pb, bb = (int(np.sum(ok & (n_poly == m))) for m in (0, 1, 2))
    contacts = pp + 2 * pb + 4 * bb
    return capacity_class(Capacities(candidates=HEADROOM * candidates, pairs_pp=HEADROOM * pp, pairs_pb=HEADROOM * pb,
                                     pairs_bb=HEADROOM * bb, contacts=HEADROOM * contacts), LEAST)
