"""The algorithm of MATH.md in position-momentum form, written once.

The state is ``(q_k, p_k)``. A grid step is a chain of *segments*
``(q_s, v_s, tau_s)``: the first starts at the grid point with momentum
``p_k`` (46)/(47); every later one starts at an impact point, where the
momentum jumps along the contact normal and the energy is kept (48), (78).
The last segment ends at the grid time; the others end on a contact.

The stepper only calls a small kernels interface (``smooth_step``, ``solve``,
``segment``, ``contacts``, ``legendre``), which each backend provides.
"""

from __future__ import annotations

import math
import time
import warnings
from dataclasses import dataclass
from typing import TYPE_CHECKING, Protocol

import numpy as np

from .errors import NONFINITE, SolverError
from .held_roots import hermite_min
from .held_step import HeldSteps
from .impact_step import ImpactSteps, Seg
from .progress import Progress
from .result import Impact, Result
from .sustained import SustainedSteps, SustainLog, held_contacts

if TYPE_CHECKING:
    from .sensitivity import Tracker


class Kernels(Protocol):
    n: int
    m: int
    contact_names: tuple[str, ...]

    def smooth_step(self, q0, p0, tau, guess): ...
    def solve(self, name: str, guess, *args): ...
    def segment(self, q0, v, tau): ...
    def start_energy(self, q0, v, tau) -> float: ...  # E_d - f_d- . v: the energy at the segment's start
    def contacts(self, q): ...
    def legendre(self, q, v): ...
    def jump_quadratic(self, qc, nrm, p_in, e_in, tau): ...  # ((a, b, c), w0, dw) or None
    def restitution(self): ...  # coefficient of restitution per contact
    def at(self, t): ...  # segments start at t: the time slot of forces of time (last parameter)

    explicit_path: bool  # contact_path available: (47) as a scalar root along the segment map

    def contact_path(self, j, s, q0, p0, tau): ...  # (g, g', v) at fraction s

    r: int  # rows of sustained contact (vcigen.rows); row_contact, row_constraint, row_bilateral per row

    def rows(self, q, u): ...  # (psi, grad psi, u . Hess psi . u) of every row
    def dynamics(self, q, u): ...  # (rhs of M qddot = rhs, each contact's curvature u . Hess phi . u)


GRAZING_MODES = ("contact", "error", "reflect")


@dataclass(frozen=True)
class Tolerances:
    """Acceptance thresholds shared by both backends."""

    residual: float = 1e-9  # |res|_inf accepted, relative to 1 + the data's scale
    phi: float = 1e-12  # phi_end < -phi is a crossing; |phi| <= phi is "on" the contact
    admissible: float = 1e-9  # phi(q_k) >= -admissible; shallower dips inside a step are no impact
    max_impacts_per_step: int = 64
    bracket_samples: int = 8
    jump_restarts: tuple[float, ...] = (1.0, 2.0, 4.0, 0.5, 8.0, 16.0, 0.25)
    simultaneous: float = 1e-9  # crossings this close (fraction of the step) are one impact
    dip: float = 0.25  # sample the segment map when the cubic's minimum of phi < dip * |slopes|
    # Impacts the jump (48) cannot resolve (MATH.md, Sustained contact). "contact" (default): an
    # impact whose outgoing normal speed is below rest * h * |d2phi/dt2| with forces pressing in, or
    # with no root mu > 0 of (48a), is plastic and the contact is held (sustained contact, lift-off);
    # a rootless one with forces not pressing in is grazing (n.qdot -> -e n.qdot). The paper's method
    # alone: "error" raises SolverError where (48a) has no root mu > 0; "reflect" applies the continuous
    # law n.qdot -> -e n.qdot there instead, (48b) solved with mu = mu0, E_d reset, and warns.
    grazing: str = "contact"
    rest: float = 1.0  # the jump's speed resolution, in units of h |d2phi/dt2| (mode "contact")

    def __post_init__(self) -> None:
        if self.grazing not in GRAZING_MODES:
            raise ValueError(f"Tolerances.grazing = {self.grazing!r}; use one of {list(GRAZING_MODES)}")
        if not (math.isfinite(self.rest) and self.rest >= 0):
            raise ValueError(f"Tolerances.rest = {self.rest!r}; use a number >= 0")


