"""Errors raised by vcigen."""

from __future__ import annotations

PHASES = ("smooth", "contact time", "jump", "jump to contact", "start", "sustained")
# The reason of a SolverError for a step whose p_k+1 or E_d is not finite (both backends).
NONFINITE = (
    "non-finite state (an overflow, or a NaN from the model at these parameters); "
    "check the parameters and the initial state, or reduce h"
)


class SolverError(RuntimeError):
    """A step could not be solved, or only to a non-physical root.

    Carries the step index, the time, the phase (smooth, contact time, jump,
    jump to contact) and the residual norm; the message names all four.
    Raised by ``simulate``, it also carries ``result``: the
    :class:`~vcigen.Result` up to the last completed step (its impacts too), so
    that a long run that fails late loses nothing it had computed.
    """

    def __init__(self, step: int, time: float, phase: str, residual: float, reason: str = "") -> None:
        self.step = step
        self.time = time
        self.phase = phase
        self.residual = residual
        self.reason = reason
        self.result = None  # set by simulate: the Result up to the last completed step
        msg = f"step {step} (t = {time:.12g}): {phase} solve failed, residual norm {residual:.3e}"
        super().__init__(f"{msg}; {reason}" if reason else msg)

    def __reduce__(self):  # keep the fields through pickling (multiprocessing)
        return (type(self), (self.step, self.time, self.phase, self.residual, self.reason))


class CompileError(RuntimeError):
    """The C compiler failed; the message carries its output."""
