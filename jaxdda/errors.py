"""Errors raised on bad input."""


class SceneError(ValueError):
    """A scene is invalid; the message names the offending body and field."""


class CapacityError(RuntimeError):
    """A fixed-capacity buffer overflowed and could not be regrown."""


class ConvergenceError(RuntimeError):
    """A contact solve did not converge and the run was asked to stop (``simulate(...,
    on_nonconvergence="raise")``), or it still did not at the smallest sub-step allowed
    (``"halve"``). ``step`` is the step's number (1-based), ``time`` the time at its
    start, ``dt`` the (sub-)step length tried last, ``residual`` and ``iterations`` that
    solve's relative residual and iterations (products with W)."""

    def __init__(self, message: str, *, step: int, time: float, dt: float, residual: float, iterations: int):
        super().__init__(message)
        self.step, self.time, self.dt, self.residual, self.iterations = step, time, dt, residual, iterations


class NonConvergenceWarning(UserWarning):
    """Steps of a run whose contact solve missed its tolerance (``simulate(...,
    on_nonconvergence="continue")``): warned once per run, with their count and the worst
    relative residual."""
