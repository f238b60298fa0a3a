"""Speed benchmarks: jaxdda beside its peers (pymunk, Jax2D) on the same scenes, in one run.

    python experiments/benchmarks.py [--only pile,batched,scaling,warmstart,compile]
        [--sizes 100,1000,4000,10000] [--budget 300] [--quick] [--out PATH]

Every benchmark prints a markdown table and the results go to one JSON file (default
``experiments/results/benchmarks.json``; with ``--quick`` ``benchmarks_quick.json``, so a
smoke run never overwrites the real numbers). With ``--only`` the other benchmarks'
entries already in the file are kept. The peers are optional (``pip install -e .[bench]``):
a missing one is reported in its table, and the rest carries on.

The peer scenes are built from the jaxdda scene object (radii, centroids, polygon vertices,
fixed flags, masses and moments, friction, restitution, gravity, dt), so the geometry is
the same. Timings exclude compilation (each executable is compiled ahead of time and timed
separately; ``jax.block_until_ready`` before the clock stops); pymunk is timed over its
``space.step`` loop with ``time.perf_counter``.

pile       disks settling in a box (``examples.pile``), N = --sizes: body-steps per second,
           jaxdda with its contacts solved to a relative residual of ``tol`` = 1e-8 (the
           scene's), against pymunk (a fixed-iteration sequential impulse solver: its
           contact forces are not converged) at its default 10 iterations and, as extra
           rows, at 100 iterations and threaded on 2 threads. jaxdda runs in jitted
           chunks (a ``lax.scan`` of ``step``) and regrows its buffers on overflow: a
           warm-up run (compiles, settles the capacities; its chunk times are recorded
           too, compile excluded), then a timed run of the same steps from the same
           initial state with the final capacities. A run stops after --budget seconds
           (steps actually run are reported; the peers' rows cover the same steps).
scaling    cost per step against N, from the pile runs (run for it if ``pile`` is not
           selected): ms/step over the steps that every size completed (same phase of the
           settling), and over all the steps each ran. Target: 10 000 bodies cost at most
           12x 1000 bodies.
batched    the rockfall (``examples.rockfall``, one rock on two fixed slabs) for a batch of
           B initial velocities: scenario-steps per second, jaxdda vmapped (or
           ``jaxdda.monte_carlo`` when present) against pymunk run sequentially and Jax2D
           vmapped (float32, its native precision).
warmstart  solver iterations per step on a settled (static) pile: as is (each step starts
           from last step's forces), and cold (``state.contact_force`` zeroed before every
           step). Zeroing also makes every contact "new" (the step treats a contact that
           carried force last step as sustained, otherwise as a possible impact), so a
           third run, "cold, sustained kept", zeroes the forces but marks each loaded
           contact with a force of 1e-200 N: the pure effect of the solver's start.
compile    wall time of ``jax.jit(step).lower(model, state, params).compile()`` and of a
           10-step scanned chunk, for the rockfall and a pile of 1000 disks, each in a
           fresh process.
"""
from __future__ import annotations

import argparse
import dataclasses
import json
import math
import os
import pathlib
import platform
import subprocess
import sys
import time

import numpy as np

CHILD_TAG = "BENCH_CHILD "
MAX_REGROW = 8
ALL = ("pile", "scaling", "batched", "warmstart", "compile")


# -- output ------------------------------------------------------------------------------
def _fmt(v) -> str:
    if v is None:
        return "-"
    if isinstance(v, (bool, np.bool_)):
        return "yes" if v else "no"
    if isinstance(v, (float, np.floating)):
        v = float(v)
        if not math.isfinite(v):
            return str(v)
        if v == 0:
            return "0"
        if abs(v) >= 1e5:
            return f"{v:.3g}"
        if abs(v) >= 100:
            return f"{v:.0f}"
        return f"{v:.3g}"
    return str(v)


def md_table(rows: list[dict], cols: list[str]) -> str:
    cells = [[_fmt(r.get(c)) for c in cols] for r in rows]
    widths = [max(len(c), *(len(line[k]) for line in cells)) if cells else len(c) for k, c in enumerate(cols)]
    head = "| " + " | ".join(c.ljust(w) for c, w in zip(cols, widths)) + " |"
    rule = "|" + "|".join("-" * (w + 1) + ":" if k else ":" + "-" * (w + 1) for k, w in enumerate(widths)) + "|"
    body = ["| " + " | ".join((x.rjust(w) if k else x.ljust(w)) for k, (x, w) in enumerate(zip(line, widths))) + " |"
            for line in cells]
    return "\n".join([head, rule] + body)


def _json_default(x):
    if isinstance(x, np.ndarray):
        return x.tolist()
    if isinstance(x, (np.floating,)):
        return float(x)
    if isinstance(x, (np.integer,)):
        return int(x)
    if isinstance(x, (np.bool_,)):
        return bool(x)
    if dataclasses.is_dataclass(x):
        return dataclasses.asdict(x)
    return str(x)


def machine_facts() -> dict:
    import jax

    facts = {"python": platform.python_version(), "platform": platform.platform(), "cpu count": os.cpu_count(),
             "jax": jax.__version__, "backend": jax.default_backend(),
             "devices": [str(d) for d in jax.devices()], "x64": bool(jax.config.jax_enable_x64),
             "XLA_FLAGS": os.environ.get("XLA_FLAGS", "")}
    try:
        facts["cpu affinity"] = len(os.sched_getaffinity(0))
    except (AttributeError, OSError):
        pass
    try:
        facts["load average at start"] = os.getloadavg()
    except OSError:
        pass
    try:
        import jaxlib
        facts["jaxlib"] = jaxlib.__version__
    except Exception:
        pass
    try:
        cpu = [line for line in pathlib.Path("/proc/cpuinfo").read_text().splitlines() if line.startswith("model name")]
        facts["cpu model"] = cpu[0].split(":", 1)[1].strip() if cpu else None
    except OSError:
        pass
    for name in ("jaxdda", "pymunk", "jax2d", "flax"):
        facts[name] = _version(name)
    return facts


def _version(name: str) -> str | None:
    try:
        from importlib.metadata import version
        return version(name)
    except Exception:
        return None


def _peer(name: str):
    """The peer module, or the reason it is missing (a string)."""
    try:
        if name == "pymunk":
            import pymunk
            return pymunk
        if name == "jax2d":
            import jax2d.engine  # noqa: F401  (needs flax and chex)
            import jax2d
            return jax2d
    except Exception as e:  # ImportError, or a broken install
        return f"{name} not available ({type(e).__name__}: {e}); pip install -e .[bench]"
    raise ValueError(name)


