"""Routines -> ``casadi.Function`` + ``casadi.rootfinder`` (Newton, exact Jacobian).

Every Function is built once, at build time, with the parameters as an input.
Each solve is one call of a Function that wraps the rootfinder and also
returns the residual's infinity norm at the answer, so the stepper can check it.
Every call takes and returns one flat vector (the fastest way across the
Python/CasADi boundary).
"""

from __future__ import annotations

import math

import casadi as ca
import numpy as np

from ..derive import WHOLE, DiscreteSystem, set_rows
from ..explicit import grid_routines, jump_quadratic, path_routines
from ..held import held_routines
from ..held_circle import circle_step
from ..held_step import closed_carried, held_step
from ..routines import Routine
from ..simulator import Simulator
from ..stepper import Tolerances
from ..sustained import End
from ..tangents import is_tangent
from .ccontext import newton_options
from .slots import ParameterSlots
from .sym2casadi import to_casadi

# A failed solve is reported by its residual (NaN for a non-finite answer), not by warnings on stderr.
NEWTON_OPTIONS = {
    "abstol": 1e-13,
    "abstolStep": 1e-15,
    "max_iter": 40,
    "error_on_fail": False,
    "show_eval_warnings": False,
}


def later(par, dt):
    """``par`` of a segment starting ``dt`` later (forces of time: the last slot is its start time); a sum,
    not ``vertcat(par[:-1], ...)``, whose empty slice CasADi cannot stack where time is the only slot."""
    unit = ca.DM.zeros(par.shape[0], 1)
    unit[-1] = 1.0
    return par + dt * unit


