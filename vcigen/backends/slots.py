"""The parameter slots the stepper writes (both backends' kernels): the friction state and the time.

``par`` is the model's parameters, then per frictional contact its slip coefficient and stick value and
the branch signs of its tangent (``vcigen.rows``), then, with forces of time, the time a segment starts
at (``vcigen.derive``). A kernels class with ``par``, ``timed``, ``friction_slot`` and ``frictional``
inherits these two writers.
"""

from __future__ import annotations


class ParameterSlots:
    """``at`` and ``set_friction`` on ``self.par``."""

    def set_friction(self, slips, refs, branch) -> None:
        """The friction slots of the parameters: each frictional contact's slip coefficient and stick value,
        then the branch signs its tangent sticks on."""
        i, nf = self.friction_slot, len(self.frictional)
        self.par[i : i + nf] = slips
        self.par[i + nf : i + 2 * nf] = refs
        self.par[i + 2 * nf : i + 2 * nf + len(branch)] = branch

    def at(self, t: float) -> None:
        """Segments start at ``t``: the time slot (last parameter) of forces that depend on time."""
        self.t = float(t)
        if self.timed:
            self.par[-1] = t
