"""ParaView output: a trajectory as VTK XML PolyData time series, one ``.vtp`` file per
saved step plus a ``.pvd`` index per series (plain XML, no VTK library needed).

Two series: ``<name>_bodies`` (every body as a polygon; disks and rings as 48-gons, a
ring's hole as a line loop; cell data: body index, fixed, stress, velocity, angular
velocity) and ``<name>_contacts`` (one vertex per valid contact at its point; point
data: force vector on body a, normal and shear force, rolling moment, bodies a and b).
"""
from __future__ import annotations

from pathlib import Path
from xml.sax.saxutils import quoteattr

import numpy as np

from jaxdda.types import DISK, RING

ROUND_SIDES = 48  # sides of the polygon that draws a disk or ring


def _circle(centre, radius, turn, sides=ROUND_SIDES):
    angle = turn + 2.0 * np.pi * np.arange(sides) / sides
    return centre + radius * np.stack([np.cos(angle), np.sin(angle)], -1)


def _array(name: str, values: np.ndarray, components: int = 1) -> str:
    kind = "Int64" if np.issubdtype(values.dtype, np.integer) else "Float64"
    text = " ".join(repr(float(v)) if kind == "Float64" else str(int(v)) for v in np.ravel(values))
    return (f'<DataArray type="{kind}" Name={quoteattr(name)} NumberOfComponents="{components}" '
            f'format="ascii">{text}</DataArray>')


def _polydata(points: np.ndarray, polys: list[list[int]], lines: list[list[int]], verts: list[int],
              cell_data: str, point_data: str = "") -> str:
    def cells(tag, groups):
        if not groups:
            return ""
        conn = np.concatenate([np.asarray(g, np.int64) for g in groups]) if groups else np.zeros(0, np.int64)
        offsets = np.cumsum([len(g) for g in groups])
        return f"<{tag}>{_array('connectivity', conn)}{_array('offsets', offsets)}</{tag}>"

    pts3 = np.concatenate([points, np.zeros((len(points), 1))], 1) if len(points) else np.zeros((0, 3))
    return ('<?xml version="1.0"?>\n<VTKFile type="PolyData" version="1.0" byte_order="LittleEndian">'
            f'<PolyData><Piece NumberOfPoints="{len(points)}" NumberOfVerts="{len(verts)}" '
            f'NumberOfLines="{len(lines)}" NumberOfStrips="0" NumberOfPolys="{len(polys)}">'
            f'<Points>{_array("Points", pts3, 3)}</Points>'
            f'{cells("Verts", [[v] for v in verts])}{cells("Lines", lines)}{cells("Polys", polys)}'
            f'<CellData>{cell_data}</CellData><PointData>{point_data}</PointData>'
            '</Piece></PolyData></VTKFile>\n')


def _bodies_file(traj, frame: int, vertices) -> str:
    model = traj.scene.model
    kind, radius = np.asarray(model.kind), np.asarray(model.radius, float)
    inner, mask = np.asarray(model.inner_radius, float), np.asarray(model.vertex_mask, bool)
    scale = np.sqrt(np.abs(np.linalg.det(traj.stretch[frame]))) if traj.stretch is not None else np.ones(len(kind))
    points, polys, lines, owners = [], [], [], []
    count = 0
    for i, k in enumerate(kind):
        c, turn = traj.centroid[frame, i], traj.rotation[frame, i]
        outline = (_circle(c, radius[i] * scale[i], turn) if k in (DISK, RING)
                   else vertices[frame, i][mask[i]])
        polys.append(list(range(count, count + len(outline))))
        points.append(outline)
        count += len(outline)
        owners.append(i)
        if k == RING:
            hole = _circle(c, inner[i] * scale[i], turn)
            lines.append(list(range(count, count + len(hole))) + [count])
            points.append(hole)
            count += len(hole)
    # Cell order in VTK: verts, lines, polys. Lines are the rings' holes.
    ring_ids = [i for i, k in enumerate(kind) if k == RING]
    cell_body = np.asarray(ring_ids + owners, np.int64)
    data = (_array("body", cell_body) + _array("fixed", np.asarray(model.fixed, np.int64)[cell_body])
            + _array("stress", traj.stress[frame][cell_body], 3)
            + _array("velocity", traj.velocity[frame][cell_body, :2], 2)
            + _array("angular_velocity", traj.velocity[frame][cell_body, 2]))
    return _polydata(np.concatenate(points) if points else np.zeros((0, 2)), polys, lines, [], data)


def _contacts_file(traj, step: int) -> str:
    c = traj.info.contacts
    valid = np.asarray(c.valid[step], bool)
    pts = np.asarray(c.point[step])[valid]
    data = (_array("force", np.asarray(c.force[step])[valid], 2) + _array("normal_force", np.asarray(c.normal_force[step])[valid])
            + _array("shear_force", np.asarray(c.shear_force[step])[valid]) + _array("moment", np.asarray(c.moment[step])[valid])
            + _array("body_a", np.asarray(c.a[step])[valid].astype(np.int64))
            + _array("body_b", np.asarray(c.b[step])[valid].astype(np.int64)))
    return _polydata(pts, [], [], list(range(len(pts))), "", data)


def write_vtk(traj, folder, *, every: int = 1, name: str | None = None) -> list[Path]:
    """Write every ``every``-th state of ``traj`` (always the last) to ``folder``; returns
    the two ``.pvd`` index files (open them in ParaView). Contacts are those of the step
    that ends at each state (none at t = 0)."""
    if isinstance(every, bool) or int(every) != every or every < 1:
        raise ValueError(f"every must be a positive integer, got {every!r}")
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    name = name or traj.scene.name
    frames = sorted(set(range(0, len(traj.time), int(every))) | {len(traj.time) - 1})
    vertices = traj.vertices()
    index = {"bodies": [], "contacts": []}
    for frame in frames:
        for series, text in (("bodies", _bodies_file(traj, frame, vertices)),
                             ("contacts", _contacts_file(traj, frame - 1) if frame > 0 else _polydata(
                                 np.zeros((0, 2)), [], [], [], ""))):
            file = f"{name}_{series}_{frame:06d}.vtp"
            (folder / file).write_text(text)
            index[series].append((float(traj.time[frame]), file))
    out = []
    for series, entries in index.items():
        rows = "".join(f'<DataSet timestep="{t!r}" part="0" file={quoteattr(f)}/>' for t, f in entries)
        path = folder / f"{name}_{series}.pvd"
        path.write_text('<?xml version="1.0"?>\n<VTKFile type="Collection" version="1.0">'
                        f"<Collection>{rows}</Collection></VTKFile>\n")
        out.append(path)
    return out
