"""Fuzzing random scenes for 1 000 000 scene-steps (issue 9).

    python experiments/fuzz.py [--scene-steps 1000000] [--batch 32] [--steps 50] [--start 0]
                               [--out experiments/results/fuzz.json] [--hours H] [--resume] [--workers N]

Scene k is drawn from ``numpy.random.default_rng(start + k)`` by the generator of
``tests/test_fuzz.py`` (disks, rings holding bodies, convex and concave polygons; random
velocities, spins, materials, densities over 1e0..1e6; gravity in a fixed box, or a free
system without gravity) and runs ``--steps`` steps, scene by scene through one
compiled program (``fz.run_batch``), in batches of ``--batch`` scenes between writes of
the record, shared by ``--workers`` processes. The invariants of every step are those
of the test (finite state, penetration within the bound of the step's motion, energy
never growing beyond round-off and the solve's tolerance, linear momentum of free scenes
to round-off); each pose every 25 steps is also checked for overlaps on the host.

Writes ``--out`` after every batch: scenes, steps, scene-steps, failures (per invariant
and in all), the seeds of the failing scenes with what they broke and the step it first
broke at, non-converged steps, rates; and a TOML reproducer of each failing scene in
``experiments/results/fuzz_failures/seed_<seed>.toml`` (``jaxdda run FILE``).

The run can be split over sittings: ``--hours H`` stops after the batch that passes H
hours, and ``--resume`` continues the record in ``--out`` from its next seed. A record
holds the SHA-256 of the engine and of the fuzz generator (``jaxdda/**/*.py``,
``tests/test_fuzz.py``) and resumes only against the same code, so one record is one
engine's count.
"""
from __future__ import annotations

import argparse
import hashlib
import json
import multiprocessing
import os
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

import numpy as np  # noqa: E402

from tests import test_fuzz as fz  # noqa: E402

KINDS = ("non-finite", "penetration", "host-checked overlap", "energy", "momentum")


def kind_of(message: str) -> str:
    for k in KINDS:
        if message.startswith(k) or (k == "non-finite" and "non-finite" in message):
            return k
    return "other"


def code_hash() -> str:
    """SHA-256 of the engine's and the generator's source, in path order."""
    h = hashlib.sha256()
    for path in sorted((ROOT / "jaxdda").rglob("*.py")) + [ROOT / "tests" / "test_fuzz.py"]:
        h.update(str(path.relative_to(ROOT)).encode() + b"\0" + path.read_bytes() + b"\0")
    return h.hexdigest()


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scene-steps", type=int, default=None, help="target (1 000 000; with --resume, a new target)")
    ap.add_argument("--batch", type=int, default=32)
    ap.add_argument("--steps", type=int, default=fz.STEPS)
    ap.add_argument("--start", type=int, default=0, help="seed of the first scene")
    ap.add_argument("--sample", type=int, default=25, help="host overlap check every this many steps")
    ap.add_argument("--out", default=str(ROOT / "experiments" / "results" / "fuzz.json"))
    ap.add_argument("--hours", type=float, default=float("inf"), help="stop after the batch that passes this")
    ap.add_argument("--resume", action="store_true", help="continue the record in --out (same code only)")
    ap.add_argument("--workers", type=int, default=1, help="processes sharing each batch, each scene run alone "
                    "in one of them through its copy of the program")
    args = ap.parse_args(argv)
    out = Path(args.out).resolve()
    ratio_file = out.with_name(out.stem + "_energy_ratios.npy")
    failures_dir = out.parent / "fuzz_failures"
    failures_dir.mkdir(parents=True, exist_ok=True)
    command = " ".join(["python", "experiments/fuzz.py"] + (argv or sys.argv[1:]))
    if args.resume:
        record = json.loads(out.read_text())
        if record["code_sha256"] != code_hash():
            raise SystemExit(f"{out} counts another version of jaxdda/ or tests/test_fuzz.py; start a new record")
        if (record["batch"], record["steps_per_scene"]) != (args.batch, args.steps):
            raise SystemExit(f"{out} ran --batch {record['batch']} --steps {record['steps_per_scene']}")
        if args.scene_steps is not None:
            record["target_scene_steps"] = args.scene_steps
        return run(args, record, np.load(ratio_file).tolist(), out, ratio_file, failures_dir, command)
    for stale in failures_dir.glob("seed_*.toml"):  # reproducers of the record this one replaces
        stale.unlink()
    record = {"command": command, "code_sha256": code_hash(), "sittings": [],
              "batch": args.batch, "steps_per_scene": args.steps, "target_scene_steps": args.scene_steps or 1_000_000,
              "start_seed": args.start, "next_seed": args.start, "cpus": os.cpu_count(),
              "scenes": 0, "steps": 0, "scene_steps": 0, "failures": 0,
              "failures_by_invariant": {k: 0 for k in KINDS}, "failing": [],
              "scenes_by_kind": {"box": 0, "free": 0}, "nonconverged_steps": 0, "scenes_with_nonconverged": 0,
              "max_iterations": 0, "max_pen_ratio": 0.0, "max_pen_rel": 0.0,
              "max_energy_ratio": 0.0, "max_energy_growth": 0.0, "max_momentum_ratio": 0.0,
              "max_angular_rel": 0.0, "energy_ratio_quantiles": {},
              "seconds": 0.0, "compile_and_first_batch_s": None, "scene_steps_per_s": None, "done": False}
    return run(args, record, [], out, ratio_file, failures_dir, command)


