"""Built-in example scenes: ``names()``, ``get(name)``, ``default_steps(name)``."""
from jaxdda.examples.registry import default_steps, describe, get, names

__all__ = ["names", "get", "default_steps", "describe"]
