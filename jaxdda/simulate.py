"""Host driver: run a scene in jit-compiled chunks, regrow overflowing buffers, collect output."""
from __future__ import annotations

import dataclasses
import warnings

import jax
import jax.numpy as jnp
import numpy as np

from jaxdda import programs
from jaxdda.errors import CapacityError, ConvergenceError, NonConvergenceWarning
from jaxdda.progress import Progress
from jaxdda.scene.builder import Scene
from jaxdda.scene.capacity import capacity_class
from jaxdda.scene.padding import Shape, pad_scene, unpad_state
from jaxdda.scene.validate import check_counts, check_params
from jaxdda.step.pipeline import step_if
from jaxdda.types import Capacities, ContactReport, Model, Params, State, StepInfo

MAX_REGROW = 8
ON_NONCONVERGENCE = ("continue", "halve", "raise")


@dataclasses.dataclass
class Trajectory:
    """A simulated run of S steps, as numpy arrays. Index 0 is the initial state; step k
    ends at index k (with ``simulate(..., save_every=k)``: the step ``saved_steps[i]``).

    ``info`` holds one StepInfo entry per step (leading axis S); ``info.contacts`` the
    per-step contact report, padded to the largest contact capacity of the run (its
    ``moment`` holds the rolling resistance moments). Cemented joints (found at t = 0,
    ``scene.model.joint_a/joint_b``) report ``joint_tension`` and ``joint_broken`` (S, J).
    """

    scene: Scene
    time: np.ndarray  # (S+1,)
    centroid: np.ndarray  # (S+1, bodies, 2)
    rotation: np.ndarray  # (S+1, bodies)
    velocity: np.ndarray  # (S+1, bodies, 3): vx, vy, omega
    stress: np.ndarray  # (S+1, bodies, 3): sigma_x, sigma_y, tau_xy of deformable bodies (0 if rigid)
    info: StepInfo
    final_state: State
    stretch: np.ndarray | None = None  # (S+1, bodies, 2, 2): shape x = c + R(rotation) stretch X (I if rigid)
    saved_steps: np.ndarray | None = None  # (S+1,) the step each index ends (0: the start); None: every step
    step_converged: np.ndarray | None = None  # (steps,) whether each step run converged, saved or not
    params: Params | None = None  # the parameters of the run (default: the scene's)
    capacity: Capacities | None = None  # buffer capacities at the end (grown where they overflowed)
    halvings: np.ndarray | None = None  # (steps,) times each step run was halved (on_nonconvergence="halve")

    @property
    def steps(self) -> int:
        """Steps run (with ``save_every``, more than were kept)."""
        return len(self.time) - 1 if self.saved_steps is None else int(self.saved_steps[-1])

    @property
    def joint_tension(self) -> np.ndarray:
        """(S, J) tension in each cemented joint per step (0 when it carries compression)."""
        return self.info.joint_tension[:, : self.n_joints]

    @property
    def joint_broken(self) -> np.ndarray:
        """(S, J) bool: the joint is broken at the end of each step."""
        return self.info.joint_broken[:, : self.n_joints]

    @property
    def n_joints(self) -> int:
        return int(np.sum(np.asarray(self.scene.model.joint_key) >= 0))

    @property
    def connector_force(self) -> np.ndarray:
        """(S, K, 4) per connector at the end of each step: axial force (tension +), shear
        force, and the bending moments at ends a and b (beams; connectors.connector_forces)."""
        return self.info.connector_force

    def vertices(self, frames=slice(None)) -> np.ndarray:
        """(F, bodies, V, 2): polygon vertices in the world frame at the saved states
        ``frames`` (a slice or index array; default all S+1), padding entries and those of
        disks and rings meaningless."""
        rotation, centroid = np.asarray(self.rotation)[frames], np.asarray(self.centroid)[frames]
        stretch = np.broadcast_to(np.eye(2), rotation.shape + (2, 2)) if self.stretch is None else \
            np.asarray(self.stretch)[frames]
        local = np.einsum("snij,nvj->snvi", stretch, np.asarray(self.scene.model.local_vertices))
        c, s = np.cos(rotation)[..., None], np.sin(rotation)[..., None]
        x, y = local[..., 0], local[..., 1]
        return centroid[:, :, None, :] + np.stack([c * x - s * y, s * x + c * y], -1)

    def material_points(self, body, local) -> np.ndarray:
        """(S+1, P, 2): world paths of material points given per point by ``body`` (P,)
        and ``local`` (P, 2), each body-local at rotation 0 (x = c + R(rotation) S X)."""
        body, local = np.asarray(body, np.int64).reshape(-1), np.asarray(local, float).reshape(-1, 2)
        stretch = np.broadcast_to(np.eye(2), self.rotation.shape + (2, 2)) if self.stretch is None else self.stretch
        x = np.einsum("spij,pj->spi", stretch[:, body], local)
        c, s = np.cos(self.rotation[:, body]), np.sin(self.rotation[:, body])
        return self.centroid[:, body] + np.stack([c * x[..., 0] - s * x[..., 1], s * x[..., 0] + c * x[..., 1]], -1)

    def measured_points(self) -> np.ndarray:
        """(S+1, P, 2): the paths of the scene's measured points (``add_measured_point``)."""
        return self.material_points([b for b, _ in self.scene.measured], [x for _, x in self.scene.measured])

    def load_points(self) -> np.ndarray:
        """(S+1, L, 2): where each point load acts at each saved step."""
        return self.material_points(self.scene.model.load_body, self.scene.model.load_point)

    def load_forces(self) -> np.ndarray:
        """(S+1, L, 2): each point load's force F(t) = force + rate t + history(t) at each
        saved time (the step ending at t applies F(t))."""
        p, m = self.params or self.scene.params, self.scene.model
        t = self.time[:, None, None]
        times, history = np.asarray(m.load_times), np.asarray(p.load_history)
        h = np.zeros((len(self.time), len(times), 2))
        for k in range(len(times)):  # host-side, per load
            for i in range(2):
                h[:, k, i] = np.interp(self.time, times[k], history[k, :, i])
        return np.asarray(p.load_force)[None] + np.asarray(p.load_rate)[None] * t + h

    def mesh_nodes(self, mesh) -> np.ndarray:
        """(S+1, nodes, 2): the node positions of a meshed block (the ``Mesh`` that
        ``add_mesh`` returned) at each step."""
        verts = self.vertices()
        out = np.empty((len(self.time), len(mesh.nodes), 2))
        for element, body in enumerate(mesh.bodies):
            out[:, mesh.triangles[element]] = verts[:, body, :3]
        return out

    def force_between(self, i: int, j: int) -> np.ndarray:
        """(S, 2): the resultant contact force that body i exerts on body j in each step
        (global frame, step average: impact impulses count as impulse / dt)."""
        c = self.info.contacts
        on_a = np.where(c.valid[..., None], c.force, 0.0)  # force on a from b
        from_i_on_j = ((c.a == j) & (c.b == i))[..., None] * on_a - ((c.a == i) & (c.b == j))[..., None] * on_a
        return from_i_on_j.sum(axis=1)


