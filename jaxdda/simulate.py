"""Host driver: run a scene in jit-compiled chunks, regrow overflowing buffers, collect output."""
from __future__ import annotations

import dataclasses

import jax
import jax.numpy as jnp
import numpy as np

from jaxdda.errors import CapacityError
from jaxdda.progress import Progress
from jaxdda.scene.builder import Scene
from jaxdda.step import step
from jaxdda.types import Capacities, ContactReport, Model, Params, State, StepInfo

MAX_REGROW = 8


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

    def vertices(self) -> np.ndarray:
        """(S+1, bodies, V, 2): polygon vertices in the world frame at each step (padding
        entries and those of disks and rings are meaningless)."""
        stretch = np.broadcast_to(np.eye(2), self.rotation.shape + (2, 2)) if self.stretch is None else self.stretch
        local = np.einsum("snij,nvj->snvi", stretch, np.asarray(self.scene.model.local_vertices))
        c, s = np.cos(self.rotation)[..., None], np.sin(self.rotation)[..., None]
        x, y = local[..., 0], local[..., 1]
        return self.centroid[:, :, None, :] + np.stack([c * x - s * y, s * x + c * y], -1)

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


def _run_chunk(model: Model, state: State, params: Params, n_valid, length: int):
    """Scan ``length`` steps; steps at index >= n_valid are skipped (state unchanged,
    zero info), so every run of a scene shares one compilation whatever its length."""
    info_shape = jax.eval_shape(step, model, state, params)[1]

    def skip(s):
        return s, jax.tree.map(lambda x: jnp.zeros(x.shape, x.dtype), info_shape)

    def body(s, k):
        s2, info = jax.lax.cond(k < n_valid, lambda s: step(model, s, params), skip, s)
        return s2, (s2.time, s2.centroid, s2.rotation, s2.velocity[:, :3], s2.stress, s2.stretch, info)

    return jax.lax.scan(body, state, jnp.arange(length))


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


def simulate(scene: Scene, steps: int, *, params: Params | None = None, chunk: int = 1000, save_every: int = 1,
             progress: bool | None = None) -> Trajectory:
    """Run ``steps`` (>= 1) steps of ``scene`` and return the trajectory.

    Runs in jit-compiled chunks of ``chunk`` steps (one compilation per scene and chunk
    length, whatever ``steps``; the unused tail of the last chunk is skipped). When
    a buffer overflows in a chunk, its capacity is grown from the counts the step
    reported and the chunk is run again from its start, so no contact is ever lost.
    Raises CapacityError if that does not settle within a few regrowths.

    ``save_every=k`` keeps the state and step diagnostics of every k-th step only (and
    the last), so memory stays flat on long runs (``Trajectory.saved_steps`` numbers
    them). ``progress`` shows a bar with steps per second and the chunk's largest
    solver iteration count (None: when the run takes more than one chunk).
    """
    for name, value in (("steps", steps), ("chunk", chunk), ("save_every", save_every)):
        if isinstance(value, bool) or int(value) != value or value < 1:
            raise ValueError(f"{name} must be a positive integer, got {value!r}")
    params = scene.params if params is None else params
    model, state = scene.model, scene.state
    length = int(chunk)
    pieces, saved, converged, done = [], [np.zeros(1, np.int64)], [], 0
    bar = Progress(int(steps), "steps", steps > length if progress is None else bool(progress))
    while done < steps:
        n_valid = min(length, steps - done)
        for _ in range(MAX_REGROW):
            end, out = _run_chunk_jit(model, state, params, n_valid, length=length)
            info = out[-1]
            if not bool(np.any(np.asarray(info.overflow)[:n_valid])):
                break
            needed = Capacities(*np.asarray(info.needed)[:n_valid].max(0).tolist())
            model, state = with_capacity(model, state, model.capacity.grown(needed))
        else:
            raise CapacityError(f"contact buffers kept overflowing after {MAX_REGROW} regrowths "
                                f"(capacity {model.capacity})")
        number = done + 1 + np.arange(n_valid)
        keep = np.flatnonzero((number % save_every == 0) | (number == steps))
        pieces.append(jax.tree.map(lambda x: np.asarray(x)[keep], out))
        saved.append(number[keep])
        converged.append(np.asarray(info.converged)[:n_valid])
        bar.update(n_valid, iterations=int(np.asarray(info.iterations)[:n_valid].max()))
        state, done = end, done + n_valid
    bar.close()
    return dataclasses.replace(_assemble(scene, pieces, state), saved_steps=np.concatenate(saved),
                               step_converged=np.concatenate(converged), params=params)


def _pad_contacts(report: ContactReport, width: int) -> ContactReport:
    def pad(x):
        extra = width - x.shape[1]
        if extra == 0:
            return x
        fill = np.zeros((x.shape[0], extra) + x.shape[2:], x.dtype)
        return np.concatenate([x, fill], 1)

    return jax.tree.map(pad, report)


def _assemble(scene: Scene, pieces, final_state: State) -> Trajectory:
    s0 = scene.state
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