def routine_to_function(r: Routine) -> ca.Function:
    """One SX Function per routine: named inputs and outputs, CSE kept."""
    ins = [ca.SX.sym(a.name, a.size) for a in r.inputs]
    env = {s: ins[i][k] for i, a in enumerate(r.inputs) for k, s in enumerate(a.symbols)}
    repl, reduced = r.cse()
    for sym, expr in repl:
        env[sym] = to_casadi(expr, env)
    outs = []
    for o, entries in zip(r.outputs, reduced):
        rows, cols = o.shape
        vals = [to_casadi(e, env) for e in entries]
        mat = ca.SX(rows, cols)
        for k, val in enumerate(vals):
            mat[k // cols, k % cols] = val
        outs.append(mat)
    return ca.Function(r.name, ins, outs, [a.name for a in r.inputs], [o.name for o in r.outputs])


def _residual(sol_and_res: np.ndarray) -> float:
    """The residual norm of a solve (last entry), NaN if the solution is not finite.

    CasADi's ``norm_inf`` skips NaN entries, so a diverged Newton can report a small residual; the C
    Newton's norm is NaN there (``<model>_norm_inf``), and so is this one.
    """
    return float(sol_and_res[-1]) if np.isfinite(sol_and_res).all() else math.nan


class CasadiKernels(ParameterSlots):
    """The stepper's kernels, evaluated by CasADi for one parameter vector."""

    backend = "casadi"

    def __init__(self, system: DiscreteSystem) -> None:
        self.system = system
        self.structure = system.structure  # detected once per system (vcigen.structure), as the C reads it
        self.n, self.m = system.n, system.m
        self.contact_names = system.contact_names
        self.par = np.zeros(len(system.params))
        self.timed, self.t = system.timed, 0.0
        self._buffers: dict[str, tuple] = {}
        # the tangents (vcigen.tangents) are converted on first use (vcigen.sensitivity), never solved
        self.functions = {
            name: routine_to_function(r) for name, r in system.routines.items() if not is_tangent(name)
        }
        self.stages = system.stages  # internal unknowns of a segment: solved here, never seen by the stepper
        self._solvers = {
            name: self._solver(name)
            for name in self.functions
            if "x" in [a.name for a in system.routines[name].inputs]
        }
        self._step = self._smooth_step()
        self.explicit_path = self.structure.explicit_path
        paths = path_routines(system) if self.explicit_path else []
        self._paths = [self._flat_function(routine_to_function(r)) for r in paths]
        quad = jump_quadratic(system) if self.structure.jump_quadratic else None
        self._quad = None if quad is None else self._flat_function(routine_to_function(quad))
        flat = ("legendre", "contacts", "restitution") + (("rows", "dynamics") if system.r else ())
        flat += ("friction",) if "friction" in system.routines else ()
        flat += ("friction_cone",) if "friction_cone" in system.routines else ()
        self._flat = {name: self._flatten(name) for name in flat}
        self._flat["segment"] = self._flat_function(self._segment_function())
        set_rows(self, system)
        self._rattle = self._rattle_segment() if system.r else None
        self.held = self.structure.held  # the held grid step (vcigen.held)
        self._held = (
            {r.name: self._flat_function(routine_to_function(r)) for r in held_routines(system)}
            if self.held
            else {}
        )
        self._held_k: tuple[float, np.ndarray, np.ndarray] | None = None
        self._held_dir: tuple[np.ndarray, np.ndarray, list[np.ndarray]] | None = None  # held_root_dir's last
        self.held_pattern = list(self.structure.held_pattern)
        self.held_closed = list(self.structure.held_closed)  # held_root's rows (vcigen.held_step.closed_step)
        self.closed_carried = True  # closed_step takes w (vcigen.held_step.HeldSteps)
        self.held_circle = list(
            self.structure.held_circle
        )  # rows whose closed step is a rotation (held_circle)

    def bind(self, par: list[float]) -> CasadiKernels:
        """Fix the parameter values for the next simulation."""
        self.par = np.asarray(par, dtype=float)
        return self

    # -- building -------------------------------------------------------------
    def _solver(self, name: str) -> ca.Function:
        """``(guess, args..., par) -> (x, |res|_inf)`` in one flat vector each."""
        f = self.functions[name]
        r = self.system.routines[name]
        x = ca.MX.sym("x", r.inputs[0].size)
        rest = [ca.MX.sym(a.name, a.size) for a in r.inputs[1:]]
        prm = ca.vertcat(*rest)
        g = ca.Function(
            "g",
            [x, prm],
            [f(x, *ca.vertsplit(prm, np.cumsum([0] + [a.size for a in r.inputs[1:]]).tolist()))[0]],
        )
        options = NEWTON_OPTIONS | {"abstol": newton_options(self.system)["abstol"]}
        rf = ca.rootfinder(f"{name}_newton", "newton", g, options)
        guess = ca.MX.sym("guess", x.shape[0])
        ns = self.system.stages if name not in WHOLE else 0
        if ns:  # internal points: settle u on their stationarity (the first ns rows) at the guess first
            nx = x.shape[0] - ns
            u, xp = ca.MX.sym("u", ns), ca.MX.sym("xp", nx)
            g_u = ca.Function("g_u", [u, ca.vertcat(xp, prm)], [g(ca.vertcat(xp, u), prm)[:ns]])
            rf_u = ca.rootfinder(f"{name}_stage_newton", "newton", g_u, options)
            guess_full = ca.vertcat(guess[:nx], rf_u(guess[nx:], ca.vertcat(guess[:nx], prm)))
        else:
            guess_full = guess
        sol = rf(guess_full, prm)
        res = ca.norm_inf(g(sol, prm))
        return ca.Function(f"{name}_solve", [ca.vertcat(guess, prm)], [ca.vertcat(sol, res)])

    def _segment_function(self) -> ca.Function:
        """``segment(q0, v, tau, par)``; with internal points it solves their stationarity first (routine
        ``stage``, Newton from ``u = 0``: ``u`` is O(tau)) and evaluates at the stationary point."""
        f = self.functions["segment"]
        if not self.stages:
            return f
        q0, v, tau, par = (ca.MX.sym(a.name, a.size) for a in self.system.routines["stage"].inputs[1:])
        u = self._solvers["stage"](ca.vertcat(ca.MX.zeros(self.stages), q0, v, tau, par))[: self.stages]
        return ca.Function(
            "segment", [q0, v, tau, par], f(q0, v, tau, u, par), ["q0", "v", "tau", "par"], f.name_out()
        )

    def _smooth_step(self) -> ca.Function:
        """Smooth step (46) and everything the stepper needs after it, in one call."""
        n = self.n
        vec = ca.MX.sym("in", 3 * n + 1 + len(self.par))
        q0, p0, tau, guess, par = (
            vec[:n],
            vec[n : 2 * n],
            vec[2 * n],
            vec[2 * n + 1 : 3 * n + 1],
            vec[3 * n + 1 :],
        )
        phi0, grad0 = self.functions["contacts"](q0, par)
        if self.structure.explicit_grid:  # the C backend's straight-line step, the same round-off
            consts, step, _ = (routine_to_function(r) for r in grid_routines(self.system))
            v, p1, e = step(q0, p0, consts(tau, par))
            p_minus, _, _ = self.functions["segment"](q0, v, tau, par)
            res = ca.norm_inf(p_minus - p0)
        else:
            ns = self.stages  # internal points: their unknowns follow v, from 0 (O(tau))
            out = self._solvers["smooth"](ca.vertcat(guess, ca.MX.zeros(ns), q0, p0, tau, par))
            v, res = out[:n], out[n + ns]
            inner = (out[n : n + ns],) if ns else ()
            _, p1, e = self.functions["segment"](q0, v, tau, *inner, par)
        phi1, grad1 = self.functions["contacts"](q0 + tau * v, par)
        # Slopes of phi along the segment map at s = 0 and s = 1: tau grad phi . qdot, with the
        # continuous velocities of p0 and p1 (one Newton step of the Legendre transform from v).
        mom0, mass0 = self.functions["legendre"](q0, v, par)
        mom1, mass1 = self.functions["legendre"](q0 + tau * v, v, par)
        vel0 = v + ca.solve(mass0, p0 - mom0)
        vel1 = v + ca.solve(mass1, p1 - mom1)
        d0, d1 = ca.mtimes(grad0, tau * vel0), ca.mtimes(grad1, tau * vel1)
        return ca.Function("smooth_step", [vec], [ca.vertcat(v, res, p1, e, phi0, phi1, d0, d1)])

    def _rattle_segment(self) -> ca.Function:
        """``vcigen.sustained.rattle_segment`` in one call: both solves and the evaluations at the end."""
        n, r, npar, ns = self.n, self.r, len(self.par), self.stages
        nx = n + r + r * self.system.rule.stages  # (v, Lam), and Lam_m of the held internal points
        vec = ca.MX.sym("in", 2 * n + 1 + nx + r + npar)
        parts = np.cumsum([0, n, n, 1, nx, r, npar]).tolist()
        q, p, tau, x0, act, par = (vec[parts[i] : parts[i + 1]] for i in range(6))
        # internal points: u (O(tau)) from 0 with the rest, one Newton on (v, Lam, Lam_m, u) (derive.WHOLE)
        out = self._solvers["rattle"](ca.vertcat(x0, ca.MX.zeros(ns), q, p, tau, act, par))
        x, res = out[:nx], out[nx + ns]
        v = x[:n]
        q1 = q + tau * v
        if ns:  # p+ and E_d with the internal multipliers' share (derive.held_internal_points)
            p_plus, e_seg = self.functions["rattle_end"](q, v, tau, out[nx : nx + ns], x[n + r :], act, par)
        else:
            _, p_plus, e_seg = self.functions["segment"](q, v, tau, par)
        out = self._solvers["rattle_project"](ca.vertcat(v, ca.MX.zeros(r), q1, p_plus, act, par))
        y, res1 = out[: n + r], out[n + r]
        u1 = y[:n]
        psi, grad, curv = self.functions["rows"](q1, u1, par)
        # the forces at the segment's end, at its time (the last parameter slot: the time it starts)
        par_end = later(par, tau) if self.timed else par
        rhs, _ = self.functions["dynamics"](q1, u1, par_end)
        _, mass = self.functions["legendre"](q1, u1, par)
        flat = ca.vertcat(x, res, p_plus, e_seg, y, res1, psi, ca.vec(grad.T), curv, rhs, ca.vec(mass.T))
        return ca.Function("rattle_segment", [vec], [flat])

    def _flatten(self, name: str) -> ca.Function:
        return self._flat_function(self.functions[name])

    @staticmethod
    def _flat_function(f: ca.Function) -> ca.Function:
        ins = [ca.SX.sym(a, f.size1_in(i)) for i, a in enumerate(f.name_in())]
        outs = f.call(ins)  # a list, also for a single output
        return ca.Function(f"{f.name()}_flat", [ca.vertcat(*ins)], [ca.vertcat(*[ca.vec(o.T) for o in outs])])

    # -- the kernels interface --------------------------------------------------
    def _buffer(self, f: ca.Function) -> tuple[np.ndarray, np.ndarray, object]:
        """``(arg, res, trigger)``: ``f``'s CasADi buffer over two numpy arrays, made once per Function."""
        b = self._buffers.get(f.name())
        if b is None:
            arg, res = np.zeros(f.size1_in(0)), np.zeros(f.size1_out(0))
            buf, trigger = f.buffer()
            buf.set_arg(0, memoryview(arg))
            buf.set_res(0, memoryview(res))
            b = self._buffers[f.name()] = (arg, res, trigger, buf)  # buf kept alive beside its arrays
        return b[0], b[1], b[2]

    def _call(self, f: ca.Function, *parts: np.ndarray | float) -> np.ndarray:
        """Evaluate ``f`` on the concatenated parts (and the parameters) via a CasADi buffer."""
        arg, res, trigger = self._buffer(f)
        i = 0
        for part in (*parts, self.par):
            if np.ndim(part) == 0:
                arg[i] = part
                i += 1
            else:
                arg[i : i + len(part)] = part
                i += len(part)
        trigger()
        return res.copy()

    def smooth_step(self, q0, p0, tau, guess):
        """Smooth step from ``(q0, p0)``: ``(v, |res|, p1, E_d, phi(q0), phi(q1), d0, d1)``.

        ``d0``, ``d1`` are ``tau grad phi . qdot`` at both ends: the slopes of phi along the
        sub-step map of (47), with ``qdot`` the velocities of ``p0`` and ``p1``.
        """
        n, m = self.n, self.m
        o = self._call(self._step, q0, p0, tau, guess)
        c = 2 * n + 2
        return (
            o[:n],
            o[n],
            o[n + 1 : c - 1],
            o[c - 1],
            o[c : c + m],
            o[c + m : c + 2 * m],
            o[c + 2 * m : c + 3 * m],
            o[c + 3 * m :],
        )

    def solve(self, name: str, guess, *args):
        """Newton on routine ``name`` from ``guess``; returns ``(x, |res|_inf)``.

        With internal points (``DiscreteSystem.stages``) the routine's unknowns end with them: Newton
        starts them from 0 (they are O(tau)) and ``x`` comes back without them."""
        if not self.stages or name in WHOLE:
            o = self._call(self._solvers[name], guess, *args)
            return o[:-1], _residual(o)
        o = self._call(self._solvers[name], np.append(guess, np.zeros(self.stages)), *args)
        return o[: -1 - self.stages], _residual(o)

    def legendre(self, q, v):
        n = self.n
        o = self._call(self._flat["legendre"], q, v)
        return o[:n], o[n:].reshape(n, n)

    def segment(self, q0, v, tau):
        n = self.n
        o = self._call(self._flat["segment"], q0, v, tau)
        return o[:n], o[n : 2 * n], float(o[2 * n])

    def rattle_end(self, q0, v, tau, u, lm, act):
        """``(p+, E_d)`` of a constrained segment with its internal points held (routine ``rattle_end``)."""
        p_plus, e = self.functions["rattle_end"](q0, v, tau, u, lm, act, self.par)
        return np.asarray(p_plus, dtype=float).ravel(), float(e)

    def start_energy(self, q0, v, tau) -> float:
        """The energy at the start of the segment ``(q0, v, tau)`` (``E_d - f_d- . v`` with forces): the
        energy row of the jump's residual (48a) at ``e_in = 0``."""
        n, zero, ns = self.n, np.zeros(self.n), self.stages
        x = np.append(v, 0.0)
        if ns:  # at the stationary internal points of the segment (rows: the stationarity first)
            u = self._call(self._solvers["stage"], np.zeros(ns), q0, v, tau)[:ns]
            x = np.append(x, u)
        res = self.functions["jump"](x, q0, zero, zero, 0.0, tau, self.par)[0]
        return float(res[ns + n])

    def contacts(self, q):
        m, n = self.m, self.n
        o = self._call(self._flat["contacts"], q)
        return o[:m], o[m:].reshape(m, n)

    def contact_path(self, j: int, s: float, q0, p0, tau: float):
        """``(g, g', v)`` of contact ``j`` along the explicit segment map at fraction ``s`` (47)."""
        n = self.n
        o = self._call(self._paths[j], s, q0, p0, tau)
        return float(o[0]), float(o[1]), o[2 : 2 + n]

    def friction(self, q):
        """``(mu_f, grad psi, branch)`` at ``q``: each contact's mu_f (0: frictionless) and tangent gradient,
        and the arguments of the sign() atoms of the frictional tangents."""
        m, n = self.m, self.n
        o = self._call(self._flat["friction"], q)
        return o[:m], o[m : m + m * n].reshape(m, n), o[m + m * n :]

    def friction_cone(self, q):
        """``(m, n)``: each contact's second tangent gradient (0 unless it has an isotropic cone)."""
        m, n = self.m, self.n
        return self._call(self._flat["friction_cone"], q)[: m * n].reshape(m, n).copy()

    def restitution(self) -> np.ndarray:
        """Coefficient of restitution of each contact at the bound parameters."""
        if self.m == 0:
            return np.zeros(0)
        return self._call(self._flat["restitution"])[: self.m]

    def rattle_segment(self, q, p, tau, x0, act):
        """A constrained segment and the evaluations at its end (``vcigen.sustained.rattle_segment``)."""
        n, r = self.n, self.r
        o = self._call(self._rattle, q, p, tau, x0, act)
        nx = n + r + r * self.system.rule.stages
        cuts = np.cumsum([0, nx, 1, n, 1, n + r, 1, r, r * n, r, n, n * n]).tolist()
        x, res, p_plus, e, y, res1, psi, grad, curv, rhs, mass = (o[a:b] for a, b in zip(cuts, cuts[1:]))
        end = End(psi, grad.reshape(r, n), curv, rhs, mass.reshape(n, n))
        return x, _residual(np.append(x, res)), p_plus, float(e[0]), y, _residual(np.append(y, res1)), end

    # -- the held grid step (vcigen.held) ----------------------------------------------
    def held_step(self, q, p, lam_in, act, h: float, residual: float, phi_tol: float):
        """``vcigen.held_step.held_step`` on these kernels."""
        return held_step(self, q, p, lam_in, act, h, residual, phi_tol)

    def held_consts(self, h: float) -> np.ndarray:
        """The run constants of the held step at ``h`` and the bound parameters (kept while they hold)."""
        if self._held_k is None or self._held_k[0] != h or not np.array_equal(self._held_k[1], self.par):
            self._held_k = (h, self.par.copy(), self._call(self._held["held_consts"], h))
        return self._held_k[2]

    def _held_call(self, name: str, sizes: tuple[int, ...], *args) -> list[np.ndarray]:
        """Routine ``name`` of :func:`vcigen.held.held_routines` (its inputs end with ``k``, not ``par``)."""
        f = self._held[name]
        arg, res, trigger = self._buffer(f)  # as in _call (these routines read k, not par)
        arg[:] = np.concatenate(args)
        trigger()
        o = res.copy()
        cuts = np.cumsum((0, *sizes)).tolist()
        return [o[a:z] for a, z in zip(cuts, cuts[1:])]

    def held_free(self, q0, p0, kc):
        """``(v0, 1/J_ii)``: the free velocity of (46) over ``h`` and the inverse Jacobian."""
        return self._held_call("held_free", (self.n, self.n), q0, p0, kc)

    def held_rows(self, q, kc):
        """``(psi, grad, hess)`` of every row at ``q`` (``hess``: Hessian on ``Structure.held_pattern``)."""
        n, r = self.n, self.r
        nh = len(self.held_pattern)
        psi, grad, hess = self._held_call("held_rows", (r, r * n, r * nh), q, kc)
        return psi, grad.reshape(r, n), hess.reshape(r, nh)

    def held_segment(self, q0, v, kc):
        """``(p+, E_d)`` of the segment ``(q0, v)`` over ``h``."""
        pp, e = self._held_call("held_segment", (self.n, 1), q0, v, kc)
        return pp, float(e[0])

    def held_end(self, q, kc):
        """``(M^-1 rhs(q), 1/M_ii)``."""
        return self._held_call("held_end", (self.n, self.n), q, kc)

    def held_root_dir(self, q, kc):
        """Per row ``(m, e, f, s, y, w, a2, g, iw)`` at ``q`` for its closed held step
        (``held.closed_routines``), flat (row-major, as ``held_root`` and ``held_root_end`` read them). The
        last call's are kept: a closed step reads them at its end, the next step at its start (as the C loop
        carries them)."""
        last = self._held_dir
        if last is not None and last[1] is kc and np.array_equal(last[0], q):
            return last[2]
        n, r = self.n, self.r
        out = self._held_call("held_root_dir", (r * n, r * n, r * n, r, r * n, r * n, r, r, r), q, kc)
        self._held_dir = (np.array(q, dtype=float), kc, out)
        return out

    def held_root(self, q0, p0, m, s, a2, kc):
        """``(v0, a, nu, B, D)`` of its closed held step: ``v0``, ``a`` once, the others per row."""
        n, r = self.n, self.r
        return self._held_call("held_root", (n, n, r, r, r), q0, p0, m, s, a2, kc)

    def held_root_end(self, q1, p_plus, y, w, iw, kc):
        """Per row ``(p1, Lam', force, res)`` of its closed held step's end."""
        n, r = self.n, self.r
        p1, lam1, force, res = self._held_call("held_root_end", (r * n, r, r, r), q1, p_plus, y, w, iw, kc)
        return p1.reshape(r, n), lam1, force, res

    def circle_step(self, q, p, w, row: int, act, h: float, residual: float, phi_tol: float):
        """``vcigen.held_circle.circle_step`` on these kernels."""
        return circle_step(self, q, p, w, row, act, h, residual, phi_tol)

    def closed_step(self, q, p, w, row: int, act, h: float, residual: float, phi_tol: float):
        """``vcigen.held_step.closed_carried`` on these kernels (``w`` ``None``: from ``(p, 0)``)."""
        return closed_carried(self, q, p, w, row, act, h, residual, phi_tol)

    def held_circle_start(self, q, p, kc):
        """Per row ``(omega, arg)`` of the rotation step at ``(q, p)`` (``vcigen.held_circle``), ``r x 2``."""
        return self._held_call("held_circle_start", (2 * self.r,), q, p, kc)[0].reshape(self.r, 2)

    def held_circle_step(self, q, p, w, s, kc):
        """Per row ``(q1, p1, pt, w1, slope)`` of the rotation step from ``(q, p, w)`` with
        ``s = sqrt(w[1])``."""
        r = self.r
        sizes = (2 * r, 2 * r, r, 4 * r, r)
        q1, p1, pt, w1, slope = self._held_call("held_circle_step", sizes, q, p, w, s, kc)
        return q1.reshape(r, 2), p1.reshape(r, 2), pt, w1.reshape(r, 4), slope

    def held_circle_end(self, q, p, q1, p1, e, kc):
        """Per row ``(imp, E_d, force, res)`` of the rotation step from ``(q, p)`` to ``(q1, p1)``, with
        ``e = (pt, s)``."""
        return self._held_call("held_circle_end", (self.r,) * 4, q, p, q1, p1, e, kc)

    def held_circle_lam(self, q, p, v, kc):
        """Per row ``Lam`` of a rotation step from ``(q, p)`` with velocity ``v``."""
        return self._held_call("held_circle_lam", (self.r,), q, p, v, kc)[0]

    def rows(self, q, u):
        """``(psi, grad psi, u . Hess psi . u)`` of every row (vcigen.rows)."""
        r, n = self.r, self.n
        o = self._call(self._flat["rows"], q, u)
        return o[:r], o[r : r + r * n].reshape(r, n), o[r + r * n :]

    def dynamics(self, q, u):
        """``(rhs, curv)``: ``M qddot = rhs`` without constraints, and each contact's curvature."""
        n = self.n
        o = self._call(self._flat["dynamics"], q, u)
        return o[:n], o[n:]

    def jump_quadratic(self, qc, nrm, p_in, e_in, tau):
        """``((a, b, c), w0, dw)`` of the jump (48) as a quadratic in ``mu``, or ``None``."""
        if self._quad is None:
            return None
        n = self.n
        o = self._call(self._quad, qc, nrm, p_in, e_in, tau)
        return (float(o[0]), float(o[1]), float(o[2])), o[3 : 3 + n], o[3 + n : 3 + 2 * n]


def build_casadi(system: DiscreteSystem, tol: Tolerances | None = None, **options: object) -> Simulator:
    """The Python stepper over CasADi Functions (the ``"casadi"`` backend; ``options`` of the C backend,
    such as ``cc``, do not apply and are ignored)."""
    return Simulator(system, CasadiKernels(system), tol)
