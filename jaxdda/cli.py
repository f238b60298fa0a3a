"""Command line: ``jaxdda run NAME_OR_FILE [--steps N] [--out run.npz] [--plot run.png] ...``,
``jaxdda export NAME FILE.toml``, ``jaxdda list`` and ``jaxdda cache [--clear]``."""
from __future__ import annotations

import argparse
import os
import sys
import time
from pathlib import Path

import numpy as np

from jaxdda import examples
from jaxdda.errors import CapacityError, ConvergenceError, SceneError
from jaxdda.simulate import CHUNK, simulate


class _UsageError(Exception):
    """A mistake on the command line or in the input: message, exit status 2."""


def _positive_int(text: str) -> int:
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a positive integer, got {text!r}") from None
    if value < 1:
        raise argparse.ArgumentTypeError(f"expected a positive integer, got {text!r}")
    return value


def _parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="jaxdda", description="Differentiable 2D DDA contact simulations.")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    run = sub.add_parser("run", help="simulate an example or a scene file",
                         description="Simulate a built-in example (see 'jaxdda list') or a TOML or JSON scene "
                                     "file (docs/scene-format.md) and summarise the run.")
    run.add_argument("scene", metavar="NAME_OR_FILE", help="example name or path to a .toml or .json scene file")
    run.add_argument("--steps", type=_positive_int,
                     help="number of steps (default: the file's \"steps\", or the example's default)")
    run.add_argument("--out", metavar="FILE.npz", help="save the trajectory and step diagnostics (numpy .npz)")
    run.add_argument("--plot", metavar="FILE.png", help="save a picture of the run (needs matplotlib)")
    run.add_argument("--animate", metavar="FILE.gif", help="save an animation of the run (needs matplotlib)")
    run.add_argument("--frames", type=_positive_int, default=100, help="frames of the animation (default 100)")
    run.add_argument("--save-every", type=_positive_int, default=1, metavar="K",
                     help="keep every K-th step (and the last) in memory and outputs (default 1)")
    run.add_argument("--quiet", action="store_true", help="no progress bar")
    run.add_argument("--vtk", metavar="DIR", help="save a ParaView time series (.pvd + .vtp) of bodies and contacts")
    run.add_argument("--vtk-every", type=_positive_int, default=1, metavar="K",
                     help="with --vtk: every K-th step (default 1; the last is always written)")
    run.add_argument("--report", metavar="DIR", help="save pictures of paths, forces, energy and the force network "
                                                   "(needs matplotlib)")
    run.add_argument("--csv", metavar="DIR", help="save measured-point and load-point histories as CSV")
    run.add_argument("--checkpoint", metavar="FILE.npz", help="save the final state to restart from (--resume)")
    run.add_argument("--resume", metavar="FILE.npz", help="continue from a checkpoint of this scene (--checkpoint): "
                                                          "--steps more steps, bit-identical to an unbroken run")
    run.add_argument("--chunk", type=_positive_int, default=CHUNK,
                     help=f"steps per compiled chunk (default: {CHUNK}, as simulate's, so they share programs)")
    run.add_argument("--on-nonconvergence", choices=("continue", "halve", "raise"), default="continue",
                     help="a step whose contact solve does not converge: go on and report it (default), run it "
                          "again as steps of dt/2 (down to dt/16), or stop with an error")
    export = sub.add_parser("export", help="write a built-in example as a scene file",
                            description="Write a built-in example as a TOML (or, for a .json path, JSON) scene "
                                        "file that 'jaxdda run FILE' runs as the example.")
    export.add_argument("name", metavar="NAME", help="example name (see 'jaxdda list')")
    export.add_argument("path", metavar="FILE", help="the scene file to write (.toml or .json)")
    ntdda = sub.add_parser("ntdda", help="convert ntdda (DDA for Windows) input files to a scene file",
                           description="Convert a DDA for Windows (ntdda) geometry file and, optionally, its "
                                       "analysis file (DDAML or plain) to a TOML or JSON scene file.")
    ntdda.add_argument("geometry", metavar="GEO", help="the geometry file")
    ntdda.add_argument("analysis", metavar="ANA", nargs="?", help="the analysis file")
    ntdda.add_argument("--out", metavar="FILE", required=True, help="the scene file to write (.toml or .json)")
    sub.add_parser("list", help="list the built-in examples")
    cache = sub.add_parser("cache", help="show (or clear) the cache of compiled programs",
                           description="Show where compiled programs are kept, their number and size; "
                                       "--clear deletes them. JAXDDA_CACHE=DIR moves the cache, "
                                       "JAXDDA_CACHE=off turns it off.")
    cache.add_argument("--clear", action="store_true", help="delete every cached program")
    return parser


