"""Fit physical parameters to a measured trajectory by gradient descent (optax).

The gradient of the trajectory misfit comes from reverse mode through a checkpointed
rollout, with the contact solves differentiated implicitly (``solver.fista_newton``).
"""
from __future__ import annotations

import dataclasses
import functools
from typing import Callable, NamedTuple, Sequence

import jax
import jax.flatten_util
import jax.numpy as jnp
import numpy as np
import optax

from jaxdda._pytree import float0, int_zeros
from jaxdda.errors import CapacityError
from jaxdda.progress import Progress
from jaxdda.scene.builder import Scene
from jaxdda.scene.padding import Shape, unpad_state
from jaxdda.simulate import MAX_REGROW, Trajectory, padded_scene, simulate, with_capacity
from jaxdda.step import rollout
from jaxdda.step.pipeline import step_if
from jaxdda.types import Capacities, Model, Params, State

TABLES = ("friction", "restitution", "cohesion", "rolling", "tensile")  # (M, M) per material pair
PER_BODY = ("density", "young", "poisson")  # (N,)
POSITIVE = {"friction", "cohesion", "rolling", "tensile", "density", "young"}  # fitted as logarithms
LM_RADIUS = 0.5  # the largest change of a fitted value per Levenberg-Marquardt iteration
OBSERVE = {
    "centroid": lambda s: s.centroid,  # (S+1, N, 2)
    "pose": lambda s: jnp.concatenate([s.centroid, s.rotation[..., None]], -1),  # (S+1, N, 3)
}


@dataclasses.dataclass
class Calibration:
    """The result of ``calibrate``: fitted ``params``, the fitted ``values`` by item, the
    loss before each iteration and after the last (``history``, length iterations + 1)
    and each item's value along the way (``trace``)."""

    params: Params
    values: dict[str, float | np.ndarray]
    history: np.ndarray
    trace: dict[str, np.ndarray]


@dataclasses.dataclass(frozen=True)
class _Item:
    name: str
    field: str
    mask: np.ndarray  # which entries of the field the one fitted value sets


def _item(scene: Scene, spec: str) -> _Item:
    field, _, sel = spec.partition(":")
    params = scene.params
    if field in TABLES:
        names = list(scene.materials)
        if sel:
            pair = sel.split("/")
            unknown = [m for m in pair if m not in names]
            if len(pair) > 2 or unknown:
                raise ValueError(f"fit item {spec!r}: unknown material {unknown or sel!r} (materials: {names})")
            i, j = names.index(pair[0]), names.index(pair[-1])
            mask = np.zeros((len(names),) * 2, bool)
            mask[i, j] = mask[j, i] = True
        else:  # every pair of the materials the bodies use
            used = np.zeros(len(names), bool)
            used[np.asarray(scene.model.material)] = True
            mask = used[:, None] & used[None, :]
    elif field in PER_BODY:
        n = scene.n_bodies
        if sel:
            if not sel.isdigit() or int(sel) >= n:
                raise ValueError(f"fit item {spec!r}: no body {sel!r} (bodies 0 ... {n - 1})")
            mask = np.arange(n) == int(sel)
        else:  # every free body (deformable ones only, for the elastic constants)
            mask = ~np.asarray(scene.model.fixed)
            if field != "density":
                mask &= np.asarray(params.young) > 0
        if not mask.any():
            raise ValueError(f"fit item {spec!r} selects no body")
    elif field == "gravity" and not sel:
        mask = np.ones(2, bool)
    else:
        raise ValueError(f"cannot fit {spec!r}: fit items are {', '.join(TABLES + PER_BODY)} (optionally "
                         f"':material', ':material_a/material_b' or ':body index') and 'gravity'")
    return _Item(spec, field, mask)


def _start(params: Params, item: _Item, initial: dict) -> jax.Array:
    current = np.asarray(getattr(params, item.field))
    value = np.asarray(initial[item.name], float) if item.name in initial else (
        current[item.mask].reshape(-1)[0] if item.field != "gravity" else current)
    if item.field in POSITIVE:
        if not np.all(value > 0):
            raise ValueError(f"fit item {item.name!r} starts at {value}; it is fitted as a logarithm and needs a "
                             f"positive start (give initial={{{item.name!r}: ...}})")
        return jnp.log(jnp.asarray(value, float))
    return jnp.asarray(value, float)


