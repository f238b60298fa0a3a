"""The analytic billiard path in a square box: each coordinate is a triangle wave."""
import numpy as np


def billiard(start: float, velocity: float, time: np.ndarray, half: float) -> np.ndarray:
    """Position of a point moving at ``velocity`` between mirrors at +-half."""
    unfolded = np.mod(start + velocity * time + half, 4 * half)
    return np.where(unfolded < 2 * half, unfolded - half, 3 * half - unfolded)