def _run_chunk(model: Model, state: State, params: Params, n_valid, length: int, stop=False):
    """Scan ``length`` steps; steps at index >= n_valid are skipped (state unchanged,
    zero info), so every run of a scene shares one compilation whatever its length.

    ``stop`` (a traced bool: pass it always, so that every call shares the program):
    at the first step whose contact solve does not converge, the chunk keeps the state
    from before that step and skips the rest (that step's info is still returned)."""
    def body(carry, k):
        s, halted = carry
        run = (k < n_valid) & ~halted
        s2, info = step_if(run, model, s, params)
        failed = run & stop & ~info.converged
        kept = jax.tree.map(lambda old, new: jnp.where(failed, old, new), s, s2)
        return (kept, halted | failed), (s2.time, s2.centroid, s2.rotation, s2.velocity[:, :3], s2.stress, s2.stretch,
                                         info)

    (end, _), out = jax.lax.scan(body, (state, jnp.asarray(False)), jnp.arange(length))
    return end, out


_run_chunk_jit = jax.jit(_run_chunk, static_argnames=("length",))


def with_capacity(model: Model, state: State, capacity: Capacities) -> tuple[Model, State]:
    """The same model with new buffer capacities, and the state's contact memory re-padded
    (also for a batch of states: the contact axis is the last of ``contact_key``)."""
    c = capacity.contacts
    key, force = state.contact_key, state.contact_force
    old = key.shape[-1]
    if c >= old:
        key = jnp.concatenate([key, -jnp.ones(key.shape[:-1] + (c - old,), key.dtype)], -1)
        force = jnp.concatenate([force, jnp.zeros(force.shape[:-2] + (c - old, force.shape[-1]), force.dtype)], -2)
    else:
        key, force = key[..., :c], force[..., :c, :]
    return dataclasses.replace(model, capacity=capacity), dataclasses.replace(state, contact_key=key, contact_force=force)


