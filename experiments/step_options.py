"""What each refinement of the step costs and what it buys (issue 40, item 5).

Cost, per option set (all on; each refinement off alone; all off), on the rockfall
(3 bodies): StableHLO ops of ``jit(step)``, trace + compile time (persistent cache off),
and one compiled step (median of 500 calls; and the solves' iterations in it).

Gain, per refinement: a probe scene that the refinement is for, run with it on and off
(the others on), against a closed form:

- impact_instants: a disk (e = 0.5) dropped on a floor, striking 0.45 into a step:
  |apex - e^2 h| (m);
- impact_refits: a disk crossing a ring's hole strikes its wall (e = 1): |v+ - v_exact|
  (m/s) after the impact (the mirror image about the exact impact point's normal);
- windows: a block dropped flat on a floor (e = 0), landing 0.3 into a step: its speed
  at the end of that step (m/s; exact: 0);
- linearisation_cut: the fuzz scenes whose end overlaps the linearisation at the predictor
  missed (seeds 656, 2519, 2686, 3901), 50 steps: how many break the fuzz invariants;
- discrete_gradient: a square tipping about its corner on a frictionless floor, 0.3 s:
  the energy gained relative to m g r (the contact does no work);
- newton_finish: the fuzz regression seeds (tests/test_fuzz.py), 50 steps: invariants
  broken, the most iterations a step's solves took, and the unconverged steps.

    python experiments/step_options.py

Prints a markdown table and writes experiments/results/step_options.{json,md}.
"""
from __future__ import annotations

import argparse
import dataclasses
import json
import math
import sys
import time
from pathlib import Path

import jax
import numpy as np

import jaxdda
from jaxdda.examples.practical import rockfall
from jaxdda.types import StepOptions

jax.config.update("jax_enable_compilation_cache", False)
HERE = Path(__file__).resolve().parent
G = 10.0
OFF = {"impact_instants": False, "impact_refits": 0, "windows": False, "linearisation_cut": False,
       "discrete_gradient": False, "newton_finish": False}


def cost(scene) -> dict:
    """Ops, trace + compile (s) and one step (ms) of ``jit(step)`` on ``scene``."""
    jax.clear_caches()
    args = (scene.model, scene.state, scene.params)
    t0 = time.perf_counter()
    lowered = jax.jit(jaxdda.step).lower(*args)
    t1 = time.perf_counter()
    compiled = lowered.compile()
    t2 = time.perf_counter()
    ops = sum(1 for line in lowered.as_text().splitlines() if "stablehlo." in line and "=" in line)
    _, info = jax.block_until_ready(compiled(*args))
    times = []
    for _ in range(500):
        s = time.perf_counter()
        jax.block_until_ready(compiled(*args))
        times.append(time.perf_counter() - s)
    return {"ops": ops, "trace s": t1 - t0, "compile s": t2 - t1, "step ms": 1e3 * float(np.median(times)),
            "min ms": 1e3 * float(np.min(times)), "iterations": np.asarray(info.iterations).tolist()}


# -- probes: (scene, steps, measure(run) -> dict) ------------------------------------------
def drop_probe():
    e, t_hit = 0.5, 30.45 * 0.01
    h = 0.5 * G * t_hit ** 2
    sb = jaxdda.SceneBuilder(dt=0.01, gravity=(0.0, -G))
    sb.add_material("ball", restitution=e, friction=0.0)
    sb.add_polygon(vertices=[(-5, -1), (5, -1), (5, 0), (-5, 0)], density=1.0, fixed=True, material="ball")
    sb.add_disk(center=(0.0, 0.5 + h), radius=0.5, density=2.0, material="ball")

    def measure(run):
        y, vy = run.centroid[-1, 1, 1] - 0.5, run.velocity[-1, 1, 1]  # body 1: the disk
        return {"apex error m": abs(y + vy ** 2 / (2 * G) - e * e * h)}

    return sb.build(), 50, measure


