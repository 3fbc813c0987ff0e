"""The impulse law of an impact with rows held (MATH.md *Sustained contact*, *Friction*), for
:class:`vcigen.held_impacts.HeldImpacts`: Newton's law on the active rows and the rows hit, a complementarity
problem solved by enumeration, with Coulomb's cone on the held stick rows (sticking or slipping), on the
contacts that land, and on isotropic cones (a 1-D root); and the law as the tangent takes it."""

from __future__ import annotations

import math

import numpy as np

from .errors import SolverError
from .friction import cone_slide, line_slide
from .held_roots import DEP_EPS, EPS_LAM, MAX_LAW_ROWS, SLIDE_EPS, SLIDE_SWEEPS, SLIDE_TOL, in_span, span_add
from .law_pgs import pgs
from .law_split import fit
from .law_split import least_split as _least_split


def _pooled(pools, lam) -> float:
    """``sum mu_f Lam_n`` over the pools of a stick row's cone (``SustainedSteps._law_cones``): its room."""
    return sum(mu * float(np.sum(lam[normals])) for normals, mu in pools)


def _spanned(g, tight, normal) -> bool:
    """Is a normal row among ``tight`` (indices of the law's rows ``g``) within ``DEP_EPS`` of the span of the
    normal rows before it (modified Gram-Schmidt)? Such a set of tight rows (a box's four vertices on a face)
    has no unique split of its impulse: the law takes a subset of them instead, the first independent one."""
    basis: list = []
    return any(not span_add(basis, g[i]) for i in tight if normal[i])


def _cone_blocks(isos) -> list[tuple[int, int, int, float]] | None:
    """Each isotropic cone of ``isos`` (:meth:`ImpulseLaw._law_cones`) as ``(n, i, o, mu)``: its one normal
    row and its two stick rows (indices in the law's rows); None where one has several normal rows (C
    ``law_one_normal``)."""
    if any(len(iso[2]) != 1 for iso in isos):
        return None
    return [(iso[2][0], iso[0], iso[1], iso[3]) for iso in isos]


def _gains(lam, b, gap, tgts) -> bool:
    """Does the law's impulse ``lam`` raise the kinetic energy? ``dT = lam . (u- + u+) / 2``, ``u- = targets -
    b`` the rows' velocities before, ``u+ = targets + gap`` after (a function of ``G^T lam`` alone, whatever
    the split), above ``EPS_LAM`` of ``sum |lam| (|u-| + |u+|)``. Newton's restitution with a stick can
    (the normal and tangential rows coupled through the body), and so can a slide (the sliding impulse moves
    the normal velocity, which the normal impulse then sets anew); the law takes no loose cone's friction that
    does (:meth:`ImpulseLaw._impulse_law`)."""
    before, after = tgts - b, tgts + gap
    gain = float(lam @ (before + after)) / 2.0
    return gain > EPS_LAM * float(np.abs(lam) @ (np.abs(before) + np.abs(after)))


def law_gains(grad, lam, vel_m, vel_p) -> bool:
    """Does an impulse law's result (``Lam`` per row, velocities ``vel_m`` before and ``vel_p`` after) raise
    the kinetic energy? ``dT = Lam . G (qdot- + qdot+) / 2`` over all rows, above ``EPS_LAM`` of ``sum |Lam|
    (|u-| + |u+|)`` (:func:`_gains` on the whole law). Newton's restitution with Coulomb's friction can
    (``HeldImpacts._reduced_restitution`` then takes less restitution); without friction it cannot."""
    before = grad @ vel_m
    return _gains(lam, -before, grad @ vel_p, np.zeros_like(before))  # targets 0: u- = -b, u+ = gap


