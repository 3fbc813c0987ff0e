"""Coulomb friction in sustained contact (MATH.md *Friction*, the paper's (38)-(39)), for
:class:`vcigen.sustained.SustainedSteps`: each frictional contact's mode in a held step (stick: its stick
row held; slip: the slot ``-mu_f s`` of ``par``), dependent sticks, isotropic cones (their sliding
direction aimed at each segment's start, braked near rest, split when a joint slides), and the friction
events that end a constrained segment (a stop, a slide). :class:`FrictionModes` reads the stepper's state
(``k``, ``act``, ``_slip``, ...)."""

from __future__ import annotations

import math

import numpy as np

from .cone_split import line_turns, null_combination, split, split_line
from .coupling import coupled_cones
from .derive import KINK
from .held_roots import (
    BRAKE,
    DEP_EPS,
    EPS_LAM,
    EPS_LIFT,
    LIFT_ITER,
    SLIDE_EPS,
    SLIDE_LEAVE,
    End,
    illinois,
    in_span,
)


class FrictionModes:
    """The friction modes of the held rows (a base of :class:`vcigen.sustained.SustainedSteps`)."""

    def _dirs(self, grad: np.ndarray) -> np.ndarray:
        """The force direction of each row: ``grad psi_r``, plus ``slip_f grad tangent_f`` on the rows of a
        slipping frictional contact ``f`` (the same as the derived ``rattle``)."""
        if not self._slip.any():
            return grad
        out = grad.copy()
        for f, j in enumerate(self.k.frictional):
            if self._slip[f]:
                rows = [r for r in range(self.k.r) if self.k.row_contact[r] == j]
                out[rows] += self._slip[f] * grad[self._stick_rows[f]]
        return out

    def _set_friction(self) -> None:
        if self._stick_rows:
            self.k.set_friction(self._slip, self._ref, self._branch)

    def _friction_modes(self, q, u, tau: float | None = None) -> None:
        """Stick or slip for each frictional contact at ``(q, u)``: off when it is not held; on entering
        sustained contact it sticks if its sliding velocity is 0 (to round-off), else slips against it.
        A dependent stick (:meth:`_stick`) is checked anew: released if its contact's rows changed or its
        stick row is independent now. A held stick row that a row held since has made dependent rides from
        here (:meth:`_owner`), as one that stuck dependent: a particle sticking on one wall of a V-groove
        meets the other at the vertex, whose normal row is in the span of the first wall's two rows, and the
        held step's rows were dependent (``bench.groove_drops``: 133 of 200 drops raised). A contact slipping
        at a sliding of 0 (to round-off) whose stick row depends on the active rows stops (:meth:`_stick`: it
        rides): its sliding is theirs, 0 over the segment, and no stop event sees it change sign (pyramid draw
        1 of ``bench.pyramids --seed 2``: the second lower disk, held to the first, stuck, by the row between
        them after an impact, slipped on at rest in C, its kinetic friction pressing the disks together, and
        stopped on CasADi, by round-off). Cones (two tangents) by :meth:`_cone_modes`, aiming their slip for a
        segment of ``tau``."""
        k = self.k
        if not self._stick_rows:
            return
        for f, j in enumerate(k.frictional):
            sr = self._stick_rows[f]
            mask = sum(1 << r for r in range(k.r) if self.act[r] and k.row_contact[r] == j)
            if not mask or self._mu_f[f] <= 0.0 or mask != self._held_rows[f]:
                self.act[sr], self._slip[f], self._ride[f] = False, 0.0, -1  # off, or another vertex or face
            self._held_rows[f] = mask
        grad = k.rows(q, u)[1]
        for f, sr in enumerate(self._stick_rows):
            if self.act[sr] and self._dependent(grad, sr):  # a row held since is in its span: it rides
                self._ride[f] = self._owner(f, grad)
                self.act[sr] = False
        for f in range(len(self._stick_rows)):
            if self._ride[f] >= 0:
                self._ride[f] = self._owner(f, grad)
        for f in range(len(self._stick_rows)):
            sr = self._stick_rows[f]
            if self._partner[f] >= 0 or self._ride[f] >= 0:
                continue  # a cone: both tangents at once, below; a dependent stick: held by another's row
            if self._held_rows[f] and self._mu_f[f] > 0.0 and not self.act[sr] and self._slip[f] == 0.0:
                self._freeze_branch(f, q)
                sliding = float(k.rows(q, u)[1][sr] @ u)
                if abs(sliding) <= SLIDE_EPS * (1.0 + float(np.max(np.abs(u)))) or self._jammed:
                    self._stick(f, q, u)
                else:
                    self._slip[f] = -self._mu_f[f] * math.copysign(1.0, sliding)
            elif self._slip[f] and abs(float(grad[sr] @ u)) <= SLIDE_EPS * (1.0 + float(np.max(np.abs(u)))):
                # slipping at a sliding of 0 (its tangent frozen when it began to slip: grad's row is its
                # own); where the rows held carry that tangent (the rows anew: branches frozen above) it stops
                if self._owner(f, k.rows(q, u)[1]) >= 0:
                    self._stick(f, q, u)
        self._cone_modes(q, u, tau)
        self._set_friction()

    def _friction_mode(self) -> tuple:
        """The friction mode: the rows held, the slots (slips, references, branches) and dependent sticks; a
        slipping cone's slips as 1 (its direction is aimed anew every segment, within the mode)."""
        slots = (*self._mode_slips(self._slip).tolist(), *self._ref.tolist(), *self._branch.tolist())
        return (*self.act.tolist(), *slots, *self._ride)

    def _mode_slips(self, slip: np.ndarray) -> np.ndarray:
        """The slips ``slip`` as the friction mode reads them: a slipping cone's as 1 (C ``mode_slip``)."""
        slip = slip.copy()
        for f, p in self._cones():
            if slip[f] or slip[p]:
                slip[[f, p]] = 1.0
        return slip

    def _friction_acts(self) -> bool:
        """Whether a frictional contact slips or holds its stick row."""
        return bool(self._slip.any() or any(self.act[sr] for sr in self._stick_rows))

    # -- dependent sticks: two contacts of one body sticking at once (statically indeterminate) -----------
    def _dependent(self, grad, sr: int, skip: int = -1, sticks: bool = True) -> bool:
        """Is row ``sr``'s gradient in the span of the other active rows' (but row ``skip``; the normal rows
        alone if not ``sticks``)?

        Modified Gram-Schmidt over the active rows in index order (a row within ``DEP_EPS`` of the span so far
        adds nothing), then ``sr``'s residual against that basis, relative to its length."""
        stick = self.k.row_stick
        rows = [r for r in np.flatnonzero(self.act) if r not in (sr, skip)]
        return in_span(grad, [r for r in rows if sticks or not (stick and stick[r] >= 0)], sr)

    def _owner(self, f: int, grad) -> int:
        """Whose stick holds frictional contact ``f``'s tangent: ``-1`` if its stick row is independent of
        the active rows; else the first sticking contact ``g`` without whose stick row it is independent
        (``f`` itself if the other rows hold it alone). A cone's row too (:meth:`_cone_split`)."""
        sr = self._stick_rows[f]
        if not self._dependent(grad, sr):
            return -1
        for g, sg in enumerate(self._stick_rows):
            if g != f and self.act[sg] and not self._dependent(grad, sr, sg):
                return g
        return f

    # -- isotropic cones: a contact with two tangents, frictional contacts f and its partner ----------------
    def _cones(self):
        """``(f, partner)`` of each cone contact, ``f`` its first tangent."""
        return [(f, p) for f, p in enumerate(self._partner) if p > f]

    def _sliding(self, f: int, p: int, grad, u) -> np.ndarray:
        """The sliding velocity of cone ``(f, p)``: both tangents' rates ``grad tangent . u``."""
        return np.array([float(grad[self._stick_rows[f]] @ u), float(grad[self._stick_rows[p]] @ u)])

    def _cone_modes(self, q, u, tau: float | None) -> None:
        """Stick or slip of each cone contact at ``(q, u)``, as :meth:`_friction_modes` for one tangent: on
        entering sustained contact it sticks if its sliding velocity is 0 (to round-off), else slips with the
        force ``-mu_f lambda s`` along the sliding direction ``s``. The slipping cones' ``s`` are aimed anew
        at the start of every segment, all at once (:meth:`_cone_aim`), and frozen over it."""
        k = self.k
        aimed = []
        for f, p in self._cones():
            if not self._held_rows[f] or self._mu_f[f] <= 0.0:
                continue
            held = [bool(self.act[self._stick_rows[x]]) or self._ride[x] >= 0 for x in (f, p)]
            if any(held):  # sticking; a row that no longer depends on the others' is held by its own again
                for x in [x for x, on in zip((f, p), held) if not on]:
                    self._stick(x, q, u)
                continue
            if self._slip[f] == 0.0 and self._slip[p] == 0.0:
                self._freeze_branch(f, q)
                self._freeze_branch(p, q)
                w = self._sliding(f, p, k.rows(q, u)[1], u)
                if math.hypot(*w) <= SLIDE_EPS * (1.0 + float(np.max(np.abs(u)))) or self._jammed:
                    self._stick(f, q, u)
                    self._stick(p, q, u)
                    continue
                self._slip[[f, p]] = -self._mu_f[f] * w / math.hypot(*w)
            aimed.append((f, p))
        if tau is not None and aimed:
            self._cone_aim(aimed, q, u, tau)

    def _cone_aim(self, cones, q, u, tau: float) -> None:
        """The slip direction of each slipping cone ``(f, p)`` in ``cones`` over a segment of ``tau`` from
        ``(q, u)``: the sliding velocity predicted at the segment's midpoint, ``w + tau/2 dw/dt`` (``dw/dt =
        grad tangent . qddot + u . Hess tangent . u`` with the contact forces at the start and the start's
        directions), normalised. Explicit and second order (the direction of the chord of RATTLE's step to
        O(tau^2); exact while the sliding keeps its direction); the start's direction if the prediction turns
        back (a stop in the segment, located by :meth:`_friction_events`) or if ``tau/2 |dw/dt| > |w|`` (near
        rest, breaking away: there the prediction is made by the slip direction itself). Every cone is aimed
        from the same state (the start's directions of all, one evaluation of the contact forces), so that the
        aim of two cones of one body does not depend on their order. When two or more cones slide slower than
        ``BRAKE tau`` times the rate friction alone changes their sliding (``mu_f N`` times the mean of
        ``grad t M^-1 grad t^T``) and are linked to each other (one body, a constraint:
        :func:`vcigen.coupling.coupled_cones`) they are aimed implicitly together (:meth:`_cone_brake`): there
        the explicit aim made a body's relative modes (the yaw of a rod on two cones) unstable. Not where more
        than one of their stick rows would ride (a box on three cones): the best split of
        :meth:`_cone_split` is one dependence's, and its forces aimed a cone across its sliding."""
        k = self.k
        _, grad, curv = k.rows(q, u)
        tiny = SLIDE_EPS * (1.0 + float(np.max(np.abs(u))))
        for f, p in cones:
            w = self._sliding(f, p, grad, u)
            if math.hypot(*w) > tiny:
                self._slip[[f, p]] = -self._mu_f[f] * w / math.hypot(*w)
        self._set_friction()
        forces = self._contact_forces(q, u)
        acc = self._accel(q, u, forces)
        mass = k.legendre(q, u)[1]
        aims, slow = [], []
        for f, p in cones:
            w = self._sliding(f, p, grad, u)
            sf, sp_ = self._stick_rows[f], self._stick_rows[p]
            turn = 0.5 * tau * np.array([grad[sf] @ acc + curv[sf], grad[sp_] @ acc + curv[sp_]])
            mid = w + turn
            norm = math.hypot(*mid)
            # the rate friction alone changes w by: mu_f N times the cone's mean inverse mass
            g2 = grad[[sf, sp_]]
            normal = sum(forces[r] for r in range(k.r) if k.row_contact[r] == k.frictional[f])
            brake = self._mu_f[f] * normal * 0.5 * float(np.trace(g2 @ np.linalg.solve(mass, g2.T)))
            aim = norm > tiny and float(mid @ self._slip[[f, p]]) < 0.0  # along -slip: the way it slides
            if aim and math.hypot(*turn) <= math.hypot(*w):  # a correction of w, not made by the friction
                aims.append((f, p, -self._mu_f[f] * mid / norm))
            if math.hypot(*w) <= BRAKE * tau * brake:
                slow.append((f, p))
        if len(slow) >= 2:  # only cones linked to another (one body, a constraint): vcigen.coupling
            rows = [x for f, p in slow for x in (self._stick_rows[f], self._stick_rows[p])]
            g2 = grad[rows + [int(r) for r in np.flatnonzero(self.act)]]
            linked = coupled_cones(g2 @ np.linalg.solve(mass, g2.T), len(slow))
            slow = [cone for cone, on in zip(slow, linked) if on]
        braked = self._cone_brake(slow, q, u, tau) if len(slow) >= 2 else None
        if braked is not None:  # several cones near rest: implicit in the direction
            self._braked = True
            aims = [a for a in aims if (a[0], a[1]) not in slow] + braked
        for f, p, slip in aims:
            self._slip[[f, p]] = slip
        self._set_friction()

    def _cone_brake(self, cones, q, u, tau: float):
        """Slip directions of ``cones`` near rest (``tau/2 |dw/dt| > |w|``): along the tangential forces that
        would bring their sliding to rest at the segment's midpoint, their stick rows held together with the
        active rows (a row dependent on them rides, the split of the forces the best one,
        :meth:`_cone_split`) at the velocity target ``d(grad tangent . u)/dt = -2 w / tau``. For a point (an
        isotropic mass) that is the direction of ``w + tau/2 dw/dt`` with Coulomb's force along it, solved
        for: implicit in the direction, where the explicit aim made the relative modes of two cones of one
        body (the rod's yaw) unstable. ``[(f, p, slip)]``, none for a cone with no force; None (nothing
        changed) where more than one of their stick rows rides (:meth:`_cone_aim`: the explicit aim stays)."""
        k = self.k
        act, slip, ride = self.act.copy(), self._slip.copy(), list(self._ride)
        _, grad, curv = k.rows(q, u)
        for f, p in cones:
            self._slip[[f, p]] = 0.0
        self._set_friction()
        target = curv.copy()
        riding = 0
        for f, p in cones:
            for x in (f, p):
                sr = self._stick_rows[x]
                target[sr] += 2.0 * float(grad[sr] @ u) / tau
                if self._dependent(grad, sr):
                    self._ride[x] = x
                    riding += 1
                else:
                    self.act[sr] = True
        if riding > 1:
            self.act, self._slip, self._ride = act, slip, ride
            self._set_friction()
            return None
        forces = self._forces(End(None, grad, target, k.dynamics(q, u)[0], k.legendre(q, u)[1]))
        out = []
        for f, p in cones:
            lam = np.array([forces[self._stick_rows[f]], forces[self._stick_rows[p]]])
            joint = self._cone_split(f, forces, grad)
            if joint is not None:
                _, alpha, _, coupled, lams, dirs = joint
                i = coupled.index((f, p))
                lam = np.array(lams[i]) + alpha * np.array(dirs[i])
            if math.hypot(*lam) > 0.0:
                out.append((f, p, self._mu_f[f] * lam / math.hypot(*lam)))
        self.act, self._slip, self._ride = act, slip, ride
        self._set_friction()
        return out

    def _cone_stop(self, f: int, p: int, step, t_k, q, p0, tau, v, u1, end, vel0, events) -> None:
        """A slipping cone that stops inside the segment: its sliding velocity along the frozen slip direction
        ``s`` at the segment's end is negative; located along the sub-step map (Illinois) where it is 0.
        Within round-off of 0 there (``SLIDE_EPS``), having slid at the start, it stops at the end (fraction
        1): its sign is round-off's, and the backends parted on it (a box pinned by three rows, at rest by the
        step's end; a block whose stop falls on a grid point)."""
        s = -self._slip[[f, p]] / self._mu_f[f]
        g1 = float(s @ self._sliding(f, p, end.grad, u1))
        tiny = SLIDE_EPS * (1.0 + float(np.max(np.abs(vel0))))
        if g1 > tiny:
            return
        g0 = float(s @ self._sliding(f, p, self.k.rows(q, vel0)[1], vel0))
        if g1 >= -tiny:  # stopped at the end to round-off: there if it slid at the start
            if g0 > tiny:
                events[self._stick_rows[f]] = ("stop", 1.0)
            return

        def along(c, w):
            w, end_c, u_c = self._sub_end(step, t_k, q, p0, tau, c, w)
            return float(s @ self._sliding(f, p, end_c.grad, u_c)), w

        frac = 0.0 if g0 <= 0.0 else illinois(along, g0, g1, 1e-14, 1e-13, LIFT_ITER, v)
        events[self._stick_rows[f]] = ("stop", frac)

    def _cone_switch(self, kind: str, f: int, p: int, q, u) -> None:
        """At a located event of cone ``(f, p)``: a stop sticks both tangents (what sliding is left across
        the frozen direction, O(tau^2), goes with it); a stick force out of the cone slips the way it
        pushes, ``s = -lambda_t / |lambda_t|``."""
        if kind == "stop":
            self._stick(f, q, u)
            self._stick(p, q, u)
            grad = self.k.rows(q, u)[1]
            tiny = SLIDE_EPS * (1.0 + float(np.max(np.abs(u))))
            for c, pc in self._cones():  # another cone of the body stopped at the same instant sticks with it
                if (self._slip[c] or self._slip[pc]) and math.hypot(*self._sliding(c, pc, grad, u)) <= tiny:
                    self._stick(c, q, u)
                    self._stick(pc, q, u)
        elif (joint := self._cone_split(f, self._contact_forces(q, u), self.k.rows(q, u)[1])) is not None:
            self._split_slide(joint, q, u)
        else:
            forces = self._contact_forces(q, u)
            lam = np.array([forces[self._stick_rows[f]], forces[self._stick_rows[p]]])
            self.act[self._stick_rows[f]] = self.act[self._stick_rows[p]] = False
            self._slip[[f, p]] = self._mu_f[f] * lam / max(math.hypot(*lam), 1e-300)
        self._set_friction()

    def _cone_split(self, f: int, forces, grad):
        """The cones coupled with cone ``f`` by a dependent stick row (a cone row riding, :meth:`_stick`) and
        their best split (:func:`vcigen.cone_split.split`): ``(margin, alpha, values, cones, stick forces,
        null combinations)``, the least margin over the riders whose null combination involves ``f``; None
        if none does."""
        f = min(f, self._partner[f])
        rows = self._stick_rows
        best = None
        for g in range(len(rows)):
            if self._partner[g] < 0 or self._ride[g] < 0:
                continue
            n = null_combination(grad, self.act, rows[g])
            cones = [(c, pc) for c, pc in self._cones() if max(abs(n[rows[c]]), abs(n[rows[pc]])) > DEP_EPS]
            if (f, self._partner[f]) not in cones:
                continue
            caps, lams, dirs = [], [], []
            for c, pc in cones:
                j = self.k.frictional[c]
                normal = sum(forces[r] for r in range(self.k.r) if self.k.row_contact[r] == j)
                caps.append(self._mu_f[c] * normal)
                lams.append((float(forces[rows[c]]), float(forces[rows[pc]])))
                dirs.append((float(n[rows[c]]), float(n[rows[pc]])))
            margin, alpha, values = split(caps, lams, dirs)
            if best is None or margin < best[0]:
                best = (margin, alpha, values, cones, lams, dirs)
        return best

    def _stick_split(self, f: int, forces, grad):
        """The contacts coupled with one-tangent contact ``f`` by the dependent sticks it carries (``_ride[g]
        = f``) and their best split along the line of each one's null combination
        (:func:`vcigen.cone_split.split_line`): ``(margin, alpha, values, contacts, stick forces, null
        combinations, null combination over the rows, whether the margin turns at alpha``
        (:func:`vcigen.cone_split.line_turns`; not in a jam)), the least margin over those sticks; None if
        ``f`` carries none or a cone is coupled.
        A contact is coupled where the null combination is on its stick row or its normal rows: one with
        friction keeps its force in its cone with its normal force shifted, ``mu_c (N_c + alpha sum n_r) -
        |F_c + alpha n_t|``; one without keeps ``N_c + alpha sum n_r >= 0``. A part of ``n`` within
        ``DEP_EPS`` of 0 is round-off's, none (a rod level on a floor: 1e-35 on its normal rows, whose cap's
        zero at 1e35 left the bisection far from the split)."""
        k, rows = self.k, self._stick_rows
        best = None
        for g, owner in enumerate(self._ride):
            if owner != f or g == f or self._partner[g] >= 0:
                continue
            n = null_combination(grad, self.act, rows[g])
            contacts, caps, slopes, lams, dirs = [], [], [], [], []
            for j in range(k.m):
                own = [r for r in range(k.r) if k.row_contact[r] == j]
                fr = [c for c, jc in enumerate(k.frictional) if jc == j]
                d = float(n[rows[fr[0]]]) if fr else 0.0
                shift = sum(float(n[r]) for r in own)
                d, shift = (0.0 if abs(x) <= DEP_EPS else x for x in (d, shift))  # round-off's: none
                if d == 0.0 and shift == 0.0:
                    continue
                if fr and self._partner[fr[0]] >= 0:
                    return None  # a cone coupled: pooled (_cone_margin)
                mu_c = self._mu_f[fr[0]] if fr and self._mu_f[fr[0]] > 0.0 else 1.0
                fric = bool(fr) and self._mu_f[fr[0]] > 0.0
                contacts.append(fr[0] if fric else -1)
                caps.append(mu_c * sum(float(forces[r]) for r in own))
                slopes.append(mu_c * shift)
                lams.append(float(forces[rows[fr[0]]]) if fric else 0.0)
                dirs.append(d if fric else 0.0)
            if not caps:
                continue
            margin, alpha, values = split_line(caps, slopes, lams, dirs)
            if best is None or margin < best[0]:
                turns = line_turns(caps, slopes, lams, dirs, alpha)
                best = (margin, alpha, values, contacts, lams, dirs, n, turns)
        return best

    def _owners(self) -> list[int]:
        """The one-tangent contacts that carry another's dependent stick (:meth:`_stick_split`), in order."""
        return sorted({o for g, o in enumerate(self._ride) if o >= 0 and o != g and self._partner[g] < 0})

    def _pressed(self, forces, grad) -> np.ndarray:
        """The held rows' forces ``forces`` as the lift-off test reads them: shifted along the null
        combination of each one-tangent contact's dependent sticks by their best split (:meth:`_stick_split`,
        ``forces + alpha n``: the same joint force on the body), whose normal forces are those Coulomb's law
        holds the stick with. Where a stick row rides the held rows' forces are one split of many: a rod with
        both ends stopping in a rough bowl put all its friction on the held stick row's end, whose normal
        force came out -0.51 (a spurious lift-off and landing 3e-12 s later), where the best split presses
        both ends (``tests/test_rod_in_a_rough_bowl.py``). Exact for one dependence, as the split is. Not
        where friction jams (the margin rises without bound along ``n``, :func:`vcigen.cone_split.line_turns`:
        a rod at ``mu = 2`` in the bowl, wedged): the split's ``alpha`` is then its widest bracket's, 1e19,
        and the held rows' own forces are read."""
        owners = self._owners()
        if not owners:
            return forces
        out = np.array(forces, dtype=float)
        for f in owners:
            joint = self._stick_split(f, forces, grad)
            if joint is not None and joint[7]:
                out += joint[1] * joint[6]
        return out

    def _stick_split_slide(self, joint, q, u) -> None:
        """A stick split's stick breaks (:meth:`_stick_split`): the contacts with friction at the edge of
        their cone in the best split (within ``DEP_EPS`` of the least margin) slip the way their split force
        pushes, ``slip = mu_c sign(F_c + alpha d_c)``; the others stick on, a stick row that no longer depends
        on the rest held by its own again."""
        margin, alpha, values, contacts, lams, dirs, _, _ = joint
        for c, value, lam, d in zip(contacts, values, lams, dirs):
            if c >= 0 and value <= margin + DEP_EPS * (1.0 + abs(value)):
                self.act[self._stick_rows[c]] = False
                self._ride[c] = -1
                self._slip[c] = -self._mu_f[c] if lam + alpha * d < 0.0 else self._mu_f[c]
        grad = self.k.rows(q, u)[1]
        for g in range(len(self._stick_rows)):
            if self._partner[g] < 0 and self._ride[g] >= 0:
                self._ride[g] = self._owner(g, grad)
                self.act[self._stick_rows[g]] = self._ride[g] < 0

    def _split_slide(self, joint, q, u) -> None:
        """The coupled cones' stick breaks: those at the edge of their cone in the best split (within
        ``DEP_EPS`` of the least margin) slip along their split force, ``s = -lambda_c / |lambda_c|``; the
        others stick on, a row of theirs that no longer depends on the rest held by its own again."""
        margin, alpha, values, cones, lams, dirs = joint
        for (c, pc), value, lam, d in zip(cones, values, lams, dirs):
            if value <= margin + DEP_EPS * (1.0 + abs(value)):
                x, y = lam[0] + alpha * d[0], lam[1] + alpha * d[1]
                norm = max(math.hypot(x, y), 1e-300)
                for r, comp in ((c, x), (pc, y)):
                    self.act[self._stick_rows[r]] = False
                    self._ride[r] = -1
                    self._slip[r] = self._mu_f[c] * comp / norm
        grad = self.k.rows(q, u)[1]
        for g in range(len(self._stick_rows)):
            if self._partner[g] >= 0 and self._ride[g] >= 0:
                self._ride[g] = self._owner(g, grad)
                self.act[self._stick_rows[g]] = self._ride[g] < 0

    def _freeze_branch(self, f: int, q) -> None:
        """The signs of frictional contact ``f``'s tangent at ``q`` (0 at a kink: the face's centre) into its
        branch slots: its stick row is then that vertex's or face's smooth tangent."""
        if self._branch_of[f]:
            args = self.k.friction(q)[2]
            for b in self._branch_of[f]:
                self._branch[b] = 0.0 if abs(args[b]) <= KINK else math.copysign(1.0, args[b])
            self._set_friction()

    def _stick(self, f: int, q, u) -> None:
        """Frictional contact ``f`` sticks where its tangent is now (on the branch its mode was set on).

        If its stick row depends on the active rows (:meth:`_owner`: a rod lying on both ends, the second
        end to stick) it sticks with no row of its own: the rows already held keep its tangent, and its
        tangential force, not unique, is carried by its owner's stick row, whose cone has room for both
        (:meth:`_cone_margin`). Then any other one-tangent contact still slipping at a sliding velocity of 0
        (to round-off) whose stick row is now dependent sticks with it."""
        k = self.k
        sr = self._stick_rows[f]
        psi, grad, _ = k.rows(q, u)
        self._ref[f] += float(psi[sr])
        self._slip[f] = 0.0
        self._ride[f] = self._owner(f, grad)
        self.act[sr] = self._ride[f] < 0
        if self._ride[f] >= 0:
            return
        tiny = SLIDE_EPS * (1.0 + float(np.max(np.abs(u))))
        for g, sg in enumerate(self._stick_rows):
            if self._slip[g] and self._partner[g] < 0 and abs(float(grad[sg] @ u)) <= tiny:
                owner = self._owner(g, grad)
                if owner >= 0:
                    self._ref[g] += float(psi[sg])
                    self._slip[g], self._ride[g] = 0.0, owner

    def _cone_margin(self, f: int, forces, grad) -> float:
        """``mu_f sum lambda_rows - |lambda_stick|``: negative when the stick force leaves Coulomb's cone. A
        cone coupled to others by a dependent stick row: the margin of their best split
        (:meth:`_cone_split`)."""
        k = self.k
        j = k.frictional[f]
        split = self._cone_split if self._partner[f] >= 0 else self._stick_split
        joint = split(f, forces, grad)
        if joint is not None:
            return joint[0]
        normal = sum(forces[r] for r in range(k.r) if k.row_contact[r] == j)
        for g, owner in enumerate(self._ride):  # the dependent sticks it carries: their cones are room too
            if owner == f and g != f and self._partner[g] < 0:
                normal += (
                    self._mu_f[g]
                    / self._mu_f[f]
                    * sum(forces[r] for r in range(k.r) if k.row_contact[r] == k.frictional[g])
                )
        if self._partner[f] >= 0:  # a cone: the length of the tangential force
            tangential = math.hypot(forces[self._stick_rows[f]], forces[self._stick_rows[self._partner[f]]])
            return float(self._mu_f[f] * normal - tangential)
        return float(self._mu_f[f] * normal - abs(forces[self._stick_rows[f]]))

    def _friction_events(self, step, t_k, q, p, tau, v, u1, end, f1, events) -> None:
        """A slipping contact that stops inside the segment ("stop"; at its end where its sliding there is
        round-off's, ``SLIDE_EPS``, :meth:`_cone_stop`), a sticking one whose force leaves the cone
        ("slide"): each located as a root along the sub-step map (Illinois), as a lift-off is."""
        k = self.k
        vel0 = self._velocity(q, v, p)
        for f in range(len(self._stick_rows)):
            sr = self._stick_rows[f]
            if 0 <= self._partner[f] < f:
                continue  # a cone's second tangent: its events are its first's
            if self._partner[f] >= 0 and (self._slip[f] or self._slip[self._partner[f]]):
                self._cone_stop(f, self._partner[f], step, t_k, q, p, tau, v, u1, end, vel0, events)
            elif self._slip[f]:
                s = -math.copysign(1.0, self._slip[f])  # the sliding direction
                g1 = s * float(end.grad[sr] @ u1)
                tiny = SLIDE_EPS * (1.0 + float(np.max(np.abs(vel0))))
                if g1 < tiny:  # turned inside, or stopped at the end to round-off
                    g0 = s * float(k.rows(q, vel0)[1][sr] @ vel0)
                    if g1 >= -tiny:  # stopped at the end to round-off: there if it slid at the start
                        if g0 > tiny:
                            events[sr] = ("stop", 1.0)
                        continue

                    def sliding(c, w, s=s, sr=sr):
                        w, end_c, u_c = self._sub_end(step, t_k, q, p, tau, c, w)
                        return s * float(end_c.grad[sr] @ u_c), w

                    lo, w = 0.0, v
                    if abs(g0) <= tiny:
                        # slipping from rest (a slide at the segment's start): s = 0 is a root of its own; a
                        # stop is where the sliding, grown, comes back to 0 (none grown: a stop at the start)
                        g0 = 0.0
                        for s_try in SLIDE_LEAVE:
                            g_try, w_try = sliding(s_try, v)
                            if g_try > 1e-14:
                                lo, g0, w = s_try, g_try, w_try
                                break
                    frac = 0.0 if g0 <= 0.0 else illinois(sliding, g0, g1, 1e-14, 1e-13, LIFT_ITER, w, lo)
                    events[sr] = ("stop", frac)
            elif sr in self._stuck_on:
                continue  # sticking on at this instant, its force out of the cone (SustainedSteps._chain)
            elif self.act[sr] or (self._partner[f] >= 0 and self.act[self._stick_rows[self._partner[f]]]):
                g1 = self._cone_margin(f, f1, end.grad)
                if g1 < -EPS_LIFT * (1.0 + float(np.max(np.abs(f1)))):  # as a lift-off: round-off
                    g0 = self._cone_margin(f, self._contact_forces(q, vel0), k.rows(q, vel0)[1])

                    def margin(c, w, f=f):
                        w, end_c, _ = self._sub_end(step, t_k, q, p, tau, c, w)
                        return self._cone_margin(f, self._forces(end_c), end_c.grad), w

                    tiny = EPS_LAM * (1.0 + abs(g0) + abs(g1))
                    frac = 0.0 if g0 < 0.0 else illinois(margin, g0, g1, tiny, 1e-12, LIFT_ITER, v)
                    events[sr] = ("slide", frac)

    def _friction_switch(self, kind: str, sr: int, q, u) -> None:
        """At a located friction event: a stopped contact sticks; a sliding one slips against its force. A
        ``"turn"`` (:meth:`_chain`: a stop at the instant its slide began, the held step's impulse turning its
        sliding at once, as where a row an impact pulled off stays held) slips the other way: sticking there,
        its force would leave the cone again."""
        f = self.k.row_stick[sr]
        if self._partner[f] >= 0:
            self._cone_switch("stop" if kind == "turn" else kind, f, self._partner[f], q, u)
            return
        if kind == "turn":
            self._slip[f] = -self._slip[f]
            self._set_friction()
            return
        sliding = float(self.k.rows(q, u)[1][sr] @ u)
        if kind == "stop" and abs(sliding) > SLIDE_EPS * (1.0 + float(np.max(np.abs(u)))):
            self._slip[f] = -self._mu_f[f] * math.copysign(1.0, sliding)  # an impact turned it: slip that way
        elif kind == "stop":
            self._stick(f, q, u)
        else:
            forces, grad = self._contact_forces(q, u), self.k.rows(q, u)[1]
            joint = self._stick_split(f, forces, grad)
            if joint is not None:  # dependent sticks it carries: the contacts at the edge of their split slip
                self._stick_split_slide(joint, q, u)
            else:
                lam = forces[sr]
                self.act[sr] = False
                self._slip[f] = -self._mu_f[f] * math.copysign(1.0, -lam)  # slides the way the force pushes
                for g, owner in enumerate(self._ride):  # its dependent sticks slide with it, the same way
                    if owner == f and g != f and self._partner[g] < 0:
                        along = float(grad[self._stick_rows[g]] @ grad[sr])
                        self._slip[g] = -self._mu_f[g] * math.copysign(1.0, -lam * along)
                        self._ride[g] = -1
        self._set_friction()
