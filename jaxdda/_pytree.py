"""Frozen dataclasses registered as JAX pytrees (static fields become tree metadata),
and the integer leaves of tangent trees."""
from __future__ import annotations

import dataclasses
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np


def static_field(**kwargs: Any) -> Any:
    """A dataclass field that is part of the pytree structure (hashable, never traced)."""
    return dataclasses.field(metadata={"static": True}, **kwargs)


def pytree_dataclass(cls: type) -> type:
    """Make ``cls`` a frozen dataclass whose non-static fields are pytree leaves."""
    cls = dataclasses.dataclass(frozen=True)(cls)
    fields = dataclasses.fields(cls)
    meta = [f.name for f in fields if f.metadata.get("static", False)]
    data = [f.name for f in fields if not f.metadata.get("static", False)]
    jax.tree_util.register_dataclass(cls, data_fields=data, meta_fields=meta)
    cls.replace = dataclasses.replace  # type: ignore[attr-defined]
    return cls


def int_zeros(tangents, primals):
    """float0 tangents (of integer leaves) as integer zeros, which jit and vmap pass."""
    return jax.tree.map(lambda t, x: jnp.zeros(t.shape, x.dtype) if t.dtype == jax.dtypes.float0 else t, tangents,
                        primals)


def float0(tangents):
    """Integer tangents back to float0, as jax.jvp and jax.vjp take them."""
    return jax.tree.map(lambda t: np.zeros(t.shape, jax.dtypes.float0) if not jnp.issubdtype(t.dtype, jnp.inexact)
                        else t, tangents)
