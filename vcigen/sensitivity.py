"""Exact sensitivities of a run: tangents chained through every phase of the stepper (MATH.md).

The columns are ``z = (q0, v0, params)`` (``K = 2n + P``, ``P = len(model.defaults)``); the tangent of
the grid state is ``S_k = d(q_k, p_k)/dz``. Every phase solves ``F(x; d) = 0`` for its unknowns ``x``
given data ``d``; with ``F_x`` (the residual routine's ``jac``) and ``F_d`` (its ``d_*`` routine,
:mod:`vcigen.tangents`) at the solution, ``dx/dz = -F_x^-1 (F_d dd/dz)`` (implicit-function theorem).
The outputs of a phase (segment end, momenta, energy, impact point, the next phase's data) are explicit
in ``(x, d)``, their partials chained. Phases:

* smooth step (46): unknown ``v``; ``q_k+1 = q_k + h v``, ``p_k+1 = p+(q_k, v, h)``;
* contact time (47): unknowns ``(v, alpha)``; ``q~ = q + alpha tau v``, ``p~- = p+(q, v, alpha tau)``,
  ``E- = E_d(q, v, alpha tau)``, ``t~ = t + alpha tau``, the rest of the step ``(1 - alpha) tau``;
* jump (48): unknowns ``(w, mu)``, data ``(q~, nrm, p~-, E-, tau)``, ``nrm = grad phi_j(q~)``; the loss of
  restitution (39) ``(1 - e^2)/2 (n.qdot)^2 / (n.M^-1 n)`` with ``qdot`` one Newton step of the inverse
  Legendre transform from the incoming segment velocity (as the stepper computes it);
* several impacts in one step (78): unknowns ``(w, mu, beta)``, as (47) with ``beta`` for ``alpha``;
* a held grid step (sustained contact, its active set unchanged: one constrained segment, no event):
  ``rattle`` (unknowns ``(v, Lam)``) then ``rattle_project`` (unknowns ``(u1, Lam')``), whichever path
  found them (``vcigen.held`` or ``SustainedSteps._chain``);
* a lift-off at a located time in a held grid step (or in the rest of a plastic impact's step), then a free
  rest (46): the constrained sub-step to the root of the released row's force (its force law's partials
  ``d_forces``), that root's time by the implicit-function theorem (``Tracker.liftoff``);
* events inside a held step, one after another (``Tracker.event``, ``impulse``, ``free_end``): the segment's
  tangents ``(dq, dp, dtau, dt)`` are carried from the grid point (or the plastic impact) through each
  constrained sub-step to an event, located like (47) with its fraction: a lift-off (the root of the row's
  force) or an inactive row crossed (the root of ``psi_r(q1)``, ``d_psi``), whose impact takes the impulse law
  onto the rows (``p+ = p~- + G^T Lam``, targets ``-e g_r.qdot``: elastic, restitution or plastic); a release
  at a segment's start changes the active set only; then the constrained rest with the active set it has
  (``Tracker.held`` from the segment's tangents) or the free rest (46), with its own impacts (47)-(79);
* forces of time: the time slot of ``par`` is the start of the segment, its tangent ``d t~/dz``;
* Coulomb friction in one mode (MATH.md *Friction*): a held step whose frictional contacts slip throughout
  (the slip slot ``-mu_f s`` of ``par``, ``s`` fixed within the mode for one tangent, its tangent through
  ``mu_f``: ``d_friction``; an isotropic cone's ``s`` aimed at the segment's start from the state, its tangent
  through that aim, :meth:`Tracker._cone_slots`) or stick throughout (the stick row ``t(q) - ref = 0`` held,
  ``d ref = d t(q_k; par)``, its ``q`` and parameter partials): :meth:`Tracker._friction_slots`; a
  frictional impact (one tangent) in the branch of Coulomb's impulse law it takes (stick, or slip at either
  edge of the cone): the impulse direction ``n + rho t`` and the energy ``E + dK`` by
  :func:`vcigen.friction.impact_law_tangent`
  (:meth:`Tracker._friction_impact`); with an isotropic cone (two tangents, :func:`vcigen.friction.cone_law`)
  in its branch (stick: ``H m + g = 0``; slip: the edge's equations in ``(m, nu)`` by the implicit-function
  theorem), the direction ``n + rho_1 t1 + rho_2 t2`` by :func:`vcigen.friction.cone_law_tangent`;
* events inside a held step while friction acts, the friction mode kept (``SustainedSteps._no_switch``):
  each constrained sub-step with its friction slots' tangent from its start (:meth:`Tracker._friction_slots`;
  a slipping cone's aim there over what is left of the step, :meth:`Tracker._cone_slots` with ``dtau``),
  a lift-off's force law with the slipping contacts' directions
  ``grad psi + slip grad t`` (:meth:`Tracker._dforce`); a frictional contact let go (its friction ends with
  its normal force) or held anew at the event (a plastic landing: it slips or sticks from there) is no
  switch;
* a friction switch of a one-tangent contact inside a held step (no isotropic cone in the model), located
  like a lift-off (:mod:`vcigen.sensitivity_switch`), among the events above: a slipping contact that stops
  (the root of its sliding speed ``grad t(q1) . u1``) or a sticking one whose force reaches the cone (the root
  of ``mu_f N - |lambda_t|``), then the rest of the step in the new mode (a stick's reference
  ``d ref = grad t(q*) dq*`` at the point it stuck; a slip's slot); a slide back at the instant of such a stop
  (a slope steeper than the friction angle);
* rules with internal points (lobatto3): in every phase above the internal points ``u`` are one more
  unknown of the implicit-function theorem (their stationarity rows are the residual's first), recovered
  at the phase's solution (:meth:`Tangents.internal`; the stepper never sees them) and chained into
  ``p±``, ``E_d`` through ``d_segment``'s ``u`` columns. In a held phase the internal points are held on
  the active rows with their own multipliers ``Lam_m`` (``derive.held_internal_points``): ``rattle``'s
  unknowns are ``(v, Lam, Lam_m, u)``, all of the implicit-function theorem, and ``p+`` is ``rattle_end``'s
  (``d_rattle_end``; :meth:`Tracker._held_sub`), also in each constrained sub-step to an event inside a held
  step (:meth:`Tracker._located`).

Not covered (each a mode change or a set-valued law, no derivative to give): a simultaneous impact (a
group of contacts at once, free or while held), a grazing impact taking the continuous law, an event inside
a held step with isotropic cones under forces of time, a friction switch not located inside the step or not
of one contact alone (``"friction switch in a held step"``: at a segment's start, the sliding direction
turned, a dependent stick, a stop or slide in a model with isotropic cones, a slide while another contact
slips, a contact on another face), several cones aimed implicitly near rest (``SustainedSteps._cone_brake``),
an isotropic cone's impulse at its degenerate 0 (``"friction at an impact"``: round-off only), a landing
cone's second split, least split beside a slide or slide along a line (``"friction at an impact"``; a plain
least split is carried, :func:`vcigen.sensitivity_held._least_tangent`), a lift-off located on the best
split of dependent sticks (``"lift-off while a stick rides"``: ``FrictionModes._pressed``), the
``_restart`` fallback. From the first such step ``k`` on the tangent is NaN (``S_j`` for ``j > k``),
``Result.stats["sensitivity_lost"] = k`` and ``Result.sensitivity_breaks`` lists ``(step, reason)``.
"""

