"""The step maps as ``casadi.Function``, differentiable through ``casadi.rootfinder`` (MATH.md).

``casadi_functions(model, rule)`` returns

* ``"step"``: ``(q, p, h, par) -> (q1, p1)``, one smooth step (46), (51): ``p = p-(q, q1, h)`` solved for
  ``q1``, then ``p1 = p+(q, q1, h)``;
* ``"impact_<c>"`` for each frictionless contact ``c``: ``(q, p, h, par) -> (q1, p1, alpha, mu)``, one step
  holding one impact on ``c``: the contact time and point (47) (unknowns ``v``, ``alpha``), the jump (48)
  (unknowns ``w``, ``mu``; tangential momentum kept, ``E_d`` kept less the loss (39) of a restitution
  ``e < 1``) and ``p1 = p+`` of the segment after the impact (49);
* ``"contact_<c>"`` for each contact: ``(q, p, h, par) -> (qc, pc, alpha)``, the impact point ``q~``, the
  incoming momentum ``p~- = p+(q, q~, alpha h)`` and ``alpha`` of the same step (47) alone (to constrain
  where an impact happens).

Every phase is a ``casadi.rootfinder`` (Newton) over the residuals :func:`vcigen.derive` writes down, the
same ones the CasADi backend solves. A rootfinder's outputs are differentiated by the implicit-function
theorem, ``dx/dz = -(dF/dx)^-1 dF/dz``, so ``casadi.jacobian`` of these Functions is the exact Jacobian
of the step map (``alpha`` and ``mu`` included; the discrete saltation matrix), and they embed in
``casadi.nlpsol`` problems. The Newton starts are CasADi expressions of the inputs (the velocity of ``p``
corrected by one Newton step; the interpolated crossing of ``phi``; the reflected velocity), which carry no
derivative (a rootfinder's answer does not depend on its start).

Rules with internal points (``lobatto3``): their unknowns ``u`` (MATH.md, *Higher order: lobatto3*) are
unknowns of the same rootfinders, appended to each phase's and hidden from the signatures (the same as
the trapezoid rule's); they start at their stationary value for the phase's start (Newton on their own
rows, as the CasADi backend does) and the Jacobians differentiate through them.

``par`` is the parameter vector of :func:`vcigen.derive`'s ``params``: the model's parameters in the order
of ``model.defaults``, then per frictional contact the friction slots (unused here: 0), then, when the
forces depend on time, the time the step starts at. :func:`casadi_parameters` builds it.

Not covered (each is a mode of its own, not a smooth map): several impacts in one step (78), simultaneous
impacts (a corner, two vertices at once), friction at an impact (no ``impact_<c>`` for a frictional
contact), plastic or grazing impacts and sustained contact (where (48a) has no root ``mu > 0`` the
rootfinder fails), bilateral constraints (a ``ValueError``). The Functions do not check that the mode holds
(no crossing in ``"step"``, the earliest crossing on ``c`` in ``"impact_<c>"``): the caller fixes the mode
sequence, for instance from a run of ``simulate``, and checks ``0 <= alpha <= 1`` and ``mu > 0`` (out of its
mode an impact Function returns the root of the same equations with ``alpha`` outside ``[0, 1]``, or fails
to converge and raises).
"""

from __future__ import annotations

from collections.abc import Mapping

import casadi as ca
import numpy as np

from .backends.casadi import NEWTON_OPTIONS, later, routine_to_function
from .derive import DiscreteSystem, derive
from .model import Model
from .rules import Rule

# Newton as in the CasADi backend, but a failed solve raises instead of returning a wrong root, and it stops
# on a step below 1e-13 (the backend: residual 1e-13), so alpha matches the backend's to 1e-12. These are
# absolute: for unknowns of order 1e3 and more pass a larger "abstolStep" in ``newton_options``.
FUNCTION_NEWTON_OPTIONS = NEWTON_OPTIONS | {"abstol": 1e-15, "abstolStep": 1e-13, "error_on_fail": True}


