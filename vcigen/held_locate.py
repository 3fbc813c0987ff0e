"""Events inside a constrained segment, for :class:`vcigen.sustained.SustainedSteps` (MATH.md *Sustained
contact*): the sub-step map at a fraction of the segment, where a held row's force vanishes (lift-off), where
an inactive row reaches 0 along it (an impact while held) and the rows that dip below 0 inside it. They read
the stepper's state and solves (``_constrained``, ``_forces``, ``_pressed``)."""

from __future__ import annotations

import numpy as np

from .errors import SolverError
from .held_roots import EPS_LAM, LEAVE_FRACTIONS, LIFT_ITER, ROOT_EPS, End, hermite_min, illinois


class HeldLocate:
    """The located events of a constrained segment (a base of :class:`vcigen.sustained.SustainedSteps`)."""

    # -- events inside a constrained segment -------------------------------------------
    def _sub_end(self, step, t_k, q, p, tau, s, guess):
        """The constrained sub-step map at fraction ``s``: ``(v, end, u_end)`` (the evaluations at its end and
        the end velocity). A sub-step no longer than the chain's least (``1e-13 h``: a root finder's point at
        the segment's start) is its start, ``(guess, start, u)``: its solve, at ``tau ~ 1e-18``, had no
        reliable Newton (NaN on CasADi's path)."""
        if s * tau <= 1e-13 * self._h:
            u = self._velocity(q, guess, p)
            psi, grad, curv = self.k.rows(q, u)
            return guess, End(psi, grad, curv, self.k.dynamics(q, u)[0], self.k.legendre(q, u)[1]), u
        v, *_, u1, end = self._constrained(step, t_k, q, p, s * tau, guess)
        return v, end, u1

    def _liftoff_fraction(self, step, t_k, q, p, tau, guess, r, f0, f1) -> float:
        """Fraction where row ``r``'s force (:meth:`_contact_forces` at the sub-step's end, :meth:`_pressed`)
        vanishes.

        ``0`` if the force at the segment start ``f0`` is already negative (release at the start); else the
        root in ``[0, 1]`` of the force along the sub-step map (Illinois): where ``|force| <= EPS_LAM`` scale,
        or else the bracket's negative end, so that the released body leaves.
        """
        if f0 < 0:
            return 0.0
        ga, gb = float(f0), float(f1)

        def force(c, v):
            v, end, _ = self._sub_end(step, t_k, q, p, tau, c, v)
            return float(self._pressed(self._forces(end), end.grad)[r]), v

        return illinois(force, ga, gb, EPS_LAM * (1.0 + abs(ga) + abs(gb)), 1e-12, LIFT_ITER, guess)

    def _row_crossing(self, step, t_k, q, p, tau, guess, r, g1, s_hi: float = 1.0) -> float:
        """Fraction where inactive row ``r`` reaches 0 along the constrained sub-step map (Illinois) on ``[0,
        s_hi]`` (``g1 < 0`` its value at ``s_hi``).

        A row on the contact at the start (``|psi_r| <= Tolerances.phi``: an impact on it at this instant, or
        its lift-off) is bracketed from the first of ``LEAVE_FRACTIONS`` (times ``s_hi``) where it is above
        ``phi``, as free flight's :meth:`_leave`: the root at the start is the one it leaves. With ``psi_r``
        1e-19 above 0 there, the secant's first point (1e-16) took it: box on box draw 94's bounce was met
        again at once and held, where C, whose ``psi_r`` was below 0, bounced on."""
        psi0 = float(self.k.rows(q, guess)[0][r])
        lo, ga, gb = 0.0, max(psi0, 0.0), float(g1)

        def height(c, v):
            v, end, _ = self._sub_end(step, t_k, q, p, tau, c, v)
            return float(end.psi[r]), v

        if abs(psi0) <= self.tol.phi:
            for s in LEAVE_FRACTIONS:
                g, _ = height(s * s_hi, guess)
                if g > self.tol.phi:
                    lo, ga = s * s_hi, g
                    break
        return illinois(height, ga, gb, ROOT_EPS * max(ga, -gb), 4e-16, 200, guess, lo=lo, hi=s_hi)

    def _located(self, step, t_k, q_s, q, v, group) -> None:
        """An impact while held meets its rows ``group`` at ``q`` on their contacts: one admissible at the
        segment's start ``q_s`` and still below ``-Tolerances.admissible`` at ``q`` was not located (its
        height along the sub-step map jumps across 0, the map changing branch, and Illinois' bracket closed
        on its end without a root) and is a ``SolverError``, not an impact started below its contact (a box
        rotating 1.3 rad a step on a plate at ``h = 0.05``: a corner held 4.3 cm below it,
        ``bench.plate_drops --seed 23 --h 0.05``, drop 731). One below at the start already is met as before
        (a box in a V met a corner again 2.6e-5 below at ``h = 0.01`` till stop 59, ``bench.box_v_drops
        --seed 21``, drops 183 and 284: an event before had been taken with it below, which
        ``SustainedSteps._sunk_at_event`` now locates first)."""
        start, psi = self.k.rows(q_s, v)[0], self.k.rows(q, v)[0]
        for r in group:
            if psi[r] < -self.tol.admissible <= start[r]:
                raise SolverError(
                    step,
                    t_k,
                    "sustained",
                    float(-psi[r]),
                    f"an impact while held on '{self.k.row_names[r]}' was not located: it is {psi[r]:.3e} "
                    "below its contact where taken (its height along the held segment jumps across 0); "
                    "reduce h",
                )

    def _row_dips(self, step, t_k, q, p, tau, v, u1, end, cross) -> dict[int, tuple[float, float]]:
        """Inactive contact rows admissible at both ends of the segment that dip below 0 inside it (a rod's
        bob across the corner its circle cuts off a wall at ``h = 0.1``: it ended past the corner, on the
        wall's side again): ``{r: (s, psi_r < 0 at s)}``, as free flight's (``Stepper._crossings``): the
        cubic through the ends' values and slopes ``d = tau grad psi . u`` flags a dip, and the sub-step map
        is sampled there and at ``Tolerances.bracket_samples`` points (a dip within
        ``Tolerances.admissible`` is none). A row moving in at its start by less than ``admissible`` over the
        segment (``d0 >= -admissible``) is not tested: after an impact that left it at a normal speed of 0
        the sign of ``d0`` is round-off's, and C and CasADi parted on a rough star whose second face vertex
        then sank 4.9e-4 under the rotation (a dip the cubic misses, as free flight's does)."""
        k, tol = self.k, self.tol
        idle = ~self.act & ~cross & (np.asarray(k.row_stick) < 0) & (end.psi >= -tol.phi)
        d1 = tau * (end.grad @ u1)
        if not (idle & (d1 > 0.0)).any():
            return {}
        u0 = self._velocity(q, v, p)
        psi0, grad0, _ = k.rows(q, u0)
        d0 = tau * (grad0 @ u0)
        out, inner = {}, self._seg_inner  # the segment's, for its tangent: the samples' solves overwrite it
        for r in np.flatnonzero(idle & (d0 < -tol.admissible) & (d1 > 0.0)):
            s_min, g_min = hermite_min(float(psi0[r]), float(end.psi[r]), float(d0[r]), float(d1[r]))
            if g_min < tol.dip * (abs(d0[r]) + abs(d1[r])):
                for s in (s_min, *np.linspace(0.0, 1.0, tol.bracket_samples + 2)[1:-1]):
                    psi_s = (
                        self._sub_end(step, t_k, q, p, tau, float(s), v)[1].psi[r] if 0.0 < s < 1.0 else 0.0
                    )
                    if psi_s < -tol.admissible:
                        out[int(r)] = (float(s), float(psi_s))
                        break
        self._seg_inner = inner
        return out