class Stepper(ImpactSteps, SustainedSteps, HeldSteps):
    """Runs the method of MATH.md on a set of kernels."""

    def __init__(
        self, kernels: Kernels, tol: Tolerances | None = None, tangent: Tracker | None = None
    ) -> None:
        self.k = kernels
        self._tan = tangent  # exact sensitivities (vcigen.sensitivity.Tracker): hooks after each phase
        self._record_held = False  # a held step keeps its solution for the tangent (Stepper.step)
        self._lift_seg = self._free_seg = None  # a lift-off, then a free rest: the tangent (Tracker.liftoff)
        self._ev_tan = None  # inside a held step: the tangent its events are carried by (SustainedSteps)
        self._ev_entry = self._ev_done = self._ev_carried = False  # _ev_carried: C ev_carried (_ev_rest_end)
        self._law = None  # the last jump's frictional law (contact, normal before it): Tracker.jump's
        self._fswitch = False  # a held step's first event was a friction switch (Stepper._tangent_held)
        self._sw_stop = None  # (step, events) after a carried friction stop (SustainedSteps._sw_back)
        self._bounces: dict[int, int] = {}  # impacts of each row in this step's held chains (step resets it)
        self.tol = tol or Tolerances()
        self.reflected = 0  # grazing impacts that took the continuous law (Tolerances.grazing)
        self.fallbacks = 0  # impacts re-resolved by the continuous law where (78) had no solution
        self.friction_dropped = 0  # landing contacts whose friction the impulse law left out (_law_lands)
        self.restitution_reduced = 0  # impacts whose restitution was cut: with friction it raised the energy
        self.least_splits = 0  # impulse laws whose stick rows were dependent: the least split (_least_split)
        self.riders_cut = 0  # impulse laws solved anew, a dependent stick cut from its owner (_cut_riders)
        self._timed = bool(getattr(kernels, "timed", False))  # forces of time: kernels.at(t) per segment
        system = getattr(kernels, "system", None)
        self._forced = bool(system is not None and system.model.force)  # energy: the last segment's
        self._init_sustained()

    # -- public -----------------------------------------------------------------
    def simulate(
        self,
        q0,
        v0,
        h: float,
        t_end: float | None = None,
        n_impacts: int | None = None,
        t0: float = 0.0,
        max_steps: int = 50_000_000,
        progress: Progress | None = None,
    ) -> Result:
        k = self.k
        q = np.array(q0, dtype=float)
        p = k.legendre(q, np.asarray(v0, dtype=float))[0]
        steps = _n_steps(h, t0, t_end, max_steps)
        n = k.n
        cap = steps if t_end is not None else 1024
        Q, P, E = np.empty((cap + 1, n)), np.empty((cap + 1, n)), np.empty(cap)
        Q[0], P[0] = q, p
        tan = self._tan
        if tan is not None:
            tan.start(q, v0, t0, cap)
        impacts: list[Impact] = []
        v = np.asarray(v0, dtype=float).copy()
        self._h = h
        self._at(t0)
        self._start_sustained(q, v, h)
        sus = SustainLog(k, cap)
        sus.active[0] = self.contact_activity()
        wall = time.perf_counter()
        step = 0
        bar = progress if progress is not None and progress.enabled else None
        while step < steps:
            if n_impacts is not None and len(impacts) >= n_impacts:
                break
            if step >= cap:
                cap *= 2
                Q, P, E = _grow(Q, cap + 1), _grow(P, cap + 1), _grow(E, cap)
                sus.grow(cap)
                if tan is not None:
                    tan.grow(cap)
            t = t0 + step * h
            if tan is not None:
                tan.begin(step, t)
            try:
                q, p, e, v = self._solved_step(step, t, h, q, p, v, impacts)
            except SolverError as err:  # keep what was computed: the run up to the last completed step
                kept = [im for im in impacts if im.step < step]
                err.result = _result(t0, h, step, Q, P, E, kept, n, time.perf_counter() - wall)
                sus.attach(err.result, step, [lo for lo in self.liftoffs if lo[0] < t])
                self._counts(err.result)
                if tan is not None:
                    tan.attach(err.result, step)
                raise
            if tan is not None:
                tan.end(step)
            step += 1
            Q[step], P[step], E[step - 1] = q, p, e
            if self._chained or self._booked:  # the log is zero where nothing is held
                sus.record(step, self.contact_activity(), self._force, self._cforce)
            if bar is not None:
                bar.update(done_fraction(step, steps, max_steps, len(impacts), n_impacts))
        else:
            if n_impacts is not None and t_end is None and len(impacts) < n_impacts:
                warnings.warn(
                    f"stopped after max_steps = {max_steps} with {len(impacts)} of {n_impacts} impacts",
                    RuntimeWarning,
                    stacklevel=2,
                )
        res = _result(t0, h, step, Q, P, E, impacts, n, time.perf_counter() - wall)
        sus.attach(res, step, self.liftoffs)
        self._counts(res)
        if tan is not None:
            tan.attach(res, step)
        return res

    def _counts(self, res: Result) -> None:
        """The run's counters into ``res.stats``, as they stand: a completed run's, and the run so far of a
        failed one (``SolverError.result``, as C's ``crun.stats``; it held the timings alone)."""
        res.stats["grazing_reflected"] = self.reflected
        res.stats.update({f"impacts_{kind}": count for kind, count in self.kinds.items()})
        res.stats["liftoffs"] = len(res.liftoffs)
        res.stats["jump_fallbacks"] = self.fallbacks
        res.stats["landing_friction_dropped"] = self.friction_dropped
        res.stats["restitution_reduced"] = self.restitution_reduced
        res.stats["least_splits"] = self.least_splits
        res.stats["loads_passed"] = self.passes
        res.stats["sticks_kept"] = self.sticks_kept
        res.stats["lifts_kept"] = self.lifts_kept
        res.stats["jams"] = self.jams
        res.stats["halvings"] = self.halvings
        res.stats["riders_cut"] = self.riders_cut

    def contact_activity(self) -> np.ndarray:
        """Per contact: is any of its rows active (in sustained contact)?"""
        return held_contacts(self.k, self.act)

    def _solved_step(self, step, t, h, q, p, v, impacts):
        """:meth:`step`, a singular linear system in it (a mass matrix singular at the state: a coordinate
        singularity of the model, Euler angles at gimbal lock) raised as the ``SolverError`` it is."""
        try:
            return self.step(step, t, h, q, p, v, impacts)
        except np.linalg.LinAlgError as exc:
            phase = "sustained" if self.act.any() else "smooth"
            raise SolverError(
                step,
                t,
                phase,
                math.nan,
                f"a linear system of the step is singular ({exc}): the mass matrix at this state (a "
                "singularity of the coordinates, e.g. Euler angles at gimbal lock) or the rows held",
            ) from exc

    def step(
        self,
        step: int,
        t: float,
        h: float,
        q: np.ndarray,
        p: np.ndarray,
        guess: np.ndarray,
        impacts: list[Impact],
    ):
        """One grid step from ``(q_k, p_k)``; returns ``(q_k+1, p_k+1, E_d, v)``."""
        k = self.k
        if self._booked:  # the forces of the step before: cleared only if a constraint acted
            self._force[:] = 0.0
            self._cforce[:] = 0.0
            self._booked = False
        self._events = 0
        self._bounces = {}
        self._h = h
        self._chained = False
        self._at(t)
        if self._held:  # sustained contact or constraints: the held step (vcigen.held), else the chain
            out = self._tangent_held(q, p, h, False, self._held_or_chain, step, t, h, q, p, guess, impacts)
            self._held = bool(self.act.any())
            return out
        v, res, p1, e, phi0, phi1, d0, d1 = k.smooth_step(q, p, h, guess)
        if not (math.isfinite(e) and np.isfinite(p1).all()):  # E_d is finite only if v is
            raise SolverError(step, t, "smooth", float(e), NONFINITE)
        self._check(res, p, step, t, "smooth")
        if phi1.size == 0 or (phi1.min() >= -self.tol.phi and not ((d0 < 0) & (d1 > 0)).any()):
            if self._tan is not None:
                self._tan.smooth(q, p, h, v)
            return q + h * v, p1, e, v
        seg = Seg(q=q, t=t, tau=h, p_in=p, e_in=math.nan, nrm=None, contact=-1, x=v)
        crossings = self._crossings(seg, phi0, phi1, d0, d1)
        if not crossings:
            if self._tan is not None:
                self._tan.smooth(q, p, h, v)
            return q + h * v, p1, e, v
        if self._tan is not None:
            self._tan.first_segment()
        out = self._impact_step(step, t, h, seg, crossings, impacts)
        self._held = bool(self.act.any())  # a plastic impact may have started sustained contact
        return out

    def _held_or_chain(self, step, t, h, q, p, guess, impacts):
        """A held grid step: the held step of :mod:`vcigen.held`, else the chain (:mod:`vcigen.sustained`)."""
        return self._held_step(h, q, p) or self._chain(step, t, h, q, p, t, h, guess, impacts, None)

    def _tangent_held(self, q, p, tau: float, entry: bool, run, *args):
        """``run()``, a held step (or the rest of a step after a plastic impact, ``entry``), with the
        tangent's hooks set aside: its phases have none. One with its active set and friction mode unchanged
        (one segment, no event, no switch, no cone slipping) leaves its solution in ``_held_seg``: then
        ``Tracker.held``; its events carried one by one as they happen (``_ev_tan``, ``SustainedSteps._ev_*``;
        ``_ev_done``: covered; frictionless only), a lone lift-off then a free rest ``Tracker.liftoff``; else
        a break (``"friction switch in a held step"`` if a switch stopped it first)."""
        tan, self._tan = self._tan, None
        self._held_seg, self._record_held = None, tan is not None
        self._lift_seg = self._free_seg = None
        self._ev_tan, self._ev_entry, self._ev_done = self._events_tangent(tan), entry, False
        self._ev_carried = False
        self._fswitch = False
        try:
            out = run(*args)
        finally:
            self._tan, self._record_held, self._ev_tan = tan, False, None
        if tan is not None and self._held_seg is not None:
            tan.held(q, p, tau, *self._held_seg, entry)
        elif self._ev_done:  # events inside it, carried one by one (SustainedSteps._ev_*)
            pass
        elif tan is not None and self._lift_seg is not None and self._free_seg is not None:
            sub, r, s, tau_s = self._lift_seg
            tan.liftoff(sub, r, s, tau_s, self._free_seg, entry)
        elif tan is not None and not entry:
            tan.lose("friction switch in a held step" if self._fswitch else "held step (sustained contact)")
        elif tan is not None and tan.active:
            tan.lose("plastic impact")
        return out

    def _at(self, t: float) -> None:
        """Segments start at ``t``: the time the forces see (``Kernels.at``; only with forces of time)."""
        if self._timed:
            self.k.at(t)

    # -- detection -----------------------------------------------------------------
    def _crossings(self, seg: Seg, phi0, phi1, d0, d1) -> dict[int, tuple[float, float]]:
        """Contacts crossed in the segment, each with ``(s_hi, phi_j(q(s_hi)) < 0)``.

        A contact is crossed if ``phi_j < 0`` at the end (the contact the segment leaves from, ``seg.contact``
        or ``seg.leaves``, from a start within ``Tolerances.admissible`` only below that start: the impact
        point is on it to the contact time's tolerance, and a slow rebound from a point found at
        ``phi = -1.35e-10`` ended below ``-Tolerances.phi`` and was met again there, at ``s = 0`` with no
        impulse, till ``max_impacts_per_step``: ``bench.table_drops --plastic``); or, with both ends
        admissible, if ``phi_j`` dips below 0 inside (tunnelling, a grazing approach): the cubic through the
        end values and slopes ``d = tau grad phi . v`` flags a dip, and the segment map of (47)/(78) itself
        is then sampled at the dip. A dip both miss is found at the next impact (:meth:`_missed`).
        """
        tol = self.tol
        self._at(seg.t)
        own = seg.contact if seg.contact >= 0 else seg.leaves
        left = (np.arange(phi1.size) == own) & (phi0 >= -tol.admissible) & (phi1 >= phi0)
        below = (phi1 < -tol.phi) & ~left
        out = {int(j): (1.0, float(phi1[j])) for j in np.flatnonzero(below)}
        for j in np.flatnonzero((phi1 >= -tol.phi) & (d0 < 0) & (d1 > 0)):
            if j == own:
                continue
            s_min, g_min = hermite_min(phi0[j], phi1[j], d0[j], d1[j])
            if g_min < tol.dip * (abs(d0[j]) + abs(d1[j])):
                hit = self._sample_dip(seg, int(j), s_min)
                if hit is not None:
                    out[int(j)] = hit
        return out

    def _sample_dip(self, seg: Seg, j: int, s_min: float) -> tuple[float, float] | None:
        """Sample ``phi_j`` along the segment map near ``s_min``; a negative sample or ``None``."""
        for s in (s_min, *np.linspace(0.0, 1.0, self.tol.bracket_samples + 2)[1:-1]):
            if not 0.0 < s < 1.0:
                continue
            _, phi, _ = self._sub_solve(seg, float(s), seg.x)
            if phi[j] < -self.tol.admissible:  # a dip within the admissibility tolerance is no impact
                return float(s), float(phi[j])
        return None

    def _segment_end(self, seg: Seg, w) -> tuple[np.ndarray, dict[int, tuple[float, float]]]:
        """End point of a post-impact segment and the contacts it crosses."""
        k = self.k
        self._at(seg.t)
        q_end = seg.q + seg.tau * w
        phi0, g0 = k.contacts(seg.q)
        phi1, g1 = k.contacts(q_end)
        p_start, p_end, _ = k.segment(seg.q, w, seg.tau)
        d0 = seg.tau * (g0 @ self._velocity(seg.q, w, p_start))
        d1 = seg.tau * (g1 @ self._velocity(q_end, w, p_end))
        return q_end, self._crossings(seg, phi0, phi1, d0, d1)

    def _velocity(self, q, v, p) -> np.ndarray:
        """The velocity of momentum ``p`` at ``q``: one Newton step of ``dL/dqdot = p`` from ``v``."""
        mom, mass = self.k.legendre(q, v)
        return v + np.linalg.solve(mass, p - mom)