CHUNK = 1000  # steps per compiled chunk, by default (the CLI's too: they share programs)


def simulate(scene: Scene, steps: int, *, params: Params | None = None, chunk: int = CHUNK, save_every: int = 1,
             progress: bool | None = None, state: State | None = None, on_nonconvergence: str = "continue",
             max_halvings: int = 4) -> Trajectory:
    """Run ``steps`` (>= 1) steps of ``scene`` and return the trajectory.

    Runs in jit-compiled chunks of ``chunk`` steps (one compilation per scene and chunk
    length, whatever ``steps``; the unused tail of the last chunk is skipped). When
    a buffer overflows, its capacity is grown from the counts its first overflowing step
    reported and the run goes on from that step, so no contact is ever lost and the
    results do not depend on where chunks begin (restarts are bit-identical).
    Raises CapacityError if that does not settle within a few regrowths. The scene runs
    padded to its size class (``Shape.bucket``), so that scenes of similar size share one
    compilation; what is returned is the scene's own bodies, joints and connectors.

    ``state``: start from it instead of ``scene.state`` (a ``final_state``, or a
    checkpoint's: ``jaxdda.checkpoint``); time goes on from ``state.time``. Its contact
    memory is re-padded to the scene's contact capacity where they differ; a checkpoint's
    ``scene()`` carries the capacities its run had grown, for a bit-identical continuation.

    ``save_every=k`` keeps the state and step diagnostics of every k-th step only (and
    the last), so memory stays flat on long runs (``Trajectory.saved_steps`` numbers
    them). ``progress`` shows a bar with steps per second and the chunk's largest
    solver iteration count (None: when the run takes more than one chunk).

    ``on_nonconvergence`` says what a step whose contact solve misses its tolerance within
    ``max_iter`` (``StepInfo.converged`` False) does to the run:

    * ``"continue"`` (default): the run goes on with that step's best iterate; the step
      is reported in ``step_converged`` (and ``info.converged``, ``info.residual``).
    * ``"raise"``: stop with a ConvergenceError naming the step, its time, residual and
      iterations.
    * ``"halve"``: run that step again as two steps of dt / 2 (as DDA codes do), each
      halved again where it does not converge, to ``max_halvings`` halvings (dt / 2^k),
      then raise ConvergenceError; the run goes on at dt after it. The trajectory keeps
      one entry per step of dt (its end; its info that of the last sub-step, iterations
      summed, residual and penetration the worst), and ``Trajectory.halvings`` says how
      many times each step was halved (0: not). A non-converged step costs a rerun of
      the chunk from it (see docs/design.md, "Non-convergence").

    With ``"continue"``, a run with steps that did not converge warns once
    (``NonConvergenceWarning``: their count, the worst residual and what to do).
    """
    check_counts(steps=steps, chunk=chunk, save_every=save_every)
    _check_nonconvergence(on_nonconvergence, max_halvings)
    stop = on_nonconvergence != "continue"
    own, shape, model, state, params = padded_scene(scene, params, state)
    start, length = state, int(chunk)
    kept = _Kept(own, steps, save_every)
    bar = Progress(int(steps), "steps", steps > length if progress is None else bool(progress))
    done = 0
    while done < steps:
        model, state, end, out, n_valid, grown = _run_grown(model, state, params, min(length, steps - done), length,
                                                            stop)
        info = out[-1]
        ok = np.asarray(info.converged)[:n_valid]
        failed = stop and not ok.all()
        n_ok = int(np.argmin(ok)) if failed else n_valid  # with stop: the steps before the first failure
        kept.add(jax.tree.map(lambda x: np.asarray(x)[:n_ok], out), done + 1, ok[:n_ok], np.zeros(n_ok, np.int64))
        bar.update(n_ok, iterations=int(np.asarray(info.iterations)[:n_valid].max()))
        state, done = end, done + n_ok
        if grown is not None:
            model, state = with_capacity(model, state, grown)
        if failed:  # step done + 1 did not converge; ``state`` is from before it
            if on_nonconvergence == "raise" or max_halvings < 1:
                raise _convergence_error(info, n_ok, done + 1, state, params, 0)
            model, state, row, depth = _subdivide(model, state, params, length, 1, max_halvings, done + 1)
            done += 1
            kept.add(jax.tree.map(lambda x: np.asarray(x)[None], row), done, np.ones(1, bool), np.array([depth]))
            bar.update(1, iterations=int(row[-1].iterations))
    bar.close()
    converged = np.concatenate(kept.converged)
    _warn_unconverged(converged, kept.worst, params)
    final, first = (jax.tree.map(jnp.asarray, unpad_state(s, own, shape)) for s in (state, start))
    return dataclasses.replace(_assemble(scene, kept.pieces, final, first), saved_steps=np.concatenate(kept.saved),
                               step_converged=converged, params=own.params, capacity=model.capacity,
                               halvings=np.concatenate(kept.halvings))