from __future__ import annotations

import math

import casadi as ca
import numpy as np

from .backends.casadi import routine_to_function
from .derive import DiscreteSystem
from .result import ordered_breaks
from .sensitivity_held import HeldTangents, _guarded
from .sensitivity_switch import SwitchTangents
from .tangents import tangent_routines

SYMBOLIC_SOLVE = 6  # the smooth step's tangent solves F_v symbolically (SX) up to this many unknowns
STAGE_ITERATIONS = 30  # Newton iterations recovering the internal points of a phase (Tangents.internal)


class _Flat:
    """A routine's outputs, row-major and concatenated, from its inputs concatenated (a CasADi buffer)."""

    def __init__(self, fns: list[ca.Function], sizes: list[tuple[int, int]]) -> None:
        first = fns[0]
        sym = ca.MX if first.is_a("MXFunction") else ca.SX
        ins = [sym.sym(first.name_in(i), first.sparsity_in(i)) for i in range(first.n_in())]
        outs = [ca.vec(o.T) for f in fns for o in f.call(ins)]
        # dense: the buffer receives the nonzeros only, so a structural zero would shift every entry after it
        self.f = ca.Function("flat", [ca.vertcat(*[ca.vec(i) for i in ins])], [ca.densify(ca.vertcat(*outs))])
        self.arg, self.res = np.zeros(self.f.size1_in(0)), np.zeros(self.f.size1_out(0))
        self._buf, self._trigger = self.f.buffer()
        self._buf.set_arg(0, memoryview(self.arg))
        self._buf.set_res(0, memoryview(self.res))
        self.cuts = np.cumsum([0] + [r * c for r, c in sizes]).tolist()
        self.sizes = sizes

    def __call__(self, *parts) -> list[np.ndarray]:
        i = 0
        for part in parts:
            part = np.ravel(part, order="F")  # a matrix input column-major, as ca.vec
            self.arg[i : i + part.size] = part
            i += part.size
        self._trigger()
        out = self.res.copy()  # the next call reuses the buffer
        return [out[a:b].reshape(s) for a, b, s in zip(self.cuts, self.cuts[1:], self.sizes)]


