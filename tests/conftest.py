"""Shared test setup."""
import os
import tempfile
import warnings

import jax
import pytest

from jaxdda import programs
from tests.interrupt import pytest_configure, pytest_keyboard_interrupt  # noqa: F401 (hooks: stop workers at once)

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
    scenes among its own tests; nothing is shared across modules, and each program holds
    thousands of the process's memory maps (``jaxdda.programs``)."""
    yield
    jax.clear_caches()


@pytest.fixture(autouse=True)
def _map_headroom():
    """Drop the compiled programs after a test that leaves the process over half its memory
    maps (``jaxdda.programs``): test_gradients' seven programs in one process reached
    vm.max_map_count and the next compilation segfaulted."""
    yield
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        programs.make_room()


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