def _check_nonconvergence(on_nonconvergence: str, max_halvings: int) -> None:
    if on_nonconvergence not in ON_NONCONVERGENCE:
        raise ValueError(f"on_nonconvergence must be one of {', '.join(map(repr, ON_NONCONVERGENCE))}, "
                         f"got {on_nonconvergence!r}")
    if isinstance(max_halvings, bool) or int(max_halvings) != max_halvings or max_halvings < 0:
        raise ValueError(f"max_halvings must be a non-negative integer, got {max_halvings!r}")


def padded_scene(scene: Scene, params: Params | None, state: State | None):
    """(the scene run: its params and start state, contact memory re-padded to its
    capacity; its size class; that scene padded to it as model, state, params). Scenes of
    similar size share one compiled program (a notebook's edited scene, a suite's scenes)."""
    params = scene.params if params is None else params
    check_params(params)
    model, state = scene.model, (scene.state if state is None else state)
    if state.contact_key.shape[-1] != model.capacity.contacts:
        model, state = with_capacity(model, state, dataclasses.replace(
            model.capacity, contacts=max(model.capacity.contacts, state.contact_key.shape[-1])))
    own = dataclasses.replace(scene, model=model, state=state, params=params)
    shape = Shape.covering([own]).bucket()
    return (own, shape, *jax.tree.map(jnp.asarray, pad_scene(own, shape)))


