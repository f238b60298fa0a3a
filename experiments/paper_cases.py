"""Measure cases 7.1-7.5 against their closed forms, beside the paper's own errors.

    python experiments/paper_cases.py [--out experiments/results/paper_cases.json]

Prints a table and writes JSON. Wall times exclude compilation (each case is run once
to compile, then timed).
"""
from __future__ import annotations

import argparse
import json
import math
import pathlib
import time

import numpy as np

import jaxdda

G_ACC = 10.0


def timed(name: str, steps: int, heavy: bool = False):
    scene = jaxdda.examples.get(name, heavy=heavy)
    jaxdda.simulate(scene, steps)  # compile
    t0 = time.perf_counter()
    run = jaxdda.simulate(scene, steps)
    return run, time.perf_counter() - t0


def billiard(start, velocity, time_, half):
    unfolded = np.mod(start + velocity * time_ + half, 4 * half)
    return np.where(unfolded < 2 * half, unfolded - half, 3 * half - unfolded)


def case_7_1(heavy):
    run, wall = timed("paper-7.1", 100, heavy)
    g = 2500 * math.pi * 100 * G_ACC
    errors = [abs(run.force_between(2, 1)[-1, 1] + g), abs(run.force_between(1, 0)[-1, 1] + 2 * g),
              abs(run.force_between(0, 3)[-1, 1] + 3 * g)]
    return {"max |F - kG| (N)": max(errors), "paper": 2.2e-3,
            "drift (m)": float(np.abs(run.centroid[:, :3] - run.centroid[0, :3]).max())}, run, wall


def case_7_2(heavy):
    run, wall = timed("paper-7.2", 100, heavy)
    w = 4.0e6
    c = run.info.contacts
    sel = c.valid[-1] & (c.a[-1] == 3) & (c.b[-1] == 4)
    pts, f = c.point[-1][sel], c.force[-1][sel]
    f1, f2 = f[np.argsort(pts[:, 0]), 1]
    return {"|F1 - W/2| (N)": abs(f1 - w / 2), "paper F1": 0.02319, "|F2 - 7W/2| (N)": abs(f2 - 3.5 * w),
            "paper F2": 0.11433, "drift (m)": float(np.abs(run.centroid - run.centroid[0]).max())}, run, wall


def case_billiard(name, steps, half):
    run, wall = timed(name, steps)
    exact = np.stack([billiard(0, 2.5, run.time, half), billiard(0, 5.0, run.time, half)], -1)
    speed = np.linalg.norm(run.velocity[:, 0, :2], axis=1)
    return {"path error (m)": float(np.linalg.norm(run.centroid[:, 0] - exact, axis=1).max()),
            "speed error (rel)": float(np.abs(speed / math.hypot(2.5, 5.0) - 1).max()),
            "rotation (rad)": float(np.abs(run.rotation[:, 0]).max()), "paper": "graph only"}, run, wall


def case_7_5(heavy):
    run, wall = timed("paper-7.5", 4000, heavy)
    m = math.pi * 1600
    a, b = 1.0, math.sqrt(0.5)
    for _ in range(40):
        a, b = 0.5 * (a + b), math.sqrt(a * b)
    period = 4 * math.sqrt(60 / G_ACC) * math.pi / (2 * a)
    force = np.linalg.norm(run.force_between(1, 0), axis=1)
    mid = 0.5 * (run.time[:-1] + run.time[1:])
    first = mid < period / 2
    k = np.argmax(np.where(first, force, 0))
    v = run.velocity[:, 0, :2]
    energy = 0.5 * m * np.sum(v * v, 1) + m * G_ACC * run.centroid[:, 0, 1]
    return {"|Fmax - 3mg| (N)": abs(force[k] - 3 * m * G_ACC), "paper": 7.05,
            "peak time error (%)": 100 * abs(mid[k] - period / 4) / (period / 4), "paper %": 2.9,
            "energy drift (rel)": float(np.abs(energy - energy[0]).max() / (m * G_ACC * 60))}, run, wall


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--out", default="experiments/results/paper_cases.json")
    args = parser.parse_args()
    rows = []
    for label, fn in [("7.1 fixed base", lambda: case_7_1(False)), ("7.1 heavy base", lambda: case_7_1(True)),
                      ("7.2 fixed base", lambda: case_7_2(False)), ("7.2 heavy base", lambda: case_7_2(True)),
                      ("7.3 ring in frame", lambda: case_billiard("paper-7.3", 2050, 17.0)),
                      ("7.4 block in frame", lambda: case_billiard("paper-7.4", 10000, 50.0)),
                      ("7.5 fixed ring", lambda: case_7_5(False)), ("7.5 heavy ring", lambda: case_7_5(True))]:
        figures, run, wall = fn()
        figures.update({"case": label, "steps": run.steps, "wall s": wall,
                        "max PC iterations": int(run.info.iterations.max()),
                        "all converged": bool(run.info.converged.all())})
        rows.append(figures)
        shown = ", ".join(f"{k} {v:.3g}" if isinstance(v, float) else f"{k} {v}" for k, v in figures.items()
                          if k != "case")
        print(f"{label:20s} {shown}")
    out = pathlib.Path(args.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(json.dumps({"jax": __import__("jax").__version__, "rows": rows}, indent=1, default=float))
    print(f"wrote {out}")


if __name__ == "__main__":
    main()
