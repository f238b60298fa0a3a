"""jaxdda: differentiable 2D discontinuous deformation analysis (PB-DDA) in JAX."""
import os

# Bit-identical results from run to run: XLA:CPU's multi-threaded Eigen kernels sum in an
# order that depends on the load of the machine (last bits: 1e-19 m, 1e-11 Pa), so they
# are turned off unless the user set the flag (no measurable cost: the engine's products
# are small). XLA reads it when jax starts its backend, i.e. at the first computation.
if "xla_cpu_multi_thread_eigen" not in os.environ.get("XLA_FLAGS", ""):
    os.environ["XLA_FLAGS"] = f"{os.environ.get('XLA_FLAGS', '')} --xla_cpu_multi_thread_eigen=false".strip()

import jax  # noqa: E402

jax.config.update("jax_enable_x64", True)  # forces of 1e7 N next to errors of 1e-3 N

from jaxdda import cache  # noqa: E402

cache.enable()  # compiled programs persist across processes (``jaxdda.cache``)

from jaxdda import examples
from jaxdda.calibrate import Calibration, calibrate
from jaxdda.checkpoint import load_checkpoint, save_checkpoint
from jaxdda.energy import energy
from jaxdda.montecarlo import MonteCarlo, monte_carlo
from jaxdda.observe import Observable
from jaxdda.errors import CapacityError, ConvergenceError, NonConvergenceWarning, SceneError
from jaxdda.scene.builder import Scene, SceneBuilder
from jaxdda.scene.io import save_scene
from jaxdda.scene.loader import load_scene
from jaxdda.simulate import Trajectory, simulate
from jaxdda.step import rollout, step
from jaxdda.types import Model, Params, State, StepInfo, StepOptions

__all__ = ["calibrate", "Calibration", "monte_carlo", "MonteCarlo", "Observable", "SceneBuilder", "Scene", "load_scene", "save_scene", "save_checkpoint", "load_checkpoint", "energy", "simulate", "Trajectory", "step", "rollout", "examples", "Model",
           "Params", "StepOptions", "State", "StepInfo", "SceneError", "CapacityError", "ConvergenceError",
           "NonConvergenceWarning"]
__version__ = "0.1.0"
