"""The held step's hooks into the tangent (:class:`vcigen.sensitivity.Tracker`), for
:class:`vcigen.sustained.SustainedSteps`: the tangent through the events inside a held step (a lift-off, a row
crossed, the impact chain of its free rest; ``Tracker.event``, ``impulse``, ``free_end``) and the friction
switches it carries as located events (:mod:`vcigen.sensitivity_switch`) or breaks at. They read the
stepper's state (``_ev_tan``, the friction mode); C: ``templates/sens_*.c.j2``."""

from __future__ import annotations


class HeldTangent:
    """The tangent's hooks of a held step (a base of :class:`vcigen.sustained.SustainedSteps`)."""

    # -- the tangent through events inside a held step (vcigen.sensitivity.Tracker.event) -----------------
    def _events_tangent(self, tan):
        """The tangent a held step's events are carried by (``Stepper._tangent_held``): frictionless or with
        Coulomb friction (isotropic cones but under forces of time: ``Tracker._cone_slots`` holds the time
        fixed), under any rule (internal points are held in each constrained sub-step,
        ``Tracker._held_sub``); else None (the step breaks as before). A friction switch in it is a located
        event if :meth:`_sw_covered`, else a break (:meth:`_sw_lose`); cones aimed implicitly (``_braked``)
        break."""
        cones = any(g >= 0 for g in self._partner) if self._stick_rows else False
        return tan if tan is not None and not (cones and self._timed) else None

    def _friction_state(self) -> tuple:
        """The friction mode as arrays (:meth:`_no_switch`): stick rows held, slips, references, branch signs,
        dependent sticks, each contact's held rows."""
        return (
            self.act.copy(),
            self._slip.copy(),
            self._ref.copy(),
            self._branch.copy(),
            list(self._ride),
            list(self._held_rows),
        )

    def _no_switch(self, before: tuple) -> bool:
        """Whether the friction mode changed from ``before`` (:meth:`_friction_state`) only by frictional
        contacts let go (no row of theirs held any more: their friction ends with their normal force) or held
        anew (slipping or sticking from the impact that put them in contact), each at an event whose time the
        tangent has. Anything else (stick <-> slip, the sliding turned, a contact on another face) is a
        switch. A slipping cone's direction is aimed anew at every segment's start, within the mode: its slips
        count as 1 (:meth:`_mode_slips`)."""
        act, slip, ref, branch, ride, held = before
        slip, slip_now = self._mode_slips(slip), self._mode_slips(self._slip)
        for f, sr in enumerate(self._stick_rows):
            if not self._held_rows[f] or not held[f]:
                continue  # let go, or held anew
            now = (self._held_rows[f], self.act[sr], slip_now[f], self._ref[f], self._ride[f])
            if (held[f], act[sr], slip[f], ref[f], ride[f]) != now:
                return False
            if any(branch[b] != self._branch[b] for b in self._branch_of[f]):
                return False
        return True

    def _ev_event(self, sub, r: int, s: float, tau: float, kind: str) -> None:
        """A constrained sub-step to an event of row ``r`` (``"lift"``, ``"cross"``, a friction switch
        ``"stop"`` or ``"slide"``): ``Tracker.event``."""
        if self._ev_tan is not None and not self._sw_covered(kind, r):
            return
        if self._ev_tan is not None:
            self._ev_tan.events_begin(self._ev_entry)
            self._ev_tan.event(sub, r, s, tau, kind)
            self._ev_carried = True

    def _ev_rest_end(self, q, p, guess) -> None:
        """Events carried and nothing left of the step after them (the last within the least sub-step of its
        end: a block's stop on a grid point): ``Tracker.rest_end`` with the state's velocity and ``M qddot``
        of the mode it ends in, ``rhs + D^T lambda`` (:meth:`_contact_forces`). Forces of time: a break, as
        before (their slots move with the time)."""
        if self._ev_tan is None or not self._ev_carried or self._ev_done or self._timed:
            return
        k = self.k
        u = self._velocity(q, guess, p)
        lam = self._contact_forces(q, u)
        force = k.dynamics(q, u)[0] + self._dirs(k.rows(q, u)[1]).T @ lam
        self._ev_tan.rest_end(q, u, force)
        self._ev_done = True

    # -- a friction switch inside a held step (vcigen.sensitivity_switch): a located event ----------------
    def _sw_covered(self, kind: str, r: int = -1) -> bool:
        """Whether the tangent carries an event of ``kind`` (of row ``r``) in the current friction mode: a
        lift-off or a row crossed in any mode (``Tracker.event``: the sub-step's friction slots, the slipping
        contacts' directions); without isotropic cones a slipping contact's stop and a lone sticking contact's
        slide (no contact slipping, no dependent stick: the force law of the stick row alone); with them a
        slipping cone's stop (its root along its slip, ``SwitchTangents._switch_root``) where no stick is
        dependent. Else the step breaks here (``"friction switch in a held step"``)."""
        if kind in ("lift", "cross"):
            return True
        if not any(g >= 0 for g in self._partner):  # no cone: one-tangent switches (SwitchTangents)
            if kind == "stop" or (not self._slip.any() and all(o < 0 for o in self._ride)):
                return True
        elif kind == "stop" and r >= 0 and self._partner[self.k.row_stick[r]] >= 0:
            if all(o < 0 for o in self._ride):
                return True
        self._sw_lose()
        return False

    def _sw_lose(self, why: str = "friction switch in a held step") -> None:
        """A friction switch the tangent of a held step's events does not carry (stick <-> slip at a
        segment's start or not of one contact alone, the sliding direction turned, a contact set on another
        face, a cone's stop or slide): a mode change, no derivative; the step breaks with ``"friction switch
        in a held step"`` (the later hooks find the tangent lost). ``why``: another reason (``"friction at an
        impact"``: a slipping contact's sliding impulse at an impact while held, :meth:`_chain_impact`)."""
        if self._ev_tan is not None:
            self._ev_tan.lose(why)
            self._ev_done = True

    def _sw_state(self) -> tuple:
        """The rows held, slips and dependent sticks before a located switch (:meth:`_sw_check`)."""
        return self.act.copy(), self._slip.copy(), list(self._ride)

    def _sw_check(self, kind: str, sr: int, before: tuple) -> None:
        """After a located switch of stick row ``sr`` (:meth:`_friction_switch`): carried if it switched that
        contact alone, into a stick on its own row (``"stop"``) or a slip (``"slide"``); else (the sliding
        turned by an impact, a dependent stick, others switched with it) the step breaks. With isotropic cones
        a cone's stop, into a stick on both its rows (:meth:`_sw_covered`); any other switch broke already."""
        f = self.k.row_stick[sr]
        own = [f] if self._partner[f] < 0 else [f, self._partner[f]]
        if any(g >= 0 for g in self._partner) and (kind != "stop" or len(own) == 1):
            return
        act, slip, ride = before
        rows = {self._stick_rows[g] for g in own}
        others = [g for g in range(len(self._stick_rows)) if g not in own]
        same = all(slip[g] == self._slip[g] and ride[g] == self._ride[g] for g in others)
        same = same and all(act[x] == self.act[x] for x in range(self.k.r) if x not in rows)
        if kind == "stop":
            ok = all(self.act[self._stick_rows[g]] and not self._slip[g] and self._ride[g] < 0 for g in own)
        else:
            ok = not self.act[sr] and self._slip[f] != 0.0
        if not (ok and same):
            self._sw_lose()
        elif kind == "stop" and self._ev_tan is not None and len(own) == 1:  # a slide back at once (_sw_back)
            self._sw_stop = (self._ev_tan.step, self._events)

    def _sw_back(self, kind: str) -> bool:
        """A slide at the start of a segment right after a carried stop, no event between (a body stopped on a
        slope steeper than its friction angle slides back at once): its time is the stop's, whose tangent the
        events' tangent has, and the rest of the step slips from there (its slot by ``_friction_slots``)."""
        tan = self._ev_tan
        return kind == "slide" and tan is not None and self._sw_stop == (tan.step, self._events)

    def _ev_impulse(self, q, v, p, lam, targets, group, law) -> None:
        """The impulse law of an impact while held (:meth:`_chain_impact`): ``Tracker.impulse`` on its rows
        with an impulse (``law``, :meth:`_law_tangent`), each with the contact whose restitution sets its
        target (-1: target 0), the normal rows of the contacts slipping on or landing and sliding through it
        with their sliding impulse along their owner's stick row (whose own impulse follows from theirs: not
        a row of the law); a group of rows hit at once (the weights of its impulse switch) breaks."""
        tan = self._ev_tan
        if tan is None:
            return
        if len(group) > 1:
            tan.lose("simultaneous impact")
            return
        k = self.k
        tight, slides, _ = law
        contact = [k.row_contact[r] if r in targets else -1 for r in tight]
        tan.impulse(q, v, p, tight, contact, slides)

    def _ev_free(self, q, p, w, tau: float) -> None:
        """The free rest after a held step's events (``Tracker.free_end``); a lone lift-off before it is
        ``Tracker.liftoff``'s (``_lift_seg``)."""
        if self._ev_tan is not None and self._lift_seg is None:
            self._ev_tan.events_begin(self._ev_entry)
            self._ev_tan.free_end(q, p, w, tau)
            self._ev_done = True

    def _ev_impacts(self, step, t_k, h, seg, crossings, impacts, e_step):
        """The impact chain (47)-(79) of a held step's free rest (``Stepper._impact_step``). With the tangent
        of its events (a pending lone lift-off is one first) the free impact hooks (``Tracker.contact``,
        ``jump``, ``jump_end``; a plastic impact's own held rest) carry it from the segment's tangents: the
        step is covered as far as they cover it."""
        tan = self._ev_tan
        if tan is None:
            return self._impact_step(step, t_k, h, seg, crossings, impacts, e_step)
        if self._lift_seg is not None:
            self._ev_event(*self._lift_seg, "lift")
            self._lift_seg = None
        tan.events_begin(self._ev_entry)
        entry, self._tan = self._ev_entry, tan
        try:
            return self._impact_step(step, t_k, h, seg, crossings, impacts, e_step)
        finally:  # a plastic impact in it ran its own held rest (Stepper._tangent_held): the flags back
            self._tan, self._ev_tan, self._ev_entry, self._record_held = None, tan, entry, True
            self._held_seg = self._lift_seg = self._free_seg = None
            self._ev_done = True