def log(*args) -> None:
    print(*args, flush=True, file=sys.stderr)


# -- the scene, read from the jaxdda objects ----------------------------------------------
def scene_geometry(scene) -> dict:
    """Everything a peer needs to build the same scene: rigid disks and fixed polygons."""
    from jaxdda.types import DISK, POLYGON

    m, s, p = scene.model, scene.state, scene.params
    kind, fixed = np.asarray(m.kind), np.asarray(m.fixed)
    centroid, rotation = np.asarray(s.centroid), np.asarray(s.rotation)
    local, mask = np.asarray(m.local_vertices), np.asarray(m.vertex_mask)
    density, area, polar = np.asarray(p.density), np.asarray(m.area), np.asarray(m.polar_moment)
    material = np.asarray(m.material)
    friction, restitution, rolling = (np.asarray(t) for t in (p.friction, p.restitution, p.rolling))
    young = np.asarray(p.young)
    used = np.unique(material)
    notes = []
    if len(used) > 1:
        notes.append("several materials: peers get each shape's own (diagonal) coefficients")
    bodies = []
    for i in range(m.n_bodies):
        mi = int(material[i])
        if young[i] > 0 and not fixed[i]:
            raise ValueError(f"body {i} is deformable: the peers are rigid-body engines")
        b = {"index": i, "fixed": bool(fixed[i]), "center": centroid[i].tolist(),
             "velocity": np.asarray(s.velocity)[i, :3].tolist(), "density": float(density[i]),
             "mass": float(density[i] * area[i]), "moment": float(density[i] * polar[i]),
             "friction": float(friction[mi, mi]), "restitution": float(restitution[mi, mi]),
             "rolling": float(rolling[mi, mi])}
        if kind[i] == DISK:
            b.update(shape="disk", radius=float(np.asarray(m.radius)[i]))
        elif kind[i] == POLYGON:
            c, sn = math.cos(rotation[i]), math.sin(rotation[i])
            v = local[i][mask[i]] @ np.array([[c, sn], [-sn, c]])  # rotate counter-clockwise
            b.update(shape="polygon", vertices=(v + centroid[i]).tolist())  # world, counter-clockwise
        else:
            raise ValueError(f"body {i}: rings are not supported by the peers")
        bodies.append(b)
    return {"bodies": bodies, "gravity": np.asarray(p.gravity).tolist(), "dt": float(p.dt), "notes": notes,
            "rolling": float(np.max(rolling[np.ix_(used, used)]))}


# -- pymunk ----------------------------------------------------------------------------
def pymunk_space(geom: dict, *, iterations: int = 10, threads: int = 1, slop: float = 0.01, velocity=None, body=0):
    """A pymunk Space of the scene: static Polys for the fixed polygons, dynamic Circles
    (mass and moment from jaxdda) for the disks. pymunk multiplies the two shapes'
    friction (and elasticity), so each shape gets the square root of the pair's
    coefficient. ``velocity``: (vx, vy) of jaxdda body ``body`` instead of the scene's."""
    import pymunk

    space = pymunk.Space(threaded=threads > 1)
    if threads > 1:
        space.threads = threads
    space.gravity = tuple(geom["gravity"])
    space.iterations = iterations
    space.collision_slop = slop
    dynamic = []
    for b in geom["bodies"]:
        if b["fixed"]:
            if b["shape"] != "polygon":
                raise ValueError("fixed disks are not supported here")
            shape = pymunk.Poly(space.static_body, [tuple(v) for v in b["vertices"]])
        else:
            if b["shape"] != "disk":
                raise ValueError("free polygons are not supported here")
            body_ = pymunk.Body(b["mass"], b["moment"])
            body_.position = tuple(b["center"])
            vel = b["velocity"]
            body_.velocity = tuple(velocity) if (velocity is not None and b["index"] == body) else (vel[0], vel[1])
            body_.angular_velocity = vel[2]
            shape = pymunk.Circle(body_, b["radius"])
            space.add(body_)
            dynamic.append(body_)
        shape.friction = math.sqrt(b["friction"])
        shape.elasticity = math.sqrt(b["restitution"])
        space.add(shape)
    return space, dynamic


def pymunk_run(space, steps: int, dt: float, budget: float | None = None) -> np.ndarray:
    """Step ``steps`` times (or until ``budget`` seconds); returns the cumulative seconds after each step."""
    times = np.empty(steps)
    clock, total = time.perf_counter, 0.0
    for k in range(steps):
        t0 = clock()
        space.step(dt)
        total += clock() - t0
        times[k] = total
        if budget is not None and total > budget:
            return times[:k + 1]
    return times


def pymunk_quality(dynamic, radius: float) -> dict:
    """Largest overlap (relative to ``radius``) among the contacts, and largest speed."""
    worst = [0.0]

    def look(arb):
        for pt in arb.contact_point_set.points:
            worst[0] = max(worst[0], -pt.distance)

    for b in dynamic:
        b.each_arbiter(look)
    speed = max((b.velocity.length for b in dynamic), default=0.0)
    return {"max overlap / r": worst[0] / radius, "max speed": speed}


# -- jaxdda: chunked runs with buffer regrowth ------------------------------------------------
class Chunks:
    """AOT-compiled scans of ``length`` steps, one per (capacity, variant); compile time
    recorded apart from run time. ``variant``: "warm" (plain step), "cold" (contact
    forces zeroed before each step), "cold-sustained" (zeroed, but a loaded contact keeps
    a force of 1e-200 so that the step still treats it as sustained)."""

    def __init__(self, length: int):
        self.length = length
        self.exes: dict = {}
        self.compile_s: list[float] = []

    def _fn(self, variant: str):
        import jax
        import jax.numpy as jnp

        from jaxdda.step import step

        def prepare(s):
            if variant == "warm":
                return s
            f = s.contact_force
            if variant == "cold":
                return dataclasses.replace(s, contact_force=jnp.zeros_like(f))
            marker = jnp.where(f[:, :1] > 0, 1e-200, 0.0)
            return dataclasses.replace(s, contact_force=jnp.concatenate([marker, jnp.zeros_like(f[:, 1:])], 1))

        def run(model, state, params):
            def body(s, _):
                s2, info = step(model, prepare(s), params)
                speed = jnp.max(jnp.where(model.fixed, 0.0, jnp.linalg.norm(s2.velocity[:, :2], axis=1)), initial=0.0)
                return s2, {"iterations": info.iterations, "converged": info.converged, "residual": info.residual,
                            "overflow": info.overflow, "needed": info.needed, "contacts": info.n_contacts,
                            "penetration": info.max_penetration, "speed": speed}
            return jax.lax.scan(body, state, None, length=self.length)
        return run

    def get(self, model, state, params, variant: str = "warm"):
        import jax

        key = (model.capacity, variant)
        if key not in self.exes:
            t0 = time.perf_counter()
            self.exes[key] = jax.jit(self._fn(variant)).lower(model, state, params).compile()
            self.compile_s.append(time.perf_counter() - t0)
            log(f"    compiled a {self.length}-step chunk ({variant}, {model.capacity}) in {self.compile_s[-1]:.1f} s")
        return self.exes[key]


