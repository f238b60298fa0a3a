"""Checkpoint and restart: a run broken at a checkpoint file goes on bit-identically; files
are read without executing code. Determinism: the same inputs give the same bits, after
recompiling and in a fresh process (issue 9, items 5 and 6)."""
import dataclasses
import hashlib
import os
import pickle
import subprocess
import sys
from pathlib import Path

import jax
import numpy as np
import pytest

import jaxdda
from jaxdda.checkpoint import VERSION, CheckpointError, load_checkpoint, save_checkpoint
from jaxdda.cli import main
from jaxdda.simulate import with_capacity

STEPS, HALF, CHUNK = 40, 20, 40  # the checkpoint falls inside the unbroken run's one chunk
ROOT = Path(__file__).resolve().parents[1]


def restart_scene():
    """Friction, a cemented block pulled off the base (its joints break at step 6), a disk
    tied to a deformable block by a spring, and two disks that land at step 25, after the
    checkpoint; the contact buffer is cut to the first step's needs, so it overflows and
    regrows when they land (the capacities then differ from those at the checkpoint)."""
    sb = jaxdda.SceneBuilder(dt=2e-3, gravity=(0.0, -9.81), name="restart")
    sb.add_material("rock", friction=0.5, restitution=0.0)
    sb.add_material("cement", friction=0.5, restitution=0.0, tensile=2000.0)
    sb.add_polygon([(-4, -1), (4, -1), (4, 0), (-4, 0)], density=2600, fixed=True, material="cement")
    block = sb.add_polygon([(1, 0), (2, 0), (2, 1), (1, 1)], density=1000, material="cement")
    sb.add_load(block, force=(0.0, 9810.0), rate=(0.0, 2e5))
    disk = sb.add_disk(center=(-2, 0.54), radius=0.5, density=2600, velocity=(1.0, -0.5), material="rock")
    soft = sb.add_polygon([(-0.5, 0.0), (0.5, 0.0), (0.5, 0.6), (-0.5, 0.6)], density=2000, young=1e8, poisson=0.25,
                          material="rock")
    sb.add_spring(disk, soft, (-2, 0.54), (-0.5, 0.3), 1e5)
    sb.add_disk(center=(3, 0.44), radius=0.4, density=2600, velocity=(-0.5, -0.5), material="rock")
    sb.add_disk(center=(-3.3, 0.34), radius=0.3, density=2600, velocity=(0.0, -0.5), material="rock")
    scene = sb.build()
    model, state = with_capacity(scene.model, scene.state, dataclasses.replace(scene.model.capacity, contacts=4))
    return dataclasses.replace(scene, model=model, state=state)


def leaves(traj):
    """Every array of a trajectory and its final state, by name."""
    out = {f: getattr(traj, f) for f in ("time", "centroid", "rotation", "velocity", "stress", "stretch",
                                          "step_converged")}
    out.update({f"info.{k}": v for k, v in _flat(traj.info).items()})
    out.update({f"state.{k}": np.asarray(v) for k, v in _flat(traj.final_state).items()})
    return out


def _flat(tree):
    paths, _ = jax.tree_util.tree_flatten_with_path(tree)
    return {jax.tree_util.keystr(p): np.asarray(x) for p, x in paths}


def digest(traj) -> str:
    """sha256 of every array's name, dtype, shape and bytes."""
    h = hashlib.sha256()
    for name, a in sorted(leaves(traj).items()):
        a = np.ascontiguousarray(a)
        h.update(f"{name} {a.dtype.str} {a.shape}".encode())
        h.update(a.tobytes())
    return h.hexdigest()


# XLA CPU's multi-threaded Eigen kernels give different last bits from one run to another
# when the machine is busy (seen here: 1e-19 m, 1e-11 Pa); single-threaded, they do not, and
# importing jaxdda turns them off (docs/design.md, "Checkpoints, restarts and determinism").
# So the runs happen in fresh processes with XLA_FLAGS as a user has them: unset.


