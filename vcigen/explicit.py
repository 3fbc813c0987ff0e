"""The explicit grid step: one smooth step (46) as straight-line code, when the mass is constant.

When the smooth residual (46) has a constant diagonal Jacobian and the mass
matrix is constant and diagonal (a Lagrangian ``1/2 v.M v - V(q)`` whose
discrete ``p-`` is linear in ``v``: every scene with a potential linear under
the rule, the trapezoidal rule for any ``V``), a grid step needs no solve:

* ``v_i = -r_i(0) / J_ii`` solves (46) exactly; ``q_k+1 = q_k + h v``;
* ``p_k+1 = p+`` (50)-(51) and ``E_d`` (55) of the segment; ``M v`` cancels
  symbolically against ``v = M^-1 (...)``, so ``p_k+1`` is ``p_k`` plus a force;
* ``phi(q_k+1)`` and its slope ``d = h grad phi . M^-1 (p_k+1 - p(q_k+1, 0))``
  for the crossing pre-test (as ``Kernels.smooth_step``'s ``d1``).

Every subexpression of ``(h, par)`` alone is hoisted into run constants
(``grid_consts``), so the step (``grid_step``, ``grid_end``) has no division.
Both backends take ``v``, ``p_k+1`` and ``E_d`` of the smooth grid step from
``grid_step``: one formula, the same round-off. Likewise, both solve the first
contact time (47) along the explicit segment map (``contact_path_<c>``, when (46)
has a diagonal, ``v``-free Jacobian) and the jump (48) from its quadratic in
``mu`` (``jump_quadratic``, when ``E_d`` is quadratic in the velocity).

Whether a scene allows each of them is decided once, in :mod:`vcigen.structure`
(``system.structure.explicit_grid``, ``.explicit_path``, ``.jump_quadratic``).
"""

from __future__ import annotations

from functools import lru_cache

import sympy as sp

from .calculus import hessian, jacobian
from .derive import DiscreteSystem
from .routines import Arg, Output, Routine


@lru_cache(maxsize=64)
def _expanded(a: sp.ImmutableMatrix) -> sp.ImmutableMatrix:
    return a.applyfunc(sp.expand)


def expanded(a: sp.Matrix) -> sp.Matrix:
    """``a`` with every entry expanded: terms that cancel only after expansion do.

    The chain rule through ``V(q0 + tau v)`` leaves, e.g., ``(4 q + 4 tau v)/4 - (q + tau v)``
    in the Jacobian of (46) under the trapezoidal rule; expanded, it is 0, and the
    Jacobian is the constant mass matrix it is.
    """
    return sp.Matrix(_expanded(sp.ImmutableMatrix(a)))


def smooth_jacobian(system: DiscreteSystem) -> sp.Matrix:
    """The Jacobian of the smooth residual (46) in ``v``, expanded."""
    return expanded(system.routines["smooth"].output("jac").expr)


Constants = list[tuple[sp.Symbol, sp.Expr]]


def hoist(exprs: list[sp.Expr], varying: set[sp.Symbol]) -> tuple[Constants, list[sp.Expr]]:
    """Replace every maximal subexpression free of ``varying`` by a constant symbol.

    Inside a sum or product the invariant terms are grouped into one constant
    (``(p0 - h g m / 2) / m`` -> ``(p0 + k1) k0``). Returns ``(constants, exprs)``
    with the constants in order of first use; numbers stay literal, except a number factored out of a sum
    (``4.905 (y0 + y1)``, as ``sympy.factor_terms`` leaves it), which becomes a constant: CSE's basic
    optimizations would distribute a literal one again.
    """
    consts: dict[sp.Expr, sp.Symbol] = {}

    def const(e: sp.Expr, number: bool = False) -> sp.Expr:
        if e.is_number and not number:
            return e
        if e not in consts:
            consts[e] = sp.Dummy(f"k{len(consts)}", real=True)
        return consts[e]

    def visit(e: sp.Basic) -> sp.Basic:
        if not isinstance(e, sp.Expr):  # a condition of a Piecewise, or one of its pairs
            return e.func(*[visit(a) for a in e.args]) if e.args else e
        if not e.free_symbols & varying:
            return const(e)
        if e.is_Atom:
            return e
        if isinstance(e, sp.Mul) and len(e.args) == 2 and e.args[0].is_Number and e.args[1].is_Add:
            # a number factored out of a sum (sympy.factor_terms): a constant, so that no later pass (CSE's
            # basic optimizations) distributes it again
            return sp.Mul(const(e.args[0], number=True), visit(e.args[1]))
        if isinstance(e, (sp.Add, sp.Mul)):
            fixed = [a for a in e.args if not a.free_symbols & varying]
            moving = [visit(a) for a in e.args if a.free_symbols & varying]
            return e.func(const(e.func(*fixed)), *moving) if fixed else e.func(*moving)
        return e.func(*[visit(a) for a in e.args])

    out = [visit(e) for e in exprs]
    return [(k, e) for e, k in consts.items()], out


