"""Impacts with rows held (MATH.md *Sustained contact*), for :class:`vcigen.sustained.SustainedSteps`:
the impulse law on the active rows and the rows hit (Newton's law, a complementarity problem solved by
enumeration, with Coulomb's cone on the held stick rows), an impact while held, the plastic entry (a free
impact whose rows become held) and its log. :class:`HeldImpacts` reads the stepper's state."""

from __future__ import annotations

import math

import numpy as np

from .errors import SolverError
from .friction import cone_slide
from .held_roots import EPS_LAM, MAX_LAW_ROWS, SLIDE_EPS
from .result import Impact


def _pooled(pools, lam) -> float:
    """``sum mu_f Lam_n`` over the pools of a stick row's cone (``SustainedSteps._law_cones``): its room."""
    return sum(mu * float(np.sum(lam[normals])) for normals, mu in pools)


class HeldImpacts:
    """Impacts while rows are held (a base of :class:`vcigen.sustained.SustainedSteps`)."""

    def _impulse_law(self, step, t_k, q, p, guess, hit, targets):
        """Newton's law on the active rows and the rows ``hit`` (targets: outgoing ``g_r.qdot``), with
        Coulomb's cone on the held stick rows (MATH.md *Friction*).

        The complementarity problem of the rows ``S`` involved: impulses ``Lam >= 0`` and outgoing normal
        velocities ``g_r.qdot+ >= target_r``, one of the two tight for every row (bilateral rows: equality,
        ``Lam`` free). A held stick row (a one-tangent contact ``f`` sticking, :meth:`_law_cones`) sticks
        (tight, ``|Lam_t| <= mu_f Lam_n``, ``Lam_n`` its contact's normal impulse in this impact) or slips at
        either edge of its cone, ``Lam_t = -+mu_f Lam_n`` with the tangential velocity after ``>= 0`` resp.
        ``<= 0`` (its contact's normal rows then push along ``g_n -+ mu_f g_t``). Without friction the
        Delassus matrix ``G M^-1 G^T`` is positive definite and the solution unique; the friction modes are
        tried all sticking first (the law of old where it stays inside the cones), then the first stick row
        slipping (``Lam_t = -mu_f Lam_n``, then ``+mu_f Lam_n``) and so on in base 3, each over the sets of
        tight rows from the largest down: the first solution is taken, deterministically. A one-tangent
        contact held and slipping (:meth:`_law_slips`) joins with its stick row and the same three modes, its
        own first: on the edge against its slip (``Lam_t = slip_f / mu_f * mu_f Lam_n``, Coulomb's sliding
        impulse, its tangential velocity after not reversed), then sticking within its cone, then the other
        edge. An isotropic cone held (both tangents' stick rows; sticking, or slipping and joined by
        :meth:`_law_slips`) sticks within its cone (``|Lam_t| <= mu_f Lam_n``, 2-norm) or slips with Coulomb's
        sliding impulse ``Lam_t = -mu_f Lam_n w+ / |w+|`` against its tangential velocity after ``w+``
        (:meth:`_law_slide`, a 1-D root); its modes come after all the one-tangent ones (stick then slip, a
        slipping cone's slip first), one cone slipping at a time. Returns ``(p+, Lam, vel-, vel+, dropped,
        slipped, slips)``, ``dropped`` the rows left with no impulse (the caller releases the active ones),
        ``slipped`` the stick rows that slipped, ``slips`` the slipping contacts that joined (the caller sets
        their contacts' modes, :meth:`_slip_at_impact`).
        """
        k = self.k
        vel = self._velocity(q, guess, p)
        mass = k.legendre(q, vel)[1]
        grad = k.rows(q, vel)[1]
        rows = [int(r) for r in np.flatnonzero(self.act)] + [r for r in hit if not self.act[r]]
        slips = self._law_slips(grad, rows)
        for f, _ in slips:  # a cone's two stick rows, its first tangent's first
            rows += [self._stick_rows[x] for x in (f, self._partner[f]) if x >= 0]
        if len(rows) > MAX_LAW_ROWS:
            raise SolverError(
                step, t_k, "sustained", math.nan, f"impulse law on {len(rows)} contacts at once"
            )
        tgt = {r: 0.0 for r in rows} | dict(targets)
        free = [not (k.row_bilateral[r] or (k.row_stick and k.row_stick[r] >= 0)) for r in rows]
        g = grad[rows]
        w = g @ np.linalg.solve(mass, g.T)
        b = np.array([tgt[r] for r in rows]) - g @ vel
        lam_eps = EPS_LAM * (1.0 + float(np.max(np.abs(p))))
        vel_eps = EPS_LAM * (1.0 + float(np.max(np.abs(vel))))
        n = len(rows)
        cones, strict, orders, isos = self._law_cones(rows, slips)
        out = ""  # a strict stick row's impulse out of its cone (the error if nothing else solves the law)
        for modes in range(3 ** len(cones) * 2 ** len(isos)):
            # 0 stick, 1 Lam_t = -mu Lam_n, 2 +; each cone's digits in its order (its own mode first)
            slips_ = [orders[c][(modes // 3**c) % 3] for c in range(len(cones))]
            # then the isotropic cones' (after all of those): 0 stick, 1 slip; each its own first
            upper = modes // 3 ** len(cones)
            slides = [(upper >> c & 1) ^ iso[4] for c, iso in enumerate(isos)]
            if sum(slides) > 1:
                out = out or (
                    f"impulse law: {sum(slides)} isotropic cones slipping at once at an impact while held"
                )
                continue
            ws = w.copy()  # the columns of the slipping contacts' normal rows: g_n -+ mu g_t
            for (i, pools), mode in zip(cones, slips_):
                for normals, mu in pools if mode else ():
                    ws[:, normals] += (-mu if mode == 1 else mu) * w[:, [i]]
            sliding = {i for (i, _), mode in zip(cones, slips_) if mode}
            slide = [iso for iso, on in zip(isos, slides) if on]
            sliding |= {x for iso in slide for x in iso[:2]}
            for mask in range((1 << n) - 1, -1, -1):
                tight = [i for i in range(n) if mask >> i & 1]
                if any(not free[i] and (not mask >> i & 1) != (i in sliding) for i in range(n)):
                    continue
                if slide:
                    lam = self._law_slide(slide[0], w, ws, b, tight, cones, slips_, lam_eps)
                    if lam is None:
                        continue
                else:
                    lam = np.zeros(n)
                    if tight:
                        try:
                            lam[tight] = np.linalg.solve(ws[np.ix_(tight, tight)], b[tight])
                        except np.linalg.LinAlgError:
                            continue
                    for (i, pools), mode in zip(cones, slips_):
                        if mode:
                            lam[i] = (-1.0 if mode == 1 else 1.0) * _pooled(pools, lam)
                gap = w @ lam - b  # g_r.qdot+ - target_r
                if not (
                    all(lam[i] >= -lam_eps or not free[i] for i in tight)
                    and all(gap[i] >= -vel_eps for i in range(n) if not mask >> i & 1 and i not in sliding)
                ):
                    continue
                inside = True
                for (i, pools), mode in zip(cones, slips_):
                    if mode == 0:
                        inside = inside and abs(lam[i]) <= _pooled(pools, lam) + lam_eps
                    else:
                        inside = inside and (gap[i] >= -vel_eps if mode == 1 else gap[i] <= vel_eps)
                for (i, o, normals, mu, _, _), on in zip(isos, slides):
                    if not on:  # sticking: within its cone (slipping: on its edge by _law_slide)
                        cap = mu * float(np.sum(lam[normals]))
                        inside = inside and math.hypot(float(lam[i]), float(lam[o])) <= cap + lam_eps
                if inside and strict:
                    why = self._law_strict(strict, rows, lam, lam_eps)
                    out, inside = out or why, not why
                if inside:
                    break
            else:
                continue
            break
        else:
            if out:
                raise SolverError(step, t_k, "sustained", math.nan, out)
            raise SolverError(
                step,
                t_k,
                "sustained",
                math.nan,
                f"impulse law: no solution on {n} contacts (dependent normals?)",
            )
        lam_full = np.zeros(k.r)
        lam_full[rows] = lam
        dropped = [r for i, r in enumerate(rows) if not mask >> i & 1 and i not in sliding]
        slipped = [rows[i] for i in sorted(sliding)]
        for (i, o, _, _, on, f), slid in zip(isos, slides):
            if on and slid and lam[i] == 0.0 and lam[o] == 0.0:  # no normal impulse: it slips on as before
                slips = [s for s in slips if s[0] != f]
                slipped = [r for r in slipped if r not in (rows[i], rows[o])]
        p_plus = p + grad.T @ lam_full
        return p_plus, lam_full, vel, self._velocity(q, vel, p_plus), dropped, slipped, slips

    def _law_slips(self, grad, rows) -> list[tuple[int, list[int]]]:
        """The one-tangent contacts held and slipping whose friction joins the impulse law on ``rows``
        (:meth:`_impulse_law`): ``[(f, riders)]``, ``f`` one whose stick row is independent of the active rows
        and of the stick rows of those before it (it joins the law), ``riders`` the slipping contacts whose
        stick row depends on ``f``'s (a box slipping on a face, two vertices: their normal impulses are
        ``f``'s room too, as for a dependent stick, :meth:`_law_cones`). A slipping contact whose stick row
        depends on the held rows alone (its sliding fixed by them) takes none. An isotropic cone slipping
        (``f`` its first tangent, ``riders`` empty) joins with both its stick rows if both are independent of
        those before (else it takes none: a cone coupled to another's slip is not handled)."""
        k = self.k
        out: list[tuple[int, list[int]]] = []
        if not self._stick_rows:
            return out
        act = self.act.copy()
        try:
            for f, sr in enumerate(self._stick_rows):
                j = k.frictional[f]
                held = any(self.act[r] and k.row_contact[r] == j for r in rows)
                pf = self._partner[f]
                if pf > f and held and (self._slip[f] or self._slip[pf]):  # a cone: both rows independent
                    sp_ = self._stick_rows[pf]
                    if not self._dependent(grad, sr):
                        self.act[sr] = True
                        if not self._dependent(grad, sp_):
                            self.act[sp_] = True
                            out.append((f, []))
                            continue
                        self.act[sr] = False
                    continue
                if not (self._slip[f] and pf < 0 and held):
                    continue
                if not self._dependent(grad, sr):
                    self.act[sr] = True
                    out.append((f, []))
                    continue
                for g, riders in out:
                    if self._partner[g] < 0 and not self._dependent(grad, sr, self._stick_rows[g]):
                        riders.append(f)
                        break
        finally:
            self.act = act
        return out

    def _law_cones(self, rows, slips=()):
        """The held stick rows of the impulse law on ``rows`` with Coulomb's cone: ``[(i, pools)]`` of each
        one-tangent contact ``f`` sticking with its own row (``i`` its index in ``rows``), ``pools`` the
        ``(normals, mu_f)`` whose normal impulses give its room: its own contact's normal rows (indices in
        ``rows``), then those of the one-tangent dependent sticks it carries (their cones are its room too, as
        in :meth:`_cone_margin`; they slip with it); ``[(i, normals, mu_f, -1)]`` of the isotropic cones with
        one tangent held, which may only stick; ``isos``: ``[(i, o, normals, mu_f, on, f)]`` of those with
        both held (``i``, ``o`` their indices, ``f`` the first tangent, ``on`` 1 if slipping and joined by
        :meth:`_law_slips`), which stick or slip (:meth:`_law_slide`). A cone coupled to others by a dependent
        stick (:meth:`_cone_split`) is not checked. Then the slipping one-tangent contacts ``slips``, pooled
        the same way. ``orders``: each one-tangent cone's modes in the order tried, its own first (stick ``(0,
        1, 2)``; slipping against ``+`` sliding ``(1, 0, 2)``, against ``-`` ``(2, 0, 1)``)."""
        k = self.k
        cones, strict, orders, isos = [], [], [], []
        slipping = {f for f, _ in slips}

        def normals(f):
            return [i for i, r in enumerate(rows) if k.row_contact[r] == k.frictional[f]]

        for f, sr in enumerate(self._stick_rows):
            pf = self._partner[f]
            if pf >= 0:
                if pf < f:
                    continue  # a cone's second tangent: with its first
                riders = [g for g, owner in enumerate(self._ride) if g not in (f, pf) and owner in (f, pf)]
                both = [rows.index(x) if x in rows else -1 for x in (sr, self._stick_rows[pf])]
                if max(both) >= 0 and not riders and self._ride[f] < 0 and self._ride[pf] < 0:
                    i, o = (both[0], both[1]) if both[0] >= 0 else (both[1], -1)
                    if o >= 0:  # both tangents held: stick or slip (on the slipping ones, below)
                        isos.append((i, o, normals(f), float(self._mu_f[f]), int(f in slipping), f))
                    else:
                        strict.append((i, normals(f), float(self._mu_f[f]), o))
            elif sr in rows and f not in slipping:
                riders = [
                    g for g, owner in enumerate(self._ride) if g != f and owner == f and self._partner[g] < 0
                ]
                pools = [(normals(g), float(self._mu_f[g])) for g in [f, *riders]]
                cones.append((rows.index(sr), pools))
                orders.append((0, 1, 2))
        for f, riders in slips:
            if self._partner[f] >= 0:
                continue  # an isotropic cone: in isos
            pools = [(normals(g), float(self._mu_f[g])) for g in [f, *riders]]
            cones.append((rows.index(self._stick_rows[f]), pools))
            orders.append((1, 0, 2) if self._slip[f] < 0 else (2, 0, 1))
        return cones, strict, orders, isos

    def _law_slide(self, iso, w, ws, b, tight, cones, slips_, lam_eps):
        """The impulses of the impulse law (:meth:`_impulse_law`) on the tight rows ``tight`` with the
        isotropic cone ``iso = (i, o, normals, mu_f, on, f)`` slipping: Coulomb's sliding impulse, its
        tangential impulse ``m`` against its tangential velocity after (:func:`vcigen.friction.cone_slide`);
        None if it would stick (or the rows are singular, or a tangent is fixed by them: ``H`` singular). The
        law is affine in ``m`` (the tight rows' impulses, the one-tangent slipping rows' edges): its value at
        ``m = 0`` and its two columns give the cone's normal impulse ``a - b.m`` (``a`` within ``lam_eps`` of
        0: none, ``m = 0``) and the tangential velocity after ``g + H m``, one solve with three right-hand
        sides."""
        i, o, normals, mu, _, _ = iso
        n = len(b)
        lams = np.zeros((3, n))  # the law at m = 0, then its columns in m1, m2
        if tight:
            rhs = np.column_stack([b[tight], -w[tight, i], -w[tight, o]])
            try:
                lams[:, tight] = np.linalg.solve(ws[np.ix_(tight, tight)], rhs).T
            except np.linalg.LinAlgError:
                return None
        lams[1, i] = lams[2, o] = 1.0
        for lam in lams:
            for (c, pools), mode in zip(cones, slips_):
                if mode:
                    lam[c] = (-1.0 if mode == 1 else 1.0) * _pooled(pools, lam)
        gaps = lams @ w.T  # their velocities: g_r.qdot+ (less b at m = 0)
        a = float(np.sum(lams[0, normals]))
        a = a if a > lam_eps else 0.0  # no normal impulse (to round-off): no friction impulse
        bn = (-float(np.sum(lams[1, normals])), -float(np.sum(lams[2, normals])))
        g = (float(gaps[0, i] - b[i]), float(gaps[0, o] - b[o]))
        m = cone_slide(g, (gaps[1, i], gaps[2, i], gaps[1, o], gaps[2, o]), bn, mu, a)
        if m is None:
            return None
        return lams[0] + m[0] * lams[1] + m[1] * lams[2]

    def _law_strict(self, strict, rows, lam, lam_eps) -> str:
        """The first held isotropic cone (:meth:`_law_cones`) whose stick impulse leaves its cone: the error's
        text, "" if none does (slipping at an impact while held is for one-tangent contacts only)."""
        k = self.k
        for i, normals, mu, o in strict:
            cap = mu * float(np.sum(lam[normals]))
            tangential = math.hypot(float(lam[i]), float(lam[o]) if o >= 0 else 0.0)
            if tangential > cap + lam_eps:
                name = k.contact_names[k.frictional[k.row_stick[rows[i]]]]
                return (
                    f"impulse law: the stick impulse of {name} leaves its friction cone at an impact "
                    f"while held ({tangential:.3g} > {cap:.3g}); slip at such an impact is for one-tangent "
                    "contacts only"
                )
        return ""

    def _slip_at_impact(self, q, vel_p, slipped, slips=()) -> str:
        """The stick rows that slipped in the impulse law (:meth:`_impulse_law`): their contacts slip after it
        along the tangential velocity after, ``slip_f = -mu_f sign(g_t.qdot+)``, or stick on where that is 0
        (to round-off). The slipping contacts that joined it (``slips``, :meth:`_law_slips`): slip on (the
        same way: no switch; turned: a switch) or, where their sliding after is 0 (to round-off), stick
        (:meth:`_stick`, a switch). Isotropic cones (:meth:`_law_cones`) the same way, along their sliding
        after (``slip = -mu_f w+ / |w+|``): a sticking one that slipped or a slipping one that stuck is a
        switch; one slipping on took a sliding impulse the tangent does not carry. Why the tangent stops
        here: ``"friction switch in a held step"`` (a contact's mode changed), ``"friction at an impact"``
        (a cone's sliding impulse), ``""`` (carried)."""
        k = self.k
        if not slipped and not slips:
            return ""
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
        return "friction at an impact" if slid else ""

    def _cone_at_impact(self, q, vel_p, grad, tiny, slipped, slips) -> tuple[bool, bool]:
        """The isotropic cones of the impulse law after it (:meth:`_slip_at_impact`): one that slipped in it
        (its stick rows in ``slipped``) slips on along its sliding after, ``slip = -mu_f w+ / |w+|`` (a switch
        if it stuck before), or sticks where that is 0 (to round-off); one that slipped before and joined
        (``slips``) but stuck in it sticks (:meth:`_stick`, a switch). ``(switched, slid)``, ``slid``: a cone
        slipped on through the impact."""
        switched = slid = False
        for f, p in self._cones():
            sr, sp_ = self._stick_rows[f], self._stick_rows[p]
            joined = any(g == f for g, _ in slips)
            w = self._sliding(f, p, grad, vel_p)
            if sr in slipped and math.hypot(*w) > tiny:
                switched = switched or not joined
                slid = slid or joined
                self.act[sr] = self.act[sp_] = False
                self._slip[[f, p]] = -self._mu_f[f] * w / math.hypot(*w)
            elif joined:
                self._stick(f, q, vel_p)
                self._stick(p, q, vel_p)
                switched = True
        return switched, slid

    def _chain_impact(self, step, t_k, h, q, p, v, t, group, impacts, e_before):
        """An impact on rows ``group`` during sustained contact; returns the momentum after it."""
        k = self.k
        self._at(t)
        rest = k.restitution()
        vel = self._velocity(q, v, p)
        lam_now = np.where(self.act, self._lam, 0.0) * self._lam_rate / self._h
        acc = self._row_accel(q, vel, self._accel(q, vel, lam_now))
        grad = k.rows(q, vel)[1]
        targets, plastic = {}, []
        for r in group:
            e = float(rest[k.row_contact[r]])
            rate = float(grad[r] @ vel)
            if self.tol.grazing == "contact" and self._settles(rate, acc[r], e, h):
                plastic.append(r)
            else:
                targets[r] = -e * rate
        law = self._impulse_law(step, t_k, q, p, v, group, targets)
        p_plus, lam, vel_m, vel_p, dropped, slipped, slips = law
        why = self._slip_at_impact(q, vel_p, slipped, slips)
        if why:  # stick <-> slip at the impact (a mode change), or a cone's sliding impulse: no tangent
            self._sw_lose(why)
        else:  # the contacts slipping on: their sliding impulse in Tracker.impulse
            self._ev_impulse(q, v, p, lam, targets, group, slips)
        mass = k.legendre(q, vel_m)[1]
        loss = 0.5 * (vel_m @ mass @ vel_m - vel_p @ mass @ vel_p)
        leaving = [r for r in dropped if self.act[r] and r not in group]  # active rows the impact pulls off
        if leaving:  # each stays unless it leaves below the resolution, pulled back by the rows held after
            after = self._held_accel(q, vel_p, leaving, plastic)
            for r in leaving:
                if not self._settles(float(grad[r] @ vel_p), after[r], 1.0, h):
                    self._release(step, t_k, t, r)
        for r in plastic:  # pressed in and settling: held (its force, checked next, may release it)
            self.act[r] = True
        by_contact: dict[int, list[int]] = {}
        for r in group:
            by_contact.setdefault(k.row_contact[r], []).append(r)
        for j, rs in by_contact.items():
            kind = (
                "plastic"
                if any(self.act[r] for r in rs)
                else ("elastic" if rest[j] == 1.0 else "restitution")
            )
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
        return p_plus

    def _held_accel(self, q, u, off, on) -> np.ndarray:
        """Every row's ``d2 psi/dt2`` at ``(q, u)`` under the forces of the rows held after an impact (the
        active ones but ``off``, and ``on``): how a row the impact pulls off is pulled back (a held row's own
        force would cancel it)."""
        k = self.k
        act = self.act.copy()
        self.act[list(off)] = False
        self.act[list(on)] = True
        held = {k.row_contact[r] for r in np.flatnonzero(self.act) if k.row_contact[r] >= 0}
        for r in np.flatnonzero(self.act):  # a contact no longer held keeps no stick row
            if k.row_stick and k.row_stick[r] >= 0 and k.frictional[k.row_stick[r]] not in held:
                self.act[r] = False
        try:
            lam = self._contact_forces(q, u)
        except np.linalg.LinAlgError:  # dependent rows: no forces (C: <model>_forces_to's failed LU)
            lam = np.zeros(k.r)
        finally:
            self.act[:] = act
        return self._row_accel(q, u, self._accel(q, u, lam))

    def _plastic_entry(self, step, t_k, h, q, p, v, t, group_contacts):
        """Plastic impact on contacts ``group_contacts`` at ``q``: their touching rows become active."""
        k = self.k
        psi = k.rows(q, v)[0]
        rows, lowest = [], []
        for j in group_contacts:
            own = [r for r in range(k.r) if k.row_contact[r] == j]
            lowest.append(min(own, key=lambda r: (psi[r], r)))
            rows += [r for r in own if psi[r] <= psi[lowest[-1]] + self.tol.admissible]
        # no row is held here (the free impact chain runs with none), so no stick row slips in the law
        p_plus, lam, vel_m, vel_p, dropped, _, _ = self._impulse_law(step, t_k, q, p, v, rows, {})
        for r in rows:  # the touching row of each contact is held; another branch at a kink if it presses
            self.act[r] = r in lowest or r not in dropped
        mass = k.legendre(q, vel_m)[1]
        loss = 0.5 * (vel_m @ mass @ vel_m - vel_p @ mass @ vel_p)
        return p_plus, lam, loss, rows

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
