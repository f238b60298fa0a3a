"""``plot_trajectory``: the final state, the initial outlines and the centroid paths of a run.

matplotlib is imported inside the function, so ``import jaxdda.viz`` works without it.
"""
from __future__ import annotations

import numpy as np

from jaxdda.types import DISK, POLYGON, RING

FIXED_COLOR = "0.55"


def _import_matplotlib():
    try:
        import matplotlib  # noqa: F401
        from matplotlib import collections, figure, patches
    except ImportError as err:
        raise ImportError('plotting needs matplotlib: pip install "jaxdda[plot]"') from err
    return figure, patches, collections


def body_colors(model) -> list[str]:
    """One color per body: grey when fixed, else matplotlib's color cycle; the elements of
    a meshed block share the color of its first element."""
    cycle = [f"C{k}" for k in range(10)]
    mesh = np.asarray(model.mesh)
    first = {m: i for i, m in reversed(list(enumerate(mesh.tolist()))) if m >= 0}
    return [FIXED_COLOR if f else cycle[(first[mesh[i]] if mesh[i] >= 0 else i) % len(cycle)]
            for i, f in enumerate(np.asarray(model.fixed, bool))]


def body_shapes(patches, model, centroid: np.ndarray, rotation: np.ndarray, vertices: np.ndarray | None = None):
    """(patches, radius lines) of every body at the pose (centroid (N, 2), rotation (N,));
    polygons at ``vertices`` (N, V, 2, world frame) when given (a deformed shape), else
    placed rigidly."""
    kind, radius = np.asarray(model.kind), np.asarray(model.radius, float)
    inner, local = np.asarray(model.inner_radius, float), np.asarray(model.local_vertices, float)
    mask = np.asarray(model.vertex_mask, bool)
    out, marks = [], []
    for i, k in enumerate(kind):
        c, th = centroid[i], rotation[i]
        direction = np.array([np.cos(th), np.sin(th)])
        if k == DISK:
            out.append(patches.Circle(c, radius[i]))
            marks.append([c, c + radius[i] * direction])
        elif k == RING:
            out.append(patches.Wedge(c, radius[i], 0.0, 360.0, width=radius[i] - inner[i]))
            marks.append([c + inner[i] * direction, c + radius[i] * direction])
        elif vertices is not None:
            out.append(patches.Polygon(vertices[i][mask[i]], closed=True))
        else:
            out.append(patches.Polygon(c + local[i][mask[i]] @ _rotation(th).T, closed=True))
    return out, marks


def connector_lines(model, centroid: np.ndarray, rotation: np.ndarray) -> list:
    """[[attachment a, attachment b], ...] of every connector at the pose (rigid placement
    of the attachment points; a deformable body's stretch is not drawn)."""
    a, b = np.asarray(model.connector_a), np.asarray(model.connector_b)
    pa = centroid[a] + np.einsum("kij,kj->ki", _rotation(rotation[a]), np.asarray(model.connector_pa))
    pb = centroid[b] + np.einsum("kij,kj->ki", _rotation(rotation[b]), np.asarray(model.connector_pb))
    return [[p, q] for p, q in zip(pa, pb)]


def scene_box(traj, frames=slice(None)) -> tuple[np.ndarray, np.ndarray]:
    """(low, high) corners of the box that holds every body (polygon vertices, disk and
    ring rims) at the saved states ``frames`` (a slice or index array), 5 % wider each side."""
    model = traj.scene.model
    round_ = np.asarray(model.kind) != POLYGON
    corners = traj.vertices(frames)[:, np.asarray(model.vertex_mask, bool) & ~round_[:, None]]
    centroid, rim = np.asarray(traj.centroid, float)[frames][:, round_], np.asarray(model.radius, float)[round_, None]
    points = np.concatenate([corners, centroid - rim, centroid + rim], 1).reshape(-1, 2)
    low, high = points.min(0), points.max(0)
    pad = 0.05 * (high - low)
    return low - pad, high + pad


def figure_size(low, high, longest: float = 7.0, most: float = 4.0) -> tuple[float, float]:
    """(width, height) in inches of a figure shaped as the box ``low`` .. ``high``, its
    aspect clamped to between 1:``most`` and ``most``:1, its longer side ``longest``."""
    width, height = np.asarray(high, float) - np.asarray(low, float)
    aspect = float(np.clip(width / height, 1.0 / most, most))
    return (longest, longest / aspect) if aspect >= 1.0 else (longest * aspect, longest)