def _apply(params: Params, fields: Sequence[tuple[str, str]], masks: Sequence, theta: dict) -> Params:
    """``params`` with each fitted value (``theta`` by item name) set where its mask is."""
    updates = {}
    for (name, field), mask in zip(fields, masks):
        value = jnp.exp(theta[name]) if field in POSITIVE else theta[name]
        base = updates.get(field, getattr(params, field))
        updates[field] = jnp.where(jnp.asarray(mask), value, base)
    return dataclasses.replace(params, **updates)


class _Spec(NamedTuple):
    """What a fit compiles for (static, hashable): a second fit of the same kind reuses it."""
    fields: tuple[tuple[str, str], ...]  # (item name, Params field)
    observe: str | Callable
    steps: int


class _Problem(NamedTuple):
    """What a fit runs on (arrays): the scene, the parameters not fitted, the target."""
    model: Model
    state: State
    params: Params
    target: jax.Array
    masks: tuple[jax.Array, ...]


def _residual(spec: _Spec, problem: _Problem, theta: dict):
    """The misfit, scaled so that loss = |residual|^2, and (buffer counts, overflow)."""
    params = _apply(problem.params, spec.fields, problem.masks, theta)
    _, (states, infos) = rollout(problem.model, problem.state, params, spec.steps)
    states = jax.tree.map(lambda s0, s: jnp.concatenate([s0[None], s]), problem.state, states)
    err = (observe_trajectory(spec.observe, states) - problem.target).reshape(-1)
    return err / np.sqrt(err.size), (jnp.max(infos.needed, 0), jnp.any(infos.overflow))


# Steps per compiled chunk of the forward-mode linearisation: fits of scenes of one size
# class share its program, whatever the number of steps, items or observable.
LM_CHUNK = 50


@functools.partial(jax.jit, static_argnames="length")
def _chunk_tangents(model: Model, state: State, params: Params, d_state, d_params, n_valid, length: int):
    """``length`` steps (those from ``n_valid`` on skipped) and their tangents along k
    directions (leading axis of ``d_state``, ``d_params``; integer leaves as zeros):
    ((end, stacked states, needed, overflow), (d_end, d_states))."""
    def run(s, p):
        def body(carry, k):
            s2, info = step_if(k < n_valid, model, carry, p)
            return s2, (s2, info.needed, info.overflow & (k < n_valid))

        end, (states, needed, overflow) = jax.lax.scan(body, s, jnp.arange(length))
        return end, states, jnp.max(needed, 0), jnp.any(overflow)

    def along(ds, dp):
        out, d_out = jax.jvp(run, (state, params), float0((ds, dp)))
        return out, int_zeros(d_out[:2], out[:2])

    return jax.vmap(along, out_axes=(None, 0))(d_state, d_params)


class _PaddedFit(NamedTuple):
    """A Levenberg-Marquardt fit's scene padded to its size class (``Shape.bucket``), so
    that fits of scenes of similar size share ``_chunk_tangents``."""

    model: Model
    state: State
    params: Params
    masks: tuple[jax.Array, ...]  # the items' masks, padded
    target: jax.Array
    own: Scene  # the scene itself (its own bodies are observed)
    shape: Shape


def _padded_fit(scene: Scene, problem: _Problem, spec: _Spec) -> _PaddedFit:
    own, shape, model, state, params = padded_scene(dataclasses.replace(scene, model=problem.model), problem.params,
                                                    problem.state)
    masks = []
    for (_, field), mask in zip(spec.fields, problem.masks):
        mask = np.asarray(mask)
        room = np.shape(getattr(params, field))[:mask.ndim]
        masks.append(jnp.asarray(np.pad(mask, [(0, r - m) for r, m in zip(room, mask.shape)])))
    return _PaddedFit(model, state, params, tuple(masks), problem.target, own, shape)


