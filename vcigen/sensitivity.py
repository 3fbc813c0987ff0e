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
  ``d ref = grad t(q_k) dq_k``): :meth:`Tracker._friction_slots`; a frictional impact (one tangent) in the
  branch of Coulomb's impulse law it takes (stick, or slip at either edge of the cone): the impulse direction
  ``n + rho t`` and the energy ``E + dK`` by :func:`vcigen.friction.impact_law_tangent`
  (:meth:`Tracker._friction_impact`);
* rules with internal points (lobatto3): in every phase above the internal points ``u`` are one more
  unknown of the implicit-function theorem (their stationarity rows are the residual's first), recovered
  at the phase's solution (:meth:`Tangents.internal`; the stepper never sees them) and chained into
  ``p±``, ``E_d`` through ``d_segment``'s ``u`` columns. In a held phase the internal points are held on
  the active rows with their own multipliers ``Lam_m`` (``derive.held_internal_points``): ``rattle``'s
  unknowns are ``(v, Lam, Lam_m, u)``, all of the implicit-function theorem, and ``p+`` is ``rattle_end``'s
  (``d_rattle_end``; :meth:`Tracker._held_sub`).

Not covered (each a mode change or a set-valued law, no derivative to give): a simultaneous impact (a
group of contacts at once, free or while held), a grazing impact taking the continuous law, an event inside
a held step while friction acts or under a rule with internal points, a friction switch (``"friction switch
in a held step"``: stick <-> slip, the sliding direction turned, a contact released or on another face),
several cones aimed implicitly near rest (``SustainedSteps._cone_brake``), an isotropic cone's impulse at an
impact, the ``_restart`` fallback. From the first such step ``k`` on the tangent is NaN (``S_j`` for
``j > k``), ``Result.stats["sensitivity_lost"] = k`` and ``Result.sensitivity_breaks`` lists
``(step, reason)``.
"""

from __future__ import annotations

import functools
import math

import casadi as ca
import numpy as np

from .backends.casadi import routine_to_function
from .derive import DiscreteSystem
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


def _guarded(hook, name: str | None = None):
    """A hook whose linear solve meets a singular matrix loses the tangent instead of stopping the run (the
    reason names ``name``, else the hook)."""

    @functools.wraps(hook)
    def run(self, *args) -> None:
        try:
            hook(self, *args)
        except np.linalg.LinAlgError:
            self.lose(f"a singular Jacobian in the tangent of {name or hook.__name__}")

    return run


def _event_hook(hook):
    """:func:`_guarded`, each phase of an event inside a held step named ``event`` (C WHY_SINGULAR_EVENT)."""
    return _guarded(hook, "event")


class Tracker:
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

    def _friction_slots(self, q, dq, act, t: float) -> np.ndarray | None:
        """The tangent of the friction slots of ``par`` within a friction mode (MATH.md *Friction*), at the
        start ``q`` of a held segment (``dq`` its tangent): a slipping contact's slot ``-mu_f s`` moves with
        ``mu_f`` alone (``d_friction``; the sliding direction ``s`` of a one-tangent contact is fixed within
        the mode), a sticking one's reference ``ref_f`` with the point it sticks at: its stick row
        ``tangent_f(q) - ref_f = 0`` holds at every point of the mode, so ``d ref_f = grad tangent_f(q) dq``
        (exact, whenever the stick began: before the step it held at ``q`` too). The branch signs: 0.
        ``None`` without friction (every slot 0)."""
        k = self.k
        nf = len(getattr(k, "frictional", ()))
        if not nf:
            return None
        fs, par = k.friction_slot, self.par(t)
        out = np.zeros((self.tg.npar, self.K))
        slip = par[fs : fs + nf]
        if slip.any():
            mu = k.friction(q)[0]
            dmu = self.tg.get("d_friction")(q, par)[0] @ self._par0  # (m, K): mu_f moves with the parameters
            for f, j in enumerate(k.frictional):
                if slip[f]:
                    out[fs + f] = slip[f] / mu[j] * dmu[j]
        grad = self.tg.get("rows")(q, np.zeros(self.n), par)[1]
        for f in range(nf):
            sr = k.row_stick.index(f)
            if act[sr]:
                out[fs + nf + f] = grad[sr] @ dq[:, : self.K]
        return out

    def _cone_slots(self, q, p, dq, dp, tau: float, act, t: float, out: np.ndarray) -> bool:
        """The slip slots of the slipping cones (two tangents) in ``out``: ``SustainedSteps._cone_aim`` at the
        segment's start ``(q, u)``, ``u = M^-1 p`` (the stepper's one Newton step, exact for a momentum
        linear in the velocity): every slipping cone first along its sliding velocity ``w = (grad t1 . u,
        grad t2 . u)``, ``s0 = -mu_f w / |w|``, then, if the stepper took it, along the midpoint prediction
        ``mid = w + tau/2 (grad t . a + curv_t)``, ``s1 = -mu_f mid / |mid|``, ``a`` the acceleration of
        the force law with the directions ``s0`` (``M a = rhs + dirs^T lam``, ``G a + curv = 0`` on the
        active rows: its tangent by the implicit-function theorem with ``d_forces`` at ``lam~``, the stick
        rows carrying ``s lam``). Which one the stepper took is read from the slots (to 1e-9); ``False`` if
        neither (the implicit aim of several cones near rest, or a cone too slow to aim): no tangent then."""
        k, n, K, tg = self.k, self.n, self.K, self.tg
        fs, nf = k.friction_slot, len(k.frictional)
        par = self.par(t)
        cones = [(f, g) for f, g in enumerate(k.partner) if g > f and (par[fs + f] or par[fs + g])]
        if not cones:
            return True
        rows = [k.row_stick.index(f) for f in range(nf)]
        dpar = self._par0 + out  # the one-tangent slips' tangents already in out
        mom0, mass0 = k.legendre(q, np.zeros(n))
        u = np.linalg.solve(mass0, p - mom0)
        dmom0, dma0 = tg.get("d_legendre")(q, np.zeros(n), u, par)
        d0 = np.vstack([dq, np.zeros((n, K)), dpar])
        du = np.linalg.solve(mass0, dp - (dmom0 + dma0) @ d0)
        _, grad, curv = k.rows(q, u)
        rhs, mass = k.dynamics(q, u)[0], k.legendre(q, u)[1]
        dgrad = tg.get("d_rows")(q, u, par)[0]
        dqp = np.vstack([dq, dpar])
        mu = k.friction(q)[0]
        dmu = tg.get("d_friction")(q, par)[0] @ self._par0
        tiny = 1e-12 * (1.0 + float(np.max(np.abs(u))))  # sustained.SLIDE_EPS

        def unit(vec, dvec, m, dm):  # -m vec/|vec| and its tangent
            nv = float(np.linalg.norm(vec))
            e = vec / nv
            return -m * e, -np.outer(e, dm) - m * (dvec - np.outer(e, e @ dvec)) / nv

        slip = par[fs : fs + nf].copy()
        dslip = out[fs : fs + nf].copy()
        w, dw = {}, {}
        for f, g in cones:
            rr = [rows[f], rows[g]]
            w[f] = np.array([grad[r] @ u for r in rr])
            dw[f] = np.array([u @ (dgrad[r * n : (r + 1) * n] @ dqp) + grad[r] @ du for r in rr])
            if float(np.linalg.norm(w[f])) <= tiny:
                return False
            j = k.frictional[f]
            slip[[f, g]], dslip[[f, g]] = unit(w[f], dw[f], mu[j], dmu[j])
        # the force law with the directions s0 (SustainedSteps._forces), and its tangent
        on = np.flatnonzero(act)
        dirs = grad.copy()
        for f, j in enumerate(k.frictional):
            if slip[f]:
                dirs[[r for r in on if k.row_contact[r] == j]] += slip[f] * grad[rows[f]]
        jac = np.block([[mass, -dirs[on].T], [grad[on], np.zeros((on.size, on.size))]])
        sol = np.linalg.solve(jac, np.concatenate([rhs, -curv[on]]))
        acc, lam = sol[:n], np.zeros(k.r)
        lam[on] = sol[n:]
        lam_t = lam.copy()  # the stick rows carry slip_f times their contact's normal force
        normal = {}
        for f, j in enumerate(k.frictional):
            if slip[f]:
                normal[f] = sum(lam[r] for r in on if k.row_contact[r] == j)
                lam_t[rows[f]] += slip[f] * normal[f]
        dres = tg.get("d_forces")(q, u, acc, lam_t, par)[0]
        d_state = np.vstack([dq, du, self._par0])
        d_state[2 * n :] += out  # the one-tangent slips (par's friction slots)
        df = dres[np.r_[np.arange(n), n + on]] @ d_state
        for f, s in normal.items():  # the slips' own columns: -N_f grad t_f dslip_f
            df[:n] -= s * np.outer(grad[rows[f]], dslip[f])
        dsol = -np.linalg.solve(jac, df)
        dacc = dsol[:n]
        for f, g in cones:
            rr = [rows[f], rows[g]]
            turn = 0.5 * tau * np.array([grad[r] @ acc + curv[r] for r in rr])
            dturn = 0.5 * tau * np.array([dres[n + r] @ d_state + grad[r] @ dacc for r in rr])
            j = k.frictional[f]
            s0, ds0 = slip[[f, g]], dslip[[f, g]]
            have = par[fs + np.array([f, g])]
            scale = 1e-9 * max(mu[j], 1e-300)
            if float(np.linalg.norm(w[f] + turn)) > tiny:
                s1, ds1 = unit(w[f] + turn, dw[f] + dturn, mu[j], dmu[j])
                if np.abs(have - s1).max() <= scale:
                    out[fs + f], out[fs + g] = ds1
                    continue
            if np.abs(have - s0).max() <= scale:
                out[fs + f], out[fs + g] = ds0
                continue
            return False
        return True

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
    def jump(self, seg, v_in, rest: float, kind: str, law=None) -> None:
        """After the jump (48) on ``seg``: plastic and grazing are not covered; the loss of (39), or with
        Coulomb friction (``law = (j, n)``: the contact and its normal before the impulse direction became
        ``n + rho t``) the tangent of its impulse law (:meth:`_friction_impact`)."""
        if not self.active:
            return
        if kind == "plastic":  # the impulse law and the constrained rest of the step follow (plastic, held)
            return
        if kind != "jump":
            self.lose(f"{kind} impact")
            return
        if law is not None and getattr(self.k, "cone", ()) and self.k.cone[law[0]]:
            self.lose("friction at an impact")  # the isotropic cone's impulse: not differentiated
            return
        if law is not None:
            self._friction_impact(seg, v_in, rest, *law)
            return
        if rest >= 1.0:
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
            return
        dpar = self.dpar(self.dt)
        dvel = self._dvel(seg.q, v_in, a, mass0, par, dpar)
        _, dma1 = dleg(seg.q, vel, minv_n, par)
        dminv = np.linalg.solve(mass1, self.dnrm - dma1 @ np.vstack([self.dq, dvel, dpar]))
        dnv = vel @ self.dnrm + seg.nrm @ dvel
        dnmn = minv_n @ self.dnrm + seg.nrm @ dminv
        j = seg.contact
        de_rest = self.tg.get("d_restitution")(par)[0][j] @ dpar
        dloss = -rest * de_rest * nv * nv / nmn + (1.0 - rest * rest) * (
            nv * dnv / nmn - 0.5 * nv * nv * dnmn / (nmn * nmn)
        )
        self.de = self.de - dloss

    def _friction_impact(self, seg, v_in, rest: float, j: int, nrm) -> None:
        """Coulomb friction at an impact on contact ``j`` (``Stepper._frictional_law``, :func:`impact_law`)
        in the branch it took: the jump (48) runs along ``n + rho t`` with the energy ``E + dK``; ``dnrm`` and
        ``de`` become their tangents. ``rho`` and ``dK`` are closed forms of ``n.qdot``, ``t.qdot``,
        ``n.A n``, ``n.A t``, ``t.A t`` (``A = M^-1`` at ``(q~, qdot)``, ``qdot`` one Newton step of the
        inverse Legendre transform from ``v_in``), ``mu_f`` and ``e``
        (:func:`vcigen.friction.impact_law_tangent`); ``dn`` is the contact time's ``dnrm``, ``dt`` from
        ``d_friction``, ``d(A n) = A (dn - d(M) A n)`` by ``d_legendre``."""
        from .friction import impact_law_tangent

        k, n = self.k, self.n
        par, dpar = self.par(seg.t), self.dpar(self.dt)
        mom0, mass0 = k.legendre(seg.q, v_in)
        a = np.linalg.solve(mass0, seg.p_in - mom0)
        vel = v_in + a
        dvel = self._dvel(seg.q, v_in, a, mass0, par, dpar)
        mu, tgrad, _ = k.friction(seg.q)
        t = tgrad[j]
        mass = k.legendre(seg.q, vel)[1]
        an, at = np.linalg.solve(mass, np.column_stack([nrm, t])).T
        dmu, dtg = self.tg.get("d_friction")(seg.q, par)
        dt = dtg[j * n : (j + 1) * n] @ np.vstack([self.dq, dpar])
        dn = self.dnrm
        dleg = self.tg.get("d_legendre")
        d_state = np.vstack([self.dq, dvel, dpar])
        dan = np.linalg.solve(mass, dn - dleg(seg.q, vel, an, par)[1] @ d_state)
        dat = np.linalg.solve(mass, dt - dleg(seg.q, vel, at, par)[1] @ d_state)
        scalars = (float(nrm @ vel), float(t @ vel), float(nrm @ an), float(nrm @ at), float(t @ at))
        dscalars = np.array(
            [
                vel @ dn + nrm @ dvel,
                vel @ dt + t @ dvel,
                an @ dn + nrm @ dan,
                at @ dn + nrm @ dat,
                at @ dt + t @ dat,
            ]
        )
        de_rest = self.tg.get("d_restitution")(par)[0][j] @ dpar
        law = impact_law_tangent(scalars, dscalars, float(mu[j]), dmu[j] @ dpar, rest, de_rest)
        rho, _, drho, ddk, _ = law
        self.dnrm = dn + np.outer(t, drho) + rho * dt
        self.de = self.de + ddk

    def _dvel(self, q, v_in, a, mass0, par, dpar) -> np.ndarray:
        """Tangent of ``vel = v_in + a``, ``a = M(q, v_in)^-1 (p - mom(q, v_in))`` (``Stepper._velocity``, one
        Newton step of the inverse Legendre transform), ``dq``, ``dp``, ``dvin`` the segment's tangents."""
        dmom0, dma0 = self.tg.get("d_legendre")(q, v_in, a, par)
        d0 = np.vstack([self.dq, self.dvin, dpar])
        return self.dvin + np.linalg.solve(mass0, self.dp - dmom0 @ d0 - dma0 @ d0)

    @_guarded
    def plastic(self, seg, v_in, tight) -> None:
        """A plastic impact (``SustainedSteps._plastic_entry``) on the rows ``tight`` (those with an impulse):
        ``p+ = p~- + G^T Lam``, ``G M^-1 G^T Lam = -G vel`` (the frictionless impulse law, target normal
        velocity 0), ``vel`` one Newton step of the inverse Legendre transform from ``v_in``, ``G`` and ``M``
        at ``(q~, vel)``: ``dp`` becomes the tangent of ``p+`` (the rest of the step starts there)."""
        if not self.active:
            return
        self._impulse(seg.q, v_in, seg.p_in, tight, [-1] * len(tight))

    @_event_hook
    def impulse(self, q, v, p, tight, contact) -> None:
        """An impact while rows are held (``SustainedSteps._chain_impact``, after :meth:`event`): the impulse
        law on the rows ``tight`` (those with an impulse), each row's target ``-e g_r.vel`` (``contact[l]``
        the contact whose restitution ``e`` it takes, ``-1``: target 0, an active or plastic row)."""
        if self.active:
            self._impulse(q, v, p, tight, contact)

    def _impulse(self, q, v_in, p_in, tight, contact) -> None:
        """``p+ = p + G^T Lam``, ``G M^-1 G^T Lam = b``, ``b_l = -(1 + e_l) g_l.vel`` (``e_l = 0`` where
        ``contact[l] < 0``), ``vel`` one Newton step of the inverse Legendre transform from ``v_in`` (its
        tangent ``self.dvin``), ``G`` and ``M`` at ``(q, vel)``: ``self.dp`` becomes the tangent of ``p+``."""
        k, n = self.k, self.n
        par, dpar = self.par(self.t_seg), self.dpar(self.dt)  # at the impact point
        mom0, mass0 = k.legendre(q, v_in)
        a = np.linalg.solve(mass0, p_in - mom0)
        vel = v_in + a
        dvel = self._dvel(q, v_in, a, mass0, par, dpar)
        mass1 = k.legendre(q, vel)[1]
        grad = k.rows(q, vel)[1][tight]  # (na, n)
        dgrad = self.tg.get("d_rows")(q, vel, par)[0]
        dq_par = np.vstack([self.dq, dpar])
        dg = [dgrad[r * n : (r + 1) * n] @ dq_par for r in tight]  # each (n, K)
        y = np.linalg.solve(mass1, grad.T)  # M^-1 G^T, (n, na)
        dleg = self.tg.get("d_legendre")
        dy = []
        for c in range(len(tight)):
            dma = dleg(q, vel, y[:, c], par)[1]
            dy.append(np.linalg.solve(mass1, dg[c] - dma @ np.vstack([self.dq, dvel, dpar])))
        rest = k.restitution() if any(j >= 0 for j in contact) else None
        de = self.tg.get("d_restitution")(par)[0] @ dpar if rest is not None else None
        coef = np.array([1.0 + (float(rest[j]) if j >= 0 else 0.0) for j in contact])
        w = grad @ y
        lam = np.linalg.solve(w, -coef * (grad @ vel))
        db = -coef[:, None] * np.array([vel @ dg[c] + grad[c] @ dvel for c in range(len(tight))])
        for c, j in enumerate(contact):  # a restitution target moves with e
            if j >= 0:
                db[c] -= de[j] * float(grad[c] @ vel)
        dw_lam = np.array(
            [
                sum((y[:, e] @ dg[c] + grad[c] @ dy[e]) * lam[e] for e in range(len(tight)))
                for c in range(len(tight))
            ]
        )
        dlam = np.linalg.solve(w, db - dw_lam)
        self.dp = self.dp + sum(dg[c] * lam[c] + np.outer(grad[c], dlam[c]) for c in range(len(tight)))

    @_guarded
    def jump_end(self, seg) -> None:
        """The last segment after an impact ends at the grid time (48), (49): ``S_k+1``."""
        if not self.active:
            return
        n = self.n
        data, dd = self._data(seg)
        x = seg.x
        dx, u, du = self._ift_staged("jump", x[: n + 1], data, dd, seg.t)
        dw, w = dx[:n], x[:n]
        dq_end = self.dq + np.outer(w, self.dtau) + seg.tau * dw
        _, dp_end, _ = self._segment(seg.q, w, seg.tau, seg.t, self.dq, dw, self.dtau, self.dt, u, du)
        self.next = np.vstack([dq_end, dp_end])

    @_guarded
    def held(self, q, p, tau: float, v, lam, lam1, lam_m, u1, act, entry: bool = False) -> None:
        """A held grid step with a fixed active set (MATH.md *Sustained contact*): ``S_k+1``.

        ``rattle``, unknowns ``x = (v, Lam)`` given ``(q_k, p_k, tau, act, par)``, then ``rattle_project``,
        unknowns ``y = (u1, Lam')`` given ``(q_k+1, p+, act, par)``, ``q_k+1 = q_k + tau v``,
        ``p+ = p+(q_k, v, tau)``; ``p_k+1 = dL/dqdot(q_k+1, u1)`` (``= p+ + G1^T Lam'``). The active set and
        the multipliers off it are held fixed (their columns 0): the derivative of the step for its mode.
        With internal points held on the rows (lobatto3, ``derive.held_internal_points``) ``x = (v, Lam,
        Lam_m, u)`` (``lam_m`` the internal points' multipliers, ``u`` recovered) and ``p+`` is routine
        ``rattle_end``'s (:meth:`_held_sub`).
        ``entry``: the rest of a step after a plastic impact (:meth:`plastic`), from the impact point ``q~``,
        ``p+``, its time and the rest of the step (the segment's tangents ``dq, dp, dt, dtau``).
        """
        if not self.active:
            return
        n, K = self.n, self.K
        if entry:
            dq, dp, dtau, dt, t = self.dq, self.dp, self.dtau, self.dt, self.t_seg
        else:
            dq, dp, dtau, dt, t = self.cur[:n], self.cur[n:], np.zeros((1, K)), None, self.t
        self._slots = self._friction_slots(q, dq, act, t)
        if self._slots is not None and not self._cone_slots(q, p, dq, dp, tau, act, t, self._slots):
            self._slots = None
            self.lose("a phase without a tangent")
            return
        try:
            dq1, du1, dpar = self._held_sub(q, p, tau, v, lam, lam1, lam_m, u1, act, dq, dp, dtau, dt, t)
        finally:
            self._slots = None
        dmom, _ = self.tg.get("d_legendre")(q + tau * v, u1, np.zeros(n), self.par(t))
        self.next = np.vstack([dq1, dmom @ np.vstack([dq1, du1, dpar])])

    def _held_sub(self, q, p, tau: float, v, lam, lam1, lam_m, u1, act, dq, dp, dtau, dt, t):
        """Tangents ``(dq1, du1, dpar)`` of a constrained segment ``(q, p, tau)`` from ``t`` (``rattle`` then
        ``rattle_project``, the active set ``act`` fixed); the columns are those of ``dq`` (any number).

        With internal points held on the rows (``lam_m`` their multipliers, stage after stage) ``rattle``'s
        unknowns are ``(v, Lam, Lam_m, u)``: ``u`` is recovered at the solution (:meth:`Tangents.internal`,
        Newton on the stationarity rows ``l_u + G_m^T Lam_m = 0`` at the given ``Lam_m``), all of them are
        unknowns of the implicit-function theorem, and ``p+`` is ``rattle_end(q, v, tau, u, Lam_m, act)``
        (``D2 L_d`` with the internal multipliers' share), its partials ``d_rattle_end`` chained with
        ``(dq, dv, dtau, du, dLam_m, 0, dpar)``."""
        n, cols = self.n, dq.shape[1]
        nr = len(act)
        actf = np.asarray(act, dtype=float)
        par = self.par(t)
        dpar = self.dpar(dt)
        if dpar.shape[1] != cols:
            dpar = np.hstack([dpar, np.zeros((dpar.shape[0], cols - dpar.shape[1]))])
        zr = np.zeros((nr, cols))
        data = (q, p, [tau], actf)
        x = np.concatenate([v, lam, lam_m])
        u = self.tg.internal("rattle", x, data, par)
        dx = self._ift("rattle", np.concatenate([x, u]), data, np.vstack([dq, dp, dtau, zr, dpar]), t)
        dv = self._sub_dv = dx[:n]  # the sub-step's velocity (an impulse law after it starts from it)
        q1 = q + tau * v
        dq1 = dq + np.outer(v, dtau) + tau * dv
        if self.tg.ns:  # p+ of the segment with its internal points held (rattle_end)
            nx = x.size
            dlm, du = dx[n + nr : nx], dx[nx:]
            ins = (q, v, [tau], u, lam_m, actf, par)
            p_plus = self.tg.get("rattle_end")(*ins)[0][:, 0]
            dpp = self.tg.get("d_rattle_end")(*ins)[0] @ np.vstack([dq, dv, dtau, du, dlm, zr, dpar])
        else:
            p_plus = self.k.segment(q, v, tau)[1]
            _, dpp, _ = self._segment_cols(q, v, tau, t, dq, dv, dtau, dpar)
        y = np.concatenate([u1, lam1])
        dy = self._ift("rattle_project", y, (q1, p_plus, actf), np.vstack([dq1, dpp, zr, dpar]), t)
        return dq1, dy[:n], dpar

    def _segment_cols(self, q, v, tau: float, t: float, dq, dv, dtau, dpar, u=None, du=None):
        """:meth:`_segment` with ``dpar`` given (any number of columns)."""
        if self.tg.ns:  # d_segment(q0, v, tau, u, par): its u columns chained with du
            dpm, dpp, de = self.tg.get("d_segment")(q, v, tau, u, self.par(t))
            d = np.vstack([dq, dv, dtau, du, dpar])
            return dpm @ d, dpp @ d, de @ d
        dpm, dpp, de = self.tg.get("d_segment")(q, v, tau, self.par(t))
        d = np.vstack([dq, dv, dtau, dpar])
        return dpm @ d, dpp @ d, de @ d

    @_guarded
    def liftoff(self, sub, r: int, s: float, tau: float, free, entry: bool = False) -> None:
        """A held grid step whose row ``r`` lifts off at fraction ``s`` (MATH.md *Sustained contact*), then a
        free rest (46) to the grid time: ``S_k+1`` for this mode sequence.

        ``sub = (q, p, v, lam, lam1, u1, act)``: the constrained sub-step over ``tau_s = s tau`` from the
        grid point (``tau = h``), ``act`` its active rows (``r`` among them). The lift-off fraction is the
        root of ``g(s) = lambda_r(q1(s), u1(s), par)`` (``SustainedSteps._liftoff_fraction``): by the
        implicit-function theorem ``d tau_s = -(dg|_{tau_s}) / (dg/d tau_s)``, both through the sub-step's
        tangent (one extra column: ``d/d tau_s``). ``free = (q_l, p_l, w)``: the smooth step (46) over
        ``tau - tau_s`` from the lift-off point, its start time and duration chained. ``entry``: the rest of
        a step after a plastic impact (:meth:`plastic`), from the impact point, its time and the rest of the
        step (the segment's tangents ``dq, dp, dt, dtau``), as :meth:`held`.
        """
        if not self.active:
            return
        n, K = self.n, self.K
        if entry:
            dq0, dp0, dtau0, dt0, t = self.dq, self.dp, self.dtau, self.dt, self.t_seg
        else:
            dq0, dp0, dtau0, dt0, t = self.cur[:n], self.cur[n:], np.zeros((1, K)), None, self.t
        dq_l, dp_l, _, dtau_s = self._located(sub, r, s, tau, "lift", dq0, dp0, dt0, t)
        dt_l = dtau_s[0] if dt0 is None else dt0 + dtau_s[0]
        self._free_end(free, tau - s * tau, t + s * tau, dq_l, dp_l, dtau0 - dtau_s, dt_l)

    def _located(self, sub, r: int, s: float, tau: float, kind: str, dq0, dp0, dt0, t):
        """The constrained sub-step ``sub = (q, p, v, lam, lam1, lam_m, u1, act)`` over ``tau_s = s tau`` from
        ``t`` to an event of row ``r`` (``kind``: ``"lift"``, the root of its force, :meth:`_dforce`;
        ``"cross"``, the root of its value ``psi_r(q1)``, ``d_psi``), with one extra column ``d/d tau_s``,
        and the root's ``d tau_s = -(dg|_{tau_s}) / (dg/d tau_s)``: ``(dq_l, dp_l, dv_l, dtau_s)`` at the
        event (``dv_l``: the sub-step's velocity ``v``, where the impulse law's Newton step starts)."""
        n, K = self.n, self.K
        q, p, v, lam, lam1, lam_m, u1, act = sub
        tau_s = s * tau
        dq = np.hstack([dq0, np.zeros((n, 1))])
        dp = np.hstack([dp0, np.zeros((n, 1))])
        dtau = np.zeros((1, K + 1))
        dtau[0, K] = 1.0  # the extra column: d/d tau_s
        dq1, du1, dpar = self._held_sub(q, p, tau_s, v, lam, lam1, lam_m, u1, act, dq, dp, dtau, dt0, t)
        dv = self._sub_dv
        q1 = q + tau_s * v
        t_l = t + tau_s
        dpar_end = dpar.copy()
        if self.timed:
            dpar_end[-1] = dpar[-1] + dtau[0]
        if kind == "lift":
            dg = self._dforce(q1, u1, act, r, self.par(t_l), np.vstack([dq1, du1, dpar_end]))  # (K + 1,)
        else:
            dg = self.tg.get("d_psi")(q1, u1, self.par(t_l))[0][r] @ np.vstack([dq1, dpar_end])
        if dg[K] == 0.0:
            raise np.linalg.LinAlgError("the event's root does not move with its fraction")
        dtau_s = (-dg[:K] / dg[K])[None, :]
        dq_l = dq1[:, :K] + np.outer(dq1[:, K], dtau_s)
        du_l = du1[:, :K] + np.outer(du1[:, K], dtau_s)
        dv_l = dv[:, :K] + np.outer(dv[:, K], dtau_s)
        dmom, _ = self.tg.get("d_legendre")(q1, u1, np.zeros(n), self.par(t))
        dp_l = dmom @ np.vstack([dq_l, du_l, dpar[:, :K]])
        return dq_l, dp_l, dv_l, dtau_s

    def _free_end(self, free, tau_r: float, t_l: float, dq_l, dp_l, dtau_r, dt_l) -> None:
        """The free rest (46) ``free = (q_l, p_l, w)`` over ``tau_r`` from ``t_l`` to the grid time, its
        start, start time and duration chained (their tangents ``dq_l, dp_l, dt_l, dtau_r``): ``S_k+1``."""
        ql, pl, w = free
        dd = np.vstack([dq_l, dp_l, dtau_r, self.dpar(dt_l)])
        dw, uw, duw = self._ift_staged("smooth", w, (ql, pl, [tau_r]), dd, t_l)
        dq_end = dq_l + np.outer(w, dtau_r) + tau_r * dw
        _, dp_end, _ = self._segment(ql, w, tau_r, t_l, dq_l, dw, dtau_r, dt_l, uw, duw)
        self.next = np.vstack([dq_end, dp_end])

    # -- events inside a held step (SustainedSteps._chain): the segment's tangents carried event by event --
    def events_begin(self, entry: bool) -> None:
        """Before the first event of a held grid step: its segment's tangents ``(dq, dp, dtau, dt)`` start at
        the grid point (``S_k``, 0, 0, ``t_k``); the rest of a plastic impact's step (``entry``) has them."""
        if not self.active or entry or self._ev_step == self.step:
            return
        n, K = self.n, self.K
        self.dq, self.dp = self.cur[:n].copy(), self.cur[n:].copy()
        self.dtau, self.dt, self.t_seg = np.zeros((1, K)), np.zeros(K), self.t
        self._ev_step = self.step

    @_event_hook
    def event(self, sub, r: int, s: float, tau: float, kind: str) -> None:
        """A constrained sub-step of a held step to an event of row ``r`` at fraction ``s`` of ``tau`` (a
        lift-off, ``"lift"``, or an inactive row crossed, ``"cross"``, :meth:`_located`) from the segment's
        tangents: they become the event point's (the rest of the step after it, from ``t_seg + s tau``)."""
        if not self.active:
            return
        dq_l, dp_l, dv_l, dtau_s = self._located(sub, r, s, tau, kind, self.dq, self.dp, self.dt, self.t_seg)
        self.dq, self.dp, self.dvin = dq_l, dp_l, dv_l
        self.dt, self.dtau, self.t_seg = self.dt + dtau_s[0], self.dtau - dtau_s, self.t_seg + s * tau

    @_event_hook
    def free_end(self, q, p, w, tau: float) -> None:
        """The free rest (46) of a held step after its events (:meth:`event`), from the segment's tangents."""
        if self.active:
            self._free_end((q, p, w), tau, self.t_seg, self.dq, self.dp, self.dtau, self.dt)

    def _dforce(self, q1, u1, act, r: int, par, dd) -> np.ndarray:
        """The tangent of row ``r``'s force ``lambda_r(q1, u1, par)`` (``SustainedSteps._forces``, the
        frictionless rows ``act`` held), ``dd`` the tangent of ``(q1, u1, par)`` (any number of columns): the
        force law ``J (a, lam) = (rhs, -curv)``, ``J = [[M, -G^T], [G, 0]]`` on the active rows, by the
        implicit-function theorem with its derived partials ``d_forces`` (C: ``sens_liftoff``)."""
        n, tg = self.n, self.tg
        rows = np.flatnonzero(act)
        _, grad, curv = tg.get("rows")(q1, u1, par)
        rhs = tg.get("dynamics")(q1, u1, par)[0][:, 0]
        mass = tg.get("legendre")(q1, u1, par)[1]
        g = grad[rows]
        jac = np.block([[mass, -g.T], [g, np.zeros((rows.size, rows.size))]])
        sol = np.linalg.solve(jac, np.concatenate([rhs, -curv[rows, 0]]))
        lam = np.zeros(grad.shape[0])
        lam[rows] = sol[n:]
        dres = tg.get("d_forces")(q1, u1, sol[:n], lam, par)[0]
        dx = -np.linalg.solve(jac, dres[np.r_[np.arange(n), n + rows]] @ dd)
        return dx[n + int(np.flatnonzero(rows == r)[0])]

    # -- the result ----------------------------------------------------------------
    def attach(self, res, steps: int) -> None:
        """``res.sensitivity`` ``(N, 2n, K)``, its column names and breaks, ``stats["sensitivity_lost"]``."""
        res.sensitivity = self.S[: steps + 1].copy()
        res.sensitivity_names = self.tg.names()
        res.sensitivity_breaks = list(self.breaks)
        if self.lost is not None:
            res.stats["sensitivity_lost"] = self.lost
