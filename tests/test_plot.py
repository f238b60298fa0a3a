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


@pytest.mark.smoke
def test_missing_matplotlib_message(monkeypatch):
    monkeypatch.setitem(sys.modules, "matplotlib", None)
    with pytest.raises(ImportError, match=r'pip install "jaxdda\[plot\]"'):
        plot_trajectory(trajectory(1))


# ------------------------------------------------ charts: paths, forces, energy, force network

from matplotlib.collections import LineCollection  # noqa: E402

from jaxdda.energy import energy  # noqa: E402
from jaxdda.types import ContactReport, StepInfo  # noqa: E402
from jaxdda.viz.charts import (NETWORK_LABEL, plot_energy, plot_force_network, plot_forces,  # noqa: E402
                               plot_paths, plot_report)

# Per step k (scaled by k + 1): contacts (a, b, normal force, point, valid) of the "mix" scene
# (0: fixed base, 1: disk, 2: ring, 3: triangle). Touching pairs: 0-1 (3 + 1 at two points),
# 1-2 (6), 0-3 (2); 2-3 has a contact without force, and an invalid slot carries junk.
CONTACTS = [(1, 0, 3.0, (-3.0, 0.0), True), (1, 0, 1.0, (-2.0, 0.0), True), (2, 1, 6.0, (-1.5, 1.5), True),
            (3, 2, 0.0, (1.5, 1.0), True), (3, 0, 2.0, (3.0, 0.0), True), (2, 3, 99.0, (0.0, 0.0), False)]
PAIR_FORCE = {(0, 1): 4.0, (1, 2): 6.0, (0, 3): 2.0}


def with_contacts(traj: Trajectory) -> Trajectory:
    s, c = len(traj.time) - 1, len(CONTACTS)
    scale = (np.arange(s) + 1.0)[:, None]
    a, b, fn, point, valid = (np.array(col) for col in zip(*CONTACTS))
    normal = np.tile([0.0, 1.0], (s, c, 1))
    report = ContactReport(
        valid=np.tile(valid, (s, 1)), a=np.tile(a, (s, 1)), b=np.tile(b, (s, 1)),
        point=np.tile(point, (s, 1, 1)), normal=normal, normal_force=scale * fn,
        shear_force=np.zeros((s, c)), force=scale[..., None] * fn[:, None] * normal, moment=np.zeros((s, c)),
        cemented=np.zeros((s, c), bool), gap=np.zeros((s, c)), bearing=scale * fn)
    info = StepInfo(iterations=np.ones(s, np.int32), residual=np.zeros(s), converged=np.ones(s, bool),
                    needed=np.zeros((s, 5), np.int32), overflow=np.zeros(s, bool), n_contacts=np.full(s, c),
                    max_penetration=np.zeros(s), joint_tension=np.zeros((s, 0)), joint_broken=np.zeros((s, 0), bool),
                    connector_force=np.zeros((s, 0, 4)), contacts=report)
    moving = ~np.asarray(traj.scene.model.fixed)
    velocity = np.zeros_like(traj.velocity)
    velocity[:, moving] = (20.0, -20.0, 30.0)  # as the poses of trajectory() move
    return Trajectory(traj.scene, traj.time, traj.centroid, traj.rotation, velocity, traj.stress, info,
                      traj.final_state)


def network(fig) -> LineCollection:
    (lines,) = [c for c in fig.axes[0].collections if c.get_label() == NETWORK_LABEL]
    return lines


@pytest.mark.parametrize("step", [1, -1])
def test_force_network_widths_follow_pair_forces(step):
    traj = with_contacts(trajectory())
    lines = network(plot_force_network(traj, step=step, max_width=6.0))
    segments, widths = lines.get_segments(), np.asarray(lines.get_linewidths())
    assert len(segments) == len(widths) == len(PAIR_FORCE)  # 2-3 carries no force: no line
    k = step % (len(traj.time) - 1)
    centroid = traj.centroid[k + 1]  # positions at the end of the step
    expected = {}  # from each line's ends back to its pair
    for (i, j), f in PAIR_FORCE.items():
        if i == 0:  # with the fixed base: from the free body's centroid to the contact point
            own = [p for a, b, fn, p, v in CONTACTS if {a, b} == {i, j} and v and fn]
            weights = [fn for a, b, fn, p, v in CONTACTS if {a, b} == {i, j} and v and fn]
            end = np.average(own, axis=0, weights=weights)
        else:
            end = centroid[j]
        expected[(tuple(np.round(centroid[j if i == 0 else i], 9)), tuple(np.round(end, 9)))] = f * (k + 1)
    drawn = {(tuple(np.round(s[0], 9)), tuple(np.round(s[1], 9))): w for s, w in zip(segments, widths)}
    assert drawn.keys() == expected.keys()
    peak = max(expected.values())
    for key, force in expected.items():
        assert drawn[key] == pytest.approx(6.0 * force / peak, rel=1e-12)


def test_forces_plot_carries_pair_sums():
    traj = with_contacts(trajectory(5))
    ax = plot_forces(traj).axes[0]
    lines = {line.get_label(): line for line in ax.get_lines()}
    assert set(lines) == {"contact 0 (fixed)-1", "contact 1-2", "contact 0 (fixed)-3"}
    for (i, j), f in PAIR_FORCE.items():
        label = f"contact {i} (fixed)-{j}" if i == 0 else f"contact {i}-{j}"
        np.testing.assert_allclose(lines[label].get_xdata(), traj.time[1:])
        np.testing.assert_allclose(lines[label].get_ydata(), f * np.arange(1, 5))