def main(argv: list[str] | None = None) -> int:
    """Entry point of the ``jaxdda`` command; returns the exit status."""
    parser = _parser()
    try:
        args = parser.parse_args(argv)
    except SystemExit as exit_:  # argparse's usage errors (2) and --help (0)
        return exit_.code if isinstance(exit_.code, int) else (0 if exit_.code is None else 2)
    try:
        if args.command == "list":
            return _list()
        if args.command == "run":
            return _run(args)
        if args.command == "export":
            return _export(args)
        if args.command == "ntdda":
            return _ntdda(args)
        if args.command == "cache":
            return _cache(args)
        parser.print_help(sys.stderr)
        return 2
    except (_UsageError, SceneError) as err:
        print(f"jaxdda: error: {err}", file=sys.stderr)
        return 2
    except (CapacityError, ConvergenceError) as err:
        print(f"jaxdda: simulation failed: {err}", file=sys.stderr)
        return 1
    except BrokenPipeError:  # the reader went away (``jaxdda list | head -3``): stop quietly
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())  # so that the interpreter's last flush cannot fail again
        return 1


def _list() -> int:
    for name in examples.names():
        print(f"{name:<12} {examples.default_steps(name):>6} steps  {examples.describe(name)}")
    return 0


def _cache(args) -> int:
    from jaxdda import cache

    path = cache.folder()
    if path is None:
        print("the cache of compiled programs is off (JAXDDA_CACHE)")
        return 0
    entries, size = cache.clear(path) if args.clear else cache.size(path)
    verb = "deleted" if args.clear else "holds"
    print(f"{path} {verb} {entries} compiled programs, {size / 2**20:.1f} MiB")
    return 0


def _export(args) -> int:
    if args.name not in examples.names():
        raise _UsageError(f"unknown example {args.name!r} (examples: {', '.join(examples.names())})")
    _check_writable("export", args.path)
    from jaxdda.scene.io import save_scene

    save_scene(examples.get(args.name), args.path, steps=examples.default_steps(args.name))
    print(f"wrote {args.path}")
    return 0


def _ntdda(args) -> int:
    import json

    from jaxdda.scene.io import toml_text
    from jaxdda.scene.ntdda import read_ntdda

    _check_writable("--out", args.out)
    data = read_ntdda(args.geometry, args.analysis)
    out = Path(args.out)
    out.write_text(json.dumps(data, indent=1) if out.suffix.lower() == ".json" else toml_text(data), encoding="utf-8")
    print(f"wrote {out} ({len(data.get('bodies', []))} blocks)")
    return 0


def _load(spec: str):
    """(scene, default steps) of an example name or a scene file."""
    if spec in examples.names():
        return examples.get(spec), examples.default_steps(spec)
    path = Path(spec)
    if path.suffix.lower() in (".json", ".toml") or path.exists():
        from jaxdda.scene.loader import load_scene

        return load_scene(path)
    raise _UsageError(f"unknown example {spec!r} and no such file (examples: {', '.join(examples.names())}; "
                      "or give the path to a .toml or .json scene file)")


def _check_writable(option: str, target: str | None) -> None:
    if target is not None and not Path(target).resolve().parent.is_dir():
        raise _UsageError(f"{option} {target}: the directory {Path(target).parent} does not exist")


