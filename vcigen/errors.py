"""Errors raised by vcigen."""

from __future__ import annotations

PHASES = ("smooth", "contact time", "jump", "jump to contact", "start", "sustained")
# The reason of a SolverError for a step whose p_k+1 or E_d is not finite (both backends).
NONFINITE = (
    "non-finite state (an overflow, or a NaN from the model at these parameters); "
    "check the parameters and the initial state, or reduce h"
)
# A Newton that missed its residual test (Stepper._check, C <model>_check)
NOT_CONVERGED = (
    "Newton did not converge; reduce h or check that the Lagrangian is regular along the trajectory"
)
# Added to a held segment's failed Newton (the sustained phase, both backends): RATTLE has no root where the
# step moves a point farther than its rows' curvature allows; on a rod of length l (m = 1, no force)
# |q + tau (p + 2 Lam q)|^2 = (1 + 2 tau Lam)^2 l^2 + tau^2 |p|^2 = l^2 needs tau |p| <= l
HELD_NO_ROOT = (
    "; a held step has no root where it moves a point farther than its rows' curvature allows "
    "(on a rod of length l: where tau |v| >= l)"
)
HELD_ROWS = "; held: "  # then the held rows' names (Rows.names), ", " between them: a held step's failure
REASON_LEN = 512  # the C error's reason buffer (<model>_error_t.reason), NUL included


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
