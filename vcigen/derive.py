"""Discrete mechanics, symbolically: momenta, energy and every phase's residual.

Pure SymPy: a :class:`~vcigen.model.Model` and a rule in, a
:class:`DiscreteSystem` of :class:`~vcigen.routines.Routine` out. Nothing here
knows about a backend.

Every quantity is written in the segment start ``q0``, the segment velocity
``v = (q1 - q0)/tau`` and the segment duration ``tau``. With the rule's mean
Lagrangian ``l`` (``L_d = tau l``):

* ``p-  = -D1 L_d = l_v - tau l_q0``   (50), (51)
* ``p+  =  D2 L_d = l_v``              (50), (51)
* ``E_d = -D3 L_d = v . l_v - l - tau l_tau``   (55)

all polynomial in ``tau``, so sub-steps of vanishing length (impacts at
``alpha -> 0`` or ``alpha -> 1``) are well conditioned (MATH.md).
"""

from __future__ import annotations

from dataclasses import dataclass, field, fields, replace
from functools import cached_property
from typing import TYPE_CHECKING

import sympy as sp

from . import diskmemo, memo
from .calculus import hessian, jacobian
from .model import Model
from .routines import Arg, Output, Routine
from .rows import Rows, contact_rows
from .rules import RULES, Rule, get_rule
from .tangents import tangent_routines

if TYPE_CHECKING:
    from .structure import Structure

KINK = 1e-12  # |u| below which sign(u), Heaviside(u) in a contact normal count as a kink


def _cone_centre(expr: sp.Expr) -> sp.Expr:
    """At a kink of phi (``Abs``, ``Min``, ``Max``) take the centre of the normal cone (86).

    ``sign(u)`` and ``Heaviside(u)`` become 0 and 1/2 for ``|u| <= KINK``, so that a
    kink hit exactly (a flat star's two vertices at once) does not pick a side from
    round-off in the solver.
    """
    return expr.replace(
        lambda e: isinstance(e, sp.sign),
        lambda e: sp.Piecewise((-1, e.args[0] < -KINK), (0, e.args[0] <= KINK), (1, True)),
    ).replace(
        lambda e: isinstance(e, sp.Heaviside),
        lambda e: sp.Piecewise((0, e.args[0] < -KINK), (sp.S.Half, e.args[0] <= KINK), (1, True)),
    )


def _vec(prefix: str, n: int) -> tuple[sp.Symbol, ...]:
    return tuple(sp.Dummy(f"{prefix}{i}", real=True) for i in range(n))


@dataclass(frozen=True)
class Segment:
    """Momenta and energy of one segment ``(q0, v, tau)`` as expressions."""

    q0: sp.Matrix
    v: sp.Matrix
    tau: sp.Symbol
    p_minus: sp.Matrix
    p_plus: sp.Matrix
    energy: sp.Expr  # E_d + f_d+ . v: the energy at the segment's end (E_d without forces)
    energy_start: sp.Expr  # E_d - f_d- . v: the energy at its start (E_d without forces)
    f_minus: sp.Matrix  # f_d-, the discrete force at the segment's start (0 without forces)
    f_plus: sp.Matrix  # f_d+, at its end; (f_d- + f_d+) . v = energy - energy_start (vcigen.work; not
    # under internal points: there f_d-, f_d+ depend on u and that difference is the rule's own quadrature)
    # A rule with internal points (Rule.stages): their O(1) unknowns u and the stationarity dl/du = 0.
    # p-, p+ and E_d above are the partial derivatives at fixed u, equal to -D1, D2, -D3 of the
    # extremal L_d where the stationarity holds (the envelope theorem).
    internal: sp.Matrix = field(default_factory=lambda: sp.zeros(0, 1))
    stationarity: sp.Matrix = field(default_factory=lambda: sp.zeros(0, 1))

    def _rep(self, q0: sp.Matrix, v: sp.Matrix, tau: sp.Expr, u: sp.Matrix | None) -> dict:
        rep = dict(zip(self.q0, q0)) | dict(zip(self.v, v)) | {self.tau: tau}
        return rep | dict(zip(self.internal, u)) if u is not None else rep

    def at(
        self, q0: sp.Matrix, v: sp.Matrix, tau: sp.Expr, u: sp.Matrix | None = None
    ) -> tuple[sp.Matrix, sp.Matrix, sp.Expr]:
        """``(p-, p+, E_d)`` with the segment's symbols (and internal unknowns ``u``) replaced."""
        rep = self._rep(q0, v, tau, u)
        return (self.p_minus.xreplace(rep), self.p_plus.xreplace(rep), self.energy.xreplace(rep))

    def start_energy(self, q0: sp.Matrix, v: sp.Matrix, tau: sp.Expr, u: sp.Matrix | None = None) -> sp.Expr:
        """The energy at the segment's start, with its symbols replaced: what (48a) keeps across an impact."""
        return self.energy_start.xreplace(self._rep(q0, v, tau, u))

    def stationary(self, q0: sp.Matrix, v: sp.Matrix, tau: sp.Expr, u: sp.Matrix | None = None) -> sp.Matrix:
        """The internal points' stationarity ``dl/du`` with the symbols replaced (no rows without stages)."""
        return self.stationarity.xreplace(self._rep(q0, v, tau, u))


