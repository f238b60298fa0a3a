"""The analytic billiard path in a square box: each coordinate is a triangle wave."""
import dataclasses

import numpy as np

import jaxdda


def billiard(start: float, velocity: float, time: np.ndarray, half: float) -> np.ndarray:
    """Position of a point moving at ``velocity`` between mirrors at +-half."""
    unfolded = np.mod(start + velocity * time + half, 4 * half)
    return np.where(unfolded < 2 * half, unfolded - half, 3 * half - unfolded)


def wall_hits(velocity: float, duration: float, half: float) -> int:
    """How many walls a point starting at the centre with ``velocity`` hits by ``duration``:
    the first at half / |v|, then one every 2 half / |v| (a hit at ``duration`` counts)."""
    travel = abs(velocity) * duration
    return 0 if travel < half else int(np.floor((travel - half) / (2 * half) + 1e-9)) + 1


def runs_from_starts(name: str, starts, steps: int) -> dict:
    """The example ``name`` (body 0 the bouncing body) run from each start velocity in
    ``starts``: one compiled scene, only the state differs."""
    scene = jaxdda.examples.get(name)
    out = {}
    for v0 in starts:
        velocity = np.asarray(scene.state.velocity).copy()
        velocity[0, :2] = v0
        out[v0] = jaxdda.simulate(dataclasses.replace(scene, state=dataclasses.replace(scene.state, velocity=velocity)),
                                  steps)
    return out


def assert_billiard(run, v0, half: float, least_hits: int) -> None:
    """Body 0's centre on the billiard path (< 1e-6), and one velocity reversal per wall
    hit of that path on each axis (at least ``least_hits`` of them)."""
    exact = np.stack([billiard(0.0, v0[0], run.time, half), billiard(0.0, v0[1], run.time, half)], -1)
    assert np.linalg.norm(run.centroid[:, 0] - exact, axis=1).max() < 1e-6
    for axis in (0, 1):
        hits = wall_hits(v0[axis], run.time[-1], half)
        assert hits >= least_hits
        assert (np.diff(np.sign(run.velocity[:, 0, axis])) != 0).sum() == hits
