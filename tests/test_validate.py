import time

import numpy as np
import pytest

from jaxdda.errors import SceneError
from jaxdda.scene.validate import check_finite, check_no_interpenetration, check_positive, overlap_depth

TOUCH = 1e-9  # "zero" for touching shapes of size ~1-100


def rect(x0, y0, w, h):
    return ("polygon", np.array([[x0, y0], [x0 + w, y0], [x0 + w, y0 + h], [x0, y0 + h]], float))


def disk(x, y, r):
    return ("disk", np.array([x, y], float), r)


def ring(x, y, ro, ri):
    return ("ring", np.array([x, y], float), ro, ri)


def depth(a, b):
    d1, d2 = overlap_depth(a, b), overlap_depth(b, a)
    assert d1 == pytest.approx(d2, abs=1e-12)
    return d1


# ---------------------------------------------------------------- field checks
@pytest.mark.smoke
def test_check_finite():
    check_finite("body 0 (disk)", "radius", 1.0)
    check_finite("body 0 (disk)", "center", [1.0, 2.0])
    with pytest.raises(SceneError, match=r"body 3 \(disk\): field 'radius'.*not finite"):
        check_finite("body 3 (disk)", "radius", float("nan"))
    with pytest.raises(SceneError, match=r"body 1 \(polygon\): field 'vertices'.*\(2, 1\).*not finite"):
        check_finite("body 1 (polygon)", "vertices", [[0, 0], [1, 0], [0, np.inf]])
    with pytest.raises(SceneError, match="not numeric"):
        check_finite("body 1", "density", "heavy")


@pytest.mark.smoke
def test_check_positive():
    check_positive("body 2 (ring)", "inner_radius", 0.5)
    for bad in (0.0, -1.0):
        with pytest.raises(SceneError, match=r"body 2 \(ring\): field 'inner_radius' must be > 0, got"):
            check_positive("body 2 (ring)", "inner_radius", bad)
    for bad in (float("nan"), float("inf")):
        with pytest.raises(SceneError, match=r"body 2 \(ring\): field 'inner_radius'"):
            check_positive("body 2 (ring)", "inner_radius", bad)
    assert issubclass(SceneError, ValueError)


# ---------------------------------------------------------------- circles
@pytest.mark.smoke
def test_disk_disk():
    assert depth(disk(0, 0, 1), disk(3, 0, 2)) < TOUCH
    assert depth(disk(0, 0, 1), disk(0.6, 0.8 * 3.75, 2)) < TOUCH * 10
    assert depth(disk(0, 0, 1), disk(2.9, 0, 2)) == pytest.approx(0.1)
    assert depth(disk(0, 0, 1), disk(5, 0, 2)) == 0.0
    assert depth(disk(0, 0, 10), disk(1, 0, 1)) > 1  # small disk inside a big one


@pytest.mark.smoke
def test_disk_ring():
    assert depth(ring(0, 0, 150, 100), disk(60, 0, 40)) < TOUCH  # touching the hole from inside
    assert depth(ring(0, 0, 150, 100), disk(36, 48, 40)) < TOUCH
    assert depth(ring(0, 0, 150, 100), disk(61, 0, 40)) == pytest.approx(1.0)
    assert depth(ring(0, 0, 150, 100), disk(10, 0, 40)) == 0.0  # loose in the hole
    assert depth(ring(0, 0, 150, 100), disk(190, 0, 40)) < TOUCH  # touching the outside
    assert depth(ring(0, 0, 150, 100), disk(189, 0, 40)) == pytest.approx(1.0)
    assert depth(ring(0, 0, 150, 100), disk(125, 0, 5)) > 1  # inside the material
    assert depth(ring(0, 0, 150, 100), disk(0, 0, 120)) > 10  # disk larger than the hole
    assert depth(ring(0, 0, 150, 100), disk(0, 0, 500)) > 10  # disk covering the ring


