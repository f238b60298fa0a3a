"""plot_trajectory draws every kind of body and returns a Figure (no simulation needed)."""
import sys

import numpy as np
import pytest

from matplotlib.figure import Figure  # matplotlib is part of the "test" extra

from jaxdda import SceneBuilder, Trajectory
from jaxdda.viz import plot_trajectory


def trajectory(frames: int = 4) -> Trajectory:
    sb = SceneBuilder(dt=0.01, name="mix")
    sb.add_polygon(vertices=[(-5, -1), (5, -1), (5, 0), (-5, 0)], density=1.0, fixed=True)
    sb.add_disk(center=(-3, 1), radius=1.0, density=1.0)
    sb.add_ring(center=(0, 2), inner_radius=0.5, outer_radius=1.5, density=1.0)
    sb.add_polygon(vertices=[(2, 0.5), (4, 0.5), (3, 2)], density=1.0)
    scene = sb.build()
    t = np.arange(frames) * 0.01
    c0, moving = np.asarray(scene.state.centroid), ~np.asarray(scene.model.fixed)
    centroid = c0 + moving[None, :, None] * np.stack([t, -t], -1)[:, None, :] * 20
    rotation = moving[None, :] * t[:, None] * 30.0
    velocity = np.zeros((frames, scene.n_bodies, 3))
    stress = np.zeros((frames, scene.n_bodies, 3))
    return Trajectory(scene, t, centroid, rotation, velocity, stress, None, scene.state)


def test_returns_figure_and_saves_png(tmp_path):
    path = tmp_path / "mix.png"
    fig = plot_trajectory(trajectory(), path)
    assert isinstance(fig, Figure)
    assert path.stat().st_size > 1000
    ax = fig.axes[0]
    assert ax.get_title().startswith("mix: t = 0.03 s (3 steps)")
    assert len(ax.collections) >= 4  # initial outlines, final bodies, radius marks, paths
    x0, x1 = ax.get_xlim()
    assert x0 < -5 and x1 > 5


def test_into_given_axes_with_title():
    fig = Figure()
    ax = fig.add_subplot()
    assert plot_trajectory(trajectory(1), ax=ax, title="hello") is fig
    assert ax.get_title() == "hello"


def test_missing_matplotlib_message(monkeypatch):
    monkeypatch.setitem(sys.modules, "matplotlib", None)
    with pytest.raises(ImportError, match=r'pip install "jaxdda\[plot\]"'):
        plot_trajectory(trajectory(1))