def casadi_functions(
    model: Model, rule: str | Rule = "trapezoid", newton_options: Mapping[str, object] | None = None
) -> dict[str, ca.Function]:
    """``{"step": ..., "impact_<c>": ...}``: the step maps of ``model`` under ``rule`` as ``casadi.Function``.

    Signatures (all inputs and outputs are column vectors, named as shown):

    * ``step(q[n], p[n], h, par[P]) -> (q1[n], p1[n])`` -- smooth step (46), (51);
    * ``impact_<c>(q[n], p[n], h, par[P]) -> (q1[n], p1[n], alpha, mu)`` -- contact time (47), jump (48),
      ``p+`` (49); ``alpha`` is the fraction of the step at the impact, ``mu >= 0`` the impulse along
      ``grad phi_c`` (the paper's ``lambda`` is ``-mu``);
    * ``contact_<c>(q[n], p[n], h, par[P]) -> (qc[n], pc[n], alpha)`` -- the impact point and incoming
      momentum of that step (47).

    ``newton_options`` go to ``casadi.rootfinder(..., "newton", ...)`` (default
    :data:`FUNCTION_NEWTON_OPTIONS`: a failed solve raises).
    """
    if not isinstance(model, Model):
        raise ValueError(f"casadi_functions() needs a vcigen.Model, got {type(model).__name__}")
    if model.constraints:
        # an unconstrained "step" of a constrained model would leave the constraint silently
        raise ValueError(
            f"casadi_functions() has no step for bilateral constraints (model {model.name!r} has "
            f"{sorted(model.constraints)}): the held step (RATTLE) is not among its Functions; use simulate()"
        )
    return functions_of(derive(model, rule), newton_options)


def casadi_parameters(
    model: Model, function: ca.Function, params: Mapping[object, float] | None = None, t: float = 0.0
) -> np.ndarray:
    """The ``par`` input of ``function`` (one of :func:`casadi_functions`): the model's parameters
    (defaults overridden by ``params``), zeros in the friction slots, and ``t`` last when the forces depend
    on time -- the vector ``simulate`` binds."""
    values = model.resolve_params(params)
    timed = model.time_symbol is not None
    slots = function.size1_in("par") - len(values) - timed
    return np.array(values + [0.0] * slots + ([float(t)] if timed else []))


