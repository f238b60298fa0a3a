"""Fuzzing random scenes for 1 000 000 scene-steps (issue 9).

    python experiments/fuzz.py [--scene-steps 1000000] [--batch 32] [--steps 50] [--start 0]
                               [--out experiments/results/fuzz.json]

Scene k is drawn from ``numpy.random.default_rng(start + k)`` by the generator of
``tests/test_fuzz.py`` (disks, rings holding bodies, convex and concave polygons; random
velocities, spins, materials, densities over 1e0..1e6; gravity in a fixed box, or a free
system without gravity) and runs ``--steps`` steps in vmapped batches of ``--batch``
scenes, all through one compiled program. The invariants of every step are those of the
test (finite state, penetration within the bound of the step's motion, energy never
growing beyond round-off and the solve's tolerance, linear momentum of free scenes to
round-off); each pose every 25 steps is also checked for overlaps on the host.

Writes ``--out`` after every batch: scenes, steps, scene-steps, failures (per invariant
and in all), the seeds of the failing scenes with what they broke and the step it first
broke at, non-converged steps, rates; and a TOML reproducer of each failing scene in
``experiments/results/fuzz_failures/seed_<seed>.toml`` (``jaxdda run FILE``).
"""
from __future__ import annotations

import argparse
import json
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


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scene-steps", type=int, default=1_000_000)
    ap.add_argument("--batch", type=int, default=32)
    ap.add_argument("--steps", type=int, default=fz.STEPS)
    ap.add_argument("--start", type=int, default=0, help="seed of the first scene")
    ap.add_argument("--sample", type=int, default=25, help="host overlap check every this many steps")
    ap.add_argument("--out", default=str(ROOT / "experiments" / "results" / "fuzz.json"))
    args = ap.parse_args(argv)
    out = Path(args.out)
    failures_dir = out.parent / "fuzz_failures"
    failures_dir.mkdir(parents=True, exist_ok=True)

    record = {"command": " ".join(["python", "experiments/fuzz.py"] + (argv or sys.argv[1:])),
              "batch": args.batch, "steps_per_scene": args.steps, "target_scene_steps": args.scene_steps,
              "start_seed": args.start, "cpus": os.cpu_count(),
              "scenes": 0, "steps": 0, "scene_steps": 0, "failures": 0,
              "failures_by_invariant": {k: 0 for k in KINDS}, "failing": [],
              "scenes_by_kind": {"box": 0, "free": 0}, "nonconverged_steps": 0, "scenes_with_nonconverged": 0,
              "max_iterations": 0, "max_pen_ratio": 0.0, "max_pen_rel": 0.0,
              "max_energy_ratio": 0.0, "max_energy_growth": 0.0, "max_momentum_ratio": 0.0,
              "max_angular_rel": 0.0, "energy_ratio_quantiles": {},
              "seconds": 0.0, "compile_and_first_batch_s": None, "scene_steps_per_s": None, "done": False}
    ratios = []
    t0 = time.perf_counter()
    seed = args.start
    while record["scene_steps"] < args.scene_steps:
        tb = time.perf_counter()
        seeds = list(range(seed, seed + args.batch))
        specs = [fz.draw_spec(fz.RngDraw(s)) for s in seeds]
        scenes = [fz.build(s) for s in specs]
        acc, poses, _ = fz.run_batch(scenes, args.steps, sample=args.sample)
        bad = fz.check_batch(scenes, acc, poses, args.steps)
        seed += args.batch
        record["scenes"] += len(scenes)
        record["steps"] += args.steps
        record["scene_steps"] += len(scenes) * args.steps
        for sp in specs:
            record["scenes_by_kind"]["free" if sp["free"] else "box"] += 1
        for i, broken in bad:
            path = fz.jaxdda.scene.io.save_scene(scenes[i], failures_dir / f"seed_{seeds[i]}.toml", steps=args.steps)
            record["failing"].append({"seed": seeds[i], "kind": "free" if specs[i]["free"] else "box",
                                      "broken": broken, "first_step": int(acc["first_bad"][i]),
                                      "nonconverged_steps": int(acc["nonconverged"][i]),
                                      "reproducer": str(path.relative_to(ROOT))})
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
        if record["compile_and_first_batch_s"] is None:
            record["compile_and_first_batch_s"] = now - tb
        else:
            done_after_first = record["scene_steps"] - args.batch * args.steps
            record["scene_steps_per_s"] = done_after_first / (now - t0 - record["compile_and_first_batch_s"])
        record["seconds"] = now - t0
        out.write_text(json.dumps(record, indent=1) + "\n")
        rate = record["scene_steps_per_s"]
        left = (args.scene_steps - record["scene_steps"]) / rate if rate else float("nan")
        print(f"{record['scenes']} scenes, {record['scene_steps']} scene-steps, {record['failures']} failures "
              f"{record['failures_by_invariant']}, {record['nonconverged_steps']} non-converged steps; "
              f"{rate or 0:.0f} scene-steps/s, {left / 3600:.2f} h left", flush=True)
    record["done"] = True
    out.write_text(json.dumps(record, indent=1) + "\n")
    print(json.dumps({k: record[k] for k in ("scenes", "steps", "scene_steps", "failures",
                                             "failures_by_invariant", "nonconverged_steps")}))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
