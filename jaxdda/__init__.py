"""jaxdda: differentiable 2D discontinuous deformation analysis (PB-DDA) in JAX."""
import jax

jax.config.update("jax_enable_x64", True)  # forces of 1e7 N next to errors of 1e-3 N

from jaxdda import examples  # noqa: E402
from jaxdda.calibrate import Calibration, calibrate  # noqa: E402
from jaxdda.montecarlo import MonteCarlo, monte_carlo  # noqa: E402
from jaxdda.observe import Observable  # noqa: E402
from jaxdda.errors import CapacityError, SceneError  # noqa: E402
from jaxdda.scene.builder import Scene, SceneBuilder  # noqa: E402
from jaxdda.scene.loader import load_scene  # noqa: E402
from jaxdda.simulate import Trajectory, simulate  # noqa: E402
from jaxdda.step import rollout, step  # noqa: E402
from jaxdda.types import Model, Params, State, StepInfo  # noqa: E402

__all__ = ["calibrate", "Calibration", "monte_carlo", "MonteCarlo", "Observable", "SceneBuilder", "Scene", "load_scene", "simulate", "Trajectory", "step", "rollout", "examples", "Model",
           "Params", "State", "StepInfo", "SceneError", "CapacityError"]
__version__ = "0.1.0"