def warn_reflected(count: int, stacklevel: int = 2) -> None:
    """Say how many grazing impacts took the continuous law (``Tolerances.grazing = "reflect"``)."""
    if count:
        warnings.warn(
            f"{count} grazing impact(s) had no root mu > 0 of the energy balance (48a) and took the "
            "continuous elastic law instead (Tolerances.grazing = 'reflect'); E_d jumps there by the "
            "O(h^2) bias (see Impact.energy_before/energy_after)",
            RuntimeWarning,
            stacklevel=stacklevel + 1,
        )


def warn_friction_dropped(count: int, stacklevel: int = 2) -> None:
    """Say how many landing contacts took no friction impulse (``res.stats["landing_friction_dropped"]``)."""
    if count:
        warnings.warn(
            f"{count} landing contact(s) took no friction impulse and slide after it: their stick rows "
            "depend on the other contacts' and neither a slide nor a stick on the least split of the "
            "impulses solved the law (a box landing on rough vertices; sliding ones take Coulomb's impulse, "
            "sticking ones where that split fits the cones), so the landing's tangential impulse may be "
            "short (docs/limits.md: Friction); the sustained friction after the landing is right",
            RuntimeWarning,
            stacklevel=stacklevel + 1,
        )


def warn_restitution_reduced(count: int, stacklevel: int = 2) -> None:
    """Say at how many impacts the restitution was reduced because Newton's restitution with Coulomb's
    friction would have raised the kinetic energy, or had no solution (``res.stats["restitution_reduced"]``).
    """
    if count:
        warnings.warn(
            f"{count} impact(s) with friction took less restitution than their coefficient (the largest "
            "fraction that adds no kinetic energy; none: plastic): Newton's restitution with Coulomb's "
            "friction would have raised the kinetic energy there (a body rocking onto a second contact, a "
            "spinning one landing), which the law refuses, or had no solution (a body wedged by friction) "
            "(docs/limits.md: Friction)",
            RuntimeWarning,
            stacklevel=stacklevel + 1,
        )


