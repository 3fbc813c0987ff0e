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
from dataclasses import dataclass, replace
from typing import TYPE_CHECKING, Protocol

import numpy as np

from .errors import NONFINITE, SolverError
from .friction import cone_law, impact_law
from .held_step import HeldSteps
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


@dataclass
class _Seg:
    """The segment under construction: its start and incoming data."""

    q: np.ndarray  # start point
    t: float  # start time
    tau: float  # remaining duration of the grid step
    p_in: np.ndarray  # grid momentum (first) or incoming momentum p~- (after an impact)
    e_in: float  # energy kept across the impact (after an impact)
    nrm: np.ndarray | None  # contact normal at the start (after an impact)
    contact: int  # contact hit at the start, -1 for the first segment
    x: np.ndarray  # the segment's unknowns: v, or (w, mu) after an impact
    rest: float = 1.0  # the coefficient of restitution of the impact at the start


class Stepper(SustainedSteps, HeldSteps):
    """Runs the method of MATH.md on a set of kernels."""

    def __init__(
        self, kernels: Kernels, tol: Tolerances | None = None, tangent: Tracker | None = None
    ) -> None:
        self.k = kernels
        self._tan = tangent  # exact sensitivities (vcigen.sensitivity.Tracker): hooks after each phase
        self._record_held = False  # a held step keeps its solution for the tangent (Stepper.step)
        self._lift_seg = self._free_seg = None  # a lift-off, then a free rest: the tangent (Tracker.liftoff)
        self._ev_tan = None  # inside a held step: the tangent its events are carried by (SustainedSteps)
        self._ev_entry = self._ev_done = False
        self._law = None  # the last jump's frictional law (contact, normal before it): Tracker.jump's
        self._fswitch = False  # a held step's first event was a friction switch (Stepper._tangent_held)
        self.tol = tol or Tolerances()
        self.reflected = 0  # grazing impacts that took the continuous law (Tolerances.grazing)
        self.fallbacks = 0  # impacts re-resolved by the continuous law where (78) had no solution
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
                q, p, e, v = self.step(step, t, h, q, p, v, impacts)
            except SolverError as err:  # keep what was computed: the run up to the last completed step
                kept = [im for im in impacts if im.step < step]
                err.result = _result(t0, h, step, Q, P, E, kept, n, time.perf_counter() - wall)
                sus.attach(err.result, step, [lo for lo in self.liftoffs if lo[0] < t])
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
        res.stats["grazing_reflected"] = self.reflected
        sus.attach(res, step, self.liftoffs)
        res.stats.update({f"impacts_{kind}": count for kind, count in self.kinds.items()})
        res.stats["liftoffs"] = len(self.liftoffs)
        res.stats["jump_fallbacks"] = self.fallbacks
        if tan is not None:
            tan.attach(res, step)
        return res

    def contact_activity(self) -> np.ndarray:
        """Per contact: is any of its rows active (in sustained contact)?"""
        return held_contacts(self.k, self.act)

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
        seg = _Seg(q=q, t=t, tau=h, p_in=p, e_in=math.nan, nrm=None, contact=-1, x=v)
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
    def _crossings(self, seg: _Seg, phi0, phi1, d0, d1) -> dict[int, tuple[float, float]]:
        """Contacts crossed in the segment, each with ``(s_hi, phi_j(q(s_hi)) < 0)``.

        A contact is crossed if ``phi_j < 0`` at the end; or, with both ends admissible,
        if ``phi_j`` dips below 0 inside (tunnelling, a grazing approach): the cubic
        through the end values and slopes ``d = tau grad phi . v`` flags a dip, and the
        segment map of (47)/(78) itself is then sampled at the dip.
        """
        tol = self.tol
        self._at(seg.t)
        out = {int(j): (1.0, float(phi1[j])) for j in np.flatnonzero(phi1 < -tol.phi)}
        for j in np.flatnonzero((phi1 >= -tol.phi) & (d0 < 0) & (d1 > 0)):
            if j == seg.contact:
                continue
            s_min, g_min = _hermite_min(phi0[j], phi1[j], d0[j], d1[j])
            if g_min < tol.dip * (abs(d0[j]) + abs(d1[j])):
                hit = self._sample_dip(seg, int(j), s_min)
                if hit is not None:
                    out[int(j)] = hit
        return out

    def _sample_dip(self, seg: _Seg, j: int, s_min: float) -> tuple[float, float] | None:
        """Sample ``phi_j`` along the segment map near ``s_min``; a negative sample or ``None``."""
        for s in (s_min, *np.linspace(0.0, 1.0, self.tol.bracket_samples + 2)[1:-1]):
            if not 0.0 < s < 1.0:
                continue
            _, phi = self._sub_solve(seg, float(s), seg.x)
            if phi[j] < -self.tol.admissible:  # a dip within the admissibility tolerance is no impact
                return float(s), float(phi[j])
        return None

    def _segment_end(self, seg: _Seg, w) -> tuple[np.ndarray, dict[int, tuple[float, float]]]:
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

    # -- the impact step ---------------------------------------------------------
    def _impact_step(self, step, t_k, h, seg: _Seg, crossings, impacts, e_step=None):
        """Chain of segments (47), (48), (78), (79) until one ends inside C at ``t_k + h``.

        A plastic impact (mode ``"contact"``) hands the rest of the step to the constrained
        chain (:mod:`vcigen.sustained`). ``e_step``: E_d of the grid step, if an earlier phase fixed it.
        """
        k, tol = self.k, self.tol
        n = k.n
        pending: list[tuple[Impact, float]] = []
        restitution = k.restitution()
        for _ in range(tol.max_impacts_per_step):
            # Earliest crossing over all crossed contacts (47)/(78); ties are one impact.
            try:
                roots = {
                    j: self._contact_root(step, t_k, seg, j, s_hi, g_hi)
                    for j, (s_hi, g_hi) in sorted(crossings.items())
                }
            except SolverError:
                if not (tol.grazing == "contact" and seg.contact >= 0):
                    raise
                # (78) unsolvable (a lossy impact into a corner): the impact at the segment start takes
                # the continuous law instead, and the rest of the step starts afresh from it (47).
                if self._tan is not None:
                    self._tan.lose("restart (continuous law where (78) has no root)")
                seg, crossings, e_after, mu = self._restart(seg)
                impacts.extend(replace(im, impulse=mu * wgt, energy_after=e_after) for im, wgt in pending)
                pending = []
                if not crossings:
                    q_end = seg.q + seg.tau * seg.x[:n]
                    self._at(seg.t)
                    _, p_end, e_end = k.segment(seg.q, seg.x[:n], seg.tau)
                    return q_end, p_end, (e_end if self._forced else e_step), seg.x[:n]
                continue
            j = min(roots, key=lambda i: (roots[i][1], i))
            x, s = roots[j]
            group = [i for i in sorted(roots) if roots[i][1] - s <= tol.simultaneous]
            if self._tan is not None:
                self._tan.contact(seg, j, x, s, group)
            # The impulse at the previous impact, re-solved with beta (78).
            impacts.extend(replace(im, impulse=float(x[n]) * wgt) for im, wgt in pending)
            tau_c = s * seg.tau
            v_c = x[:n]
            q_c = seg.q + tau_c * v_c
            self._at(seg.t)
            _, p_minus_c, e_c = k.segment(seg.q, v_c, tau_c)
            e_in = e_c if seg.contact < 0 else seg.e_in
            e_step = e_in if e_step is None else e_step
            t_c = seg.t + tau_c
            nrm, weights = self._normal(q_c, v_c, p_minus_c, group)
            seg = _Seg(q=q_c, t=t_c, tau=seg.tau - tau_c, p_in=p_minus_c, e_in=e_in, nrm=nrm, contact=j, x=x)
            # Jump (48): tangential momentum kept, the normal one jumps by mu grad phi; energy kept
            # (less the loss of (39) with restitution; seg.e_in becomes the energy after).
            elastic = all(restitution[i] == 1.0 for i in group)
            e_rest = 1.0 if elastic else float(sum(wgt * restitution[i] for i, wgt in zip(group, weights)))
            seg.rest = e_rest
            x_jump, kind = self._jump(step, t_k, seg, v_c, e_rest, group, weights)
            if self._tan is not None:
                self._tan.jump(seg, v_c, e_rest, kind, self._law)
            if x_jump is None:  # plastic: the contact is held for the rest of the step
                self._count_event(step, t_k)
                p_plus, lam, loss, rows = self._plastic_entry(step, t_k, h, q_c, p_minus_c, v_c, t_c, group)
                for i in group:
                    own = sum(lam[r] for r in rows if k.row_contact[r] == i)
                    self._log(impacts, t_c, i, q_c, (t_c - t_k) / h, own, step, e_in, e_in - loss, "plastic")
                if self._tan is not None:
                    self._tan.plastic(seg, v_c, [r for r in rows if lam[r] != 0.0])
                return self._tangent_held(
                    q_c,
                    p_plus,
                    seg.tau,
                    True,
                    self._chain,
                    step,
                    t_k,
                    h,
                    q_c,
                    p_plus,
                    t_c,
                    seg.tau,
                    v_c,
                    impacts,
                    e_step,
                )
            seg.x = x_jump
            w = seg.x[:n]
            self._at(seg.t)
            _, p_end, e_after = k.segment(seg.q, w, seg.tau)
            pending = [
                (
                    Impact(
                        t=t_c,
                        contact=k.contact_names[i],
                        q=q_c.copy(),
                        alpha=(t_c - t_k) / h,
                        impulse=float(seg.x[n]) * wgt,
                        step=step,
                        energy_before=e_in,
                        energy_after=seg.e_in if self._forced else e_after,  # forces: the energy at its start
                        kind=kind
                        if kind == "grazing"
                        else ("elastic" if restitution[i] == 1.0 else "restitution"),
                    ),
                    wgt,
                )
                for i, wgt in zip(group, weights)
            ]
            for im, _ in pending:
                self.kinds[im.kind] += 1
            q_end, crossings = self._segment_end(seg, w)
            if not crossings:
                if self._tan is not None:
                    self._tan.jump_end(seg)
                impacts.extend(im for im, _ in pending)
                return q_end, p_end, (e_after if self._forced else e_step), w
        raise SolverError(
            step,
            t_k,
            "jump",
            0.0,
            f"more than {tol.max_impacts_per_step} impacts in one step (Tolerances.max_impacts_per_step); "
            "raise it if the impacts are real, or reduce h" + self._unheld(),
        )

    def _unheld(self) -> str:
        """The note an error adds under a rule with internal points, which holds no contact."""
        system = getattr(self.k, "system", None)
        return "" if system is None else unheld_note(system)

    def _continuous_law(self, q, v_in, p_in, nrm, e: float):
        """The continuous impulse law at an impact: ``(qdot-, M^-1 n, n.qdot-, n.M^-1 n, mu0)``.

        ``mu0 = max(-(1 + e) n.qdot- / n.M^-1 n, 0)`` turns ``n.qdot`` into ``-e n.qdot``; ``qdot-`` is
        the velocity of ``p_in`` at ``q`` (Newton from ``v_in``).
        """
        vel = self._velocity(q, v_in, p_in)
        minv_n = np.linalg.solve(self.k.legendre(q, vel)[1], nrm)
        nv, nmn = float(nrm @ vel), float(nrm @ minv_n)
        return vel, minv_n, nv, nmn, max(-(1.0 + e) * nv / nmn, 0.0)

    def _frictional_law(self, seg: _Seg, vel, group, restitution: float):
        """Friction at an impact on one frictional contact (:func:`vcigen.friction.impact_law`).

        ``seg.nrm`` becomes the impulse direction ``n + (mu_t/mu_n) t``; returns ``(mu_n, M^-1 nrm, dK)``, or
        ``None`` (no friction here: frictionless contact, several contacts at once, or no normal impulse).
        """
        k = self.k
        if not getattr(k, "frictional", ()) or len(group) != 1:
            return None
        mu_f, tgrad, _ = k.friction(seg.q)
        j = group[0]
        if mu_f[j] <= 0.0:
            return None
        mass = k.legendre(seg.q, vel)[1]
        if getattr(k, "cone", ()) and k.cone[j]:  # two tangents: the isotropic cone
            t2 = k.friction_cone(seg.q)[j]
            mu_n, mu_t, dk, an, at = cone_law(vel, mass, seg.nrm, tgrad[j], t2, float(mu_f[j]), restitution)
            if not mu_n > 0.0:
                return None
            seg.nrm = seg.nrm + (mu_t[0] / mu_n) * tgrad[j] + (mu_t[1] / mu_n) * t2
            return mu_n, an + (mu_t[0] / mu_n) * at[0] + (mu_t[1] / mu_n) * at[1], dk
        mu_n, mu_t, dk, an, at = impact_law(vel, mass, seg.nrm, tgrad[j], float(mu_f[j]), restitution)
        if not mu_n > 0.0:
            return None
        seg.nrm = seg.nrm + (mu_t / mu_n) * tgrad[j]
        return mu_n, an + (mu_t / mu_n) * at, dk

    def _restart(self, seg: _Seg):
        """The impact at the start of ``seg`` by the continuous law ``n.qdot -> -e n.qdot``; the rest of the
        step as a first segment from there: ``(segment, its crossings, E_d after, mu)``."""
        k = self.k
        self._at(seg.t)
        vel, minv_n, _, _, mu = self._continuous_law(seg.q, seg.x[: k.n], seg.p_in, seg.nrm, seg.rest)
        p_plus = seg.p_in + mu * seg.nrm
        self.fallbacks += 1
        v, _, _, e, phi0, phi1, d0, d1 = k.smooth_step(seg.q, p_plus, seg.tau, vel + mu * minv_n)
        fresh = _Seg(q=seg.q, t=seg.t, tau=seg.tau, p_in=p_plus, e_in=math.nan, nrm=None, contact=-1, x=v)
        crossings = {}
        if phi1.size and (phi1.min() < -self.tol.phi or ((d0 < 0) & (d1 > 0)).any()):
            crossings = self._crossings(fresh, phi0, phi1, d0, d1)
        return fresh, crossings, e, mu

    def _normal(self, q_c, v_c, p_c, group: list[int]) -> tuple[np.ndarray, list[float]]:
        """Impulse direction at an impact on the contacts ``group`` and each contact's share.

        One contact: its gradient. Several at once (a corner, two vertices): the normal-cone
        direction (86) ``sum_j w_j grad phi_j`` with ``w_j`` proportional to each contact's own
        elastic impulse ``-(n_j . qdot)/(n_j M^-1 n_j)``, so that no contact is served first
        and M-orthogonal walls reflect independently, whatever the order of the contacts.
        """
        grads = self.k.contacts(q_c)[1]
        if len(group) == 1:
            return grads[group[0]], [1.0]
        vel = self._velocity(q_c, v_c, p_c)
        mass = self.k.legendre(q_c, vel)[1]
        c = np.array(
            [max(-(grads[i] @ vel) / (grads[i] @ np.linalg.solve(mass, grads[i])), 0.0) for i in group]
        )
        c = c / c.sum() if c.sum() > 0 else np.full(len(group), 1.0 / len(group))
        return sum(ci * grads[i] for ci, i in zip(c, group)), [float(ci) for ci in c]

    def _jump(self, step, t_k, seg: _Seg, v_in, restitution: float = 1.0, group=(), weights=()):
        """Solve (48) for ``(w, mu)``: the physical root, ``mu > 0`` (MATH.md).

        With a coefficient of restitution ``e < 1`` the energy equation (48a) keeps
        ``E_d`` less the loss of (39), ``(1 - e^2)/2 (n.qdot)^2 / (n.M^-1 n)`` with ``qdot``
        the incoming velocity at the impact point; ``seg.e_in`` becomes that energy.

        Newton starts from the reflected velocity; if it lands on a root with ``mu <= 0``
        (the trajectory passing through the wall), it restarts from larger and smaller
        impulses along the same normal. Where (48) is a quadratic in ``mu``
        (``Kernels.jump_quadratic``, :mod:`vcigen.explicit`) a start is replaced by the
        root on its side of the vertex, the one Newton converges to, if that root is within
        ``mu0`` of the elastic impulse ``mu0``, and Newton only checks it; a root further
        away (grazing: the energy bias of (48a) dominates) is left to Newton from the
        start, as without the closed form. Under a rule with internal points a start's ``w``
        is the smooth step (46) from ``p_in + mu n``, (48b) alone: the reflected velocity is the
        continuous one, O(tau) from a segment's, and from it Newton can slide to the root
        ``mu = 0`` of a shallow crossing, which an exact ``E_d`` makes exact.
        Near grazing (48a) can have no root with ``mu > 0`` at all: that is a located ``SolverError``, or with
        ``Tolerances(grazing="reflect")`` the continuous law ``mu = mu0`` with (48b) alone.

        Mode ``"contact"`` (default, :mod:`vcigen.sustained`): ``(None, "plastic")`` where forces press
        the body in and the outgoing normal speed is below the jump's resolution, or (48a) has no root;
        a rootless impact not pressed in takes the continuous law (``"grazing"``). Returns ``(x, kind)``.
        """
        k = self.k
        n = k.n
        self._at(seg.t)
        self._law = None
        vel, minv_n, nv, nmn, mu0 = self._continuous_law(seg.q, v_in, seg.p_in, seg.nrm, restitution)
        sustain = self.tol.grazing == "contact" and k.r > 0
        accel = self._contact_accel(seg.q, vel, seg.nrm, group, weights) if sustain else 0.0
        pressed = accel < 0.0
        if pressed and self._settles(nv, accel, restitution, self._h):
            return None, "plastic"
        nrm0 = seg.nrm
        law = self._frictional_law(seg, vel, group, restitution) if nv < 0.0 else None
        self._law = (group[0], nrm0) if law is not None else None  # the tangent's (Tracker.jump)
        if law is not None:  # Coulomb friction: the impulse along n + (mu_t/mu_n) t, the energy less dK
            mu0, minv_n, dk = law
            seg.e_in += dk
        elif restitution < 1.0 and nv < 0.0:  # (39): the energy the normal velocity loses
            seg.e_in -= (1.0 - restitution * restitution) * nv * nv / (2.0 * nmn)
        mu_scale = mu0 if mu0 > 0 else float(np.linalg.norm(seg.p_in)) / float(np.linalg.norm(seg.nrm))
        roots = []
        quad = k.jump_quadratic(seg.q, seg.nrm, seg.p_in, seg.e_in, seg.tau)
        staged = bool(getattr(getattr(k, "system", None), "stages", 0))
        for factor in self.tol.jump_restarts:
            mu_try = mu_scale * factor
            x0 = np.append(vel + mu_try * minv_n, mu_try)
            if staged:  # (48b) alone at mu_try: the segment map's own w (internal points: no quadratic)
                w_try = k.solve("smooth", x0[:n], seg.q, seg.p_in + mu_try * seg.nrm, seg.tau)[0]
                x0[:n] = w_try if np.isfinite(w_try).all() else x0[:n]
            if quad is not None:  # the root Newton from mu_try converges to, in closed form
                (a, b, c), w0, dw = quad
                mu_q = quadratic_root(a, b, c, mu_try)
                if mu_q is not None and abs(mu_q - mu0) <= mu0:
                    x0 = np.append(w0 + mu_q * dw, mu_q)
            x, res = k.solve("jump", x0, seg.q, seg.nrm, seg.p_in, seg.e_in, seg.tau)
            if res <= self._scale(seg.p_in, seg.e_in):
                if x[n] > 0:
                    return x, "jump"
                roots.append(float(x[n]))
        if pressed:
            return None, "plastic"
        reflect = self.tol.grazing == "reflect" and mu0 > 0.0
        if reflect or sustain:  # the continuous law, energy reset
            w, res = k.solve("smooth", vel + mu0 * minv_n, seg.q, seg.p_in + mu0 * seg.nrm, seg.tau)
            if res <= self._scale(seg.p_in, seg.e_in):
                self.reflected += reflect
                # forces: the energy at the segment's start, as after (48a) (segment gives its end's)
                e_in = k.start_energy(seg.q, w, seg.tau) if self._forced else k.segment(seg.q, w, seg.tau)[2]
                seg.e_in = e_in
                return np.append(w, mu0), "grazing"
        vn = nv / float(np.linalg.norm(seg.nrm))
        found = ", ".join(sorted({f"{r:.3e}" for r in roots})) or "none"

        raise SolverError(
            step,
            t_k,
            "jump",
            float("nan") if not roots else 0.0,
            f"no root with mu > 0 of the jump (48) on '{k.contact_names[seg.contact]}' at "
            f"t = {seg.t:.12g} (roots found: mu = {found}); normal speed {vn:.3e} is too small for "
            "the discrete energy balance (48a) at this h (grazing impact): reduce h" + self._unheld(),
        )

    def _args(self, seg: _Seg) -> tuple:
        if seg.contact < 0:
            return (seg.q, seg.p_in, seg.tau)
        return (seg.q, seg.nrm, seg.p_in, seg.e_in, seg.tau)

    def _contact_root(self, step, t_k, seg: _Seg, j: int, hi: float, g_hi: float):
        """Earliest root ``s`` in ``[lo, hi]`` of ``phi_j`` along the segment map; ``(x, s)``.

        Newton on the whole system (47) or (78) from an interpolated guess; if it
        fails or leaves the bracket, a safeguarded scalar root on ``s`` instead.
        """
        k = self.k
        first = seg.contact < 0
        name = ("contact_time_" if first else "jump_contact_") + k.contact_names[j]
        phase = "contact time" if first else "jump to contact"
        self._at(seg.t)
        lo, phi_lo = 0.0, k.contacts(seg.q)[0][j]
        if not first and j == seg.contact:  # leaving the contact just hit: step off the trivial root
            lo, phi_lo = self._leave(seg, j)
        s0 = lo + (hi - lo) * float(np.clip(phi_lo / (phi_lo - g_hi), 0.0, 1.0))
        if first and k.explicit_path:  # the position is explicit in s: a safeguarded scalar root
            x, res = k.solve(name, self._path_root(seg, j, s0, hi), *self._args(seg))
        else:
            x, res = k.solve(name, np.append(seg.x, s0), *self._args(seg))
        s, ok = self._root_ok(x, res, seg, first, lo, hi)
        if not ok and lo > 0.0 and getattr(getattr(k, "system", None), "stages", 0):
            s0 = self._leave_guess(lo, phi_lo, hi, g_hi)
            x, res = k.solve(name, np.append(seg.x, s0), *self._args(seg))
            s, ok = self._root_ok(x, res, seg, first, lo, hi)
        if not ok:
            x, s, res = self._bracketed_root(step, t_k, seg, j, name, phase, lo, phi_lo, hi, g_hi)
        self._check(res, seg.p_in, step, t_k, phase, seg.e_in)
        return x, min(max(s, 0.0), 1.0)

    def _root_ok(self, x, res: float, seg: _Seg, first: bool, lo: float, hi: float) -> tuple[float, bool]:
        """``(s, ok)``: the contact root ``x`` converged, in the bracket, past ``lo`` with ``mu > 0``."""
        s = float(x[-1])
        ok = res <= self._scale(seg.p_in, seg.e_in) and lo - 1e-12 <= s <= hi + 1e-12
        if ok and not first:
            ok = x[self.k.n] > 0 and (s > lo or lo == 0)
        return s, ok

    @staticmethod
    def _leave_guess(lo: float, phi_lo: float, hi: float, g_hi: float) -> float:
        """The root of the quadratic ``A s + B s**2`` through ``phi_j = 0`` at ``s = 0`` (the contact just
        hit), ``phi_lo`` at ``lo`` and ``g_hi < 0`` at ``hi``: always in ``(lo, hi)``. Rules with internal
        points retry the (78) Newton from there when the one from the chord fails: with ``phi_lo`` tiny the
        chord lands next to ``lo``, Newton slides back to ``s = 0`` and a dozen bracketing solves follow."""
        return float(np.clip((phi_lo * hi * hi - g_hi * lo * lo) / (phi_lo * hi - g_hi * lo), lo, hi))

    def _path_root(self, seg: _Seg, j: int, s0: float, hi: float) -> np.ndarray:
        """Newton on ``g(s) = phi_j(q(s tau))`` along the explicit segment map, kept in its bracket.

        From ``s0`` in ``[0, hi]`` (``g(0) >= 0 > g(hi)``); a step leaving the bracket is a
        bisection. Returns ``(v(s), s)``, the unknowns of (47), for Newton to check.
        """
        k = self.k
        a, b, s = 0.0, hi, s0
        for _ in range(100):
            g, dg, _ = k.contact_path(j, s, seg.q, seg.p_in, seg.tau)
            if g == 0:
                break
            if g < 0:
                b = s
            else:
                a = s
            sn = s - g / dg if dg != 0 else math.nan
            if not (a < sn < b):
                sn = 0.5 * (a + b)
            if abs(sn - s) <= 4e-16 * (1.0 + abs(s)):
                s = sn
                break
            s = sn
        _, _, v = k.contact_path(j, s, seg.q, seg.p_in, seg.tau)
        return np.append(v, s)

    def _sub_solve(self, seg: _Seg, s: float, guess) -> tuple[np.ndarray, float]:
        """The segment map at fraction ``s``: its unknowns and ``phi`` at its end."""
        k = self.k
        self._at(seg.t)
        if seg.contact < 0:
            x, _ = k.solve("smooth", guess, seg.q, seg.p_in, s * seg.tau)
        else:
            x, _ = k.solve("jump", guess, seg.q, seg.nrm, seg.p_in, seg.e_in, s * seg.tau)
        return x, k.contacts(seg.q + s * seg.tau * x[: k.n])[0]

    def _leave(self, seg: _Seg, j: int):
        """After an impact on ``j``: a small fraction where ``phi_j > 0`` again."""
        for s in (1e-3, 1e-6, 1e-9):
            _, phi = self._sub_solve(seg, s, seg.x)
            if phi[j] > self.tol.phi:
                return s, float(phi[j])
        return 0.0, 0.0

    def _bracketed_root(self, step, t_k, seg, j, name, phase, a, ga, b, gb):
        """Illinois regula falsi on ``g(s) = phi_j(q(s))`` over ``[a, b]``, then a Newton polish."""
        k = self.k
        xb, _ = self._sub_solve(seg, b, seg.x)  # sets the segment's time
        if not (ga >= -self.tol.phi and gb < 0):
            raise SolverError(
                step,
                t_k,
                phase,
                abs(gb),
                f"no sign change of phi_{k.contact_names[j]} on [{a:.3g}, 1] (phi = {ga:.3e}, {gb:.3e})",
            )
        side, phi_b = 0, gb
        for _ in range(200):
            c = (a * gb - b * ga) / (gb - ga)
            if not a < c < b:
                c = 0.5 * (a + b)
            xc, phic = self._sub_solve(seg, c, xb)
            gc = phic[j]
            if gc == 0:  # c is a root
                b, gb, xb, phi_b = c, gc, xc, gc
                break
            if gc < 0:
                b, gb, xb, phi_b = c, gc, xc, gc
                ga = ga / 2 if side == -1 else ga
                side = -1
            else:
                a, ga = c, gc
                gb = gb / 2 if side == 1 else gb
                side = 1
            if b - a < 4e-16 or gc == 0:
                break
        x, res = k.solve(name, np.append(xb, b), *self._args(seg))
        if not (a - 1e-12 <= x[-1] <= b + 1e-12) and (b - a <= 1e-12 or abs(phi_b) <= self.tol.phi):
            # A shallow crossing: the polish ran to the nearby exit root. The bracket itself
            # has converged, and its end solves the segment map with |phi| = |gb|.
            return np.append(xb, b), b, abs(phi_b)
        if not (a - 1e-12 <= x[-1] <= b + 1e-12):
            raise SolverError(
                step,
                t_k,
                phase,
                res,
                f"Newton polish of the contact on "
                f"'{k.contact_names[j]}' left the bracket [{a:.17g}, {b:.17g}]",
            )
        return x, float(x[-1]), res

    # -- checks --------------------------------------------------------------------
    def _scale(self, p, e=math.nan) -> float:
        scale = 1.0 + float(np.max(np.abs(p))) + (abs(e) if math.isfinite(e) else 0.0)
        return self.tol.residual * scale

    def _check(self, res, p, step, t, phase, e=math.nan) -> None:
        if not (res <= self._scale(p, e)):
            raise SolverError(
                step,
                t,
                phase,
                float(res),
                "Newton did not converge; reduce h or check "
                "that the Lagrangian is regular along the trajectory",
            )


