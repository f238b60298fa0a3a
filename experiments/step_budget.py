"""The step's budgets (issue 40), for two engines side by side in one run.

Each engine is a source tree (default: a git worktree of the baseline commit, and this
checkout); each figure is measured in a fresh child process of that tree, with JAX's
persistent compilation cache off, one after the other, so both share the machine's state.

Figures per engine:

- ``ops``: StableHLO operations of ``jax.jit(step).lower(...)`` for the rockfall (3 bodies);
  ``solver copies``: how many times the contact solve is traced into that program;
- ``kernels``: fusion kernels of the compiled rockfall step (each an LLVM module to compile
  and a thunk to run on XLA:CPU);
- trace + compile of ``jax.jit(step)``: rockfall (and the compile's CPU time, which load
  on the machine disturbs less), and a pile of 1000 disks;
- one rockfall step (compiled, single scene), median over 200 calls;
- batched rockfall: ``vmap(step)`` in a ``lax.scan``, B scenarios, scenario-steps per second;
- ``value_and_grad`` of a 10-step incline rollout (friction and start speed): compile time,
  keeping every intermediate (``checkpoint=False``) and through ``rollout``'s default;
- ``jaxdda run paper-7.5`` (4000 steps): wall time of the CLI in a new process;
- fuzz: scene-steps per second of ``experiments/fuzz.py`` over a range of seeds.

    python experiments/step_budget.py [--base 965b16d] [--new .] [--only ops,compile,...]

Prints a markdown table and writes experiments/results/step_budget.{json,md}.
"""
from __future__ import annotations

import argparse
import json
import os
import re
import subprocess
import sys
import tempfile
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent
FIGURES = ("ops", "kernels", "compile", "pile_compile", "single", "batched", "grad", "grad_default", "cli", "fuzz")


# -- children: one figure of one engine, in a process importing that engine ---------------
def _lowered_step(scene):
    import jax

    from jaxdda.step import step
    return jax.jit(step).lower(scene.model, scene.state, scene.params)


def _count_solves():
    """Patch the solver's ``solve`` to count how often it is traced; returns the counter."""
    import importlib

    count = [0]
    for name in ("jaxdda.solver.fista_newton", "jaxdda.solver.pc"):
        try:
            mod = importlib.import_module(name)
        except ImportError:
            continue
        inner = mod.solve

        def counted(*a, _inner=inner, **k):
            count[0] += 1
            return _inner(*a, **k)
        mod.solve = counted
        break
    return count


def child_ops(args) -> dict:
    from jaxdda.examples.practical import rockfall
    count = _count_solves()
    text = _lowered_step(rockfall()).as_text()
    ops = sum(1 for line in text.splitlines() if re.search(r"(= |^\s*)\"?stablehlo\.", line))
    # a jitted solver is one private function of the program, however often it is called
    functions = len(set(re.findall(r"func\.func private @(solve(?:_\d+)?)\b", text)))
    return {"ops": ops, "solver copies": functions or count[0]}


def _compile_time(scene) -> dict:
    t0 = time.perf_counter()
    lowered = _lowered_step(scene)
    t1, c1 = time.perf_counter(), time.process_time()
    lowered.compile()
    t2, c2 = time.perf_counter(), time.process_time()
    return {"trace s": t1 - t0, "compile s": t2 - t1, "total s": t2 - t0, "compile cpu s": c2 - c1}


def child_kernels(args) -> dict:
    """Fusion kernels and executable instructions of the compiled rockfall step, from XLA's
    dump of the optimized module (XLA:CPU compiles each kernel as an LLVM module)."""
    import glob
    dump = tempfile.mkdtemp(prefix="step_budget-")
    os.environ["XLA_FLAGS"] = (os.environ.get("XLA_FLAGS", "") + f" --xla_dump_to={dump} --xla_dump_hlo_as_text"
                               " --xla_dump_hlo_module_re=jit_step --xla_dump_hlo_pass_re=NONE")
    from jaxdda.examples.practical import rockfall
    _lowered_step(rockfall()).compile()
    text = Path(glob.glob(f"{dump}/*jit_step*after_optimizations.txt")[0]).read_text()
    fusions = sum(1 for line in text.splitlines() if re.match(r"^\s+(ROOT )?%[\w.-]+ = .* fusion\(", line))
    return {"kernels": fusions}


def child_compile(args) -> dict:
    from jaxdda.examples.practical import rockfall
    return _compile_time(rockfall())


def child_pile_compile(args) -> dict:
    from jaxdda import examples
    return _compile_time(examples.get("pile", n=1000))


