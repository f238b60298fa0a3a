"""Where the step's StableHLO ops and compiled kernels are (issue 40's budget: <= 6 000 ops
for the rockfall). Ops: the step is lowered as growing prefixes of its pipeline
(``jaxdda/step/pipeline.py``), each stage's share is the difference. Kernels: the fusions of
the compiled step (XLA:CPU compiles each as an LLVM module and runs each as a thunk, so
they drive compile and run time), by the stage's named scope in their op names. Prints a
table, writes results/stage_ops.json.

    python experiments/stage_ops.py [SCENE ...]      (default: rockfall pile)
"""
from __future__ import annotations

import collections
import glob
import json
import os
import re
import shutil
import sys
import tempfile
from pathlib import Path

DUMP = tempfile.mkdtemp(prefix="stage_ops-")
os.environ["XLA_FLAGS"] = (os.environ.get("XLA_FLAGS", "") + f" --xla_dump_to={DUMP} --xla_dump_hlo_as_text"
                           " --xla_dump_hlo_module_re=jit_step --xla_dump_hlo_pass_re=NONE")

import jax
import jax.numpy as jnp

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))  # this checkout's jaxdda

import jaxdda  # noqa: E402
from jaxdda.connectors import connector_forces  # noqa: E402
from jaxdda.scene.padding import Shape, pad_scene  # noqa: E402
from jaxdda.step.frame import contact_frame  # noqa: E402
from jaxdda.step.jump import impact_rows  # noqa: E402
from jaxdda.step.operators import assemble  # noqa: E402
from jaxdda.step.predict import predict  # noqa: E402
from jaxdda.step.report import contact_report, step_info  # noqa: E402
from jaxdda.step.resolve import impacts_then_contacts, step_end  # noqa: E402
from jaxdda.step.rupture import rupture  # noqa: E402
from jaxdda.step.update import update  # noqa: E402

STAGES = ["assemble", "detect (contact_frame)", "predict", "impact_rows", "impacts_then_contacts (2 VI solves)",
          "step_end", "rupture", "update", "report"]


def prefix(k: int):
    """The step's first ``k + 1`` stages, returning everything they made (so none is pruned)."""
    def run(model, state, params):
        base, out = model, []
        model, ops = assemble(base, state, params)
        out.append(ops)
        if k >= 1:
            out.append(frame := contact_frame(model, state, params))
        if k >= 2:
            out.append(pred := predict(model, state, params, ops, frame))
        if k >= 3:
            out.append(rows := impact_rows(model, state, params, ops, frame, pred))
        if k >= 4:
            out.append(solved := impacts_then_contacts(model, state, params, ops, frame, pred, rows))
        if k >= 5:
            out.append(res := step_end(model, params, ops, frame, rows, solved))
        if k >= 6:
            out.append(broken := rupture(model, state, params, frame.cemented, frame.joint, res.force, res.gap_end,
                                         res.w_nn, res.force_scale))
        if k >= 7:
            out.append(new := update(base, model, state, params, ops, res.displacement, res.velocity,
                                     frame.contacts.key, res.memory, broken[0]))
        if k >= 8:
            report = contact_report(frame, res.point, res.normal, res.parts)
            out.append(step_info(model, frame, res.solutions, *broken, connector_forces(base, params, new), report))
        return out
    return run


def ops(fn, *args) -> int:
    text = jax.jit(fn).lower(*args).as_text()
    return sum(1 for line in text.splitlines() if re.search(r"(= |^\s*)\"?stablehlo\.", line))


SCOPES = ["assemble", "detect", "predict", "impacts", "solves", "end", "rupture", "update", "report"]  # pipeline's


def kernels(*args) -> dict:
    """Fusion kernels of the compiled step per stage scope (``other``: none of them)."""
    shutil.rmtree(DUMP, ignore_errors=True)
    jax.jit(jaxdda.step).lower(*args).compile()
    text = Path(glob.glob(f"{DUMP}/*jit_step*after_optimizations.txt")[0]).read_text()
    counts = collections.Counter()
    for line in text.splitlines():
        if re.match(r"^\s+(ROOT )?%[\w.-]+ = .* fusion\(", line):
            name = re.search(r'op_name="([^"]+)"', line)
            scope = [s for s in SCOPES if name and f"/{s}/" in name.group(1) + "/"]
            counts[scope[0] if scope else "other"] += 1
    return dict(counts)


def shares(name: str) -> dict:
    scene = jaxdda.examples.get(name)
    args = jax.tree.map(jnp.asarray, pad_scene(scene, Shape.covering([scene]).bucket()))
    counts = [ops(prefix(k), *args) for k in range(len(STAGES))]
    return {"step": ops(jaxdda.step, *args),
            "stages": {s: c - p for s, c, p in zip(STAGES, counts, [0] + counts[:-1])},
            "kernels": kernels(*args)}


def main() -> None:
    names = sys.argv[1:] or ["rockfall", "pile"]
    table = {name: shares(name) for name in names}
    print("| stage (scope) | " + " | ".join(f"{n}: ops | kernels" for n in names) + " |\n|---|" + "---|" * (2 * len(names)))
    for stage, scope in zip(STAGES, SCOPES):
        print(f"| {stage} ({scope}) | " + " | ".join(
            f"{table[n]['stages'][stage]} | {table[n]['kernels'].get(scope, 0)}" for n in names) + " |")
    print("| jit(step) | " + " | ".join(
        f"{table[n]['step']} | {sum(table[n]['kernels'].values())}" for n in names) + " |")
    out = Path(__file__).parent / "results" / "stage_ops.json"
    out.write_text(json.dumps({"jax": jax.__version__, "scenes": table}, indent=1))
    print(f"wrote {out}")


if __name__ == "__main__":
    main()