class Tangents:
    """The ``d_*`` routines of a system as numeric functions, converted on first use (one per simulator)."""

    def __init__(self, system: DiscreteSystem) -> None:
        self.system = system
        self.n, self.m = system.n, system.m
        self.npar, self.P = len(system.params), len(system.model.defaults)
        self.K = 2 * self.n + self.P
        self.ns = system.stages  # internal unknowns of a segment (lobatto3: n), the last ones of every phase
        have = {k: r for k, r in system.routines.items() if k.startswith("d_")}
        self._routines = have or tangent_routines(system.routines)
        self._fns: dict[str, _Flat] = {}

    def names(self) -> list[str]:
        """The ``K`` column names ``q0[<coord>]..., v0[<coord>]..., <param>...``."""
        coords = self.system.model.coordinate_names
        return (
            [f"q0[{c}]" for c in coords]
            + [f"v0[{c}]" for c in coords]
            + [str(s) for s in self.system.model.defaults]
        )

    def get(self, name: str) -> _Flat:
        """``name`` (``"d_segment"``, ...) or, for a residual routine, ``(jac, dres)`` in one call."""
        f = self._fns.get(name)
        if f is None:
            r = self._routines.get(name) or self.system.routines[name]
            if r.inputs[0].name != "x" or name in self._routines:  # its outputs, as they are
                f = _Flat([routine_to_function(r)], [o.shape for o in r.outputs])
            else:  # a residual routine: its jac and its d_ routine's dres, in one call
                d = self._routines["d_" + name]
                ins = [ca.SX.sym(a.name, a.size) for a in r.inputs]
                both = ca.Function(
                    name, ins, [routine_to_function(r).call(ins)[1], routine_to_function(d).call(ins)[0]]
                )
                f = _Flat([both], [r.output("jac").shape, d.output("dres").shape])
            self._fns[name] = f
        return f

    def internal(self, name: str, x, data: tuple, par) -> np.ndarray:
        """The internal points ``u`` of residual routine ``name`` at its solution ``x`` (without them: the
        stepper never sees them): Newton on the routine's first ``ns`` rows, their stationarity, from 0.

        ``u`` is a function of the phase's segment alone (its start, velocity and duration), so this is
        the stepper's ``u`` to the solve's tolerance; an empty array for a rule without internal points."""
        ns = self.ns
        if not ns:
            return np.zeros(0)
        f = self._fns.get("res_" + name)
        if f is None:
            r = self.system.routines[name]
            f = self._fns["res_" + name] = _Flat([routine_to_function(r)], [o.shape for o in r.outputs])
        u = np.zeros(ns)
        for _ in range(STAGE_ITERATIONS):
            res, jac = f(np.concatenate([x, u]), *data, par)
            du = np.linalg.solve(jac[:ns, -ns:], res[:ns, 0])
            u -= du
            if np.max(np.abs(du)) <= 1e-15 * (1.0 + np.max(np.abs(u))):
                break
        return u

    def smooth_map(self) -> _Flat:
        """``(x, q, p, h, par, S_k, dpar/dz) -> S_k+1`` of a smooth step (46) in one call: the implicit
        function ``dx = -F_x^-1 F_d (dq, dp, 0, dpar)`` and ``dp+`` chained (``S``, ``dpar`` column-major).

        ``x = v``, or ``(v, u)`` with internal points: ``u`` is one more unknown of the implicit function
        (its stationarity rows are in the residual), and ``p+`` depends on it (``d_segment``'s ``u``
        columns), so ``du`` is chained too."""
        f = self._fns.get("smooth_map")
        if f is None:
            n, K, npar, ns = self.n, self.K, self.npar, self.ns
            r, d = self.system.routines["smooth"], self._routines["d_smooth"]
            seg = self._routines["d_segment"]
            # larger: a linear solver at run time, not QR in SX
            sym = ca.SX if n + ns <= SYMBOLIC_SOLVE else ca.MX
            x, q, p, h, par = (sym.sym(a.name, a.size) for a in r.inputs)
            s, dpar = sym.sym("S", 2 * n, K), sym.sym("dpar", npar, K)
            dq, dp = s[:n, :], s[n:, :]
            jac = routine_to_function(r)(x, q, p, h, par)[1]
            dres = routine_to_function(d)(x, q, p, h, par)
            dx = -ca.solve(jac, ca.mtimes(dres, ca.vertcat(dq, dp, sym.zeros(1, K), dpar)))
            v, dv = x[:n], dx[:n, :]
            inner = (x[n:],) if ns else ()  # d_segment(q0, v, tau, [u,] par)
            dpp = routine_to_function(seg)(q, v, h, *inner, par)[1]
            dp1 = ca.mtimes(dpp, ca.vertcat(dq, dv, sym.zeros(1, K), *(dx[n:, :],) * bool(ns), dpar))
            fn = ca.Function("smooth_map", [x, q, p, h, par, s, dpar], [ca.vertcat(dq + h * dv, dp1)])
            f = self._fns["smooth_map"] = _Flat([fn], [(2 * n, K)])
        return f


