"""Monte Carlo studies: many scenarios of a scene, vmapped, chunked and sharded.

Scenarios differ in initial velocities, parameters or whole scenes (padded to one shape,
``scene.padding``). They run in batches that fit memory; each batch is split over the
local devices with ``jax.shard_map`` (one independent ``vmap`` per device, so a device
whose scenarios converge early never waits on another's contact solve) and stepped in
jit-compiled chunks of steps. Per scenario only the reduced observables (``observe``)
are kept, unless trajectories are asked for. Buffers that overflow in a chunk are grown
and the chunk is run again, so no contact is lost.
"""
from __future__ import annotations

import dataclasses
import functools
import time
from typing import Sequence

import jax
import jax.numpy as jnp
import numpy as np
from jax.sharding import Mesh, NamedSharding, PartitionSpec as P

from jaxdda import observe as obs_mod, programs
from jaxdda.calibrate import _item
from jaxdda.errors import CapacityError
from jaxdda.progress import Progress
from jaxdda.scene.builder import Scene
from jaxdda.scene.padding import stack_scenes
from jaxdda.scene.validate import check_counts, check_params
from jaxdda.simulate import MAX_REGROW, with_capacity
from jaxdda.step.pipeline import step_if
from jaxdda.types import Capacities, Params

BATCH_BUDGET = 4_000_000  # default batch: scenarios x (bodies + contact slots) per device


@dataclasses.dataclass
class MonteCarlo:
    """The result of ``monte_carlo`` for B scenarios (numpy arrays, leading axis B).

    ``observables[name]`` is per scenario (per body ones padded to the largest scene:
    ``n_bodies`` says how many are real). ``converged`` is True where every contact solve
    of the run met its tolerance; ``iterations`` and ``residual`` are the worst step's;
    ``devices`` is how many devices shared the batches.
    With ``trajectories=True``: ``time`` (T,) and ``trajectory`` with ``centroid`` (B, T, N, 2),
    ``rotation`` (B, T, N) and ``velocity`` (B, T, N, 3), every ``save_every``-th step.
    """

    observables: dict[str, np.ndarray]
    converged: np.ndarray
    iterations: np.ndarray
    residual: np.ndarray
    max_penetration: np.ndarray
    n_bodies: np.ndarray
    steps: int
    seconds: float
    devices: int
    time: np.ndarray | None = None
    trajectory: dict[str, np.ndarray] | None = None

    def __getitem__(self, name: str) -> np.ndarray:
        return self.observables[name]

    def __len__(self) -> int:
        return len(self.converged)

    def exceedance(self, name: str = "runout", body: int = 0) -> tuple[np.ndarray, np.ndarray]:
        """The empirical exceedance curve of a per-body observable: values x sorted
        ascending and P(X >= x), the share of scenarios reaching at least x."""
        values = np.asarray(self.observables[name])
        values = values[:, body] if values.ndim > 1 else values
        x = np.sort(values)
        return x, 1.0 - np.arange(len(x)) / len(x)


