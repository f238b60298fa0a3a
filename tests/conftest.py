"""Shared test setup."""
import jax
import pytest


@pytest.fixture(autouse=True, scope="module")
def _fresh_compilations():
    """Drop each module's compiled programs when it ends. A test module shares its compiled
    scenes among its own tests; nothing is shared across modules, and without this one
    process accumulates several hundred large XLA CPU executables, after which compiling
    the deformable block's gradient crashed inside XLA (jaxlib 0.10.2; alone it compiles)."""
    yield
    jax.clear_caches()
