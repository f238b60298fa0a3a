"""jaxdda.programs: compiled programs are dropped before they exhaust the process's memory maps."""
import jax
import jax.numpy as jnp
import numpy as np
import pytest

from jaxdda import programs

pytestmark = pytest.mark.smoke  # the whole module is cheap: `pytest -m smoke`


def _program():
    def f(x):  # several kernels (a loop, a sort, reductions), so its maps are many
        y = jax.lax.fori_loop(0, 3, lambda i, y: jnp.sin(y) + i, x)
        return jnp.sum(jnp.sort(y) * jnp.cumsum(y)) + jnp.max(jnp.exp(-y))

    return jax.jit(f)


def test_make_room_drops_compiled_programs_past_its_threshold():
    count, limit = programs.memory_maps()
    assert 0 < count < limit  # Linux: /proc tells
    f = _program()
    x = jnp.linspace(0.0, 1.0, 64)
    expected = float(f(x))
    held = programs.memory_maps()[0]
    assert not programs.make_room(fraction=1.0)  # far below the limit: nothing dropped
    with pytest.warns(RuntimeWarning, match="vm.max_map_count"):
        assert programs.make_room(fraction=0.0)
    assert programs.memory_maps()[0] < held  # the program's code and data are unmapped
    np.testing.assert_array_equal(float(f(x)), expected)  # and it compiles again when used
