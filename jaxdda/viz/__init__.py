"""Pictures of runs (needs matplotlib: ``pip install "jaxdda[plot]"``)."""
from jaxdda.viz.plot import plot_trajectory

__all__ = ["plot_trajectory"]