def test_energy_plot_carries_energy_values():
    traj = with_contacts(trajectory())
    ax = plot_energy(traj).axes[0]
    lines = {line.get_label(): line for line in ax.get_lines()}
    e = energy(traj)
    assert set(lines) == {"kinetic", "potential", "elastic", "total"}
    assert e["kinetic"].min() > 0 and e["potential"][-1] != 0
    for name, line in lines.items():
        np.testing.assert_array_equal(line.get_xdata(), traj.time)
        np.testing.assert_array_equal(line.get_ydata(), e[name])


def test_paths_plot_tracks_centroids():
    traj = trajectory()
    ax = plot_paths(traj).axes[0]
    tracks = {line.get_label(): line for line in ax.get_lines() if not line.get_label().startswith("_")}
    labels = traj.scene.labels
    assert set(tracks) == {labels[1], labels[2], labels[3]}  # the free bodies, not the fixed base
    for i in (1, 2, 3):
        np.testing.assert_array_equal(np.stack([tracks[labels[i]].get_xdata(), tracks[labels[i]].get_ydata()], -1),
                                      traj.centroid[:, i])
    only = plot_paths(traj, bodies=[2]).axes[0]
    assert [line.get_label() for line in only.get_lines() if not line.get_label().startswith("_")] == [labels[2]]


def test_report_writes_four_pngs(tmp_path):
    paths = plot_report(with_contacts(trajectory()), tmp_path / "report")
    assert [p.name for p in paths] == ["paths.png", "forces.png", "energy.png", "network.png"]
    for p in paths:
        assert p.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" and p.stat().st_size > 1000


@pytest.mark.smoke
@pytest.mark.parametrize("draw", [plot_paths, plot_forces, plot_energy, plot_force_network])
def test_charts_missing_matplotlib_message(monkeypatch, draw):
    monkeypatch.setitem(sys.modules, "matplotlib", None)
    with pytest.raises(ImportError, match=r'pip install "jaxdda\[plot\]"'):
        draw(with_contacts(trajectory(2)))


# ------------------------------------------------ figures shaped as the scene

from PIL import Image  # noqa: E402  (matplotlib needs Pillow)

from jaxdda.viz.animate import animate_trajectory  # noqa: E402


def slab_trajectory(width: float, rows: int, frames: int = 3) -> Trajectory:
    """A fixed slab [0, width] x [0, 1] under ``rows`` stacked unit disks at each of
    x = 2, 6, 10, ... (< width), the disks drifting right by 0.1 per frame: the bodies
    span [0, width] x [0, 1 + rows]."""
    sb = SceneBuilder(dt=0.01, name="slab")
    sb.add_polygon(vertices=[(0, 0), (width, 0), (width, 1), (0, 1)], density=1.0, fixed=True)
    for x in np.arange(2.0, width - 1.0, 4.0):
        for k in range(rows):
            sb.add_disk(center=(x, 1.5 + k), radius=0.5, density=1.0)
    scene = sb.build()
    moving = ~np.asarray(scene.model.fixed)
    centroid = np.asarray(scene.state.centroid) + 0.1 * np.arange(frames)[:, None, None] * moving[None, :, None] * [1, 0]
    zeros = np.zeros((frames, scene.n_bodies, 3))
    return Trajectory(scene, np.arange(frames) * 0.01, centroid, np.zeros((frames, scene.n_bodies)), zeros, zeros,
                      None, scene.state)


def covers(ax, low, high) -> bool:
    (x0, x1), (y0, y1) = ax.get_xlim(), ax.get_ylim()
    return x0 <= low[0] and x1 >= high[0] and y0 <= low[1] and y1 >= high[1]


@pytest.mark.parametrize("draw", [plot_trajectory, plot_paths, plot_force_network])
def test_wide_scene_gets_a_wide_figure(draw, tmp_path):
    traj = slab_trajectory(20.0, 1)  # 20 m x 2 m
    fig = draw(traj, tmp_path / "wide.png")
    width, height = fig.get_size_inches()
    assert width / height > 3 and max(width, height) == pytest.approx(7.0)
    assert covers(fig.axes[0], (0.0, 0.0), (20.0, 2.0))
    with Image.open(tmp_path / "wide.png") as png:
        assert png.width / png.height > 3


@pytest.mark.parametrize("draw", [plot_trajectory, plot_paths, plot_force_network])
def test_square_scene_gets_a_square_figure(draw):
    fig = draw(slab_trajectory(4.0, 3))  # 4 m x 4 m
    width, height = fig.get_size_inches()
    assert width / height == pytest.approx(1.0, abs=0.1)
    assert covers(fig.axes[0], (0.0, 0.0), (4.0, 4.0))


def test_tall_scene_aspect_is_clamped():
    width, height = plot_paths(slab_trajectory(4.0, 40)).get_size_inches()  # 4 m x 41 m
    assert width / height == pytest.approx(1 / 4)


def test_figure_into_given_axes_keeps_its_size():
    fig = Figure(figsize=(5, 5))
    plot_trajectory(slab_trajectory(20.0, 1), ax=fig.add_subplot())
    assert tuple(fig.get_size_inches()) == (5, 5)


@pytest.mark.parametrize("width, rows", [(20.0, 1), (4.0, 3)])
def test_gif_frames_follow_the_scene(tmp_path, width, rows):
    path = tmp_path / "run.gif"
    assert animate_trajectory(slab_trajectory(width, rows), path, frames=3, dpi=50) == 3
    with Image.open(path) as gif:
        aspect = gif.width / gif.height
        assert gif.n_frames == 3 and max(gif.size) == pytest.approx(6 * 50, abs=2)
    assert aspect > 3 if width > 4 * (rows + 1) else aspect == pytest.approx(1.0, abs=0.1)
