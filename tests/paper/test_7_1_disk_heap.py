"""Case 7.1: three disks stacked on a base; contact forces G, 2G, 3G (validation-cases.md)."""
import math

import numpy as np
import pytest

import jaxdda

pytestmark = pytest.mark.smoke  # one small run, the program that `pytest -m smoke` compiles

G = 2500.0 * math.pi * 10.0 ** 2 * 10.0  # weight of one disk, 7 853 981.633974483 N
PAPER_ERROR = 2.2e-3  # N, the paper's largest absolute error (Table 1)


@pytest.fixture(scope="module", params=[False, True], ids=["fixed-base", "heavy-base"])
def run(request):
    return jaxdda.simulate(jaxdda.examples.get("paper-7.1", heavy=request.param), 100)


def test_contact_forces_match_statics(run):
    # bodies: 0 bottom disk, 1 middle, 2 top, 3 base; force_between(i, j) = force of i on j
    f_top_on_middle = run.force_between(2, 1)[-1]
    f_middle_on_bottom = run.force_between(1, 0)[-1]
    f_bottom_on_base = run.force_between(0, 3)[-1]
    np.testing.assert_allclose(f_top_on_middle, [0.0, -G], atol=PAPER_ERROR, rtol=0)
    np.testing.assert_allclose(f_middle_on_bottom, [0.0, -2 * G], atol=PAPER_ERROR, rtol=0)
    np.testing.assert_allclose(f_bottom_on_base, [0.0, -3 * G], atol=PAPER_ERROR, rtol=0)
    # action and reaction
    np.testing.assert_allclose(run.force_between(1, 2), -run.force_between(2, 1))


def test_disks_do_not_drift(run):
    assert np.abs(run.centroid[:, :3] - run.centroid[0, :3]).max() < 1e-9
    assert np.abs(run.rotation[:, :3]).max() < 1e-9
    assert run.info.converged.all() and not run.info.overflow.any()
