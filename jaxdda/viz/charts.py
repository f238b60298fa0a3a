"""Charts of a run: centroid paths, contact and connector forces over time, energy over
time, and the contact force network of one step; ``plot_report`` writes all four.

matplotlib is imported inside the functions (plot.py), so ``import jaxdda.viz`` works
without it. Each function draws into ``ax`` when given (else a new figure), saves a PNG
to ``path`` when given, and returns the Figure.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from jaxdda.energy import energy
from jaxdda.viz.plot import _import_matplotlib, body_colors, body_shapes, connector_lines, new_axes, scene_axes

NETWORK_LABEL = "force network"  # the label of plot_force_network's LineCollection


def _save(fig, path):
    if path is not None:
        fig.savefig(path, dpi=120, bbox_inches="tight")
    return fig


def _n_steps(traj) -> int:
    return 0 if traj.info is None else int(np.shape(traj.info.contacts.valid)[0])


def _step_number(traj, index: int) -> int:
    """The step that saved state ``index`` ends."""
    return index if traj.saved_steps is None else int(traj.saved_steps[index])


def pair_forces(traj, step: int | None = None):
    """Contact normal force summed per body pair.

    Returns ``(pairs, force, point)``: pairs (P, 2) of body indices (i < j) that have a
    valid contact in some step (in ``step`` only, when given), force (S, P) the sum of
    their contacts' normal forces in each step (compression +; step average, so an impact
    counts as impulse / dt), point (S, P, 2) the contact point of the pair, the mean of its
    contact points weighted by |normal force| (plain mean when none carries force).
    With ``step`` given, force is (P,) and point (P, 2) for that step only.
    """
    c = traj.info.contacts
    valid, a, b = np.asarray(c.valid, bool), np.asarray(c.a), np.asarray(c.b)
    fn, pt = np.asarray(c.normal_force, float), np.asarray(c.point, float)
    if step is not None:
        valid, a, b, fn, pt = valid[step][None], a[step][None], b[step][None], fn[step][None], pt[step][None]
    n = traj.scene.n_bodies
    lo, hi = np.minimum(a, b), np.maximum(a, b)
    key = np.where(valid, lo.astype(np.int64) * n + hi, -1)
    keys = np.unique(key[valid])
    pairs = np.stack([keys // n, keys % n], -1).astype(int).reshape(-1, 2)
    s = np.arange(key.shape[0])[:, None] * np.ones_like(key)
    slot = np.searchsorted(keys, key)
    rows, cols = s[valid], slot[valid]
    force = np.zeros((key.shape[0], len(keys)))
    np.add.at(force, (rows, cols), fn[valid])
    weight = np.zeros_like(force)
    np.add.at(weight, (rows, cols), np.abs(fn[valid]))
    count = np.zeros_like(force)
    np.add.at(count, (rows, cols), 1.0)
    wsum = np.zeros(force.shape + (2,))
    np.add.at(wsum, (rows, cols), np.abs(fn[valid])[:, None] * pt[valid])
    psum = np.zeros(force.shape + (2,))
    np.add.at(psum, (rows, cols), pt[valid])
    with np.errstate(invalid="ignore", divide="ignore"):
        point = np.where(weight[..., None] > 0, wsum / weight[..., None], psum / count[..., None])
    if step is not None:
        return pairs, force[0], point[0]
    return pairs, force, point


def _tracked(traj, bodies):
    """[(label, (S+1, 2) track, color)] of the bodies to track: the given indices, else
    every free body that is not a mesh element, plus each meshed block's area-weighted
    centroid."""
    model = traj.scene.model
    centroid = np.asarray(traj.centroid, float)
    colors = body_colors(model)
    if bodies is not None:
        return [(traj.scene.labels[i], centroid[:, i], colors[i]) for i in bodies]
    fixed, mesh = np.asarray(model.fixed, bool), np.asarray(model.mesh)
    area = np.asarray(model.area, float)
    out = [(traj.scene.labels[i], centroid[:, i], colors[i]) for i in np.flatnonzero(~fixed & (mesh < 0))]
    for m in np.unique(mesh[mesh >= 0]):
        members = np.flatnonzero(mesh == m)
        if fixed[members].all():
            continue
        w = area[members] / area[members].sum()
        out.append((f"meshed block {m}", np.einsum("snk,n->sk", centroid[:, members], w), colors[members[0]]))
    return out


def _draw_bodies(ax, traj, frame: int, *, alpha: float, outline: float = 0.8):
    """The bodies at saved state ``frame``, filled with ``alpha`` (fixed ones grey)."""
    _, patches, collections = _import_matplotlib()
    model = traj.scene.model
    verts = None if traj.stretch is None else traj.vertices([frame])[0]
    shapes, _ = body_shapes(patches, model, np.asarray(traj.centroid[frame], float),
                            np.asarray(traj.rotation[frame], float), verts)
    colors = body_colors(model)
    ax.add_collection(collections.PatchCollection(shapes, facecolors=colors, edgecolors=colors, alpha=alpha,
                                                  linewidths=outline))


def plot_paths(traj, path=None, *, bodies=None, ax=None):
    """The centroid track of each body over the scene's initial picture (bodies faintly
    filled at t = 0), with a circle at the start and a cross at the end of each track.
    ``bodies``: indices of the bodies to track (default: every free body, and each
    meshed block as a whole). Returns the Figure."""
    _, _, collections = _import_matplotlib()
    fig, ax = scene_axes(traj, ax, path)
    model = traj.scene.model
    _draw_bodies(ax, traj, 0, alpha=0.2)
    if np.asarray(model.connector_a).shape[0]:
        ax.add_collection(collections.LineCollection(
            connector_lines(model, np.asarray(traj.centroid[0]), np.asarray(traj.rotation[0])),
            colors="k", linewidths=0.8, alpha=0.5))
    tracks = _tracked(traj, bodies)
    for label, track, color in tracks:
        ax.plot(track[:, 0], track[:, 1], "-", color=color, linewidth=1.2, label=label)
        ax.plot(track[0, 0], track[0, 1], "o", color=color, markersize=4, markerfacecolor="none")
        ax.plot(track[-1, 0], track[-1, 1], "x", color=color, markersize=5)
    if 0 < len(tracks) <= 10:
        ax.legend(fontsize="small", loc="best")
    ax.set_aspect("equal")
    ax.autoscale_view()
    ax.margins(0.05)
    ax.set_title(f"{traj.scene.name}: centroid paths, t = 0 to {float(traj.time[-1]):.4g} s")
    ax.set_xlabel("x (m)")
    ax.set_ylabel("y (m)")
    return _save(fig, path)


def plot_forces(traj, path=None, *, ax=None, top=6):
    """Forces over time, at the end of each step: the total contact normal force of each
    body pair (the sum over its contacts, compression +; the ``top`` pairs with the
    largest peak), and the axial force of each connector (dashed, tension +; the ``top``
    largest). Contact forces are step averages, so an impact shows as a spike of
    impulse / dt. Returns the Figure."""
    _import_matplotlib()
    fig, ax = new_axes(ax, path, figsize=(8, 4.5))
    drawn = 0
    if _n_steps(traj):
        t = np.asarray(traj.time, float)[1:]
        pairs, force, _ = pair_forces(traj)
        fixed = np.asarray(traj.scene.model.fixed, bool)
        order = np.argsort(-np.abs(force).max(0), kind="stable")[:top]
        for p in order:
            if not np.any(force[:, p]):
                continue
            i, j = (f"{k} (fixed)" if fixed[k] else str(k) for k in pairs[p])
            ax.plot(t, force[:, p], "-", linewidth=1.0, label=f"contact {i}-{j}")
            drawn += 1
        axial = np.asarray(traj.connector_force, float)[..., 0]  # (S, K)
        if axial.shape[1]:
            for k in np.argsort(-np.abs(axial).max(0), kind="stable")[:top]:
                ax.plot(t, axial[:, k], "--", linewidth=1.0, label=f"connector {k} axial")
                drawn += 1
    if drawn:
        ax.legend(fontsize="small", loc="best")
    else:
        ax.text(0.5, 0.5, "no contact or connector forces", transform=ax.transAxes, ha="center", va="center")
    ax.set_title(f"{traj.scene.name}: contact normal force per body pair, connector axial force")
    ax.set_xlabel("t (s)")
    ax.set_ylabel("force (N per unit thickness)")
    ax.grid(True, alpha=0.3)
    return _save(fig, path)


ENERGY_LINES = (("kinetic", "C0", "-"), ("potential", "C1", "-"), ("elastic", "C2", "-"), ("total", "k", "-"))


def plot_energy(traj, path=None, *, ax=None, params=None):
    """The energy terms of ``jaxdda.energy.energy`` over time: kinetic, gravitational
    potential (zero at the start), elastic (strain + connectors) and their total, one line
    each, labelled by the term. ``params``: those of the run (default: ``traj.params``
    where kept, else the scene's).
    Returns the Figure."""
    _import_matplotlib()
    fig, ax = new_axes(ax, path, figsize=(8, 4.5))
    e = energy(traj, params)
    t = np.asarray(traj.time, float)
    for name, color, style in ENERGY_LINES:
        ax.plot(t, e[name], style, color=color, linewidth=1.6 if name == "total" else 1.0, label=name)
    drift = float(e["total"][-1] - e["total"][0])
    ax.legend(fontsize="small", loc="best")
    ax.set_title(f"{traj.scene.name}: energy (total changed by {drift:.3g} J)")
    ax.set_xlabel("t (s)")
    ax.set_ylabel("energy (J per unit thickness)")
    ax.grid(True, alpha=0.3)
    return _save(fig, path)


def network_segments(traj, step: int = -1):
    """The lines of the force network of ``step`` (an index into the S steps): segments
    (P, 2, 2), pair normal forces (P,) and pairs (P, 2) of the touching pairs, those
    whose summed normal force is not zero. A pair of free bodies is drawn from centroid to
    centroid; a pair with a fixed body from the free body's centroid to the contact point
    (pair_forces). Positions are those at the end of the step."""
    s = _n_steps(traj)
    if not -s <= step < s:
        raise IndexError(f"step {step} is outside the run's {s} steps")
    step = step % s
    pairs, force, point = pair_forces(traj, step)
    fixed = np.asarray(traj.scene.model.fixed, bool)
    touching = (force != 0) & ~(fixed[pairs[:, 0]] & fixed[pairs[:, 1]])
    pairs, force, point = pairs[touching], force[touching], point[touching]
    centroid = np.asarray(traj.centroid[step + 1], float)
    i, j = pairs[:, 0], pairs[:, 1]
    start = np.where(fixed[i][:, None], centroid[j], centroid[i])
    end = np.where(fixed[i][:, None] | fixed[j][:, None], point, centroid[j])
    return np.stack([start, end], 1).reshape(-1, 2, 2), force, pairs


def plot_force_network(traj, path=None, *, step=-1, ax=None, max_width=6.0):
    """The contact force network of one step (``step`` indexes the S steps; -1 the last):
    the bodies at the end of the step drawn faintly, and one line per touching body pair
    (network_segments) with width proportional to the pair's summed normal force
    (``max_width`` points for the largest); black: compression, red: tension of a cemented
    pair. The lines are one LineCollection labelled ``NETWORK_LABEL``. Returns the Figure."""
    _, _, collections = _import_matplotlib()
    s = _n_steps(traj)
    index = (step % s) if s else 0
    frame = index + 1 if s else 0
    fig, ax = scene_axes(traj, ax, path, [frame])
    _draw_bodies(ax, traj, frame, alpha=0.12, outline=0.5)
    model = traj.scene.model
    if np.asarray(model.connector_a).shape[0]:  # connectors, thin and grey, for orientation
        ax.add_collection(collections.LineCollection(
            connector_lines(model, np.asarray(traj.centroid[frame]), np.asarray(traj.rotation[frame])),
            colors="0.5", linewidths=0.6, linestyles="--"))
    peak = 0.0
    if s:
        segments, force, _ = network_segments(traj, step)
        peak = float(np.abs(force).max(initial=0.0))
        widths = max_width * np.abs(force) / peak if peak > 0 else np.zeros(len(force))
        ax.add_collection(collections.LineCollection(
            segments, linewidths=widths, colors=np.where(force >= 0, "k", "C3").tolist(), capstyle="round",
            label=NETWORK_LABEL))
    ax.set_aspect("equal")
    ax.autoscale_view()
    ax.margins(0.05)
    ax.set_title(f"{traj.scene.name}: contact forces at t = {float(traj.time[frame]):.4g} s "
                 f"(step {_step_number(traj, frame)}); widest = {peak:.4g} N")
    ax.set_xlabel("x (m)")
    ax.set_ylabel("y (m)")
    return _save(fig, path)


REPORT = (("paths.png", plot_paths), ("forces.png", plot_forces), ("energy.png", plot_energy),
          ("network.png", plot_force_network))


def plot_report(traj, folder, *, params=None) -> list[Path]:
    """Write paths.png, forces.png, energy.png and network.png (last step) of ``traj``
    into ``folder`` (made if missing); returns their paths. ``params``: those of the run
    (for the energy; default as plot_energy)."""
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    out = []
    for name, draw in REPORT:
        target = folder / name
        if draw is plot_energy:
            draw(traj, target, params=params)
        else:
            draw(traj, target)
        out.append(target)
    return out