def run_chunks(chunks: Chunks, model, state, params, steps: int, *, budget: float | None = None,
               variant: str = "warm", label: str = "") -> dict:
    """Run ``steps`` (rounded up to whole chunks) or until ``budget`` seconds of run time;
    an overflowing chunk regrows the buffers and is run again (its time goes to
    ``wasted s``, not to ``seconds``)."""
    import jax

    from jaxdda.simulate import with_capacity
    from jaxdda.types import Capacities

    done, seconds, wasted, regrows = 0, 0.0, 0.0, 0
    chunk_s, diags = [], []
    n_compiled = len(chunks.compile_s)
    t_start = time.perf_counter()
    while done < steps and (budget is None or seconds < budget):
        for _ in range(MAX_REGROW):
            exe = chunks.get(model, state, params, variant)
            t0 = time.perf_counter()
            end, d = exe(model, state, params)
            jax.block_until_ready(end)
            dt = time.perf_counter() - t0
            d = {k: np.asarray(v) for k, v in d.items()}
            if not d["overflow"].any():
                break
            wasted += dt
            regrows += 1
            need = Capacities(*d["needed"].max(0).tolist())
            model, state = with_capacity(model, state, model.capacity.grown(need))
        else:
            raise RuntimeError(f"{label}: buffers kept overflowing ({model.capacity})")
        state, done, seconds = end, done + chunks.length, seconds + dt
        chunk_s.append(dt)
        diags.append(d)
        if len(chunk_s) % 10 == 0 or done >= steps:
            log(f"    {label} {variant}: {done} steps, {seconds:.1f} s run, "
                f"{np.mean(d['iterations']):.0f} iterations/step in the last chunk")
    cat = {k: np.concatenate([d[k] for d in diags]) for k in diags[0]} if diags else {}
    return {"model": model, "state": state, "steps": done, "seconds": seconds, "chunk seconds": chunk_s,
            "wasted s": wasted, "regrows": regrows, "compile s": sum(chunks.compile_s[n_compiled:]),
            "wall s": time.perf_counter() - t_start, "diag": cat,
            "budget hit": bool(budget is not None and done < steps)}


def _iter_stats(diag: dict) -> dict:
    it = diag.get("iterations", np.zeros(0))
    if it.size == 0:
        return {}
    return {"iterations/step": float(np.mean(it)), "median iterations": float(np.median(it)),
            "max iterations": int(np.max(it)), "converged": float(np.mean(diag["converged"])),
            "max residual": float(np.max(diag["residual"])), "contacts (last)": int(diag["contacts"][-1])}


def presized(model, state, n: int):
    """Capacities for a settled pile of ``n`` disks (about 3 pair contacts per disk and
    the walls' contacts), so that the warm-up regrows once or twice instead of five
    times (each regrowth is a compilation). The run still regrows if they fall short."""
    from jaxdda.simulate import with_capacity
    from jaxdda.types import Capacities

    cap = model.capacity
    side = 4 * int(math.ceil(math.sqrt(n))) + 8
    need = Capacities(candidates=cap.candidates, pairs_pp=max(cap.pairs_pp, 3 * n), pairs_pb=max(cap.pairs_pb, side),
                      pairs_bb=cap.pairs_bb, contacts=max(cap.contacts, 3 * n + 2 * side))
    return with_capacity(model, state, cap.grown(need))