@lru_cache(maxsize=64)
def shorter(e: sp.Expr) -> sp.Expr:
    """``e`` expanded if that takes fewer operations (E_d (55) collects to a short form)."""
    x = sp.expand(e)
    return x if sp.count_ops(x) < sp.count_ops(e) else e


def grid_routines(system: DiscreteSystem) -> list[Routine]:
    """``grid_consts(tau, par) -> k``, ``grid_step(q0, p0, k) -> v, p1, E``, ``grid_end(q, p, k) -> phi, d``.

    One smooth grid step (46) as straight-line code, for a constant diagonal mass:
    ``v_i = -r_i(0) / J_ii``, ``p1 = p+`` and ``E_d`` (55); the caller forms
    ``q1 = q0 + tau v`` (as the stepper does); then ``phi(q1)`` and its slope
    ``d = tau grad phi(q1) . M^-1 (p1 - p(q1, 0))``.
    """
    smooth, r = system.routines["smooth"], system.routines
    xs, q0, p0, tau, par = smooth.inputs
    zero = dict.fromkeys(xs.symbols, sp.S.Zero)
    res, jac = smooth.output("res").expr, smooth_jacobian(system)
    v = sp.Matrix([-res[i].xreplace(zero) / jac[i, i] for i in range(system.n)])
    h = tau.symbols[0]

    def at(name: str, values: dict[str, sp.Matrix]) -> dict[sp.Symbol, sp.Expr]:
        rep: dict[sp.Symbol, sp.Expr] = {}
        for arg in r[name].inputs:
            if arg.name in values:
                rep.update(zip(arg.symbols, values[arg.name]))
        return rep

    seg_at = at("segment", {"q0": sp.Matrix(q0.symbols), "v": v, "tau": sp.Matrix([h])})
    energy = shorter(r["segment"].output("energy").expr[0]).xreplace(seg_at)
    p1 = r["segment"].output("p_plus").expr.xreplace(seg_at)  # M v cancels against v = M^-1 (...)
    q = Arg("q", tuple(r["contacts"].input("q").symbols))
    p = Arg("p", tuple(sp.Dummy(f"p{i}", real=True) for i in range(system.n)))
    phi, grad = r["contacts"].output("phi").expr, r["contacts"].output("grad").expr
    leg = r["legendre"]
    l_at = at("legendre", {"q": sp.Matrix(q.symbols), "v": sp.zeros(system.n, 1)})
    mom0, mass = leg.output("momentum").expr.xreplace(l_at), expanded(leg.output("mass").expr).xreplace(l_at)
    vel = sp.Matrix([(p.symbols[i] - mom0[i]) / mass[i, i] for i in range(system.n)])
    d = h * grad * vel if system.m else sp.zeros(0, 1)
    outputs = [("v", v), ("p1", p1), ("energy", sp.Matrix([energy])), ("phi", phi), ("d", d)]
    flat = [e for _, o in outputs for e in o]
    consts, reduced = hoist(flat, {*q0.symbols, *p0.symbols, *q.symbols, *p.symbols})
    ks = Arg("k", tuple(k for k, _ in consts))
    outs, i = [], 0
    for name, o in outputs:
        outs.append(Output(name, sp.Matrix(o.rows, o.cols, reduced[i : i + len(o)])))
        i += len(o)
    return [
        Routine(
            "grid_consts",
            (tau, par),
            (Output("k", sp.Matrix([e for _, e in consts]) if consts else sp.zeros(0, 1)),),
            "Run constants of the explicit grid step: its subexpressions of (h, par) alone.",
        ),
        Routine(
            "grid_step",
            (q0, p0, ks),
            tuple(outs[:3]),
            "Explicit grid step (46), (73): v, p_k+1 = p+ (51) and E_d (55); q_k+1 = q_k + h v.",
        ),
        Routine(
            "grid_end",
            (q, p, ks),
            tuple(outs[3:]),
            "phi at the end q of an explicit grid step and its slope h grad phi . M^-1 (p - p(q, 0)).",
        ),
    ]


def _jump_energy(system: DiscreteSystem):
    """``(w, p-(w), E_d(w), Hess_w E_d)`` of the jump's segment (48), in the jump routine's symbols."""
    n, r = system.n, system.routines
    x, qc, nrm, p_in, e_in, tau, par = r["jump"].inputs
    w = sp.Matrix(x.symbols[:n])
    seg = r["segment"]
    rep = dict(zip(seg.input("q0").symbols, qc.symbols)) | dict(zip(seg.input("v").symbols, w))
    rep[seg.input("tau").symbols[0]] = tau.symbols[0]
    p_minus = seg.output("p_minus").expr.xreplace(rep)
    energy = shorter(seg.output("energy").expr[0]).xreplace(rep)
    return w, p_minus, energy, expanded(hessian(energy, list(w)))


