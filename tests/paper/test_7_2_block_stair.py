"""Case 7.2: four blocks as a staircase; base reactions W/2 and 7W/2 (validation-cases.md)."""
import numpy as np
import pytest

import jaxdda

W = 2000.0 * 10.0 * 20.0 * 10.0  # block weight, 4.0e6 N
PAPER_F1_ERROR, PAPER_F2_ERROR = 0.02319, 0.11433  # N, the paper's errors (Table 2)
BASE = 4  # body index of the base; blocks 0..3 are B1 (top) .. B4 (bottom)


@pytest.fixture(scope="module", params=[False, True], ids=["fixed-base", "heavy-base"])
def run(request):
    return jaxdda.simulate(jaxdda.examples.get("paper-7.2", heavy=request.param), 100)


def contacts_at_end(run, a, b):
    c = run.info.contacts
    sel = c.valid[-1] & (c.a[-1] == a) & (c.b[-1] == b)
    return c.point[-1][sel], c.force[-1][sel]


def test_base_reactions_split_one_to_seven(run):
    points, forces = contacts_at_end(run, 3, BASE)  # B4's corners on the base
    order = np.argsort(points[:, 0])
    np.testing.assert_allclose(points[order, 0], [0.0, 20.0], atol=1e-9, rtol=0)
    f1, f2 = forces[order, 1]  # force on B4 from the base (upwards)
    assert abs(f1 - W / 2) <= PAPER_F1_ERROR
    assert abs(f2 - 7 * W / 2) <= PAPER_F2_ERROR
    np.testing.assert_allclose(run.force_between(BASE, 3)[-1], [0.0, 4 * W], atol=PAPER_F2_ERROR, rtol=0)


def test_substack_rests_on_the_corner_of_b4(run):
    # B1-B3 have their centroid above B4's top-right corner: B3's bottom-left corner
    # (on B4) carries nothing and all 3W passes through x = 20.
    c = run.info.contacts
    k = -1
    between = c.valid[k] & (((c.a[k] == 2) & (c.b[k] == 3)) | ((c.a[k] == 3) & (c.b[k] == 2)))
    pts, f = c.point[k][between], c.force[k][between]
    left = np.isclose(pts[:, 0], 5.0)
    right = np.isclose(pts[:, 0], 20.0)
    assert left.sum() == 1 and right.sum() == 1
    assert np.abs(f[left]).max() <= PAPER_F2_ERROR
    np.testing.assert_allclose(np.abs(f[right][0, 1]), 3 * W, atol=PAPER_F2_ERROR, rtol=0)


def test_nothing_moves(run):
    assert np.abs(run.centroid - run.centroid[0]).max() < 1e-9
    assert np.abs(run.rotation).max() < 1e-9
    assert run.info.converged.all()


def test_stiff_deformable_blocks_give_the_rigid_answer():
    # E = 1e14, nu = 0.45 (plane stress), as the paper; run as a static analysis.
    run = jaxdda.simulate(jaxdda.examples.get("paper-7.2", young=1e14), 100)
    points, forces = contacts_at_end(run, 3, BASE)
    order = np.argsort(points[:, 0])
    f1, f2 = forces[order, 1]
    assert abs(f1 - W / 2) <= PAPER_F1_ERROR
    assert abs(f2 - 7 * W / 2) <= PAPER_F2_ERROR
    # What moves is the elastic settlement: at most the stack's height times its largest strain.
    strain = np.abs(run.stress[-1, :4]).max() / 1e14
    assert np.abs(run.centroid - run.centroid[0]).max() <= 40.0 * strain
    assert np.abs(run.rotation).max() < 1e-12
