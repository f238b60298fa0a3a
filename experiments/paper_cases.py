"""Measure cases 7.1-7.8 against their closed forms, beside the paper's own errors.

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


def timed(name: str, steps: int, heavy: bool = False, **options):
    scene = jaxdda.examples.get(name, heavy=heavy, **options)
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


def case_7_2(heavy, **options):
    run, wall = timed("paper-7.2", 100, heavy, **options)
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


def corner_forces(run, a, b, k=-1):
    c = run.info.contacts
    sel = c.valid[k] & (c.a[k] == a) & (c.b[k] == b)
    return c.force[k][sel][np.argsort(c.point[k][sel][:, 0])], c.moment[k][sel]


def case_7_6(heavy):
    run, wall = timed("paper-7.6", 100, heavy)
    (rear, front), _ = corner_forces(run, 0, 1)
    x = run.centroid[:, 0, 0] - run.centroid[0, 0, 0]
    return {"|Fn1 - 4600| (N)": abs(rear[1] - 4600), "|Fn2 - 5400| (N)": abs(front[1] - 5400),
            "|Fs + 400| (N)": abs(rear[0] + front[0] + 400), "paper": 1e-5,
            "|x - 0.3 t^2| (m)": float(np.abs(x - 0.3 * run.time ** 2).max()),
            "rotation (rad)": float(np.abs(run.rotation[:, 0]).max())}, run, wall


def case_7_7_rolling():
    m, f = 1000 * math.pi, 1000.0
    worst_n = worst_s = worst_m = 0.0
    for d in (0.0, 0.5, 1.0, 1.5, 2.0):
        run, wall = timed("paper-7.7", 20, height=d)
        for k in range(run.steps):
            (force,), _ = corner_forces(run, 0, 1, k)
            lever = 1 + (d - 1) * math.cos(run.rotation[k, 0])
            worst_n = max(worst_n, abs(force[1] - 10 * m))
            worst_s = max(worst_s, abs(force[0] - f * (lever - 1.5) / 1.5))
        held, _ = timed("paper-7.7", 20, height=d, rolling=1.0)
        _, moment = corner_forces(held, 0, 1)
        worst_m = max(worst_m, abs(moment[0] - f * d))
    return {"|Fn - G| (N)": worst_n, "paper Fn": 0.00361, "|Fs - F(d-1.5)/1.5| (N)": worst_s, "paper Fs": 1e-5,
            "|Mr - F d| (N m)": worst_m, "paper Mr": 8.6e-4}, run, wall


def case_7_7_motion():
    m, f, g = 1000 * math.pi, 1000.0, 10 * 1000 * math.pi
    cases = {"I": (10.0, 0.0, f / (1.5 * m), -f / (1.5 * m)), "II": (0.005, 0.005, (f - 0.005 * g) / m, 0.0),
             "II'": (0.005, 0.0025, (f - 0.005 * g) / m, -0.0025 * g / (0.5 * m)),
             "III": (0.005, 0.0, (f - 0.005 * g) / m, -0.005 * g / (0.5 * m))}
    out = {}
    for label, (mu, delta, accel, alpha) in cases.items():
        run, wall = timed("paper-7.7", 500, height=1.0, friction=mu, rolling=delta)
        out[f"{label} |x(5) - x*| (m)"] = abs(run.centroid[-1, 0, 0] - 12.5 * accel)
        out[f"{label} |w(5) - w*| (rad/s)"] = abs(run.velocity[-1, 0, 2] - 5 * alpha)
    return out, run, wall


def case_7_8():
    worst = 0.0
    for h in (0.0, 0.5, 1.0):
        run, wall = timed("paper-7.8", 50, height=h)
        top = int(np.argmax(np.asarray(run.scene.model.joint_point)[:, 1]))
        worst = max(worst, abs(run.joint_tension[-1, top] - 500 * (1 + h)),
                    abs(run.joint_tension[-1, 1 - top] - 500 * (1 - h)))
    ramp, _ = timed("paper-7.8", 260, force=0.0, rate=900.0)
    return {"|P - F(H +- h)/2H| (N)": worst, "paper": 1e-5,
            "break step (ramp 900 N/s)": int(np.argmax(ramp.joint_broken.all(1)) + 1), "closed form": 223}, run, wall


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--out", default="experiments/results/paper_cases.json")
    args = parser.parse_args()
    rows = []
    for label, fn in [("7.1 fixed base", lambda: case_7_1(False)), ("7.1 heavy base", lambda: case_7_1(True)),
                      ("7.2 fixed base", lambda: case_7_2(False)), ("7.2 heavy base", lambda: case_7_2(True)),
                      ("7.2 E = 1e14", lambda: case_7_2(False, young=1e14)),
                      ("7.3 ring in frame", lambda: case_billiard("paper-7.3", 2050, 17.0)),
                      ("7.4 block in frame", lambda: case_billiard("paper-7.4", 10000, 50.0)),
                      ("7.5 fixed ring", lambda: case_7_5(False)), ("7.5 heavy ring", lambda: case_7_5(True)),
                      ("7.6 fixed base", lambda: case_7_6(False)), ("7.6 heavy base", lambda: case_7_6(True)),
                      ("7.7 rolling", case_7_7_rolling), ("7.7 motion", case_7_7_motion),
                      ("7.8 cement", case_7_8)]:
        figures, run, wall = fn()
        figures.update({"case": label, "steps": run.steps, "wall s": wall,
                        "max solver iterations": int(run.info.iterations.max()),
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
