"""Sustained contact: the phases of MATH.md *Sustained contact*, for :class:`vcigen.stepper.Stepper`.

A grid step with active rows (``vcigen.rows``: contacts held at ``psi_r = 0`` and bilateral
constraints) is a chain of *constrained segments*, each the constrained discrete
Euler-Lagrange step (RATTLE in position-momentum form; routines ``rattle`` and
``rattle_project``), cut where

* an active contact's force would turn negative (**lift-off**, located as the root of the
  continuous contact force along the sub-step map, like the contact time (47)); the rest of
  the step runs without it;
* an inactive row is crossed (an **impact while another contact is active**), resolved by
  the impulse law below.

Entry: a free impact (47)-(48) whose outgoing normal speed is below what the jump resolves at
this ``h`` (``e |dphi/dt| <= Tolerances.rest * h * |d2phi/dt2|`` with forces pressing in),
or for which (48a) has no root ``mu > 0`` while forces press the body in, is completed as a
*plastic* impact: normal velocity to 0, tangential momentum kept, the contact active. Where
forces do not press it in, a rootless impact is *grazing*: the continuous law
``n.qdot -> -e n.qdot`` (touch and go).

The impulse law of an impact with rows active and of the plastic entry is :mod:`vcigen.held_impacts`;
the friction modes of the held rows (MATH.md *Friction*) are :mod:`vcigen.friction_modes`; what the phases
share (tolerances, :class:`~vcigen.held_roots.End`, the Illinois root finder) is :mod:`vcigen.held_roots`;
the events located inside a constrained segment (lift-off, a row crossed or dipped) are
:mod:`vcigen.held_locate`, and the hooks of the tangent through a held step's events
:mod:`vcigen.held_tangent`.
"""

from __future__ import annotations

import math

import numpy as np

from .errors import SolverError
from .friction_modes import FrictionModes
from .held_impacts import HeldImpacts
from .held_locate import HeldLocate
from .held_roots import (
    BACK_CYCLES,
    DEP_EPS,
    E_SHORT,
    EPS_LIFT,
    JAM_CYCLES,
    LEAVE_STEPS,
    LIFT_CYCLES,
    ONTO_ITER,
    SLIDE_EPS,
    SPLITS,
    SPURIOUS,
    STICK_CYCLES,
    End,
    span_add,
)
from .held_tangent import HeldTangent
from .impact_step import Seg
from .result import KINDS


def rattle_segment(k, q, p, tau, x0, act):
    """``Kernels.rattle_segment`` from the kernels' single calls (the C kernels use this).

    The constrained step ``rattle`` from ``x0``, ``p+`` and ``E_d`` of its segment, the projection
    ``rattle_project`` from ``(v, 0)``, and the evaluations at the end:
    ``(x, |res|, p+, E_d, y, |res'|, end)``. With internal points ``x0`` and ``x`` are ``(v, Lam, Lam_m)``:
    the Newton runs on ``(v, Lam, Lam_m, u)`` from ``u = 0`` and ``rattle_end`` gives ``p+``, ``E_d``.
    """
    n, ns = k.n, k.system.stages
    x, res = k.solve("rattle", np.append(x0, np.zeros(ns)), q, p, tau, act)
    v = x[:n]
    q1 = q + tau * v
    if ns:
        nx = x.size - ns
        p_plus, e_seg = k.rattle_end(q, v, tau, x[nx:], x[n + k.r : nx], act)
        x = x[:nx]
    else:
        _, p_plus, e_seg = k.segment(q, v, tau)
    y, res1 = k.solve("rattle_project", np.concatenate([v, np.zeros(k.r)]), q1, p_plus, act)
    u1 = y[:n]
    psi, grad, curv = k.rows(q1, u1)
    t0 = k.t
    if k.timed:  # the forces at the segment's end, at its time
        k.at(t0 + tau)
    end = End(psi, grad, curv, k.dynamics(q1, u1)[0], k.legendre(q1, u1)[1])
    if k.timed:
        k.at(t0)
    return x, res, p_plus, e_seg, y, res1, end


