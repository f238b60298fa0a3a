"""Polygon-polygon contact geometry: a vertex is held at its real clearance or overlap,
never at its distance to the line of an edge it lies beside, nor to the line of a
farther edge than the one it entered by (fuzz seed 82: such a gap of -0.14 m threw a
light polygon out at 138 m/s); a corner entering a notch meets both its edges (seed 194:
held on one, it went 12 mm into the other); two faces overlapping edge to edge keep both
their corners however far the detection distance reaches (seed 1643: one kept, the
other went 15 mm in)."""
import jax.numpy as jnp
import numpy as np

import jaxdda
from jaxdda.contact.detect import detect
from jaxdda.contact.kinematics import gap_frame

SQUARE = [(-0.5, -0.5), (0.5, -0.5), (0.5, 0.5), (-0.5, 0.5)]  # A; its corner (0.5, 0.5)
FAR = 5.0  # B is built this far to the right (apart), then moved back for the test


def _wedge(tip, lo_deg, hi_deg, length=0.5):
    """A triangle with a corner at ``tip`` whose two edges leave it at these angles."""
    tip = np.asarray(tip)
    u = lambda deg: np.array([np.cos(np.radians(deg)), np.sin(np.radians(deg))])
    return [tuple(tip), tuple(tip + length * u(lo_deg)), tuple(tip + length * u(hi_deg))]


def _gaps(polygon, reach=0.4, first=SQUARE, turn=0.0):
    """Sorted gaps of every contact detected between A (``first``) and the polygon B
    where they are given (world coordinates; the pair's detection distance ``reach``
    and the angle ``turn`` it may turn in the step)."""
    sb = jaxdda.SceneBuilder(dt=1e-3)
    sb.add_polygon(first, density=1.0)
    sb.add_polygon([(x + FAR, y) for x, y in polygon], density=1.0)
    scene = sb.build()
    centroid = scene.state.centroid - jnp.array([[0.0, 0.0], [FAR, 0.0]])
    rotation = scene.state.rotation
    c, needed = detect(scene.model, centroid, rotation, jnp.full(2, 0.5 * reach), jnp.full(2, 0.5 * turn),
                     scene.params.margin)
    cap = scene.model.capacity
    assert np.all(np.asarray(needed) <= [cap.candidates, cap.pairs_pp, cap.pairs_pb, cap.pairs_bb, cap.contacts])
    gap = np.asarray(gap_frame(c, centroid, rotation)[0])
    return np.sort(gap[np.asarray(c.valid)])


def test_a_corner_beside_an_edge_extension_is_held_at_its_clearance():
    # B's corner (0.55, 0.4) lies right of A's right edge (clearance 0.05) and 0.1 below
    # the line of A's top edge; its wedge (20..100 deg) faces that top edge, so the old
    # vertex-vertex rule held it there at -0.1. Nothing overlaps: A's corner is 0.0318
    # from B's edge at 100 deg, the least clearance of the pair.
    gaps = _gaps(_wedge((0.55, 0.4), 20.0, 100.0))
    assert gaps.size, "the corners 0.03 apart are within reach"
    clearance = abs(-0.05 * np.sin(np.radians(100.0)) - 0.1 * np.cos(np.radians(100.0)))
    assert np.isclose(gaps[0], clearance, rtol=0, atol=1e-12), gaps


def test_a_corner_inside_is_held_by_its_nearest_edge():
    # B's corner 0.01 inside A's right edge and 0.03 below its top edge; the wedge
    # (30..70 deg) leaves through the right edge, so this corner is the whole overlap:
    # held at -0.01, not at -0.03 by the top edge its wedge faces.
    gaps = _gaps(_wedge((0.49, 0.47), 30.0, 70.0))
    assert np.isclose(gaps[0], -0.01, rtol=0, atol=1e-12), gaps
    assert np.sum(gaps < 0) == 1, gaps


def test_a_corner_entering_a_notch_meets_both_its_edges():
    # A: a block with a V-notch in its top (reflex vertex (0, -0.5), edges of slope 1/2);
    # B: a spike whose tip is 0.05 above the notch's vertex. Both notch edges are
    # 0.05 / sqrt(1.25) from the tip; held on one only, it slides into the other.
    notched = [(-1.0, -1.0), (1.0, -1.0), (1.0, 0.0), (0.0, -0.5), (-1.0, 0.0)]
    spike = [(0.0, -0.45), (0.3, 0.5), (-0.3, 0.5)]
    gaps = _gaps(spike, first=notched)
    clearance = 0.05 / np.sqrt(1.25)
    assert np.sum(np.isclose(gaps, clearance, rtol=0, atol=1e-12)) == 2, gaps
    assert np.all(gaps > clearance - 1e-12), gaps


def test_faces_overlapping_edge_to_edge_keep_both_corners():
    # B: a unit block above A's top face, tilted by -0.02 rad about its lower-left corner
    # Q = (0.3, 0.51); A's top-right corner P = (0.5, 0.5) lies under B's bottom face. The
    # faces overlap over 0.2 m, less than the detection distance (0.4 m, a fast spinning
    # pair), so P and Q are also a vertex-vertex pair. Edge to edge, each corner is held
    # by the other's face: P at its distance to B's bottom line, Q at 0.01 above A's top.
    theta, q = -0.02, np.array([0.3, 0.51])
    rot = np.array([[np.cos(theta), -np.sin(theta)], [np.sin(theta), np.cos(theta)]])
    block = [tuple(q + rot @ np.array(v)) for v in [(0.0, 0.0), (1.0, 0.0), (1.0, 1.0), (0.0, 1.0)]]
    gaps = _gaps(block, reach=0.4, turn=0.05)
    p_gap = (np.array([0.5, 0.5]) - q) @ np.array([np.sin(theta), -np.cos(theta)])
    assert np.allclose(gaps, sorted([p_gap, 0.01]), rtol=0, atol=1e-12), gaps
