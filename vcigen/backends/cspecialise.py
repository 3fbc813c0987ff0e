"""Structure of a scene that the generated C exploits, detected at generation time.

* **Linear smooth step.** The smooth residual (46) is ``p-(q0, v, tau) - p0``;
  when its Jacobian is free of ``v`` (a constant mass matrix), one Newton step
  from any guess is exact: the C code does a single linear solve, no loop. When
  the Jacobian is also diagonal the solve is a componentwise division.
* **Explicit contact path.** Then ``v(alpha)`` is an explicit expression and the
  contact time (47) reduces to a scalar root of ``g(s) = phi(q0 + s tau v(s tau))``,
  solved by a safeguarded Newton on ``s`` (routine ``contact_path_<c>``).
* **Contact values only.** Sub-solves along a segment need ``phi`` but not its
  gradient: routine ``phi`` skips the gradients there.
* **Explicit grid step.** With a constant diagonal mass as well, a whole grid
  step away from contacts is one straight-line routine ``grid_step``: ``v`` of
  (46), ``q_k+1``, ``p_k+1``, ``E_d`` (55), ``phi(q_k+1)`` and its
  slope. Every subexpression of ``(h, par)`` alone is hoisted out of the loop
  into ``grid_consts``, computed once per run (no division is left in the loop).
"""

from __future__ import annotations

from dataclasses import dataclass

from ..derive import DiscreteSystem
from ..explicit import (
    has_explicit_path,
    is_explicit,
    jump_quadratic,
    mass_diagonal,
    smooth_diagonal,
    smooth_jacobian,
)
from ..routines import Routine


@dataclass(frozen=True)
class Structure:
    """What the generated C specialises, and why (for the comment block)."""

    smooth_linear: bool
    smooth_diagonal: bool
    explicit_path: bool
    mass_diagonal: bool = False

    explicit_grid: bool = False
    jump_quadratic: bool = False

    def notes(self, system: DiscreteSystem) -> list[str]:
        """Plain-language lines for the top of the generated source."""
        names = ", ".join(system.contact_names) or "none"
        lines = [
            f"contacts: {system.m} ({names}); only these are generated",
            f"sizes fixed: n = {system.n}, m = {system.m}; {len(system.params)} parameters as runtime inputs",
        ]
        if self.smooth_diagonal:
            lines.append(
                "smooth step (46): residual linear in v with a diagonal Jacobian -> one division, no Newton"
            )
        elif self.smooth_linear:
            lines.append(
                "smooth step (46): residual linear in v (constant mass matrix) -> one LU solve, no Newton"
            )
        else:
            lines.append("smooth step (46): configuration-dependent mass -> damped Newton")
        if self.explicit_path:
            lines.append(
                "contact time (47): position explicit in alpha -> safeguarded scalar Newton on alpha"
            )
        else:
            lines.append("contact time (47): Newton on (v, alpha)")
        if self.mass_diagonal:
            lines.append("velocity of a momentum (crossing slopes): constant diagonal mass -> one division")
        if self.jump_quadratic:
            lines.append("jump (48): a quadratic in mu -> closed-form root, Newton only checks it")
        if self.explicit_grid:
            lines.append(
                "grid step away from contacts: one straight-line routine (v, q, p, E_d, phi, "
                "slope); subexpressions of (h, par) hoisted out of the loop, computed once per run"
            )
        lines.append(
            "grid test: phi and grad phi at q_k reused from the previous step; sub-solves use phi only"
        )
        return lines


def detect(system: DiscreteSystem) -> Structure:
    """Inspect the smooth residual's Jacobian (46) for linearity and diagonality.

    A rule with internal points takes the general path: Newton on ``(v, u)`` in every phase."""
    if system.stages:
        return Structure(False, False, False, mass_diagonal=mass_diagonal(system))
    smooth = system.routines["smooth"]
    x = set(smooth.inputs[0].symbols)
    jac = smooth_jacobian(system)  # expanded: terms that cancel only then do
    linear = not (jac.free_symbols & x)
    return Structure(
        linear,
        smooth_diagonal(system),
        explicit_path=has_explicit_path(system),
        mass_diagonal=mass_diagonal(system),
        explicit_grid=is_explicit(system),
        jump_quadratic=jump_quadratic(system) is not None,
    )


def phi_routine(system: DiscreteSystem) -> Routine:
    """The contact values ``phi_j(q)`` alone (no gradients), for the grid test."""
    c = system.routines["contacts"]
    return Routine("phi", c.inputs, (c.outputs[0],), "Contact values phi_j(q) only (grid test).")
