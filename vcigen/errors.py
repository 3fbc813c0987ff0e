"""Errors raised by vcigen."""

from __future__ import annotations

PHASES = ("smooth", "contact time", "jump", "jump to contact", "start")


class SolverError(RuntimeError):
    """A step could not be solved, or only to a non-physical root.

    Carries the step index, the time, the phase (smooth, contact time, jump,
    jump to contact) and the residual norm; the message names all four.
    """

    def __init__(self, step: int, time: float, phase: str, residual: float, reason: str = "") -> None:
        self.step = step
        self.time = time
        self.phase = phase
        self.residual = residual
        self.reason = reason
        msg = f"step {step} (t = {time:.12g}): {phase} solve failed, residual norm {residual:.3e}"
        super().__init__(f"{msg}; {reason}" if reason else msg)

    def __reduce__(self):  # keep the fields through pickling (multiprocessing)
        return (type(self), (self.step, self.time, self.phase, self.residual, self.reason))


class CompileError(RuntimeError):
    """The C compiler failed; the message carries its output."""
