"""Regenerate the README's picture: the force network of the ``pile`` example.

60 disks, friction 0.5, 600 steps of 0.01 s (6 s), drawn by ``plot_force_network``
into ``docs/images/pile-force-network.png``. As a check it prints the largest line
force (the README's caption quotes it), and the vertical reaction of the floor and of
the walls on the disks in the last step against the disks' weight (at rest they sum to
it; friction lets the walls carry a part).

    python experiments/readme_images.py
"""
from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))  # draw with this checkout's jaxdda, whatever is installed

import jaxdda  # noqa: E402
from jaxdda.viz import plot_force_network  # noqa: E402
from jaxdda.viz.charts import network_segments  # noqa: E402

OUT = ROOT / "docs" / "images" / "pile-force-network.png"
DISKS, FRICTION, STEPS = 60, 0.5, 600
FLOOR, WALLS = 0, (1, 2)  # the pile's fixed bodies, in the order examples.pile adds them


def vertical_reaction(traj, support: int) -> float:
    """The upward force of ``support`` on all the disks in the last step (N)."""
    return float(sum(traj.force_between(support, j)[-1, 1] for j in range(3, traj.scene.n_bodies)))


def main() -> None:
    scene = jaxdda.examples.get("pile", n=DISKS, friction=FRICTION)
    traj = jaxdda.simulate(scene, STEPS)
    model, params = scene.model, scene.params
    free = ~np.asarray(model.fixed, bool)
    weight = float(np.sum(np.asarray(params.density)[free] * np.asarray(model.area)[free]) * -params.gravity[1])
    _, force, _ = network_segments(traj)
    floor = vertical_reaction(traj, FLOOR)
    walls = sum(vertical_reaction(traj, w) for w in WALLS)
    print(f"t = {float(traj.time[-1]):.3g} s, all steps converged: {bool(np.all(traj.info.converged))}")
    print(f"largest line force: {force.max():.4g} N")
    print(f"weight of the disks: {weight:.6g} N; floor carries {floor:.6g} N ({floor / weight:.4f}), "
          f"walls {walls:.6g} N ({walls / weight:.4f}); (floor + walls) / weight - 1 = {(floor + walls) / weight - 1:.1e}")
    OUT.parent.mkdir(parents=True, exist_ok=True)
    fig = plot_force_network(traj, OUT)
    print(f"wrote {OUT} ({OUT.stat().st_size / 1024:.0f} kB, {fig.get_size_inches()} in)")


if __name__ == "__main__":
    main()
