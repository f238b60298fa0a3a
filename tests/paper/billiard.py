"""The analytic billiard path in a square box: each coordinate is a triangle wave."""
import numpy as np


def billiard(start: float, velocity: float, time: np.ndarray, half: float) -> np.ndarray:
    """Position of a point moving at ``velocity`` between mirrors at +-half."""
    unfolded = np.mod(start + velocity * time + half, 4 * half)
    return np.where(unfolded < 2 * half, unfolded - half, 3 * half - unfolded)


def wall_hits(velocity: float, duration: float, half: float) -> int:
    """How many walls a point starting at the centre with ``velocity`` hits by ``duration``:
    the first at half / |v|, then one every 2 half / |v| (a hit at ``duration`` counts)."""
    travel = abs(velocity) * duration
    return 0 if travel < half else int(np.floor((travel - half) / (2 * half) + 1e-9)) + 1