# -- pile ------------------------------------------------------------------------------------
def bench_pile(args) -> dict:
    from jaxdda.examples.practical import pile
    from jaxdda.simulate import with_capacity

    pymunk = _peer("pymunk")
    rows, runs, finals = [], [], {}
    for n in args.sizes:
        log(f"pile N={n}")
        scene = pile(n=n, friction=args.friction, tol=args.tol)
        params = scene.params
        free = int(np.sum(~np.asarray(scene.model.fixed)))
        radius = float(np.mean(np.asarray(scene.model.radius)[~np.asarray(scene.model.fixed)]))
        chunks = Chunks(args.chunk)
        model, state = presized(scene.model, scene.state, n) if args.presize else (scene.model, scene.state)
        warm = run_chunks(chunks, model, state, params, args.steps, budget=args.budget, label=f"N={n} warm-up")
        model, state = with_capacity(scene.model, scene.state, warm["model"].capacity)
        timed = run_chunks(chunks, model, state, params, warm["steps"], label=f"N={n} timed")
        steps = timed["steps"]
        d = timed["diag"]
        entry = {"N": n, "free bodies": free, "steps requested": args.steps, "steps": steps, "dt": float(params.dt),
                 "tol": float(params.tol), "friction": args.friction, "chunk": args.chunk,
                 "budget hit": warm["budget hit"], "capacity": dataclasses.asdict(timed["model"].capacity),
                 "jaxdda": {"seconds": timed["seconds"], "chunk seconds": timed["chunk seconds"],
                            "warm-up seconds (compile excluded)": warm["seconds"],
                            "warm-up wasted s (overflowed chunks)": warm["wasted s"],
                            "regrows (warm-up)": warm["regrows"], "regrows (timed)": timed["regrows"],
                            "compile s": warm["compile s"] + timed["compile s"],
                            "iterations": d["iterations"], "converged": d["converged"], "residual": d["residual"],
                            "contacts": d["contacts"], **_iter_stats(d),
                            "final max overlap / r": float(d["penetration"][-1]) / radius,
                            "final max speed": float(d["speed"][-1])}}
        finals[n] = (scene, timed["model"], timed["state"], steps)
        jrow = {"N": n, "engine": "jaxdda", "steps": steps, "s": timed["seconds"],
                "ms/step": 1e3 * timed["seconds"] / steps, "body-steps/s": free * steps / timed["seconds"],
                "iters/step": entry["jaxdda"].get("iterations/step"),
                "max iters": entry["jaxdda"].get("max iterations"),
                "converged": entry["jaxdda"].get("converged"), "max residual": entry["jaxdda"].get("max residual"),
                "overlap/r": entry["jaxdda"]["final max overlap / r"], "max speed": entry["jaxdda"]["final max speed"],
                "note": "budget hit" if warm["budget hit"] else ""}
        rows.append(jrow)
        if isinstance(pymunk, str):
            rows.append({"N": n, "engine": "pymunk", "note": pymunk})
            entry["pymunk"] = pymunk
        else:
            geom = scene_geometry(scene)
            entry["pymunk"] = []
            variants = [("pymunk (10 it)", 10, 1), ("pymunk (100 it)", 100, 1), ("pymunk (10 it, 2 threads)", 10, 2)]
            for name, iterations, threads in variants:
                space, dynamic = pymunk_space(geom, iterations=iterations, threads=threads, slop=args.pymunk_slop)
                # The same steps as jaxdda's timed run first, then on to the full --steps.
                cum = pymunk_run(space, max(steps, args.steps), geom["dt"], budget=args.budget)
                k = min(steps, len(cum))
                q = pymunk_quality(dynamic, radius)
                entry["pymunk"].append({"variant": name, "iterations": iterations, "threads": threads,
                                        "collision_slop": args.pymunk_slop,
                                        "seconds (jaxdda's steps)": float(cum[k - 1]), "steps (jaxdda's)": k,
                                        "seconds (all)": float(cum[-1]), "steps (all)": len(cum),
                                        "body-steps/s (all)": free * len(cum) / float(cum[-1]), **q})
                rows.append({"N": n, "engine": name, "steps": k, "s": float(cum[k - 1]),
                             "ms/step": 1e3 * cum[k - 1] / k, "body-steps/s": free * k / float(cum[k - 1]),
                             "overlap/r": q["max overlap / r"], "max speed": q["max speed"],
                             "note": f"after {len(cum)} steps" if len(cum) != k else ""})
                log(f"    {name}: {rows[-1]['body-steps/s']:.3g} body-steps/s")
        runs.append(entry)
    notes = ["jaxdda: contacts solved to the relative VI residual tol (iters/step: projection-contraction "
             "iterations of the impact and contact solves together); warm-up run first, compile excluded.",
             "pymunk: a fixed-iteration sequential impulse solver (Chipmunk2D): its contact forces are not converged "
             "(no residual to report); 'it' = space.iterations. collision_slop set to "
             f"{args.pymunk_slop} m (pymunk's default 0.1 is for pixel units); no sleeping.",
             "overlap/r: largest overlap at the end over the mean radius; max speed at the end (m/s): how settled.",
             "body-steps/s counts the free disks (not the 3 walls)."]
    cols = ["N", "engine", "steps", "s", "ms/step", "body-steps/s", "iters/step", "max iters", "converged",
            "max residual", "overlap/r", "max speed", "note"]
    print("\n## pile: disks settling in a box (body-steps per second)\n")
    print(md_table(rows, cols))
    print("\n" + "\n".join(f"- {x}" for x in notes))
    target = _pile_target(runs)
    if target:
        print(f"- target (N=1000, jaxdda >= pymunk 10 it): {target}")
    return {"runs": runs, "rows": rows, "notes": notes, "target": target, "_finals": finals}


def _pile_target(runs) -> str | None:
    for r in runs:
        if r["N"] == 1000 and isinstance(r.get("pymunk"), list):
            j = r["free bodies"] * r["steps"] / r["jaxdda"]["seconds"]
            p = r["pymunk"][0]
            pm = r["free bodies"] * p["steps (jaxdda's)"] / p["seconds (jaxdda's steps)"]
            return f"jaxdda {j:.3g} vs pymunk {pm:.3g} body-steps/s: {'met' if j >= pm else 'NOT met'} (x{j / pm:.3g})"
    return None


# -- scaling -----------------------------------------------------------------------------
def bench_scaling(pile_result: dict) -> dict:
    runs = pile_result["runs"]
    common = min(r["steps"] for r in runs)
    rows = []
    for r in runs:
        j = r["jaxdda"]
        chunk = r["chunk"]
        k = common // chunk
        prefix_s = sum(j["chunk seconds"][:k])
        it = np.asarray(j["iterations"])
        rows.append({"N": r["N"], "steps (common)": common, "ms/step (common)": 1e3 * prefix_s / common,
                     "iters/step (common)": float(np.mean(it[:common])),
                     "us/iteration (common)": 1e6 * prefix_s / max(1, int(np.sum(it[:common]))),
                     "steps (all)": r["steps"], "ms/step (all)": 1e3 * j["seconds"] / r["steps"],
                     "iters/step (all)": float(np.mean(it))})
    ref = next((x for x in rows if x["N"] == 1000), rows[0])
    for x in rows:
        x["x cost of ref (common)"] = x["ms/step (common)"] / ref["ms/step (common)"]
        x["x N of ref"] = x["N"] / ref["N"]
    target = None
    big = next((x for x in rows if x["N"] == 10000), None)
    if big is not None and ref["N"] == 1000:
        ratio = big["ms/step (common)"] / ref["ms/step (common)"]
        target = f"10 000 / 1000 bodies: x{ratio:.3g} per step over the first {common} steps: " \
                 f"{'met' if ratio <= 12 else 'NOT met'} (target <= 12)"
    notes = [f"'common': the first {common} steps, which every size ran (the same phase of the settling; "
             "the grid start falls freely for about 15 steps, then collapses).",
             "us/iteration: run time over the total solver iterations (a rough cost of one iteration).",
             f"reference size: N={ref['N']}."]
    print("\n## scaling: jaxdda cost per step against N (from the pile runs)\n")
    print(md_table(rows, ["N", "steps (common)", "ms/step (common)", "iters/step (common)", "us/iteration (common)",
                          "x cost of ref (common)", "x N of ref", "steps (all)", "ms/step (all)", "iters/step (all)"]))
    print("\n" + "\n".join(f"- {x}" for x in notes))
    if target:
        print(f"- target: {target}")
    return {"rows": rows, "notes": notes, "target": target}


