"""The time step: ``step(model, state, params) -> (state, info)`` and ``rollout``."""
from jaxdda.step.pipeline import rollout, step

__all__ = ["rollout", "step"]
