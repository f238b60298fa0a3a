"""The XLA:CPU flags jaxdda sets when imported (jaxdda/__init__.py): set where the user did
not, the user's own kept, and a warning where JAX had started before they could apply."""
import os
import subprocess
import sys

import pytest

DEFAULTS = ("--xla_cpu_multi_thread_eigen=false", "--xla_cpu_use_fusion_emitters=false")


def _python(code: str, flags: str | None) -> subprocess.CompletedProcess:
    env = {k: v for k, v in os.environ.items() if k != "XLA_FLAGS"}
    if flags is not None:
        env["XLA_FLAGS"] = flags
    return subprocess.run([sys.executable, "-W", "always", "-c", code], capture_output=True, text=True, env=env,
                          timeout=120)


@pytest.mark.smoke
def test_flags_are_set_where_the_user_set_none():
    out = _python("import os, jaxdda; print(os.environ['XLA_FLAGS'])", None)
    assert out.returncode == 0, out.stderr
    assert out.stdout.split() == list(DEFAULTS)
    assert "Warning" not in out.stderr


@pytest.mark.smoke
def test_the_users_flag_wins():
    out = _python("import os, jaxdda; print(os.environ['XLA_FLAGS'])", "--xla_cpu_use_fusion_emitters=true")
    assert out.returncode == 0, out.stderr
    assert out.stdout.split() == ["--xla_cpu_use_fusion_emitters=true", DEFAULTS[0]]


@pytest.mark.smoke
def test_importing_after_jax_started_warns_which_flags_do_not_apply():
    out = _python("import jax; jax.numpy.ones(1).block_until_ready(); import jaxdda", None)
    assert out.returncode == 0, out.stderr
    assert "imported after JAX started its backend" in out.stderr
    assert all(flag in out.stderr for flag in DEFAULTS)