def discrete_segment(model: Model, rule: Rule) -> Segment:
    """Discrete momenta (50)-(51) and energy (55) of the rule's ``L_d``."""
    n = model.n
    q0, v, tau = sp.Matrix(_vec("q", n)), sp.Matrix(_vec("v", n)), sp.Dummy("tau", real=True)
    qs, vs = model.coordinates, model.velocities

    def lagrangian(qq: sp.Matrix, vv: sp.Matrix) -> sp.Expr:
        return model.L.xreplace(dict(zip(qs, qq)) | dict(zip(vs, vv)))

    u = sp.Matrix(_vec("u", n * rule.stages)) if rule.stages else sp.zeros(0, 1)
    inside = (u,) if rule.stages else ()  # the internal points' unknowns, for a rule that has them
    ell = rule.mean_lagrangian(lagrangian, q0, v, tau, *inside)
    inner = {"internal": u, "stationarity": sp.Matrix([ell.diff(s) for s in u]) if inside else sp.zeros(0, 1)}
    ell_v = sp.Matrix([ell.diff(s) for s in v])
    ell_q = sp.Matrix([ell.diff(s) for s in q0])
    p_plus = ell_v
    p_minus = ell_v - tau * ell_q
    energy = (v.T * ell_v)[0] - ell - tau * ell.diff(tau)
    if not model.force:
        zero = sp.zeros(n, 1)
        return Segment(q0, v, tau, p_minus, p_plus, energy, energy, zero, zero, **inner)
    if rule.stages:  # internal points: the rule's quadrature also forces them, and (37) sees their velocities
        sf = staged_forces(model, rule, q0, v, tau, u)
        inner["stationarity"] = inner["stationarity"] + sf.stage
        e_d = energy + sf.energy
        pm, pp = p_minus - sf.minus, p_plus + sf.plus
        return Segment(q0, v, tau, pm, pp, e_d + sf.end, e_d - sf.start, sf.minus, sf.plus, **inner)
    f_minus, f_plus = discrete_forces(model, rule, q0, v, tau)
    e_in, e_out = (v.T * f_minus)[0], (v.T * f_plus)[0]
    pm, pp = p_minus - f_minus, p_plus + f_plus
    return Segment(q0, v, tau, pm, pp, energy + e_out, energy - e_in, f_minus, f_plus, **inner)


def time_slot(model: Model) -> sp.Symbol:
    """The symbol of the time a segment starts at (the last entry of ``par`` when forces depend on time)."""
    return model.time_symbol if model.time_symbol is not None else sp.Dummy("t", real=True)


def force_at(model: Model, q: sp.Matrix, v: sp.Matrix, t: sp.Expr) -> sp.Matrix:
    """The generalized force ``F(q, v, t)`` as a column."""
    rep = dict(zip(model.coordinates, q)) | dict(zip(model.velocities, v))
    if model.time_symbol is not None:
        rep[model.time_symbol] = t
    return sp.Matrix([f.xreplace(rep) for f in model.force])


def discrete_forces(model: Model, rule: Rule, q0: sp.Matrix, v: sp.Matrix, tau: sp.Symbol):
    """``(f_d-, f_d+)`` of the segment ``(q0, v, tau)`` starting at the time slot (MATH.md, Forcing).

    With them ``p- = -D1 L_d - f_d-`` and ``p+ = D2 L_d + f_d+`` (discrete Lagrange-d'Alembert); the
    alpha-variation with the time component ``F_t = -F . qdot`` (37) of the same quadrature keeps
    ``E_d - f_d- . v`` of the segment after an impact equal to ``E_d + f_d+ . v`` of the one before.
    """
    if rule.discrete_forces is None:
        raise ValueError(f"rule {rule.name!r} has no discrete forces (trapezoid, midpoint, lobatto3 have)")
    return rule.discrete_forces(lambda q, vv, t: force_at(model, q, vv, t), q0, v, tau, time_slot(model))