# -- batched rockfall ----------------------------------------------------------------------
class OwnBatch:
    """jaxdda vmapped over the initial velocity of body ``body``: a jitted scan of
    ``vmap(step)``, with buffer regrowth. Same interface as the library driver below."""

    def __init__(self, scene, steps: int, body: int = 0):
        self.scene, self.steps, self.body = scene, steps, body
        self.model, self.state = scene.model, scene.state
        self.exes, self.compile_s = {}, []

    def _fn(self):
        import jax
        import jax.numpy as jnp

        from jaxdda.step import step

        body_i, steps = self.body, self.steps

        def run(model, state0, params, velocity):
            states = jax.vmap(lambda v: dataclasses.replace(
                state0, velocity=state0.velocity.at[body_i, :2].set(v)))(velocity)

            def one_step(s, _):
                s2, info = jax.vmap(step, in_axes=(None, 0, None))(model, s, params)
                speed = jnp.linalg.norm(s2.velocity[:, body_i, :2], axis=-1)
                return s2, (info.overflow, info.needed, info.iterations, speed)

            end, (overflow, needed, iterations, speed) = jax.lax.scan(one_step, states, None, length=steps)
            return {"final_centroid": end.centroid[:, body_i], "max_speed": jnp.max(speed, 0),
                    "overflow": jnp.any(overflow), "needed": jnp.max(needed, (0, 1)),
                    "iterations": jnp.max(iterations, 1)}
        return run

    def __call__(self, velocity) -> dict:
        import jax

        from jaxdda.simulate import with_capacity
        from jaxdda.types import Capacities

        params = self.scene.params
        for _ in range(MAX_REGROW):
            key = (self.model.capacity, velocity.shape)
            if key not in self.exes:
                t0 = time.perf_counter()
                self.exes[key] = jax.jit(self._fn()).lower(self.model, self.state, params, velocity).compile()
                self.compile_s.append(time.perf_counter() - t0)
            out = self.exes[key](self.model, self.state, params, velocity)
            out = {k: np.asarray(v) for k, v in jax.block_until_ready(out).items()}
            if not out["overflow"]:
                return out
            self.model, self.state = with_capacity(self.model, self.state,
                                                   self.model.capacity.grown(Capacities(*out["needed"].tolist())))
        raise RuntimeError("rockfall batch: buffers kept overflowing")


class LibraryBatch:
    """``jaxdda.monte_carlo`` (when the library has it): compiles on its first call."""

    def __init__(self, scene, steps: int, body: int = 0):
        self.scene, self.steps, self.body, self.compile_s = scene, steps, body, []

    def __call__(self, velocity) -> dict:
        import jaxdda

        # chunk = steps: one compiled chunk, no skipped tail (vmapped, a skipped step still costs).
        res = jaxdda.monte_carlo(self.scene, self.steps, velocity=velocity, body=self.body,
                                 observe=("final_centroid", "max_speed"), progress=False, chunk=self.steps)
        out = {k: np.asarray(v) for k, v in res.observables.items()}
        if out["final_centroid"].ndim == 3:  # (B, bodies, 2): keep the rock's
            out["final_centroid"] = out["final_centroid"][:, self.body]
        return out


def jaxdda_batch_driver(kind: str):
    import jaxdda

    if kind == "auto":
        kind = "monte_carlo" if hasattr(jaxdda, "monte_carlo") else "own"
    return (LibraryBatch if kind == "monte_carlo" else OwnBatch), kind


def jax2d_rockfall(geom: dict):
    """(engine, static params, params, initial SimState, index of the rock among the circles)
    for the scene: fixed polygons and free disks, float32 (build inside ``jax.enable_x64(False)``).
    Jax2D's friction is sqrt((f_a b)^2 + (f_b b)^2) with base b: b = 1 and f = mu / sqrt(2) per
    shape give the pair mu; its restitution is the smaller of the two: e per shape."""
    import jax.numpy as jnp
    from jax2d.engine import PhysicsEngine, create_empty_sim
    from jax2d.scene import add_circle_to_scene, add_polygon_to_scene
    from jax2d.sim_state import SimParams, StaticSimParams

    polys = [b for b in geom["bodies"] if b["shape"] == "polygon"]
    disks = [b for b in geom["bodies"] if b["shape"] == "disk"]
    nv = max(len(b["vertices"]) for b in polys)
    if nv > 4:
        raise ValueError("Jax2D's circle-polygon test handles at most 4 vertices")
    # One inactive padding polygon and circle: Jax2D fails to build with no polygon-polygon
    # or no circle-circle pair. The fixed polygons are "static fixated" (no pairs among them).
    ssp = StaticSimParams(num_polygons=len(polys) + 1, num_circles=max(2, len(disks)), num_joints=1,
                          num_thrusters=1, max_polygon_vertices=4, num_static_fixated_polys=len(polys))
    span = max(abs(x) for b in geom["bodies"] for x in (b.get("center") or [0.0])) + 1e3
    sp = SimParams(dt=geom["dt"], base_friction=1.0, clip_position=span)  # clip_position: default 15 m
    st = create_empty_sim(ssp, add_floor=False, add_walls_and_ceiling=False)
    for b in polys:
        v = np.asarray(b["vertices"]) - np.asarray(b["center"])
        v = v[::-1]  # Jax2D wants clockwise, starting at the top-left vertex
        first = int(np.lexsort((v[:, 0], -v[:, 1]))[0])
        v = np.roll(v, -first, axis=0)
        st, _ = add_polygon_to_scene(st, ssp, jnp.asarray(b["center"], jnp.float32), jnp.asarray(v, jnp.float32),
                                     len(v), density=b["density"], friction=b["friction"] / math.sqrt(2),
                                     restitution=b["restitution"], fixated=b["fixed"])
    for b in disks:
        st, _ = add_circle_to_scene(st, ssp, jnp.asarray(b["center"], jnp.float32), b["radius"],
                                    velocity=jnp.asarray(b["velocity"][:2], jnp.float32),
                                    angular_velocity=b["velocity"][2], density=b["density"],
                                    friction=b["friction"] / math.sqrt(2), restitution=b["restitution"],
                                    fixated=b["fixed"])
    st = st.replace(gravity=jnp.asarray(geom["gravity"], jnp.float32))
    return PhysicsEngine(ssp), ssp, sp, st


def best_of(fn, repeats: int, max_total: float = 10.0):
    """(best seconds, last result, all timings) of up to ``repeats`` calls, stopping once
    the calls have taken ``max_total`` seconds together (a shared machine is noisy)."""
    times, out = [], None
    while len(times) < max(1, repeats) and sum(times) < max_total:
        t0 = time.perf_counter()
        out = fn()
        times.append(time.perf_counter() - t0)
    return min(times), out, times


