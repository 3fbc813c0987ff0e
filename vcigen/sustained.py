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

**Impulse law** (at an impact with rows active, and for the plastic entry): the frictionless
Newton law on the rows ``S`` involved, ``p+ = p- + G_S^T Lam``, with target normal velocities
``-e_r g_r.qdot-`` (0 for plastic and active rows), ``Lam_r >= 0`` enforced by releasing the most
negative row and solving again.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from .cone_split import null_combination, split
from .derive import KINK
from .errors import SolverError
from .impact_step import Seg
from .result import KINDS, Impact

ROOT_EPS = 1e-14  # a row crossing is located where |psi| <= ROOT_EPS max|psi at the bracket ends|
LIFT_ITER = 60  # Illinois iterations locating a lift-off at most
EPS_LAM = 1e-14  # |Lam| below this (relative to 1 + |p|) is zero: no release for round-off
SLIDE_EPS = 1e-12  # a sliding velocity below this (relative to 1 + |u|) is 0: the contact sticks
MAX_LAW_ROWS = 12  # rows one impulse law may involve (its complementarity problem is solved by enumeration)
BRAKE = 2.0  # cones sliding slower than BRAKE tau (friction's rate on them) are aimed implicitly
DEP_EPS = 1e-9  # a stick row this close (relative) to the span of the active rows' gradients is dependent


def _illinois(value, ga: float, gb: float, tiny: float, width: float, iters: int, guess) -> float:
    """Illinois regula falsi for the root of ``value`` on ``[0, 1]`` (``value(0) = ga >= 0 > gb = value(1)``).

    ``value(s, guess) -> (g(s), guess')`` evaluates the sub-step map at ``s`` from a warm guess. Returns
    the first ``s`` with ``|g(s)| <= tiny``, or else, once the bracket is narrower than ``width`` (or after
    ``iters`` evaluations), its end where ``g < 0``.
    """
    a, b, side, v = 0.0, 1.0, 0, guess
    for _ in range(iters):
        c = (a * gb - b * ga) / (gb - ga)
        if not a < c < b:
            c = 0.5 * (a + b)
        gc, v = value(c, v)
        if gc < 0:
            b, gb = c, gc
            ga = ga / 2 if side == -1 else ga
            side = -1
        else:
            a, ga = c, gc
            gb = gb / 2 if side == 1 else gb
            side = 1
        if abs(gc) <= tiny:
            return c
        if b - a <= width:
            break
    return b


def _pooled(pools, lam) -> float:
    """``sum mu_f Lam_n`` over the pools of a stick row's cone (``SustainedSteps._law_cones``): its room."""
    return sum(mu * float(np.sum(lam[normals])) for normals, mu in pools)


class End(NamedTuple):
    """Evaluations at the end ``(q1, u1)`` of a constrained segment: rows, their gradients and curvatures,
    the free dynamics' right-hand side and the mass matrix."""

    psi: np.ndarray | None
    grad: np.ndarray
    curv: np.ndarray
    rhs: np.ndarray
    mass: np.ndarray


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