def staged_forces(model: Model, rule: Rule, q0: sp.Matrix, v: sp.Matrix, tau: sp.Symbol, u: sp.Matrix):
    """:class:`~vcigen.rules.StagedForces` of a rule with internal points ``u`` (MATH.md, Forcing)."""
    if rule.staged_forces is None:
        raise ValueError(f"rule {rule.name!r} has no discrete forces for its internal points")
    return rule.staged_forces(lambda q, vv, t: force_at(model, q, vv, t), q0, v, tau, time_slot(model), u)


@dataclass(frozen=True)
class DiscreteSystem:
    """Everything a backend needs: routines plus what they mean."""

    model: Model
    rule: Rule
    contact_names: tuple[str, ...]
    params: tuple[sp.Symbol, ...]
    routines: dict[str, Routine] = field(default_factory=dict)
    rows: Rows | None = None  # rows of sustained contact and bilateral constraints (vcigen.rows)
    segment: Segment | None = None  # the rule's momenta, energies and discrete forces (vcigen.work)

    @property
    def n(self) -> int:
        return self.model.n

    @property
    def m(self) -> int:
        return len(self.contact_names)

    @property
    def stages(self) -> int:
        """Number of internal unknowns of a segment (``n`` per internal point of the rule; 0 for most rules).

        They are the last ``stages`` unknowns of every residual routine, after the phase's own
        (``x = (v, u)``, ``(v, alpha, u)``, ``(w, mu, u)``, ``(w, mu, beta, u)``), and its first
        ``stages`` rows are their stationarity; routine ``stage`` solves them alone for a given
        segment (``segment`` then takes them)."""
        return self.n * self.rule.stages

    @cached_property
    def structure(self) -> Structure:
        """What the scene allows (:class:`vcigen.structure.Structure`): detected once, on first use, and
        read by both backends (and printed in the generated C header)."""
        from . import structure  # the detectors read this system's routines (vcigen.structure imports derive)

        return structure.detect(self)

    @property
    def timed(self) -> bool:
        """Whether the forces depend on time: then ``par`` ends with the time a segment starts at."""
        return self.model.time_symbol is not None

    @property
    def r(self) -> int:
        """Number of rows (``0``: no contact and no constraint, nothing is ever sustained)."""
        return 0 if self.rows is None else self.rows.size


def _residual_routine(
    name: str, unknown: Arg, args: list[Arg], res: sp.Matrix, doc: str, head: Routine | None = None
) -> Routine:
    """Residual and Jacobian; with ``head`` (the leading rows) only the rest is differentiated."""
    if head is None:
        return Routine(
            name, (unknown, *args), (Output("res", res), Output("jac", jacobian(res, unknown.symbols))), doc
        )
    top, top_jac = head.output("res").expr, head.output("jac").expr
    jac = top_jac.col_join(jacobian(res, unknown.symbols))
    return Routine(name, (unknown, *args), (Output("res", top.col_join(res)), Output("jac", jac)), doc, head)


_DERIVED = memo.Lru()  # (model_key, id(rule)) -> (rule, DiscreteSystem): vcigen.memo


def derive(model: Model, rule: str | Rule = "trapezoid", sensitivities: bool = False) -> DiscreteSystem:
    """Derive every routine of MATH.md for ``model`` under ``rule``.

    ``sensitivities``: also the ``d_*`` routines of :mod:`vcigen.tangents` (the partials of every phase in
    its data, for exact sensitivities); a scene that does not ask does not pay for them.

    A model derived before in this process under the same rule is not derived again (:mod:`vcigen.memo`):
    the same routines, in a new dict with copied matrices, with ``model`` as the system's model. One
    derived by another process under a built-in rule is read from disk (:mod:`vcigen.diskmemo`).
    """
    rule = get_rule(rule)
    if not memo.enabled():
        return _derive(model, rule, sensitivities)
    key = memo.model_key(model)
    # the rule is kept in the entry, so that its id is not reused while the entry lives
    _, first = _DERIVED.get_or_make((key, id(rule)), lambda: (rule, _derive_stored(model, rule, key)))
    routines = memo.copy_routines(first.routines)
    if sensitivities:
        routines.update(tangent_routines(routines))
    return replace(first, model=model, routines=routines)


def _derive_stored(model: Model, rule: Rule, key: str) -> DiscreteSystem:
    """:func:`_derive`, read from the disk memo when it can be (a built-in rule, a model without dummies:
    their key prints the same in every process)."""
    if not diskmemo.enabled() or RULES.get(rule.name) is not rule or "Dummy(" in key:
        return _derive(model, rule)

    def parts() -> dict:
        system = _derive(model, rule)
        return {f.name: getattr(system, f.name) for f in fields(system) if f.name not in ("model", "rule")}

    return DiscreteSystem(model, rule, **diskmemo.get_or_make("derive", f"{key}\0{rule.name}", parts))


