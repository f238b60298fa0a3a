"""ParaView output, read back with the standard library's XML parser."""
import xml.etree.ElementTree as ET

import numpy as np
import pytest

import jaxdda
from jaxdda.viz.vtk import ROUND_SIDES, write_vtk


@pytest.fixture(scope="module")
def run():
    sb = jaxdda.SceneBuilder(dt=0.01, name="mix")
    sb.add_polygon(vertices=[(-5, -1), (5, -1), (5, 0), (-5, 0)], density=1.0, fixed=True)
    sb.add_disk(center=(-3, 1.0), radius=1.0, density=1.0)
    sb.add_ring(center=(0, 1.5), inner_radius=0.5, outer_radius=1.5, density=1.0)
    sb.add_polygon(vertices=[(2, 0.0), (4, 0.0), (3, 2)], density=1.0, young=1e6, poisson=0.2)
    return jaxdda.simulate(sb.build(), 6)


def arrays(piece, section):
    out = {}
    for a in piece.find(section).findall("DataArray"):
        values = np.array(a.text.split(), float) if a.text else np.zeros(0)
        out[a.get("Name")] = values.reshape(-1, int(a.get("NumberOfComponents")))
    return out


def test_series_read_back(run, tmp_path):
    bodies_pvd, contacts_pvd = write_vtk(run, tmp_path, every=4)
    for pvd in (bodies_pvd, contacts_pvd):
        sets = ET.parse(pvd).getroot().find("Collection").findall("DataSet")
        assert [float(d.get("timestep")) for d in sets] == pytest.approx(run.time[[0, 4, 6]])
        assert all((tmp_path / d.get("file")).exists() for d in sets)
    last = ET.parse(tmp_path / "mix_bodies_000006.vtp").getroot().find("PolyData/Piece")
    assert int(last.get("NumberOfPolys")) == 4 and int(last.get("NumberOfLines")) == 1  # the ring's hole
    cells = arrays(last, "CellData")
    assert cells["body"].ravel().tolist() == [2, 0, 1, 2, 3]  # lines first, then polygons
    np.testing.assert_allclose(cells["stress"][1:], run.stress[-1])
    np.testing.assert_allclose(cells["velocity"][1:], run.velocity[-1][:, :2])
    points = arrays(last, "Points")["Points"]
    assert len(points) == 4 + ROUND_SIDES + 2 * ROUND_SIDES + 3
    triangle = points[-3:, :2]
    np.testing.assert_allclose(triangle, run.vertices()[-1, 3, :3], atol=1e-12)
    disk = points[4:4 + ROUND_SIDES, :2]
    np.testing.assert_allclose(np.linalg.norm(disk - run.centroid[-1, 1], axis=1), 1.0, rtol=1e-12)
    contacts = ET.parse(tmp_path / "mix_contacts_000006.vtp").getroot().find("PolyData/Piece")
    c = run.info.contacts
    valid = c.valid[5]
    assert int(contacts.get("NumberOfVerts")) == valid.sum() > 0
    data = arrays(contacts, "PointData")
    np.testing.assert_allclose(data["force"], c.force[5][valid])
    np.testing.assert_allclose(arrays(contacts, "Points")["Points"][:, :2], c.point[5][valid])
    with pytest.raises(ValueError, match="every must be a positive integer"):
        write_vtk(run, tmp_path, every=0)
