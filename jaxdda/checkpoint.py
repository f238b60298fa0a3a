"""Checkpoints: a run's state saved to a file, and a restart that goes on bit-identically.

``save_checkpoint(path, traj)`` (or ``(path, scene, state, params)``) writes a numpy
``.npz`` that holds every array of the Model, State and Params (the contact memory that
warm-starts the solver and the integrity of cemented joints included), the Model's static
sizes, the step count, a format name and version, the jaxdda version and, for provenance,
the scene's name, body labels, material names, measured points and scene file (JSON).
``load_checkpoint(path)`` reads it back without executing code: ``numpy.load`` with
``allow_pickle=False`` (an object array is refused), and every array is checked against
the format (names, dtypes, shapes) before use. A restart needs nothing else::

    traj = jaxdda.simulate(scene, 500)
    save_checkpoint("run.ckpt.npz", traj)
    ck = load_checkpoint("run.ckpt.npz")
    more = jaxdda.simulate(ck.scene(), 500)        # == steps 500..1000 of a 1000-step run, bit for bit

``simulate(scene, steps, state=ck.state)`` also continues from it, but only with the
checkpoint's model (``ck.scene()``, or ``ck.scene(scene)`` to keep a scene's labels and
recipe) are the buffer capacities those the first run had grown, and the continuation
bit-identical (the capacities change the last bits of a step's results).

On CPU, bit-identical results across processes need ``--xla_cpu_multi_thread_eigen=false``
in ``XLA_FLAGS`` when jax starts, which ``import jaxdda`` adds (multi-threaded kernels vary
in the last bits on a busy machine; docs/design.md, "Checkpoints, restarts and determinism").
"""
from __future__ import annotations

import dataclasses
import io
import json
import os
import tempfile
import zipfile
import zlib
from pathlib import Path

import jax.numpy as jnp
import numpy as np

from jaxdda.types import Capacities, Model, Params, State, StepOptions

FORMAT = "jaxdda-checkpoint"
VERSION = 1

_F, _I32, _I64, _B = "float64", "int32", "int64", "bool"

# name -> (dtype, shape); the letters are sizes that must agree across arrays: N bodies,
# V vertices per polygon, L loads, T knots of a load history, J cemented joints, K
# connectors, P fixed points, G dof groups, S group slots, R reduced dofs, M materials,
# C the contact capacity.
_MODEL = {
    "kind": (_I32, "N"), "fixed": (_B, "N"), "radius": (_F, "N"), "inner_radius": (_F, "N"),
    "local_vertices": (_F, "NV2"), "vertex_mask": (_B, "NV"), "edge_mask": (_B, "NV"), "edge_material": (_I32, "NV"),
    "n_vertices": (_I32, "N"), "area": (_F, "N"), "polar_moment": (_F, "N"), "second_moment": (_F, "N3"),
    "plane_strain": (_B, "N"), "bound_radius": (_F, "N"), "gravity_scale": (_F, "N"), "material": (_I32, "N"),
    "dof_projector": (_F, "N66"), "dof_basis": (_F, "N66"), "mesh": (_I32, "N"),
    "load_body": (_I32, "L"), "load_point": (_F, "L2"), "load_times": (_F, "LT"),
    "joint_key": (_I64, "J"), "joint_a": (_I32, "J"), "joint_b": (_I32, "J"), "joint_point": (_F, "J2"),
    "connector_kind": (_I32, "K"), "connector_a": (_I32, "K"), "connector_b": (_I32, "K"),
    "connector_pa": (_F, "K2"), "connector_pb": (_F, "K2"), "connector_length": (_F, "K"),
    "connector_chord0": (_F, "K2"), "pin_body": (_I32, "P"), "pin_point": (_F, "P2"), "pin_role": (_I32, "P"),
    "group_members": (_I32, "GS"), "group_dofs": (_I32, "GS6"), "group_free": (_B, "GR"),
    "body_group": (_I32, "N"), "body_slot": (_I32, "N"),
}
_PARAMS = {
    "dt": (_F, ""), "gravity": (_F, "2"), "density": (_F, "N"), "young": (_F, "N"), "poisson": (_F, "N"),
    "friction": (_F, "MM"), "restitution": (_F, "MM"), "cohesion": (_F, "MM"), "rolling": (_F, "MM"),
    "tensile": (_F, "MM"), "load_force": (_F, "L2"), "load_rate": (_F, "L2"), "load_history": (_F, "LT2"),
    "dynamic": (_F, ""), "tol": (_F, ""), "max_iter": (_F, ""), "margin": (_F, ""), "rupture_width": (_F, ""),
    "connector_axial": (_F, "K"), "connector_bending": (_F, "K"), "connector_shear": (_F, "K"),
    "connector_pretension": (_F, "K"),
}
_STATE = {
    "time": (_F, ""), "origin": (_F, "N2"), "displacement": (_F, "N2"), "rotation": (_F, "N"),
    "velocity": (_F, "N6"), "stretch": (_F, "N22"), "stress": (_F, "N3"), "contact_key": (_I64, "C"),
    "contact_force": (_F, "C3"), "joint_integrity": (_F, "J"),
}
_GROUPS = (("model", Model, _MODEL), ("state", State, _STATE), ("params", Params, _PARAMS))
# Other arrays: (dtype kind, ndim); "U" a string. Optional ones may be absent.
_META = {"format": ("U", 0), "version": ("i", 0), "jaxdda_version": ("U", 0), "step": ("i", 0),
         "model.capacity": ("i", 1), "model.n_bodies": ("i", 0), "model.max_vertices": ("i", 0),
         "scene.name": ("U", 0), "scene.labels": ("U", 1), "scene.materials": ("U", 1),
         "scene.measured_body": ("i", 1), "scene.measured_point": ("f", 2)}