def _linearise(spec: _Spec, fit: _PaddedFit, theta: dict):
    """(residual, its Jacobian in the flattened theta by forward mode, aux): the rollout
    in chunks of LM_CHUNK steps carrying one tangent per fitted value."""
    flat, unravel = jax.flatten_util.ravel_pytree(theta)

    def set_params(x):
        return _apply(fit.params, spec.fields, fit.masks, unravel(x))

    k = flat.size
    params = set_params(flat)
    d_params = jax.vmap(lambda v: jax.jvp(set_params, (flat,), (v,))[1])(jnp.eye(k, dtype=flat.dtype))
    state = fit.state
    d_state = jax.tree.map(lambda x: jnp.zeros((k,) + x.shape, x.dtype), state)
    states, tangents, needed, overflow = [fit.state], [d_state], [], False
    for start in range(0, spec.steps, LM_CHUNK):
        n = min(LM_CHUNK, spec.steps - start)
        (state, chunk, need, over), (d_state, d_chunk) = _chunk_tangents(fit.model, state, params, d_state, d_params,
                                                                         n, length=LM_CHUNK)
        states.append(jax.tree.map(lambda x: x[:n], chunk))
        tangents.append(jax.tree.map(lambda x: x[:, :n], d_chunk))
        needed.append(need)
        overflow = overflow | over
    states = jax.tree.map(lambda x0, *xs: np.concatenate([np.asarray(x0)[None], *map(np.asarray, xs)]), *states)
    tangents = jax.tree.map(lambda x0, *xs: np.concatenate([np.asarray(x0)[:, None], *map(np.asarray, xs)], 1),
                            *tangents)
    own = unpad_state(states, fit.own, fit.shape, leading=1)
    d_own = unpad_state(tangents, fit.own, fit.shape, leading=2, keys=False)
    r, jac = _observed_misfit(spec.observe, fit.target, own, d_own)
    return r, jac.T, (jnp.max(jnp.stack(needed), 0), overflow)


@functools.partial(jax.jit, static_argnums=0)
def _observed_misfit(observe, target, states, tangents):
    """The scaled misfit of the observed stacked states, and its tangents (k, size)."""
    def misfit(s):
        err = (observe_trajectory(observe, s) - target).reshape(-1)
        return err / np.sqrt(err.size)

    return misfit(states), jax.vmap(lambda t: jax.jvp(misfit, (states,), (float0(t),))[1])(tangents)


def _loss(spec: _Spec, problem: _Problem, theta: dict):
    r, aux = _residual(spec, problem, theta)
    return r @ r, aux


@functools.partial(jax.jit, static_argnums=(0, 1))
def _descend(spec: _Spec, optimizer, problem: _Problem, theta: dict, opt_state):
    """One optax step on the loss (reverse mode): (new theta, new state, loss, aux)."""
    (value, aux), grad = jax.value_and_grad(functools.partial(_loss, spec, problem), has_aux=True)(theta)
    updates, opt_state = optimizer.update(grad, opt_state, theta, value=value, grad=grad,
                                          value_fn=lambda t: _loss(spec, problem, t)[0])
    return optax.apply_updates(theta, updates), opt_state, value, aux


def observe_trajectory(observe: str | Callable, states: State) -> jax.Array:
    """The observed quantity of stacked states (leading axis: time)."""
    if callable(observe):
        return observe(states)
    if observe not in OBSERVE:
        raise ValueError(f"observe must be a callable or one of {sorted(OBSERVE)}, got {observe!r}")
    return OBSERVE[observe](states)


def _target(target, observe) -> np.ndarray:
    if isinstance(target, Trajectory):
        if callable(observe):
            raise ValueError("with a callable observe, give the target as an array, observe applied to its states")
        pose = np.concatenate([target.centroid, target.rotation[..., None]], -1)
        return target.centroid if observe == "centroid" else pose
    return np.asarray(target, float)