class SustainedSteps(FrictionModes, HeldImpacts, HeldLocate, HeldTangent):
    """The sustained-contact phases; mixed into :class:`~vcigen.stepper.Stepper`."""

    # -- state of a run ------------------------------------------------------------
    def _init_sustained(self) -> None:
        """No contact held; bilateral constraints always are."""
        k = self.k
        self.act = np.array(k.row_bilateral, dtype=bool) if k.r else np.zeros(0, dtype=bool)
        nf = len(getattr(k, "frictional", ()))
        self._stick_rows = [
            k.row_stick.index(f) for f in range(nf)
        ]  # the stick row of each frictional contact
        self._slip = np.zeros(nf)  # -mu_f s of each frictional contact while it slips (s: sliding direction)
        self._ref = np.zeros(nf)  # its tangent's value while it sticks
        self._mu_f = k.friction(np.zeros(k.n))[0][list(k.frictional)] if nf else np.zeros(0)
        counts = getattr(k, "branch_count", ())
        self._branch = np.zeros(sum(counts))  # the signs each sticking tangent is frozen at
        self._branch_of = [list(range(sum(counts[:f]), sum(counts[: f + 1]))) for f in range(nf)]
        self._held_rows = [0] * nf  # the active rows (a bitmask) each frictional contact's mode was set on
        # the sticking frictional contact whose stick row holds contact f's tangent too (a dependent stick, no
        # row of its own: statically indeterminate), f itself if the other active rows hold it, -1 if none
        self._ride = [-1] * nf
        self._partner = list(getattr(k, "partner", ())) or [-1] * nf  # the other tangent of a cone contact
        if nf:
            k.set_friction(self._slip, self._ref, self._branch)
        self.liftoffs: list[tuple[float, str]] = []
        self.kinds = {kind: 0 for kind in KINDS}
        self.passes = 0  # lift-offs whose load a riding row took (_pass_load)
        self.sticks_kept = 0  # stick <-> slip cycles (STICK_CYCLES slides in a step) cut by sticking on
        self.lifts_kept = 0  # lift-off <-> landing cycles at one instant cut by holding the row on (_chain)
        self._left_step: dict[int, int] = {}  # the grid step of each row's last release (_met_back)
        self._sunk: dict[int, int] = {}  # the grid step each row was last held on by _sinks_free
        self._sunk_at: dict[int, float] = {}  # where its force vanished, logged at its release (_sinks_free)
        self._stuck_on: set[int] = set()  # stick rows held on at this instant, their force out of the cone
        self.jams = 0  # Painleve jams (JAM_CYCLES lift-offs in a step, _painleve) resolved by sticking (_jam)
        self._jammed = False  # at a jam: every held frictional contact sticks (_friction_modes)
        self.halvings = 0  # held segments halved (_split_segment: their Newton failed or root was spurious)
        self._lam = np.zeros(k.r)
        self._on_rows = np.zeros(k.r, dtype=bool)  # the active rows the state was last put on (_onto_rows)
        # a rule with internal points holds them too (derive.held_internal_points), each with its multipliers
        rule = k.system.rule
        self._stages, self._inner_ratio, self._lam_rate = rule.stages, rule.inner_ratio, rule.lam_rate
        self._force = np.zeros(k.m)  # mean multipliers of the step being taken, per contact
        self._cforce = np.zeros(len(k.system.model.constraint) if k.r else 0)  # and per constraint
        self._booked = False  # whether a constraint acted in it
        self._chained = False  # whether it ran the constrained chain (the active set may have changed)
        self._held = bool(self.act.any())  # whether any row is active at the start of the next step
        self._braked = False  # whether cones were aimed implicitly in this step (_cone_brake)

    def _start_sustained(self, q0, v0, h: float) -> None:
        """Active rows at the start: bilateral constraints, and contacts touched at rest (``|rate| <=
        Tolerances.admissible / h``) and pressed in under the forces of the bilateral rows and of the rows
        held so far, tested again till none is added (a pendulum at rest against a wall is pressed in by its
        rod alone, a ladder at rest against a wall by the floor's force: tested once, under the bilateral
        rows' forces alone, its wall took a plastic impact of 2.5e-9 at t = 1.2e-9), or moving below the
        jump's resolution and pressed in by the free motion (moving into the corner a bilateral row makes with
        the contact is an impact; moving out, only where the free path comes back within the step: held, the
        first step pulled it back), or at rest where the free path curves into them within the step (to second
        order: released at rest on a bowl's rim, where the wall is vertical and ``phi'' = 0``, the free fall
        leaves the bowl at fourth order; not held, it crossed the wall again and again at once). A rough
        contact (Coulomb's cone, ``mu_f > 0``) moving faster than ``Tolerances.admissible / h`` is not held:
        moving in, it takes its impact at the start, with friction (held at once, the first held step would
        take its normal speed as a force, and the friction with it); moving out, it flies and lands as an
        impact (held, the first step pulled it back, and a pulling normal force reverses sliding friction: a
        rough star spun on a face gained energy 1400-fold in one step); a frictionless one is held (the map
        stays smooth in ``v0`` for the tangent). The first held step's Newton starts from the forces holding
        the rows at ``(q0, v0)`` (:meth:`_contact_forces`): from 0, C's did not converge on a bob at rest in
        the corner of its rod and a wall 2.6 degrees apart at ``h = 0.1``, where the wall pushes with 22 ``m
        g``."""
        k = self.k
        self._init_sustained()
        if not k.r or self.tol.grazing != "contact":
            return
        psi, grad, _ = k.rows(q0, v0)
        rates = grad @ v0
        frees = self._row_accel(q0, v0, self._accel(q0, v0, np.zeros(k.r)))
        still = self.tol.admissible / h
        added = True
        while added:  # again under the forces of the rows held so far, till none is added
            acc = self._accel(q0, v0, self._contact_forces(q0, v0))  # first: under the bilateral rows' forces
            accs = self._row_accel(q0, v0, acc)
            ahead = k.rows(q0 + h * v0 + 0.5 * h * h * acc, v0)[0]  # the free path's end, to second order
            added = False
            for r in range(k.r):
                skip = self.act[r] or k.row_bilateral[r] or k.row_stick[r] >= 0
                if skip or abs(psi[r]) > self.tol.admissible:
                    continue
                if abs(rates[r]) <= still:  # at rest: pressed in, or curving in ahead of the free path
                    held = self._settles(rates[r], accs[r], 1.0, h) or ahead[r] < -self.tol.phi
                else:  # moving: pressed in by the free motion (a bilateral row's reaction alone: a corner)
                    held = (
                        self._settles(rates[r], frees[r], 1.0, h)
                        and not self._rough([k.row_contact[r]])
                        and (rates[r] < 0.0 or ahead[r] < -self.tol.phi)
                    )  # a rough one moving in takes its (plastic) impact, with friction, at t = 0 first, one
                    # moving out flies; a frictionless one moving out is held only where its free path comes
                    # back
                if held:
                    self._hold(grad, r)
                    added = added or bool(self.act[r])
        self._friction_modes(q0, v0)
        self._held = bool(self.act.any())
        if self._held:  # the first held step's Newton starts from the forces holding the rows at (q0, v0)
            lam = self._contact_forces(q0, v0) * (h / self._lam_rate)
            self._lam = np.where(self.act & np.isfinite(lam), lam, 0.0)

    def _settles(self, rate: float, acc: float, e: float, h: float) -> bool:
        """Forces press the row in and the outgoing normal speed is below the jump's resolution."""
        return acc < 0.0 and e * abs(rate) <= self.tol.rest * h * abs(acc)

    def _departs(self, rate: float, acc: float, e: float, h: float) -> bool:
        """Restitution ``e < 1``, forces not pressing the row in, and the outgoing normal speed below the
        jump's resolution: completed as plastic, it touches and goes (MATH.md *Entry*, ``"grazing"``)."""
        return e < 1.0 and acc >= 0.0 and e * abs(rate) <= self.tol.rest * h * abs(acc)

    def _accel(self, q, u, lam_rows) -> np.ndarray:
        """``qddot`` from ``M qddot = rhs + sum lam_r grad psi_r`` (lam: force per unit time)."""
        k = self.k
        rhs, _ = k.dynamics(q, u)
        mass = k.legendre(q, u)[1]
        if k.r and np.any(lam_rows):
            rhs = rhs + self._dirs(k.rows(q, u)[1]).T @ lam_rows
        return np.linalg.solve(mass, rhs)

    def _row_accel(self, q, u, acc) -> np.ndarray:
        """``d2 psi_r / dt2 = grad psi_r . qddot + u . Hess psi_r . u`` for every row."""
        _, grad, curv = self.k.rows(q, u)
        return grad @ acc + curv

    def _contact_forces(self, q, u) -> np.ndarray:
        """The force ``lambda_r`` of each active row keeping ``d2 psi_r/dt2 = 0`` at ``(q, u)`` (0 elsewhere).

        ``G M^-1 (rhs + G^T lambda) + curv = 0`` over the active rows: the continuous normal force at
        the discrete state, second-order accurate where the state is; lift-off is where it vanishes.
        """
        k = self.k
        if not self.act.any():
            return np.zeros(k.r)
        _, grad, curv = k.rows(q, u)
        return self._forces(End(None, grad, curv, k.dynamics(q, u)[0], k.legendre(q, u)[1]))

    def _forces(self, end: End) -> np.ndarray:
        """:meth:`_contact_forces` from the evaluations at a segment's end."""
        out = np.zeros(self.k.r)
        rows = np.flatnonzero(self.act)
        if rows.size == 0:
            return out
        rhs, mass, grad, curv = end.rhs, end.mass, end.grad, end.curv
        g = grad[rows]
        minv = np.linalg.solve(mass, np.column_stack([rhs, self._dirs(grad)[rows].T]))
        out[rows] = np.linalg.solve(g @ minv[:, 1:], -(g @ minv[:, 0] + curv[rows]))
        return out

    def _split_segment(self, step, t_k, q, p, tau, guess):
        """The chain's constrained segment from ``(q, p)`` over ``tau`` (:meth:`_constrained`); where its root
        is spurious (:meth:`_spurious`), or its Newton fails while a rough contact is held
        (:meth:`_halvable`), over ``tau / 2``, ``tau / 4``, ... (``SPLITS`` halvings at most), each from the
        velocity of ``p``: ``(the length taken, the halvings, the segment)``. None holding: the last one's
        ``SolverError``, or one naming its spurious root. A rough star sliding on a vertex at ``mu = 5`` near
        Painleve's boundary, its slide stopping within a millisecond, took over ``h = 0.1`` a root that turned
        it 20 rad with a pulling normal force; rough stars started sliding on a corner at ``h = 0.05`` failed
        their first Newton. A frictionless segment whose Newton fails is a step too coarse for its row and
        raises as before: halved, a particle in an ellipse of radius 0.02 at ``h = 0.01`` ran on, its energy
        up 3.6e11-fold, to a later failure. ``None`` where every halving's root is spurious, or the last one's
        Newton fails, while a held rough contact slips (also after a jam at this instant, a stick row having
        slid from it: the next slide there sticks on, ``STICK_CYCLES``): the slide has no root down to ``tau /
        2^SPLITS``, whose velocity tends to a jump's, Painleve's inconsistency of two contacts at once (a box
        wedged in a rough V rocking to rest on a corner of each wall, both sliding from rest:
        ``bench.box_v_drops --seed 51``, drop 32), or none at all (a hoop with a mass on its rim slipping at
        ``mu = 3`` just inside Painleve's boundary, ``grad . M^-1 d`` 1.3e-3 of ``grad . M^-1 grad``:
        ``bench.hoop_drops --seed 232 --h 0.05``, drop 767), which the chain resolves as :meth:`_painleve`'s,
        by the tangential impact at the segment's start (:meth:`_jam`)."""
        halved = 0
        while True:
            failed = None  # the Newton's failure, or None: a root
            try:
                seg = self._constrained(step, t_k, q, p, tau, guess)
            except SolverError as exc:
                if halved < SPLITS and not self._halvable(step):
                    raise  # frictionless: too coarse a step, not halved (_halvable)
                seg, failed = None, exc
            if seg is not None:
                ratio = self._spurious(q, p, tau, seg, guess)
                if ratio is None:
                    return tau, halved, seg
                if halved == SPLITS and self._reverses(q, p, seg, guess):
                    return tau, halved, seg  # its slide stops inside: the chain keeps that part
            if halved == SPLITS:
                if self._slip.any() and self._rough_held():  # also after a jam at this instant
                    return None  # wedged: no slide the halvings resolve; the chain jams (_jam)
                if failed is not None:
                    raise failed
                raise SolverError(
                    step,
                    t_k,
                    "sustained",
                    0.0,
                    f"a held segment's root is spurious: the kinetic energy of its velocity is "
                    f"{ratio:.3g} times its start's and the forces' over it, after {SPLITS} halvings; "
                    "reduce h",
                )
            halved += 1
            tau *= 0.5
            guess = self._velocity(q, guess, p)

    def _spurious(self, q, p, tau: float, seg, guess) -> float | None:
        """``T / (T(u0) + tau^2 rhs . M^-1 rhs / 2)`` of the segment ``seg`` (:meth:`_constrained`'s) where it
        exceeds ``SPURIOUS`` (``u0`` the velocity of ``p``; ``T`` the kinetic energy of its velocity ``v`` or
        of its end's ``u1``, the larger): a velocity no start and no applied force over ``tau`` gives (the
        rows' forces do no work, friction takes energy), nor the rows' offsets closed over ``tau``
        (:meth:`_gap_energy`); else ``None``. Forces of time are read at the segment's start and end (at ``q,
        u0``), the larger (since stop 68): read at the start alone, where the plate's force was small, a box
        on a vibrating plate had its segments halved 23 times in a run, 4 now (``bench.plate_drops --seed 444
        --h 0.01``, drop 992). The bound holds for the exact motion's velocity at every instant
        (``SPURIOUS``), so for the end's too: a rough hoop's segment of 0.025 whose velocity was within it
        ended at 87 m/s from 2.2 (its lift-off's part then took a root of that kind, the energy 84.5 -> 711 in
        one step: ``bench.hoop_drops --seed 417``, drop 843, at ``h`` = 0.025 and 0.05)."""
        k = self.k
        v, u1, end = seg[0], seg[7], seg[8]
        u0 = self._velocity(q, guess, p)
        mass = k.legendre(q, u0)[1]
        rhs = k.dynamics(q, u0)[0]
        work = float(rhs @ np.linalg.solve(mass, rhs))
        budget = 0.5 * float(u0 @ mass @ u0) + 0.5 * tau * tau * work
        kinetic = max(0.5 * float(v @ mass @ v), 0.5 * float(u1 @ end.mass @ u1))
        if kinetic > SPURIOUS * budget + 1e-24:  # and the rows' offsets: the root closes them over tau
            if self._timed:  # forces of time: at the segment's end too, the larger (read only here: a budget
                t0 = self.k.t  # that already holds needs no more)
                self._at(t0 + tau)
                rhs = k.dynamics(q, u0)[0]
                self._at(t0)
                work = max(work, float(rhs @ np.linalg.solve(mass, rhs)))
                budget = 0.5 * float(u0 @ mass @ u0) + 0.5 * tau * tau * work
            budget += self._gap_energy(q, u0, mass, tau)
        return kinetic / budget if kinetic > SPURIOUS * budget + 1e-24 else None

    def _gap_energy(self, q, u, mass, tau: float) -> float:
        """The least kinetic energy that closes the active rows' offsets ``psi_r(q)`` over ``tau``, ``psi .
        (G M^-1 G^T)^-1 psi / (2 tau^2)`` (0 where the rows are dependent). A root closes them (RATTLE): over
        the last 1.6e-9 s of a step, a rough cube's stick rows 1e-16 off their anchors moved it at 7e-8, 5e8
        times what its rest and the forces give, and halving the piece only raised that (C and CasADi raised
        "a held segment's root is spurious", drop 636 of ``bench.cube_drops --seed 21``, rough)."""
        rows = np.flatnonzero(self.act)
        psi, grad, _ = self.k.rows(q, u)
        off = psi[rows]
        try:
            return 0.5 * float(off @ np.linalg.solve(row_matrix(grad[rows], mass)[1], off)) / (tau * tau)
        except np.linalg.LinAlgError:
            return 0.0

    def _reverses(self, q, p, seg, guess) -> bool:
        """Does the segment ``seg`` reverse a slide (a slipping contact's sliding velocity of opposite signs
        at its ends)? Its last halving, spurious, is then kept: the chain stops the slide inside it
        (:meth:`_friction_events`) and drops the rest, where the friction pushed. A star on a corner at ``mu
        = 5`` whose slide at 3e-4 stops at once gained 885-fold over ``h = 0.005`` and still 1.5e4-fold over
        ``h / 64``; the stop, located, is within 1e-7 s. A slide from rest (its start sliding within
        ``SLIDE_EPS``, whose sign is round-off's) slides against its friction, ``-sign(slip)``: a rough cube
        whose cones a large internal stick force broke at rest kept the last halving in C and raised on
        CasADi by that sign (``bench.cube_books --seed 5``, drop 39)."""
        if not self._slip.any():
            return False
        u0, u1, end = self._velocity(q, guess, p), seg[7], seg[8]
        grad = self.k.rows(q, u0)[1]
        tiny = SLIDE_EPS * (1.0 + float(np.max(np.abs(u0))))
        for f, sr in enumerate(self._stick_rows):
            if self._slip[f]:
                s0 = float(grad[sr] @ u0)
                s0 = -self._slip[f] if abs(s0) <= tiny else s0
                if s0 * float(end.grad[sr] @ u1) < 0.0:
                    return True
        return False

    def _onto_rows(self, q, guess, p):
        """``q`` moved onto the active rows where one held since the last call is off by more than
        ``Tolerances.phi`` (a start touching within ``Tolerances.admissible``, a face's second vertex): the
        least move in ``M``'s norm, ``ONTO_ITER`` Gauss-Newton steps ``dq = -M^-1 G^T (G M^-1 G^T)^-1 psi``;
        else (or where the rows are dependent) ``None``. Held, a segment takes the rows' offset ``d`` into its
        velocity as ``d / tau``: a sub-step cut at an event near its start ran at 1e3 m/s, its friction with
        it, and the next segment's Newton, started there, took a root a whole turn of the star away (fuzzed
        rough stars started 1e-10 off a face, a whole turn a step from then on)."""
        k = self.k
        new = self.act & ~self._on_rows
        self._on_rows = self.act.copy()
        if not new.any():
            return None
        u = self._velocity(q, guess, p)
        psi = k.rows(q, u)[0]
        if float(np.max(np.abs(psi[new]))) <= self.tol.phi:
            return None
        rows = np.flatnonzero(self.act)
        mass = k.legendre(q, u)[1]
        moved = None  # q after the last step that could be taken (C returns whether one was)
        for _ in range(ONTO_ITER):
            psi, grad, _ = k.rows(q, u)
            try:
                minv_g, delassus = row_matrix(grad[rows], mass)
                q = moved = q - minv_g @ np.linalg.solve(delassus, psi[rows])
            except np.linalg.LinAlgError:
                break
        return moved

    def _contact_accel(self, q, u, nrm, group, weights) -> float:
        """``d2 phi/dt2`` along the impulse direction ``nrm`` of a free impact on ``group``."""
        rhs, curv = self.k.dynamics(q, u)
        acc = np.linalg.solve(self.k.legendre(q, u)[1], rhs)
        return float(nrm @ acc + sum(w * curv[j] for j, w in zip(group, weights)))

    # -- the chain of constrained segments ---------------------------------------------
    def _constrained(self, step, t_k, q, p, tau, guess):
        """One constrained segment (RATTLE): ``(v, Lam, q1, p+, E_d, Lam', p1, u1, end)``.

        ``u1`` is the velocity of ``p1``; ``end`` holds the rows, dynamics and mass at ``(q1, u1)``
        (``Kernels.rattle_segment``: one call of the kernels for all of it).
        """
        k = self.k
        n, r = k.n, k.r
        act = self.act.astype(float)
        lam0 = np.where(self.act, self._lam * (tau / self._h), 0.0)
        x0 = np.concatenate([guess, lam0, np.tile(lam0 * self._inner_ratio, self._stages)])
        x, res, p_plus, e_seg, y, res1, end = k.rattle_segment(q, p, tau, x0, act)
        self._check(res, p, step, t_k, "sustained")
        self._check(res1, p_plus, step, t_k, "sustained")
        v = x[:n]
        lam, lam1 = (
            np.where(self.act, x[n : n + r], 0.0),
            np.where(self.act, y[n:], 0.0),
        )  # 0 off the active rows
        p1 = p_plus + self._dirs(end.grad).T @ lam1
        # the tangent's (Tracker.held): Lam' alone and the internal points' Lam_m (0 off the active rows)
        self._seg_inner = lam1, np.where(np.tile(self.act, self._stages), x[n + r :], 0.0)
        for s in range(self._stages):  # the internal points' impulses: booked with Lam' (after the start)
            lam1 = lam1 + np.where(self.act, x[n + r * (s + 1) : n + r * (s + 2)], 0.0)
        return v, lam, q + tau * v, p_plus, e_seg, lam1, p1, y[:n], end

    def _chain(self, step, t_k, h, q, p, t, tau, guess, impacts, e_step):
        """The rest of a grid step from ``(q, p)`` at ``t`` (``tau`` left) with the active rows held."""
        k, tol = self.k, self.tol
        self._chained = True
        plain = True  # no event, no change of friction mode so far: a held step the tangent goes through
        turn = -1  # the stick row that slid at this instant (a stop of it here turns it, _friction_switch)
        self._braked = False  # cones aimed implicitly near rest (_cone_brake): no tangent
        passed: set[int] = set()  # rows that passed their load at this instant (_pass_load): none passes back
        hit: set[int] = set()  # rows an impact while held met at this instant (_chain_impact: again, held)
        pulls: dict[int, int] = {}  # rows lifted off and met again at this instant: pulls since (LIFT_CYCLES:
        # held on to the next instant)
        slid: dict[int, int] = {}  # stick rows that slid from rest in this step, how often
        relands: dict[int, int] = {}  # rows that lifted off (or passed their load) in this step: landings
        backs: dict[int, int] = {}  # rows met again moving away after their release (_met_back): how often
        struck = False  # an impact or a friction switch at this segment's start: held forces read there too
        self._stuck_on.clear()
        self._jammed = False
        rest = tau  # the time left of the grid step; tau: the segment's (less where _split_segment halved it)
        e_at = None  # E_d at the segment's start where known (its last event's; an impact's after it)
        cap = (math.nan, rest, 0)  # (t, the longest segment from t, its halvings): _halve_part's
        while True:
            self._at(t)
            if rest <= 1e-13 * h:
                self._ev_rest_end(q, p, guess)  # events carried to the step's end: the tangent there
                return q, p, (e_step if e_step is not None else math.nan), guess
            if self._stick_rows:
                mode = self._friction_mode()
                before = self._friction_state() if self._ev_tan is not None else None  # the events' tangent's
                self._friction_modes(q, self._velocity(q, guess, p), rest)
                # a switch (stick, slip, released, another face) or a cone's slip aimed anew: no tangent
                same = mode == self._friction_mode()
                if not same and before is not None and not self._no_switch(before):  # let go, held anew: none
                    # a switch at a segment's start: not located (after a plastic entry: its impact)
                    entry = plain and self._ev_entry
                    self._sw_lose("plastic impact" if entry else "friction switch in a held step")
                if self._braked and self._ev_tan is not None and self._ev_tan.active:
                    self._ev_tan.lose("held step (sustained contact)")
                self._fswitch = self._fswitch or (plain and not same)  # what stops the tangent
                plain = plain and same and not self._braked
            if not self.act.any():
                return self._free_rest(step, t_k, h, q, p, t, rest, guess, impacts, e_step)
            moved = self._onto_rows(q, guess, p)
            if moved is not None:  # a move, not a segment: the tangent has no derivative of it
                q = moved
                self._sw_lose("start moved onto the held rows")
                plain = False
            if not plain:  # a constrained segment after an event: no lift-off then a free rest
                if self._lift_seg is not None:  # the lift-off is one event of several (Tracker.event)
                    self._ev_event(*self._lift_seg, "lift")
                self._lift_seg = None
            slips = self._slip.any() and not self._jammed  # past Painleve's boundary at the start: no segment
            u0 = self._velocity(q, guess, p) if slips else None  # the jam's (past only where slipping)
            past = slips and self._painleve(k.rows(q, u0)[1], k.legendre(q, u0)[1])
            if not past:
                length = min(rest, cap[1]) if cap[0] == t else rest  # halved for its event (_halve_part)
                split = self._split_segment(step, t_k, q, p, length, guess)
                past = split is None  # wedged: jammed as past Painleve's boundary
            if not past:
                tau, halved, seg = split
                v, lam, q1, _, e_seg, lam1, p1, u1, end = seg
                struck_seg = struck  # restored where the segment is halved for its event (_halve_part)
                self.halvings += halved
                if halved:  # not a segment of the step's map: the tangent has none
                    self._sw_lose("held segment halved")
                    plain = False
                past = slips and self._painleve(end.grad, end.mass)
            if past:
                if u0 is None:  # wedged after a jam at this instant (its slips not read at the start)
                    u0 = self._velocity(q, guess, p)
                self._jam(q, u0)  # the tangential impact, at the segment's start
                self._fswitch = self._fswitch or plain
                self._sw_lose()
                plain = False
                continue
            e_step = e_seg if (e_step is None or self._forced) else e_step
            unilateral = self.act & ~np.asarray(k.row_bilateral, dtype=bool) & (np.asarray(k.row_stick) < 0)
            events = {}
            f1 = self._forces(end)
            try:  # a location failing while a rough contact is held: the segment halved (_halve_part)
                if self._stick_rows:
                    self._friction_events(step, t_k, q, p, tau, v, u1, end, f1, events)
                f1p = self._pressed(f1, end.grad)
                pulled = unilateral & (f1p < -EPS_LIFT * (1.0 + float(np.max(np.abs(f1p)))))
                f0 = self._start_forces(q, self._velocity(q, v, p)) if struck else None
                if f0 is not None:  # pulled at the impact's instant, pushed again by the segment's end
                    pulled |= unilateral & (f0 < -EPS_LIFT * (1.0 + float(np.max(np.abs(f0)))))
                pulled[[r for r, n in pulls.items() if n >= LIFT_CYCLES]] = False  # held on
                if pulled.any():
                    f0 = self._start_forces(q, self._velocity(q, v, p)) if f0 is None else f0
                    for r in np.flatnonzero(pulled):
                        events[int(r)] = (
                            "lift",
                            self._liftoff_fraction(step, t_k, q, p, tau, v, int(r), f0[r], f1p[r]),
                        )
            except SolverError as exc:
                cap = self._halve_part(step, t_k, t, tau, cap, exc=exc)
                struck, plain = struck_seg, False
                continue
            for r, (kind, s) in events.items():  # within the least sub-step (1e-13 h): at the start
                events[r] = (kind, 0.0 if s * tau <= 1e-13 * h else s)
            if any(s == 0.0 for _, s in events.values()):  # at the segment start: release or switch there
                # a friction switch first: a stick force out of its cone says nothing of the normal force
                # (sticking, it may pull; slipping, it presses), and a release there would land again at once
                r = min(
                    (r for r, (_, s) in events.items() if s == 0.0), key=lambda r: (events[r][0] == "lift", r)
                )
                self._fswitch = self._fswitch or (plain and events[r][0] in ("stop", "slide"))
                if events[r][0] in ("stop", "slide") and not self._sw_back(events[r][0]):
                    self._sw_lose()  # at the start: not located (a slide back at a stop: _sw_back)
                plain = False
                if events[r][0] == "slide" and slid.get(r, 0) >= STICK_CYCLES:
                    self._stuck_on.add(r)  # stick <-> slip cycling at one instant: it sticks on (counted)
                    self.sticks_kept += 1
                    continue
                slid[r] = slid.get(r, 0) + (events[r][0] == "slide")
                if events[r][0] == "lift" and r in passed and r in hit:
                    pulls[r] = pulls.get(r, 0) + 1
                if events[r][0] == "lift" and pulls.get(r, 0) >= LIFT_CYCLES:
                    # lift-off <-> landing cycling at one instant (pulled held, falling in free: its force 0
                    # to the method's order): held on to the next instant (counted)
                    self.lifts_kept += 1
                elif events[r][0] == "lift":
                    rider = self._pass_load(q, self._velocity(q, v, p), r, passed)
                    if rider < 0 and self._sinks_free(step, q, p, t, v, r, True, rest):
                        pulls[r] = LIFT_CYCLES  # the free rest sinks it at once: held on (counted)
                        self.lifts_kept += 1
                    else:
                        self._release(step, t_k, t, r, rider, True)
                        passed.add(r)
                        relands.setdefault(r, 0)
                else:
                    kind = "turn" if events[r][0] == "stop" and r == turn else events[r][0]
                    before = self._sw_state()
                    self._count_event(step, t_k)  # stick <-> slip at one instant: bounded, never a loop
                    self._friction_switch(kind, r, q, self._velocity(q, v, p))
                    self._sw_check(events[r][0], r, before)
                    turn = r if kind == "slide" else -1
                    struck = True  # its forces changed at the start: a row pulled there leaves there
                continue
            struck = False
            psi1 = end.psi
            cross = ~self.act & (psi1 < -tol.phi) & (np.asarray(k.row_stick) < 0)
            try:  # a location failing while a rough contact is held: the segment halved (_halve_part)
                dips = self._row_dips(step, t_k, q, p, tau, v, u1, end, cross)
                for r in np.flatnonzero(cross):
                    events[int(r)] = ("cross", self._row_crossing(step, t_k, q, p, tau, v, int(r), psi1[r]))
                for r, (s_hi, g_hi) in dips.items():  # both ends admissible, below 0 inside: before s_hi
                    events[r] = ("cross", self._row_crossing(step, t_k, q, p, tau, v, r, g_hi, s_hi))
            except SolverError as exc:
                cap = self._halve_part(step, t_k, t, tau, cap, exc=exc)
                struck, plain = struck_seg, False
                continue
            if not events:
                if tau < rest:  # a halved segment: the rest of the step next
                    self._book(lam + lam1, q1)
                    self._lam = np.where(self.act, lam * (self._h / tau), 0.0)
                    t, rest, q, p, guess = t + tau, rest - tau, q1, p1, v
                    e_at = e_seg
                    continue
                if plain and self._record_held:  # the tangent of the step (Stepper.step, Tracker.held)
                    self._held_seg = (v, lam, *self._seg_inner, u1, self.act.copy())
                elif self._ev_tan is not None:  # the constrained rest after events (Tracker.held, entry)
                    self._ev_tan.events_begin(self._ev_entry)
                    self._ev_tan.held(q, p, tau, v, lam, *self._seg_inner, u1, self.act.copy(), True)
                    self._ev_done = True
                self._book(lam + lam1, q1)
                self._lam = np.where(self.act, lam * (self._h / tau), 0.0)
                return q1, p1, e_step, v
            q_s, p_s, tau_s, v_s = q, p, tau, v
            wedged, halve = False, None  # halve: _halve_part's ratio or exc, the part having no root to take
            while True:  # the first event; a row below where it is taken crossed before it (_sunk_at_event)
                r0 = min(events, key=lambda r: (events[r][1], r))
                if events[r0][0] != "lift":  # of a landing's instant (Tolerances.simultaneous), a friction
                    # switch first, as at a segment's start; of a switch's, a lift-off (the rows' forces
                    # change with it, and the switch is sought again from there). Round-off ordered them, C
                    # one way and CasADi the other: a slide's stop 7e-14 of the step after a landing while
                    # held (box_v_drops --seed 61, drop 30), a slide 1.3e-16 before a lift-off (plate_drops
                    # --seed 31 --h 0.02, drop 18)
                    s0, kinds = events[r0][1] + tol.simultaneous, ("lift",)
                    if events[r0][0] == "cross":
                        kinds = ("stop", "slide")
                    take = [r for r, (kd, sr) in events.items() if kd in kinds and sr <= s0]
                    r0 = min(take, key=lambda r: (events[r][1], r), default=r0)
                s = events[r0][1]
                self._count_event(step, t_k)
                act0 = self.act.copy()
                if s * tau <= 1e-13 * h:  # within the least sub-step: the event at the segment's start, its
                    # E_d the start's where known (E_SHORT), not the segment's end's (box_v_drops --seed 61,
                    # drop 30: a landing at a slide's stop logged 5.9e-4 from the other backend's)
                    e_sub = e_seg if e_at is None else e_at
                    lam, lam1, u1 = np.zeros(k.r), np.zeros(k.r), self._velocity(q, v, p)
                    self._seg_inner = lam1, np.zeros(k.r * self._stages)
                    limit = self._held_limit(step, t_k, q, p, v)  # held rows an impact left moving: projected
                    if limit is not None:
                        lam1, p, u1 = limit
                    break
                try:
                    sub = self._constrained(step, t_k, q, p, s * tau, v)
                except SolverError as exc:  # while a rough contact is held: the segment halved (_halve_part)
                    halve = {"exc": exc}
                    break
                # tested as a segment is (_split_segment), but a part too short for its own E_d (E_SHORT): its
                # velocity closes the rows' round-off offsets (a plate's box, 2.5e-13 s: 11 times its start's
                # kinetic energy, its end's the start's; bench.plate_drops --seed 414 --h 0.01, drop 1044)
                ratio = self._spurious(q, p, s * tau, sub, v) if s * tau > E_SHORT * h else None
                if ratio is not None:
                    halve = {"ratio": ratio}
                    break
                if self._slip.any() and self._painleve(sub[8].grad, sub[8].mass):
                    wedged = True  # its part to the event ends past Painleve's boundary: as a segment's end
                    break
                v, lam, q, _, e_sub, lam1, p, u1, _ = sub
                e_sub = e_at if (s * tau <= E_SHORT * h and e_at is not None) else e_sub  # too short for it
                sunk = self._sunk_at_event(q, u1, events, r0)
                if not sunk:
                    break
                q, p, v = q_s, p_s, v_s
                try:
                    for r, g in sunk.items():
                        events[r] = ("cross", self._row_crossing(step, t_k, q, p, tau, v, r, g, s))
                except SolverError as exc:  # while a rough contact is held: the segment halved (_halve_part)
                    halve = {"exc": exc}
                    break
            if halve is not None:  # the segment from its start again, halved (_halve_part)
                cap = self._halve_part(step, t_k, t, tau, cap, **halve)
                struck, plain = struck_seg, False
                continue
            if wedged:  # the tangential impact at the segment's start (_jam), as past the boundary at its end
                self._jam(q_s, self._velocity(q_s, v_s, p_s))
                guess = sub[0]  # the next segment's Newton from the part's root (C: v, its output)
                self._fswitch = self._fswitch or plain
                self._sw_lose()
                plain = False
                continue
            if plain and self._record_held and events[r0][0] == "lift" and not self._friction_acts():
                # the tangent: Tracker.liftoff (its force law frictionless)
                self._lift_seg = ((q_s, p_s, v, lam, *self._seg_inner, u1, act0), r0, s, tau_s)
            else:  # one event of several, an impact while held, a lift-off under friction, a friction switch
                if events[r0][0] == "lift" and f1p[r0] != f1[r0]:  # located on the best split (_pressed): the
                    self._sw_lose("lift-off while a stick rides")  # tangent's force law is the held rows'
                self._ev_event((q_s, p_s, v, lam, *self._seg_inner, u1, act0), r0, s, tau_s, events[r0][0])
            self._fswitch = self._fswitch or (plain and events[r0][0] in ("stop", "slide"))
            plain = False
            e_step = e_sub if self._forced else e_step  # forces: the step's energy is its last segment's
            e_at = e_sub
            self._book(lam + lam1, q)
            t, rest, guess = t + s * tau, (1.0 - s) * tau if tau == rest else rest - s * tau, v
            turn = -1
            if s > tol.simultaneous:  # a later instant (within Tolerances.simultaneous: this one)
                passed, hit, pulls = set(), set(), {}
                self._jammed = False
                self._stuck_on.clear()
            if events[r0][0] == "lift":
                rider = self._pass_load(q, self._velocity(q, v, p), r0, passed)
                if rider < 0 and self._sinks_free(step, q, p, t, v, r0, False, rest):
                    pulls[r0] = LIFT_CYCLES  # the free rest sinks it at once: held on (counted)
                    self.lifts_kept += 1
                    continue
                self._release(step, t_k, t, r0, rider)
                passed.add(r0)
                relands.setdefault(r0, 0)
                continue
            if events[r0][0] in ("stop", "slide"):
                before = self._sw_state()
                self._friction_switch(events[r0][0], r0, q, self._velocity(q, v, p))
                self._sw_check(events[r0][0], r0, before)
                continue
            group = [r for r, (kind, sr) in events.items() if kind == "cross" and sr - s <= tol.simultaneous]
            ahead = s * tau > 1e-13 * h  # met at the segment's start: no end there (an impact, below)
            back = self._met_back(step, q, self._velocity(q, v, p), group, backs) if ahead else []
            if back:  # released lately, met again moving away: a segment's end, no impact
                group = [r for r in group if r not in back]
                if not group:
                    continue
            joined = self._joined(q, self._velocity(q, v, p), group, hit)  # touching, met at this instant
            group += joined
            self._located(step, t_k, q_s, q, v, group)  # on its rows, not below them
            p = self._chain_impact(step, t_k, h, q, p, v, t, group, impacts, e_sub, hit, joined)
            e_at = impacts[-1].energy_after
            struck = True
            guess = self._velocity(q, v, p)  # the next segment's Newton from the velocity after the impact
            hit |= set(group)
            for r in [r for r in group if r in relands and self.act[r]]:  # lifted off, landed again, held
                relands[r] += 1
                if relands[r] >= JAM_CYCLES and self._stick_rows and not self._jammed:
                    self._jam(q, self._velocity(q, v, p))

    def _halve_part(self, step, t_k, t: float, tau: float, cap: tuple, ratio: float = 0.0, exc=None) -> tuple:
        """The chain's ``cap`` (``(t, the longest segment from t, its halvings)``) after the segment of length
        ``tau`` from ``t`` had no part to its first event it can take: the part's root spurious
        (:meth:`_spurious`, ``ratio``), or its Newton, or the location of an event (a lift-off, a slide's
        stop, a stick force leaving its cone, an inactive row's crossing or dip), failing while a rough
        contact is held (``exc``, :meth:`_halvable`). The segment is taken again from ``t`` over ``tau / 2``,
        as a spurious segment is (:meth:`_split_segment`); after ``SPLITS`` such halvings at ``t`` (a
        frictionless Newton's failure at once: too coarse a step) it raises ``exc``, or a ``SolverError``
        naming the spurious root (C ``halve_part``). A rough hoop's slide turned past a jam took over 0.025 a
        segment whose lift-off's part had a root 19 times that budget: in C the energy went 952 -> 5543 in one
        step, silently, and on CasADi the location's Newton failed (``bench.hoop_drops --seed 418 --h 0.025``,
        drop 427)."""
        halvings = cap[2] if cap[0] == t else 0
        if exc is not None and (halvings >= SPLITS or not self._halvable(step)):
            raise exc
        if halvings >= SPLITS:
            raise SolverError(
                step,
                t_k,
                "sustained",
                0.0,
                f"the part of a held segment to its event has a spurious root: the kinetic energy of its "
                f"velocity is {ratio:.3g} times its start's and the forces' over it, after {SPLITS} "
                "halvings; reduce h",
            )
        self.halvings += 1
        self._sw_lose("held segment halved")
        return (t, 0.5 * tau, halvings + 1)

    def _sunk_at_event(self, q, u, events, r0: int) -> dict[int, float]:
        """Inactive contact rows below ``-Tolerances.admissible`` at ``(q, u)``, where the segment's first
        event ``events[r0]`` is taken, none of its instant (within ``Tolerances.simultaneous``): ``{r:
        psi_r}``. Each has a crossing before it, which the caller locates (C ``sunk_at_event``). The ends'
        tests miss such a dip where the row's slope at the start is round-off's: released at a normal speed of
        0, a box's corner sank 2.6e-5 below its wall inside the next segment (each sub-step length is its own
        map), a friction switch inside the dip went on from there, and the corner was met that far below
        (``bench.box_v_drops --seed 21``, drops 183 and 284; a plate's corner 2.5e-5, ``bench.plate_drops
        --seed 21 --h 0.02``, drop 1397, whose row ended the segment above and moving in)."""
        k, tol = self.k, self.tol
        psi = k.rows(q, u)[0]
        s = events[r0][1]
        out = {}
        below = ~self.act & (np.asarray(k.row_stick) < 0) & (psi < -tol.admissible)
        for r in map(int, np.flatnonzero(below)):
            if r != r0 and not (r in events and events[r][1] - s <= tol.simultaneous):
                out[r] = float(psi[r])
        return out

    def _start_forces(self, q, u) -> np.ndarray:
        """The held rows' forces at a segment's start ``(q, u)``, read as at its end: :meth:`_contact_forces`,
        their best split (:meth:`_pressed`) where a stick row rides. The lift-off's search starts there
        (:meth:`_liftoff_fraction`); after an impact while held (``struck`` in :meth:`_chain`) a row pulled
        there lifts off there: one the incoming velocity pressed in, held by the impact, may be pulled once
        stopped (MATH.md *Entry*, as free flight's plastic entry reads it). The end's force alone, pushing
        again 0.98 h later, held a chain's tip with a mean force of -4.36 over the step (-9.28 at its start;
        at h / 2 and below, the same landing lifted off at once). So after a friction switch at the segment's
        start (stop 67): a hoop's rim mass past Painleve's boundary, jammed, its stick force out of the cone,
        slipping back and turned at once, pulled the floor at the start; the end, a coarse step past the pole
        of the end's projection, pushed, and the slide's stop was located on that pole (2.3e8 m/s after it;
        ``bench.hoop_drops --seed 419 --h 0.05``, drop 384: "smooth solve failed"). Now it lifts off there,
        as at ``h / 2``."""
        f0 = self._contact_forces(q, u)
        if self._owners():  # as at the end (_pressed): the rows only where a stick rides
            f0 = self._pressed(f0, self.k.rows(q, u)[1])
        return f0

    def _sinks_free(self, step: int, q, p, t: float, guess, r: int, start: bool, rest: float) -> bool:
        """Would row ``r``'s lift-off at ``(q, p)``, ``t``, which no rider takes (the caller's
        :meth:`_pass_load`), leave nothing held (no row of another contact, not sliding past Painleve's
        boundary) and a free step (46) of ``h`` or of the grid step's ``rest`` from there meet its contact
        (``Stepper._crossings``: below ``-Tolerances.phi`` at its end, or a dip inside)? The exact row leaves
        as the cube of the time since its lift-off and the smooth step's error is of that order: where the
        free step sinks, the row has not left at this ``h``. A full step: a lift-off 27 us before a step's end
        flew that rest and sank at once in the next step. The rest too: each length is its own map, and a
        follower lifting off a cam turning 0.37 rad a step (``h = 0.05``) rose by 4e-6 over ``h`` and sank
        6.6e-6 over the rest; released, the rest met the cam at once, an impact of impulse 0 held it, its
        force pulled at once, and it lifted off again, 64 times at one instant (``bench.cam_drops --seed 23
        --h 0.05``, drop 202). Such a row is held on to the step's end (``LIFT_CYCLES``,
        counted in ``lifts_kept``; its force there within the method's order of 0; ``_sunk`` for
        :meth:`_sunk_held`) and lifts off in a later step: 0.16-1.54 h after the exact lift-off, not to second
        order; its log keeps the instant its force vanished (``_sunk_at``, :meth:`_held_since`), second order.
        Released, the free flight met the contact at once with no normal speed, and what followed hung
        on round-off: a hoop with a mass on its rim hopping off a rough floor logged impacts at the lift-off's
        instant (of impulse 1e-15, grazing and plastic; a restitution kick of 6e-4 ... 7e-3 at ``e = 0``) and
        more lift-offs, other ones on each backend; it raised "more than 64 impacts in one step" from one
        start at ``h = 0.0025`` (C) and in a random run at ``h = 0.01`` (both); in another random run CasADi
        took a mirror root of (78), impulses of -0.195 and 0.294, and the backends parted by 5.5e-2
        (``tests/test_hopping_hoop.py``, ``bench.hoop_drops``). The tangent stops there."""
        k = self.k
        j = k.row_contact[r]
        stick = k.row_stick
        for i in np.flatnonzero(self.act):
            if i != r and not (stick and stick[i] >= 0 and k.frictional[stick[i]] == j):
                return False  # another row held: the chain's own (_met_back, LIFT_CYCLES)
        if self._slip.any():  # sliding past Painleve's boundary: released, it sinks at second order (_jam's)
            u = self._velocity(q, guess, p)
            if self._painleve(k.rows(q, u)[1], k.legendre(q, u)[1]):
                return False
        self._at(t)
        if not any(self._meets_free(q, p, t, guess, j, tau) for tau in free_lengths(self._h, rest)):
            return False
        self._sw_lose("a lift-off sinking at once")
        if not self._held_since(step, r, start):  # a new lift-off: its instant, to log at its release
            self._sunk_at[r] = t
        self._sunk[r] = step
        return True

    def _meets_free(self, q, p, t: float, guess, j: int, tau: float) -> bool:
        """Does a free step (46) of ``tau`` from ``(q, p)`` at ``t`` meet contact ``j``, as the free rest
        would (:meth:`_free_rest`)?"""
        v, _, _, _, phi0, phi1, d0, d1 = self.k.smooth_step(q, p, tau, guess)
        seg = Seg(q=q, t=t, tau=tau, p_in=p, e_in=math.nan, nrm=None, contact=-1, x=v)
        return j in self._crossings(seg, phi0, phi1, d0, d1)

    def _held_since(self, step: int, r: int, start: bool) -> bool:
        """Is row ``r``'s lift-off at a segment's ``start`` the one :meth:`_sinks_free` held it on at in
        this grid step or the one before, not logged yet (``_sunk_at``)? Held on, its force below 0, it is met
        again at the start of the next segment (after another event) or grid step; a lift-off inside a
        segment is new."""
        return start and r in self._sunk_at and self._sunk_lately(step, r)

    def _sunk_lately(self, step: int, r: int) -> bool:
        """Was row ``r`` held on by :meth:`_sinks_free` in grid step ``step`` or the one before?"""
        return step - self._sunk.get(r, step - 2) <= 1

    def _sunk_held(self, step: int) -> bool:
        """Is a row held on by :meth:`_sinks_free` in this grid step or the one before held still? Its held
        segment whose Newton fails is halved (:meth:`_split_segment`), as a slipping contact's: held on at its
        lift-off, a frictionless cube rocking on one vertex as its Euler angles neared their singularity
        (pitch -1.57, angle rates of 2e3) had no held step of ``h`` in the next step, one of ``h / 2``."""
        return any(self.act[r] and self._sunk_lately(step, r) for r in self._sunk)

    def _halvable(self, step: int) -> bool:
        """Is a held segment whose Newton fails halved (:meth:`_split_segment`, :meth:`_halve_part`)? Where a
        rough contact is held, slipping or (since stop 68) sticking, or a row held on by :meth:`_sinks_free`
        (:meth:`_sunk_held`); a frictionless segment whose Newton fails is a step too coarse for its row (C
        ``halvable``). Sticking: a box thrown by a vibrating plate, held on a corner sticking after a landing,
        had no held root over ``h = 0.02`` on either backend; halved, it runs on as at ``h = 0.01`` and 0.005
        (``bench.plate_drops --seed 426 --h 0.02``, drop 656: at t = 2 within 0.02 of them; drops 1096 and
        1309 of seeds 427 and 428, ...)."""
        sticks = self.act & (np.asarray(self.k.row_stick) >= 0)
        return bool(self._slip.any() or self._sunk_held(step) or sticks.any())

    def _met_back(self, step: int, q, u, group, backs) -> list[int]:
        """Rows of the crossing ``group`` at ``(q, u)`` released in this grid step or the ``LEAVE_STEPS``
        before it that meet their contact again moving away from it (``grad psi_r . u >= 0``): after a
        lift-off the exact row rises as the cube of the time since, and the map, whose error is of that order,
        sank instead; the root located is where the row has not left yet, not an impact. The crossing is a
        segment's end with no impulse and no log (the next segment starts there, on the contact; counted in
        ``backs``, the chain's; from the ``BACK_CYCLES``-th on, an impact as before). The caller does not ask
        where the crossing is at the segment's start (within ``1e-13 h``): the next segment would start where
        this one did and meet it there again (a tip 1e-11 m/s off its floor met 20 times at one point); the
        map does not let the row leave from there, and the impact holds it, as before. A double pendulum in
        its bobs' coordinates whose tip lifted off a floor logged six impacts of impulse 0 and two more
        lift-offs in the step of its lift-off (``tests/test_double_pendulum_rods.py``). The tangent stops
        there."""
        if not group:
            return []
        grad = self.k.rows(q, u)[1]
        back = [
            r
            for r in group
            if step - self._left_step.get(r, step - LEAVE_STEPS - 1) <= LEAVE_STEPS
            and not self.act[r]
            and float(grad[r] @ u) >= 0.0
            and backs.get(r, 0) < BACK_CYCLES
        ]
        for r in back:
            backs[r] = backs.get(r, 0) + 1
        if back:
            self._sw_lose("a lift-off met again moving away")
        return back

    def _free_rest(self, step, t_k, h, q, p, t, tau, guess, impacts, e_step):
        """A free remainder of the grid step from ``(q, p)``: smooth (46), or the impact chain (47)-(79)."""
        k = self.k
        self._at(t)
        v, res, p1, e, phi0, phi1, d0, d1 = k.smooth_step(q, p, tau, guess)
        self._check(res, p, step, t_k, "smooth")
        e_step = e if (e_step is None or self._forced) else e_step
        if phi1.size == 0 or (phi1.min() >= -self.tol.phi and not ((d0 < 0) & (d1 > 0)).any()):
            self._free_seg = (q, p, v) if self._record_held else None  # the tangent: Tracker.liftoff
            self._ev_free(q, p, v, tau)
            return q + tau * v, p1, e_step, v
        seg = Seg(q=q, t=t, tau=tau, p_in=p, e_in=math.nan, nrm=None, contact=-1, x=v)
        crossings = self._crossings(seg, phi0, phi1, d0, d1)
        if not crossings:
            self._free_seg = (q, p, v) if self._record_held else None
            self._ev_free(q, p, v, tau)
            return q + tau * v, p1, e_step, v
        q1, p1, e_end, w = self._ev_impacts(step, t_k, h, seg, crossings, impacts, e_step)
        return q1, p1, (e_end if self._forced else e_step), w

    def _release(self, step, t_k, t, r: int, rider: int = -1, start: bool = False) -> None:
        """Lift-off of row ``r`` at ``t``: logged once per contact that leaves sustained contact, at the
        instant its force vanished where :meth:`_sinks_free` held it on since (:meth:`_held_since`). With a
        ``rider`` (:meth:`_pass_load`) that row is held in its place and nothing leaves: ``r`` rides on."""
        k = self.k
        if self._held_since(step, r, start):
            t = self._sunk_at[r]
        self._sunk_at.pop(r, None)
        self.act[r] = False
        if rider >= 0:
            self.act[rider] = True
            self.passes += 1
            self._sw_lose("load passed to a riding row")
            return
        self._left_step[r] = step
        j = k.row_contact[r]
        if not any(self.act[i] for i in range(k.r) if k.row_contact[i] == j):
            self.liftoffs.append((float(t), k.contact_names[j]))

    def _jam(self, q, u) -> None:
        """A row lifted off and landed again ``JAM_CYCLES`` times in one step (its force below 0 held, sinking
        free: Painleve's inconsistency under sliding friction, high ``mu``), or a held slipping contact past
        Painleve's boundary at a segment's end (:meth:`_painleve`): every held frictional contact
        sticks from here (the tangential impact of its theory, the sliding stopped at once by the stick rows'
        impulse, not bounded by the cones), counted in ``jams``. Where no held contact has friction (``mu =
        0`` on each) there is no Painleve inconsistency and no jam: nothing sticks, nothing is counted (a
        double pendulum on a frictionless floor whose tip cycled at one instant counted two, and the run
        warned of Painleve's inconsistency; stop 50)."""
        rough = self._rough_held()
        if not rough:
            return
        self.jams += 1
        self._jammed = True
        for f in rough:
            if not self.act[self._stick_rows[f]] and self._ride[f] < 0:
                self._stick(f, q, u)
        self._set_friction()

    def _rough_held(self) -> list[int]:
        """The frictional contacts held with ``mu > 0`` (by their index in ``frictional``)."""
        held = held_contacts(self.k, self.act)
        return [f for f, j in enumerate(self.k.frictional) if held[j] and self._mu_f[f] > 0.0]

    def _painleve(self, grad, mass) -> bool:
        """Is a held contact slipping past Painleve's boundary at a segment's start or end (the rows'
        gradients ``grad`` and the mass ``mass`` there): one of its held normal rows ``r`` with ``grad_r .
        M^-1 d_r <= 0`` (``d_r``: its force direction with the sliding friction, :meth:`_dirs`)? There the
        normal force that holds the row grows without bound as the boundary nears, and the segment's root
        lies beyond it (a rough star tipping as it slides on a vertex, ``mu = 1.38``: the end impulse -67,
        the speeds 93 m/s after one step); from a start past it, the root holds the row by a pulling impulse
        (a rough star sliding on a corner at 2.4 m/s, ``mu = 1.33``: -0.88 over ``h = 0.05``, its stop's
        search then met the pole of the end's projection). The chain then takes the tangential impact of the
        theory instead (:meth:`_jam`, at the segment's start)."""
        k = self.k
        dirs = self._dirs(grad)
        for f, j in enumerate(k.frictional):
            if not self._slip[f]:
                continue
            for r in range(k.r):
                if self.act[r] and k.row_contact[r] == j and k.row_stick[r] < 0 and not k.row_bilateral[r]:
                    if float(grad[r] @ np.linalg.solve(mass, dirs[r])) <= 0.0:
                        return True
        return False

    def _pass_load(self, q, u, r: int, barred) -> int:
        """The riding row that takes held row ``r``'s load at its lift-off (its force below 0), or -1.

        A riding row is a contact row not held at ``phi = 0`` whose gradient is in the span of the held
        normal rows with ``r`` (:meth:`_hold`: a box's fourth vertex on its face). Where its expansion over
        them takes ``r`` with a coefficient ``c_r < 0`` it is independent of the others, and held in ``r``'s
        place its force is ``lambda_r / c_r >= 0`` (the same joint force on the body): the load crosses over
        (a sliding box's load moving across its diagonal) and ``r`` rides. The first such in row order, none
        of ``barred`` (rows that passed theirs at this instant: no passing back). Without it ``r``, its force
        0 to round-off at the located lift-off and the rider never loaded, sinks and lands again at once.
        The sign of ``c_r`` is that of ``grad psi_i`` along ``r``'s Gram-Schmidt direction against the other
        held normal rows (``span_add``)."""
        k = self.k
        stick = k.row_stick
        psi, grad, _ = k.rows(q, u)
        basis: list = []
        for j in np.flatnonzero(self.act):
            if j != r and not (stick and stick[j] >= 0):
                span_add(basis, grad[j])
        if not span_add(basis, grad[r]):
            return -1
        for i in range(k.r):
            if self.act[i] or i == r or i in barred or k.row_contact[i] < 0 or (stick and stick[i] >= 0):
                continue
            g = grad[i]
            along = float(basis[-1] @ g)  # the sign of c_r
            if abs(psi[i]) > self.tol.admissible or not along < -DEP_EPS * float(np.linalg.norm(g)):
                continue
            if not span_add(list(basis), g):  # it rides on them
                return i
        return -1

    def _book(self, impulses, q_end) -> None:
        """Add the constraint impulses of a segment (``Lam + Lam'``, per row; ``q_end`` its end) to the step's
        forces. Where a stick row rides they are one split of many: booked as their best split
        (:meth:`_pressed`, the split homogeneous in the impulses), so that a resting body's forces are the
        same whichever stick row holds (a rod stopped in a rough bowl reported -0.51 on one end or 2.9 and
        5.5 against 5.5 and 8.1, as round-off chose)."""
        k = self.k
        self._booked = True
        if self._owners():
            impulses = self._pressed(impulses, k.rows(q_end, np.zeros(k.n))[1])
        for r in np.flatnonzero(impulses):
            if k.row_stick and k.row_stick[r] >= 0:
                continue  # a stick row's force is tangential: not a normal force
            if k.row_contact[r] >= 0:
                self._force[k.row_contact[r]] += impulses[r] / self._h
            else:
                self._cforce[k.row_constraint[r]] += impulses[r] / self._h

    def _count_event(self, step, t_k) -> None:
        self._events += 1
        if self._events > self.tol.max_impacts_per_step:
            raise SolverError(
                step,
                t_k,
                "sustained",
                0.0,
                f"more than {self.tol.max_impacts_per_step} impacts and lift-offs in one step; reduce h",
            )


