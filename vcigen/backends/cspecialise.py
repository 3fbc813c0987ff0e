"""Routines only the generated C specialises on; what a scene allows is :mod:`vcigen.structure`.

* **Contact values only.** Sub-solves along a segment need ``phi`` but not its
  gradient: routine ``phi`` skips the gradients there.

The rest of the C's specialisation (the linear smooth step, the explicit contact
path, the explicit and implicit grid steps, the quadratic jump, the held step) reads
``system.structure`` (:class:`vcigen.structure.Structure`), the one object the CasADi
backend reads too; :func:`vcigen.backends.ccontext.render_context` prints it in the header.
"""

from __future__ import annotations

from ..derive import DiscreteSystem
from ..routines import Routine


def phi_routine(system: DiscreteSystem) -> Routine:
    """The contact values ``phi_j(q)`` alone (no gradients), for the grid test."""
    c = system.routines["contacts"]
    return Routine("phi", c.inputs, (c.outputs[0],), "Contact values phi_j(q) only (grid test).")
