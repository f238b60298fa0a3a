"""jaxdda: differentiable 2D discontinuous deformation analysis (PB-DDA) in JAX."""
import os

# XLA:CPU (jaxlib 0.10) can stall for good running a vmapped scan of while loops (every
# batched rollout of 512 or more scenarios here) under its concurrency-optimized
# scheduler; with it off they run, and no slower. XLA reads the flag when its CPU backend
# starts, so jaxdda must be imported before the first JAX computation. A value the user
# set is kept. See docs/design.md, "Monte Carlo and devices".
SCHEDULER_FLAG = "--xla_cpu_enable_concurrency_optimized_scheduler"
if SCHEDULER_FLAG not in os.environ.get("XLA_FLAGS", ""):
    os.environ["XLA_FLAGS"] = f"{os.environ.get('XLA_FLAGS', '')} {SCHEDULER_FLAG}=false".strip()

import jax  # noqa: E402

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
