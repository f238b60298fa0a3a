"""Errors raised on bad input."""


class SceneError(ValueError):
    """A scene is invalid; the message names the offending body and field."""


class CapacityError(RuntimeError):
    """A fixed-capacity buffer overflowed and could not be regrown."""