@pytest.mark.smoke
def test_ring_ring():
    assert depth(ring(0, 0, 150, 100), ring(50, 0, 50, 30)) < TOUCH  # inside the hole, touching
    assert depth(ring(0, 0, 150, 100), ring(51, 0, 50, 30)) == pytest.approx(1.0)
    assert depth(ring(0, 0, 150, 100), ring(0, 0, 50, 30)) == 0.0
    assert depth(ring(0, 0, 150, 100), ring(0, 0, 300, 150)) < TOUCH  # nested, touching
    assert depth(ring(0, 0, 150, 100), ring(0, 0, 300, 149)) == pytest.approx(1.0)
    assert depth(ring(0, 0, 150, 100), ring(0, 0, 300, 200)) == 0.0  # first inside the second's hole
    assert depth(ring(0, 0, 2, 1), ring(4, 0, 2, 1)) < TOUCH
    assert depth(ring(0, 0, 2, 1), ring(3, 0, 2, 1)) == pytest.approx(1.0)


# ---------------------------------------------------------------- polygon / circle
@pytest.mark.smoke
def test_disk_polygon():
    sq = rect(0, 0, 2, 2)
    assert depth(sq, disk(1, 3, 1)) < TOUCH  # resting on the top edge
    assert depth(sq, disk(3, 3, np.sqrt(2))) < TOUCH  # touching a corner
    assert depth(sq, disk(1, 2.9, 1)) == pytest.approx(0.1)
    assert depth(sq, disk(1, 5, 1)) == 0.0
    assert depth(sq, disk(1, 1, 0.2)) == pytest.approx(1.2)  # disk fully inside
    assert depth(sq, disk(1, 1, 10)) == pytest.approx(11)  # polygon fully inside the disk
    assert depth(rect(3, 0, 1, 1), disk(0, 0, 10)) > 5  # inside, centre outside the polygon
    assert depth(rect(0, 0, 2, 2), disk(1, 1.5, 0.5)) == pytest.approx(1.0)  # inside, touching


@pytest.mark.smoke
def test_polygon_concave_notch_disk():
    u = ("polygon", np.array([[0, 0], [3, 0], [3, 3], [2, 3], [2, 1], [1, 1], [1, 3], [0, 3]], float))
    assert depth(u, disk(1.5, 2, 0.5)) < TOUCH  # in the slot, touching both walls
    assert depth(u, disk(1.5, 2, 0.51)) == pytest.approx(0.01)
    assert depth(u, disk(1.5, 1.5, 0.5)) < TOUCH  # also touching the bottom of the slot


@pytest.mark.smoke
def test_polygon_ring():
    r = ring(0, 0, 150, 100)
    assert depth(r, rect(-10, -10, 20, 20)) == 0.0  # loose in the hole
    assert depth(r, rect(0, 0, 60, 80)) < TOUCH  # corner (60, 80) touches the hole from inside
    assert depth(r, rect(0, 0, 61, 80)) > 0.5
    assert depth(r, rect(-10, 150, 20, 10)) < TOUCH  # resting on the outside
    assert depth(r, rect(-10, 149, 20, 10)) == pytest.approx(1.0)
    assert depth(r, rect(-5, 120, 10, 10)) > 5  # inside the material
    assert depth(r, rect(-500, -500, 1000, 1000)) > 10  # covering the ring
    assert depth(r, rect(-5, -200, 10, 400)) > 1  # a bar through the whole ring