def calibrate(scene: Scene, target, fit: Sequence[str], *, optimizer: optax.GradientTransformation | None = None,
              iterations: int = 100, observe: str | Callable = "centroid", initial: dict | None = None,
              rupture_width: float | None = None, params: Params | None = None,
              progress: bool = True) -> Calibration:
    """Fit the parameters named in ``fit`` so that ``scene`` reproduces ``target``.

    Args:
      scene: the scene, started from its own initial state.
      target: the measured trajectory: a Trajectory, or an array (S+1, ...) of the
        observed quantity at t = 0, dt, ..., S dt (S steps are simulated).
      fit: items such as ``"friction"`` (every pair of the materials in use, one value),
        ``"friction:rock"``, ``"rolling:rock/steel"``, ``"tensile"``, ``"cohesion"``,
        ``"restitution"``, ``"density"`` (all free bodies) or ``"density:3"``, ``"young"``,
        ``"poisson"``, ``"gravity"`` (the vector).
      optimizer: None for Levenberg-Marquardt (forward-mode Jacobian of the misfit; a
        few iterations for a few parameters), or any optax transformation, which then
        descends the loss's reverse-mode gradient (line-search methods such as
        ``optax.lbfgs()`` get the loss as ``value_fn``). Positive quantities (friction,
        cohesion, rolling, tensile, density, young) are fitted as logarithms.
      iterations: optimizer steps (each one linearisation or gradient). observe: ``"centroid"``, ``"pose"`` (centroid and
        rotation) or a function of stacked States. initial: start values by item
        (default: the scene's).
      rupture_width: the smoothed rupture of cemented joints (a force, N) used while
        fitting; default 1 % of the starting tensile strength when ``tensile`` is fitted,
        else the scene's (0). The returned params keep the scene's own (sharp) rupture.
      progress: show a bar of iterations with the loss.

    The loss is the mean squared difference of the observed quantity over all steps.
    The compiled programs are kept: a second fit of the same items, observable, number
    of steps and scene shape (other start values or targets; the same optimizer object)
    compiles nothing. Levenberg-Marquardt runs the scene padded to its size class in
    chunks of ``LM_CHUNK`` steps, so that its one large program (the chunk with its
    tangents) serves every fit of a scene of that class with as many fitted values,
    whatever the items, steps or observable. Returns the final parameters (Calibration).
    """
    items = [_item(scene, spec) for spec in fit]
    if not items:
        raise ValueError("fit names no parameter")
    base = scene.params if params is None else params
    theta = _starts(base, items, dict(initial or {}))
    target = jnp.asarray(_target(target, observe))
    spec = _Spec(tuple((i.name, i.field) for i in items), observe, int(target.shape[0]) - 1)
    if spec.steps < 1:
        raise ValueError("the target needs at least two time points (t = 0 and one step)")
    fit_base = _fit_base(base, items, theta, rupture_width)
    masks = tuple(jnp.asarray(i.mask) for i in items)
    # Buffers sized by a plain run at the start values, regrown if the fit outgrows them.
    trial = simulate(scene, spec.steps, params=_apply(fit_base, spec.fields, masks, theta))
    needed = Capacities(*np.asarray(trial.info.needed).max(0).tolist())
    model, state = with_capacity(scene.model, scene.state, scene.model.capacity.grown(needed))
    if optimizer is None:
        logarithmic = {item.name: jnp.full(jnp.shape(theta[item.name]), item.field in POSITIVE) for item in items}
        method = functools.partial(_levenberg_marquardt, logarithmic=logarithmic, scene=scene)
    else:
        method = functools.partial(_optax, optax.with_extra_args_support(optimizer))
    for _ in range(MAX_REGROW):
        bar = Progress(int(iterations) + 1, "iterations", progress)
        record = _Record(items, bar)
        theta_end, needed = method(spec, _Problem(model, state, fit_base, target, masks), theta, int(iterations),
                                   record)
        bar.close()
        if needed is None:
            break
        model, state = with_capacity(model, state, model.capacity.grown(needed))
    else:
        raise CapacityError(f"contact buffers kept overflowing during the fit (capacity {model.capacity})")
    values = {item.name: _scalar(record.trace[item.name][-1]) for item in items}
    return Calibration(_apply(base, spec.fields, masks, theta_end), values, np.asarray(record.history),
                       {k: np.asarray(v) for k, v in record.trace.items()})


def _starts(params: Params, items: Sequence[_Item], initial: dict) -> dict:
    unknown = set(initial) - {i.name for i in items}
    if unknown:
        raise ValueError(f"initial values for items not fitted: {sorted(unknown)}")
    return {item.name: _start(params, item, initial) for item in items}


