"""Pictures of runs (needs matplotlib: ``pip install "jaxdda[plot]"``)."""
from jaxdda.viz.animate import animate_trajectory
from jaxdda.viz.charts import plot_energy, plot_force_network, plot_forces, plot_paths, plot_report
from jaxdda.viz.plot import plot_trajectory

__all__ = ["plot_trajectory", "animate_trajectory", "plot_paths", "plot_forces", "plot_energy", "plot_force_network",
           "plot_report"]
