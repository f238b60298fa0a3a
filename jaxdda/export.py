"""Run outputs as files: the trajectory as ``.npz``, measured-point and load-point
histories as CSV (ParaView output: viz.vtk; pictures: viz.plot)."""
from __future__ import annotations

from pathlib import Path

import numpy as np


def save_npz(traj, path) -> Path:
    """The trajectory, the step diagnostics, the contacts and the measured and load
    points of every saved step, as a compressed numpy ``.npz``."""
    info, c = traj.info, traj.info.contacts
    steps = np.arange(len(traj.time)) if traj.saved_steps is None else traj.saved_steps
    np.savez_compressed(
        path, time=traj.time, step=steps, centroid=traj.centroid, rotation=traj.rotation, velocity=traj.velocity,
        stress=traj.stress, iterations=info.iterations, residual=info.residual, converged=info.converged,
        n_contacts=info.n_contacts, max_penetration=info.max_penetration, contact_a=c.a, contact_b=c.b,
        contact_valid=c.valid, contact_force=c.force, contact_point=c.point,
        measured_points=traj.measured_points(), load_points=traj.load_points(), load_forces=traj.load_forces())
    return Path(path)


def write_csv(traj, folder, *, name: str | None = None) -> list[Path]:
    """``<name>_measured.csv`` (step, time, then x, y and the displacement dx, dy of each
    measured point) and ``<name>_loads.csv`` (step, time, then the point x, y and force
    fx, fy of each point load), one row per saved step; a file only where the scene has
    such points. Returns the files written."""
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    name = name or traj.scene.name
    steps = np.arange(len(traj.time)) if traj.saved_steps is None else np.asarray(traj.saved_steps)
    written = []
    measured = traj.measured_points()
    if measured.shape[1]:
        moved = measured - measured[:1]
        columns = [(f"p{k}_{q}", a[:, k, i]) for k in range(measured.shape[1])
                   for q, a, i in (("x", measured, 0), ("y", measured, 1), ("dx", moved, 0), ("dy", moved, 1))]
        written.append(_write(folder / f"{name}_measured.csv", steps, traj.time, columns))
    points, forces = traj.load_points(), traj.load_forces()
    if points.shape[1]:
        columns = [(f"load{k}_{q}", a[:, k, i]) for k in range(points.shape[1])
                   for q, a, i in (("x", points, 0), ("y", points, 1), ("fx", forces, 0), ("fy", forces, 1))]
        written.append(_write(folder / f"{name}_loads.csv", steps, traj.time, columns))
    return written


def _write(path: Path, steps, time, columns) -> Path:
    header = ",".join(["step", "time"] + [label for label, _ in columns])
    table = np.column_stack([steps, time] + [values for _, values in columns])
    fmt = ["%d", "%.17g"] + ["%.17g"] * len(columns)
    np.savetxt(path, table, delimiter=",", header=header, comments="", fmt=fmt)
    return path