def ring_probe():
    dt, rho = 0.05, 0.8
    p, v = np.array([0.0, -0.5]), np.array([4.0, -0.5])
    sb = jaxdda.SceneBuilder(dt=dt, gravity=(0.0, 0.0))
    sb.add_material("m", friction=0.0, restitution=1.0)
    sb.add_ring(center=(0.0, 0.0), inner_radius=1.0, outer_radius=1.2, density=1.0, fixed=True, material="m")
    sb.add_disk(center=tuple(p), radius=1.0 - rho, density=1.0, velocity=tuple(v), material="m")
    a, b, c = v @ v, 2 * p @ v, p @ p - rho ** 2
    t_hit = (-b + math.sqrt(b * b - 4 * a * c)) / (2 * a)
    n = (p + v * t_hit) / rho
    v_out = v - 2 * (v @ n) * n

    def measure(run):
        k = int(t_hit // dt) + 1
        return {"velocity error m/s": float(np.abs(run.velocity[k, 1, :2] - v_out).max())}

    return sb.build(), 14, measure


def landing_probe():
    dt, fall = 0.01, 0.3  # lands 0.3 into step 11 (from rest, 0.5 g t^2)
    t_hit = (10 + fall) * dt
    h = 0.5 * G * t_hit ** 2
    sb = jaxdda.SceneBuilder(dt=dt, gravity=(0.0, -G))
    sb.add_material("m", friction=0.5, restitution=0.0)
    sb.add_polygon(vertices=[(-5, -1), (5, -1), (5, 0), (-5, 0)], density=1.0, fixed=True, material="m")
    sb.add_polygon(vertices=[(0, h), (1, h), (1, h + 1), (0, h + 1)], density=2000.0, material="m")

    def measure(run):
        k = int(t_hit // dt) + 1
        return {"speed after landing m/s": float(np.abs(run.velocity[k, 1, :2]).max())}

    return sb.build(), 15, measure


def _fuzz():
    if str(HERE.parent) not in sys.path:
        sys.path.insert(0, str(HERE.parent))  # the fuzz scenes are drawn by tests/test_fuzz.py
    from tests import test_fuzz as fz
    return fz


def tipping_probe():
    """A square tipping about its corner on a frictionless floor (tests/test_fuzz.py
    ``tipping_square``, dt = 4 ms), 0.3 s: the energy gained, relative to m g times the
    corner's reach (the contact does no work: it must not grow)."""
    scale = 1000.0 * 9.81 * math.sqrt(2.0)

    def measure(run):
        total = jaxdda.energy(run)["total"]
        return {"energy gained / (m g r)": float(total.max() - total[0]) / scale}

    return _fuzz().tipping_square(4e-3, 0.0), 75, measure


def fuzz_probe(options: StepOptions, seeds, newton: bool = False) -> dict:
    """Fuzz scenes (tests/test_fuzz.py) of ``seeds``, 50 steps, one padded program: how many
    break the fuzz invariants (and with ``newton``, the solves' iterations)."""
    fz = _fuzz()
    scenes = [fz.build(fz.draw_spec(fz.RngDraw(seed))).with_options(**dataclasses.asdict(options)) for seed in seeds]
    acc, poses, _ = fz.run_batch(scenes, 50, sample=25)
    bad = fz.check_batch(scenes, acc, poses, 50)
    out = {"scenes failing": f"{len(bad)} of {len(scenes)}",
           "broken": sorted({msg.split(" ")[0] for _, broken in bad for msg in broken})}
    if newton:
        out.update({"max iterations": int(np.max(acc["max_iterations"])),
                    "unconverged steps": int(np.sum(acc["nonconverged"]))})
    return out


# the fuzz scenes whose end overlaps the linearisation at the predictor missed
LINEARISATION_SEEDS = (656, 2519, 2686, 3901)
PROBES = {"impact_instants": drop_probe, "impact_refits": ring_probe, "windows": landing_probe,
          "linearisation_cut": lambda options: fuzz_probe(options, LINEARISATION_SEEDS),
          "discrete_gradient": tipping_probe,
          "newton_finish": lambda options: fuzz_probe(options, _fuzz().REGRESSION_SEEDS, newton=True)}


def gain(name: str) -> dict:
    out = {}
    for label, options in (("on", StepOptions()), ("off", dataclasses.replace(StepOptions(), **{name: OFF[name]}))):
        if name in ("linearisation_cut", "newton_finish"):
            out[label] = PROBES[name](options)
            continue
        scene, steps, measure = PROBES[name]()
        run = jaxdda.simulate(dataclasses.replace(scene, model=dataclasses.replace(scene.model, options=options)), steps)
        out[label] = measure(run)
    return out


def _fmt(x) -> str:
    return f"{x:.2e}" if isinstance(x, float) else str(x)


def table(costs: dict, gains: dict) -> str:
    lines = ["| options | ops | trace + compile (s) | step (ms): median, least | probe: with it | without it |",
             "|---|---|---|---|---|---|"]
    for label, c in costs.items():
        name = label.removesuffix(" off")
        probe = gains.get(name)
        on = ", ".join(f"{k} {_fmt(v)}" for k, v in probe["on"].items()) if probe else ""
        off = ", ".join(f"{k} {_fmt(v)}" for k, v in probe["off"].items()) if probe else ""
        lines.append(f"| {label} | {c['ops']} | {c['trace s'] + c['compile s']:.1f} | {c['step ms']:.3f}, "
                     f"{c['min ms']:.3f} | {on} | {off} |")
    return "\n".join(lines)


def main() -> None:
    argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter).parse_args()
    base = rockfall()
    variants = {"all on": {}, **{f"{k} off": {k: v} for k, v in OFF.items()}, "all off": OFF}
    costs = {}
    for label, changes in variants.items():
        costs[label] = cost(base.with_options(**changes))
        print(f"{label:>24}: {json.dumps(costs[label])}", flush=True)
    gains = {}
    for name in PROBES:
        gains[name] = gain(name)
        print(f"{name:>24}: {json.dumps(gains[name])}", flush=True)
    md = table(costs, gains)
    print("\n" + md)
    meta = {"cores": __import__("os").cpu_count(), "when": time.strftime("%Y-%m-%d %H:%M"), "jax": jax.__version__}
    out = HERE / "results" / "step_options"
    out.with_suffix(".json").write_text(json.dumps({"meta": meta, "cost": costs, "gain": gains}, indent=1))
    out.with_suffix(".md").write_text(md + "\n")


if __name__ == "__main__":
    main()
