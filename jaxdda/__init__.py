"""jaxdda: differentiable 2D discontinuous deformation analysis (PB-DDA) in JAX."""
import os

# XLA:CPU settings the engine is measured with, unless the user set them. XLA reads
# XLA_FLAGS when jax starts its backend (the first computation), so they take effect where
# jaxdda is imported before anything is computed.
# - multi_thread_eigen off: bit-identical results from run to run. The multi-threaded Eigen
#   kernels sum in an order that depends on the load of the machine (last bits: 1e-19 m,
#   1e-11 Pa); the engine's products are small, so the threads buy nothing measurable.
# - fusion_emitters off: the step is about a thousand small fused kernels, each compiled
#   as its own LLVM module; XLA:CPU's MLIR fusion emitters compile them about 1.6 times
#   slower than its classic emitters and run them no faster (rockfall step: compile 23 s
#   -> 14 s, one step 2.0 -> 1.5 ms; experiments/results/step_budget.md).
_XLA_DEFAULTS = {"xla_cpu_multi_thread_eigen": "false", "xla_cpu_use_fusion_emitters": "false"}
_flags = os.environ.get("XLA_FLAGS", "")
_unset = [f"--{k}={v}" for k, v in _XLA_DEFAULTS.items() if k not in _flags]
os.environ["XLA_FLAGS"] = " ".join([_flags] + _unset).strip()

import jax  # noqa: E402

try:
    from jax._src.xla_bridge import backends_are_initialized as _started
except ImportError:  # another jax: no warning
    def _started():
        return False
if _unset and _started():
    import warnings

    warnings.warn(f"jaxdda was imported after JAX started its backend, so XLA_FLAGS {' '.join(_unset)} do not "
                  "apply: the step compiles about 1.6x slower, and runs may differ in their last bits. "
                  "Import jaxdda before computing with JAX, or set XLA_FLAGS yourself.", stacklevel=2)

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
