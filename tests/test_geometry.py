import numpy as np
import pytest

from jaxdda.bodies.geometry import (
    counter_clockwise,
    disk_area,
    disk_polar_moment,
    polygon_properties,
    ring_area,
    ring_polar_moment,
    simple_polygon_problem,
)

pytestmark = pytest.mark.smoke  # the whole module is cheap: `pytest -m smoke`


def rect(x0, y0, w, h):
    return np.array([[x0, y0], [x0 + w, y0], [x0 + w, y0 + h], [x0, y0 + h]], float)


def test_unit_square():
    area, c, j = polygon_properties(rect(0, 0, 1, 1))
    assert area == pytest.approx(1.0)
    assert np.allclose(c, [0.5, 0.5])
    assert j == pytest.approx(1.0 / 6.0)


def test_rectangle_far_from_origin():
    w, h = 3.0, 0.5
    area, c, j = polygon_properties(rect(1e4, -2e4, w, h))
    assert area == pytest.approx(w * h)
    assert np.allclose(c, [1e4 + w / 2, -2e4 + h / 2], rtol=0, atol=1e-9)
    assert j == pytest.approx(w * h * (w**2 + h**2) / 12, rel=1e-9)


def test_right_triangle():
    a, b = 3.0, 2.0
    area, c, j = polygon_properties([[0, 0], [a, 0], [0, b]])
    assert area == pytest.approx(a * b / 2)
    assert np.allclose(c, [a / 3, b / 3])
    # About the right-angle corner: Ix + Iy = a b (a^2 + b^2) / 12; shift to the centroid.
    j_corner = a * b * (a**2 + b**2) / 12
    assert j == pytest.approx(j_corner - area * (c @ c))
    assert j == pytest.approx(a * b * (a**2 + b**2) / 36)


def test_l_shape_concave():
    # L = 2x1 bottom bar + 1x1 block on top of its left end.
    poly = [[0, 0], [2, 0], [2, 1], [1, 1], [1, 2], [0, 2]]
    parts = [(2.0, np.array([1.0, 0.5]), 2 * (4 + 1) / 12), (1.0, np.array([0.5, 1.5]), 1 * (1 + 1) / 12)]
    total = sum(p[0] for p in parts)
    centroid = sum(p[0] * p[1] for p in parts) / total
    moment = sum(jc + a * np.sum((cc - centroid) ** 2) for a, cc, jc in parts)
    area, c, j = polygon_properties(poly)
    assert area == pytest.approx(total)
    assert np.allclose(c, centroid)
    assert j == pytest.approx(moment)


def test_clockwise_input():
    poly = np.array([[0, 0], [2, 0], [2, 1], [1, 1], [1, 2], [0, 2]], float)
    a1, c1, j1 = polygon_properties(poly)
    a2, c2, j2 = polygon_properties(poly[::-1])
    assert a2 == pytest.approx(-a1) and a2 < 0
    assert np.allclose(c1, c2)
    assert j2 == pytest.approx(j1) and j2 > 0


def test_counter_clockwise():
    poly = rect(0, 0, 2, 1)
    assert np.array_equal(counter_clockwise(poly), poly)
    fixed = counter_clockwise(poly[::-1])
    assert polygon_properties(fixed)[0] > 0
    assert np.array_equal(fixed, poly[::-1][::-1])


def test_zero_area_properties_raises():
    with pytest.raises(ValueError):
        polygon_properties([[0, 0], [1, 0], [2, 0]])


def star(n=5, r_out=1.0, r_in=0.4):
    ang = np.pi / 2 + np.arange(2 * n) * np.pi / n
    r = np.where(np.arange(2 * n) % 2 == 0, r_out, r_in)
    return np.stack([r * np.cos(ang), r * np.sin(ang)], axis=1)


def test_valid_polygons():
    assert simple_polygon_problem(rect(0, 0, 1, 1)) is None
    assert simple_polygon_problem(star()) is None
    assert simple_polygon_problem(star()[::-1]) is None
    assert simple_polygon_problem([[0, 0], [2, 0], [2, 1], [1, 1], [1, 2], [0, 2]]) is None
    # Collinear consecutive vertices (a vertex in the middle of an edge) are allowed.
    assert simple_polygon_problem([[0, 0], [1, 0], [2, 0], [2, 1], [0, 1]]) is None
    assert simple_polygon_problem(rect(1e6, 1e6, 1e-3, 1e-3)) is None


def test_bow_tie():
    msg = simple_polygon_problem([[0, 0], [1, 1], [1, 0], [0, 1]])
    assert msg is not None and msg.startswith("self-intersecting")
    msg = simple_polygon_problem([[0, 0], [2, 1], [2, 0], [0, 1]])  # asymmetric, nonzero area
    assert msg == "self-intersecting (edges 0 and 2 cross)"


def test_touching_and_folding_edges():
    # A vertex touching a non-adjacent edge.
    assert simple_polygon_problem([[0, 0], [4, 0], [4, 2], [2, 0], [0, 2]]).startswith("self-intersecting")
    # An edge doubling back onto the previous one.
    assert simple_polygon_problem([[0, 0], [2, 0], [1, 0], [1, 1]]).startswith("self-intersecting")


def test_degenerate_polygons():
    assert simple_polygon_problem([[0, 0], [1, 1]]) == "fewer than 3 vertices"
    assert simple_polygon_problem([[0, 0], [1, 0], [2, 0]]) == "zero area"
    assert simple_polygon_problem([[0, 0], [1, 1], [2, 2], [3, 3]]) == "zero area"
    assert simple_polygon_problem([[0, 0], [1, 0], [1, 0], [0, 1]]) == "repeated vertex 2"
    assert simple_polygon_problem([[0, 0], [1, 0], [0, 1], [0, 0]]) == "repeated vertex 3"
    assert simple_polygon_problem([[0, 0], [1, np.nan], [0, 1]]) == "non-finite coordinate at vertex 1"
    assert simple_polygon_problem([[0, 0], [1, 0], [np.inf, 1]]) == "non-finite coordinate at vertex 2"


def test_circles():
    assert disk_area(2.0) == pytest.approx(4 * np.pi)
    assert ring_area(2.0, 1.0) == pytest.approx(3 * np.pi)
    assert disk_polar_moment(2.0) == pytest.approx(8 * np.pi)
    assert ring_polar_moment(2.0, 1.0) == pytest.approx(7.5 * np.pi)
    assert ring_polar_moment(2.0, 0.0) == pytest.approx(disk_polar_moment(2.0))


def test_regular_polygon_tends_to_disk():
    ang = np.linspace(0, 2 * np.pi, 2000, endpoint=False)
    area, c, j = polygon_properties(np.stack([np.cos(ang), np.sin(ang)], 1) + 5.0)
    assert area == pytest.approx(disk_area(1.0), rel=1e-5)
    assert np.allclose(c, [5, 5])
    assert j == pytest.approx(disk_polar_moment(1.0), rel=1e-5)