def child_single(args) -> dict:
    import jax
    import numpy as np

    from jaxdda.examples.practical import rockfall
    scene = rockfall()
    exe = _lowered_step(scene).compile()
    state = scene.state
    for _ in range(20):  # past the release
        state = jax.block_until_ready(exe(scene.model, state, scene.params)[0])
    times = []
    for _ in range(200):
        t0 = time.perf_counter()
        state = jax.block_until_ready(exe(scene.model, state, scene.params)[0])
        times.append(time.perf_counter() - t0)
    return {"step ms": 1e3 * float(np.median(times)), "min ms": 1e3 * float(np.min(times))}


def child_batched(args) -> dict:
    import dataclasses

    import jax
    import numpy as np

    from jaxdda.examples.practical import rockfall
    from jaxdda.step import step
    scene, B, steps = rockfall(), args.batch, args.batch_steps
    rng = np.random.default_rng(0)
    velocity = np.stack([rng.uniform(0.0, 2.0, B), rng.uniform(-2.0, 0.0, B)], 1)

    def run(model, state0, params, velocity):
        states = jax.vmap(lambda v: dataclasses.replace(state0, velocity=state0.velocity.at[0, :2].set(v)))(velocity)

        def one(s, _):
            s2, info = jax.vmap(step, in_axes=(None, 0, None))(model, s, params)
            return s2, info.overflow
        end, overflow = jax.lax.scan(one, states, None, length=steps)
        return end.centroid[:, 0], overflow.any()

    t0 = time.perf_counter()
    exe = jax.jit(run).lower(scene.model, scene.state, scene.params, velocity).compile()
    compile_s = time.perf_counter() - t0
    best = None
    for _ in range(2):
        t0 = time.perf_counter()
        _, overflow = jax.block_until_ready(exe(scene.model, scene.state, scene.params, velocity))
        sec = time.perf_counter() - t0
        best = sec if best is None else min(best, sec)
    return {"B": B, "steps": steps, "s": best, "scenario-steps/s": B * steps / best, "compile s": compile_s,
            "overflow": bool(overflow)}


def child_grad(args, checkpoint: bool = False) -> dict:
    import dataclasses
    import math

    import jax
    import jax.numpy as jnp

    import jaxdda
    from jaxdda.examples import practical
    scene = practical.incline()
    down = jnp.asarray([math.cos(math.radians(30)), -math.sin(math.radians(30))])

    def f(theta):
        params = dataclasses.replace(scene.params, friction=jnp.full_like(scene.params.friction, theta["mu"]))
        state = dataclasses.replace(scene.state, velocity=scene.state.velocity.at[0, :2].set(theta["v0"] * down))
        end, _ = jaxdda.rollout(scene.model, state, params, 10, checkpoint=checkpoint)
        return end.displacement[0] @ down

    theta = {"mu": jnp.asarray(0.3), "v0": jnp.asarray(0.5)}
    t0 = time.perf_counter()
    lowered = jax.jit(jax.value_and_grad(f)).lower(theta)
    t1 = time.perf_counter()
    exe = lowered.compile()
    t2 = time.perf_counter()
    value, grad = exe(theta)
    return {"trace s": t1 - t0, "compile s": t2 - t1, "total s": t2 - t0, "value": float(value),
            "d/dmu": float(grad["mu"]), "d/dv0": float(grad["v0"])}


def child_grad_default(args) -> dict:
    """``child_grad`` through ``rollout``'s default, a checkpointed reverse pass."""
    return child_grad(args, checkpoint=True)


def child_cli(args) -> dict:
    with tempfile.TemporaryDirectory() as tmp:
        t0 = time.perf_counter()
        out = subprocess.run([sys.executable, "-m", "jaxdda", "run", "paper-7.5", "--plot", f"{tmp}/run.png"],
                             capture_output=True, text=True, env=_child_env())
        wall = time.perf_counter() - t0
    return {"wall s": wall, "rc": out.returncode, "tail": out.stdout[-300:] + out.stderr[-300:]}


def child_fuzz(args) -> dict:
    """Scene-steps per second of experiments/fuzz.py over the first ``fuzz_seeds`` seeds
    (50 steps each, batches of 32, one worker), after its compile and first batch."""
    with tempfile.TemporaryDirectory() as tmp:
        out_file = Path(tmp, "fuzz.json")
        t0 = time.perf_counter()
        out = subprocess.run([sys.executable, "experiments/fuzz.py", "--start", "0", "--scene-steps",
                              str(50 * args.fuzz_seeds), "--batch", "32", "--workers", "1", "--out", str(out_file)],
                             capture_output=True, text=True, env=_child_env())
        wall = time.perf_counter() - t0
        report = json.loads(out_file.read_text()) if out_file.exists() else {}
    return {"wall s": wall, "rc": out.returncode, "scene-steps/s": report.get("scene_steps_per_s"),
            "scene-steps": report.get("scene_steps"), "failures": report.get("failures"),
            "tail": (out.stdout + out.stderr)[-400:]}