class ImpulseLaw:
    """The impulse law while rows are held (a base of :class:`vcigen.held_impacts.HeldImpacts`)."""

    def _impulse_law(self, step, t_k, q, p, guess, hit, targets):
        """:meth:`_law_once`, and again where its solution cut a dependent stick from its owner
        (:meth:`_cut_riders`: two disks side by side on a rough floor, the first riding on the second's stick
        row through the row between them, which the impact leaves with no impulse). The rider's friction was
        pooled into its owner's cone, which no longer holds its tangent: the law is solved anew with the
        rider's stick row its own (its cone its own contact's), every set of tight rows that is dependent
        (stick rows too) left out, and taken if it has a solution (counted, ``res.stats["riders_cut"]``;
        the tangent stops there, ``why``); else the first solution stands. First, where the law left a
        landing contact's friction out and active rows leave in it, :meth:`_law_leaving`."""
        before = self.least_splits, self.friction_dropped
        law = self._law_once(step, t_k, q, p, guess, hit, targets)
        law, leave = self._law_leaving(step, t_k, q, p, guess, hit, targets, law, before)
        cut = self._cut_riders(q, law, hit)
        if not cut:
            return law
        state = self._law_state()
        counts = self.least_splits, self.friction_dropped
        self.least_splits, self.friction_dropped = before  # the law taken counts
        for g in cut:
            self._ride[g] = -1
            self.act[self._stick_rows[g]] = True
        try:
            again = self._law_once(step, t_k, q, p, guess, hit, targets, every=True, leave=leave)
        except SolverError:
            self._set_law_state(state)
            self.least_splits, self.friction_dropped = counts
            return law
        self.riders_cut += 1
        return (*again[:8], again[8] or "friction at an impact")

    def _law_leaving(self, step, t_k, q, p, guess, hit, targets, law, before) -> tuple:
        """The law ``law`` (:meth:`_law_once`), or the law solved anew where it left a landing contact's
        friction out and active rows leave in it (no impulse): a block sliding down a rough ramp onto a rough
        floor lands on the floor at the foot of the ramp, whose row is then held; the floor's stick row is in
        the span of the two normal rows, so its friction was left out, though the ramp's row takes no impulse
        and leaves. Likewise where a landing contact's friction rides on the stick row of a contact that
        leaves (:meth:`_astray`). The landing stick rows are tested anew against the rows but those leaving
        and the stick rows of their contacts (:meth:`_law_lands`' ``leave``: the ramp's stick row carried the
        floor's friction along the ramp), every set of tight rows that is dependent left out, and the new
        solution taken where it exists, the leaving rows still leave in it, and it leaves fewer landing
        contacts without friction of their own (left out or astray; the tangent stops there, ``why``); else
        the first stands. ``before``: the counts before the law. Returns ``(law, leave)``, ``leave`` the rows
        left out of the dependence tests (for a second try)."""
        k = self.k
        leaving = [r for r in law[4] if self.act[r] and not (k.row_stick and k.row_stick[r] >= 0)]
        if not leaving:
            return law, ()
        stay = {k.row_contact[r] for r in range(k.r) if (self.act[r] or r in hit) and r not in law[4]}
        gone = {k.row_contact[r] for r in leaving} - stay  # the contacts none of whose rows stays
        astray = self._astray(law[7], gone)
        if self.friction_dropped == before[1] and not astray:
            return law, ()
        leave = leaving + [self._stick_rows[f] for f, j in enumerate(k.frictional) if j in gone]
        state = self._law_state()
        counts = self.least_splits, self.friction_dropped
        self.least_splits, self.friction_dropped = before  # the law taken counts
        try:
            again = self._law_once(step, t_k, q, p, guess, hit, targets, every=True, leave=leave)
        except SolverError:
            again = None
        if (
            again is None
            or not set(leaving) <= set(again[4])
            or self.friction_dropped + self._astray(again[7], gone) >= counts[1] + astray
        ):
            self._set_law_state(state)
            self.least_splits, self.friction_dropped = counts
            return law, ()
        return (*again[:8], again[8] or "friction at an impact"), leave

    def _astray(self, lands: dict[int, int], gone: set[int]) -> int:
        """How many landing contacts (``lands``, :meth:`_law_lands`) ride on the stick row of a contact in
        ``gone`` (none of its rows stays after the law): their friction acts along a leaving contact's tangent
        (a disk rolling down a rough ramp onto a rough floor: its floor's stick row is in the span of the two
        normal rows and the ramp's stick row, so it rode on that, and the ramp's row carried the floor's
        friction along the ramp; the disk left the landing sliding, 0.3 % slow once rolling again)."""
        k = self.k
        return sum(o != f and k.frictional[o] in gone for f, o in lands.items())

    def _law_state(self) -> tuple:
        """What a law's second try (:meth:`_impulse_law`) changes: the rows held, the dependent sticks' owners
        and ``riders_cut``; :meth:`_set_law_state` puts it back (a trial of ``_reduced_restitution`` too)."""
        return self.act.copy(), list(self._ride), self.riders_cut

    def _set_law_state(self, state: tuple) -> None:
        self.act, self._ride, self.riders_cut = state[0].copy(), list(state[1]), state[2]

    def _cut_riders(self, q, law, hit) -> list[int]:
        """The dependent sticks (``_ride[g] = f``: a one-tangent contact or a cone's tangent, ``f``'s stick
        row kept by the law) pressed after the law ``law`` (:meth:`_law_once`: a normal row of theirs kept)
        whose stick row is no longer in the span of the rows it keeps (active or hit, neither dropped nor
        slipped)."""
        k = self.k
        dropped, slipped = set(law[4]), set(law[5])
        kept = [r for r in range(k.r) if (self.act[r] or r in hit) and r not in dropped and r not in slipped]
        cut = []
        grad = None
        for g, f in enumerate(self._ride):
            if f < 0 or f == g:
                continue
            if self._stick_rows[f] not in kept:
                continue
            if not any(k.row_contact[r] == k.frictional[g] for r in kept):
                continue
            grad = k.rows(q, law[2])[1] if grad is None else grad
            if not in_span(grad, kept, self._stick_rows[g]):
                cut.append(g)
        return cut

    def _law_once(self, step, t_k, q, p, guess, hit, targets, every: bool = False, leave=()):
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
        slipping cone's slip first), several slipping at once by block Gauss-Seidel. A frictional contact
        that lands (a row of its hit, none held: :meth:`_law_lands`) joins the same way, sticking first: with
        a stick row of its own (a one-tangent contact's three modes, a cone's stick or slide), or in the cone
        of the contact whose stick row carries its tangent (its normal impulse is that one's room too); a
        cone with a dependent stick row joins loose: sliding first (along a line where the law's other rows
        fix its sliding but along one, :func:`vcigen.friction.line_slide`), then sticking (its impulses split
        the least way where its rows are dependent, :func:`_least_split`, also beside a sliding one), else
        left out (no friction impulse), the modes without a loose cone left out first; not a slide or stick
        of a loose cone that adds kinetic energy (:func:`_gains`).
        Returns ``(p+, Lam, vel-, vel+, dropped, slipped, slips, lands, why)``, ``dropped`` the rows left with
        no impulse (the caller releases the active ones), ``slipped`` the stick rows that slipped, ``slips``
        the slipping contacts that joined (the caller sets their contacts' modes, :meth:`_slip_at_impact`),
        ``lands`` the landing ones (their modes are set when they are held, ``_friction_modes``), ``why``
        why the tangent does not carry the law (``"friction at an impact"``: a landing cone's second split,
        its least split beside a slide, a slide along a line; else ``""``; :meth:`_law_tangent`). ``every``:
        a set of tight rows may not be dependent at all, stick rows too (:meth:`_impulse_law`'s second try);
        ``leave``: rows the landing stick rows are not tested against (:meth:`_law_leaving`). A
        law of more than ``MAX_LAW_ROWS`` rows is not enumerated: :meth:`_law_pgs` alone (its frictional
        contacts all isotropic cones), else a ``SolverError`` ("impulse law on N contacts at once").
        """
        k = self.k
        vel = self._velocity(q, guess, p)
        mass = k.legendre(q, vel)[1]
        grad = k.rows(q, vel)[1]
        rows = [int(r) for r in np.flatnonzero(self.act)] + [r for r in hit if not self.act[r]]
        slips = self._law_slips(grad, rows)
        for f, _ in slips:  # a cone's two stick rows, its first tangent's first
            rows += [self._stick_rows[x] for x in (f, self._partner[f]) if x >= 0]
        lands, loose, grad, bare = self._law_lands(q, vel, rows, grad, leave)
        for f in [f for f, o in lands.items() if o == f]:  # landing with a row of its own (or loose)
            rows += [self._stick_rows[x] for x in (f, self._partner[f]) if x >= 0]
        crowded = len(rows) > MAX_LAW_ROWS  # too many to enumerate: the projected Gauss-Seidel alone, below
        tgt = {r: 0.0 for r in rows} | dict(targets)
        tgts = np.array([tgt[r] for r in rows])
        free = [not (k.row_bilateral[r] or (k.row_stick and k.row_stick[r] >= 0)) for r in rows]
        normal = [not (k.row_stick and k.row_stick[r] >= 0) for r in rows]
        g = grad[rows]
        spans = [True] * len(rows) if every else normal  # the rows a set of tight rows may not have dependent
        dependent = _spanned(g, range(len(rows)), spans)  # only then may a set of tight rows be dependent
        w = g @ np.linalg.solve(mass, g.T)
        b = np.array([tgt[r] for r in rows]) - g @ vel
        lam_eps = EPS_LAM * (1.0 + float(np.max(np.abs(p))))
        vel_eps = EPS_LAM * (1.0 + float(np.max(np.abs(vel))))
        n = len(rows)
        cones, strict, orders, isos = self._law_cones(rows, slips, lands, loose)
        out = ""  # a strict stick row's impulse out of its cone (the error if nothing else solves the law)
        base = 3 ** len(cones)
        plain = base * 2 ** len(isos)  # the modes with no loose cone left out, then those with one
        radix = [3 if iso[5] in loose else 2 for iso in isos]
        solved = None  # the projected Gauss-Seidel's solution (_law_pgs), where the modes found none first
        if crowded:  # a pile of balls touching at once: cones alone (_law_pgs), else too many rows
            solved = self._law_pgs(w, b, tgts, free, isos, cones, strict, lam_eps, vel_eps)
            if solved is None:
                raise SolverError(step, t_k, "sustained", math.nan, f"impulse law on {n} contacts at once")
        for modes in range(0 if crowded else plain + base * math.prod(radix)):
            if modes == plain and loose:  # before a landing cone is left out: the whole problem at once
                solved = self._law_pgs(w, b, tgts, free, isos, cones, strict, lam_eps, vel_eps)
                if solved is not None:
                    break
            at = modes - plain if modes >= plain else modes
            # 0 stick, 1 Lam_t = -mu Lam_n, 2 +; each cone's digits in its order (its own mode first)
            slips_ = [orders[c][(at // 3**c) % 3] for c in range(len(cones))]
            # then the isotropic cones' (after all of those): 0 stick, 1 slip, each its own first; a loose
            # landing cone: 0 slide, 1 stick (its rows dependent: the least split, _least_split), 2 left out
            upper, digits = at // base, []
            for r_ in radix if modes >= plain else [2] * len(isos):
                upper, d = divmod(upper, r_)
                digits.append(d)
            if modes >= plain and 2 not in digits:
                continue  # tried in the first pass
            slides = [int(d == 0) if iso[5] in loose else d ^ iso[4] for d, iso in zip(digits, isos)]
            joint = any(d == 1 and iso[5] in loose for d, iso in zip(digits, isos))
            rough = any(d < 2 and iso[5] in loose for d, iso in zip(digits, isos))  # a loose cone's friction
            ws = w.copy()  # the columns of the slipping contacts' normal rows: g_n -+ mu g_t
            for (i, pools), mode in zip(cones, slips_):
                for normals, mu in pools if mode else ():
                    ws[:, normals] += (-mu if mode == 1 else mu) * w[:, [i]]
            sliding = {i for (i, _), mode in zip(cones, slips_) if mode}
            slide = [iso for iso, on in zip(isos, slides) if on]
            sliding |= {x for iso in slide for x in iso[:2]}
            # a loose landing cone not sliding: left out (no friction impulse; rows not tight, not checked)
            left = {x for iso, d in zip(isos, digits) if d == 2 and iso[5] in loose for x in iso[:2]}
            sliding |= left
            for mask in range((1 << n) - 1, -1, -1):
                tight = [i for i in range(n) if mask >> i & 1]
                if any(not free[i] and (not mask >> i & 1) != (i in sliding) for i in range(n)):
                    continue
                # a subset of the dependent normals carries it; with a loose cone sticking, all rows may
                least = joint and _spanned(g, tight, [True] * n)
                if dependent and not joint and _spanned(g, tight, spans) or least and any(slips_):
                    continue
                line = weighted = False  # a loose cone slid along a line (line_slide); a second split
                # a sliding cone none of whose normal rows is tight takes no normal impulse, so no friction
                # impulse: not slid (its rows neither tight nor checked), so that the rest may split (fit)
                slide_t = [iso for iso in slide if any(mask >> x & 1 for x in iso[2])]
                if slide_t:
                    lam, why, line = self._law_slide(
                        slide_t, w, ws, b, tight, cones, slips_, lam_eps, loose, g if least else None
                    )
                    out = out or why
                    if lam is None:
                        continue
                elif least:
                    lam, weighted = self._law_least(g, w, b, tight, isos, slides, free, cones, lam_eps)
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
                    and not (least and any(abs(gap[i]) > vel_eps for i in tight))  # its targets consistent
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
                if inside and rough and _gains(lam, b, gap, tgts):  # a loose cone's friction adding energy
                    inside = False
                if inside:
                    break
            else:
                continue
            break
        else:
            if not crowded:  # (crowded: solved above)
                why = out or f"impulse law: no solution on {n} contacts (dependent normals?)"
                raise SolverError(step, t_k, "sustained", math.nan, why)
        if solved is not None:
            lam, tight_set, sliding = solved
            mask = sum(1 << i for i in tight_set)
            slides = [int(iso[0] in sliding) for iso in isos]
            left, least, weighted, line, slide_t = set(), False, True, False, []
        self.least_splits += least
        # the tangent carries a plain least split (sensitivity_held._least_tangent), not a second one, one
        # beside a slide or a slide along a line (_law_tangent), nor the projected Gauss-Seidel's
        why = "friction at an impact" if least and (slide_t or weighted) or line or solved is not None else ""
        lam_full = np.zeros(k.r)
        lam_full[rows] = lam
        dropped = [r for i, r in enumerate(rows) if not mask >> i & 1 and i not in sliding]
        slipped = [rows[i] for i in sorted(sliding - left)]
        for iso in isos:
            if iso[0] in left:  # a loose landing cone left out: README, Known limits
                del lands[iso[5]]
                bare.append(iso[5])
        for (i, o, _, _, on, f), slid in zip(isos, slides):
            if on and slid and lam[i] == 0.0 and lam[o] == 0.0:  # no normal impulse: it slips on as before
                slips = [s for s in slips if s[0] != f]
                slipped = [r for r in slipped if r not in (rows[i], rows[o])]
        p_plus = p + grad.T @ lam_full
        vel_p = self._velocity(q, vel, p_plus)
        self.friction_dropped += self._bare_slides(grad, vel_p, bare)
        return p_plus, lam_full, vel, vel_p, dropped, slipped, slips, lands, why

    def _bare_slides(self, grad, vel_p, bare) -> int:
        """How many of the landing contacts ``bare`` that took no friction impulse (:meth:`_law_lands`, a
        loose cone left out) slide after the law (``vel_p``): their friction was left out (README, Known
        limits). One whose stick rows' velocities are 0 (``SLIDE_EPS``) sticks with a tangential impulse of
        0, inside its cone: Coulomb's law holds (a box landing with a vertex on one wall of a V while its face
        rests on the other: the three normal rows fix the body; its friction is then indeterminate, 0 one
        value)."""
        tiny = SLIDE_EPS * (1.0 + float(np.max(np.abs(vel_p))))
        rows = lambda f: [self._stick_rows[x] for x in (f, self._partner[f]) if x >= 0]  # noqa: E731
        return sum(any(abs(float(grad[r] @ vel_p)) > tiny for r in rows(f)) for f in bare)

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
                    if self._cone_joins(grad, f):
                        out.append((f, []))
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

    def _cone_joins(self, grad, f: int) -> bool:
        """Are both stick rows of the isotropic cone ``f`` (its first tangent) independent of the active rows,
        the second of the first too? Then both are set active (they join the impulse law), else neither."""
        sr, sp_ = self._stick_rows[f], self._stick_rows[self._partner[f]]
        if not self._dependent(grad, sr):
            self.act[sr] = True
            if not self._dependent(grad, sp_):
                self.act[sp_] = True
                return True
            self.act[sr] = False
        return False

    def _law_lands(
        self, q, vel, rows, grad, leave=()
    ) -> tuple[dict[int, int], set[int], np.ndarray, list[int]]:
        """The frictional contacts landing in the impulse law on ``rows`` (a row of their contact among them,
        none held) whose friction joins it (MATH.md *Friction*: Coulomb's impulse at an impact): ``{f:
        owner}``, ``owner = f`` for one whose stick row (an isotropic cone: both) is independent of ``rows``
        and of the stick rows of those before it (it joins the law), else the one-tangent contact whose stick
        row carries its tangent (held and sticking, slipping and joined, or landing before it; a box landing
        flat, two vertices). One whose stick row depends on the normal rows alone takes none. An isotropic
        cone with a dependent row (a box landing flat on four rough vertices: the body has three tangential
        freedoms for eight stick rows) joins *loose* (``loose``, ``owner = f``): it may slide (Coulomb's
        sliding impulse needs no row held) or, where it would stick, is left out (:meth:`_impulse_law`), while
        the law has room for its rows (``MAX_LAW_ROWS``). Their branches are frozen where they land
        (:meth:`_freeze_branch`); with any landing, ``grad`` (the rows' gradients at ``(q, vel)``) is taken
        anew. Returns ``(lands, loose, grad, bare)``, ``bare`` the landing contacts whose friction takes no
        impulse (counted where they slide after the law, :meth:`_bare_slides`)."""
        k = self.k
        out: dict[int, int] = {}
        loose: set[int] = set()
        bare: list[int] = []
        if not self._stick_rows:
            return out, loose, grad, bare
        held = {k.row_contact[r] for r in np.flatnonzero(self.act)}
        hit = {k.row_contact[r] for r in rows} - held
        landing = [
            f
            for f, j in enumerate(k.frictional)
            if j in hit and self._mu_f[f] > 0.0 and not 0 <= self._partner[f] < f
        ]
        if not landing:
            return out, loose, grad, bare
        for f in landing:
            for x in (f, self._partner[f]):
                if x >= 0:
                    self._freeze_branch(x, q)
        grad = k.rows(q, vel)[1]
        act = self.act.copy()
        try:
            self.act[rows] = True
            self.act[list(leave)] = False  # rows that leave in the law (_law_leaving): not tested against
            owners = [g for g, sg in enumerate(self._stick_rows) if self.act[sg] and self._partner[g] < 0]
            room = MAX_LAW_ROWS - len(rows)
            for f in landing:
                sr, pf = self._stick_rows[f], self._partner[f]
                if pf >= 0:  # an isotropic cone: both rows independent, or loose
                    joins = self._cone_joins(grad, f)
                    if joins or room >= 2:
                        if not joins:
                            loose.add(f)
                        out[f] = f
                        room -= 2
                    else:
                        bare.append(f)  # no friction impulse (_bare_slides)
                    continue
                if not self._dependent(grad, sr):
                    self.act[sr] = True
                    out[f] = f
                    owners.append(f)
                    room -= 1
                    continue
                for g in sorted(owners):  # held and sticking or slipping and joined, or landing before
                    if not self._dependent(grad, sr, self._stick_rows[g]):
                        out[f] = g
                        break
                if f not in out:
                    bare.append(f)
        finally:
            self.act = act
        return out, loose, grad, bare

    def _law_cones(self, rows, slips=(), lands=None, loose=()):
        """The held stick rows of the impulse law on ``rows`` with Coulomb's cone: ``[(i, pools)]`` of each
        one-tangent contact ``f`` sticking with its own row (``i`` its index in ``rows``), ``pools`` the
        ``(normals, mu_f)`` whose normal impulses give its room: its own contact's normal rows (indices in
        ``rows``), then those of the one-tangent dependent sticks and landing contacts it carries (``lands``,
        :meth:`_law_lands`; their cones are its room too, as in :meth:`_cone_margin`; they slip with it), in
        index order; ``[(i, normals, mu_f, -1)]`` of the isotropic cones with
        one tangent held, which may only stick; ``isos``: ``[(i, o, normals, mu_f, on, f)]`` of those with
        both held (``i``, ``o`` their indices, ``f`` the first tangent, ``on`` 1 if slipping and joined by
        :meth:`_law_slips` or landing loose, ``loose``), which stick or slip (:meth:`_law_slide`; a loose
        one slides or is left out). A cone coupled to others by a dependent
        stick (:meth:`_cone_split`) is not checked. Then the slipping one-tangent contacts ``slips``, pooled
        the same way. ``orders``: each one-tangent cone's modes in the order tried, its own first (stick ``(0,
        1, 2)``; slipping against ``+`` sliding ``(1, 0, 2)``, against ``-`` ``(2, 0, 1)``)."""
        k = self.k
        cones, strict, orders, isos = [], [], [], []
        slipping = {f for f, _ in slips}
        lands = lands or {}

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
                        on = int(f in slipping or f in loose)  # a loose landing cone: its slide first
                        isos.append((i, o, normals(f), float(self._mu_f[f]), on, f))
                    else:
                        strict.append((i, normals(f), float(self._mu_f[f]), o))
            elif sr in rows and f not in slipping:
                riders = [
                    g
                    for g, owner in enumerate(self._ride)
                    if g != f and (owner == f and self._partner[g] < 0 or lands.get(g, -1) == f)
                ]
                pools = [(normals(g), float(self._mu_f[g])) for g in [f, *riders]]
                cones.append((rows.index(sr), pools))
                orders.append((0, 1, 2))
        for f, riders in slips:
            if self._partner[f] >= 0:
                continue  # an isotropic cone: in isos
            riders = sorted([*riders, *(g for g, o in lands.items() if o == f and g != f)])
            pools = [(normals(g), float(self._mu_f[g])) for g in [f, *riders]]
            cones.append((rows.index(self._stick_rows[f]), pools))
            orders.append((1, 0, 2) if self._slip[f] < 0 else (2, 0, 1))
        return cones, strict, orders, isos

    def _law_slide(self, slide, w, ws, b, tight, cones, slips_, lam_eps, loose=(), least=None):
        """The impulses of the impulse law (:meth:`_impulse_law`) on the tight rows ``tight`` with the
        isotropic cones ``slide`` (each ``(i, o, normals, mu_f, on, f)``) slipping: Coulomb's sliding impulse,
        each cone's tangential impulse ``m_c`` against its tangential velocity after
        (:func:`vcigen.friction.cone_slide`). The law is affine in ``m`` (the tight rows' impulses, the
        one-tangent slipping rows' edges): its value at ``m = 0`` and its columns give each cone's normal
        impulse ``a_c - b_c.m`` (``a_c`` within ``lam_eps`` of 0: none, ``m_c = 0``) and tangential velocity
        after ``g_c + H_c m``, one solve with ``1 + 2 K`` right-hand sides. One cone: its 1-D root. Several
        (two pucks, one landing while the other slides): block Gauss-Seidel, each cone's root with the
        others' ``m`` fixed, a cone whose stick is inside its cone taking the stick for that sweep, until no
        ``m`` moves by ``SLIDE_TOL (1 + max |m|)`` (cones not coupled by the law: the second sweep repeats
        the first). A loose landing cone, ``loose``, whose ``det H`` is within ``DEP_EPS`` of 0 against its
        own rows' ``(w_ii + w_oo)^2`` has its sliding fixed by the tight rows but along one line
        (:func:`vcigen.friction.line_slide`, ``tr H`` above ``DEP_EPS (w_ii + w_oo)``) or wholly (a held cone
        sticking on the body: it cannot slide). Returns ``(lam, "", line)``, ``line`` whether a cone slid
        along a line; ``(None, "", False)`` if a cone sticks at the end (or the rows are singular, or a
        tangent is fixed by them: ``H`` singular), ``(None, why, False)`` if the sweeps do not settle in
        ``SLIDE_SWEEPS``. ``least``: the rows' gradients where the tight rows are dependent (a loose cone
        sliding while others stick: a box landing flat, one vertex sliding): each of the ``1 + 2 K``
        right-hand sides takes its least split (:func:`_least_split`; each lies in the tight rows' range, so
        the law stays affine in ``m``), not a solve."""
        n, nc = len(b), len(slide)
        cols = [x for iso in slide for x in iso[:2]]  # each cone's two stick rows, in order
        lams = np.zeros((1 + 2 * nc, n))  # the law at m = 0, then its columns in m
        if tight:
            rhs = np.column_stack([b[tight], *(-w[tight, x] for x in cols)])
            if least is not None:  # dependent tight rows (a loose cone sticking): each column's least split
                cols_b = np.zeros((n, rhs.shape[1]))
                cols_b[tight] = rhs
                split = _least_split(least, w, cols_b, tight)
                if split is None:
                    return None, "", False
                lams[:] = split.T
            else:
                try:
                    lams[:, tight] = np.linalg.solve(ws[np.ix_(tight, tight)], rhs).T
                except np.linalg.LinAlgError:
                    return None, "", False
        for x, col in enumerate(cols):
            lams[1 + x, col] = 1.0
        for lam in lams:
            for (c, pools), mode in zip(cones, slips_):
                if mode:
                    lam[c] = (-1.0 if mode == 1 else 1.0) * _pooled(pools, lam)
        gaps = lams @ w.T  # their velocities: g_r.qdot+ (less b at m = 0)
        m = [0.0] * (2 * nc)
        lines: set[int] = set()
        hs, normal = [], []  # each cone's H, and its normal impulse at m = 0 and per column of m (fixed)
        for c, (i, o, normals, _, _, f) in enumerate(slide):
            x = 1 + 2 * c
            hs.append((gaps[x, i], gaps[x + 1, i], gaps[x, o], gaps[x + 1, o]))
            normal.append([float(np.sum(lams[y, normals])) for y in range(1 + 2 * nc)])
            own, h = w[i, i] + w[o, o], hs[-1]  # H's scale without the tight rows
            if f in loose and not (h[0] * h[3] - h[1] * h[2] > DEP_EPS * own * own and h[0] + h[3] > 0.0):
                if not h[0] + h[3] > DEP_EPS * own:
                    return None, "", False  # a loose cone whose sliding the tight rows fix: it cannot slide
                lines.add(c)  # fixed but along one line: it slides along it (line_slide)
        for _ in range(SLIDE_SWEEPS):
            moved, stuck = 0.0, False
            for c, (i, o, _, mu, _, _) in enumerate(slide):
                a, h = normal[c][0], hs[c]
                g = [float(gaps[0, i] - b[i]), float(gaps[0, o] - b[o])]
                for x in range(2 * nc):  # the other cones' impulses, fixed
                    if x // 2 != c:
                        a += normal[c][1 + x] * m[x]
                        g[0] += float(gaps[1 + x, i]) * m[x]
                        g[1] += float(gaps[1 + x, o]) * m[x]
                a = a if a > lam_eps else 0.0  # no normal impulse (to round-off): no friction impulse
                slide_ = line_slide if c in lines else cone_slide
                mc = slide_(g, h, (-normal[c][1 + 2 * c], -normal[c][2 + 2 * c]), mu, a)
                if mc is None:
                    det = h[0] * h[3] - h[1] * h[2]
                    if nc == 1 or not det > 0.0:
                        return None, "", False
                    mc, stuck = (-(h[3] * g[0] - h[1] * g[1]) / det, -(h[0] * g[1] - h[2] * g[0]) / det), True
                moved = max(moved, abs(mc[0] - m[2 * c]), abs(mc[1] - m[2 * c + 1]))
                m[2 * c], m[2 * c + 1] = mc
            if nc == 1 or moved <= SLIDE_TOL * (1.0 + max(abs(x) for x in m)):
                break
        else:
            return (
                None,
                (
                    f"impulse law: {nc} isotropic cones slipping at once did not settle in {SLIDE_SWEEPS} "
                    "sweeps at an impact while held"
                ),
                False,
            )
        if stuck:
            return None, "", False
        lam = lams[0].copy()
        for x in range(2 * nc):
            lam = lam + m[x] * lams[1 + x]
        return lam, "", bool(lines)

    @staticmethod
    def _law_least(g, w, b, tight, isos, slides, free, cones, lam_eps) -> tuple[np.ndarray | None, bool]:
        """The impulses of the impulse law (:meth:`_impulse_law`) on the dependent tight rows ``tight``, the
        isotropic cones sticking but those in ``slides`` (their normal rows not tight: no impulse): the least
        split (:func:`vcigen.law_split.least_split`); where it leaves a cone, a second one, each cone's stick
        rows weighted by the square root of its room; where that leaves one too, a split inside the cones
        found from it (:func:`vcigen.law_split.fit`; cones with one normal row each, no one-tangent cone in
        the law). Returns ``(lam, weighted)``, ``weighted`` whether the split is not the least one (the
        tangent does not carry it), ``lam`` None where singular."""
        lam = _least_split(g, w, b, tight)
        if lam is None:
            return None, False
        rooms = [_pooled([(nm, mu)], lam) for _, _, nm, mu, _, _ in isos]
        pairs = [(float(lam[iso[0]]), float(lam[iso[1]]), room) for iso, room in zip(isos, rooms)]
        if not any(math.hypot(x, y) > room + lam_eps for x, y, room in pairs):
            return lam, False
        s = np.ones(len(b))  # a cone left: again, each cone's rows weighted by its room
        for (i, o, *_), room in zip(isos, rooms):
            s[[i, o]] = math.sqrt(max(room, 0.0))
        lam = _least_split(g, w, b, tight, s)
        blocks = _cone_blocks([iso for iso, on in zip(isos, slides) if not on])
        if lam is None or cones or blocks is None:
            return lam, True
        if any(math.hypot(lam[i], lam[o]) > mu * lam[n] + lam_eps for n, i, o, mu in blocks):
            inner = {x for block in blocks for x in block[:3]}
            fitted = fit(g, lam, tight, blocks, [i for i in tight if free[i] and i not in inner], lam_eps)
            lam = lam if fitted is None else fitted
        return lam, True

    @staticmethod
    def _law_pgs(w, b, tgts, free, isos, cones, strict, lam_eps, vel_eps):
        """The law's complementarity problem by projected block Gauss-Seidel (:func:`vcigen.law_pgs.pgs`),
        where every frictional contact of the law is an isotropic cone with one normal row (no one-tangent
        cone, no strict one): ``(lam, tight, sliding)`` where its result meets the law's conditions (each
        normal row's impulse >= 0 and its velocity at its target where it pushes, above it where not; each
        cone sticking inside it or sliding on its edge against its velocity after; the other rows at their
        targets; no kinetic energy added, :func:`_gains`) to ``100 EPS_LAM``; else None."""
        blocks = _cone_blocks(isos)
        if cones or strict or blocks is None:
            return None
        inner = {x for block in blocks for x in block[:3]}
        normals = [i for i in range(len(b)) if free[i] and i not in inner]
        equal = [i for i in range(len(b)) if not free[i] and i not in inner]
        lam = pgs(w, b, blocks, normals, equal)
        if lam is None:
            return None
        gap = w @ lam - b
        tl, tv = 100.0 * lam_eps, 100.0 * vel_eps
        tight, sliding = [], set()
        for i in [*normals, *(n for n, *_ in blocks)]:
            if lam[i] < -tl or gap[i] < -tv or (lam[i] > tl and gap[i] > tv):
                return None
            tight += [i] if gap[i] <= tv else []
        if any(abs(gap[i]) > tv for i in equal):
            return None
        tight += equal
        for n, i, o, mu in blocks:
            room, t, u = mu * lam[n], math.hypot(lam[i], lam[o]), math.hypot(gap[i], gap[o])
            against = lam[i] * gap[i] + lam[o] * gap[o] <= -(1.0 - 1e-9) * t * u
            if u <= tv and t <= room + tl:
                tight += [i, o]  # sticking
            elif abs(t - room) <= tl and against:
                sliding |= {i, o}  # on its edge, against its sliding after (none: no normal impulse)
            else:
                return None
        if _gains(lam, b, gap, tgts):
            return None
        return lam, sorted(tight), sliding

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

    def _law_tangent(self, lam, slipped, slips, lands, why: str = ""):
        """The impulse law (:meth:`_impulse_law`) as the tangent takes it (``Tracker._impulse``): ``(tight,
        slides, why)``, ``tight`` the rows with an impulse but the stick rows of the one-tangent contacts
        sliding through it (their impulse follows from their normal rows'), ``slides`` per row of ``tight``
        ``(sr, sgn, j)`` for a normal row of such a contact (Coulomb's sliding impulse along the stick row
        ``sr`` of its owner, sign ``sgn``, contact ``j``'s mu) or None: the slipping contacts that joined
        (``slips``, the sign of their slip) and the landing ones (``lands``) whose owner slid on an edge (the
        sign of its impulse); ``(t1, t2, w_hat, j)`` for a normal row of an isotropic cone that slid, landing
        or slipping on through it without riders: ``-mu_j N w_hat`` on its stick rows ``t1, t2`` (``w_hat``
        its direction: the tangent turns it with the sliding after, ``Tracker._cone_slides``). ``why``: the
        law's own (:meth:`_impulse_law`), passed through."""
        k = self.k
        along = {}
        skip = set()
        for f, riders in slips:
            if self._partner[f] >= 0 and self._stick_rows[f] in slipped and not riders:  # a cone slipping on
                self._cone_along(along, skip, lam, f, f)
                continue
            skip.add(self._stick_rows[f])
            for g in [f, *riders]:
                along[k.frictional[g]] = (
                    self._stick_rows[f],
                    math.copysign(1.0, self._slip[f]),
                    k.frictional[g],
                )
        for g, o in lands.items():
            so, po = self._stick_rows[o], self._partner[o]
            if po >= 0 and so in slipped:  # a landing cone sliding
                self._cone_along(along, skip, lam, o, g)
                continue
            if so not in skip and so not in slipped or po >= 0:
                continue  # sticking (its stick row, or a cone's two, tight)
            sgn = math.copysign(1.0, self._slip[o] if so in skip else float(lam[so]))
            skip.add(so)
            along[k.frictional[g]] = (so, sgn, k.frictional[g])
        tight = [int(r) for r in np.flatnonzero(lam) if int(r) not in skip]
        return tight, [along.get(k.row_contact[r]) for r in tight], why

    def _cone_along(self, along: dict, skip: set, lam, o: int, g: int) -> None:
        """:meth:`_law_tangent` for the cone ``o`` (its first tangent) of contact ``g``'s that slid in the
        law: ``-mu N w_hat`` on its two stick rows (``skip``), ``w_hat = -(Lam_t1, Lam_t2) / |.|``."""
        t1, t2 = self._stick_rows[o], self._stick_rows[self._partner[o]]
        tang = np.array([float(lam[t1]), float(lam[t2])])
        skip.update((t1, t2))
        along[self.k.frictional[g]] = (t1, t2, -tang / max(math.hypot(*tang), 1e-300), self.k.frictional[g])