def _run(args) -> int:
    _check_writable("--out", args.out)
    _check_writable("--checkpoint", args.checkpoint)
    _check_writable("--plot", args.plot)
    _check_writable("--animate", args.animate)
    for option, folder in (("--vtk", args.vtk), ("--csv", args.csv), ("--report", args.report)):
        if folder is not None and Path(folder).exists() and not Path(folder).is_dir():
            raise _UsageError(f"{option} {folder}: not a directory")
    if args.plot or args.animate or args.report:
        from jaxdda.viz.plot import _import_matplotlib

        try:
            _import_matplotlib()  # fail before a long run, not after it
        except ImportError as err:
            raise _UsageError(str(err)) from None
    scene, default = _load(args.scene)
    steps = args.steps or default
    if steps is None:
        raise _UsageError(f"{args.scene}: give --steps (the scene file has no \"steps\")")

    first_step = 0
    if args.resume:
        from jaxdda.checkpoint import CheckpointError, load_checkpoint

        try:
            ck = load_checkpoint(args.resume)
            scene, first_step = ck.scene(scene), ck.step
        except (CheckpointError, FileNotFoundError) as err:
            raise _UsageError(f"--resume {args.resume}: {err}") from None
        print(f"resuming from {args.resume}: step {first_step}, t = {ck.time:.6g} s")
    start = time.perf_counter()
    traj = simulate(scene, steps, chunk=args.chunk, save_every=args.save_every, progress=False if args.quiet else None,
                    on_nonconvergence=args.on_nonconvergence)
    wall = time.perf_counter() - start
    _summarise(scene, steps, traj, wall, args.save_every)
    _write_outputs(args, traj, first_step + traj.steps)
    return 0


def _summarise(scene, steps: int, traj, wall: float, save_every: int) -> None:
    """Print the run's summary: time, solver iterations, convergence, halvings, contacts."""
    info = traj.info
    converged = np.asarray(traj.step_converged, bool)  # every step run, saved or not
    print(f"{scene.name}: {scene.n_bodies} bodies, {steps} steps of dt = {float(scene.params.dt):g} s")
    print(f"  simulated time    {float(traj.time[-1]):.6g} s")
    print(f"  wall time         {wall:.2f} s (including compilation)")
    of = "" if save_every == 1 else " (of the saved steps)"
    print(f"  solver iterations max {int(np.max(info.iterations))} per step{of}")
    if converged.all():
        print("  converged         every step")
    else:
        print(f"  converged         NO: {int((~converged).sum())} steps did not converge "
              f"(first: step {int(np.argmin(converged)) + 1})")
    if traj.halvings is not None and traj.halvings.any():
        print(f"  halved steps      {int(np.count_nonzero(traj.halvings))} (first: step "
              f"{int(np.argmax(traj.halvings > 0)) + 1}; smallest sub-step dt/{2 ** int(traj.halvings.max())})")
    print(f"  contacts          max {int(np.max(info.n_contacts))}{of}")
    print(f"  penetration       max {float(np.max(info.max_penetration)):.3g}{of}")


def _write_outputs(args, traj, step: int) -> None:
    """Write what the command line asked for: checkpoint, npz, report, CSV, picture,
    animation, VTK (``step``: the number of the run's last step, for the checkpoint)."""
    if args.checkpoint:
        from jaxdda.checkpoint import save_checkpoint

        save_checkpoint(args.checkpoint, traj, step=step)
        print(f"  wrote {args.checkpoint} (checkpoint at step {step})")
    if args.out:
        from jaxdda.export import save_npz

        save_npz(traj, args.out)
        print(f"  wrote {args.out}")
    if args.report:
        from jaxdda.viz.charts import plot_report

        for path in plot_report(traj, args.report):
            print(f"  wrote {path}")
    if args.csv:
        from jaxdda.export import write_csv

        for path in write_csv(traj, args.csv) or ["nothing: the scene has no measured or load points"]:
            print(f"  wrote {path}")
    if args.plot:
        from jaxdda.viz.plot import plot_trajectory

        plot_trajectory(traj, args.plot)
        print(f"  wrote {args.plot}")
    if args.animate:
        from jaxdda.viz.animate import animate_trajectory

        count = animate_trajectory(traj, args.animate, frames=args.frames)
        print(f"  wrote {args.animate} ({count} frames)")
    if args.vtk:
        from jaxdda.viz.vtk import write_vtk

        for path in write_vtk(traj, args.vtk, every=args.vtk_every):
            print(f"  wrote {path}")
