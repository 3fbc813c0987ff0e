"""Impacts with rows held (MATH.md *Sustained contact*), for :class:`vcigen.sustained.SustainedSteps`: an
impact while held (its impulse law: :mod:`vcigen.impulse_law`), the friction modes after it, the rows it pulls
off, the plastic entry (a free impact whose rows become held) and its log. :class:`HeldImpacts` reads the
stepper's state."""

from __future__ import annotations

import math

import numpy as np

from .errors import SolverError
from .held_roots import BOUNCE_CYCLES, RESTITUTION_BISECTIONS, SLIDE_EPS, in_span, span_add
from .impulse_law import ImpulseLaw, law_gains
from .result import Impact


class HeldImpacts(ImpulseLaw):
    """Impacts while rows are held (a base of :class:`vcigen.sustained.SustainedSteps`)."""

    def _slip_at_impact(self, q, vel_p, slipped, slips=(), lands=None) -> str:
        """The stick rows that slipped in the impulse law (:meth:`_impulse_law`): their contacts slip after it
        along the tangential velocity after, ``slip_f = -mu_f sign(g_t.qdot+)``, or stick on where that is 0
        (to round-off). The slipping contacts that joined it (``slips``, :meth:`_law_slips`): slip on (the
        same way: no switch; turned: a switch) or, where their sliding after is 0 (to round-off), stick
        (:meth:`_stick`, a switch). Isotropic cones (:meth:`_law_cones`) the same way, along their sliding
        after (``slip = -mu_f w+ / |w+|``): a sticking one that slipped or a slipping one that stuck is a
        switch; one slipping on took a sliding impulse the tangent does not carry. Why the tangent stops
        here: ``"friction switch in a held step"`` (a contact's mode changed), ``"friction at an impact"``
        (a cone's sliding impulse), ``""`` (carried). The landing contacts (``lands``) keep no mode here (a
        landing cone's sliding impulse the tangent carries: ``ImpulseLaw._law_tangent``)."""
        k = self.k
        why = ""
        slipped = [r for r in slipped if k.row_stick[r] not in (lands or {})]
        if not slipped and not slips:
            return why
        grad = k.rows(q, vel_p)[1]
        tiny = SLIDE_EPS * (1.0 + float(np.max(np.abs(vel_p))))
        switched, slid = self._cone_at_impact(q, vel_p, grad, tiny, slipped, slips)
        owners = {self._stick_rows[f]: riders for f, riders in slips}
        for sr in slipped:
            f = k.row_stick[sr]
            if self._partner[f] >= 0:
                continue  # an isotropic cone's: above
            sliding = float(grad[sr] @ vel_p)
            if sr in owners:  # a slipping contact that joined: on, turned, or stuck (below)
                for g in [f, *owners[sr]]:
                    along = float(grad[self._stick_rows[g]] @ vel_p)
                    if abs(along) > tiny:
                        slip = -self._mu_f[g] * math.copysign(1.0, along)
                        switched = switched or slip != self._slip[g]
                        self._slip[g] = slip
                continue
            if abs(sliding) > tiny:
                self.act[sr] = False
                self._slip[f] = -self._mu_f[f] * math.copysign(1.0, sliding)
                switched = True
                for g, owner in enumerate(self._ride):  # its dependent sticks slide with it, the same way
                    if owner == f and g != f and self._partner[g] < 0:
                        along = float(grad[self._stick_rows[g]] @ grad[sr])
                        self._slip[g] = -self._mu_f[g] * math.copysign(1.0, sliding * along)
                        self._ride[g] = -1
        for f, riders in slips:  # stuck in the law (its stick row tight) or at a sliding of 0 after it
            for g in [f, *riders] if self._partner[f] < 0 else ():
                if self._slip[g] and abs(float(grad[self._stick_rows[g]] @ vel_p)) <= tiny:
                    self._stick(g, q, vel_p)
                    switched = True
        self._set_friction()
        if switched:
            return "friction switch in a held step"
        return "friction at an impact" if slid else why

    def _cone_at_impact(self, q, vel_p, grad, tiny, slipped, slips) -> tuple[bool, bool]:
        """The isotropic cones of the impulse law after it (:meth:`_slip_at_impact`): one that slipped in it
        (its stick rows in ``slipped``) slips on along its sliding after, ``slip = -mu_f w+ / |w+|`` (a switch
        if it stuck before), or sticks where that is 0 (to round-off); one that slipped before and joined
        (``slips``) but stuck in it sticks (:meth:`_stick`, a switch). ``(switched, slid)``, ``slid``: a cone
        with riders slipped on through the impact (one without: the tangent carries its sliding impulse,
        ``ImpulseLaw._law_tangent``)."""
        switched = slid = False
        for f, p in self._cones():
            sr, sp_ = self._stick_rows[f], self._stick_rows[p]
            joined = any(g == f for g, _ in slips)
            w = self._sliding(f, p, grad, vel_p)
            if sr in slipped and math.hypot(*w) > tiny:
                switched = switched or not joined
                slid = slid or (joined and any(g == f and riders for g, riders in slips))  # with riders: none
                self.act[sr] = self.act[sp_] = False
                self._slip[[f, p]] = -self._mu_f[f] * w / math.hypot(*w)
            elif joined:
                self._stick(f, q, vel_p)
                self._stick(p, q, vel_p)
                switched = True
        return switched, slid

    def _chain_impact(self, step, t_k, h, q, p, v, t, group, impacts, e_before, again=(), joined=()):
        """An impact on rows ``group`` during sustained contact; returns the momentum after it. A row hit
        settles (plastic, held) where the forces of the rows held at ``(q, vel)`` press it in and its outgoing
        normal speed is below the resolution (:meth:`_settles`), or where it is in ``again`` (met by an impact
        at this instant already: it left at a normal speed of 0 and sank again at once). One the incoming
        velocity does not press in is read again once the impact has stopped it (:meth:`_stopped_pressed`).
        Rows of ``group`` in ``joined`` (:meth:`_joined`, all in ``again``) that the law leaves with no
        impulse are not of the impact: not held, not logged. Each contact of the impact is logged once:
        ``"plastic"`` where a row of it is held after, ``"grazing"`` where none is and all its rows touch and
        go (:meth:`_departs` at the state met, as a free impact's; MATH.md *Entry*), else by restitution. Each
        row of ``group`` counts in the step's bounces (``_bounces``, ``joined`` ones too); one met
        ``BOUNCE_CYCLES`` times in the step already settles as one in ``again`` does (Zeno: a few a step)."""
        k = self.k
        met = list(group)  # the rows met, for the step's bounces (joined ones with no impulse too)
        again = set(again) | {r for r in group if self._bounces.get(r, 0) >= BOUNCE_CYCLES}
        self._at(t)
        rest = k.restitution()
        vel = self._velocity(q, v, p)
        # pressed in by the forces of the rows held at this state, not the step's (an impact before it in the
        # chain changed them: a double pendulum's bob stopped on the floor by e = 0, the rods pulling it in)
        acc = self._held_accel(q, vel, (), ())
        grad = k.rows(q, vel)[1]
        targets, plastic, pulled, departing = {}, [], {}, set()
        for r in group:
            e = float(rest[k.row_contact[r]])
            rate = float(grad[r] @ vel)
            if self.tol.grazing == "contact" and (r in again or self._settles(rate, acc[r], e, h)):
                plastic.append(r)
            else:
                targets[r] = -e * rate
                if self.tol.grazing == "contact" and self._departs(rate, acc[r], e, h):
                    departing.add(r)  # below the resolution, not pressed: a touch and go where not held after
                if self.tol.grazing == "contact" and acc[r] >= 0.0 and rate < 0.0:
                    pulled[r] = (rate, e)
        counts = self.least_splits, self.friction_dropped
        state = self._law_state()  # before the law (its cut riders)
        if pulled:
            self._stopped_pressed(step, t_k, q, p, v, group, targets, plastic, pulled, counts, state)
        try:
            law = self._impulse_law(step, t_k, q, p, v, group, targets)
        except SolverError:
            if not (targets and self._stick_rows):
                raise
            law = None  # Newton's restitution with Coulomb's friction has no solution (a box wedged in a V)
        reduced = bool(targets) and bool(self._stick_rows) and (law is None or self._law_raises(q, law))
        if reduced:  # Newton's restitution with Coulomb's friction raising the kinetic energy, or unsolvable
            cut = self._reduced_restitution(step, t_k, q, p, v, group, targets, plastic, counts, state)
            law, targets, plastic = cut
        p_plus, lam, vel_m, vel_p, dropped, slipped, slips, lands, law_why = law
        if joined:  # touching rows the law did not push: not of the impact
            group = [r for r in group if r not in joined or lam[r] > 0.0]
            plastic = [r for r in plastic if r in group]
        why = self._slip_at_impact(q, vel_p, slipped, slips, lands) or law_why
        why = why or ("friction at an impact" if reduced else "")  # its fraction depends on the state
        if why:  # stick <-> slip at the impact (a mode change), a cone's sliding impulse, a split not carried
            self._sw_lose(why)
        else:  # the contacts slipping on or landing: their sliding impulse in Tracker.impulse
            self._ev_impulse(q, v, p, lam, targets, group, self._law_tangent(lam, slipped, slips, lands))
        mass = k.legendre(q, vel_m)[1]
        loss = 0.5 * (vel_m @ mass @ vel_m - vel_p @ mass @ vel_p)
        leaving = self._leaving(dropped, group)
        if leaving:  # each stays unless it leaves below the resolution, pulled back by the rows held after
            landed = self._landed(lands, slipped, plastic, leaving)
            after = self._held_accel(q, vel_p, leaving, plastic + landed)
            cut = self.riders_cut > state[2]  # the law cut a rider: its stick row is its own now
            tiny = SLIDE_EPS * (1.0 + float(np.max(np.abs(vel_p))))
            for r in leaving:  # one in the span of the rows held after rides on them: it stays (_rides_after)
                if self._rides_after(grad, r, leaving, plastic):
                    continue
                # at rest and in their span with the landing's stick rows: its acceleration after is theirs, 0
                # to round-off, whose sign decided its settle test (groove drop 17 of bench.groove_drops
                # --seed 1: released in C, held on CasADi); it stays (not after a cut: there it leaves, below)
                rest_ = abs(float(grad[r] @ vel_p)) <= tiny
                if not cut and rest_ and self._rides_after(grad, r, leaving, plastic + landed, sticks=True):
                    continue
                # after a cut, one in the span of the rows held after with their stick rows leaves: held, the
                # rows would be dependent (pyramid draw 297, p12 held at a force of 0: the held step failed)
                carried = cut and self._rides_after(grad, r, leaving, plastic, sticks=True)
                if carried or not self._settles(float(grad[r] @ vel_p), after[r], 1.0, h):
                    self._release(step, t_k, t, r)
        for r in plastic:  # pressed in and settling: held (its force, checked next, may release it)
            self._hold(grad, r)
        by_contact: dict[int, list[int]] = {}
        for r in group:
            by_contact.setdefault(k.row_contact[r], []).append(r)
        for j, rs in by_contact.items():
            if any(self.act[r] or r in plastic for r in rs):  # held, or riding on the rows held
                kind = "plastic"
            elif all(r in departing for r in rs):  # leaving below the resolution, not pressed (MATH.md Entry)
                kind = "grazing"
            else:
                kind = "elastic" if rest[j] == 1.0 else "restitution"
            self._log(
                impacts,
                t,
                j,
                q,
                (t - t_k) / h,
                float(sum(lam[r] for r in rs)),
                step,
                e_before,
                e_before - loss,
                kind,
            )
        for r in met:
            self._bounces[r] = self._bounces.get(r, 0) + 1
        return p_plus

    def _joined(self, q, u, group, hit) -> list[int]:
        """Rows that join an impact while held on ``group`` at ``(q, u)`` where a row of it was met at this
        instant already (``hit``): the other rows ``hit`` at this instant that touch (``|psi| <=
        Tolerances.phi``), at rest along their normal (``|grad psi . u| <= SLIDE_EPS (1 + |u|)``), not held.
        They take the impulse law with the group, at a target of 0 and held where they take an impulse, as the
        rows met again are (:meth:`_chain_impact`'s ``again``). Two contacts a chain of bobs touches at
        once at ``e = 0`` (a bob on the floor, the tip on a wall), met alone, stopped each other in turn:
        each impact left the other moving in, at a normal speed 0.4 times the last, a lift-off of each
        between, and from ``LIFT_CYCLES`` pulls on both held on to the step's end at forces of -17.7 and
        -16.8. Taken together (the limit of those impacts: a plastic impact on both), their forces pull and
        both leave."""
        if not any(r in hit for r in group):
            return []
        k = self.k
        psi, grad = k.rows(q, u)[:2]
        tiny = SLIDE_EPS * (1.0 + float(np.max(np.abs(u))))
        return [
            r
            for r in sorted(hit)
            if r not in group
            and not self.act[r]
            and k.row_contact[r] >= 0
            and k.row_stick[r] < 0
            and abs(float(psi[r])) <= self.tol.phi
            and abs(float(grad[r] @ u)) <= tiny
        ]

    def _stopped_pressed(self, step, t_k, q, p, v, group, targets, plastic, pulled, counts, state) -> None:
        """Rows of an impact while held that the incoming velocity does not press in (``pulled``: ``{r: (rate,
        e)}``, ``d2 psi_r/dt2 >= 0`` at ``qdot-``), read again at the velocity the impulse law leaves with
        their targets 0 (a plastic impact on them, Coulomb's cone as they land): those that settle there
        (:meth:`_settles`) are plastic, moved from ``targets`` to ``plastic`` (MATH.md *Entry*; free flight's
        ``ImpactSteps._jump`` reads a free impact the same way). A double pendulum in maximal coordinates (its
        rods held) whose tip swings down onto the floor at ``e = 0``: the tip's normal speed along the rods'
        circles pulls it up at the impact, gravity presses it in once stopped; read at the incoming velocity
        alone, the tip was stopped but not held and sank again at once, a second (plastic) impact of 2e-8
        after it. The trial is taken from the law's counters and state before it (``counts``, ``state``).

        Rows that still do not settle are read a second time with the held rows the trial law pulls off let go
        (:meth:`_let_go`), where those leave with them held. A box rocking on a vibrating plate at ``e = 0``
        (``ROCKER`` of ``tests/test_box_on_a_vibrating_plate.py``): its landing corner, read with the pivot
        held, was not pressed in; stopped (logged ``"restitution"``), the pivot pulled off and let go, it sank
        again at once, a second (``"plastic"``) impact of impulse 4e-17 at the same instant."""
        trial = {r: x for r, x in targets.items() if r not in pulled}
        try:
            law = self._impulse_law(step, t_k, q, p, v, group, trial)
        except SolverError:  # no trial law: the targets stand (the law proper raises, if it must)
            return
        finally:
            self.least_splits, self.friction_dropped = counts
            self._set_law_state(state)
        vel_p, dropped = law[3], law[4]
        acc = self._held_accel(q, vel_p, (), ())
        settle = [r for r, (rate, e) in pulled.items() if self._settles(rate, float(acc[r]), e, self._h)]
        rest = [r for r in pulled if r not in settle]
        leaving = self._leaving(dropped, group)
        if rest and leaving:
            settle += self._let_go(q, vel_p, leaving, plastic + settle, {r: pulled[r] for r in rest})
        for r in settle:
            plastic.append(r)
            del targets[r]

    def _leaving(self, dropped, group) -> list[int]:
        """The active rows an impact's law pulls off (``dropped``), not of its ``group`` (C ``leaving``)."""
        return [r for r in dropped if self.act[r] and r not in group]

    def _let_go(self, q, vel_p, leaving, plastic, rest) -> list[int]:
        """Of the stopped rows ``rest`` (``{r: (rate, e)}``) of :meth:`_stopped_pressed`, those that settle
        under the rows held once the active rows its trial law pulls off (``leaving``) are let go, where each
        of those then leaves: at a normal speed above the resolution of its pull-back under the rows held
        after, ``plastic`` and these (:meth:`_settles` with ``e = 1``, as :meth:`_chain_impact` releases it).
        Else none."""
        acc = self._held_accel(q, vel_p, leaving, ())
        more = [r for r, (rate, e) in rest.items() if self._settles(rate, float(acc[r]), e, self._h)]
        if not more:
            return []
        after = self._held_accel(q, vel_p, leaving, plastic + more)
        grad = self.k.rows(q, vel_p)[1]
        stays = any(self._settles(float(grad[r] @ vel_p), float(after[r]), 1.0, self._h) for r in leaving)
        return [] if stays else more

    def _held_limit(self, step, t_k, q, p, v):
        """An event within the chain's least sub-step (``1e-13 h``) is at the segment's start, with no
        sub-step taken. Where an impact at this instant left held rows moving (one pulled off below the
        resolution stays held, :meth:`_chain_impact`), the start is the limit of that sub-step as its length
        goes to 0: ``rattle_project`` at ``q``, the held rows' rates made 0 by impulses ``Lam'``. Returns
        ``(Lam', p', u')``, or ``None`` where no held row moves (rates below ``1e-12 (1 + |u|)``: ``p`` as it
        is). A sub-step of 1.8e-13 h on C (rough tumbling box drop 138) made that projection where CasADi's,
        within 1e-13 h, did not: the impact after took 0.0128 on C and 0 on CasADi, and the runs parted by
        8.4e-5. The projection is a move the tangent has no derivative of (``"held rows projected at an
        event's start"``)."""
        k = self.k
        u = self._velocity(q, v, p)
        grad = k.rows(q, u)[1]
        if not np.any(np.abs(grad[self.act] @ u) > 1e-12 * (1.0 + float(np.max(np.abs(u))))):
            return None
        y, res = k.solve("rattle_project", np.concatenate([u, np.zeros(k.r)]), q, p, self.act.astype(float))
        self._check(res, p, step, t_k, "sustained")
        lam1 = np.where(self.act, y[k.n :], 0.0)
        self._sw_lose("held rows projected at an event's start")
        return lam1, p + self._dirs(k.rows(q, y[: k.n])[1]).T @ lam1, y[: k.n]

    def _law_raises(self, q, law) -> bool:
        """Does the impulse law's result ``law`` (:meth:`_impulse_law`) raise the kinetic energy
        (:func:`vcigen.impulse_law.law_gains`, on the rows at ``q`` as the law left their branches)?"""
        return law_gains(self.k.rows(q, law[2])[1], law[1], law[2], law[3])

    def _reduced_restitution(self, step, t_k, q, p, v, group, targets, plastic, counts, state):
        """An impact whose Newton's restitution with Coulomb's friction raises the kinetic energy (a body
        rocking onto a second vertex beside a held one; MATH.md *Friction*: energy never rises), or has no
        solution (a box wedged in a V, a corner landing at ``e > 0`` beside two held: its law is solvable only
        plastic, ``bench.box_v_drops --seed 21`` drop 169): the largest
        fraction ``s`` of its targets whose law does not, by ``RESTITUTION_BISECTIONS`` bisections of ``[0,
        1]`` (counted, ``res.stats["restitution_reduced"]``; README, Known limits: Friction); ``s = 0`` is the
        plastic law, which cannot raise it, and holds the rows it stopped. ``counts``: the law's counters
        before it, ``state`` its :meth:`_law_state` (each trial is taken from them). Returns ``(law, targets,
        plastic)``."""
        self.restitution_reduced += 1
        lo, hi = 0.0, 1.0
        for _ in range(RESTITUTION_BISECTIONS):
            mid = 0.5 * (lo + hi)
            self.least_splits, self.friction_dropped = counts
            self._set_law_state(state)  # a trial's cut rider (_impulse_law) is not kept
            try:
                trial = self._impulse_law(step, t_k, q, p, v, group, {r: mid * x for r, x in targets.items()})
                lo, hi = (lo, mid) if self._law_raises(q, trial) else (mid, hi)
            except SolverError:
                hi = mid
        self.least_splits, self.friction_dropped = counts
        self._set_law_state(state)
        scaled = {r: lo * x for r, x in targets.items()} if lo > 0.0 else {}
        law = self._impulse_law(step, t_k, q, p, v, group, scaled)
        if not scaled:  # plastic: held, those it stopped
            plastic = [r for r in group if r in plastic or law[1][r] > 0.0]
        return law, scaled, plastic

    def _hold(self, grad, r: int) -> None:
        """Holds contact row ``r`` unless its gradient is in the span of the normal rows held (a box's fourth
        vertex landing on its face, statically indeterminate: held, the rows would be dependent): it then
        rides at ``phi = 0`` by the others, not held, with no force (a lift-off of one held passes the load
        to it where it is on the other side, ``SustainedSteps._pass_load``)."""
        if not self._dependent(grad, r, sticks=False):
            self.act[r] = True

    def _rides_after(self, grad, r: int, off, on, sticks: bool = False) -> bool:
        """Is row ``r``'s gradient in the span of the normal rows held after an impact (the active ones but
        ``off``, and ``on``; in row order; with ``sticks`` their stick rows too)? An active row the impact
        pulls off is then carried by them (its normal speed and ``d2 psi/dt2`` are theirs, 0 to round-off,
        whose sign would decide its settle test): it stays held, and a row landing dependent on it rides
        instead (:meth:`_hold`; a box's four vertices on a face). Its force, checked next, may pass its load
        on (``SustainedSteps._pass_load``)."""
        stick = self.k.row_stick
        rows = [
            i
            for i in range(self.k.r)
            if i != r
            and (self.act[i] and i not in off or i in on)
            and (sticks or not (stick and stick[i] >= 0))
        ]
        return in_span(grad, rows, r)

    def _landed(self, lands, slipped, plastic, off) -> list[int]:
        """The stick rows of the contacts that landed and stuck in the impulse law (``lands``,
        :meth:`_law_lands`: their owner's stick row not in ``slipped``) and are held after it (a row of theirs
        in ``plastic``): they stick from there on (``_friction_modes``). One carried by another's stick row
        takes its own where that contact is no longer held (its rows in ``off``: a rocking block's pivot)."""
        k = self.k
        held = {k.row_contact[r] for r in plastic}
        held |= {k.row_contact[r] for r in np.flatnonzero(self.act) if r not in off}
        out = []
        for f, o in lands.items():
            rows = [self._stick_rows[x] for x in (o, self._partner[o]) if x >= 0]
            if k.frictional[f] not in held or set(rows) & set(slipped):
                continue
            if o == f:
                out += rows
            elif k.frictional[o] not in held:
                out.append(self._stick_rows[f])
        return out

    def _held_accel(self, q, u, off, on) -> np.ndarray:
        """Every row's ``d2 psi/dt2`` at ``(q, u)`` under the forces of the rows held after an impact (the
        active ones but ``off``, and ``on``): how a row the impact pulls off is pulled back (a held row's own
        force would cancel it). Of rows that are dependent, those independent of the rows before them in row
        order (:func:`span_add`): the rows' accelerations are unique, their forces are not. A rough cube
        landing on an edge with both its vertices' cones stuck (their tangents along the edge coincide) gave
        an LU of the singular Delassus matrix forces of 1e13 and the far vertices a free fall (-9.81 for
        3 g / 4: held where C let them go; ``BOOKED_DROPS``, stop 44)."""
        k = self.k
        act = self.act.copy()
        self.act[list(off)] = False
        self.act[list(on)] = True
        held = {k.row_contact[r] for r in np.flatnonzero(self.act) if k.row_contact[r] >= 0}
        for r in np.flatnonzero(self.act):  # a contact no longer held keeps no stick row
            if k.row_stick and k.row_stick[r] >= 0 and k.frictional[k.row_stick[r]] not in held:
                self.act[r] = False
        basis: list = []  # a row in the span of the rows before it is left out: the rows' accelerations stay
        grad = k.rows(q, u)[1]
        for r in np.flatnonzero(self.act):
            if not span_add(basis, grad[r]):
                self.act[r] = False
        try:
            lam = self._contact_forces(q, u)
        except np.linalg.LinAlgError:  # dependent rows: no forces (C: <model>_forces_to's failed LU)
            lam = np.zeros(k.r)
        finally:
            self.act[:] = act
        return self._row_accel(q, u, self._accel(q, u, lam))

    def _rough(self, group) -> bool:
        """Does an impact on the contacts ``group`` of the free chain take the impulse law with Coulomb's cone
        (:meth:`_rough_rest`): sustained contact on (``Tolerances(grazing="contact")``) and one of them
        frictional? The jump (48) along the normal cone (86) has no friction for several contacts."""
        k = self.k
        rough = {k.frictional[f] for f in range(len(self._stick_rows)) if self._mu_f[f] > 0.0}
        return self.tol.grazing == "contact" and bool(rough & set(group))

    def _kinked(self, q, v, p, j: int) -> bool:
        """Does an impact of the free chain on contact ``j`` meet it at a kink whose touching rows
        (:meth:`_touching`) move at different normal speeds, one of them in (a square flat on a face and
        spinning: one vertex goes in, the other out)? The normal cone's centre (86) sees their mean speed, and
        the jump (48) along it a wrong impact (none, or a plastic one); the impulse law on the rows
        (:meth:`_rough_rest`) takes each vertex's Newton's law. Rows at one speed (a square dropped flat)
        keep (86)."""
        k = self.k
        if self.tol.grazing != "contact" or sum(c == j for c in k.row_contact) < 2:
            return False
        rows = self._touching(q, v, [j])[0]
        if len(rows) < 2:
            return False
        vel = self._velocity(q, v, p)
        rates = k.rows(q, vel)[1][rows] @ vel
        spread = float(rates.max() - rates.min())
        return bool(rates.min() < 0.0 and spread > 1e-9 * (1.0 + float(np.abs(rates).max())))

    def _rough_rest(self, step, t_k, h, q, p, t, tau, v, rows, impacts, e_before, e_step):
        """An impact of the free chain on several contacts at once, one with friction (:meth:`_rough`), or on
        a kink's rows moving apart (:meth:`_kinked`), as an impact while held with none held
        (:meth:`_chain_impact`: Newton's law with each contact's restitution, Coulomb's cone on the frictional
        ones as they land, the rows that settle held), then the rest of the step from it (:meth:`_chain`:
        held, or free). The tangent broke at the contact (``"simultaneous impact"``, ``Tracker.contact``; at
        a kink, here); the impact itself runs without the events' tangent, as C's (its ``hold`` is set after
        ``<model>_chain_impact``), so that it books no more breaks. Its rows count in the step's bounces as a
        held chain's do (:meth:`_chain_impact`: ``BOUNCE_CYCLES`` in the step, the next settles). A rough hoop
        starting on the floor, its free path leaving at second order and back at third within the step, met
        the floor again at t = 0 through the free rest after each such impact, holding nothing, 64 times
        (``bench.hoop_drops --seed 321``, drop 32)."""
        tan, self._ev_tan = self._ev_tan, None
        try:
            p = self._chain_impact(step, t_k, h, q, p, v, t, rows, impacts, e_before)
        finally:
            self._ev_tan = tan
        return self._chain(step, t_k, h, q, p, t, tau, self._velocity(q, v, p), impacts, e_step)

    def _touching(self, q, v, group_contacts) -> tuple[list[int], list[int]]:
        """The rows of the contacts ``group_contacts`` at ``q`` that touch: each contact's lowest row and
        those within ``Tolerances.admissible`` of it (another branch at a kink); ``(rows, lowest)``."""
        k = self.k
        psi = k.rows(q, v)[0]
        rows, lowest = [], []
        for j in group_contacts:
            own = [r for r in range(k.r) if k.row_contact[r] == j]
            lowest.append(min(own, key=lambda r: (psi[r], r)))
            rows += [r for r in own if psi[r] <= psi[lowest[-1]] + self.tol.admissible]
        return rows, lowest

    def _plastic_entry(self, step, t_k, h, q, p, v, t, group_contacts):
        """Plastic impact on contacts ``group_contacts`` at ``q``: their touching rows become active.
        Coulomb's cone acts on the frictional ones (:meth:`_law_lands`). Returns ``(p+, Lam, loss, rows,
        law)``, ``law`` the tangent's (:meth:`_law_tangent`: its rows in the order of ``rows``, then the stick
        rows)."""
        k = self.k
        rows, lowest = self._touching(q, v, group_contacts)
        # no row is held here (the free impact chain runs with none): friction only where they land
        p_plus, lam, vel_m, vel_p, dropped, slipped, _, lands, law_why = self._impulse_law(
            step, t_k, q, p, v, rows, {}
        )
        tight, slides, why = self._law_tangent(lam, slipped, (), lands, law_why)
        order = [tight.index(r) for r in rows if r in tight]
        order += [i for i, r in enumerate(tight) if r not in rows]
        law = ([tight[i] for i in order], [slides[i] for i in order], why)
        grad = k.rows(q, v)[1]
        for r in rows:  # the touching row of each contact is held; another branch at a kink if it presses
            self.act[r] = False
            if r in lowest or r not in dropped:
                self._hold(grad, r)
        mass = k.legendre(q, vel_m)[1]
        loss = 0.5 * (vel_m @ mass @ vel_m - vel_p @ mass @ vel_p)
        return p_plus, lam, loss, rows, law

    def _log(self, impacts, t, j, q, alpha, impulse, step, e_before, e_after, kind) -> None:
        self.kinds[kind] += 1
        impacts.append(
            Impact(
                t=float(t),
                contact=self.k.contact_names[j],
                q=np.array(q, dtype=float),
                alpha=float(alpha),
                impulse=float(impulse),
                step=step,
                energy_before=float(e_before),
                energy_after=float(e_after),
                kind=kind,
            )
        )
