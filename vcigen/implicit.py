"""The implicit grid step: the smooth step (46) by Newton, with the step's invariants hoisted.

When the smooth residual (46) is nonlinear in ``v`` (a configuration-dependent
mass, a nonlinear potential under the midpoint rule), a grid step is a Newton
solve. Its residual and Jacobian, the momentum ``p+`` (51), the energy ``E_d``
(55), the contacts at the step end and the slopes' Legendre terms share most of
their subexpressions, and every subexpression of ``(q_k, p_k, h, par)`` alone
(``M(q_k)``, ``grad V(q_k)``, ``sin(q_k)``, ...) is the same in every Newton
iteration of the step. Three routines, written in ``v`` with ``q_k+1 = q_k + h v``:

* ``smooth_consts(q0, tau, par) -> k``: the step's invariants (of ``q_k``, ``h``
  and ``par`` alone), for the first step of a run and after an impact;
* ``smooth_iter(x, p0, k) -> res, jac``: (46) and its Jacobian, per Newton iteration;
  with the stage eliminated (``structure.stage_reduced``, :mod:`vcigen.stage`) the unknown is the
  internal point's mean velocity ``z`` (``n`` of them, not ``(v, u)``), the rows the stage's
  stationarity at ``v(z)``, and ``smooth_back(z, p0, k) -> x`` gives ``(v, u)`` in closed form;
* ``smooth_end(x, k) -> p1, energy, phi, grad, mom, mass, k_next``: ``p+`` (51),
  ``E_d`` (55), ``phi`` and ``grad phi`` at ``q_k+1``, the Legendre transform there
  (``dL/dqdot (q_k+1, v)`` and ``M(q_k+1)``, for the slope of ``phi`` at the end)
  and the next step's invariants, once per step, CSE'd across all of them: the
  trigonometry of ``q_k+1`` is evaluated once and carried into the next step, as a
  hand-written loop carries ``M(q_k+1)``.

Each entry is expanded where that is shorter: written in ``(q_k, v)``, the
residual of (46) carries terms of ``q_k+1`` that cancel only then (the trapezoid's
``h/2 grad V(q_k+1)`` from ``D1`` of ``L(q_k+1, v)``). The residual is the smooth
routine's own expression, so Newton's last residual norm *is* the smooth step's
residual (the stepper's check reads it).
"""

from __future__ import annotations

import sympy as sp

from .derive import DiscreteSystem
from .explicit import hoist, shorter
from .routines import Arg, Output, Routine
from .stage import predictor, reduced_smooth


def _bind(routine: Routine, values: dict[str, sp.Matrix]) -> dict[sp.Symbol, sp.Expr]:
    """The substitution that evaluates ``routine`` at the named input values."""
    rep: dict[sp.Symbol, sp.Expr] = {}
    for arg in routine.inputs:
        if arg.name in values:
            rep.update(zip(arg.symbols, values[arg.name]))
    return rep


def _hoist_with_next(
    exprs: list[sp.Expr], varying: set[sp.Symbol], at_next: dict[sp.Symbol, sp.Expr]
) -> tuple[list[tuple[sp.Symbol, sp.Expr]], list[sp.Expr], list[sp.Expr]]:
    """``hoist`` of ``exprs`` together with the invariants' values at the next step (``at_next``).

    Returns ``(consts, reduced, next)``: ``next[i]`` is ``consts[i]`` at the next step, written like
    ``reduced`` in the varying symbols and the constants. The set of constants is closed: the
    invariants of the next values are constants too (found by repeating until nothing is new).
    """
    consts, _ = hoist(exprs, varying)
    known = [e for _, e in consts]
    while True:
        consts, reduced = hoist(exprs + [e.xreplace(at_next) for e in known], varying)
        found = [e for _, e in consts]
        if set(found) == set(known):
            break
        known += [e for e in found if e not in set(known)]
    nxt = dict(zip(known, reduced[len(exprs) :]))
    return consts, reduced[: len(exprs)], [nxt[e] for _, e in consts]


