"""``animate_trajectory``: a GIF of a run (bodies, their radius lines and connectors)."""
from __future__ import annotations

import numpy as np

from jaxdda.types import POLYGON
from jaxdda.viz.plot import _import_matplotlib, body_colors, body_shapes, connector_lines, figure_size, scene_box


def animate_trajectory(traj, path, *, frames: int = 100, fps: int = 20, dpi: int = 80) -> int:
    """Write a GIF of ``traj`` to ``path``: up to ``frames`` evenly spaced saved states
    (always the first and the last), ``fps`` frames per second. Returns the frame count."""
    figure, patches, collections = _import_matplotlib()
    from matplotlib.animation import FuncAnimation, PillowWriter
    from matplotlib.backends.backend_agg import FigureCanvasAgg

    if isinstance(frames, bool) or int(frames) != frames or frames < 1:
        raise ValueError(f"frames must be a positive integer, got {frames!r}")
    model = traj.scene.model
    centroid, rotation = np.asarray(traj.centroid, float), np.asarray(traj.rotation, float)
    picks = np.unique(np.linspace(0, len(centroid) - 1, min(int(frames), len(centroid))).round().astype(int))
    colors = body_colors(model)
    round_colors = [colors[i] for i, k in enumerate(np.asarray(model.kind)) if k != POLYGON]

    lo, hi = scene_box(traj, picks)
    fig = figure.Figure(figsize=figure_size(lo, hi, longest=6.0), layout="constrained")
    FigureCanvasAgg(fig)
    ax = fig.add_subplot()

    def draw(k: int):
        ax.clear()
        frame = picks[k]
        bodies, marks = body_shapes(patches, model, centroid[frame], rotation[frame])
        ax.add_collection(collections.PatchCollection(bodies, facecolors=colors, edgecolors=colors,
                                                      linewidths=1.0, alpha=0.5))
        if marks:
            ax.add_collection(collections.LineCollection(marks, colors=round_colors, linewidths=1.2))
        if model.connector_a.shape[0]:
            ax.add_collection(collections.LineCollection(connector_lines(model, centroid[frame], rotation[frame]),
                                                         colors="k", linewidths=1.0))
        ax.set_xlim(lo[0], hi[0])
        ax.set_ylim(lo[1], hi[1])
        ax.set_aspect("equal")
        ax.set_title(f"{traj.scene.name}: t = {float(traj.time[frame]):.4g} s")
        return []

    FuncAnimation(fig, draw, frames=len(picks)).save(str(path), writer=PillowWriter(fps=fps), dpi=dpi)
    return len(picks)