def worker(folder: str, full: bool) -> None:
    """Run in a fresh process: 20 steps, a checkpoint file, 20 more from it; with ``full``
    also the unbroken 40 steps. Writes the arrays and digests to ``folder``."""
    import json

    folder = Path(folder)
    scene = restart_scene()
    first = jaxdda.simulate(scene, HALF, chunk=CHUNK, progress=False)
    save_checkpoint(folder / "half.npz", first)
    ck = load_checkpoint(folder / "half.npz")
    runs = {"first": first, "rest": jaxdda.simulate(ck.scene(), STEPS - HALF, chunk=CHUNK, progress=False)}
    if full:
        runs["whole"] = jaxdda.simulate(scene, STEPS, chunk=CHUNK, progress=False)
    for name, traj in runs.items():
        np.savez(folder / f"{name}.npz", capacity=np.array(dataclasses.astuple(traj.capacity)),
                 **{k.replace("/", "|"): v for k, v in leaves(traj).items()})
    (folder / "digests.json").write_text(json.dumps({name: digest(traj) for name, traj in runs.items()}))


def _load(path):
    with np.load(path, allow_pickle=False) as data:
        return {k.replace("|", "/"): data[k] for k in data.files}


@pytest.fixture(scope="module")
def runs(tmp_path_factory):
    """Two fresh processes at once: the full set of runs, and a second process's own."""
    import json

    folders = [tmp_path_factory.mktemp(name) for name in ("full", "second")]
    # each process compiles its own programs: no XLA flags, no shared compilation cache
    env = ({k: v for k, v in os.environ.items() if k not in ("XLA_FLAGS", "JAX_COMPILATION_CACHE_DIR")}
           | {"PYTHONPATH": str(ROOT)})
    procs = [subprocess.Popen([sys.executable, "-c", f"from tests.test_checkpoint import worker; "
                                                     f"worker({str(folder)!r}, {full})"],
                              cwd=ROOT, env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
             for folder, full in zip(folders, (True, False))]
    try:
        for proc in procs:
            _, err = proc.communicate(timeout=1200)
            assert proc.returncode == 0, err[-3000:]
    finally:
        for proc in procs:
            if proc.poll() is None:
                proc.kill()
    full, second = folders
    out = {name: _load(full / f"{name}.npz") for name in ("first", "rest", "whole")}
    out["second"] = _load(second / "rest.npz")
    out["digests"] = json.loads((full / "digests.json").read_text())
    out["second_digests"] = json.loads((second / "digests.json").read_text())
    out["path"], out["second_path"] = full / "half.npz", second / "half.npz"
    return out


def test_restart_from_a_checkpoint_file_is_bit_identical(runs):
    scene, ck = restart_scene(), load_checkpoint(runs["path"])
    first, rest, whole = runs["first"], runs["rest"], runs["whole"]
    cap = lambda run: jaxdda.types.Capacities(*run["capacity"].tolist())
    # the scene does what it should: joints broken before the checkpoint, a regrowth after it
    assert np.all(np.asarray(scene.state.joint_integrity)[:2] == 1) and len(np.asarray(scene.model.joint_key)) >= 2
    assert np.all(np.asarray(ck.state.joint_integrity)[:2] == 0)
    assert ck.model.capacity == cap(first) == scene.model.capacity
    assert cap(whole).contacts > scene.model.capacity.contacts and cap(rest) == cap(whole)
    assert whole["step_converged"].all() and whole["info..n_contacts"].max() == 5
    assert np.any(np.asarray(ck.state.contact_key) >= 0)  # warm-start memory carried over
    assert ck.step == HALF and ck.name == "restart" and ck.labels == scene.labels and ck.scene_file is not None
    # the checkpoint holds the final state exactly
    for k, v in _flat(ck.state).items():
        assert np.array_equal(v, first[f"state.{k}"]) and v.dtype == first[f"state.{k}"].dtype, k
    # the resumed run equals the second half of the unbroken run, bit for bit
    expected = {k: v if k.startswith("state.") or k == "capacity" else v[HALF:] for k, v in whole.items()}
    assert expected.keys() == rest.keys()
    for k in expected:
        assert expected[k].shape == rest[k].shape and np.array_equal(expected[k], rest[k]), k
    # the saved scene file rebuilds the recipe; a scene of the same bodies lends its own
    assert ck.scene().recipe and ck.scene(scene).labels == scene.labels


def test_same_inputs_same_bits_in_a_fresh_process(runs):
    """The run again in a second process (its own compilations, its own checkpoint file):
    the same bytes."""
    assert runs["digests"]["rest"] == runs["second_digests"]["rest"]
    for k, v in runs["rest"].items():
        assert np.array_equal(v, runs["second"][k]), k
    a, b = _load(runs["path"]), _load(runs["second_path"])
    assert a.keys() == b.keys() and all(np.array_equal(a[k], b[k]) for k in a)


def _tamper(src, dst, **changes):
    with np.load(src, allow_pickle=False) as data:
        arrays = {k: data[k] for k in data.files}
    for k, v in changes.items():
        key = k.replace("__", ".")
        if v is None:
            del arrays[key]
        else:
            arrays[key] = v
    np.savez(dst, **arrays)
    return dst


class _Payload:
    """Unpickling this creates the file ``marker``: proof that a load executed code."""

    def __init__(self, marker):
        self.marker = marker

    def __reduce__(self):
        return (open, (self.marker, "w"))


def test_unknown_damaged_or_pickled_checkpoints_are_refused(runs, tmp_path):
    scene, path = restart_scene(), runs["path"]
    ck = load_checkpoint(path)
    state = ck.state
    cases = {
        "version": (dict(version=np.array(VERSION + 1)), "version 2"),
        "format": (dict(format=np.array("something-else")), "not a jaxdda checkpoint"),
        "missing": (dict(state__joint_integrity=None), "missing arrays: state.joint_integrity"),
        "extra": (dict(state__spare=np.zeros(3)), "unknown arrays: state.spare"),
        "dtype": (dict(state__contact_key=np.asarray(state.contact_key, float)), "'state.contact_key' has dtype"),
        "shape": (dict(state__velocity=np.zeros((scene.n_bodies + 1, 6))), "'state.velocity' has shape"),
        "capacity": (dict(model__capacity=np.array([1, 2, 3, 4, 99])), "contact capacity 99"),
    }
    for name, (changes, message) in cases.items():
        bad = _tamper(path, tmp_path / f"{name}.npz", **changes)
        with pytest.raises(CheckpointError, match=message):
            load_checkpoint(bad)
    # an object array (pickle) is never unpickled: the payload would create ``marker``
    marker = tmp_path / "unpickled"
    payload = np.empty(1, object)
    payload[0] = _Payload(str(marker))
    for name, bad in (("object", _tamper(path, tmp_path / "object.npz", scene__name=payload)),
                      ("pickle", tmp_path / "pickle.npz")):
        if name == "pickle":
            bad.write_bytes(pickle.dumps(_Payload(str(marker))))
        with pytest.raises(CheckpointError, match="pickle"):
            load_checkpoint(bad)
    assert not marker.exists()
    np.save(tmp_path / "array.npy", np.zeros(3))
    with pytest.raises(CheckpointError, match="not a checkpoint"):
        load_checkpoint(tmp_path / "array.npy")
    # saving checks too: a state whose contact memory does not fit the model's capacity
    with pytest.raises(CheckpointError, match="contact capacity"):
        save_checkpoint(tmp_path / "x.npz", scene, state=dataclasses.replace(
            state, contact_key=np.zeros(7, np.int64), contact_force=np.zeros((7, 3))))
    # and a checkpoint of another scene
    with pytest.raises(CheckpointError, match="not the scene it was saved from"):
        ck.scene(jaxdda.examples.get("paper-7.8"))


def test_cli_resume_refuses_a_bad_checkpoint(runs, tmp_path, capsys):
    path = runs["path"]
    bad = _tamper(path, tmp_path / "bad.npz", version=np.array(99))
    assert main(["run", "paper-7.8", "--steps", "1", "--resume", str(bad), "--quiet"]) == 2
    assert "version 99" in capsys.readouterr().err
    assert main(["run", "paper-7.8", "--steps", "1", "--resume", str(path), "--quiet"]) == 2
    assert "not the scene it was saved from" in capsys.readouterr().err