_OPTIONAL = {"scene.file": ("U", 0), "model.options": ("U", 0)}  # (absent: none, the default options)

for _group, _cls, _spec in _GROUPS:  # the format covers every leaf of the three types
    assert set(_spec) == {f.name for f in dataclasses.fields(_cls) if not f.metadata.get("static")}, _group


class CheckpointError(ValueError):
    """A checkpoint file is not one this version can read, or is damaged; or what was
    to be saved is not a consistent model, state and parameters."""


@dataclasses.dataclass(frozen=True)
class Checkpoint:
    """A loaded checkpoint: ``simulate(ck.scene(), steps)`` continues the run."""

    model: Model
    state: State
    params: Params
    step: int  # steps run to reach ``state`` (as the saver counted them)
    name: str
    labels: tuple[str, ...]
    materials: tuple[str, ...]
    measured: tuple
    scene_file: str | None  # the scene file (JSON text) the run was made from, if it had one
    jaxdda_version: str
    version: int = VERSION

    @property
    def time(self) -> float:
        return float(self.state.time)

    def scene(self, base=None):
        """A Scene to continue from: the checkpoint's model (with its grown capacities),
        state and parameters, with the labels, materials and measured points of ``base``
        (a Scene of the same bodies: a check) or, without one, those saved (and the
        recipe of the saved scene file, so the scene can be written out again)."""
        from jaxdda.scene.builder import Scene

        if base is not None:
            if base.model.n_bodies != self.model.n_bodies or len(base.materials) != len(self.materials):
                raise CheckpointError(f"the checkpoint holds {self.model.n_bodies} bodies and {len(self.materials)} "
                                      f"materials, scene {base.name!r} {base.model.n_bodies} and "
                                      f"{len(base.materials)}: not the scene it was saved from")
            return dataclasses.replace(base, model=self.model, state=self.state, params=self.params)
        recipe = ()
        if self.scene_file is not None:
            from jaxdda.scene.loader import scene_from_dict

            recipe = scene_from_dict(json.loads(self.scene_file), "checkpoint's scene file")[0].recipe
        return Scene(self.model, self.state, self.params, self.labels, self.materials, self.name, recipe=recipe,
                     measured=self.measured)


