"""The cost of gradients: forward against forward+backward time per step, and the peak
memory of a long reverse-mode rollout.

    python experiments/gradients.py [--quick] [--out experiments/results/gradients.json]

1. For a few scenes, a jitted rollout of S steps returning a scalar loss (the sum of the
   final centroids) and its jax.grad with respect to the friction table (value and
   gradient in one pass), each timed after compilation (best of ``--repeats``); the
   compile times (trace, lower, compile) are reported separately.
2. The peak memory of the gradient of a 1000-step rollout of the 100-disk scene, with
   ``checkpoint=True`` and ``checkpoint=False``: each run in a fresh subprocess (this
   script with ``--child``), beside a baseline child that only imports jax and builds the
   scene. "peak" is the child's high-water RSS (VmHWM, compilation included; not
   ru_maxrss, which on Linux carries the parent's peak into a vfork+exec'd child);
   "run peak" the high-water mark of the execution alone (reset after compiling, so it
   starts from "after compile", the RSS that the compiler left); "XLA" the compiled
   program's own buffer estimate (temporaries, arguments, outputs). A run whose estimate exceeds ``--memory-limit`` GB is not
   executed (its row keeps the estimate).

Prints two tables and writes JSON. ``--quick``: fewer steps (50 per scene, 200 for the
memory runs) and two repeats.
"""
from __future__ import annotations

import argparse
import dataclasses
import json
import os
import pathlib
import re
import resource
import subprocess
import sys
import time

import numpy as np

CHILD_TAG = "GRADIENTS_CHILD "


def row_of_disks(n: int = 100, velocity: float = 1.0):
    """``n`` touching disks (radius 0.5, density 2000) in a row on a fixed floor, all
    launched at ``velocity`` m/s to the right without spin: each slides, then rolls
    (friction 0.5, so the friction gradient is not zero). Neighbours touch: 2n - 1 contacts."""
    import jaxdda

    sb = jaxdda.SceneBuilder(dt=0.01, gravity=(0.0, -10.0), name=f"row-{n}")
    sb.add_material("grain", friction=0.5, restitution=0.0)
    for i in range(n):
        sb.add_disk(center=(float(i), 0.5), radius=0.5, density=2000.0, material="grain", velocity=(velocity, 0.0))
    end = n + 20.0  # room to roll for 1000 steps
    sb.add_polygon(vertices=[(-2.0, -1.0), (end, -1.0), (end, 0.0), (-2.0, 0.0)], density=2000.0, fixed=True,
                   material="grain")
    return sb.build()


def scene_named(name: str):
    import jaxdda

    return row_of_disks() if name == "row-100" else jaxdda.examples.get(name)


def loss_fn(scene, steps: int, checkpoint: bool = True):
    """friction table -> (sum of the final centroids, (overflow, needed, max iterations, all converged))."""
    import jax.numpy as jnp

    import jaxdda

    def loss(friction, model, state):
        params = dataclasses.replace(scene.params, friction=friction)
        end, (_, infos) = jaxdda.rollout(model, state, params, steps, checkpoint=checkpoint)
        aux = (jnp.any(infos.overflow), jnp.max(infos.needed, 0), jnp.max(infos.iterations), jnp.all(infos.converged))
        return jnp.sum(end.centroid), aux
    return loss


def compiled(fn, *args):
    """(compiled executable, seconds to trace, lower and compile it)."""
    import jax

    t0 = time.perf_counter()
    exe = jax.jit(fn).lower(*args).compile()
    return exe, time.perf_counter() - t0


def best_of(exe, args, repeats: int) -> float:
    import jax

    best = float("inf")
    for _ in range(repeats):
        t0 = time.perf_counter()
        jax.block_until_ready(exe(*args))
        best = min(best, time.perf_counter() - t0)
    return best


def sized(scene, steps: int):
    """Model and state with buffers large enough for ``steps`` of the scene (by a forward
    rollout, regrown while it overflows), the forward executable and its compile time."""
    import jaxdda
    from jaxdda.simulate import MAX_REGROW, with_capacity
    from jaxdda.types import Capacities

    model, state, loss = scene.model, scene.state, loss_fn(scene, steps)
    for _ in range(MAX_REGROW):
        exe, compile_s = compiled(loss, scene.params.friction, model, state)
        _, (overflow, needed, _, _) = exe(scene.params.friction, model, state)
        if not bool(overflow):
            return model, state, exe, compile_s
        model, state = with_capacity(model, state, model.capacity.grown(Capacities(*np.asarray(needed).tolist())))
    raise jaxdda.errors.CapacityError(f"{scene.name}: buffers kept overflowing")