def bench_batched(args) -> dict:
    import jax

    from jaxdda.examples.practical import rockfall

    scene = rockfall()
    geom = scene_geometry(scene)
    body = 0
    steps = args.batch_steps
    rng = np.random.default_rng(0)
    pymunk, jax2d = _peer("pymunk"), _peer("jax2d")
    Driver, driver_kind = jaxdda_batch_driver(args.driver)
    rows, entries = [], []
    jax2d_setup = None
    if not isinstance(jax2d, str):
        with jax.enable_x64(False):
            jax2d_setup = jax2d_rockfall(geom)
    for B in args.batches:
        log(f"rockfall batch B={B}")
        velocity = np.stack([rng.uniform(0.0, 2.0, B), rng.uniform(-2.0, 0.0, B)], 1)
        entry = {"B": B, "steps": steps, "velocity": velocity}
        # jaxdda
        drive = Driver(scene, steps, body)
        t0 = time.perf_counter()
        drive(velocity)  # compile, settle the capacities
        first = time.perf_counter() - t0
        sec, out, times = best_of(lambda: drive(velocity), args.repeats)
        x = out["final_centroid"][:, 0]
        entry["jaxdda"] = {"driver": driver_kind, "seconds": sec, "all timings": times, "first call s": first,
                           "compile s": sum(drive.compile_s), "final x": x,
                           "max iterations": out.get("iterations")}
        rows.append({"B": B, "engine": f"jaxdda vmap ({driver_kind})", "s": sec,
                     "scenario-steps/s": B * steps / sec, "mean final x": float(np.mean(x)),
                     "max final x": float(np.max(x))})
        # pymunk, one scenario after another
        if isinstance(pymunk, str):
            rows.append({"B": B, "engine": "pymunk sequential", "note": pymunk})
        else:
            def sequential():
                total, xs = 0.0, []
                for v in velocity:
                    space, dynamic = pymunk_space(geom, slop=args.pymunk_slop, velocity=v, body=body)
                    total += float(pymunk_run(space, steps, geom["dt"])[-1])
                    xs.append(dynamic[0].position.x)
                return total, xs

            runs = [sequential()]
            while len(runs) < args.repeats and sum(r[0] for r in runs) < 10.0:
                runs.append(sequential())
            total, xs = min(runs, key=lambda r: r[0])
            entry["pymunk"] = {"seconds": total, "all timings": [r[0] for r in runs], "final x": xs,
                               "iterations": 10, "collision_slop": args.pymunk_slop}
            rows.append({"B": B, "engine": "pymunk sequential (10 it)", "s": total,
                         "scenario-steps/s": B * steps / total, "mean final x": float(np.mean(xs)),
                         "max final x": float(np.max(xs))})
        # Jax2D, vmapped
        if isinstance(jax2d, str):
            rows.append({"B": B, "engine": "Jax2D vmap", "note": jax2d})
        else:
            with jax.enable_x64(False):
                import jax.numpy as jnp

                engine, ssp, sp, st0 = jax2d_setup
                actions = jnp.zeros(ssp.num_joints + ssp.num_thrusters)

                def run(vel):
                    def one(v):
                        s = st0.replace(circle=st0.circle.replace(velocity=st0.circle.velocity.at[body].set(v)))

                        def f(s, _):
                            return engine.step(s, sp, actions)[0], None
                        return jax.lax.scan(f, s, None, length=steps)[0].circle.position[body]
                    return jax.vmap(one)(vel)

                vel32 = jnp.asarray(velocity, jnp.float32)
                t0 = time.perf_counter()
                exe = jax.jit(run).lower(vel32).compile()
                comp = time.perf_counter() - t0
                jax.block_until_ready(exe(vel32))
                sec, pos, times = best_of(lambda: np.asarray(jax.block_until_ready(exe(vel32))), args.repeats)
            entry["jax2d"] = {"seconds": sec, "all timings": times, "compile s": comp, "final x": pos[:, 0],
                              "iterations": ssp.num_solver_iterations}
            rows.append({"B": B, "engine": "Jax2D vmap (10 it, float32)", "s": sec,
                         "scenario-steps/s": B * steps / sec, "mean final x": float(np.mean(pos[:, 0])),
                         "max final x": float(np.max(pos[:, 0]))})
        base = next((r for r in rows[-3:] if r["engine"].startswith("pymunk") and "s" in r), None)
        for r in rows[-3:]:
            if base and r.get("s"):
                r["x pymunk seq"] = r["scenario-steps/s"] / base["scenario-steps/s"]
        entries.append(entry)
        log("    " + ", ".join(f"{r['engine']}: {r.get('scenario-steps/s', 0):.3g}" for r in rows[-3:]))
    notes = [f"rockfall: one rock (disk r=0.5 m, density 2650) on a 59 degree face onto a flat run-out, {steps} steps "
             f"of {geom['dt']} s; B initial velocities vx in [0, 2], vy in [-2, 0] m/s; friction "
             f"{geom['bodies'][0]['friction']}, rolling resistance {geom['rolling']} m, restitution "
             f"{geom['bodies'][0]['restitution']}.",
             "Neither peer has rolling resistance (jaxdda's rock is slowed by it), so their rocks run out further: "
             "'final x' differs by physics, not by error.",
             "pymunk and Jax2D are fixed-iteration sequential impulse solvers (10 iterations, not converged); Jax2D "
             "runs in float32 (its native precision), jaxdda in float64 with contacts solved to tol "
             f"{float(scene.params.tol):g}.",
             "vmapped solves iterate until the slowest scenario of the batch has converged.",
             "pymunk sequential: the sum of each scenario's space.step loop (building the spaces excluded).",
             f"best of up to {args.repeats} timed calls per engine (fewer once the calls took 10 s); compile excluded."]
    print("\n## batched: the rockfall for B initial velocities (scenario-steps per second)\n")
    print(md_table(rows, ["B", "engine", "s", "scenario-steps/s", "x pymunk seq", "mean final x", "max final x",
                          "note"]))
    print("\n" + "\n".join(f"- {x}" for x in notes))
    target = None
    B = max(args.batches)
    mine = [r for r in rows if r["B"] == B]
    j = next((r for r in mine if r["engine"].startswith("jaxdda")), None)
    pm = next((r for r in mine if r["engine"].startswith("pymunk") and "s" in r), None)
    j2 = next((r for r in mine if r["engine"].startswith("Jax2D") and "s" in r), None)
    if j and pm:
        a = j["scenario-steps/s"] / pm["scenario-steps/s"]
        target = f"B={B}: jaxdda x{a:.3g} pymunk sequential ({'met' if a >= 10 else 'NOT met'}, target >= 10)"
        if j2:
            b = j["scenario-steps/s"] / j2["scenario-steps/s"]
            target += f"; x{b:.3g} Jax2D vmapped ({'met' if b > 1 else 'NOT met'}, target > 1)"
        print(f"- target: {target}")
    return {"runs": entries, "rows": rows, "notes": notes, "target": target}


