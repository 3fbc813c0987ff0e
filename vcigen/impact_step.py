"""The impact step of MATH.md: the segments of a grid step that holds impacts.

A grid step with a contact crossed is a chain of segments ``(q_s, v_s, tau_s)``
(:class:`Seg`): the first from the grid point, each later one from an impact point,
where the momentum jumps along the contact normal (48), several impacts in a step
chained by (78). Contact time (47) and (78) are located by a bracketed root along the
segment map; a grazing impact takes the continuous law; restitution (39) and Coulomb
friction enter through the jump. :class:`ImpactSteps` is a base of
:class:`vcigen.stepper.Stepper` and reads its state (``k``, ``tol``, ``_tan``, ...).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from .errors import HELD_NO_ROOT, HELD_ROWS, NOT_CONVERGED, SolverError
from .friction import cone_law, impact_law
from .held_roots import LEAVE_FRACTIONS, illinois_point, illinois_update
from .result import Impact

# A (78) root or a sub-solve's whose impulse is more than SINK_GAP of the jump's below it, and that leaves the
# contact just hit moving in, is the jump's mirror root (ImpactSteps._sinks)
SINK_GAP = 0.1


@dataclass
class Seg:
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
    leaves: int = -1  # a first segment's: the contact an impact by a fixed impulse at its start left (_fixed)


class ImpactSteps:
    """The phases of a grid step with impacts: contact times, jumps, restitution, grazing."""

    def _missed(self, seg: Seg, crossings, x, s: float) -> dict[int, tuple[float, float]]:
        """Contacts not in ``crossings`` below ``-Tolerances.admissible`` at the impact ``(x, s)`` found
        first, each with ``(s, phi)``: crossed inside ``[0, s]`` (the root's bracket). The contact the
        segment leaves from (a rocking box's vertex, bounced at ``e = 0.3`` and met again before its other
        vertex landed, at ``h = 0.005``) is no dip of the cubic test, whose start slope leaves it; the other
        vertex's impact was located with it 1.7e-5 below, and C raised "more than 64 impacts in one step"
        (``bench.plate_drops``); another contact's dip the cubic missed (a box on a box: a vertex 6.7e-5 into
        the lower box at the next impact found, ``tests/test_stacks.py``)."""
        phi = self.k.contacts(seg.q + s * seg.tau * x[: self.k.n])[0]
        low = np.flatnonzero(phi < -self.tol.admissible)
        return {int(i): (s, float(phi[i])) for i in low if int(i) not in crossings}

    def _impact_step(self, step, t_k, h, seg: Seg, crossings, impacts, e_step=None):
        """Chain of segments (47), (48), (78), (79) until one ends inside C at ``t_k + h``.

        A plastic impact (mode ``"contact"``) hands the rest of the step to the constrained
        chain (:mod:`vcigen.sustained`). ``e_step``: E_d of the grid step, if an earlier phase fixed it.
        """
        k, tol = self.k, self.tol
        n = k.n
        pending: list[tuple[Impact, float]] = []
        restitution = k.restitution()
        struck: set[int] = set()  # the contacts met at the instant of the last impact
        settles = tol.grazing == "contact" and k.r > 0  # a contact met again at that instant: all at once
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
            missed = self._missed(seg, crossings, x, s)
            if missed:  # crossed before this impact (a dip the end and the cubic missed): located first
                crossings.update(missed)
                continue
            group = [i for i in sorted(roots) if roots[i][1] - s <= tol.simultaneous]
            if s * seg.tau > tol.simultaneous * h:  # a later instant
                struck = set()
            again = settles and bool(struck & set(group))
            if again:  # met again at the instant it was met: with the contacts met there, at once (below)
                group = sorted(struck | set(group))
            struck |= set(group)
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
            seg = Seg(q=q_c, t=t_c, tau=seg.tau - tau_c, p_in=p_minus_c, e_in=e_in, nrm=nrm, contact=j, x=x)
            kink = len(group) == 1 and self._kinked(q_c, v_c, p_minus_c, group[0])
            # One with friction, or a kink's rows: no (86). Or a contact met again at the instant it was
            # met: a box's face landing on a vibrating plate took its two corners in turn at e = 0, each
            # leaving the other moving in, nine impacts at one instant (bench.plate_drops --seed 31 --h
            # 0.02, drop 125), whose limit is the law on both at once
            if len(group) > 1 and self._rough(group) or kink or again:
                self._count_event(step, t_k)  # the tangent broke at the contact (simultaneous impact)
                if (kink or again) and self._tan is not None:
                    self._tan.lose("simultaneous impact")
                rest = (step, t_k, h, q_c, p_minus_c, t_c, seg.tau, v_c, self._touching(q_c, v_c, group)[0])
                return self._tangent_held(
                    q_c, p_minus_c, seg.tau, True, self._rough_rest, *rest, impacts, e_in, e_step
                )
            # Jump (48): tangential momentum kept, the normal one jumps by mu grad phi; energy kept
            # (less the loss of (39) with restitution; seg.e_in becomes the energy after).
            elastic = all(restitution[i] == 1.0 for i in group)
            e_rest = 1.0 if elastic else float(sum(wgt * restitution[i] for i, wgt in zip(group, weights)))
            seg.rest = e_rest
            x_jump, kind = self._jump(step, t_k, seg, v_c, e_rest, group, weights)
            if self._tan is not None:
                self._tan.jump(seg, v_c, e_rest, kind, self._law, self._touch)
            if x_jump is None:  # plastic: the contact is held for the rest of the step
                self._count_event(step, t_k)
                p_plus, lam, loss, rows, law = self._plastic_entry(
                    step, t_k, h, q_c, p_minus_c, v_c, t_c, group
                )
                for i in group:
                    own = sum(lam[r] for r in rows if k.row_contact[r] == i)
                    self._log(impacts, t_c, i, q_c, (t_c - t_k) / h, own, step, e_in, e_in - loss, "plastic")
                if self._tan is not None and law[2]:  # a landing cone's sliding impulse
                    self._tan.lose(law[2])
                elif self._tan is not None:
                    self._tan.plastic(seg, v_c, law[0], law[1])
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
                    self._velocity(q_c, v_c, p_plus),  # the chain's first guess: the velocity after it
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
            after = self._fixed(seg) if kind == "grazing" else seg
            q_end, crossings = self._segment_end(after, w)
            if not crossings:
                if self._tan is not None:
                    self._tan.jump_end(seg)
                impacts.extend(im for im, _ in pending)
                return q_end, p_end, (e_after if self._forced else e_step), w
            if after is not seg:  # the continuous law's impulse is final: the contacts met after it, (47)
                impacts.extend(im for im, _ in pending)
                pending = []
                seg = after
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

    def _frictional_law(self, seg: Seg, vel, group, restitution: float):
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

    def _restart(self, seg: Seg):
        """The impact at the start of ``seg`` by the continuous law ``n.qdot -> -e n.qdot``; the rest of the
        step as a first segment from there: ``(segment, its crossings, E_d after, mu)``."""
        k = self.k
        self._at(seg.t)
        vel, minv_n, _, _, mu = self._continuous_law(seg.q, seg.x[: k.n], seg.p_in, seg.nrm, seg.rest)
        p_plus = seg.p_in + mu * seg.nrm
        self.fallbacks += 1
        v, _, _, e, phi0, phi1, d0, d1 = k.smooth_step(seg.q, p_plus, seg.tau, vel + mu * minv_n)
        fresh = Seg(q=seg.q, t=seg.t, tau=seg.tau, p_in=p_plus, e_in=math.nan, nrm=None, contact=-1, x=v)
        crossings = {}
        if phi1.size and (phi1.min() < -self.tol.phi or ((d0 < 0) & (d1 > 0)).any()):
            crossings = self._crossings(fresh, phi0, phi1, d0, d1)
        return fresh, crossings, e, mu

    def _fixed(self, seg: Seg) -> Seg:
        """The rest of the step after an impact on ``seg`` by the continuous law (``"grazing"``): a first
        segment from ``p~- + mu0 n`` with the jump's ``w``, leaving ``seg.contact`` (C ``fixed``). Its map
        over a fraction ``s`` is the smooth step (46) of that momentum, where the jump's (48) at ``s``, an
        energy balance the law reset, has no root in general: sampled for a dip there, a Newton that had not
        converged flagged one on C and not on CasADi (a box on a vibrating plate, ``bench.plate_drops --agree
        --seed 31 --h 0.02``, drop 125), and a contact met after it was sought by (78)."""
        n = self.k.n
        p_in = seg.p_in + float(seg.x[n]) * seg.nrm
        return Seg(
            q=seg.q,
            t=seg.t,
            tau=seg.tau,
            p_in=p_in,
            e_in=math.nan,
            nrm=None,
            contact=-1,
            x=seg.x[:n].copy(),
            leaves=seg.contact,
        )

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

    def _jump(self, step, t_k, seg: Seg, v_in, restitution: float = 1.0, group=(), weights=()):
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
        a rootless impact not pressed in takes the continuous law (``"grazing"``), as does one not pressed
        in whose outgoing normal speed is below the resolution (``_departs``: (48a)'s roots leave at +-O(h)
        there; stop 55). Returns ``(x, kind)``.
        """
        k = self.k
        n = k.n
        self._at(seg.t)
        self._law = None
        self._touch = False  # took the continuous law as a touch and go (_departs): the tangent covers it
        vel, minv_n, nv, nmn, mu0 = self._continuous_law(seg.q, v_in, seg.p_in, seg.nrm, restitution)
        sustain = self.tol.grazing == "contact" and k.r > 0
        accel = self._contact_accel(seg.q, vel, seg.nrm, group, weights) if sustain else 0.0
        if sustain and accel >= 0.0 and nv < 0.0:  # not pressed at qdot-: is it at the velocity it leaves,
            # n.qdot = 0? A double pendulum's tip swung down onto a floor at e = 0 was pulled up by its own
            # normal speed, not once that was gone; (48a) had no root, it took the continuous law as grazing
            accel = self._contact_accel(seg.q, vel - (nv / nmn) * minv_n, seg.nrm, group, weights)
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
        # not pressed, leaving slower than the jump resolves: (48a)'s roots leave at O(h) either way (one
        # into the contact), the continuous law at -e v_n (a damper's ball at e = 0 left its wall inwards)
        departs = sustain and nv < 0.0 and self._departs(nv, accel, restitution, self._h)
        quad = k.jump_quadratic(seg.q, seg.nrm, seg.p_in, seg.e_in, seg.tau)
        staged = bool(getattr(getattr(k, "system", None), "stages", 0))
        for factor in () if departs else self.tol.jump_restarts:
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
        if sustain and not pressed and mu0 > 0.0:  # no root: pressed at the velocity the continuous law
            # leaves? (with Coulomb's impulse: a tip landing on a rough floor at e = 0 stopped, pressed, the
            # centripetal pull of its tangential speed gone with it)
            pressed = self._contact_accel(seg.q, vel + mu0 * minv_n, nrm0, group, weights) < 0.0
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
                self._touch = departs
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

    def _args(self, seg: Seg) -> tuple:
        if seg.contact < 0:
            return (seg.q, seg.p_in, seg.tau)
        return (seg.q, seg.nrm, seg.p_in, seg.e_in, seg.tau)

    def _contact_root(self, step, t_k, seg: Seg, j: int, hi: float, g_hi: float):
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
        if first and phi_lo < -self.tol.phi:  # it starts below the contact (within admissible): hit at once
            return np.append(self._velocity(seg.q, seg.x[: k.n], seg.p_in), 0.0), 0.0
        if first and phi_lo <= self.tol.phi:  # touching at the start, not held (a rough one moving out): step
            lo, phi_lo = self._leave(seg, j, hi)  # off the trivial root at s = 0 to the landing, if it leaves
        if not first and j == seg.contact:  # leaving the contact just hit: step off the trivial root
            lo, phi_lo = self._leave(seg, j, hi)
            if phi_lo < 0.0:  # crossed back at once after an impact that left it no normal speed: a restart
                back = f"phi_{k.contact_names[j]} crossed back at once after its impact"
                raise SolverError(step, t_k, phase, abs(phi_lo), back)
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

    def _root_ok(self, x, res: float, seg: Seg, first: bool, lo: float, hi: float) -> tuple[float, bool]:
        """``(s, ok)``: the contact root ``x`` converged, in the bracket, past ``lo`` with ``mu > 0``."""
        s = float(x[-1])
        ok = res <= self._scale(seg.p_in, seg.e_in) and lo - 1e-12 <= s <= hi + 1e-12
        if ok and not first:
            ok = x[self.k.n] > 0 and (s > lo or lo == 0) and not self._sinks(seg, float(x[self.k.n]))
        return s, ok

    def _sinks(self, seg: Seg, mu: float) -> bool:
        """Is impulse ``mu`` of the jump at ``seg``'s start its mirror root: more than ``SINK_GAP`` of the
        jump's own (``seg.x``) below it, and the normal velocity it leaves the contact just hit, ``n . M^-1
        (p~- + mu n)``, below ``-1/2`` of the jump's?

        Under restitution ``e`` the energy balance (48a) has a second root beside the jump's, its mirror
        about the plastic impulse: the normal velocity ``-e v_n`` where the jump's is ``+e v_n``, the same
        kinetic energy, ``(1 - e)/(1 + e)`` of its impulse. A (78) Newton or a sub-solve at a fraction far
        from the jump's can converge to it: C did on a frictionless box wedged in a V (``e = 0.195``,
        lobatto3, ``bench.box_v_drops --smooth --rule lobatto3`` drop 95), its corner sank through the wall
        it had just hit, and the run raised "more than 64 impacts in one step". Where the two roots are
        closer than ``SINK_GAP`` (a rattle's last impacts, a normal velocity of 1e-9 after them) a
        sub-solve's own drift of ``mu`` is no mirror."""
        k = self.k
        mu_jump = float(seg.x[k.n])
        if not mu < (1.0 - SINK_GAP) * mu_jump:
            return False
        n = seg.nrm
        out = float(n @ self._velocity(seg.q, seg.x[: k.n], seg.p_in + mu_jump * n))
        return out > 0.0 and float(n @ self._velocity(seg.q, seg.x[: k.n], seg.p_in + mu * n)) < -0.5 * out

    @staticmethod
    def _leave_guess(lo: float, phi_lo: float, hi: float, g_hi: float) -> float:
        """The root of the quadratic ``A s + B s**2`` through ``phi_j = 0`` at ``s = 0`` (the contact just
        hit), ``phi_lo`` at ``lo`` and ``g_hi < 0`` at ``hi``: always in ``(lo, hi)``. Rules with internal
        points retry the (78) Newton from there when the one from the chord fails: with ``phi_lo`` tiny the
        chord lands next to ``lo``, Newton slides back to ``s = 0`` and a dozen bracketing solves follow."""
        return float(np.clip((phi_lo * hi * hi - g_hi * lo * lo) / (phi_lo * hi - g_hi * lo), lo, hi))

    def _path_root(self, seg: Seg, j: int, s0: float, hi: float) -> np.ndarray:
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

    def _sub_solve(self, seg: Seg, s: float, guess) -> tuple[np.ndarray, np.ndarray, float]:
        """The segment map at fraction ``s``: its unknowns, ``phi`` at its end and the residual of the jump
        (48) at ``s`` (0 on a first segment, whose smooth step (46) is solved as in a grid step). A jump's
        root (converged) that :meth:`_sinks` is solved again from the smooth step (46) of the jump's momentum
        over ``s`` with the jump's impulse."""
        k = self.k
        self._at(seg.t)
        res = 0.0
        if seg.contact < 0:
            x, _ = k.solve("smooth", guess, seg.q, seg.p_in, s * seg.tau)
        else:
            x, res = k.solve("jump", guess, seg.q, seg.nrm, seg.p_in, seg.e_in, s * seg.tau)
            if res <= self._scale(seg.p_in, seg.e_in) and self._sinks(seg, float(x[k.n])):
                # a root, the jump's mirror (_sinks): again from the jump's impulse
                mu = float(seg.x[k.n])
                start = k.solve("smooth", seg.x[: k.n], seg.q, seg.p_in + mu * seg.nrm, s * seg.tau)[0]
                x, res = k.solve(
                    "jump", np.append(start, mu), seg.q, seg.nrm, seg.p_in, seg.e_in, s * seg.tau
                )
        return x, k.contacts(seg.q + s * seg.tau * x[: k.n])[0], res

    def _leave(self, seg: Seg, j: int, hi: float):
        """After an impact on ``j``: ``(s, phi_j)`` at a small fraction ``s < hi`` where ``phi_j > 0`` again,
        else ``(0, 0)``; ``hi`` the crossing's (below the contact there): a fraction past it would leave the
        crossing behind the bracket's start (a corner let go by the held chain, touching, dipped 2.7e-9 below
        the plate at ``s`` = 7.2e-4, above again at 1e-3, and its search on ``[1e-3, 7.2e-4]`` failed in C;
        ``bench.plate_drops --seed 23 --h 0.05``, drop 475). After an impact with no outgoing normal speed
        (``seg.rest == 0``; sustained contact, ``Tolerances.grazing == "contact"``), ``(0, phi_j < 0)`` where
        ``phi_j`` is already below ``-phi`` at the largest fraction: ``j`` crossed back at once, and the
        sub-solves at smaller fractions may take another root of (78), whose ``phi_j`` is not this path's (a
        bracket on it ended 1e-8 deep and the run stopped: frictionless cube drop 988 of seed 21). The caller
        (:meth:`_contact_root`) then raises, which :meth:`_impact_step` takes as (78) unsolvable: a restart.
        Elsewhere (an elastic star's next vertex, the same contact) the smaller fractions are tried as before.
        A sub-solve that does not converge (no root of (48) over that fraction) is no evidence: at the largest
        fraction after an impact with no outgoing normal speed it is (78) unsolvable there, a restart;
        elsewhere the next fraction is tried. Its ``phi_j`` had decided: a box's vertex left moving in at
        6.6e-5 after an ``e = 0`` impact on a vibrating plate read ``+3.5e-11`` at a residual of 4.5e-5 on
        CasADi (a second impact 2 ms later) and ``-6.3e-6`` at 0.56 in C (a restart), and the backends parted
        (``bench.plate_drops --agree``)."""
        back = seg.rest == 0.0 and self.tol.grazing == "contact" and self.k.r > 0
        for s in LEAVE_FRACTIONS:
            if s >= hi:
                continue
            _, phi, res = self._sub_solve(seg, s, seg.x)
            solved = res <= self._scale(seg.p_in, seg.e_in)
            if solved and phi[j] > self.tol.phi:
                return s, float(phi[j])
            if back and (phi[j] < -self.tol.phi or not solved) and s == LEAVE_FRACTIONS[0]:
                return 0.0, min(float(phi[j]), -self.tol.phi)
        return 0.0, 0.0

    def _bracketed_root(self, step, t_k, seg, j, name, phase, a, ga, b, gb):
        """Illinois regula falsi on ``g(s) = phi_j(q(s))`` over ``[a, b]``, then a Newton polish.

        Where the polish leaves a bracket that has closed, the bracket's end is the root, with the larger of
        its ``|phi_j|`` and its jump's residual: near a fraction where (48) has no root (its energy balance
        has none at that duration) the end's sub-solve is unconverged, and its unknowns are no root of
        (78) however small its ``phi_j`` (box on box draw 68: 9.9e-7 with ``phi_j`` 4e-12); the caller
        then takes (78) as unsolvable, as where ``phi_j`` jumps across the bracket."""
        k = self.k
        xb, _, res_b = self._sub_solve(seg, b, seg.x)  # sets the segment's time
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
            c = illinois_point(a, ga, b, gb)
            xc, phic, res_c = self._sub_solve(seg, c, xb)
            gc = phic[j]
            if gc == 0:  # c is a root
                b, gb, xb, phi_b, res_b = c, gc, xc, gc, res_c
                break
            a, ga, b, gb, side = illinois_update(a, ga, b, gb, side, c, gc)
            if gc < 0:
                xb, phi_b, res_b = xc, gc, res_c
            if b - a < 4e-16:
                break
        x, res = k.solve(name, np.append(xb, b), *self._args(seg))
        if not (a - 1e-12 <= x[-1] <= b + 1e-12) and (b - a <= 1e-12 or abs(phi_b) <= self.tol.phi):
            # A shallow crossing: the polish ran to the nearby exit root. The bracket itself
            # has converged, and its end solves the segment map with |phi| = |gb|.
            return np.append(xb, b), b, abs(phi_b) if res_b <= abs(phi_b) else res_b  # NaN stays NaN
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
            why = NOT_CONVERGED + (HELD_NO_ROOT + self._held_names() if phase == "sustained" else "")
            raise SolverError(step, t, phase, float(res), why)

    def _held_names(self) -> str:
        """``"; held: rod, floor[+-]"``: the rows held, by name (``Rows.names``), for a held step's error."""
        act = getattr(self, "act", None)
        held = [self.k.row_names[r] for r in np.flatnonzero(act)] if act is not None else []
        return HELD_ROWS + ", ".join(held) if held else ""


def unheld_note(system) -> str:
    """What a jump error adds under a rule with internal points and no sustained contact; else ``""``
    (every rule has sustained contact now: this stays for a rule that cannot place its internal points)."""
    if not system.stages or system.r:
        return ""
    return f"; rule {system.rule.name!r} has no sustained contact yet (trapezoid and midpoint have it)"


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