class _Kept:
    """What a run keeps of its steps: the output of the saved ones (every ``save_every``-th
    and the last) with their numbers, and of every step its convergence and halvings, and
    the worst residual of those that did not converge."""

    def __init__(self, own: Scene, steps: int, save_every: int):
        self.own, self.steps, self.every, self.worst = own, steps, save_every, 0.0
        self.pieces, self.saved, self.converged, self.halvings = [], [np.zeros(1, np.int64)], [], []

    def add(self, out, first: int, ok: np.ndarray, halvings: np.ndarray) -> None:
        """Output rows ``out`` of the steps numbered ``first``, ``first`` + 1, ..."""
        number = first + np.arange(ok.size)
        keep = np.flatnonzero((number % self.every == 0) | (number == self.steps))
        self.pieces.append(_own_bodies(jax.tree.map(lambda x: x[keep], out), self.own))
        self.saved.append(number[keep])
        self.converged.append(ok)
        self.halvings.append(halvings)
        self.worst = max(self.worst, float(np.max(np.asarray(out[-1].residual), where=~ok, initial=0.0)))


def _run_grown(model, state, params, n_valid, length, stop):
    """One chunk of up to ``n_valid`` steps with its buffers regrown where they overflow.

    Returns (model, state, end, out, steps run, capacities to grow to after them or None)."""
    grown = None
    for _ in range(MAX_REGROW):
        programs.make_room()
        end, out = _run_chunk_jit(model, state, params, n_valid, length=length, stop=bool(stop))
        info = out[-1]
        overflow = np.asarray(info.overflow)[:n_valid]
        if not overflow.any():
            return model, state, end, out, n_valid, grown
        # Only the first overflowing step's counts come from a correct state. Growing from
        # them at that step (the capacities change the last bits of the results) makes the
        # run independent of where chunks begin: the steps before it are kept (run again
        # alone: the same program, the same bits), the rest run with the new capacities.
        first = int(np.argmax(overflow))
        grown = capacity_class(model.capacity.grown(Capacities(*np.asarray(info.needed)[first].tolist())))
        if first > 0:
            n_valid = first
            continue
        model, state = with_capacity(model, state, grown)
        grown = None
    raise CapacityError(f"contact buffers kept overflowing after {MAX_REGROW} regrowths "
                        f"(capacity {model.capacity})")


def _subdivide(model, state, params, length, depth, limit, number):
    """Step ``number`` (which did not converge at ``params.dt``) run again from ``state``
    as two steps of ``params.dt / 2``, each halved again where it does not converge, to
    ``limit`` halvings in all. Returns (model, the state at the step's end, its output row
    (``_merge``), the halvings its smallest sub-step took)."""
    half = dataclasses.replace(params, dt=params.dt / 2)
    rows, deepest, left = [], depth, 2
    while left:
        model, state, end, out, n_run, grown = _run_grown(model, state, half, left, length, True)
        ok = np.asarray(out[-1].converged)[:n_run]
        n_ok = n_run if ok.all() else int(np.argmin(ok))
        rows += [jax.tree.map(lambda x: np.asarray(x)[k], out) for k in range(n_ok)]
        state, left = end, left - n_ok
        if grown is not None:
            model, state = with_capacity(model, state, grown)
        if n_ok < n_run:  # this sub-step did not converge either
            if depth >= limit:
                raise _convergence_error(out[-1], n_ok, number, state, half, depth)
            model, state, row, sub = _subdivide(model, state, half, length, depth + 1, limit, number)
            rows.append(row)
            deepest, left = max(deepest, sub), left - 1
    return model, state, _merge(rows), deepest


def _warn_unconverged(converged: np.ndarray, worst: float, params: Params) -> None:
    """Warn once (NonConvergenceWarning) where steps of the run did not converge."""
    if converged.all():
        return
    first = int(np.argmin(converged)) + 1
    warnings.warn(
        f"{int((~converged).sum())} of {converged.size} steps did not converge (first: step {first}); worst relative "
        f"residual {worst:.3g} against tol {float(np.asarray(params.tol)):.3g} (max_iter "
        f"{int(np.asarray(params.max_iter))}). Their contact forces are the solver's best iterate: check "
        "Trajectory.step_converged, or run with on_nonconvergence=\"halve\" (or \"raise\"), a looser tol, a "
        "larger max_iter or a smaller dt", NonConvergenceWarning, stacklevel=3)