class _Phases:
    """The derived routines as SX Functions and rootfinders, and the steps built from them."""

    def __init__(self, system: DiscreteSystem, options: Mapping[str, object]) -> None:
        self.system = system
        self.n, self.npar = system.n, len(system.params)
        self.f = {name: routine_to_function(r) for name, r in system.routines.items()}
        self.options = dict(options)

    def rootfinder(self, name: str) -> ca.Function:
        """``(x0, data) -> x`` solving routine ``name``'s residual for its unknowns ``x``."""
        r = self.system.routines[name]
        x = ca.SX.sym("x", r.inputs[0].size)
        rest = [ca.SX.sym(a.name, a.size) for a in r.inputs[1:]]
        g = ca.Function("g", [x, ca.vertcat(*rest)], [self.f[name](x, *rest)[0]])
        return ca.rootfinder(f"{name}_newton", "newton", g, self.options)

    def stage_rootfinder(self, name: str) -> ca.Function:
        """``(u0, (x, data)) -> u``: the internal points alone on routine ``name``'s first rows, their
        stationarity, at the phase's unknowns ``x`` (the start of the full solve, as the CasADi backend's)."""
        r, ns = self.system.routines[name], self.system.stages
        nx = r.inputs[0].size - ns
        u, xp = ca.SX.sym("u", ns), ca.SX.sym("xp", nx)
        rest = [ca.SX.sym(a.name, a.size) for a in r.inputs[1:]]
        g = ca.Function("g_u", [u, ca.vertcat(xp, *rest)], [self.f[name](ca.vertcat(xp, u), *rest)[0][:ns]])
        return ca.rootfinder(f"{name}_stage_newton", "newton", g, self.options)

    def solve(self, name: str, guess, data) -> tuple:
        """Routine ``name`` solved from ``guess`` (its unknowns without the internal points): ``(x, u)``.

        With internal points (``DiscreteSystem.stages``; lobatto3) they are unknowns of the same
        rootfinder, hidden from the signature: started at their stationary value for ``guess`` (Newton from
        0 on their own rows), solved with the rest, returned apart (``u`` empty without them)."""
        ns = self.system.stages
        if not ns:
            return self.rootfinder(name)(guess, data), ca.MX.zeros(0)
        u0 = self.stage_rootfinder(name)(ca.MX.zeros(ns), ca.vertcat(guess, data))
        x = self.rootfinder(name)(ca.vertcat(guess, u0), data)
        nx = x.shape[0] - ns
        return x[:nx], x[nx:]

    def segment(self, q0, v, tau, u, par):
        """``segment``'s ``(p-, p+, E_d)`` (with the internal points ``u`` under a rule that has them)."""
        return self.f["segment"](q0, v, tau, *((u,) if self.system.stages else ()), par)

    def velocity(self, q, v, p, par):
        """The velocity of momentum ``p`` at ``q``: one Newton step of ``dL/dqdot = p`` from ``v``."""
        mom, mass = self.f["legendre"](q, v, par)
        return v + ca.solve(mass, p - mom)

    def smooth(self, q, p, h, par):
        """Smooth step (46): ``v`` of ``p = p-(q, q + h v, h)``, and the internal points (:meth:`solve`)."""
        n = self.n
        start = self.velocity(q, ca.MX.zeros(n), p, par)
        if not self.system.stages:
            res, jac = self.f["smooth"](start, q, p, h, par)
            start = start - ca.solve(jac, res)  # one Newton step: the explicit predictor
        return self.solve("smooth", start, ca.vertcat(q, p, h, par))

    def timed(self, par, dt):
        """``par`` of a segment starting ``dt`` later (forces of time: the last slot is the start time)."""
        return later(par, dt) if self.system.timed else par

    def step(self) -> ca.Function:
        q, p, h, par = self.inputs()
        v, u = self.smooth(q, p, h, par)
        _, p1, _ = self.segment(q, v, h, u, par)
        return ca.Function(
            "step",
            [q, p, h, par],
            [q + h * v, p1],
            ["q", "p", "h", "par"],
            ["q1", "p1"],
        )

    def inputs(self):
        """The symbols ``(q, p, h, par)`` every Function takes."""
        n = self.n
        return ca.MX.sym("q", n), ca.MX.sym("p", n), ca.MX.sym("h"), ca.MX.sym("par", self.npar)

    def crossing(self, j: int, contact: str, q, p, h, par):
        """Contact time and point (47) on contact ``j``: ``(v, alpha, q~, p~-, E-)``, from the smooth step's
        ``v`` and the interpolated crossing of ``phi_j`` (the stepper's start)."""
        n = self.n
        v, _ = self.smooth(q, p, h, par)
        phi0 = self.f["contacts"](q, par)[0][j]
        phi1 = self.f["contacts"](q + h * v, par)[0][j]
        s0 = ca.fmin(ca.fmax(phi0 / (phi0 - phi1), 0.0), 1.0)
        x, u = self.solve(f"contact_time_{contact}", ca.vertcat(v, s0), ca.vertcat(q, p, h, par))
        v_c, alpha = x[:n], x[n]
        _, p_in, e_c = self.segment(q, v_c, alpha * h, u, par)
        return v_c, alpha, q + alpha * h * v_c, p_in, e_c

    def contact(self, j: int, contact: str) -> ca.Function:
        """The impact point of a step striking contact ``j`` (47): ``(q, p, h, par) -> (qc, pc, alpha)``."""
        q, p, h, par = self.inputs()
        _, alpha, q_c, p_in, _ = self.crossing(j, contact, q, p, h, par)
        return ca.Function(
            f"contact_{contact}",
            [q, p, h, par],
            [q_c, p_in, alpha],
            ["q", "p", "h", "par"],
            ["qc", "pc", "alpha"],
        )

    def impact(self, j: int, contact: str) -> ca.Function:
        """One step holding one impact on contact ``j``: (47), (48), (49)."""
        n = self.n
        q, p, h, par = self.inputs()
        v_c, alpha, q_c, p_in, e_c = self.crossing(j, contact, q, p, h, par)
        tau_c = alpha * h
        # Jump (48) from the reflected velocity; energy kept less the loss (39) of restitution e.
        par_c = self.timed(par, tau_c)
        nrm = self.f["contacts"](q_c, par_c)[1][j, :].T
        vel = self.velocity(q_c, v_c, p_in, par_c)
        minv_n = ca.solve(self.f["legendre"](q_c, vel, par_c)[1], nrm)
        nv, nmn = ca.dot(nrm, vel), ca.dot(nrm, minv_n)
        e = self.f["restitution"](par)[j]
        e_in = e_c - (1.0 - e * e) * nv * nv / (2.0 * nmn)
        mu0 = -(1.0 + e) * nv / nmn
        tau_r = h - tau_c
        y, u = self.solve(
            "jump", ca.vertcat(vel + mu0 * minv_n, mu0), ca.vertcat(q_c, nrm, p_in, e_in, tau_r, par_c)
        )
        w, mu = y[:n], y[n]
        _, p1, _ = self.segment(q_c, w, tau_r, u, par_c)
        return ca.Function(
            f"impact_{contact}",
            [q, p, h, par],
            [q_c + tau_r * w, p1, alpha, mu],
            ["q", "p", "h", "par"],
            ["q1", "p1", "alpha", "mu"],
        )


def functions_of(
    system: DiscreteSystem, newton_options: Mapping[str, object] | None = None
) -> dict[str, ca.Function]:
    """:func:`casadi_functions` of an already derived system."""
    ph = _Phases(system, FUNCTION_NEWTON_OPTIONS if newton_options is None else newton_options)
    out = {"step": ph.step()}
    frictional = system.model.friction_of
    for j, c in enumerate(system.contact_names):
        if c not in frictional:
            out[f"impact_{c}"] = ph.impact(j, c)
        out[f"contact_{c}"] = ph.contact(j, c)
    return out