def save_checkpoint(path, source, state: State | None = None, params: Params | None = None, *,
                    step: int | None = None) -> Path:
    """Write a checkpoint to ``path`` (a ``.npz``; written whole or not at all).

    ``source``: a Trajectory (its scene, final state, parameters, grown capacities and
    step count), or a Scene (``state`` default ``scene.state``, ``params`` default
    ``scene.params``), or a Model (``state`` and ``params`` needed). ``step``: the steps
    run to reach the state (default: the trajectory's, else 0).
    """
    from jaxdda.scene.builder import Scene
    from jaxdda.simulate import Trajectory

    scene = None
    if isinstance(source, Trajectory):
        scene = source.scene
        model = scene.model if source.capacity is None else dataclasses.replace(scene.model, capacity=source.capacity)
        state = source.final_state if state is None else state
        params = (source.params or scene.params) if params is None else params
        step = source.steps if step is None else step
    elif isinstance(source, Scene):
        scene, model = source, source.model
        state = source.state if state is None else state
        params = source.params if params is None else params
    elif isinstance(source, Model):
        model = source
        if state is None or params is None:
            raise CheckpointError("save_checkpoint(path, model, state, params): a model needs its state and params")
    else:
        raise CheckpointError(f"save_checkpoint: expected a Trajectory, Scene or Model, got {type(source).__name__}")
    if np.shape(state.contact_key)[-1] != model.capacity.contacts:
        raise CheckpointError(f"the state's contact memory holds {np.shape(state.contact_key)[-1]} slots, the model's "
                              f"contact capacity is {model.capacity.contacts}: save the Trajectory (it knows the "
                              "capacities its run grew to) or pass a model with them")
    arrays = {"format": np.array(FORMAT), "version": np.array(VERSION, np.int64),
              "jaxdda_version": np.array(_jaxdda_version()), "step": np.array(0 if step is None else int(step), np.int64),
              "model.capacity": np.array(dataclasses.astuple(model.capacity), np.int64),
              "model.n_bodies": np.array(model.n_bodies, np.int64),
              "model.max_vertices": np.array(model.max_vertices, np.int64),
              "model.options": np.array(json.dumps(dataclasses.asdict(model.options)))}
    for group, _, spec in _GROUPS:
        obj = {"model": model, "state": state, "params": params}[group]
        for name in spec:
            arrays[f"{group}.{name}"] = np.asarray(getattr(obj, name))
    n = model.n_bodies
    labels = tuple(scene.labels) if scene is not None else tuple(f"body {i}" for i in range(n))
    materials = tuple(scene.materials) if scene is not None else tuple(f"material {i}" for i in
                                                                       range(np.shape(params.friction)[0]))
    measured = tuple(scene.measured) if scene is not None else ()
    arrays.update({"scene.name": np.array(scene.name if scene is not None else "scene"),
                   "scene.labels": np.array(labels, dtype=str).reshape(-1),
                   "scene.materials": np.array(materials, dtype=str).reshape(-1),
                   "scene.measured_body": np.array([b for b, _ in measured], np.int64),
                   "scene.measured_point": np.array([p for _, p in measured], float).reshape(-1, 2)})
    if scene is not None and scene.recipe:
        from jaxdda.scene.io import scene_to_dict

        arrays["scene.file"] = np.array(json.dumps(scene_to_dict(scene)))
    _check(arrays, "the checkpoint to save")  # what is written reads back
    path = Path(path)
    buffer = io.BytesIO()
    np.savez_compressed(buffer, **arrays)
    fd, tmp = tempfile.mkstemp(prefix=path.name + ".", suffix=".tmp", dir=path.resolve().parent)
    try:
        with os.fdopen(fd, "wb") as f:
            f.write(buffer.getvalue())
        os.replace(tmp, path)
    except BaseException:
        if os.path.exists(tmp):
            os.unlink(tmp)
        raise
    return path


def load_checkpoint(path) -> Checkpoint:
    """Read a checkpoint written by ``save_checkpoint``; CheckpointError if it is not
    one (unknown format or version, missing, extra or malformed arrays, or arrays that
    would need pickle, which is never used)."""
    where = f"checkpoint {path}"
    try:
        data = np.load(path, allow_pickle=False)
    except FileNotFoundError:
        raise
    except (ValueError, OSError, EOFError, zipfile.BadZipFile) as err:  # pickled data is a ValueError
        raise CheckpointError(f"{where}: not a readable .npz checkpoint ({err})") from None
    if not isinstance(data, np.lib.npyio.NpzFile):
        raise CheckpointError(f"{where}: not a checkpoint (a single .npy array, not an .npz archive)")
    arrays = {}
    with data:
        for key in data.files:
            try:
                arrays[key] = data[key]
            except ValueError as err:  # an object array: "cannot be loaded when allow_pickle=False"
                raise CheckpointError(f"{where}: array {key!r} cannot be read without pickle (Python objects); "
                                      f"refused ({err})") from None
            except (OSError, EOFError, zipfile.BadZipFile, zlib.error) as err:
                raise CheckpointError(f"{where}: array {key!r} is damaged ({err})") from None
    sizes = _check(arrays, where)
    capacity = Capacities(*(int(x) for x in arrays["model.capacity"]))
    n_bodies, max_vertices = int(arrays["model.n_bodies"]), int(arrays["model.max_vertices"])
    if n_bodies != sizes["N"] or max_vertices != sizes["V"] or capacity.contacts != sizes["C"]:
        raise CheckpointError(f"{where}: its sizes disagree: n_bodies {n_bodies}, max_vertices {max_vertices}, "
                              f"contact capacity {capacity.contacts}, but the arrays hold {sizes['N']} bodies, "
                              f"{sizes['V']} vertices, {sizes['C']} contact slots")
    leaves = {group: {name: jnp.asarray(arrays[f"{group}.{name}"]) for name in spec} for group, _, spec in _GROUPS}
    model = Model(**leaves["model"], capacity=capacity, n_bodies=n_bodies, max_vertices=max_vertices,
                  options=_options(arrays, where))
    measured = tuple((int(b), np.asarray(p, float)) for b, p in
                     zip(arrays["scene.measured_body"], arrays["scene.measured_point"]))
    scene_file = str(arrays["scene.file"]) if "scene.file" in arrays else None
    return Checkpoint(model, State(**leaves["state"]), Params(**leaves["params"]), int(arrays["step"]),
                      str(arrays["scene.name"]), tuple(str(x) for x in arrays["scene.labels"]),
                      tuple(str(x) for x in arrays["scene.materials"]), measured, scene_file,
                      str(arrays["jaxdda_version"]), int(arrays["version"]))


