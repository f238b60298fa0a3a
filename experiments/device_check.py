"""jaxdda's speed on the device JAX finds: a GPU after ``pip install ".[cuda]"``, else the CPU.

    python experiments/device_check.py [--batches 1024 65536] [--steps 300] [--pile 10000]
        [--pile-steps 100] [--budget 600] [--batch-size B] [--note TEXT] [--out PATH]

rockfall  ``jaxdda.monte_carlo`` of the rockfall for B = --batches initial velocities of the
          rock (vx uniform in [0, 2], vy in [-2, 0] m/s, seeded), --steps steps as one
          compiled chunk, sharded over the local devices: scenario-steps per second.
          converged: share of scenarios whose every contact solve met its tolerance;
          iterations: each scenario's worst step, mean and max over the scenarios.
pile      ``jaxdda.simulate`` of N = --pile disks falling into a box (``examples.pile``,
          friction 0.5 as in benchmarks.py), --pile-steps steps as one chunk: body-steps
          per second (free disks). converged: share of steps; iterations: per step.

Compile seconds are those JAX spent tracing, lowering and compiling during the case (its
``jax.monitoring`` time spans, overlaps counted once, recompilations after buffer regrowth
included); run seconds are the call's wall time less those (so they include the reruns of
chunks whose buffers overflowed). float64 throughout, as jaxdda always runs. Cases run
smallest first; a case whose estimate (the last case of its kind, run time scaled by the
work) would take the seconds spent past --budget is skipped and listed; a case that
fails (a device out of memory) is listed with its error. Prints a table and
writes ``experiments/results/device_check_<platform>.json``.
"""
from __future__ import annotations

import argparse
import json
import math
import os
import pathlib
import sys
import time

import jax
import numpy as np

HERE = pathlib.Path(__file__).resolve().parent
sys.path[:0] = [str(HERE.parent), str(HERE)]  # this checkout's jaxdda; benchmarks.py's helpers

import jaxdda  # noqa: E402  (float64 on)
from benchmarks import _json_default, log, machine_facts, md_table  # noqa: E402

COMPILE_EVENTS = ("/jax/core/compile/jaxpr_trace_duration", "/jax/core/compile/jaxpr_to_mlir_module_duration",
                  "/jax/core/compile/backend_compile_duration")
COLUMNS = ["case", "size", "steps", "devices", "compile s", "run s", "rate", "unit", "converged",
           "iterations mean", "iterations max", "skipped", "error"]


def parse(argv=None) -> argparse.Namespace:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--batches", type=int, nargs="*", default=[1024, 65536], help="rockfall batch sizes B")
    p.add_argument("--steps", type=int, default=300, help="rockfall steps")
    p.add_argument("--pile", type=int, nargs="*", default=[10000], help="pile sizes N (disks)")
    p.add_argument("--pile-steps", type=int, default=100, help="pile steps")
    p.add_argument("--budget", type=float, default=600.0,
                   help="seconds for all cases: skip a case whose estimate would pass it")
    p.add_argument("--batch-size", type=int, default=None, help="monte_carlo batch_size (default: its own)")
    p.add_argument("--note", default="", help="a line kept in the JSON and printed above the table")
    p.add_argument("--out", default=None, help="JSON path (default results/device_check_<platform>.json)")
    args = p.parse_args(argv)
    for name in ("steps", "pile_steps", "batch_size"):
        value = getattr(args, name)
        if value is not None and value < 1:
            p.error(f"--{name.replace('_', '-')} must be >= 1")
    if any(n < 1 for n in args.batches + args.pile):
        p.error("batch and pile sizes must be >= 1")
    return args


class CompileClock:
    """Seconds JAX spends tracing, lowering and compiling inside a ``with`` block: the
    union of its ``jax.monitoring`` time spans (a nested trace counts once)."""

    def __enter__(self) -> CompileClock:
        self.spans = []
        jax.monitoring.register_event_time_span_listener(self._record)
        return self

    def __exit__(self, *exc) -> None:
        jax.monitoring.unregister_event_time_span_listener(self._record)

    def _record(self, event: str, start_time: float, end_time: float, **kwargs) -> None:
        if event in COMPILE_EVENTS:
            self.spans.append((start_time, end_time))

    @property
    def seconds(self) -> float:
        total, reach = 0.0, -math.inf
        for start, end in sorted(self.spans):
            total += max(0.0, end - max(start, reach))
            reach = max(reach, end)
        return total


def timed(fn):
    """(fn(), wall seconds, compile seconds within them)."""
    with CompileClock() as clock:
        t0 = time.perf_counter()
        out = fn()
        wall = time.perf_counter() - t0
    return out, wall, clock.seconds