def new_axes(ax=None, path=None, figsize=(7, 7)):
    """(figure, axes) to draw into: ``ax`` and its figure when given; else a new figure of
    ``figsize`` (constrained layout), on the Agg canvas when it is to be saved to ``path``
    (no display needed), else pyplot's."""
    figure, _, _ = _import_matplotlib()
    if ax is not None:
        return ax.figure, ax
    if path is not None:
        from matplotlib.backends.backend_agg import FigureCanvasAgg

        fig = figure.Figure(figsize=figsize, layout="constrained")
        FigureCanvasAgg(fig)
        return fig, fig.add_subplot()
    import matplotlib.pyplot as plt

    return plt.subplots(figsize=figsize, layout="constrained")


def scene_axes(traj, ax=None, path=None, frames=slice(None)):
    """``new_axes`` for a picture of the scene: a new figure takes the shape of the bodies'
    box over ``frames`` (``scene_box``, ``figure_size``)."""
    return new_axes(ax, path, None if ax is not None else figure_size(*scene_box(traj, frames)))


def _rotation(theta):
    c, s = np.cos(theta), np.sin(theta)
    return np.stack([np.stack([c, -s], -1), np.stack([s, c], -1)], -2)


def plot_trajectory(traj, path=None, *, ax=None, title=None):
    """Draw a Trajectory: every body at the final state (filled, semi-transparent; fixed
    bodies grey), at the initial state as thin dashed outlines, and the path of each
    free body's centroid. Disks and rings show a radius line that turns with them.

    ``ax``: draw into these axes (default: a new figure). ``path``: also save a PNG there
    (a new figure is then made on the Agg canvas, so no display is needed).
    Returns the matplotlib Figure.
    """
    figure, patches, collections = _import_matplotlib()
    fig, ax = scene_axes(traj, ax, path)

    model = traj.scene.model
    fixed = np.asarray(model.fixed, bool)
    centroid, rotation = np.asarray(traj.centroid, float), np.asarray(traj.rotation, float)
    colors = body_colors(model)

    verts = None if traj.stretch is None else traj.vertices()

    def shapes(frame: int):
        return body_shapes(patches, model, centroid[frame], rotation[frame], None if verts is None else verts[frame])

    first, first_marks = shapes(0)
    ax.add_collection(collections.PatchCollection(
        first, facecolors="none", edgecolors=colors, linewidths=0.8, linestyles="--", alpha=0.7))
    last, last_marks = shapes(-1)
    ax.add_collection(collections.PatchCollection(
        last, facecolors=colors, edgecolors=colors, linewidths=1.2, alpha=0.45))
    round_colors = [colors[i] for i, k in enumerate(np.asarray(model.kind)) if k != POLYGON]
    if last_marks:
        ax.add_collection(collections.LineCollection(first_marks, colors=round_colors, linewidths=0.8,
                                                     linestyles="--", alpha=0.7))
        ax.add_collection(collections.LineCollection(last_marks, colors=round_colors, linewidths=1.5))

    free = np.flatnonzero(~fixed & (np.asarray(model.mesh) < 0))  # paths of bodies, not of mesh elements
    if len(centroid) > 1 and len(free):
        ax.add_collection(collections.LineCollection(
            [centroid[:, i] for i in free], colors=[colors[i] for i in free], linewidths=1.0))
    ax.plot(centroid[-1, free, 0], centroid[-1, free, 1], "k.", markersize=3)
    if model.connector_a.shape[0]:
        ax.add_collection(collections.LineCollection(connector_lines(model, centroid[-1], rotation[-1]),
                                                     colors="k", linewidths=1.0))

    ax.set_aspect("equal")
    ax.autoscale_view()
    ax.margins(0.05)
    if title is None:
        steps = len(traj.time) - 1
        title = f"{traj.scene.name}: t = {float(traj.time[-1]):.4g} s ({steps} steps)"
    ax.set_title(title)
    ax.set_xlabel("x")
    ax.set_ylabel("y")
    if path is not None:
        fig.savefig(path, dpi=120, bbox_inches="tight")
    return fig
