"""The block mesher and mesh validation (paper Section 6.1's 3-node elements)."""
import numpy as np
import pytest

from jaxdda.bodies import geometry
from jaxdda.errors import SceneError
from jaxdda.scene.mesh import check_mesh, mesh_polygon, rectangle_mesh

pytestmark = pytest.mark.smoke  # the whole module is cheap: `pytest -m smoke`

SQUARE = [(0, 0), (2, 0), (2, 2), (0, 2)]
L_SHAPE = [(0, 0), (3, 0), (3, 1), (1, 1), (1, 3), (0, 3)]  # concave, area 5
STAR = [(np.cos(a) * r, np.sin(a) * r) for a, r in
        zip(np.pi / 2 + np.pi * np.arange(10) / 5, [2.0, 0.9] * 5)]


def _edges(triangles):
    count = {}
    for tri in triangles.tolist():
        for i, j in ((tri[0], tri[1]), (tri[1], tri[2]), (tri[2], tri[0])):
            key = (min(i, j), max(i, j))
            count[key] = count.get(key, 0) + 1
    return count


@pytest.mark.parametrize("polygon", [SQUARE, L_SHAPE, STAR, SQUARE[::-1]])
@pytest.mark.parametrize("max_edge", [None, 0.4])
def test_mesh_covers_the_polygon_once_and_conforms(polygon, max_edge):
    nodes, triangles = mesh_polygon(polygon, max_edge)
    check_mesh("mesh", nodes, triangles)  # counter-clockwise, no degenerate triangle, no dangling node
    p = nodes[triangles]
    area = 0.5 * ((p[:, 1, 0] - p[:, 0, 0]) * (p[:, 2, 1] - p[:, 0, 1])
                  - (p[:, 1, 1] - p[:, 0, 1]) * (p[:, 2, 0] - p[:, 0, 0]))
    expected = geometry.polygon_properties(geometry.counter_clockwise(np.asarray(polygon, float)))[0]
    np.testing.assert_allclose(area.sum(), expected, rtol=1e-12)
    # conforming: every edge inside is shared by two triangles, the boundary edges by one,
    # and the boundary edges add up to the perimeter
    count = _edges(triangles)
    assert set(count.values()) <= {1, 2}
    boundary = [k for k, v in count.items() if v == 1]
    perimeter = np.linalg.norm(np.diff(np.vstack([polygon, polygon[:1]]), axis=0), axis=1).sum()
    np.testing.assert_allclose(sum(np.linalg.norm(nodes[i] - nodes[j]) for i, j in boundary), perimeter, rtol=1e-12)
    if max_edge is not None:
        longest = max(np.linalg.norm(nodes[i] - nodes[j]) for i, j in count)
        assert longest <= max_edge


NODES = [(0, 0), (1, 0), (1, 1), (0, 1)]


@pytest.mark.parametrize("nodes, triangles, message", [
    (NODES, [(0, 1, 2), (0, 2, 3)], None),
    (NODES, [(0, 2, 1), (0, 2, 3)], "triangle 0 .* inverted"),
    ([(0, 0), (1, 0), (2, 0), (0, 1)], [(0, 1, 2), (0, 2, 3)], "triangle 0 .* degenerate"),
    (NODES, [(0, 1, 2), (0, 2, 4)], "triangle 1 .* outside 0..3"),
    (NODES, [(0, 1, 1), (0, 2, 3)], "triangle 0 .* repeats a node"),
    ([(0, 0), (1, 0), (1, 1), (np.nan, 1)], [(0, 1, 2), (0, 2, 3)], "node 3 is not finite"),
    (NODES + [(5, 5)], [(0, 1, 2), (0, 2, 3)], "node 4 belongs to no triangle"),
    (NODES + [(0.5, -1)], [(0, 1, 2), (0, 2, 3), (0, 4, 1), (0, 1, 2)], "shared by more than two"),
    (NODES, [(0.0, 1.5, 2.0)], "node indices"),
    ([(0, 0), (1, 0)], [(0, 1, 0)], "at least 3"),
])
def test_bad_meshes_are_named(nodes, triangles, message):
    if message is None:
        check_mesh("block 2", nodes, triangles)
        return
    with pytest.raises(SceneError, match=message) as err:
        check_mesh("block 2", nodes, triangles)
    assert str(err.value).startswith("block 2: ")


def test_mesher_rejects_a_self_intersecting_polygon():
    with pytest.raises(SceneError, match="not valid"):
        mesh_polygon([(0, 0), (1, 1), (1, 0), (0, 1)])


@pytest.mark.parametrize("nx, ny", [(1, 1), (3, 2), (4, 5)])
def test_rectangle_mesh_tiles_the_rectangle(nx, ny):
    nodes, triangles = rectangle_mesh(-1.0, 2.0, 3.0, 2.5, nx, ny)
    nodes, triangles = check_mesh("mesh", nodes, triangles)  # counter-clockwise, conforming
    assert len(nodes) == (nx + 1) * (ny + 1) and len(triangles) == 2 * nx * ny
    p = nodes[triangles]
    area = 0.5 * ((p[:, 1, 0] - p[:, 0, 0]) * (p[:, 2, 1] - p[:, 0, 1]) - (p[:, 1, 1] - p[:, 0, 1]) * (p[:, 2, 0] - p[:, 0, 0]))
    np.testing.assert_allclose(area, 4.0 * 0.5 / (2 * nx * ny), rtol=1e-12)


def test_rectangle_mesh_rejects_bad_sizes():
    with pytest.raises(SceneError, match="field 'nx' must be a positive integer"):
        rectangle_mesh(0, 0, 1, 1, 0, 1)
    with pytest.raises(SceneError, match="is empty"):
        rectangle_mesh(0, 0, 0, 1, 1, 1)
