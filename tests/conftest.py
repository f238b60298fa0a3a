"""Shared test setup."""
import os
import tempfile

import jax
import pytest

# Compiled programs are shared through JAX's persistent compilation cache by every process
# of a test run: both xdist workers, the notebooks' kernels and the CLI's subprocesses
# (which inherit the variable). Compilation dominates the suite, and several files compile
# the same programs (the calibration notebook's is test_calibrate's). Entries are keyed by
# the program and the jax version, so a cache left from an earlier run is safe to reuse.
os.environ.setdefault("JAX_COMPILATION_CACHE_DIR", os.path.join(tempfile.gettempdir(), "jaxdda-test-xla-cache"))
jax.config.update("jax_compilation_cache_dir", os.environ["JAX_COMPILATION_CACHE_DIR"])


@pytest.fixture(autouse=True, scope="module")
def _fresh_compilations():
    """Drop each module's compiled programs when it ends. A test module shares its compiled
    scenes among its own tests; nothing is shared across modules, and without this one
    process accumulates several hundred large XLA CPU executables, after which compiling
    the deformable block's gradient crashed inside XLA (jaxlib 0.10.2; alone it compiles)."""
    yield
    jax.clear_caches()


@pytest.fixture(scope="module")
def no_persistent_cache():
    """The module's programs are compiled without the persistent cache: serializing one of
    the gradient programs of test_gradients crashed the process (a segmentation fault in
    jaxlib 0.10.2's ``executable.serialize()``, in CI and here), and no other module
    shares them."""
    from jax.experimental.compilation_cache import compilation_cache

    jax.config.update("jax_enable_compilation_cache", False)
    compilation_cache.reset_cache()
    yield
    jax.config.update("jax_enable_compilation_cache", True)
    compilation_cache.reset_cache()
