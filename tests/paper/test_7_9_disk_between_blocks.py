"""Case 7.9: a rigid disk bouncing between a fixed block and a block meshed into
triangles (E = 1e14, held by its bottom nodes), no gravity, frictionless, e = 1.

Closed form: the disk crosses the 0.25 m clearance on either side in 0.25 / vy s, so it
hits 2 vy times in 1 s and is back at (1, 0) with its speed; the path is a triangle wave
of vy periods. Most impacts fall inside a step (vy = 2: t = 0.125 = 2.5 dt; vy = 3:
t = 1/12 = 1.67 dt). The three runs share one compiled scene (only the velocity differs)."""
import dataclasses

import numpy as np
import pytest

import jaxdda

DT, STEPS, CLEARANCE = 0.05, 20, 0.25


@pytest.fixture(scope="module")
def runs():
    base = jaxdda.examples.get("paper-7.9", vy=3.0)
    out = {}
    for vy in (1.0, 2.0, 3.0):
        velocity = jaxdda.examples.get("paper-7.9", vy=vy).state.velocity
        out[vy] = jaxdda.simulate(dataclasses.replace(base, state=dataclasses.replace(base.state, velocity=velocity)),
                                  STEPS)
    return out


def triangle_wave(t, vy):
    """The disk's height: slope +-vy, turning at +-CLEARANCE."""
    period = 4 * CLEARANCE / vy
    phase = (t / period) % 1.0
    return CLEARANCE * np.where(phase < 0.25, 4 * phase, np.where(phase < 0.75, 2 - 4 * phase, 4 * phase - 4))


@pytest.mark.parametrize("vy", [1.0, 2.0, 3.0])
def test_disk_follows_the_triangle_wave_and_keeps_its_speed(runs, vy):
    run = runs[vy]
    disk = run.centroid[:, 0]
    flips = int(np.sum(np.sign(run.velocity[1:, 0, 1]) != np.sign(run.velocity[:-1, 0, 1])))
    assert flips == 2 * vy  # collisions
    # Energy given to the meshed block is of order m_disk / (E dt^2 x size) ~ 1e-8.
    np.testing.assert_allclose(disk[-1], [1.0, 0.0], atol=1e-6)
    np.testing.assert_allclose(disk[:, 0], run.time, atol=1e-9)  # frictionless: vx untouched
    np.testing.assert_allclose(disk[:, 1], triangle_wave(run.time, vy), atol=1e-6)
    speed = np.linalg.norm(run.velocity[:, 0, :2], axis=-1)
    np.testing.assert_allclose(speed, np.hypot(1.0, vy), rtol=1e-6)
    assert run.info.max_penetration.max() <= 1e-9
    assert run.info.converged.all()


def test_meshed_block_takes_the_impacts_through_its_nodes(runs):
    """The disk strikes the lower block's top edges (contacts act on mesh elements), and
    the stiff mesh barely moves: its nodes stay within a few times the static deflection
    under the impact's mean force, P / (E dt x 1 m) with P = 2 m vy (2.4e-9 m)."""
    run = runs[3.0]
    scene = run.scene
    elements = np.flatnonzero(np.asarray(scene.model.mesh) >= 0)
    c = run.info.contacts
    struck = c.valid & (((c.a == 0) & np.isin(c.b, elements)) | ((c.b == 0) & np.isin(c.a, elements)))
    assert (struck & (np.abs(c.normal_force) > 0)).sum(1).astype(bool).sum() >= 3  # three lower impacts
    verts = run.vertices()[:, elements, :3]
    impulse = 2 * float(scene.params.density[0] * scene.model.area[0]) * 3.0
    assert np.abs(verts - verts[0]).max() < 10 * impulse / (float(scene.params.young[elements[0]]) * DT)