def free_lengths(h: float, rest: float) -> tuple[float, ...]:
    """The free steps :meth:`SustainedSteps._sinks_free` tries after a lift-off with ``rest`` of the grid
    step ``h`` left (C ``sinks_free``): ``h``, and the rest where it is shorter and above the least sub-step
    (``1e-13 h``)."""
    return (h, rest) if 1e-13 * h < rest < h else (h,)


def row_matrix(g, mass) -> tuple[np.ndarray, np.ndarray]:
    """``(M^-1 G^T, G M^-1 G^T)`` of the rows ``g`` (C ``row_matrix``): the least move onto them
    (:meth:`SustainedSteps._onto_rows`) and the energy that closes their offsets (``_gap_energy``)."""
    minv_g = np.linalg.solve(mass, g.T)
    return minv_g, g @ minv_g


def held_contacts(kernels, act) -> np.ndarray:
    """Per contact: is any of its rows in ``act`` (the active rows) held?"""
    out = np.zeros(kernels.m, dtype=bool)
    for r in np.flatnonzero(act):
        if kernels.row_contact[r] >= 0:
            out[kernels.row_contact[r]] = True
    return out


class SustainLog:
    """Per grid point and step: which contacts are active, and the mean constraint forces."""

    def __init__(self, kernels, cap: int) -> None:
        k = kernels
        self.m = k.m
        self.nc = len(k.system.model.constraint) if k.r else 0
        self.active = np.zeros((cap + 1, self.m), dtype=bool)
        self.force = np.zeros((cap, self.m))
        self.cforce = np.zeros((cap, self.nc))

    def grow(self, cap: int) -> None:
        for name, rows in (("active", cap + 1), ("force", cap), ("cforce", cap)):
            old = getattr(self, name)
            new = np.zeros((rows, old.shape[1]), dtype=old.dtype)
            new[: old.shape[0]] = old
            setattr(self, name, new)

    def record(self, step: int, active, force, cforce) -> None:
        """Grid point ``step`` reached: its active contacts, and the forces of the step before it."""
        self.active[step] = active
        self.force[step - 1] = force
        self.cforce[step - 1] = cforce

    def attach(self, res, steps: int, liftoffs) -> None:
        res.active = self.active[: steps + 1].copy()
        res.contact_force = self.force[:steps].copy()
        res.constraint_force = self.cforce[:steps].copy()
        res.liftoffs = list(liftoffs)