def _fit_base(params: Params, items: Sequence[_Item], theta: dict, rupture_width: float | None) -> Params:
    """The parameters a fit runs with: the rupture smoothed by ``rupture_width`` (default
    1 % of the starting tensile strength when it is fitted, else the scene's)."""
    if rupture_width is None:
        tensile = [i for i in items if i.field == "tensile"]
        rupture_width = 0.01 * float(jnp.exp(theta[tensile[0].name])) if tensile else float(params.rupture_width)
    return dataclasses.replace(params, rupture_width=jnp.asarray(np.float64(rupture_width)))


class _Record:
    """The loss and each item's value per iteration, shown on a progress bar."""

    def __init__(self, items: Sequence[_Item], bar: Progress):
        self.items, self.bar = items, bar
        self.history, self.trace = [], {item.name: [] for item in items}

    def __call__(self, theta: dict, value: float) -> None:
        self.history.append(value)
        for item in self.items:
            self.trace[item.name].append(np.asarray(_value(item, theta[item.name])))
        self.bar.update(1, loss=f"{value:.4g}")


def _overflowed(aux):
    needed, overflow = aux
    return Capacities(*np.asarray(needed).tolist()) if bool(overflow) else None


def _levenberg_marquardt(spec, problem, theta, iterations, record, logarithmic, scene):
    """Levenberg-Marquardt on the misfit, its Jacobian by forward mode (one tangent per
    fitted value): the usual method for least squares with few parameters. Each iteration
    is one linearisation; a rejected step raises the damping and costs an iteration."""
    flat, unravel = jax.flatten_util.ravel_pytree(theta)

    fit = _padded_fit(scene, problem, spec)

    def linearise(x):
        return _linearise(spec, fit, unravel(x))

    x = flat
    full_radius = jnp.where(jax.flatten_util.ravel_pytree(logarithmic)[0], LM_RADIUS, LM_RADIUS * (1.0 + jnp.abs(flat)))
    radius = full_radius
    r, jac, aux = linearise(x)
    if (needed := _overflowed(aux)) is not None:
        return theta, needed
    value, damping = float(r @ r), 1e-3
    record(unravel(x), value)
    for _ in range(iterations):
        jtj, jtr = jac.T @ jac, jac.T @ r
        scale = jnp.diag(jtj) + 1e-300
        step = -jnp.linalg.solve(jtj + damping * jnp.diag(scale), jtr)
        # A trust region: no value moves by more than a factor e^0.5 (or 0.5 (1 + |x|) if
        # not fitted as a logarithm) per iteration, halved on each rejected step: the
        # linearisation holds poorly where a rupture or an impact moves by whole steps.
        step = step * jnp.minimum(1.0, jnp.min(radius / (jnp.abs(step) + 1e-300)))
        r_new, jac_new, aux = linearise(x + step)
        if (needed := _overflowed(aux)) is not None:
            return theta, needed
        value_new = float(r_new @ r_new)
        if value_new <= value:
            x, r, jac, value, damping = x + step, r_new, jac_new, value_new, max(damping / 3.0, 1e-12)
            radius = jnp.minimum(2.0 * radius, full_radius)
        else:
            damping, radius = 4.0 * damping, 0.5 * radius
        record(unravel(x), value)
    return unravel(x), None


def _optax(optimizer, spec, problem, theta, iterations, record):
    """Gradient descent with an optax transformation on the loss |residual|^2 (reverse
    mode); line-search methods get the loss as ``value_fn``."""
    opt_state = optimizer.init(theta)
    for k in range(iterations + 1):  # the last pass only measures the final loss
        new_theta, new_opt_state, value, aux = _descend(spec, optimizer, problem, theta, opt_state)
        if (needed := _overflowed(aux)) is not None:
            return theta, needed
        record(theta, float(value))
        if k < iterations:
            theta, opt_state = new_theta, new_opt_state
    return theta, None


def _value(item: _Item, t: jax.Array) -> jax.Array:
    return jnp.exp(t) if item.field in POSITIVE else t


def _scalar(v: np.ndarray):
    return float(v) if np.ndim(v) == 0 else v