def implicit_routines(system: DiscreteSystem) -> list[Routine]:
    """``smooth_consts``, ``smooth_iter`` and ``smooth_end`` of the implicit grid step (see the module)."""
    r = system.routines
    smooth = r["smooth"]
    xs, q0, p0, tau, par = smooth.inputs
    n = system.n
    # with internal points (Rule.stages) the unknowns are (v, u): the stage's u is solved with v and
    # p+, E_d are the segment's at that u (no second solve of the stage)
    x, u, h = sp.Matrix(xs.symbols[:n]), sp.Matrix(xs.symbols[n:]), tau.symbols[0]
    q1 = sp.Matrix(q0.symbols) + h * x
    pars = sp.Matrix(par.symbols)
    seg, con, leg = r["segment"], r["contacts"], r["legendre"]
    at_seg = _bind(seg, {"q0": sp.Matrix(q0.symbols), "v": x, "tau": sp.Matrix([h]), "u": u, "par": pars})
    at_con = _bind(con, {"q": q1, "par": pars})
    at_leg = _bind(leg, {"q": q1, "v": x, "par": pars})
    # with the stage eliminated (vcigen.stage): Newton on z, the internal point's mean velocity, and (v, u)
    # from it in closed form (smooth_back)
    red = reduced_smooth(system) if system.structure.stage_reduced else None
    zs = red.unknowns if red is not None else ()
    iterate = (
        [("res", red.res), ("jac", red.jac())]
        if red is not None
        else [
            ("res", smooth.output("res").expr),
            ("jac", smooth.output("jac").expr),
        ]
    )
    outputs = [
        *iterate,
        ("p1", seg.output("p_plus").expr.xreplace(at_seg)),
        ("energy", seg.output("energy").expr.xreplace(at_seg)),
        ("phi", con.output("phi").expr.xreplace(at_con)),
        ("grad", con.output("grad").expr.xreplace(at_con)),
        ("mom", leg.output("momentum").expr.xreplace(at_leg)),
        ("mass", leg.output("mass").expr.xreplace(at_leg)),
        *([("x", red.x)] if red is not None else []),
    ]
    guess = predictor(red, h) if red is not None else None
    outputs += [("guess", guess)] if guess is not None else []
    flat = [shorter(e) for _, o in outputs for e in o]  # expanded, terms that cancel in (q0, v) cancel
    # p0 stays an input of the iteration: the invariants are of (q0, tau, par) alone, and those of the
    # next step are the same expressions at q0 + tau v (computed with p1, from the same trig of q1)
    consts, reduced, nxt = _hoist_with_next(
        flat, set(xs.symbols) | set(zs) | set(p0.symbols), dict(zip(q0.symbols, q1))
    )
    ks = Arg("k", tuple(k for k, _ in consts))
    outs, i = [], 0
    for name, o in outputs:
        outs.append(Output(name, sp.Matrix(o.rows, o.cols, reduced[i : i + len(o)])))
        i += len(o)
    k_next = Output("k_next", sp.Matrix(nxt) if nxt else sp.zeros(0, 1))
    back = []
    if guess is not None:
        back.append(
            Routine(
                "smooth_guess",
                (p0, ks),
                (outs.pop(),),
                "A guess of z for the smooth step (46) with the stage eliminated: one Newton step from z = 0 "
                "with the Jacobian at tau = 0 (vcigen.stage.predictor).",
            )
        )
    if red is not None:
        back.insert(
            0,
            Routine(
                "smooth_back",
                (Arg("z", zs), p0, ks),
                (outs.pop(),),
                "(v, u) of the smooth step (46) at the internal point's mean velocity z, in closed form: "
                "its momentum rows solved for v (vcigen.stage).",
            ),
        )
    it_in = Arg("z", zs) if red is not None else xs
    return [
        Routine(
            "smooth_consts",
            (q0, tau, par),
            (Output("k", sp.Matrix([e for _, e in consts]) if consts else sp.zeros(0, 1)),),
            "Invariants of the implicit grid step: its subexpressions of (q_k, h, par) alone.",
        ),
        Routine(
            "smooth_iter",
            (it_in, p0, ks),
            tuple(outs[:2]),
            "Smooth step (46), (73) and its Jacobian in v, from the step's invariants k."
            if red is None
            else "Smooth step (46): the stage's stationarity at v(z) (the momentum rows solved for v) and "
            "its Jacobian in z, the internal point's mean velocity, from the invariants k (vcigen.stage).",
        ),
        Routine(
            "smooth_end",
            (xs, ks),
            (*outs[2:], k_next),
            "End of the implicit grid step: p+ (51), E_d (55), phi and grad phi at q_k+1 = q_k + h v,"
            " dL/dqdot (q_k+1, v) and M(q_k+1) for the slope there, and the invariants of the next step.",
        ),
        *back,
    ]