# -- parent ------------------------------------------------------------------------------
def _child_env() -> dict:
    env = dict(os.environ)
    env["JAX_ENABLE_COMPILATION_CACHE"] = "false"
    env["JAXDDA_CACHE"] = "off"
    env.pop("JAX_COMPILATION_CACHE_DIR", None)
    return env


def measure(tree: Path, figure: str, args) -> dict:
    cmd = [sys.executable, str(Path(__file__).resolve()), "--child", figure, "--batch", str(args.batch),
           "--batch-steps", str(args.batch_steps), "--fuzz-seeds", str(args.fuzz_seeds)]
    env = _child_env()
    env["PYTHONPATH"] = str(tree)
    out = subprocess.run(cmd, cwd=tree, capture_output=True, text=True, env=env)
    try:
        return json.loads(out.stdout.strip().splitlines()[-1])
    except (IndexError, json.JSONDecodeError):
        return {"error": (out.stdout + out.stderr)[-600:]}


def worktree(commit: str) -> Path:
    path = Path(tempfile.gettempdir()) / f"jaxdda-{commit}"
    if not path.exists():
        subprocess.run(["git", "worktree", "add", "--detach", str(path), commit], cwd=ROOT, check=True,
                       capture_output=True)
    return path


ROWS = [  # (label, figure, key, format)
    ("StableHLO ops of jit(step), rockfall", "ops", "ops", "{:.0f}"),
    ("solver copies traced into the step", "ops", "solver copies", "{:.0f}"),
    ("compiled kernels (fusions) of jit(step), rockfall", "kernels", "kernels", "{:.0f}"),
    ("trace + compile jit(step), rockfall (s)", "compile", "total s", "{:.1f}"),
    ("XLA compile of jit(step), rockfall: CPU time (s)", "compile", "compile cpu s", "{:.1f}"),
    ("trace + compile jit(step), pile of 1000 (s)", "pile_compile", "total s", "{:.1f}"),
    ("one rockfall step (ms, median)", "single", "step ms", "{:.3f}"),
    ("batched rockfall (scenario-steps/s)", "batched", "scenario-steps/s", "{:.3g}"),
    ("value_and_grad, 10-step incline: compile (s)", "grad", "total s", "{:.1f}"),
    ("the same, rollout's default (checkpointed): compile (s)", "grad_default", "total s", "{:.1f}"),
    ("jaxdda run paper-7.5, wall (s)", "cli", "wall s", "{:.1f}"),
    ("fuzz (scene-steps/s)", "fuzz", "scene-steps/s", "{:.3g}"),
]


def table(results: dict, names: list[str]) -> str:
    lines = ["| figure | " + " | ".join(names) + " |", "|---|" + "---|" * len(names)]
    for label, fig, key, fmt in ROWS:
        cells = []
        for name in names:
            v = results[name].get(fig, {}).get(key)
            cells.append(fmt.format(v) if isinstance(v, (int, float)) else "")
        if any(cells):
            lines.append(f"| {label} | " + " | ".join(cells) + " |")
    return "\n".join(lines)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--base", default="965b16d", help="baseline commit (a worktree is made of it)")
    parser.add_argument("--new", default=str(ROOT), help="the other engine's source tree ('none': baseline only)")
    parser.add_argument("--only", default=",".join(FIGURES))
    parser.add_argument("--batch", type=int, default=1024)
    parser.add_argument("--batch-steps", type=int, default=100)
    parser.add_argument("--fuzz-seeds", type=int, default=100)
    parser.add_argument("--out", default=str(HERE / "results" / "step_budget"))
    parser.add_argument("--child", default=None, help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.child:
        print(json.dumps(globals()[f"child_{args.child}"](args), default=float))
        return
    trees = {f"base {args.base}": worktree(args.base)}
    if args.new != "none":  # "none": the baseline alone
        trees["new"] = Path(args.new).resolve()
    results = {name: {} for name in trees}
    for figure in args.only.split(","):
        for name, tree in trees.items():
            results[name][figure] = measure(tree, figure, args)
            print(f"{figure:>12} {name}: {json.dumps(results[name][figure])[:200]}", flush=True)
    names = list(trees)
    md = table(results, names)
    print("\n" + md)
    meta = {"machine": os.uname().nodename, "cores": os.cpu_count(), "when": time.strftime("%Y-%m-%d %H:%M"),
            "trees": {k: str(v) for k, v in trees.items()}, "batch": args.batch, "batch steps": args.batch_steps,
            "fuzz seeds": args.fuzz_seeds}
    Path(args.out + ".json").write_text(json.dumps({"meta": meta, "results": results}, indent=1, default=float))
    Path(args.out + ".md").write_text(md + "\n")


if __name__ == "__main__":
    main()