def time_scene(name: str, steps: int, repeats: int) -> dict:
    import jax

    scene = scene_named(name)
    model, state, forward, compile_fwd = sized(scene, steps)
    grad_exe, compile_grad = compiled(jax.value_and_grad(loss_fn(scene, steps), has_aux=True),
                                      scene.params.friction, model, state)
    args = (scene.params.friction, model, state)
    fwd_s, grad_s = best_of(forward, args, repeats), best_of(grad_exe, args, repeats)
    (value, (overflow, _, iterations, converged)), grad = grad_exe(*args)
    assert not bool(overflow) and np.all(np.isfinite(np.asarray(grad)))
    free = int(np.sum(~np.asarray(scene.model.fixed)))
    return {"scene": name, "bodies": scene.n_bodies, "free bodies": free, "steps": steps,
            "forward ms/step": 1e3 * fwd_s / steps, "fwd+bwd ms/step": 1e3 * grad_s / steps,
            "ratio": grad_s / fwd_s, "compile s (forward)": compile_fwd, "compile s (grad)": compile_grad,
            "loss": float(value), "d loss / d friction": np.asarray(grad).tolist(),
            "max solver iterations": int(iterations), "all converged": bool(converged),
            "capacity": dataclasses.asdict(model.capacity)}


# -- memory: one fresh process per measurement ---------------------------------------------
def _status_kb(field: str) -> int | None:
    try:
        return int(re.search(rf"{field}:\s+(\d+) kB", pathlib.Path("/proc/self/status").read_text()).group(1))
    except (OSError, AttributeError):
        return None


def _reset_peak() -> bool:
    try:  # Linux: "5" resets the VmHWM high-water mark of this process
        pathlib.Path("/proc/self/clear_refs").write_text("5")
        return True
    except OSError:
        return False


def child(kind: str, steps: int, checkpoint: bool, limit_gb: float) -> dict:
    """Runs in the subprocess: ``kind`` "baseline" (import and build only) or "memory"
    (compile and run the gradient of a ``steps``-step rollout)."""
    import jax
    import jax.numpy as jnp

    scene = row_of_disks()
    jax.block_until_ready(jnp.sum(scene.state.centroid))  # backend up, scene on the device
    out: dict = {}
    compile_peak = 0
    if kind == "memory":
        args = (scene.params.friction, scene.model, scene.state)
        exe, out["compile s"] = compiled(jax.value_and_grad(loss_fn(scene, steps, checkpoint), has_aux=True), *args)
        try:
            m = exe.memory_analysis()
            out["XLA GB"] = (m.temp_size_in_bytes + m.argument_size_in_bytes + m.output_size_in_bytes) / 1e9
        except Exception:  # not every backend reports it
            out["XLA GB"] = None
        out["after compile GB"] = (_status_kb("VmRSS") or 0) / 1e6
        compile_peak = _status_kb("VmHWM") or 0
        if out["XLA GB"] is not None and out["XLA GB"] > limit_gb:
            out["skipped"] = f"XLA estimate {out['XLA GB']:.1f} GB > limit {limit_gb:.1f} GB"
        else:
            reset = _reset_peak()
            t0 = time.perf_counter()
            (_, (overflow, _, _, converged)), grad = exe(*args)
            jax.block_until_ready(grad)
            out["run s"] = time.perf_counter() - t0
            hwm = _status_kb("VmHWM")
            out["run peak GB"] = hwm / 1e6 if reset and hwm else None
            out["overflow"], out["all converged"] = bool(overflow), bool(converged)
            out["grad finite"] = bool(np.all(np.isfinite(np.asarray(grad))))
            if out["run peak GB"] is not None:
                out["run increment GB"] = out["run peak GB"] - out["after compile GB"]
    hwm = _status_kb("VmHWM")  # this process only (see the module docstring)
    hwm = max(hwm, compile_peak) if hwm else resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    out["peak GB"] = hwm / 1e6
    return out