class SustainedSteps:
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
        self._lam = np.zeros(k.r)
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
        """Active rows at the start: bilateral constraints, and contacts touched at rest and pressed in."""
        k = self.k
        self._init_sustained()
        if not k.r or self.tol.grazing != "contact":
            return
        psi, grad, _ = k.rows(q0, v0)
        acc = self._accel(q0, v0, np.zeros(k.r))
        rates, accs = grad @ v0, self._row_accel(q0, v0, acc)
        for r in range(k.r):
            if k.row_bilateral[r] or k.row_stick[r] >= 0 or abs(psi[r]) > self.tol.admissible:
                continue
            if self._settles(rates[r], accs[r], 1.0, h):  # at rest to the resolution of the jump
                self.act[r] = True
        self._friction_modes(q0, v0)
        self._held = bool(self.act.any())

    def _settles(self, rate: float, acc: float, e: float, h: float) -> bool:
        """Forces press the row in and the outgoing normal speed is below the jump's resolution."""
        return acc < 0.0 and e * abs(rate) <= self.tol.rest * h * abs(acc)

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

    # -- Coulomb friction in sustained contact (MATH.md, Friction) -------------------------
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
        stick row is independent now. Cones (two tangents) by :meth:`_cone_modes`, aiming their slip for a
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
                if abs(sliding) <= SLIDE_EPS * (1.0 + float(np.max(np.abs(u)))):
                    self._stick(f, q, u)
                else:
                    self._slip[f] = -self._mu_f[f] * math.copysign(1.0, sliding)
        self._cone_modes(q, u, tau)
        self._set_friction()

    def _friction_mode(self) -> tuple:
        """The friction mode: the rows held, the slots (slips, references, branches) and dependent sticks; a
        slipping cone's slips as 1 (its direction is aimed anew every segment, within the mode)."""
        slip = self._slip.copy()
        for f, p in self._cones():
            if slip[f] or slip[p]:
                slip[[f, p]] = 1.0
        slots = (*slip.tolist(), *self._ref.tolist(), *self._branch.tolist())
        return (*self.act.tolist(), *slots, *self._ride)

    def _friction_acts(self) -> bool:
        """Whether a frictional contact slips or holds its stick row."""
        return bool(self._slip.any() or any(self.act[sr] for sr in self._stick_rows))

    # -- dependent sticks: two contacts of one body sticking at once (statically indeterminate) -----------
    def _dependent(self, grad, sr: int, skip: int = -1) -> bool:
        """Is stick row ``sr``'s gradient in the span of the other active rows' (but row ``skip``)?

        Modified Gram-Schmidt over the active rows in index order (a row within ``DEP_EPS`` of the span so far
        adds nothing), then ``sr``'s residual against that basis, relative to its length."""
        basis = []
        for r in np.flatnonzero(self.act):
            if r in (sr, skip):
                continue
            w = grad[r].copy()
            for b in basis:
                w -= float(b @ w) * b
            nw = float(np.linalg.norm(w))
            if nw > DEP_EPS * float(np.linalg.norm(grad[r])):
                basis.append(w / nw)
        w = grad[sr].copy()
        for b in basis:
            w -= float(b @ w) * b
        return float(np.linalg.norm(w)) <= DEP_EPS * float(np.linalg.norm(grad[sr]))

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
                if math.hypot(*w) <= SLIDE_EPS * (1.0 + float(np.max(np.abs(u)))):
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
        ``grad t M^-1 grad t^T``) they are aimed implicitly together (:meth:`_cone_brake`): there the
        explicit aim made a body's relative modes (the yaw of a rod on two cones) unstable."""
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
        if len(slow) >= 2:  # several cones near rest: implicit in the direction
            self._braked = True
            aims = [a for a in aims if (a[0], a[1]) not in slow] + self._cone_brake(slow, q, u, tau)
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
        body (the rod's yaw) unstable. ``[(f, p, slip)]``, none for a cone with no force."""
        k = self.k
        act, slip, ride = self.act.copy(), self._slip.copy(), list(self._ride)
        _, grad, curv = k.rows(q, u)
        for f, p in cones:
            self._slip[[f, p]] = 0.0
        self._set_friction()
        target = curv.copy()
        for f, p in cones:
            for x in (f, p):
                sr = self._stick_rows[x]
                target[sr] += 2.0 * float(grad[sr] @ u) / tau
                if self._dependent(grad, sr):
                    self._ride[x] = x
                else:
                    self.act[sr] = True
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
        ``s`` at the segment's end is negative; located along the sub-step map (Illinois) where it is 0."""
        s = -self._slip[[f, p]] / self._mu_f[f]
        g1 = float(s @ self._sliding(f, p, end.grad, u1))
        if g1 >= 0.0:
            return
        g0 = float(s @ self._sliding(f, p, self.k.rows(q, vel0)[1], vel0))

        def along(c, w):
            w, end_c, u_c = self._sub_end(step, t_k, q, p0, tau, c, w)
            return float(s @ self._sliding(f, p, end_c.grad, u_c)), w

        frac = 0.0 if g0 <= 0.0 else _illinois(along, g0, g1, 1e-14, 1e-13, LIFT_ITER, v)
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
        if self._partner[f] >= 0:
            joint = self._cone_split(f, forces, grad)
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
        """A slipping contact that stops inside the segment ("stop"), a sticking one whose force leaves the
        cone ("slide"): each located as a root along the sub-step map (Illinois), as a lift-off is."""
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
                if g1 < 0.0:
                    g0 = s * float(k.rows(q, vel0)[1][sr] @ vel0)

                    def sliding(c, w, s=s, sr=sr):
                        w, end_c, u_c = self._sub_end(step, t_k, q, p, tau, c, w)
                        return s * float(end_c.grad[sr] @ u_c), w

                    frac = 0.0 if g0 <= 0.0 else _illinois(sliding, g0, g1, 1e-14, 1e-13, LIFT_ITER, v)
                    events[sr] = ("stop", frac)
            elif self.act[sr] or (self._partner[f] >= 0 and self.act[self._stick_rows[self._partner[f]]]):
                g1 = self._cone_margin(f, f1, end.grad)
                if g1 < -EPS_LAM * (1.0 + float(np.max(np.abs(f1)))):
                    g0 = self._cone_margin(f, self._contact_forces(q, vel0), k.rows(q, vel0)[1])

                    def margin(c, w, f=f):
                        w, end_c, _ = self._sub_end(step, t_k, q, p, tau, c, w)
                        return self._cone_margin(f, self._forces(end_c), end_c.grad), w

                    tiny = EPS_LAM * (1.0 + abs(g0) + abs(g1))
                    frac = 0.0 if g0 < 0.0 else _illinois(margin, g0, g1, tiny, 1e-12, LIFT_ITER, v)
                    events[sr] = ("slide", frac)

    def _friction_switch(self, kind: str, sr: int, q, u) -> None:
        """At a located friction event: a stopped contact sticks; a sliding one slips against its force."""
        f = self.k.row_stick[sr]
        if self._partner[f] >= 0:
            self._cone_switch(kind, f, self._partner[f], q, u)
            return
        sliding = float(self.k.rows(q, u)[1][sr] @ u)
        if kind == "stop" and abs(sliding) > SLIDE_EPS * (1.0 + float(np.max(np.abs(u)))):
            self._slip[f] = -self._mu_f[f] * math.copysign(1.0, sliding)  # an impact turned it: slip that way
        elif kind == "stop":
            self._stick(f, q, u)
        else:
            lam = self._contact_forces(q, u)[sr]
            self.act[sr] = False
            self._slip[f] = -self._mu_f[f] * math.copysign(1.0, -lam)  # it slides the way the force pushes
            grad = self.k.rows(q, u)[1]
            for g, owner in enumerate(self._ride):  # its dependent sticks slide with it, the same way
                if owner == f and g != f and self._partner[g] < 0:
                    along = float(grad[self._stick_rows[g]] @ grad[sr])
                    self._slip[g] = -self._mu_f[g] * math.copysign(1.0, -lam * along)
                    self._ride[g] = -1
        self._set_friction()

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
        self._braked = False  # cones aimed implicitly near rest (_cone_brake): no tangent
        while True:
            self._at(t)
            if tau <= 1e-13 * h:
                return q, p, (e_step if e_step is not None else math.nan), guess
            if self._stick_rows:
                mode = self._friction_mode()
                before = self._friction_state() if self._ev_tan is not None else None  # the events' tangent's
                self._friction_modes(q, self._velocity(q, guess, p), tau)
                # a switch (stick, slip, released, another face) or a cone's slip aimed anew: no tangent
                same = mode == self._friction_mode()
                if not same and before is not None and not self._no_switch(before):  # let go, held anew: none
                    self._sw_lose()  # a switch at a segment's start: not located
                if self._braked and self._ev_tan is not None and self._ev_tan.active:
                    self._ev_tan.lose("held step (sustained contact)")
                self._fswitch = self._fswitch or (plain and not same)  # what stops the tangent
                plain = plain and same and not self._braked
            if not self.act.any():
                return self._free_rest(step, t_k, h, q, p, t, tau, guess, impacts, e_step)
            if not plain:  # a constrained segment after an event: no lift-off then a free rest
                if self._lift_seg is not None:  # the lift-off is one event of several (Tracker.event)
                    self._ev_event(*self._lift_seg, "lift")
                self._lift_seg = None
            v, lam, q1, _, e_seg, lam1, p1, u1, end = self._constrained(step, t_k, q, p, tau, guess)
            e_step = e_seg if (e_step is None or self._forced) else e_step
            unilateral = self.act & ~np.asarray(k.row_bilateral, dtype=bool) & (np.asarray(k.row_stick) < 0)
            events = {}
            f1 = self._forces(end)
            if self._stick_rows:
                self._friction_events(step, t_k, q, p, tau, v, u1, end, f1, events)
            pulled = unilateral & (f1 < -EPS_LAM * (1.0 + float(np.max(np.abs(f1)))))
            if pulled.any():
                f0 = self._contact_forces(q, self._velocity(q, v, p))
                for r in np.flatnonzero(pulled):
                    events[int(r)] = (
                        "lift",
                        self._liftoff_fraction(step, t_k, q, p, tau, v, int(r), f0[r], f1[r]),
                    )
            if any(s == 0.0 for _, s in events.values()):  # at the segment start: release or switch there
                r = min(r for r, (_, s) in events.items() if s == 0.0)
                self._fswitch = self._fswitch or (plain and events[r][0] in ("stop", "slide"))
                if events[r][0] in ("stop", "slide") and not self._sw_back(events[r][0]):
                    self._sw_lose()  # at the start: not located (a slide back at a stop: _sw_back)
                plain = False
                if events[r][0] == "lift":
                    self._release(step, t_k, t, r)
                else:
                    before = self._sw_state()
                    self._count_event(step, t_k)  # stick <-> slip at one instant: bounded, never a loop
                    self._friction_switch(events[r][0], r, q, self._velocity(q, v, p))
                    self._sw_check(events[r][0], r, before)
                continue
            psi1 = end.psi
            cross = ~self.act & (psi1 < -tol.phi) & (np.asarray(k.row_stick) < 0)
            if not events and not cross.any():
                if plain and self._record_held:  # the tangent of the step (Stepper.step, Tracker.held)
                    self._held_seg = (v, lam, *self._seg_inner, u1, self.act.copy())
                elif self._ev_tan is not None:  # the constrained rest after events (Tracker.held, entry)
                    self._ev_tan.events_begin(self._ev_entry)
                    self._ev_tan.held(q, p, tau, v, lam, *self._seg_inner, u1, self.act.copy(), True)
                    self._ev_done = True
                self._book(lam + lam1)
                self._lam = np.where(self.act, lam * (self._h / tau), 0.0)
                return q1, p1, e_step, v
            for r in np.flatnonzero(cross):
                events[int(r)] = ("cross", self._row_crossing(step, t_k, q, p, tau, v, int(r), psi1[r]))
            r0 = min(events, key=lambda r: (events[r][1], r))
            s = events[r0][1]
            self._count_event(step, t_k)
            act0 = self.act.copy()
            q_s, p_s, tau_s = q, p, tau
            v, lam, q, _, e_sub, lam1, p, u1, _ = self._constrained(step, t_k, q, p, s * tau, v)
            if plain and self._record_held and events[r0][0] == "lift" and not self._friction_acts():
                # the tangent: Tracker.liftoff (its force law frictionless)
                self._lift_seg = ((q_s, p_s, v, lam, *self._seg_inner, u1, act0), r0, s, tau_s)
            else:  # one event of several, an impact while held, a lift-off under friction, a friction switch
                self._ev_event((q_s, p_s, v, lam, *self._seg_inner, u1, act0), r0, s, tau_s, events[r0][0])
            self._fswitch = self._fswitch or (plain and events[r0][0] in ("stop", "slide"))
            plain = False
            e_step = e_sub if self._forced else e_step  # forces: the step's energy is its last segment's
            self._book(lam + lam1)
            t, tau, guess = t + s * tau, (1.0 - s) * tau, v
            if events[r0][0] == "lift":
                self._release(step, t_k, t, r0)
                continue
            if events[r0][0] in ("stop", "slide"):
                before = self._sw_state()
                self._friction_switch(events[r0][0], r0, q, self._velocity(q, v, p))
                self._sw_check(events[r0][0], r0, before)
                continue
            group = [r for r, (kind, sr) in events.items() if kind == "cross" and sr - s <= tol.simultaneous]
            p = self._chain_impact(step, t_k, h, q, p, v, t, group, impacts, e_sub)

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
        switch."""
        act, slip, ref, branch, ride, held = before
        for f, sr in enumerate(self._stick_rows):
            if not self._held_rows[f] or not held[f]:
                continue  # let go, or held anew
            now = (self._held_rows[f], self.act[sr], self._slip[f], self._ref[f], self._ride[f])
            if (held[f], act[sr], slip[f], ref[f], ride[f]) != now:
                return False
            if any(branch[b] != self._branch[b] for b in self._branch_of[f]):
                return False
        return True

    def _ev_event(self, sub, r: int, s: float, tau: float, kind: str) -> None:
        """A constrained sub-step to an event of row ``r`` (``"lift"``, ``"cross"``, a friction switch
        ``"stop"`` or ``"slide"``): ``Tracker.event``."""
        if self._ev_tan is not None and not self._sw_covered(kind):
            return
        if self._ev_tan is not None:
            self._ev_tan.events_begin(self._ev_entry)
            self._ev_tan.event(sub, r, s, tau, kind)

    # -- a friction switch inside a held step (vcigen.sensitivity_switch): a located event ----------------
    def _sw_covered(self, kind: str) -> bool:
        """Whether the tangent carries an event of ``kind`` in the current friction mode: a lift-off or a row
        crossed in any mode (``Tracker.event``: the sub-step's friction slots, the slipping contacts'
        directions); without isotropic cones a slipping contact's stop and a lone sticking contact's slide (no
        contact slipping, no dependent stick: the force law of the stick row alone). Else the step breaks here
        (``"friction switch in a held step"``)."""
        if kind in ("lift", "cross"):
            return True
        if not any(g >= 0 for g in self._partner):  # no cone: one-tangent switches (SwitchTangents)
            if kind == "stop" or (not self._slip.any() and all(o < 0 for o in self._ride)):
                return True
        self._sw_lose()
        return False

    def _sw_lose(self) -> None:
        """A friction switch the tangent of a held step's events does not carry (stick <-> slip at a
        segment's start or not of one contact alone, the sliding direction turned, a contact set on another
        face, a cone's stop or slide): a mode change, no derivative; the step breaks with ``"friction switch
        in a held step"`` (the later hooks find the tangent lost)."""
        if self._ev_tan is not None:
            self._ev_tan.lose("friction switch in a held step")
            self._ev_done = True

    def _sw_state(self) -> tuple:
        """The rows held, slips and dependent sticks before a located switch (:meth:`_sw_check`)."""
        return self.act.copy(), self._slip.copy(), list(self._ride)

    def _sw_check(self, kind: str, sr: int, before: tuple) -> None:
        """After a located switch of stick row ``sr`` (:meth:`_friction_switch`): carried if it switched that
        contact alone, into a stick on its own row (``"stop"``) or a slip (``"slide"``); else (the sliding
        turned by an impact, a dependent stick, others switched with it) the step breaks. With isotropic cones
        the switch broke already (:meth:`_sw_covered`; C: no ``sens_sw_check``)."""
        if any(g >= 0 for g in self._partner):
            return
        act, slip, ride = before
        f = self.k.row_stick[sr]
        others = [g for g in range(len(self._stick_rows)) if g != f]
        same = all(slip[g] == self._slip[g] and ride[g] == self._ride[g] for g in others)
        same = same and all(act[x] == self.act[x] for x in range(self.k.r) if x != sr)
        if kind == "stop":
            ok = bool(self.act[sr]) and self._slip[f] == 0.0 and self._ride[f] < 0
        else:
            ok = not self.act[sr] and self._slip[f] != 0.0
        if not (ok and same):
            self._sw_lose()
        elif kind == "stop" and self._ev_tan is not None:  # a slide back at once (_sw_back) is carried too
            self._sw_stop = (self._ev_tan.step, self._events)

    def _sw_back(self, kind: str) -> bool:
        """A slide at the start of a segment right after a carried stop, no event between (a body stopped on a
        slope steeper than its friction angle slides back at once): its time is the stop's, whose tangent the
        events' tangent has, and the rest of the step slips from there (its slot by ``_friction_slots``)."""
        tan = self._ev_tan
        return kind == "slide" and tan is not None and self._sw_stop == (tan.step, self._events)

    def _ev_impulse(self, q, v, p, lam, targets, group) -> None:
        """The impulse law of an impact while held (:meth:`_chain_impact`): ``Tracker.impulse`` on its rows
        with an impulse, each with the contact whose restitution sets its target (-1: target 0); a group of
        rows hit at once (the weights of its impulse switch) breaks."""
        tan = self._ev_tan
        if tan is None:
            return
        if len(group) > 1:
            tan.lose("simultaneous impact")
            return
        tight = [int(r) for r in np.flatnonzero(lam)]
        tan.impulse(q, v, p, tight, [self.k.row_contact[r] if r in targets else -1 for r in tight])

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

    def _release(self, step, t_k, t, r: int) -> None:
        """Lift-off of row ``r`` at ``t``: logged once per contact that leaves sustained contact."""
        k = self.k
        self.act[r] = False
        j = k.row_contact[r]
        if not any(self.act[i] for i in range(k.r) if k.row_contact[i] == j):
            self.liftoffs.append((float(t), k.contact_names[j]))

    def _book(self, impulses) -> None:
        """Add the constraint impulses of a segment (``Lam + Lam'``, per row) to the step's forces."""
        k = self.k
        self._booked = True
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

    # -- events inside a constrained segment -------------------------------------------
    def _sub_end(self, step, t_k, q, p, tau, s, guess):
        """The constrained sub-step map at fraction ``s``: ``(v, end, u_end)`` (the evaluations at its end and
        the end velocity)."""
        v, *_, u1, end = self._constrained(step, t_k, q, p, s * tau, guess)
        return v, end, u1

    def _liftoff_fraction(self, step, t_k, q, p, tau, guess, r, f0, f1) -> float:
        """Fraction where row ``r``'s force (:meth:`_contact_forces` at the sub-step's end) vanishes.

        ``0`` if the force at the segment start ``f0`` is already negative (release at the start); else the
        root in ``[0, 1]`` of the force along the sub-step map (Illinois): where ``|force| <= EPS_LAM`` scale,
        or else the bracket's negative end, so that the released body leaves.
        """
        if f0 < 0:
            return 0.0
        ga, gb = float(f0), float(f1)

        def force(c, v):
            v, end, _ = self._sub_end(step, t_k, q, p, tau, c, v)
            return float(self._forces(end)[r]), v

        return _illinois(force, ga, gb, EPS_LAM * (1.0 + abs(ga) + abs(gb)), 1e-12, LIFT_ITER, guess)

    def _row_crossing(self, step, t_k, q, p, tau, guess, r, g1) -> float:
        """Fraction where inactive row ``r`` reaches 0 along the constrained sub-step map (Illinois)."""
        ga, gb = max(float(self.k.rows(q, guess)[0][r]), 0.0), float(g1)

        def height(c, v):
            v, end, _ = self._sub_end(step, t_k, q, p, tau, c, v)
            return float(end.psi[r]), v

        return _illinois(height, ga, gb, ROOT_EPS * max(ga, -gb), 4e-16, 200, guess)

    # -- impacts with rows ---------------------------------------------------------------
    def _impulse_law(self, step, t_k, q, p, guess, hit, targets):
        """Newton's law on the active rows and the rows ``hit`` (targets: outgoing ``g_r.qdot``), with
        Coulomb's cone on the held stick rows (MATH.md *Friction*).

        The complementarity problem of the rows ``S`` involved: impulses ``Lam >= 0`` and outgoing normal
        velocities ``g_r.qdot+ >= target_r``, one of the two tight for every row (bilateral rows: equality,
        ``Lam`` free). A held stick row (a one-tangent contact ``f`` sticking, :meth:`_law_cones`) sticks
        (tight, ``|Lam_t| <= mu_f Lam_n``, ``Lam_n`` its contact's normal impulse in this impact) or slips
        at either edge of its cone, ``Lam_t = -+mu_f Lam_n`` with the tangential velocity after ``>= 0``
        resp. ``<= 0`` (its contact's normal rows then push along ``g_n -+ mu_f g_t``). Without friction
        the Delassus matrix ``G M^-1 G^T`` is positive definite and the solution unique; the friction modes
        are tried all sticking first (the law of old where it stays inside the cones), then the first
        stick row slipping (``Lam_t = -mu_f Lam_n``, then ``+mu_f Lam_n``) and so on in base 3, each over
        the sets of tight rows from the largest down: the first solution is taken, deterministically. The
        isotropic cones held may only stick: an impulse out of their cone is a ``SolverError``. Returns
        ``(p+, Lam, vel-, vel+, dropped, slipped)``, ``dropped`` the rows left with no impulse (the caller
        releases the active ones), ``slipped`` the stick rows that slipped (the caller sets their contacts'
        modes, :meth:`_slip_at_impact`).
        """
        k = self.k
        vel = self._velocity(q, guess, p)
        mass = k.legendre(q, vel)[1]
        grad = k.rows(q, vel)[1]
        rows = [int(r) for r in np.flatnonzero(self.act)] + [r for r in hit if not self.act[r]]
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
        cones, strict = self._law_cones(rows)
        out = ""  # a strict stick row's impulse out of its cone (the error if nothing else solves the law)
        for modes in range(3 ** len(cones)):
            slips = [(modes // 3**c) % 3 for c in range(len(cones))]  # 0 stick, 1 Lam_t = -mu Lam_n, 2 +
            ws = w.copy()  # the columns of the slipping contacts' normal rows: g_n -+ mu g_t
            for (i, pools), mode in zip(cones, slips):
                for normals, mu in pools if mode else ():
                    ws[:, normals] += (-mu if mode == 1 else mu) * w[:, [i]]
            sliding = {i for (i, _), mode in zip(cones, slips) if mode}
            for mask in range((1 << n) - 1, -1, -1):
                tight = [i for i in range(n) if mask >> i & 1]
                if any(not free[i] and (not mask >> i & 1) != (i in sliding) for i in range(n)):
                    continue
                lam = np.zeros(n)
                if tight:
                    try:
                        lam[tight] = np.linalg.solve(ws[np.ix_(tight, tight)], b[tight])
                    except np.linalg.LinAlgError:
                        continue
                for (i, pools), mode in zip(cones, slips):
                    if mode:
                        lam[i] = (-1.0 if mode == 1 else 1.0) * _pooled(pools, lam)
                gap = w @ lam - b  # g_r.qdot+ - target_r
                if not (
                    all(lam[i] >= -lam_eps or not free[i] for i in tight)
                    and all(gap[i] >= -vel_eps for i in range(n) if not mask >> i & 1 and i not in sliding)
                ):
                    continue
                inside = True
                for (i, pools), mode in zip(cones, slips):
                    if mode == 0:
                        inside = inside and abs(lam[i]) <= _pooled(pools, lam) + lam_eps
                    else:
                        inside = inside and (gap[i] >= -vel_eps if mode == 1 else gap[i] <= vel_eps)
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
        p_plus = p + grad.T @ lam_full
        return p_plus, lam_full, vel, self._velocity(q, vel, p_plus), dropped, slipped

    def _law_cones(self, rows):
        """The held stick rows of the impulse law on ``rows`` with Coulomb's cone: ``[(i, pools)]`` of each
        one-tangent contact ``f`` sticking with its own row (``i`` its index in ``rows``), ``pools`` the
        ``(normals, mu_f)`` whose normal impulses give its room: its own contact's normal rows (indices in
        ``rows``), then those of the one-tangent dependent sticks it carries (their cones are its room too,
        as in :meth:`_cone_margin`; they slip with it); and ``[(i, normals, mu_f, o)]`` of the isotropic
        cones held (``i``, ``o`` their tangents' indices, -1 for one not held), which may only stick. A cone
        coupled to others by a dependent stick (:meth:`_cone_split`) is not checked."""
        k = self.k
        cones, strict = [], []

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
                    strict.append((i, normals(f), float(self._mu_f[f]), o))
            elif sr in rows:
                riders = [
                    g for g, owner in enumerate(self._ride) if g != f and owner == f and self._partner[g] < 0
                ]
                pools = [(normals(g), float(self._mu_f[g])) for g in [f, *riders]]
                cones.append((rows.index(sr), pools))
        return cones, strict

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

    def _slip_at_impact(self, q, vel_p, slipped) -> bool:
        """The stick rows that slipped in the impulse law (:meth:`_impulse_law`): their contacts slip after it
        along the tangential velocity after, ``slip_f = -mu_f sign(g_t.qdot+)``, or stick on where that is 0
        (to round-off). Whether any contact's mode changed (a friction switch: no tangent)."""
        k = self.k
        if not slipped:
            return False
        grad = k.rows(q, vel_p)[1]
        tiny = SLIDE_EPS * (1.0 + float(np.max(np.abs(vel_p))))
        switched = False
        for sr in slipped:
            f = k.row_stick[sr]
            sliding = float(grad[sr] @ vel_p)
            if abs(sliding) > tiny:
                self.act[sr] = False
                self._slip[f] = -self._mu_f[f] * math.copysign(1.0, sliding)
                switched = True
                for g, owner in enumerate(self._ride):  # its dependent sticks slide with it, the same way
                    if owner == f and g != f and self._partner[g] < 0:
                        along = float(grad[self._stick_rows[g]] @ grad[sr])
                        self._slip[g] = -self._mu_f[g] * math.copysign(1.0, sliding * along)
                        self._ride[g] = -1
        self._set_friction()
        return switched

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
        p_plus, lam, vel_m, vel_p, dropped, slipped = self._impulse_law(step, t_k, q, p, v, group, targets)
        if self._slip_at_impact(q, vel_p, slipped):  # stick -> slip at the impact: a mode change, no tangent
            self._sw_lose()
        else:
            self._ev_impulse(q, v, p, lam, targets, group)
        mass = k.legendre(q, vel_m)[1]
        loss = 0.5 * (vel_m @ mass @ vel_m - vel_p @ mass @ vel_p)
        for r in dropped:  # an active row the impact pulls off, unless it leaves below the resolution
            if self.act[r] and r not in group and not self._settles(float(grad[r] @ vel_p), acc[r], 1.0, h):
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
        p_plus, lam, vel_m, vel_p, dropped, _ = self._impulse_law(step, t_k, q, p, v, rows, {})
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