def quadratic_energy(system: DiscreteSystem) -> bool:
    """Whether ``E_d`` of a segment is quadratic in its velocity (its Hessian in ``w`` is constant).

    A detector of :func:`vcigen.structure.detect` (``Structure.jump_quadratic``, with the explicit grid step).
    """
    w, _, _, hess = _jump_energy(system)
    return not (hess.free_symbols & set(w))


def jump_quadratic(system: DiscreteSystem) -> Routine | None:
    """The jump (48) as a quadratic in ``mu``, when the scene allows it (``system.structure.jump_quadratic``).

    (48b) ``p-(w) = p_in + mu n`` is linear in ``w`` with the constant diagonal
    Jacobian of (46): ``w = w0 + mu dw``, ``w0 = (p_in - p-(0)) / J``, ``dw = n / J``.
    Then (48a) ``E_d(w) = E_in`` is ``a mu^2 + b mu + c = 0`` with ``a = dw.H dw / 2``,
    ``b = grad E_d(w0) . dw``, ``c = E_d(w0) - E_in`` (exact: ``H``, the Hessian of
    ``E_d`` in ``w``, is constant). Routine ``jump_quadratic(qc, nrm, p_in, e_in, tau, par)
    -> coef (a, b, c), w0, dw``; ``None`` when the structure is not there.
    """
    if not system.structure.jump_quadratic:
        return None
    n = system.n
    x, qc, nrm, p_in, e_in, tau, par = system.routines["jump"].inputs
    w, p_minus, energy, hess = _jump_energy(system)
    zero = dict.fromkeys(w, sp.S.Zero)
    jac = expanded(jacobian(p_minus, list(w), drop_dirac=False))
    w0 = sp.Matrix([(p_in.symbols[i] - p_minus[i].xreplace(zero)) / jac[i, i] for i in range(n)])
    dw = sp.Matrix([nrm.symbols[i] / jac[i, i] for i in range(n)])
    at_w0 = dict(zip(w, w0))
    a = (dw.T * hess * dw)[0] / 2
    b = sum((energy.diff(wi).xreplace(at_w0) * dw[i] for i, wi in enumerate(w)), sp.S.Zero)
    c = energy.xreplace(at_w0) - e_in.symbols[0]
    return Routine(
        "jump_quadratic",
        (qc, nrm, p_in, e_in, tau, par),
        (Output("coef", sp.Matrix([a, b, c])), Output("w0", w0), Output("dw", dw)),
        "Jump (48) as a mu^2 + b mu + c = 0 along w = w0 + mu dw (explicit scenes).",
    )


def path_routines(system: DiscreteSystem) -> list[Routine]:
    """``contact_path_<c>``: ``g(s)``, ``g'(s)`` and ``v(s)`` of the explicit segment map (47).

    ``v(s)`` solves the smooth residual (46) over the duration ``s tau`` exactly
    (diagonal, ``v``-free Jacobian): ``v_i = -r_i(0) / J_ii``.
    """
    smooth, contacts = system.routines["smooth"], system.routines["contacts"]
    xs, q0, p0, tau, par = smooth.inputs
    s = sp.Dummy("s", real=True)
    at_s = {tau.symbols[0]: s * tau.symbols[0]}
    zero = dict.fromkeys(xs.symbols, sp.S.Zero)
    res, jac = smooth.output("res").expr, smooth_jacobian(system)
    v = sp.Matrix([-res[i].xreplace(zero).xreplace(at_s) / jac[i, i].xreplace(at_s) for i in range(system.n)])
    q_end = sp.Matrix(q0.symbols) + s * tau.symbols[0] * v
    qsub = dict(zip(contacts.input("q").symbols, q_end))
    inputs = (Arg("x", (s,)), q0, p0, tau, par)
    shared = Routine(
        "shared_contact_path", inputs, (Output("v", v),), "v(s) of the explicit segment map (47)."
    )
    out = []
    for j, name in enumerate(system.contact_names):
        g = contacts.output("phi").expr[j].xreplace(qsub)
        out.append(
            Routine(
                f"contact_path_{name}",
                inputs,
                (Output("g", sp.Matrix([g])), Output("dg", sp.Matrix([g.diff(s)])), Output("v", v)),
                f"Contact '{name}' along the explicit segment map: g(s) = phi(q(s tau)), g'(s), v(s) (47).",
                shared,
            )
        )
    return out