def unheld_note(system) -> str:
    """What a jump error adds under a rule with internal points and no sustained contact; else ``""``
    (every rule has sustained contact now: this stays for a rule that cannot place its internal points)."""
    if not system.stages or system.r:
        return ""
    return f"; rule {system.rule.name!r} has no sustained contact yet (trapezoid and midpoint have it)"


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


def quadratic_root(a: float, b: float, c: float, mu_try: float) -> float | None:
    """The root of ``a mu^2 + b mu + c`` that Newton from ``mu_try`` converges to, or ``None``.

    For a quadratic that is the root on ``mu_try``'s side of the vertex ``-b / 2a``; the
    roots are formed without cancellation. ``None``: no real root, or ``mu_try`` at the vertex.
    """
    if a == 0.0:
        return -c / b if b != 0.0 else None
    disc = b * b - 4.0 * a * c
    if disc < 0.0 or not math.isfinite(disc) or mu_try == -b / (2.0 * a):
        return None
    big = -0.5 * (b + math.copysign(math.sqrt(disc), b))
    roots = sorted((big / a, c / big) if big != 0.0 else (0.0, 0.0))
    return roots[1] if mu_try > -b / (2.0 * a) else roots[0]


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


def _hermite_min(g0: float, g1: float, d0: float, d1: float) -> tuple[float, float]:
    """Minimum over ``[0, 1]`` of the cubic with ends ``g0, g1`` and slopes ``d0, d1``."""
    c = np.array([2 * g0 - 2 * g1 + d0 + d1, -3 * g0 + 3 * g1 - 2 * d0 - d1, d0, g0])
    crit = [r.real for r in np.roots(np.polyder(c)) if abs(r.imag) < 1e-12 and 0 < r.real < 1]
    s = min((0.0, 1.0, *crit), key=lambda x: np.polyval(c, x))
    return float(s), float(np.polyval(c, s))


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