def run_rockfall(b: int, steps: int, batch_size: int | None = None) -> dict:
    """The rockfall Monte Carlo of ``b`` scenarios."""
    t0 = time.perf_counter()
    scene = jaxdda.examples.get("rockfall")
    rng = np.random.default_rng(0)
    velocity = np.stack([rng.uniform(0.0, 2.0, b), rng.uniform(-2.0, 0.0, b)], 1)
    build = time.perf_counter() - t0
    mc, wall, compile_s = timed(lambda: jaxdda.monte_carlo(scene, steps, velocity=velocity, batch_size=batch_size,
                                                           chunk=steps, progress=False))
    run = wall - compile_s
    return {"case": "rockfall", "size": b, "steps": steps, "devices": mc.devices, "build s": build,
            "compile s": compile_s, "run s": run, "wall s": build + wall, "rate": b * steps / run,
            "unit": "scenario-steps/s", "converged": float(np.mean(mc.converged)),
            "iterations mean": float(np.mean(mc.iterations)), "iterations max": int(np.max(mc.iterations)),
            "mean runout m": float(np.mean(mc["runout"][:, 0]))}


def run_pile(n: int, steps: int) -> dict:
    """``steps`` steps of a pile of ``n`` disks."""
    t0 = time.perf_counter()
    scene = jaxdda.examples.get("pile", n=n, friction=0.5)
    build = time.perf_counter() - t0
    traj, wall, compile_s = timed(lambda: jaxdda.simulate(scene, steps, chunk=steps, progress=False))
    run = wall - compile_s
    free = int(np.sum(~np.asarray(scene.model.fixed)))
    iterations = np.asarray(traj.info.iterations)
    return {"case": "pile", "size": n, "steps": steps, "devices": 1, "build s": build, "compile s": compile_s,
            "run s": run, "wall s": build + wall, "rate": free * steps / run, "unit": "body-steps/s",
            "converged": float(np.mean(traj.step_converged)), "iterations mean": float(np.mean(iterations)),
            "iterations max": int(np.max(iterations))}


def plan(args) -> list[tuple[str, int, int]]:
    """(case, size, steps), smallest first within each case."""
    return ([("rockfall", b, args.steps) for b in sorted(args.batches)]
            + [("pile", n, args.pile_steps) for n in sorted(args.pile)])


def estimate(rows: list[dict], case: str, work: int) -> float | None:
    """Seconds a case of ``work`` (size x steps) would take, from the last of its kind that ran."""
    ran = [r for r in rows if r["case"] == case and "run s" in r]
    if not ran:
        return None
    r = ran[-1]
    return r["wall s"] - r["run s"] + r["run s"] * work / (r["size"] * r["steps"])


def run_cases(args) -> list[dict]:
    """Every case of the plan that fits the budget; the others as rows with ``skipped``."""
    rows, spent = [], 0.0
    for case, size, steps in plan(args):
        guess = estimate(rows, case, size * steps)
        if spent >= args.budget or (guess is not None and spent + guess > args.budget):
            why = f"estimated {guess:.0f} s, {args.budget - spent:.0f} s left" if guess is not None else "budget spent"
            log(f"{case} {size}: skipped ({why})")
            rows.append({"case": case, "size": size, "steps": steps, "skipped": why})
            continue
        log(f"{case} {size}: {steps} steps")
        t0 = time.perf_counter()
        try:
            row = run_rockfall(size, steps, args.batch_size) if case == "rockfall" else run_pile(size, steps)
        except Exception as e:  # a device out of memory must not lose the other cases
            log(f"{case} {size}: {type(e).__name__}: {e}")
            row = {"case": case, "size": size, "steps": steps, "error": f"{type(e).__name__}: {e}"[:500],
                   "wall s": time.perf_counter() - t0}
        rows.append(row)
        spent += row["wall s"]
    return rows


def main(argv=None) -> None:
    args = parse(argv)
    facts = machine_facts()
    device = jax.devices()[0]
    facts.update({"device kind": device.device_kind, "JAX_PLATFORMS": os.environ.get("JAX_PLATFORMS", ""),
                  "JAX_COMPILATION_CACHE_DIR": os.environ.get("JAX_COMPILATION_CACHE_DIR", "")})
    print(f"# jaxdda device check: {device.device_kind} ({', '.join(facts['devices'])}), backend {facts['backend']}, "
          f"jax {facts['jax']}, float64 {'on' if facts['x64'] else 'OFF'}\n")
    if args.note:
        print(args.note + "\n")
    rows = run_cases(args)
    print(md_table(rows, COLUMNS))
    out = pathlib.Path(args.out) if args.out else HERE / "results" / f"device_check_{device.platform}.json"
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(json.dumps({"note": args.note, "device": str(device), "device kind": device.device_kind,
                               "backend": facts["backend"], "jax": facts["jax"], "float64": facts["x64"],
                               "machine": facts, "settings": vars(args), "cases": rows,
                               "finished": time.strftime("%Y-%m-%d %H:%M:%S")}, indent=1, default=_json_default))
    print(f"\nwrote {out}")


if __name__ == "__main__":
    main()
