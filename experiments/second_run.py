"""What the persistent cache saves: ``jaxdda run SCENE --plot run.png`` twice, each in a new
process, over a fresh cache folder. Prints, per run, the wall time, the seconds JAX spent
in the backend (compiling, or loading from the cache), tracing and lowering, and the
programs compiled or loaded; writes results/second_run.json.

    python experiments/second_run.py [--scene paper-7.5] [--runs 2]
"""
from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
from pathlib import Path

HERE = Path(__file__).parent

# One CLI run in this process, with JAX's compile events summed.
CHILD = """
import contextlib, io, json, sys, time
from jax import monitoring
seconds, count = {}, {}
def duration(name, secs, **_):
    seconds[name] = seconds.get(name, 0.0) + secs
def event(name, **_):
    count[name] = count.get(name, 0) + 1
monitoring.register_event_duration_secs_listener(duration)
monitoring.register_event_listener(event)
start = time.perf_counter()
from jaxdda import cli
with contextlib.redirect_stdout(io.StringIO()):
    status = cli.main(["run", sys.argv[1], "--plot", sys.argv[2], "--quiet"])
wall = time.perf_counter() - start
print(json.dumps(dict(status=status, wall=wall, seconds=seconds, count=count)))
"""
EVENTS = {"backend": "/jax/core/compile/backend_compile_duration", "trace": "/jax/core/compile/jaxpr_trace_duration",
          "lowering": "/jax/core/compile/jaxpr_to_mlir_module_duration",
          "retrieval": "/jax/compilation_cache/cache_retrieval_time_sec"}


def run_once(scene: str, cache: Path, picture: Path) -> dict:
    env = {k: v for k, v in os.environ.items() if k != "JAX_COMPILATION_CACHE_DIR"}
    env["JAXDDA_CACHE"] = str(cache)
    env["PYTHONPATH"] = os.pathsep.join([str(HERE.parent), env.get("PYTHONPATH", "")])
    done = subprocess.run([sys.executable, "-c", CHILD, scene, str(picture)], env=env, capture_output=True,
                          text=True, check=True)
    raw = json.loads(done.stdout.splitlines()[-1])
    row = {"wall_s": raw["wall"], **{f"{k}_s": raw["seconds"].get(v, 0.0) for k, v in EVENTS.items()}}
    row["programs"] = raw["count"].get("/jax/compilation_cache/compile_requests_use_cache", 0)
    row["loaded"] = raw["count"].get("/jax/compilation_cache/cache_hits", 0)
    return row


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scene", default="paper-7.5")
    parser.add_argument("--runs", type=int, default=2)
    parser.add_argument("--out", default=str(HERE / "results" / "second_run.json"))
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        rows = [run_once(args.scene, Path(tmp) / "xla", Path(tmp) / "run.png") for _ in range(args.runs)]
    cols = ["wall_s", "backend_s", "retrieval_s", "trace_s", "lowering_s", "programs", "loaded"]
    print(f"jaxdda run {args.scene} --plot run.png, each in a new process, over a fresh cache")
    print("| run | " + " | ".join(cols) + " |\n|" + "---|" * (len(cols) + 1))
    for k, row in enumerate(rows, 1):
        print(f"| {k} | " + " | ".join(f"{row[c]:.2f}" if c.endswith("_s") else str(row[c]) for c in cols) + " |")
    Path(args.out).write_text(json.dumps({"scene": args.scene, "cpu_count": os.cpu_count(),
                                          "load_average": os.getloadavg(), "runs": rows}, indent=1))
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