def _check(seeds, steps: int, sample: int):
    """Run and check the scenes of ``seeds``: their accumulators and (index, broken) failures."""
    scenes = [fz.build(fz.draw_spec(fz.RngDraw(s))) for s in seeds]
    acc, poses, _ = fz.run_batch(scenes, steps, sample=sample)
    return acc, fz.check_batch(scenes, acc, poses, steps)


def run_seeds(seeds, steps: int, sample: int, pool=None, workers: int = 1):
    """``_check`` over a batch, split into contiguous shares over the pool's ``workers``
    processes (each compiles the program once) or in this process; results in seed order."""
    if pool is None:
        return _check(seeds, steps, sample)
    shares = [share for i in range(workers) if (share := seeds[len(seeds) * i // workers:
                                                              len(seeds) * (i + 1) // workers])]
    parts = pool.starmap(_check, [(share, steps, sample) for share in shares])
    acc = {k: np.concatenate([part[k] for part, _ in parts]) for k in parts[0][0]}
    bad, offset = [], 0
    for (_, broken_of), share in zip(parts, shares):
        bad += [(offset + i, broken) for i, broken in broken_of]
        offset += len(share)
    return acc, bad


def run(args, record, ratios, out, ratio_file, failures_dir, command) -> int:
    """Batches from ``record['next_seed']`` until the target or ``--hours``; writes after each."""
    pool = None
    if args.workers > 1:  # JAX does not survive fork: spawned processes
        pool = multiprocessing.get_context("spawn").Pool(args.workers)
    t0 = time.perf_counter()
    seed = record["next_seed"]
    sitting = {"command": command, "first_seed": seed, "scene_steps": 0, "seconds": 0.0,
               "compile_and_first_batch_s": None, "scene_steps_per_s": None}
    seconds_before = record["seconds"]
    while record["scene_steps"] < record["target_scene_steps"] and (time.perf_counter() - t0) < 3600 * args.hours:
        if not sitting["scene_steps"]:
            record["sittings"].append(sitting)
        tb = time.perf_counter()
        seeds = list(range(seed, seed + args.batch))
        specs = [fz.draw_spec(fz.RngDraw(s)) for s in seeds]
        acc, bad = run_seeds(seeds, args.steps, args.sample, pool, args.workers)
        seed += args.batch
        record["next_seed"] = seed
        sitting["scene_steps"] += len(seeds) * args.steps
        record["scenes"] += len(seeds)
        record["steps"] += args.steps
        record["scene_steps"] += len(seeds) * args.steps
        for sp in specs:
            record["scenes_by_kind"]["free" if sp["free"] else "box"] += 1
        for i, broken in bad:
            path = fz.jaxdda.scene.io.save_scene(fz.build(specs[i]), failures_dir / f"seed_{seeds[i]}.toml", steps=args.steps)
            record["failing"].append({"seed": seeds[i], "kind": "free" if specs[i]["free"] else "box",
                                      "broken": broken, "first_step": int(acc["first_bad"][i]),
                                      "nonconverged_steps": int(acc["nonconverged"][i]),
                                      "reproducer": str(path.relative_to(ROOT) if path.is_relative_to(ROOT) else path)})
            for k in {kind_of(m) for m in broken}:
                record["failures_by_invariant"][k] = record["failures_by_invariant"].get(k, 0) + 1
        record["failures"] += len(bad)
        s = fz.summary(acc)
        record["nonconverged_steps"] += s["nonconverged_steps"]
        record["scenes_with_nonconverged"] += int(np.sum(acc["nonconverged"] > 0))
        for k in ("max_iterations", "max_pen_ratio", "max_pen_rel", "max_energy_ratio", "max_energy_growth",
                  "max_momentum_ratio", "max_angular_rel"):
            record[k] = max(record[k], s[k])
        ratios.extend(acc["energy_ratio"].tolist())
        q = np.quantile(np.asarray(ratios), [0.5, 0.9, 0.99, 1.0])
        record["energy_ratio_quantiles"] = dict(zip(("50%", "90%", "99%", "max"), q.tolist()))
        now = time.perf_counter()
        if sitting["compile_and_first_batch_s"] is None:
            sitting["compile_and_first_batch_s"] = now - tb
        else:
            done_after_first = sitting["scene_steps"] - args.batch * args.steps
            sitting["scene_steps_per_s"] = done_after_first / (now - t0 - sitting["compile_and_first_batch_s"])
        sitting["seconds"] = now - t0
        record["seconds"] = seconds_before + sitting["seconds"]
        record["compile_and_first_batch_s"] = record["compile_and_first_batch_s"] or sitting["compile_and_first_batch_s"]
        record["scene_steps_per_s"] = sitting["scene_steps_per_s"]
        np.save(ratio_file, np.asarray(ratios))
        out.write_text(json.dumps(record, indent=1) + "\n")
        rate = record["scene_steps_per_s"]
        left = (record["target_scene_steps"] - record["scene_steps"]) / rate if rate else float("nan")
        print(f"{record['scenes']} scenes, {record['scene_steps']} scene-steps, {record['failures']} failures "
              f"{record['failures_by_invariant']}, {record['nonconverged_steps']} non-converged steps; "
              f"{rate or 0:.0f} scene-steps/s, {left / 3600:.2f} h left", flush=True)
    if pool is not None:
        pool.close()
        pool.join()
    record["done"] = record["scene_steps"] >= record["target_scene_steps"]
    out.write_text(json.dumps(record, indent=1) + "\n")
    print(json.dumps({k: record[k] for k in ("scenes", "steps", "scene_steps", "failures",
                                             "failures_by_invariant", "nonconverged_steps")}))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
