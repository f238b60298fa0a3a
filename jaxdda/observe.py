"""Per-scenario observables reduced over a run, so a Monte Carlo study keeps no trajectory.

An ``Observable`` is a function ``(state, start) -> array`` of the state after a step
and the initial state, and a reduction over the run: ``final`` (the value after the
last step), ``max``, ``min`` (over the initial state and every step), ``sum`` or
``mean`` (over the steps).
"""
from __future__ import annotations

from typing import Callable, NamedTuple

import jax
import jax.numpy as jnp

from jaxdda.types import State

REDUCTIONS = ("final", "max", "min", "sum", "mean")


class Observable(NamedTuple):
    fn: Callable[[State, State], jax.Array]
    reduce: str = "final"


def _speed(s: State, _: State) -> jax.Array:
    return jnp.linalg.norm(s.velocity[:, :2], axis=-1)


def _displacement(s: State, s0: State) -> jax.Array:
    return jnp.linalg.norm(s.centroid - s0.centroid, axis=-1)


def _runout(s: State, s0: State) -> jax.Array:
    return jnp.abs(s.centroid[:, 0] - s0.centroid[:, 0])


BUILTIN = {
    "final_centroid": Observable(lambda s, _: s.centroid),  # (N, 2)
    "final_rotation": Observable(lambda s, _: s.rotation),  # (N,)
    "final_velocity": Observable(lambda s, _: s.velocity[:, :3]),  # (N, 3) vx, vy, omega
    "runout": Observable(_runout, "max"),  # (N,) farthest horizontal distance from the start
    "max_displacement": Observable(_displacement, "max"),  # (N,) farthest distance from the start
    "max_speed": Observable(_speed, "max"),  # (N,) largest centroid speed
    "max_height": Observable(lambda s, _: s.centroid[:, 1], "max"),  # (N,)
}
DEFAULT = ("final_centroid", "runout", "max_speed")


def resolve(observe) -> dict[str, Observable]:
    """Names and/or ``{name: Observable | fn}`` -> ``{name: Observable}``, checked."""
    if isinstance(observe, str):
        observe = (observe,)
    items = dict(observe) if isinstance(observe, dict) else {}
    if not isinstance(observe, dict):
        for name in observe:
            if not isinstance(name, str) or name not in BUILTIN:
                raise ValueError(f"unknown observable {name!r}; built-in: {', '.join(BUILTIN)} "
                                 f"(or pass {{name: Observable(fn, reduce)}})")
            items[name] = BUILTIN[name]
    out = {}
    for name, ob in items.items():
        ob = ob if isinstance(ob, Observable) else Observable(ob) if callable(ob) else None
        if ob is None or not callable(ob.fn) or ob.reduce not in REDUCTIONS:
            raise ValueError(f"observable {name!r} must be an Observable(fn, reduce) with reduce in {REDUCTIONS}")
        out[name] = ob
    if not out:
        raise ValueError("observe names no observable")
    return out


def initial(obs: dict[str, Observable], start: State) -> dict[str, jax.Array]:
    def first(ob):
        v = ob.fn(start, start)
        return jnp.zeros_like(v) if ob.reduce in ("sum", "mean") else v

    return {k: first(ob) for k, ob in obs.items()}


def update(obs: dict[str, Observable], acc: dict, state: State, start: State, valid) -> dict:
    """The accumulators after one more step (unchanged where ``valid`` is False)."""
    out = {}
    for k, ob in obs.items():
        v = ob.fn(state, start)
        new = {"final": v, "max": jnp.maximum(acc[k], v), "min": jnp.minimum(acc[k], v)}.get(ob.reduce, acc[k] + v)
        out[k] = jnp.where(valid, new, acc[k])
    return out


def finish(obs: dict[str, Observable], acc: dict, steps: int) -> dict:
    return {k: acc[k] / steps if ob.reduce == "mean" else acc[k] for k, ob in obs.items()}