def spawn(kind: str, steps: int, checkpoint: bool, limit_gb: float) -> dict:
    cmd = [sys.executable, os.path.abspath(__file__), "--child", kind, "--steps", str(steps),
           "--checkpoint", str(int(checkpoint)), "--memory-limit", str(limit_gb)]
    t0 = time.perf_counter()
    proc = subprocess.run(cmd, capture_output=True, text=True)
    wall = time.perf_counter() - t0
    lines = [line for line in proc.stdout.splitlines() if line.startswith(CHILD_TAG)]
    if proc.returncode != 0 or not lines:
        return {"error": f"exit {proc.returncode}: {proc.stderr.strip().splitlines()[-1:] or ''}", "wall s": wall}
    out = json.loads(lines[-1][len(CHILD_TAG):])
    out["wall s"] = wall
    return out


def memory_rows(steps: int, limit_gb: float) -> list[dict]:
    base = spawn("baseline", steps, True, limit_gb)
    rows = [{"run": "baseline (import, build)", "steps": 0, **base}]
    for checkpoint in (True, False):
        out = spawn("memory", steps, checkpoint, limit_gb)
        if "peak GB" in out and "peak GB" in base:
            out["increment GB"] = out["peak GB"] - base["peak GB"]
        rows.append({"run": f"grad, checkpoint={checkpoint}", "steps": steps, **out})
    return rows


def _fmt(v) -> str:
    if v is None:
        return "-"
    if isinstance(v, float):
        return f"{v:.3g}" if abs(v) < 1000 else f"{v:.0f}"
    return str(v)


def table(rows: list[dict], cols: list[str]) -> str:
    cells = [cols] + [[_fmt(r.get(c)) for c in cols] for r in rows]
    widths = [max(len(line[k]) for line in cells) for k in range(len(cols))]
    lines = ["  ".join(c.rjust(w) if k else c.ljust(w) for k, (c, w) in enumerate(zip(line, widths)))
             for line in cells]
    return "\n".join([lines[0], "-" * len(lines[0])] + lines[1:])


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--out", default="experiments/results/gradients.json")
    parser.add_argument("--quick", action="store_true", help="fewer steps and repeats")
    parser.add_argument("--repeats", type=int, default=None, help="timed runs per case (best is kept)")
    parser.add_argument("--memory-limit", type=float, default=None,
                        help="GB: skip a memory run whose XLA estimate is above (default 60%% of RAM, <= 16)")
    parser.add_argument("--child", choices=["baseline", "memory"], help=argparse.SUPPRESS)
    parser.add_argument("--steps", type=int, default=1000, help=argparse.SUPPRESS)
    parser.add_argument("--checkpoint", type=int, default=1, help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.memory_limit is None:
        ram = os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES") / 1e9
        args.memory_limit = min(16.0, 0.6 * ram)
    if args.child:
        out = child(args.child, args.steps, bool(args.checkpoint), args.memory_limit)
        print(CHILD_TAG + json.dumps(out), flush=True)
        return

    import jax

    import jaxdda  # noqa: F401  (float64)

    steps = {"incline": 100, "rockfall": 200, "row-100": 100}
    if args.quick:
        steps = dict.fromkeys(steps, 50)
    repeats = args.repeats or (2 if args.quick else 3)
    memory_steps = 200 if args.quick else 1000

    rows = []
    for name, s in steps.items():
        rows.append(time_scene(name, s, repeats))
        r = rows[-1]
        print(f"{name}: forward {r['forward ms/step']:.3g} ms/step, fwd+bwd {r['fwd+bwd ms/step']:.3g} ms/step "
              f"(x{r['ratio']:.2f}), compile {r['compile s (forward)']:.1f} s / {r['compile s (grad)']:.1f} s",
              flush=True)
    print()
    print(table(rows, ["scene", "bodies", "steps", "forward ms/step", "fwd+bwd ms/step", "ratio",
                       "compile s (forward)", "compile s (grad)"]))

    print(f"\npeak memory of jax.grad of a {memory_steps}-step rollout of row-100 (fresh process each)", flush=True)
    memory = memory_rows(memory_steps, args.memory_limit)
    print(table(memory, ["run", "steps", "peak GB", "increment GB", "after compile GB", "run peak GB",
                         "run increment GB", "XLA GB", "compile s", "run s"]))
    for r in memory:
        for key in ("skipped", "error"):
            if key in r:
                print(f"{r['run']}: {key}: {r[key]}")

    out = pathlib.Path(args.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(json.dumps({"jax": jax.__version__, "quick": args.quick, "cpu cores": os.cpu_count(),
                               "backend": jax.default_backend(), "repeats": repeats, "timing": rows,
                               "memory": memory}, indent=1, default=float))
    print(f"wrote {out}")


if __name__ == "__main__":
    main()