def _derive(model: Model, rule: Rule, sensitivities: bool = False) -> DiscreteSystem:
    """:func:`derive` without the memo."""
    n = model.n
    if rule.stages:
        unsupported(model, rule)
    names = tuple(model.phi)
    rows = contact_rows(model)
    # friction in sustained contact, set by the stepper (vcigen.sustained): slips, refs, branches
    slots = rows.slips + rows.refs + tuple(b for bs in rows.branches for b in bs)
    time = (model.time_symbol,) if model.time_symbol is not None else ()
    par = Arg("par", tuple(model.defaults) + slots + time)
    seg = discrete_segment(model, rule)
    qs, vs = model.coordinates, model.velocities

    # Continuous Legendre transform and mass matrix, for the start and the reflected guess.
    q, qd = _vec("q", n), _vec("v", n)
    rep = dict(zip(qs, q)) | dict(zip(vs, qd))
    mom = sp.Matrix([model.L.diff(s) for s in vs]).xreplace(rep)
    legendre = Routine(
        "legendre",
        (Arg("q", q), Arg("v", qd), par),
        (Output("momentum", mom), Output("mass", model.mass_matrix.xreplace(rep))),
        "p = dL/dqdot and M = d2L/dqdot2 (start, reflected initial guess).",
    )
    seg_in = (Arg("q0", tuple(seg.q0)), Arg("v", tuple(seg.v)), Arg("tau", (seg.tau,)))
    segment = Routine(
        "segment",
        (*seg_in, *((Arg("u", tuple(seg.internal)),) if rule.stages else ()), par),
        (
            Output("p_minus", seg.p_minus),
            Output("p_plus", seg.p_plus),
            Output("energy", sp.Matrix([seg.energy])),
        ),
        "Discrete momenta p-(q0,q1,tau), p+(q0,q1,tau) (50)-(51) and E_d (55)"
        + (" + f_d+ . v, the energy at the segment's end (forces)." if model.force else "."),
    )
    qrep = dict(zip(qs, q))
    phis = [model.phi[c].xreplace(qrep) for c in names]
    phi_vec = sp.Matrix(phis) if phis else sp.zeros(0, 1)
    grad = (
        sp.Matrix([[_cone_centre(d) for d in jacobian(sp.Matrix([ph]), q, drop_dirac=False)] for ph in phis])
        if phis
        else sp.zeros(0, n)
    )
    contacts = Routine(
        "contacts",
        (Arg("q", q), par),
        (Output("phi", phi_vec), Output("grad", grad)),
        "Contact functions phi_j(q) and their gradients (rows).",
    )
    rest = model.restitution_of
    restitution = Routine(
        "restitution",
        (par,),
        (Output("e", sp.Matrix([rest[c] for c in names]) if names else sp.zeros(0, 1)),),
        "Coefficient of restitution of each contact (1: elastic); the jump loses (1 - e^2)/2 of (39).",
    )
    routines = {r.name: r for r in (legendre, segment, contacts, restitution)}
    if rule.stages:
        routines["stage"] = _residual_routine(
            "stage",
            Arg("x", tuple(seg.internal)),
            [*seg_in, par],
            seg.stationarity,
            "Stationarity dl/du = 0 of the internal points of the segment (q0, v, tau): unknowns u.",
        )
    if model.friction_of:
        fr, tans = model.friction_of, model.tangents_of
        mus = sp.Matrix([fr[c][0] if c in fr else sp.S.Zero for c in names])

        def tangent_grads(d: int) -> sp.Matrix:
            """Each contact's gradient of its tangent ``d`` (0 where it has none)."""
            return sp.Matrix(
                [
                    [
                        _no_dirac(tans[c][d].xreplace(qrep).diff(s))
                        if len(tans.get(c, ())) > d
                        else sp.S.Zero
                        for s in q
                    ]
                    for c in names
                ]
            )

        tgrad = tangent_grads(0)
        routines["friction"] = Routine(
            "friction",
            (Arg("q", q), par),
            (
                Output("mu", mus),
                Output("tgrad", tgrad),
                Output(
                    "branch",
                    sp.Matrix([u.xreplace(qrep) for us in rows.branch_args for u in us])
                    if any(rows.branch_args)
                    else sp.zeros(0, 1),
                ),
            ),
            "Coulomb friction of each contact: mu_f (0: frictionless) and the tangent's gradient (MATH.md).",
        )
        if any(len(t) == 2 for t in tans.values()):
            routines["friction_cone"] = Routine(
                "friction_cone",
                (Arg("q", q), par),
                (Output("tgrad2", tangent_grads(1)),),
                "The second tangent's gradient of each contact with an isotropic cone (0 elsewhere).",
            )

    # Smooth step (46): p_k = p-(q_k, q_k + h v, h).
    # With internal points (Rule.stages) every phase's unknowns end with their O(1) unknowns u and its
    # rows with their stationarity (DiscreteSystem.stages).
    q0, p0, tau = _vec("q", n), _vec("p", n), sp.Dummy("tau", real=True)
    v, us = _vec("v", n), _vec("u", n * rule.stages)
    um = sp.Matrix(us)

    def staged(rows: sp.Matrix, start: tuple, vel: tuple, duration: sp.Expr) -> sp.Matrix:
        """With internal points, their stationarity on the segment (start, vel, duration), then ``rows``.

        The stationarity rows come first in every phase: the solvers settle ``u`` on them alone first."""
        if not us:
            return rows
        return seg.stationary(sp.Matrix(start), sp.Matrix(vel), duration, um).col_join(rows)

    pm, _, _ = seg.at(sp.Matrix(q0), sp.Matrix(v), tau, um)
    base = [Arg("q0", q0), Arg("p0", p0), Arg("tau", (tau,)), par]
    routines["smooth"] = _residual_routine(
        "smooth",
        Arg("x", (*v, *us)),
        base,
        staged(pm - sp.Matrix(p0), q0, v, tau),
        "Smooth step (46), (73): unknown v" + (" and the internal points u." if us else "."),
    )

    # Contact time and point (47), (74): unknowns (v, alpha), q~ = q_k + alpha tau v.
    alpha = sp.Dummy("alpha", real=True)
    pm_a, _, _ = seg.at(sp.Matrix(q0), sp.Matrix(v), alpha * tau, um)
    qt = sp.Matrix(q0) + alpha * tau * sp.Matrix(v)
    base_x = Arg("x", (*v, alpha, *us))
    shared = _residual_routine(
        "shared_contact_time",
        base_x,
        base,
        staged(pm_a - sp.Matrix(p0), q0, v, alpha * tau),
        "Momentum rows of (47), (74), shared by the contacts.",
    )
    for j, c in enumerate(names):
        routines[f"contact_time_{c}"] = _residual_routine(
            f"contact_time_{c}",
            base_x,
            base,
            sp.Matrix([phis[j].xreplace(dict(zip(q, qt)))]),
            f"Contact time and point (47), (74) on contact '{c}': unknowns (v, alpha).",
            shared,
        )

    # Jump (48), (75), (76): unknowns (w, mu); mu >= 0 pushes into C along nrm.
    qc, nrm, p_in, e_in = _vec("q", n), _vec("n", n), _vec("p", n), sp.Dummy("E", real=True)
    w, mu, beta = _vec("w", n), sp.Dummy("mu", real=True), sp.Dummy("beta", real=True)
    jargs = [Arg("qc", qc), Arg("nrm", nrm), Arg("p_in", p_in), Arg("e_in", (e_in,)), Arg("tau", (tau,)), par]

    def jump_res(duration: sp.Expr) -> sp.Matrix:
        pm_j, _, _ = seg.at(sp.Matrix(qc), sp.Matrix(w), duration, um)
        en_j = seg.start_energy(sp.Matrix(qc), sp.Matrix(w), duration, um)
        rows = (pm_j - sp.Matrix(p_in) - mu * sp.Matrix(nrm)).col_join(sp.Matrix([en_j - e_in]))
        return staged(rows, qc, w, duration)

    routines["jump"] = _residual_routine(
        "jump",
        Arg("x", (*w, mu, *us)),
        jargs,
        jump_res(tau),
        "Jump (48), (75)-(76): tangential momentum and energy kept; unknowns (w, mu).",
    )
    # Several impacts in one step (78): the post-impact segment ends on contact j'.
    qend = sp.Matrix(qc) + beta * tau * sp.Matrix(w)
    jump_x = Arg("x", (*w, mu, beta, *us))
    shared = _residual_routine(
        "shared_jump_contact", jump_x, jargs, jump_res(beta * tau), "Rows of (78) shared by the contacts."
    )
    for j, c in enumerate(names):
        routines[f"jump_contact_{c}"] = _residual_routine(
            f"jump_contact_{c}",
            jump_x,
            jargs,
            sp.Matrix([phis[j].xreplace(dict(zip(q, qend)))]),
            f"Jump ending on contact '{c}' (78): unknowns (w, mu, beta).",
            shared,
        )
    if rows.size:
        routines.update(sustained_routines(model, seg, rows, par, phis, q, rule))
    if sensitivities:
        routines.update(tangent_routines(routines))
    return DiscreteSystem(model, rule, names, par.symbols, routines, rows, seg)