def warn_sticks_kept(count: int, jams: int = 0, stacklevel: int = 2) -> None:
    """Say how many stick <-> slip cycles at one instant were cut by sticking on
    (``res.stats["sticks_kept"]``) and how many Painleve jams (``"jams"``: a lift-off <-> landing cycle, or a
    slide past Painleve's boundary, ``SustainedSteps._painleve``)."""
    if count:
        warnings.warn(
            f"{count} time(s) a frictional contact cycled between stick and slip at one instant (its stick "
            "force out of Coulomb's cone, its slide stopped at once) and was kept sticking for the rest of "
            "that step, its friction above mu N there (docs/limits.md: Friction)",
            RuntimeWarning,
            stacklevel=stacklevel + 1,
        )
    if jams:
        warnings.warn(
            f"{jams} time(s) a contact under sliding friction met Painleve's inconsistency (it lifted off "
            "and landed again at one instant, or slid past the boundary where the force holding it grows "
            "without bound) and every held frictional contact was made to stick there, its friction not "
            "bounded by mu N (docs/limits.md: Friction)",
            RuntimeWarning,
            stacklevel=stacklevel + 1,
        )


def done_fraction(steps_done: int, steps: int, max_steps: int, impacts: int, n_impacts: int | None) -> float:
    """How much of a run is done: its steps of a ``t_end`` run, its impacts of ``n_impacts``, the larger."""
    f = steps_done / steps if steps < max_steps else 0.0
    if n_impacts:
        f = max(f, impacts / n_impacts)
    return min(f, 1.0)


def _result(t0: float, h: float, steps: int, Q, P, E, impacts: list[Impact], n: int, wall: float) -> Result:
    """The :class:`Result` of the first ``steps`` grid steps held in the buffers."""
    stats = {"wall_time": wall, "steps": steps, "seconds_per_step": wall / max(steps, 1)}
    return Result(
        t0 + h * np.arange(steps + 1),
        Q[: steps + 1].copy(),
        P[: steps + 1].copy(),
        E[:steps].copy(),
        impacts,
        [str(s) for s in range(n)],
        h,
        stats,
    )


def _grow(a: np.ndarray, rows: int) -> np.ndarray:
    out = np.empty((rows, *a.shape[1:]))
    out[: a.shape[0]] = a
    return out


def _n_steps(h: float, t0: float, t_end: float | None, max_steps: int) -> int:
    if t_end is None:
        return max_steps
    steps = math.ceil((t_end - t0) / h - 1e-9)
    if steps > max_steps:
        raise ValueError(f"t_end = {t_end} at h = {h} needs {steps} steps, more than max_steps = {max_steps}")
    return max(steps, 0)