def _options(arrays: dict, where: str) -> StepOptions:
    """The step options a checkpoint was saved with (the defaults where it has none)."""
    if "model.options" not in arrays:
        return StepOptions()
    try:
        return StepOptions(**json.loads(str(arrays["model.options"])))
    except (ValueError, TypeError) as err:
        raise CheckpointError(f"{where}: array 'model.options' is not a set of step options ({err})") from None


def _check(arrays: dict, where: str) -> dict:
    """Check names, dtypes and shapes; return the sizes (N, V, C, ...) they agree on."""
    for key in ("format", "version"):
        if key not in arrays:
            raise CheckpointError(f"{where}: not a jaxdda checkpoint (no {key!r} entry)")
    if arrays["format"].dtype.kind != "U" or arrays["format"].shape != () or str(arrays["format"]) != FORMAT:
        raise CheckpointError(f"{where}: not a jaxdda checkpoint (format {arrays['format']!r})")
    version = arrays["version"]
    if version.dtype.kind not in "iu" or version.shape != () or int(version) != VERSION:
        raise CheckpointError(f"{where}: checkpoint format version {version.tolist()!r}; this jaxdda "
                              f"({_jaxdda_version()}) reads version {VERSION} only")
    expected = {f"{g}.{name}" for g, _, spec in _GROUPS for name in spec} | set(_META)
    missing = sorted(expected - set(arrays))
    extra = sorted(set(arrays) - expected - set(_OPTIONAL))
    if missing or extra:
        raise CheckpointError(f"{where}: " + "; ".join(
            ([f"missing arrays: {', '.join(missing)}"] if missing else [])
            + ([f"unknown arrays: {', '.join(extra)}"] if extra else [])))
    for key, (kind, ndim) in {**_META, **_OPTIONAL}.items():
        if key in arrays:
            a = arrays[key]
            if a.dtype.kind != kind or a.ndim != ndim:
                raise CheckpointError(f"{where}: array {key!r} is {a.dtype} of shape {a.shape}, expected "
                                      f"{'a string' if kind == 'U' else {'i': 'integer', 'f': 'float'}[kind]} "
                                      f"of {ndim} dimensions")
    if arrays["model.capacity"].shape != (len(dataclasses.fields(Capacities)),):
        raise CheckpointError(f"{where}: 'model.capacity' has shape {arrays['model.capacity'].shape}, expected "
                              f"({len(dataclasses.fields(Capacities))},)")
    sizes: dict[str, int] = {}
    for group, _, spec in _GROUPS:
        for name, (dtype, dims) in spec.items():
            key, a = f"{group}.{name}", arrays[f"{group}.{name}"]
            if a.dtype != np.dtype(dtype):
                raise CheckpointError(f"{where}: array {key!r} has dtype {a.dtype}, expected {dtype}")
            if a.ndim != len(dims):
                raise CheckpointError(f"{where}: array {key!r} has shape {a.shape}, expected {len(dims)} dimensions")
            for axis, (dim, size) in enumerate(zip(dims, a.shape)):
                want = int(dim) if dim.isdigit() else sizes.setdefault(dim, size)
                if size != want:
                    raise CheckpointError(f"{where}: array {key!r} has shape {a.shape}: axis {axis} should be {want} "
                                          f"(size {dim} of the other arrays)")
    n_measured = arrays["scene.measured_body"].shape[0]
    if arrays["scene.measured_point"].shape != (n_measured, 2) or arrays["scene.labels"].shape != (sizes["N"],) \
            or arrays["scene.materials"].shape != (sizes["M"],):
        raise CheckpointError(f"{where}: the scene's labels, materials or measured points do not fit its arrays")
    return sizes


def _jaxdda_version() -> str:
    import jaxdda

    return getattr(jaxdda, "__version__", "unknown")