# -- warm start ---------------------------------------------------------------------------
def bench_warmstart(args, finals: dict) -> dict:
    from jaxdda.examples.practical import pile

    n = args.static_n
    chunks = Chunks(args.chunk)
    if n in finals and finals[n][3] >= args.settle:  # reuse the pile benchmark's run
        scene, model, state, settled_steps = finals[n]
        log(f"warm start: N={n}, reusing the pile run's final state ({settled_steps} steps)")
    else:
        log(f"warm start: settling a pile of N={n} for {args.settle} steps")
        scene = pile(n=n, friction=args.friction, tol=args.tol)
        model, state = presized(scene.model, scene.state, n) if args.presize else (scene.model, scene.state)
        r = run_chunks(chunks, model, state, scene.params, args.settle, label=f"N={n} settle")
        model, state, settled_steps = r["model"], r["state"], r["steps"]
    params = scene.params
    speed0 = float(np.max(np.linalg.norm(np.asarray(state.velocity)[~np.asarray(model.fixed), :2], axis=1)))
    rows, entries = [], {}
    for variant in ("warm", "cold", "cold-sustained"):
        r = run_chunks(chunks, model, state, params, args.static_steps, variant=variant, label=f"N={n} static")
        d = r["diag"]
        st = _iter_stats(d)
        entries[variant] = {"steps": r["steps"], "seconds": r["seconds"], "compile s": r["compile s"],
                            "iterations": d["iterations"], "converged": d["converged"], "residual": d["residual"],
                            "final max speed": float(d["speed"][-1]), **st}
        rows.append({"start": {"warm": "warm (last step's forces)", "cold": "cold (forces zeroed)",
                               "cold-sustained": "cold, sustained kept"}[variant],
                     "steps": r["steps"], "iters/step": st["iterations/step"],
                     "median iters": st["median iterations"], "max iters": st["max iterations"],
                     "converged": st["converged"], "max residual": st["max residual"],
                     "ms/step": 1e3 * r["seconds"] / r["steps"], "final max speed": float(d["speed"][-1])})
    w = rows[0]["iters/step"]
    for r in rows:
        r["x warm"] = r["iters/step"] / w if w else None
    ratio = rows[1]["iters/step"] / w if w else float("inf")
    target = f"cold / warm iterations per step: x{ratio:.3g} ({'met' if ratio >= 5 else 'NOT met'}, target >= 5)"
    notes = [f"a pile of {n} disks settled for {settled_steps} steps (largest speed then {speed0:.3g} m/s), "
             f"then {args.static_steps} more steps each way from that same state.",
             "cold zeroes state.contact_force before every step: besides the solver's start, every contact then "
             "counts as new (not sustained), so it also goes through the impact solve as a possible impact.",
             "cold, sustained kept: forces zeroed but a contact that carried force keeps 1e-200 N, so it is still "
             "treated as sustained: only the solver's starting point differs from warm."]
    print(f"\n## warm start: solver iterations per step on a static pile (N={n})\n")
    print(md_table(rows, ["start", "steps", "iters/step", "x warm", "median iters", "max iters", "converged",
                          "max residual", "ms/step", "final max speed"]))
    print("\n" + "\n".join(f"- {x}" for x in notes))
    print(f"- target: {target}")
    return {"N": n, "settle steps": settled_steps, "speed before": speed0, "runs": entries, "rows": rows,
            "notes": notes, "target": target}


# -- compile (fresh process per scene) ----------------------------------------------------
def compile_child(scene_name: str, chunk: int) -> dict:
    import jax

    from jaxdda.examples.practical import pile, rockfall

    if scene_name == "rockfall":
        scene = rockfall()
    else:
        scene = pile(n=int(scene_name.split("-")[1]))
    jax.block_until_ready(scene.state.centroid)
    from jaxdda.step import step

    out = {"scene": scene_name, "bodies": scene.n_bodies}
    t0 = time.perf_counter()
    lowered = jax.jit(step).lower(scene.model, scene.state, scene.params)
    t1 = time.perf_counter()
    lowered.compile()
    t2 = time.perf_counter()
    out.update({"step trace+lower s": t1 - t0, "step compile s": t2 - t1, "step total s": t2 - t0})
    jax.clear_caches()
    chunks = Chunks(chunk)
    t0 = time.perf_counter()
    lowered = jax.jit(chunks._fn("warm")).lower(scene.model, scene.state, scene.params)
    t1 = time.perf_counter()
    lowered.compile()
    t2 = time.perf_counter()
    out.update({"chunk steps": chunk, "chunk trace+lower s": t1 - t0, "chunk compile s": t2 - t1,
                "chunk total s": t2 - t0})
    return out


def bench_compile(args) -> dict:
    rows = []
    for name in args.compile_scenes:
        log(f"compile: {name} (fresh process)")
        cmd = [sys.executable, os.path.abspath(__file__), "--child", name, "--chunk", str(args.chunk)]
        t0 = time.perf_counter()
        proc = subprocess.run(cmd, capture_output=True, text=True)
        wall = time.perf_counter() - t0
        lines = [line for line in proc.stdout.splitlines() if line.startswith(CHILD_TAG)]
        if proc.returncode != 0 or not lines:
            rows.append({"scene": name, "error": f"exit {proc.returncode}: {proc.stderr.strip().splitlines()[-1:]}"})
            continue
        out = json.loads(lines[-1][len(CHILD_TAG):])
        out["process wall s"] = wall
        rows.append(out)
    ok = [r for r in rows if "step total s" in r]
    worst = max((r["step total s"] for r in ok), default=None)
    target = None if worst is None else \
        f"slowest jit(step) compile {worst:.3g} s ({'met' if worst <= 10 else 'NOT met'}, target <= 10 s)"
    notes = ["trace+lower: jax.jit(fn).lower(model, state, params); compile: .compile() (XLA). Each scene in a "
             "fresh process (no persistent compilation cache); the chunk after jax.clear_caches().",
             "a new buffer capacity (regrowth) or batch size means one more compilation of the same cost."]
    print("\n## compile: jit compile time of a scene\n")
    print(md_table(rows, ["scene", "bodies", "step trace+lower s", "step compile s", "step total s", "chunk steps",
                          "chunk trace+lower s", "chunk compile s", "chunk total s", "error"]))
    print("\n" + "\n".join(f"- {x}" for x in notes))
    if target:
        print(f"- target: {target}")
    return {"rows": rows, "notes": notes, "target": target}