def _own_bodies(out, scene: Scene):
    """A chunk's output (time, centroid, rotation, velocity, stress, stretch, info) of a
    padded run, on the bodies, joints and connectors of ``scene`` only."""
    n, joints, connectors = scene.model.n_bodies, scene.model.joint_key.shape[0], scene.model.connector_a.shape[0]
    *cols, info = out
    info = dataclasses.replace(info, joint_tension=info.joint_tension[:, :joints],
                               joint_broken=info.joint_broken[:, :joints],
                               connector_force=info.connector_force[:, :connectors])
    return (cols[0], *(x[:, :n] for x in cols[1:]), info)


def _merge(rows):
    """The output row of a step run as sub-steps: the state and info at its end (the last
    sub-step's, with its contact report), iterations summed over the sub-steps, residual,
    penetration and buffer counts their worst."""
    infos = [r[-1] for r in rows]
    last = infos[-1]
    info = dataclasses.replace(
        last, iterations=np.sum([i.iterations for i in infos]).astype(last.iterations.dtype),
        residual=np.max([i.residual for i in infos]), converged=np.all([i.converged for i in infos]),
        overflow=np.any([i.overflow for i in infos]), needed=np.max([i.needed for i in infos], 0),
        max_penetration=np.max([i.max_penetration for i in infos]))
    return rows[-1][:-1] + (info,)


def _convergence_error(info, k: int, number: int, state: State, params: Params, halvings: int) -> ConvergenceError:
    """The error for step ``number`` whose solve (row ``k`` of a chunk's ``info``) did not
    converge, run from ``state`` at ``params.dt`` (``halvings`` times halved)."""
    residual, iterations = float(np.asarray(info.residual)[k]), int(np.asarray(info.iterations)[k])
    t, dt = float(np.asarray(state.time)), float(np.asarray(params.dt))
    how = "" if halvings == 0 else f" even at dt / {2 ** halvings} = {dt:.6g} s (max_halvings = {halvings})"
    return ConvergenceError(
        f"the contact solve of step {number} (from t = {t:.6g} s) did not converge{how}: relative residual "
        f"{residual:.3g} > tol {float(np.asarray(params.tol)):.3g} after {iterations} iterations (max_iter "
        f"{int(np.asarray(params.max_iter))} per solve, impact and contact). Raise max_iter or tol, reduce dt, or "
        f"run with on_nonconvergence=\"halve\" (or \"continue\" to go on and report it)",
        step=number, time=t, dt=dt, residual=residual, iterations=iterations)


def _pad_contacts(report: ContactReport, width: int) -> ContactReport:
    def pad(x):
        extra = width - x.shape[1]
        if extra == 0:
            return x
        fill = np.zeros((x.shape[0], extra) + x.shape[2:], x.dtype)
        return np.concatenate([x, fill], 1)

    return jax.tree.map(pad, report)


def _assemble(scene: Scene, pieces, final_state: State, s0: State) -> Trajectory:
    first = (np.asarray(s0.time)[None], np.asarray(s0.centroid)[None], np.asarray(s0.rotation)[None],
             np.asarray(s0.velocity)[None, :, :3], np.asarray(s0.stress)[None], np.asarray(s0.stretch)[None])
    k_info = len(first)
    width = max(p[k_info].contacts.valid.shape[1] for p in pieces)
    pieces = [p[:k_info] + (dataclasses.replace(p[k_info], contacts=_pad_contacts(p[k_info].contacts, width)),)
              for p in pieces]
    cols = [np.concatenate([f] + [p[k] for p in pieces]) for k, f in enumerate(first)]
    info = jax.tree.map(lambda *xs: np.concatenate(xs), *[p[k_info] for p in pieces])
    *cols, stretch = cols
    return Trajectory(scene, *cols, info, final_state, stretch)