# ---------------------------------------------------------------- polygon / polygon
@pytest.mark.smoke
def test_polygons_touching():
    assert depth(rect(0, 0, 1, 1), rect(0, 1, 1, 1)) < TOUCH  # block standing on a block
    assert depth(rect(0, 0, 1, 1), rect(0.5, 1, 1, 1)) < TOUCH  # shifted, partial shared edge
    assert depth(rect(0, 0, 1, 1), rect(1, 1, 1, 1)) < TOUCH  # corners touching
    tri = ("polygon", np.array([[0, 1], [1, 2], [-1, 2]], float))
    assert depth(rect(-1, 0, 2, 1), tri) < TOUCH  # vertex on an edge
    assert depth(rect(0, 0, 1, 1), rect(3, 0, 1, 1)) == 0.0
    big = rect(-1e4, -1e4, 2e4, 1e4)
    assert depth(big, rect(-2, 0, 4, 4)) < 1e-9 * 2e4


@pytest.mark.smoke
def test_polygons_overlapping():
    assert depth(rect(0, 0, 1, 1), rect(0, 0.9, 1, 1)) == pytest.approx(0.1)
    assert depth(rect(0, 0, 1, 1), rect(0.5, 0.5, 1, 1)) == pytest.approx(0.5)
    assert depth(rect(0, 0, 10, 10), rect(4, 4, 1, 1)) == pytest.approx(5)  # fully inside
    tri = ("polygon", np.array([[0, 0.9], [1, 2], [-1, 2]], float))
    assert depth(rect(-1, 0, 2, 1), tri) == pytest.approx(0.1)
    assert depth(rect(0, 0, 1, 1), rect(0, 0, 1, 1)) > 0.25  # coincident
    assert depth(rect(0, 0, 1, 1), rect(0.5, 0, 1, 1)) == pytest.approx(0.5)  # same height, shifted


@pytest.mark.smoke
def test_cross_of_thin_rectangles():
    # No vertex of either lies inside the other.
    assert depth(rect(-5, -0.1, 10, 0.2), rect(-0.1, -5, 0.2, 10)) == pytest.approx(0.1)


@pytest.mark.smoke
def test_concave_polygons_interlocking():
    u = ("polygon", np.array([[0, 0], [3, 0], [3, 3], [2, 3], [2, 1], [1, 1], [1, 3], [0, 3]], float))
    assert depth(u, rect(1, 1, 1, 3)) < TOUCH  # a key exactly filling the slot
    assert depth(u, rect(0.9, 1.5, 1, 1)) == pytest.approx(0.1)
    assert depth(u, rect(1.2, 1.2, 0.6, 3)) == 0.0  # loose key
    assert depth(u, rect(-1, 1.5, 5, 0.5)) > 0.2  # bar through both prongs


# ---------------------------------------------------------------- scene check
@pytest.mark.smoke
def test_check_no_interpenetration():
    shapes = [rect(0, 0, 1, 1), rect(0, 1, 1, 1), disk(1.5, 0.5, 0.5), ring(10, 10, 5, 3), disk(10, 10, 3)]
    labels = [f"body {k}" for k in range(len(shapes))]
    check_no_interpenetration(shapes, labels, tol=1e-9)
    shapes.append(disk(2.4, 0.5, 0.5))
    labels.append("body 5 (disk)")
    with pytest.raises(SceneError, match=r"body 2 and body 5 \(disk\) interpenetrate at the start \(overlap 0.1\)"):
        check_no_interpenetration(shapes, labels, tol=1e-9)
    check_no_interpenetration(shapes, labels, tol=0.2)


def test_check_no_interpenetration_many_bodies_fast():
    shapes, labels = [], []
    for i in range(40):
        for j in range(50):
            x, y = 2.0 * i, 2.0 * j
            shapes.append(disk(x, y, 1.0) if (i + j) % 2 else rect(x - 1, y - 1, 2, 2))
            labels.append(f"body {len(labels)}")
    start = time.perf_counter()
    check_no_interpenetration(shapes, labels, tol=1e-6)
    assert time.perf_counter() - start < 10
    shapes[-1] = disk(2.0 * 39, 2.0 * 49 - 0.1, 1.0)
    with pytest.raises(SceneError, match="body 1998 and body 1999"):
        check_no_interpenetration(shapes, labels, tol=1e-6)