# -- main --------------------------------------------------------------------------------
def _ints(text: str) -> list[int]:
    return [int(x) for x in text.split(",") if x.strip()]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--only", default=",".join(ALL), help="comma-separated subset of " + ",".join(ALL))
    parser.add_argument("--sizes", default=None, help="pile sizes N (default 100,1000,4000,10000; quick 20,50)")
    parser.add_argument("--steps", type=int, default=None, help="pile steps (default 300; quick 60)")
    parser.add_argument("--budget", type=float, default=None,
                        help="seconds of run time per pile run (jaxdda warm-up, timed; each pymunk variant); "
                             "default 300, quick 60")
    parser.add_argument("--chunk", type=int, default=10, help="steps per jitted chunk (steps round up to it)")
    parser.add_argument("--friction", type=float, default=0.5, help="pile friction (0.5: a granular pile that comes to rest)")
    parser.add_argument("--tol", type=float, default=1e-8, help="pile: relative residual of the contact solve")
    parser.add_argument("--no-presize", dest="presize", action="store_false",
                        help="start the pile from the scene's own capacities (more regrowths, compilations)")
    parser.add_argument("--pymunk-slop", type=float, default=0.01, help="pymunk collision_slop (m)")
    parser.add_argument("--batches", default=None, help="rockfall batch sizes (default 1,64,1024; quick 1,8)")
    parser.add_argument("--batch-steps", type=int, default=None, help="rockfall steps (default 300; quick 50)")
    parser.add_argument("--repeats", type=int, default=3,
                        help="batched: timed calls per engine, the best kept (stops after 10 s of calls)")
    parser.add_argument("--driver", choices=["auto", "own", "monte_carlo"], default="auto",
                        help="jaxdda batched driver: jaxdda.monte_carlo when present (auto), or this script's vmap")
    parser.add_argument("--static-n", type=int, default=None, help="warm start pile size (default 200; quick 20)")
    parser.add_argument("--settle", type=int, default=None, help="warm start settling steps (default 400; quick 100)")
    parser.add_argument("--static-steps", type=int, default=None,
                        help="warm start measured steps (default 50; quick 20)")
    parser.add_argument("--compile-scenes", default=None, help="default rockfall,pile-1000 (quick rockfall,pile-100)")
    parser.add_argument("--quick", action="store_true", help="a tiny smoke run of everything")
    parser.add_argument("--out", default=None)
    parser.add_argument("--child", default=None, help=argparse.SUPPRESS)
    args = parser.parse_args()

    if args.child:
        import jaxdda  # noqa: F401  (float64)
        print(CHILD_TAG + json.dumps(compile_child(args.child, args.chunk), default=_json_default), flush=True)
        return

    q = args.quick
    args.sizes = _ints(args.sizes or ("20,50" if q else "100,1000,4000,10000"))
    args.steps = args.steps or (60 if q else 300)
    args.budget = args.budget if args.budget is not None else (60.0 if q else 300.0)
    args.batches = _ints(args.batches or ("1,8" if q else "1,64,1024"))
    args.batch_steps = args.batch_steps or (50 if q else 300)
    args.static_n = args.static_n or (20 if q else 200)
    args.settle = args.settle or (100 if q else 400)
    args.static_steps = args.static_steps or (20 if q else 50)
    args.compile_scenes = (args.compile_scenes or ("rockfall,pile-100" if q else "rockfall,pile-1000")).split(",")
    only = [x.strip() for x in args.only.split(",") if x.strip()]
    unknown = set(only) - set(ALL)
    if unknown:
        parser.error(f"unknown benchmark(s) {sorted(unknown)}; choose from {ALL}")
    out_path = pathlib.Path(args.out or f"experiments/results/benchmarks{'_quick' if q else ''}.json")

    import jaxdda  # noqa: F401  (float64)

    facts = machine_facts()
    print("# jaxdda benchmarks\n")
    print(f"{facts.get('cpu count')} CPUs ({facts.get('cpu model')}), jax {facts['jax']} on {facts['backend']} "
          f"({', '.join(facts['devices'])}), load average at start {facts.get('load average at start')}; "
          f"pymunk {facts['pymunk']}, jax2d {facts['jax2d']}{' (quick run)' if q else ''}")

    results = {}
    if out_path.exists():  # keep the benchmarks not rerun now
        try:
            old = json.loads(out_path.read_text())
            results = {k: v for k, v in old.get("benchmarks", {}).items() if k not in only}
        except (OSError, ValueError):
            results = {}
    settings = {k: v for k, v in vars(args).items() if k not in ("child", "out", "only")}

    def save():
        out_path.parent.mkdir(parents=True, exist_ok=True)
        clean = {k: {kk: vv for kk, vv in v.items() if not kk.startswith("_")} for k, v in results.items()}
        out_path.write_text(json.dumps({"machine": facts, "settings": settings, "quick": q,
                                        "benchmarks": clean}, indent=1, default=_json_default))

    stamp = lambda: time.strftime("%Y-%m-%d %H:%M:%S")
    finals = {}
    pile_result = None
    if "pile" in only or "scaling" in only:
        pile_result = bench_pile(args)
        finals = pile_result["_finals"]
        if "pile" in only:
            results["pile"] = {**pile_result, "finished": stamp()}
            save()
    if "scaling" in only:
        results["scaling"] = {**bench_scaling(pile_result), "finished": stamp()}
        save()
    if "batched" in only:
        results["batched"] = {**bench_batched(args), "finished": stamp()}
        save()
    if "warmstart" in only:
        results["warmstart"] = {**bench_warmstart(args, finals), "finished": stamp()}
        save()
    if "compile" in only:
        results["compile"] = {**bench_compile(args), "finished": stamp()}
        save()

    targets = [(k, v.get("target")) for k, v in results.items() if v.get("target")]
    if targets:
        print("\n## targets\n")
        for k, t in targets:
            print(f"- {k}: {t}")
    print(f"\nwrote {out_path}")


if __name__ == "__main__":
    main()