def unsupported(model: Model, rule: Rule) -> None:
    """A rule with internal points has every phase but friction: a ``ValueError`` naming what it lacks."""
    lacks = [what for what, there in (("friction", bool(model.friction_of)),) if there]
    if len(rule.nodes) != rule.stages:
        lacks.append(
            "sustained contact and bilateral constraints (Rule.nodes does not place its internal points)"
        )
    if lacks:
        raise ValueError(
            f"rule {rule.name!r} (internal points) does not support {', '.join(lacks)} yet; "
            "use rule 'trapezoid' or 'midpoint' for this model"
        )


def _no_dirac(e: sp.Expr) -> sp.Expr:
    """Second derivatives of ``Abs``: the Dirac mass at a kink is the impact's business, not a force."""
    return _cone_centre(e.replace(lambda x: isinstance(x, sp.DiracDelta), lambda x: sp.S.Zero))


def sustained_routines(
    model: Model,
    seg: Segment,
    rows: Rows,
    par: Arg,
    phis: list[sp.Expr],
    q: tuple[sp.Symbol, ...],
    rule: Rule | None = None,
) -> dict[str, Routine]:
    """Routines of sustained contact (MATH.md): rows, free dynamics, the constrained step, the projection.

    * ``rows(q, u)``: ``psi_r``, ``grad psi_r`` and the curvature ``u . Hess psi_r . u``;
    * ``dynamics(q, u)``: ``dL/dq - (d2L/dqdot dq) u`` (so that ``M qddot = rhs``) and each contact's
      curvature, for the normal acceleration ``d2 phi/dt2`` that says whether forces press a body in;
    * ``rattle``: the constrained discrete Euler-Lagrange step (RATTLE in position-momentum form),
      unknowns ``(v, Lam)`` with ``Lam = tau/2 lambda`` an impulse: ``p-(q0, v, tau) = p0 + sum act_r
      Lam_r grad psi_r(q0)``, ``psi_r(q0 + tau v) = 0`` where ``act_r = 1`` and ``Lam_r = 0`` elsewhere;
    * ``rattle_project``: the end momentum ``p1 = p+ + sum act_r Lam'_r grad psi_r(q1)`` whose velocity
      ``u`` is tangent to every active row: unknowns ``(u, Lam')``, ``dL/dqdot(q1, u) = p1``,
      ``grad psi_r . u = 0``.

    A rule with internal points (``rule.stages``) holds them on the active rows too, each with its own
    multipliers ``Lam_m`` (:func:`held_internal_points`): ``rattle``'s unknowns are ``(v, Lam, Lam_m, u)``
    (``u`` explicit, no stage appended by the solvers: :data:`WHOLE`) and ``rattle_end`` gives ``p+`` and
    ``E_d`` of the segment with the internal multipliers' share.
    """
    n, nr = model.n, rows.size
    qs, vs = model.coordinates, model.velocities
    qrep = dict(zip(qs, q))
    u = _vec("u", n)
    rep = qrep | dict(zip(vs, u))
    psi = [e.xreplace(qrep) for e in rows.exprs]
    grad = sp.Matrix([[_no_dirac(d) for d in jacobian(sp.Matrix([ps]), q)] for ps in psi])
    # The force direction of each row: grad psi_r, plus slip_f grad tangent_f on the rows of a slipping
    # frictional contact f (Coulomb: -mu_f s lambda along the tangent; MATH.md *Friction*).
    dirs = grad.copy()
    for f, j in enumerate(rows.frictional):
        srow = rows.sticks.index(f)
        for r in range(nr):
            if rows.contact[r] == j:
                dirs[r, :] = dirs[r, :] + rows.slips[f] * grad[srow, :]
    umat = sp.Matrix(u)

    def curvature(f: sp.Expr) -> sp.Expr:
        """``u . Hess f . u``: the part of ``d2 f/dt2`` the velocity alone gives."""
        return (umat.T * hessian(f, q).applyfunc(_no_dirac) * umat)[0]

    curv = sp.Matrix([curvature(ps) for ps in psi])
    out = {
        "rows": Routine(
            "rows",
            (Arg("q", q), Arg("u", u), par),
            (Output("psi", sp.Matrix(psi)), Output("grad", grad), Output("curv", curv)),
            "Rows of sustained contact psi_r(q), their gradients and curvatures u . Hess psi_r . u.",
        )
    }
    lq = sp.Matrix([model.L.diff(s) for s in qs]).xreplace(rep)
    mixed = jacobian(sp.Matrix([model.L.diff(vi) for vi in vs]), qs, drop_dirac=False).xreplace(rep)
    rhs = lq - mixed * umat
    if model.force:  # Lagrange-d'Alembert: M qddot = dL/dq - (d2L/dqdot dq) qdot + F(q, qdot, t)
        rhs = rhs + force_at(model, sp.Matrix(q), umat, time_slot(model))
    ccurv = [curvature(ph) for ph in phis]
    out["dynamics"] = Routine(
        "dynamics",
        (Arg("q", q), Arg("u", u), par),
        (Output("rhs", rhs), Output("curv", sp.Matrix(ccurv) if ccurv else sp.zeros(0, 1))),
        "Free dynamics M qddot = rhs and contact curvatures, for the normal acceleration of a contact.",
    )
    q0, p0, tau = _vec("q", n), _vec("p", n), sp.Dummy("tau", real=True)
    v, lam, act = _vec("v", n), _vec("L", nr), _vec("a", nr)
    staged = rule is not None and rule.stages > 0
    um = sp.Matrix(_vec("u", n * rule.stages)) if staged else None
    pm, _, _ = seg.at(sp.Matrix(q0), sp.Matrix(v), tau, um)
    g0 = dirs.xreplace(dict(zip(q, q0)))
    alam = sp.Matrix([a * lm for a, lm in zip(act, lam)])
    q1 = sp.Matrix(q0) + tau * sp.Matrix(v)
    psi1 = [ps.xreplace(dict(zip(q, q1))) for ps in psi]
    args = [Arg("q0", q0), Arg("p0", p0), Arg("tau", (tau,)), Arg("act", act), par]
    held_rows = sp.Matrix([a * ps + (1 - a) * lm for a, ps, lm in zip(act, psi1, lam)])
    if staged:
        held = held_internal_points(seg, rule, dirs, psi, q, sp.Matrix(q0), sp.Matrix(v), tau, um, act)
        res = seg.stationary(sp.Matrix(q0), sp.Matrix(v), tau, um) - held.stationarity
        res = (
            res.col_join(pm + held.minus - sp.Matrix(p0) - g0.T * alam)
            .col_join(held_rows)
            .col_join(held.rows)
        )
        unknowns = (*v, *lam, *held.lam, *um)
        doc = "its internal points held on the active rows, unknowns (v, Lam, Lam_m, u), Lam ~ w tau lambda"
        _, p_plus, energy = seg.at(sp.Matrix(q0), sp.Matrix(v), tau, um)
        ends = (Arg("q0", q0), Arg("v", v), Arg("tau", (tau,)), Arg("u", tuple(um)), Arg("lm", held.lam))
        out["rattle_end"] = Routine(
            "rattle_end",
            (*ends, Arg("act", act), par),
            (Output("p_plus", p_plus - held.plus), Output("energy", sp.Matrix([energy + held.energy]))),
            "p+ = D2 L_d (51) and E_d = -D3 L_d (55) of a constrained segment whose internal points are held "
            "(the multipliers Lam_m's share).",
        )
    else:
        res = (pm - sp.Matrix(p0) - g0.T * alam).col_join(held_rows)
        unknowns, doc = (*v, *lam), "unknowns (v, Lam), Lam = tau/2 lambda"
    out["rattle"] = _residual_routine(
        "rattle",
        Arg("x", unknowns),
        args,
        res,
        f"Constrained step (RATTLE, MATH.md Sustained contact): {doc}.",
    )
    p1 = _vec("p", n)
    mom = sp.Matrix([model.L.diff(s) for s in vs]).xreplace(rep)
    gu = grad * umat
    res = (mom - sp.Matrix(p1) - dirs.T * alam).col_join(
        sp.Matrix([a * gi + (1 - a) * lm for a, gi, lm in zip(act, gu, lam)])
    )
    out["rattle_project"] = _residual_routine(
        "rattle_project",
        Arg("x", (*u, *lam)),
        [Arg("q1", q), Arg("p1", p1), Arg("act", act), par],
        res,
        "End momentum of a constrained step, velocity tangent to the active rows: unknowns (u, Lam').",
    )
    return out


