"""Joint-line block cutting: block counts and areas known in closed form; areas always
sum to the boundary's; each block edge names the line that made it."""
import numpy as np
import pytest

from jaxdda.bodies import geometry
from jaxdda.errors import SceneError
from jaxdda.scene.cutting import BOUNDARY, JointSet, cut_blocks

RECT = np.array([(0.0, 0.0), (4.0, 0.0), (4.0, 3.0), (0.0, 3.0)])


@pytest.mark.smoke
def test_two_through_joints_make_four_blocks():
    blocks = cut_blocks(RECT, [[(2, -1), (2, 4)], [(-1, 1), (5, 1)]])
    assert sorted(round(b.area, 12) for b in blocks) == [2.0, 2.0, 4.0, 4.0]
    for b in blocks:
        assert len(b.vertices) == 4
        assert sorted(b.edge_lines.tolist()) == [BOUNDARY, BOUNDARY, 0, 1]  # two boundary edges, one of each joint
        assert geometry.polygon_properties(b.vertices)[0] > 0  # counter-clockwise


@pytest.mark.smoke
def test_a_joint_ending_inside_a_block_cuts_nothing():
    blocks = cut_blocks(RECT, [[(2, -1), (2, 1.5)], [(1, 1), (3, 2)]])
    assert len(blocks) == 1
    assert blocks[0].area == pytest.approx(12.0, rel=1e-12)
    assert (blocks[0].edge_lines == BOUNDARY).all()


@pytest.mark.smoke
def test_concave_boundary():
    ell = [(0, 0), (3, 0), (3, 1), (1, 1), (1, 3), (0, 3)]
    blocks = cut_blocks(ell, [[(-1, 0.5), (4, 0.5)], [(-1, 2), (4, 2)]])
    assert [round(b.area, 12) for b in blocks] == [2.5, 1.5, 1.0]


@pytest.mark.smoke
def test_orthogonal_persistent_sets_make_a_grid():
    """Sets at 0 and 90 degrees with spacing 1, offset 0.5 about the centre (2, 1.5): rows
    cut at y = 1, 2 and columns at x = 0.5, 1.5, 2.5, 3.5: 3 x 5 blocks."""
    lines = np.concatenate([JointSet(dip=0.0, spacing=1.0, offset=0.5).lines(RECT),
                            JointSet(dip=90.0, spacing=1.0, offset=0.5).lines(RECT)])
    blocks = cut_blocks(RECT, lines)
    assert len(blocks) == 15
    assert sorted(round(b.area, 12) for b in blocks) == [0.5] * 6 + [1.0] * 9


@pytest.mark.smoke
@pytest.mark.parametrize("sets", [
    [JointSet(dip=30.0, spacing=0.7), JointSet(dip=120.0, spacing=0.9)],
    [JointSet(dip=10.0, spacing=0.6, trace=2.0, bridge=0.8), JointSet(dip=95.0, spacing=0.8, offset=0.1)],
    [JointSet(dip=45.0, spacing=0.5, trace=1.5, bridge=0.5, stagger=0.3), JointSet(dip=-40.0, spacing=0.7, trace=2.5, bridge=0.4)],
])
def test_joint_sets_tile_the_boundary(sets):
    lines = np.concatenate([s.lines(RECT) for s in sets])
    blocks = cut_blocks(RECT, lines)
    assert len(blocks) > 1
    assert sum(b.area for b in blocks) == pytest.approx(12.0, rel=1e-12)
    for b in blocks:
        assert geometry.simple_polygon_problem(b.vertices) is None
        assert ((b.edge_lines == BOUNDARY) | ((b.edge_lines >= 0) & (b.edge_lines < len(lines)))).all()


@pytest.mark.smoke
def test_bad_input_is_named():
    with pytest.raises(SceneError, match="the boundary is not a valid polygon"):
        cut_blocks([(0, 0), (1, 1), (1, 0), (0, 1)], [])
    with pytest.raises(SceneError, match="joint line 1 is not finite"):
        cut_blocks(RECT, [[(0, 0), (1, 1)], [(0, np.nan), (1, 1)]])
    with pytest.raises(SceneError, match="joint line 0 has zero length"):
        cut_blocks(RECT, [[(1, 1), (1, 1)]])
    with pytest.raises(SceneError, match="field 'spacing' must be > 0"):
        JointSet(dip=0.0, spacing=0.0).lines(RECT)
    with pytest.raises(SceneError, match="smaller than min_area"):
        cut_blocks(RECT, [[(-1, 0.01), (5, 0.01)]], min_area=0.1)


def test_cut_blocks_slide_on_their_joint_with_its_friction():
    """A rectangle cut by one joint into two blocks; the lower one fixed. The rock is
    rough (mu = 0.9, it would hold at 30 degrees) but the joint is smooth (mu = 0.2):
    the upper block slides along it as if both blocks were of the joint's material, at
    g (sin a - mu_joint cos a). Gravity is tilted.

    The closed form holds to 1.3e-6 here, for blocks of the joint's material as well: the
    blocks start corner to corner, and that start (not the joint law) leaves this error,
    which is not yet explained (noted on issue 8)."""
    import jaxdda

    g, angle = 9.81, np.radians(30.0)
    blocks = cut_blocks([(0, 0), (4, 0), (4, 2), (0, 2)], [[(-1, 1), (5, 1)]])
    sb = jaxdda.SceneBuilder(dt=0.01, gravity=(g * np.sin(angle), -g * np.cos(angle)))
    sb.add_material("rock", friction=0.9, restitution=0.0)
    sb.add_material("bedding", friction=0.2, restitution=0.0)
    lower = [k for k, b in enumerate(blocks) if b.vertices[:, 1].min() == 0][0]
    bodies = sb.add_blocks(blocks, 2500.0, joints={0: "bedding"}, fixed=[lower], material="rock")
    scene = sb.build()
    run = jaxdda.simulate(scene, 30)
    plain = jaxdda.SceneBuilder(dt=0.01, gravity=(g * np.sin(angle), -g * np.cos(angle)))
    plain.add_material("bedding", friction=0.2, restitution=0.0)
    plain.add_blocks(blocks, 2500.0, fixed=[lower], material="bedding")
    reference = jaxdda.simulate(plain.build(), 30)
    np.testing.assert_allclose(run.centroid, reference.centroid, rtol=0, atol=1e-12)
    upper = bodies[1 - lower]
    slid = run.centroid[:, upper, 0] - run.centroid[0, upper, 0]
    np.testing.assert_allclose(slid, 0.5 * g * (np.sin(angle) - 0.2 * np.cos(angle)) * run.time ** 2, rtol=2e-6)
    np.testing.assert_allclose(run.centroid[:, upper, 1], run.centroid[0, upper, 1], atol=1e-9)
    # the joint edges carry the joint's material, the boundary edges none
    edge_material = np.asarray(scene.model.edge_material)
    assert sorted(edge_material[upper][:4].tolist()) == [-1, -1, -1, scene.materials.index("bedding")]
