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
    scenes among its own tests; nothing is shared across modules, and each program holds
    thousands of the process's memory maps (see ``_map_headroom``)."""
    yield
    jax.clear_caches()


def _memory_maps() -> tuple[int, int]:
    """(memory maps this process holds, the kernel's limit vm.max_map_count); (0, 1) where
    /proc does not tell."""
    try:
        with open("/proc/self/maps") as maps, open("/proc/sys/vm/max_map_count") as limit:
            return sum(1 for _ in maps), int(limit.read())
    except OSError:
        return 0, 1


@pytest.fixture(autouse=True)
def _map_headroom():
    """Drop the compiled programs after a test that leaves the process over half its memory
    maps. XLA on CPU (jaxlib 0.10.2) maps three regions per kernel, about 5 300 for one
    step program and more for a gradient's; at vm.max_map_count (65 530 by default) the
    next compilation dies with a segmentation fault. test_gradients' seven programs in one
    process reached it (measured: 65 531 maps at the crash)."""
    yield
    count, limit = _memory_maps()
    if count > limit // 2:
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