def monte_carlo(scene: Scene | Sequence[Scene], steps: int, *, velocity=None, body: int = 0,
                params: dict | Params | None = None, observe=obs_mod.DEFAULT, batch_size: int | None = None,
                chunk: int = 200, progress: bool = True, devices=None, trajectories: bool = False,
                save_every: int = 1) -> MonteCarlo:
    """Run B scenarios of ``steps`` steps each and reduce each run to its observables.

    Args:
      scene: one Scene (scenarios differ by ``velocity`` and ``params``), or a sequence of
        B scenes, any sizes: they are padded to the largest (``n_bodies`` in the result).
      velocity: initial velocities, (B, 2) vx, vy or (B, 3) vx, vy, omega of body ``body``,
        or (B, N, 3) for every body.
      params: ``{item: values}`` with items as in ``calibrate`` (``"friction"``,
        ``"rolling:rock"``, ``"density:3"``, ``"gravity"``, ...) and values (B,) (or (B, 2)
        for gravity), or a Params whose every leaf has a leading axis B.
      observe: names of built-in observables (``observe.BUILTIN``: ``final_centroid``,
        ``final_rotation``, ``final_velocity``, ``runout``, ``max_displacement``,
        ``max_speed``, ``max_height``) or ``{name: observe.Observable(fn, reduce)}``.
      batch_size: scenarios per batch (rounded up to a multiple of the devices); default
        as many as fit ``BATCH_BUDGET`` bodies-plus-contact-slots per device.
      chunk: steps per compiled chunk (one compilation serves any ``steps``).
      progress: show a progress bar (tqdm when installed): scenario-steps, scenarios done.
      devices: the devices to shard batches over (default ``jax.local_devices()``).
      trajectories: also keep centroids, rotations and velocities every ``save_every`` steps.
    """
    check_counts(steps=steps, chunk=chunk, save_every=save_every, **({} if batch_size is None else
                                                                      {"batch_size": batch_size}))
    scenes = [scene] if isinstance(scene, Scene) else list(scene)
    if not scenes or not all(isinstance(s, Scene) for s in scenes):
        raise TypeError("scene must be a Scene or a non-empty sequence of Scenes")
    many = not isinstance(scene, Scene)
    observables = obs_mod.resolve(observe)
    b = _batch_size(scenes, many, velocity, params)

    if many:
        model, state, base = stack_scenes(scenes)
        n_real = np.array([s.n_bodies for s in scenes])
    else:
        model, state, base = jax.tree.map(jnp.asarray, (scene.model, scene.state, scene.params))
        state, base = jax.tree.map(lambda x: np.broadcast_to(np.asarray(x), (b,) + np.shape(x)), (state, base))
        n_real = np.full(b, scene.n_bodies)
    if isinstance(params, dict) and any(s.materials != scenes[0].materials for s in scenes):
        raise ValueError("params items name materials: the scenes must have the same materials, in the same order")
    state = _with_velocity(state, velocity, body, scenes[0], np.asarray(model.fixed))
    params = _with_params(base, params, scenes[0], b)
    check_params(params)

    devices = list(jax.local_devices() if devices is None else devices)
    per_device = batch_size or max(1, BATCH_BUDGET // (model.n_bodies + model.capacity.contacts))
    size = min(per_device * (1 if batch_size else len(devices)), b)
    size = -(-size // len(devices)) * len(devices)
    mesh = Mesh(np.array(devices), ("batch",))

    t0 = time.perf_counter()
    bar = Progress(b * steps, "scenario-steps", progress)
    results = []
    try:
        for lo in range(0, b, size):
            bar.update(0, scenarios=f"{lo}/{b} done")
            idx = np.minimum(np.arange(lo, lo + size), b - 1)  # the last batch repeats its last scenario
            take = lambda tree: jax.tree.map(lambda x: np.asarray(x)[idx], tree)
            batch_model = take(model) if many else model
            out, model_used = _run_batch(batch_model, take(state), take(params), observables, many, steps,
                                         int(chunk), mesh, trajectories, int(save_every), bar)
            if not many:  # grown buffers carry over to the next batch
                model = dataclasses.replace(model, capacity=model_used.capacity)
            results.append(jax.tree.map(lambda x: x[: min(size, b - lo)], out))
        bar.update(0, scenarios=f"{b}/{b} done")
    finally:
        bar.close()
    acc, traj = jax.tree.map(lambda *xs: np.concatenate(xs), *[r[0] for r in results]), None
    if trajectories:
        traj = jax.tree.map(lambda *xs: np.concatenate(xs), *[r[1] for r in results])
    saved = np.arange(0, steps + 1, save_every)
    return MonteCarlo(
        observables=obs_mod.finish(observables, acc["observe"], steps), converged=acc["converged"],
        iterations=acc["iterations"], residual=acc["residual"], max_penetration=acc["penetration"],
        n_bodies=n_real, steps=int(steps), seconds=time.perf_counter() - t0, devices=len(devices),
        time=None if traj is None else saved * float(np.asarray(scenes[0].params.dt)), trajectory=traj)


def _batch_size(scenes, many, velocity, params) -> int:
    sizes = {}
    if many:
        sizes["scenes"] = len(scenes)
    if velocity is not None:
        sizes["velocity"] = np.shape(velocity)[0] if np.ndim(velocity) else None
    if isinstance(params, dict):
        for k, v in params.items():
            sizes[f"params[{k!r}]"] = np.shape(v)[0] if np.ndim(v) else None
    elif isinstance(params, Params):
        sizes["params"] = np.shape(params.dt)[0] if np.ndim(params.dt) else None
    bad = [k for k, v in sizes.items() if v is None]
    if bad:
        raise ValueError(f"{bad[0]} needs a leading batch axis (one entry per scenario)")
    if len(set(sizes.values())) > 1:
        raise ValueError(f"batch sizes disagree: {sizes}")
    b = next(iter(sizes.values()), 1)
    if b < 1:
        raise ValueError("the batch is empty")
    return b


def _with_velocity(state, velocity, body, scene, fixed):
    if velocity is None:
        return state
    v = np.asarray(velocity, float)
    vel = np.array(state.velocity)
    n = scene.n_bodies
    if v.ndim == 2 and v.shape[1] in (2, 3):
        if isinstance(body, bool) or int(body) != body or not 0 <= body < n:
            raise ValueError(f"body must be a body index 0 ... {n - 1}, got {body!r}")
        if np.any(fixed[..., body]):
            raise ValueError(f"body {body} ({scene.labels[body]}) is fixed: it cannot be given a velocity")
        vel[:, body, : v.shape[1]] = v
    elif v.ndim == 3 and v.shape[1:] in ((vel.shape[1], 3), (n, 3)):
        vel[:, : v.shape[1], :3] = np.where(fixed[..., : v.shape[1], None], 0.0, v)
    else:
        raise ValueError(f"velocity must be (B, 2), (B, 3) or (B, {n}, 3), got shape {v.shape}")
    bad = ~np.isfinite(v)
    if bad.any():
        raise ValueError(f"velocity of scenario {int(np.argwhere(bad)[0][0])} is not finite")
    return dataclasses.replace(state, velocity=vel)


def _with_params(base: Params, params, scene: Scene, b: int) -> Params:
    if params is None:
        return base
    if isinstance(params, Params):
        for (path, x), y in zip(jax.tree_util.tree_leaves_with_path(params), jax.tree.leaves(base)):
            if np.shape(x) != np.shape(y):
                raise ValueError(f"params{jax.tree_util.keystr(path)} has shape {np.shape(x)}, expected {np.shape(y)}")
        return jax.tree.map(np.asarray, params)
    if not isinstance(params, dict):
        raise TypeError("params must be a dict {item: values} or a batched Params")
    updates = {}
    for spec, values in params.items():
        item = _item(scene, spec)
        v = np.asarray(values, float)
        if not np.all(np.isfinite(v)):
            raise ValueError(f"params[{spec!r}]: scenario {int(np.argwhere(~np.isfinite(v))[0][0])} is not finite")
        field = np.array(updates.get(item.field, getattr(base, item.field)), float)
        mask = np.zeros(field.shape[1:], bool)
        mask[tuple(slice(0, s) for s in item.mask.shape)] = item.mask
        if item.field == "gravity":
            if v.shape != (b, 2):
                raise ValueError(f"params['gravity'] must be (B, 2), got shape {v.shape}")
            field[:] = v
        else:
            if v.shape != (b,):
                raise ValueError(f"params[{spec!r}] must be one value per scenario, shape ({b},), got {v.shape}")
            field = np.where(mask, v.reshape((b,) + (1,) * mask.ndim), field)
        updates[item.field] = field
    return dataclasses.replace(base, **updates)


def _run_batch(model, state, params, observables, many, steps, length, mesh, trajectories, save_every, bar):
    """One batch through every chunk of steps; regrows buffers and reruns a chunk on overflow."""
    shard = NamedSharding(mesh, P("batch"))
    put = lambda tree: jax.device_put(tree, shard)
    model = put(model) if many else jax.device_put(model, NamedSharding(mesh, P()))
    state, params = put(state), put(params)
    start = state
    program = _program(tuple(observables.items()), many, length, mesh, trajectories)
    acc = _initial_acc(observables, start)
    saved, done = [], 0
    while done < steps:
        n_valid = min(length, steps - done)
        for _ in range(MAX_REGROW):
            programs.make_room()  # a regrown buffer compiles the chunk again
            end, new_acc, out = program(model, state, params, start, acc, n_valid)
            if not bool(np.any(np.asarray(new_acc["overflow"]))):
                break
            needed = Capacities(*np.asarray(new_acc["needed"]).max(0).tolist())
            model, state = with_capacity(model, state, model.capacity.grown(needed))
        else:
            raise CapacityError(f"contact buffers kept overflowing after {MAX_REGROW} regrowths "
                                f"(capacity {model.capacity})")
        if trajectories:
            keep = [k for k in range(n_valid) if (done + k + 1) % save_every == 0]
            saved.append(jax.tree.map(lambda x: np.asarray(x)[:, keep], out))
        state, acc, done = end, new_acc, done + n_valid
        bar.update(n_valid * len(np.asarray(acc["converged"])), iterations=int(np.max(np.asarray(acc["iterations"]))))
    acc = jax.tree.map(np.asarray, acc)
    traj = None
    if trajectories:
        first = jax.tree.map(lambda x: np.asarray(x)[:, None], _pose(start))
        traj = jax.tree.map(lambda *xs: np.concatenate(xs, 1), first, *saved)
        traj = dict(zip(("centroid", "rotation", "velocity"), traj))
    return (acc, traj), model


def _pose(s):
    return s.centroid, s.rotation, s.velocity[..., :3]


def _initial_acc(observables, start):
    b = start.time.shape[0]
    init = jax.vmap(lambda s: obs_mod.initial(observables, s))(start)
    return {"observe": init, "converged": jnp.ones(b, bool), "overflow": jnp.zeros(b, bool),
            "iterations": jnp.zeros(b, jnp.int32), "residual": jnp.zeros(b),
            "penetration": jnp.zeros(b), "needed": jnp.zeros((b, 5), jnp.int32)}


@programs.holds_programs
@functools.lru_cache(maxsize=16)
def _program(observables, many, length, mesh, trajectories):
    """The jit-compiled chunk: ``length`` steps of every scenario of a batch, sharded."""
    observables = dict(observables)

    def scenario(model, state, params, start, acc, n_valid):
        def body(carry, k):
            s, acc = carry
            valid = k < n_valid
            s2, info = step_if(valid, model, s, params)
            acc = {
                "observe": obs_mod.update(observables, acc["observe"], s2, start, valid),
                "converged": acc["converged"] & (info.converged | ~valid),
                "overflow": acc["overflow"] | info.overflow,
                "iterations": jnp.maximum(acc["iterations"], info.iterations),
                "residual": jnp.maximum(acc["residual"], info.residual),
                "penetration": jnp.maximum(acc["penetration"], info.max_penetration),
                "needed": jnp.maximum(acc["needed"], info.needed),
            }
            return (s2, acc), (_pose(s2) if trajectories else ())

        (end, acc), out = jax.lax.scan(body, (state, acc), jnp.arange(length))
        return end, acc, out

    # the chunk restarts the overflow flag and the counts (they ask for this chunk's rerun)
    def batch(model, state, params, start, acc, n_valid):
        acc = dict(acc, overflow=jnp.zeros_like(acc["overflow"]), needed=jnp.zeros_like(acc["needed"]))
        return jax.vmap(scenario, in_axes=(0 if many else None, 0, 0, 0, 0, None))(
            model, state, params, start, acc, n_valid)

    b = P("batch")
    sharded = jax.shard_map(batch, mesh=mesh, in_specs=(b if many else P(), b, b, b, b, P()),
                            out_specs=(b, b, b), check_vma=False)
    return jax.jit(sharded)