# Residual routines whose unknowns get no internal unknowns appended by the solvers (CasadiKernels, the C
# <model>_newton): the stage itself, the constrained step (it holds its internal points in its own unknowns,
# (v, Lam, Lam_m, u)) and the projection (no segment).
WHOLE = frozenset({"stage", "rattle", "rattle_project"})


@dataclass(frozen=True)
class HeldPoints:
    """The internal points of a constrained segment held on the active rows (:func:`held_internal_points`)."""

    lam: tuple[sp.Symbol, ...]  # Lam_m: r per internal point, stage after stage
    stationarity: sp.Matrix  # what dl/du equals: -sum_r act_r Lam_m,r grad psi_r(q_m) per internal point
    rows: sp.Matrix  # act_r psi_r(q_m) + (1 - act_r) Lam_m,r per internal point
    minus: sp.Matrix  # what -D1 L_d adds to p- at fixed u
    plus: sp.Matrix  # what D2 L_d takes from p+ at fixed u
    energy: sp.Expr  # what -D3 L_d adds to E_d at fixed u


def held_internal_points(
    seg: Segment,
    rule: Rule,
    dirs: sp.Matrix,
    psi: list[sp.Expr],
    q: tuple[sp.Symbol, ...],
    q0: sp.Matrix,
    v: sp.Matrix,
    tau: sp.Symbol,
    um: sp.Matrix,
    act: tuple[sp.Symbol, ...],
) -> HeldPoints:
    """The internal points ``q_m,k = q0 + tau (c_k v + u_k)`` (``c_k = rule.nodes[k]``) on the active rows.

    The constrained Galerkin step (a Lobatto IIIA-IIIB SPARK step for lobatto3; MATH.md *Sustained contact*,
    *Higher order*): ``D_m L_d + sum_r Lam_m,r grad psi_r(q_m) = 0``, ``psi_r(q_m) = 0`` on the active rows
    (``Lam_m`` pushes along ``+grad psi`` as ``Lam`` does at ``q0``: ``-D1 L_d = p0 + G0^T Lam``, so that the
    step's impulse is ``Lam + Lam_m + Lam'``, ~ ``h lambda``).
    ``L_d(q0, q_m, q1) = tau l(q0, v, u)`` with ``v = (q1 - q0)/tau`` and ``u_k = (q_m,k - (1 - c_k) q0 -
    c_k q1)/tau``, so by the chain rule ``D_m L_d = l_u`` (no division by ``tau``), ``-D1 L_d = l_v - tau
    l_q0 + sum_k (1 - c_k) l_u_k``, ``D2 L_d = l_v - sum_k c_k l_u_k`` and ``-D3 L_d = v . l_v + u . l_u - l -
    tau l_tau``: with ``l_u_k = -G_m,k^T Lam_m,k`` on the held step those are the segment's ``p-``, ``p+``,
    ``E_d`` (partials at fixed ``u``, where ``l_u = 0``) plus the shares below. Where no row is active every
    ``Lam_m = 0``: the free segment's stationarity.
    """
    n, nr = len(q), len(psi)
    lam = _vec("M", nr * rule.stages)
    stationarity, rows = [], []
    minus, plus, energy = sp.zeros(n, 1), sp.zeros(n, 1), sp.S.Zero
    for k, c in enumerate(rule.nodes):
        uk = um[k * n : (k + 1) * n, 0]
        qm = q0 + tau * (c * v + uk)
        at = dict(zip(q, qm))
        alm = sp.Matrix([a * lm for a, lm in zip(act, lam[k * nr : (k + 1) * nr])])
        force = -(dirs.xreplace(at).T * alm)  # l_u_k on the held step
        stationarity.append(force)
        rows += [
            a * ps.xreplace(at) + (1 - a) * lm for a, ps, lm in zip(act, psi, lam[k * nr : (k + 1) * nr])
        ]
        minus += (1 - c) * force
        plus += c * force
        energy += (uk.T * force)[0]
    return HeldPoints(lam, sp.Matrix.vstack(*stationarity), sp.Matrix(rows), minus, plus, energy)


def set_rows(kernels, system: DiscreteSystem) -> None:
    """The row bookkeeping every kernels object carries (``r``, and per row its contact, constraint)."""
    rows = system.rows
    kernels.r = system.r
    kernels.row_contact = rows.contact if rows else ()
    kernels.row_constraint = rows.constraint if rows else ()
    kernels.row_bilateral = rows.bilateral if rows else ()
    kernels.row_stick = rows.sticks if rows else ()  # frictional contact of a stick row, -1 otherwise
    kernels.row_names = rows.names if rows else ()  # "floor", "floor[+-]", a constraint's, "floor/stick"
    kernels.frictional = rows.frictional if rows else ()  # contact index of each frictional contact
    kernels.friction_slot = len(system.model.defaults)  # par[slot:]: nf slips, nf refs, the branch signs
    kernels.branch_count = tuple(len(b) for b in rows.branches) if rows else ()
    # per frictional contact: its partner (the other tangent of a cone contact), -1 for one tangent
    kernels.partner = (rows.partner or (-1,) * len(rows.frictional)) if rows else ()
    tans = system.model.tangents_of
    kernels.cone = tuple(len(tans.get(c, ())) == 2 for c in system.contact_names)  # per contact: two tangents