class Tracker(HeldTangents, SwitchTangents):
    """The tangent of one run, updated by the stepper's hooks after each phase (``Stepper(..., tangent=)``).

    Holds the tangent of the grid state and, inside an impact step, of the current segment's data:
    start ``q``, start time ``t``, remaining duration ``tau``, incoming momentum ``p``, kept energy ``e``,
    impulse direction ``nrm`` and the incoming segment velocity ``vin`` (for the loss of (39)).
    """

    def __init__(self, tangents: Tangents, kernels) -> None:
        self.tg, self.k = tangents, kernels
        self.n, self.K = tangents.n, tangents.K
        self.S = np.empty((0, 2 * self.n, self.K))
        self.breaks: list[tuple[int, str]] = []
        self.lost: int | None = None
        self.timed = tangents.system.timed
        base = np.zeros((tangents.npar, self.K))
        base[: tangents.P, 2 * self.n :] = np.eye(tangents.P)
        self._par0 = base
        self._slots: np.ndarray | None = None  # the friction slots' tangent in a held step (_friction_slots)
        self.step = -1
        self.graze = False
        self.cur: np.ndarray | None = None  # S_k
        self.next: np.ndarray | None = None  # S_k+1, once a hook has it
        self._ev_step = -1  # the grid step whose events carry the segment's tangents (events_begin)

    # -- bookkeeping ---------------------------------------------------------------
    def par(self, t: float) -> np.ndarray:
        """The parameter vector segments starting at ``t`` see (the kernels' own, time slot at ``t``)."""
        par = np.array(self.k.par, dtype=float)[: self.tg.npar]  # C kernels: one unused entry if none
        if self.timed:
            par[-1] = t
        return par

    def dpar(self, dt: np.ndarray | None) -> np.ndarray:
        """``d par / dz``: ``I_P`` on the model's parameters, ``dt`` on time, on the friction slots 0 but in a
        held step with friction (:meth:`_friction_slots`)."""
        out = self._par0 if self._slots is None else self._par0 + self._slots
        if not self.timed or dt is None:
            return out
        out = out.copy()
        out[-1] = dt
        return out

    def start(self, q0, v0, t0: float, cap: int) -> None:
        """``S_0``: ``dq0/dz = [I 0 0]``, ``dp0/dz = [dmom/dq, M, dmom/dpar]`` (``d_legendre``)."""
        n = self.n
        dmom, _ = self.tg.get("d_legendre")(q0, v0, np.zeros(n), self.par(t0))
        s = np.zeros((2 * n, self.K))
        s[:n, :n] = np.eye(n)
        s[n:, : 2 * n] = dmom[:, : 2 * n]
        s[n:] += dmom[:, 2 * n :] @ self._par0
        self.S = np.empty((cap + 1, 2 * n, self.K))
        self.S[0] = s
        self.cur = s

    def grow(self, cap: int) -> None:
        out = np.empty((cap + 1, *self.S.shape[1:]))
        out[: self.S.shape[0]] = self.S
        self.S = out

    def begin(self, step: int, t: float) -> None:
        """Grid step ``step`` from ``t``: its tangent is ``S_step``."""
        self.step, self.t, self.next = step, t, None
        self.graze = False  # the segment after a continuous-law impact (:meth:`jump`, :meth:`jump_end`)

    def end(self, step: int) -> None:
        """Store ``S_step+1``; a step no hook resolved loses the tangent (never silently wrong)."""
        if self.lost is None and self.next is None:
            self.lose("a phase without a tangent")
        elif self.lost is None and not np.isfinite(self.next).all():
            self.lose("a non-finite tangent (singular Jacobian)")
        if self.lost is None:
            self.cur = self.next
            self.S[step + 1] = self.next
        else:
            self.S[step + 1] = math.nan

    def lose(self, reason: str) -> None:
        """The step in progress is not covered: NaN from here on (``sensitivity_lost``, ``_breaks``)."""
        if not self.breaks or self.breaks[-1] != (self.step, reason):
            self.breaks.append((self.step, reason))
        if self.lost is None:
            self.lost = self.step

    @property
    def active(self) -> bool:
        return self.lost is None

    # -- phases ----------------------------------------------------------------------
    def _ift(self, name: str, x, data: tuple, ddata: np.ndarray, t: float) -> np.ndarray:
        """``dx/dz = -F_x^-1 F_d dd/dz`` of residual routine ``name`` at its solution ``x``."""
        jac, dres = self.tg.get(name)(x, *data, self.par(t))
        return -np.linalg.solve(jac, dres @ ddata)

    def _ift_staged(self, name: str, x, data: tuple, ddata: np.ndarray, t: float):
        """:meth:`_ift` with the internal points: ``(dx, u, du)``, ``x`` as the stepper has it (without
        ``u``), ``u`` recovered (:meth:`Tangents.internal`) and one more unknown of the implicit function
        (its stationarity rows are the residual's first); ``u``, ``du`` empty without internal points."""
        par = self.par(t)
        u = self.tg.internal(name, x, data, par)
        dx = self._ift(name, np.concatenate([x, u]), data, ddata, t)
        nx = len(x)
        return dx[:nx], u, dx[nx:]

    def _segment(self, q, v, tau: float, t: float, dq, dv, dtau, dt, u=None, du=None):
        """Tangents of ``p-``, ``p+``, ``E_d`` of the segment ``(q, v, tau)`` starting at ``t`` (with its
        internal points ``u`` and their tangent ``du`` under a rule that has them)."""
        return self._segment_cols(q, v, tau, t, dq, dv, dtau, self.dpar(dt), u, du)

    @_guarded
    def smooth(self, q, p, h: float, v) -> None:
        """Smooth step (46): ``v`` from ``p_k = p-(q_k, q_k + h v, h)``; ``S_k+1``."""
        if not self.active:
            return
        par = self.par(self.t)
        x = np.concatenate([v, self.tg.internal("smooth", v, (q, p, h), par)])
        self.next = self.tg.smooth_map()(x, q, p, h, par, self.cur, self._par0)[0]

    def first_segment(self) -> None:
        """The first segment of an impact step starts at the grid point (data ``q_k, p_k, h, t_k``)."""
        if not self.active:
            return
        n, s = self.n, self.cur
        self.dq, self.dp = s[:n].copy(), s[n:].copy()
        self.dtau, self.dt = np.zeros((1, self.K)), np.zeros(self.K)
        self.de = np.zeros((1, self.K))
        self.dnrm = None
        self.graze = False

    def _data(self, seg) -> tuple[tuple, np.ndarray]:
        """The data of the residuals of segment ``seg`` (after ``x``) and their tangent."""
        dpar = self.dpar(self.dt)
        if seg.contact < 0:
            return (seg.q, seg.p_in, seg.tau), np.vstack([self.dq, self.dp, self.dtau, dpar])
        data = (seg.q, seg.nrm, seg.p_in, seg.e_in, seg.tau)
        return data, np.vstack([self.dq, self.dnrm, self.dp, self.de, self.dtau, dpar])

    @_guarded
    def contact(self, seg, j: int, x, s: float, group) -> None:
        """Contact time (47) or the end of a segment on contact ``j`` (78): the next segment's data."""
        if not self.active:
            return
        if len(group) > 1:
            self.lose("simultaneous impact")
            return
        if self.graze:  # a segment after the continuous law meets a contact: (78) holds an energy it reset
            self.lose("grazing impact")
            return
        n, k = self.n, self.k
        name = ("contact_time_" if seg.contact < 0 else "jump_contact_") + k.contact_names[j]
        data, dd = self._data(seg)
        dx, u, du = self._ift_staged(name, x, data, dd, seg.t)
        dv, ds = dx[:n], dx[-1:]
        v = x[:n]
        tau_c = s * seg.tau
        dtau_c = seg.tau * ds + s * self.dtau
        dq_c = self.dq + np.outer(v, dtau_c) + tau_c * dv
        _, dp_in, de_c = self._segment(seg.q, v, tau_c, seg.t, self.dq, dv, dtau_c, self.dt, u, du)
        dt_c = self.dt + dtau_c[0]
        q_c, t_c = seg.q + tau_c * v, seg.t + tau_c
        dgrad = self.tg.get("d_contacts")(q_c, self.par(t_c))[0]
        self.dnrm = dgrad[j * n : (j + 1) * n] @ np.vstack([dq_c, self.dpar(dt_c)])
        if seg.contact < 0:
            self.de = de_c
        self.dq, self.dp, self.dt, self.dtau = dq_c, dp_in, dt_c, self.dtau - dtau_c
        self.dvin, self.t_seg = dv, t_c

    @_guarded
    def jump(self, seg, v_in, rest: float, kind: str, law=None, touch: bool = False) -> None:
        """After the jump (48) on ``seg``: the loss of (39), or with Coulomb friction (``law = (j, n)``: the
        contact and its normal before the impulse direction became ``n + rho t``) the tangent of its impulse
        law (:meth:`_friction_impact`). Plastic follows (:meth:`plastic`); grazing is not covered but for a
        frictionless touch and go (``touch``: ``ImpactSteps._departs``, rules without internal points): the
        continuous law's ``p~- + mu0 n`` into ``dp``, then :meth:`jump_end` solves (48b) alone."""
        if not self.active:
            return
        if kind == "plastic":  # the impulse law and the constrained rest of the step follow (plastic, held)
            return
        grazing = kind == "grazing" and touch and law is None and not self.tg.ns
        if kind != "jump" and not grazing:
            self.lose(f"{kind} impact")
            return
        if law is not None:
            self._friction_impact(seg, v_in, rest, *law)
            return
        if rest >= 1.0 and not grazing:
            return
        par = self.par(seg.t)
        leg, dleg = self.tg.get("legendre"), self.tg.get("d_legendre")
        mom0, mass0 = leg(seg.q, v_in, par)
        a = np.linalg.solve(mass0, seg.p_in - mom0[:, 0])
        vel = v_in + a
        mass1 = leg(seg.q, vel, par)[1]
        minv_n = np.linalg.solve(mass1, seg.nrm)
        nv, nmn = float(seg.nrm @ vel), float(seg.nrm @ minv_n)
        if not nv < 0.0:
            if grazing:  # mu0 = 0 (max(., 0) at its kink): no derivative
                self.lose(f"{kind} impact")
            return
        dpar = self.dpar(self.dt)
        dvel = self._dvel(seg.q, v_in, a, mass0, par, dpar)
        _, dma1 = dleg(seg.q, vel, minv_n, par)
        dminv = np.linalg.solve(mass1, self.dnrm - dma1 @ np.vstack([self.dq, dvel, dpar]))
        dnv = vel @ self.dnrm + seg.nrm @ dvel
        dnmn = minv_n @ self.dnrm + seg.nrm @ dminv
        j = seg.contact
        de_rest = self.tg.get("d_restitution")(par)[0][j] @ dpar
        if grazing:  # the continuous law: p+ = p~- + mu0 n, mu0 = -(1 + e) n.qdot / n.M^-1 n
            mu0 = -(1.0 + rest) * nv / nmn
            dmu = -(1.0 + rest) * (dnv / nmn - nv * dnmn / (nmn * nmn)) - de_rest * nv / nmn
            self.dp = self.dp + np.outer(seg.nrm, dmu) + mu0 * self.dnrm
            self.graze = True
            return
        dloss = -rest * de_rest * nv * nv / nmn + (1.0 - rest * rest) * (
            nv * dnv / nmn - 0.5 * nv * nv * dnmn / (nmn * nmn)
        )
        self.de = self.de - dloss

    def _friction_impact(self, seg, v_in, rest: float, j: int, nrm) -> None:
        """Coulomb friction at an impact on contact ``j`` (``Stepper._frictional_law``, :func:`impact_law`, or
        :func:`cone_law` on a contact with an isotropic cone) in the branch it took: the jump (48) runs along
        ``n + rho t`` (a cone: ``n + rho_1 t1 + rho_2 t2``) with the energy ``E + dK``; ``dnrm`` and ``de``
        become their tangents. ``rho`` and ``dK`` are functions of the scalars ``n.qdot``, ``t_i.qdot``,
        ``n.A n``, ``n.A t_i``, ``t_i.A t_l`` (``A = M^-1`` at ``(q~, qdot)``, ``qdot`` one Newton step of the
        inverse Legendre transform from ``v_in``), ``mu_f`` and ``e``, differentiated in their branch
        (:func:`vcigen.friction.impact_law_tangent`, :func:`vcigen.friction.cone_law_tangent`); ``dn`` is the
        contact time's ``dnrm``, ``dt_i`` from ``d_friction`` (``d_friction_cone``), ``d(A n) = A (dn - d(M)
        A n)`` by ``d_legendre``."""
        from .friction import cone_law_tangent, impact_law_tangent

        k, n = self.k, self.n
        par, dpar = self.par(seg.t), self.dpar(self.dt)
        mom0, mass0 = k.legendre(seg.q, v_in)
        a = np.linalg.solve(mass0, seg.p_in - mom0)
        vel = v_in + a
        dvel = self._dvel(seg.q, v_in, a, mass0, par, dpar)
        mu, tgrad, _ = k.friction(seg.q)
        dmu, dtg = self.tg.get("d_friction")(seg.q, par)
        dqp = np.vstack([self.dq, dpar])
        tans, dtans = [tgrad[j]], [dtg[j * n : (j + 1) * n] @ dqp]
        cone = bool(getattr(k, "cone", ())) and bool(k.cone[j])
        if cone:  # the second tangent of the isotropic cone
            tans.append(k.friction_cone(seg.q)[j])
            dtans.append(self.tg.get("d_friction_cone")(seg.q, par)[0][j * n : (j + 1) * n] @ dqp)
        mass = k.legendre(seg.q, vel)[1]
        dirs, ddirs = [nrm, *tans], [self.dnrm, *dtans]
        adirs = np.linalg.solve(mass, np.column_stack(dirs)).T  # A n, A t_i
        dleg = self.tg.get("d_legendre")
        d_state = np.vstack([self.dq, dvel, dpar])
        dadirs = [
            np.linalg.solve(mass, dd - dleg(seg.q, vel, ad, par)[1] @ d_state) for dd, ad in zip(ddirs, adirs)
        ]
        # the scalars in the laws' order: n.qdot, t_i.qdot, then d_i.A d_l over the pairs (impact_law_tangent:
        # n.qdot, t.qdot, n.A n, n.A t, t.A t; cone_law_tangent: with t1, t2)
        pairs = [(0, 0), (0, 1), (1, 1)] if not cone else [(0, 0), (0, 1), (0, 2), (1, 1), (1, 2), (2, 2)]
        scalars = [float(d @ vel) for d in dirs] + [float(dirs[i] @ adirs[r]) for i, r in pairs]
        dscalars = np.array(
            [vel @ dd + d @ dvel for d, dd in zip(dirs, ddirs)]
            + [adirs[r] @ ddirs[i] + dirs[i] @ dadirs[r] for i, r in pairs]
        )
        de_rest = self.tg.get("d_restitution")(par)[0][j] @ dpar
        tangent = cone_law_tangent if cone else impact_law_tangent
        law = tangent(tuple(scalars), dscalars, float(mu[j]), dmu[j] @ dpar, rest, de_rest)
        if law is None:  # the cone's impulse at its degenerate 0 (round-off): no derivative
            self.lose("friction at an impact")
            return
        rho, _, drho, ddk, _ = law
        rho, drho = np.atleast_1d(rho), np.atleast_2d(drho)
        self.dnrm = self.dnrm + sum(np.outer(t, dr) + r * dt for t, dt, r, dr in zip(tans, dtans, rho, drho))
        self.de = self.de + ddk

    @_guarded
    def jump_end(self, seg) -> None:
        """The last segment after an impact ends at the grid time (48), (49): ``S_k+1``."""
        if not self.active:
            return
        n = self.n
        x = seg.x
        if self.graze:  # (48b) alone from p~- + mu0 n (dp its tangent, :meth:`jump`)
            self.graze = False
            p_t = seg.p_in + x[n] * seg.nrm
            dd = np.vstack([self.dq, self.dp, self.dtau, self.dpar(self.dt)])
            dw, u, du = self._ift("smooth", x[:n], (seg.q, p_t, seg.tau), dd, seg.t), None, None
        else:
            data, dd = self._data(seg)
            dx, u, du = self._ift_staged("jump", x[: n + 1], data, dd, seg.t)
            dw = dx[:n]
        w = x[:n]
        dq_end = self.dq + np.outer(w, self.dtau) + seg.tau * dw
        _, dp_end, _ = self._segment(seg.q, w, seg.tau, seg.t, self.dq, dw, self.dtau, self.dt, u, du)
        self.next = np.vstack([dq_end, dp_end])

    # -- the result ----------------------------------------------------------------
    def attach(self, res, steps: int) -> None:
        """``res.sensitivity`` ``(N, 2n, K)``, its column names and breaks, ``stats["sensitivity_lost"]``."""
        res.sensitivity = self.S[: steps + 1].copy()
        res.sensitivity_names = self.tg.names()
        res.sensitivity_breaks = ordered_breaks(self.breaks)  # once each, in the C variant's order
        if self.lost is not None:
            res.stats["sensitivity_lost"] = self.lost
