"""The held grid step: a grid step in sustained contact as straight-line code, when the mass is constant.

The constrained step of MATH.md *Sustained contact* (RATTLE, routines ``rattle`` and
``rattle_project``) is two Newton solves on ``n + R`` unknowns. When the scene is explicit
(``system.structure.explicit_grid``: (46) has a constant diagonal Jacobian ``J``, the mass
``M`` is constant and diagonal, no forces), the momentum is ``M qdot`` and no friction acts
(``system.structure.held``, decided in :mod:`vcigen.structure`), both reduce to the ``R_A``
multipliers of the active rows ``A``:

* ``rattle``: ``p-(q0, v, h) = p0 + G0^T Lam`` is linear in ``v`` with the Jacobian ``J``, so
  ``v = v0 + J^-1 G0^T Lam`` (``v0`` the free grid step of :mod:`vcigen.explicit`, ``G0`` the
  active rows' gradients at ``q0``); left are the ``R_A`` equations ``psi_A(q0 + h v(Lam)) = 0``,
  Newton in ``Lam`` with the Jacobian ``h G1 J^-1 G0^T`` (``G1`` at ``q1``), from the previous
  step's multipliers. Rows linear in ``q`` (floors, walls) converge in one step. One active row whose zero set
  is that of a polynomial ``F`` of degree 2 in ``q`` (:func:`line_form`: a circle's, a sphere's, an
  ellipse's row) has ``F(q0 + h v(Lam))`` quadratic in ``Lam``: the step held on it alone is
  closed-form (:func:`closed_forms`,
  :func:`vcigen.held_step.closed_step`, ``held_root``, ``held_root_end``): the quadratic's small root by
  one square root, the projection onto ``grad F(q1)``; no Newton, no evaluation of the row's square root
  on the state's chain; the C loop starts each step's line from the step before's ``p+`` before its
  projection (:func:`vcigen.held_step.closed_carried`: the root absorbs the move along the gradient), so the
  projection is off the state's chain too. Where that quadratic's leading coefficient and the projection's
  ``W`` are constants on the row (a circle's or a sphere's row with an isotropic mass, a rod's) it divides
  by run constants only; else (a quadric's row: an ellipse's, a paraboloid's) they are formed per step.
* ``rattle_project``: ``M u = p+ + G1^T Lam'``, ``G1 u = 0`` is linear in ``Lam'``:
  ``W Lam' = -G1 M^-1 p+`` with the Delassus matrix ``W = G1 M^-1 G1^T``.
* the lift-off check (``SustainedSteps._forces``): ``W lambda = -(G1 M^-1 rhs + curv)`` with the
  same ``W``; ``curv_r = u1 . Hess psi_r(q1) . u1``.

One evaluation of the rows at ``q1`` (``held_rows``: values, gradients, Hessians) serves the
Newton test, the projection, the forces, the crossing test of the inactive rows and their reach
(:func:`vcigen.held_step.idle_near`: one ending within twice the step's move of 0 leaves the step to
the chain, which tests it for a dip inside), and the next step's ``G0``. Every subexpression of
``(h, par)`` alone is hoisted into run constants
(``held_consts``). A step whose end shows an event (a force turning negative, an inactive row
crossed), whose solve does not converge or whose state is not finite is not taken: the general
chain (:mod:`vcigen.sustained`) takes it from the same start. The C loop (``<model>_held_glide``
in ``templates/sustained_held_glide.c.j2``) and :func:`vcigen.held_step.held_step` (the Python stepper's)
are one algorithm.
"""

from __future__ import annotations

from typing import NamedTuple

import sympy as sp

from .derive import DiscreteSystem, _no_dirac
from .explicit import expanded, hoist, shorter, smooth_jacobian
from .held_circle import circle_pieces
from .routines import Arg, Output, Routine

# Routines whose half-integer powers C prints with sqrt (cprinter.print_routine_body): a curved row's Hessian
# holds |q|^-3 as pow(b, 3/2), libm's pow was ~40% of a held step on it (bench bowl). Only the lift-off
# test reads the Hessian, so the step's end (q, p, E_d, multipliers) does not depend on pow's last bit.
SQRT_POWERS = frozenset({"held_rows"})


def row_hessian(system: DiscreteSystem, r: int) -> sp.Matrix:
    """The Hessian of row ``r``'s ``psi`` in ``q``."""
    rows = system.routines["rows"]
    return sp.hessian(rows.output("psi").expr[r], rows.input("q").symbols).applyfunc(_no_dirac)


def line_form(psi: sp.Expr, q: tuple[sp.Symbol, ...]) -> sp.Expr | None:
    """A polynomial ``F`` of degree 2 in ``q`` whose zero set holds ``psi``'s, or ``None``.

    ``psi`` itself if it is one (an ellipse's row, a rod ``x^2 + y^2 - l^2``); ``beta^2 P - alpha^2`` if
    ``psi = alpha + beta sqrt(P)`` with ``alpha``, ``beta`` free of ``q`` and ``P`` a polynomial of degree 2
    in ``q`` (a circle's or a sphere's row ``r - |q - c|``). ``None`` for rows linear in ``q`` (their Newton
    is exact from the previous multipliers) and any other form.
    """
    parts = line_parts(psi, q)
    return None if parts is None else parts[0]


def line_parts(psi: sp.Expr, q: tuple[sp.Symbol, ...]) -> tuple[sp.Expr, sp.Expr] | None:
    """``(F, gain)``: :func:`line_form`'s ``F`` and ``gain = dF/dpsi`` where ``psi = 0`` (free of ``q``):
    1 when ``F`` is ``psi``; ``-2 alpha`` for ``F = beta^2 P - alpha^2`` (``psi = alpha + beta s``,
    ``s = sqrt(P)``: ``dF/dpsi = 2 beta s = 2 (psi - alpha)``). There ``grad F = gain grad psi``.
    ``None`` as ``line_form``."""
    qs = set(q)

    def quadratic(e: sp.Expr) -> bool:
        try:
            poly = sp.Poly(sp.expand(e), *q)
        except sp.PolynomialError:
            return False
        return poly.total_degree() == 2 and not any(c.free_symbols & qs for c in poly.coeffs())

    if quadratic(psi):
        return psi, sp.S.One
    roots = {a for a in psi.atoms(sp.Pow) if a.exp == sp.S.Half and a.base.free_symbols & qs}
    if len(roots) != 1:
        return None
    (root,) = roots
    s = sp.Dummy("s")
    e = sp.expand(psi.xreplace({root: s}))
    if e.free_symbols & qs or e.diff(s, 2) != 0:
        return None
    alpha, beta = e.xreplace({s: sp.S.Zero}), e.diff(s)
    f = beta**2 * root.base - alpha**2  # unexpanded: a circle about c keeps |a - c|^2 (no cancellation)
    return (f, -2 * alpha) if beta != 0 and quadratic(f) else None


class Closed(NamedTuple):
    """A row whose held step has a closed form (:func:`closed_forms`)."""

    form: sp.Expr  # F (line_form), in the rows' q
    gain: sp.Expr  # dF/dpsi on psi = 0 (line_parts): grad F = gain grad psi there
    a0: sp.Expr  # A = |h J^-1 grad F(q)|^2_{Hess F} / 2: on F = 0 if fixed (free of q), else at q (the start)
    w0: sp.Expr  # W = grad F(q) . M^-1 grad F(q): on F = 0 if fixed (free of q), else at q (the end)
    fixed: bool = True  # A, W constants on F = 0 (a sphere's row): no division by the state on the chain
    definite: bool = False  # Hess F definite (an ellipse's row): A far from 0 against B, as on a fixed row


def definite(hf: sp.Matrix) -> bool:
    """Whether the constant symmetric ``hf`` is definite (Sylvester: the leading minors of ``hf`` or of
    ``-hf`` provably positive)."""
    for sign in (1, -1):
        if all(sp.simplify((sign * hf)[:k, :k].det()).is_positive for k in range(1, hf.rows + 1)):
            return True
    return False


def on_surface(e: sp.Expr, f: sp.Expr, q: tuple[sp.Symbol, ...]) -> sp.Expr | None:
    """The value of ``e`` (a polynomial in ``q``) on ``f = 0`` where it is one constant there: ``e - c f`` for
    the ``c`` that removes ``f``'s leading monomial, if that is free of ``q``; else ``None``."""
    try:
        pe, pf = sp.Poly(sp.expand(e), *q), sp.Poly(sp.expand(f), *q)
    except sp.PolynomialError:
        return None
    lead = pf.monoms()[0]
    rest = sp.expand(e - pe.coeff_monomial(lead) / pf.coeff_monomial(lead) * f)
    return None if rest.free_symbols & set(q) else rest


def closed_forms(system: DiscreteSystem) -> list[Closed | None]:
    """Per row, its :class:`Closed` form or ``None``: the rows whose held step, held alone, is closed-form.

    For one active row with a :func:`line_parts` ``(F, gain)``, RATTLE's position step ``q1 = a + Lam b``
    (``a = q0 + h v0``, ``b = h J^-1 grad F(q0)``, a multiple of ``grad psi(q0)``) with ``psi(q1) = 0`` is
    ``F(a + Lam b) = A Lam^2 + B Lam + C = 0``: one square root, no Newton. Where, besides, ``A`` and the
    projection's ``W = grad F . M^-1 grad F`` are constants on ``F = 0`` (``fixed``; ``a0``, ``w0``: a
    sphere's row with an isotropic mass, a rod's), the step divides by no value of the state on its chain
    from ``(q0, p0)`` to ``(q1, p1)``. Else (an ellipse's, a paraboloid's, a circle's with an anisotropic
    mass: a quadric's) ``A`` is formed at the step's start and ``W`` at its end, each divided by once; where
    ``Hess F`` is :func:`definite` the division by ``A`` is off the state's chain (:func:`closed_routines`).
    Needs a constant diagonal ``J`` and ``M`` (``Structure.held``).
    """
    rows = system.routines["rows"]
    q = tuple(rows.input("q").symbols)
    h = system.routines["smooth"].input("tau").symbols[0]
    jac = smooth_jacobian(system)
    mass = expanded(system.routines["legendre"].output("mass").expr)
    out: list[Closed | None] = []
    for psi in rows.output("psi").expr:
        parts = line_parts(sp.sympify(psi), q)
        if parts is None or parts[1] == 0:
            out.append(None)
            continue
        f, gain = parts
        grad = [f.diff(x) for x in q]
        b = [h * g / jac[i, i] for i, g in enumerate(grad)]
        hf = sp.hessian(f, q)
        a_form = sum((b[i] * hf[i, j] * b[j] for i in range(len(q)) for j in range(len(q))), sp.S.Zero) / 2
        w_form = sum((g * g / mass[i, i] for i, g in enumerate(grad)), sp.S.Zero)
        a0, w0 = on_surface(a_form, f, q), on_surface(w_form, f, q)
        fixed = a0 is not None and w0 is not None and a0 != 0 and w0 != 0
        if fixed:
            out.append(Closed(f, gain, sp.simplify(a0), sp.simplify(w0)))
        else:  # a quadric's row: A at the step's start, W at its end
            out.append(Closed(f, gain, a_form, w_form, False, definite(hf)))
    return out


def closed_force(cf: Closed, q: tuple, p1: list, acc: sp.Matrix, minv: sp.Matrix) -> sp.Expr:
    """The normal force of ``SustainedSteps._forces`` on one closed row held alone, at ``q`` with momentum
    ``p1``: ``-gain (grad F . M^-1 rhs + u1 . Hess F . u1) / w0`` (``u1 = M^-1 p1``; equal to it there:
    ``grad psi = grad F / gain``, ``u1 . grad F = 0``)."""
    n = len(q)
    grad, hf = [cf.form.diff(x) for x in q], sp.hessian(cf.form, q)
    u1 = [minv[i] * p1[i] for i in range(n)]
    curv = sum((u1[i] * hf[i, j] * u1[j] for i in range(n) for j in range(n) if hf[i, j] != 0), sp.S.Zero)
    return -cf.gain * (sum((grad[i] * acc[i] for i in range(n)), sp.S.Zero) + curv) / cf.w0


def closed_routines(
    system: DiscreteSystem,
    q0: Arg,
    p0: Arg,
    q: Arg,
    v0: sp.Matrix,
    jinv: sp.Matrix,
    acc: sp.Matrix,
    minv: sp.Matrix,
    h: sp.Symbol,
) -> list[tuple]:
    """The pieces of the closed held step (:func:`closed_forms`), per row (zeros for rows without one), with
    ``b = h J^-1 grad F(q0)``, ``a = q0 + h v0`` and ``F(a + Lam b) = a0 Lam^2 + B Lam + C``:

    * ``held_root_dir(q, k) -> m, e, f, s, y, w, a2, g, iw``: what the step needs of ``grad F`` at ``q`` (at
      the step's start: ``m = Hess F b``, ``s = grad F(0) . b``, so that ``B = m . a + s``; ``e = b / (2
      a0)``, ``f = J^-1 grad F / (2 a0)``, ``g = gain / (2 a0)``; a quadric's ``a2 = 2 A = b . Hess F . b``
      (0 for a fixed row); at its end: ``y = M^-1 grad F``, ``iw = 1 / w0``, ``w = -grad F iw``). Its own
      routine, so that these per-coordinate factors are products off the state's chain and the chain
      multiplies each by one value (one routine would share a common factor and add a product to the chain);
    * ``held_root(q0, p0, m, s, a2, k) -> v0, a, nu, slope, disc``: the free velocity ``v0``, the line's
      start ``a = q0 + h v0`` and per row, in ``nu = 2 a0 Lam``, the small root of ``nu^2 + 2 B nu + 4 a0 C
      = 0``: ``D = B^2 - 4 a0 C``, ``nu = sqrt(D) - B`` (one ``sqrt``, no division: ``a0`` is a run
      constant); ``slope = B`` (> 0 for the small root) and ``disc = D`` (>= 0) say whether it holds. Its
      readers (:func:`vcigen.held_step.closed_step`, C ``<model>_held_closed_one``) form ``q1 = a + nu e``,
      ``v = v0 + nu f`` and ``lam = g nu`` (the multiplier of ``psi``: ``grad F = gain grad psi``) from the
      one ``nu``: ``psi(q1) = 0`` fixes ``Lam`` only to the rounding of ``q1`` (``eps |q1| / h`` in ``v``,
      as for the Newton; ``nu``'s cancellation stays within that), and the projection's ``Lam'`` takes it
      back, so the impulse ``Lam + Lam'`` the step books is exact to round-off only if ``lam`` is the root
      that moved ``v``. Formed in one routine, CSE may round ``nu`` twice (a rational in ``B``, as
      ``p / 3`` under a mass 3, gave ``v`` and ``lam`` ``nu`` from ``3 B / 3`` and from ``B``). A quadric's
      row (not ``fixed``) reads its ``A`` from ``a2``: where ``Hess F`` is definite, as a fixed row (``e``,
      ``f``, ``g`` divided by ``2 A`` at ``q0``, off the chain); else ``e = b``, ``f = J^-1 grad F``, ``g =
      gain`` and ``nu = Lam = -2C / (B + sqrt(D))``: no cancellation where ``A`` is small against ``B`` (a
      paraboloid's vertex, where ``A = 0``), one division on the chain;
    * ``held_root_end(q1, p_plus, y, w, iw, k) -> p1, lam1, force, res``: rattle_project onto ``grad
      F(q1)``, ``p1 = p+ + w (y . p+)``, ``lam1 = gain Lam'``; the force ``-gain (grad F . M^-1 rhs + u1 .
      Hess F . u1) iw`` (that of ``SustainedSteps._forces``: ``grad psi = grad F / gain``, ``u1 . grad F =
      0``); ``res = F(q1) / gain`` (``psi(q1)`` to first order). A quadric's ``1 / W(q1)`` is
      ``held_root_dir``'s one division, which ``w``, ``lam1`` and the force share (before, ``held_root_end``
      divided by ``W(q1)`` a second time); a fixed row's ``1 / w0`` is a run constant.
    """
    n, nr = system.n, system.r
    forms = system.structure.held_closed_forms

    def arg(name: str, size: int) -> Arg:
        return Arg(name, tuple(sp.Dummy(f"{name}{i}", real=True) for i in range(size)))

    pp = arg("p_plus", n)
    m_, s_ = arg("m", nr * n), arg("s", nr)
    y_, w_, a2_, iw_ = arg("y", nr * n), arg("w", nr * n), arg("a2", nr), arg("iw", nr)
    dirs = {name: sp.zeros(nr, n) for name in ("m", "e", "f", "y", "w")}
    dirs["s"], dirs["a2"], dirs["g"], dirs["iw"] = (sp.zeros(nr, 1) for _ in range(4))
    p1 = sp.zeros(nr, n)
    nus, slope, disc, lam1, force, res = (sp.zeros(nr, 1) for _ in range(6))
    a = [q0.symbols[i] + h * v0[i] for i in range(n)]  # the line's start
    zero = dict.fromkeys(q.symbols, sp.S.Zero)
    for r, cf in enumerate(forms):
        if cf is None:
            continue
        f, gain, a0, w0 = cf.form, cf.gain, cf.a0, cf.w0
        grad = [f.diff(x) for x in q.symbols]
        hf = sp.hessian(f, q.symbols)
        b = [h * jinv[i] * grad[i] for i in range(n)]  # at the direction routine's q (q0 of the step)
        nu_form = cf.fixed or cf.definite  # e, f in nu = 2 A Lam; else (stable) in Lam
        scale = 2 * a0 if nu_form else sp.S.One
        if not cf.fixed:
            dirs["a2"][r] = 2 * a0  # 2 A at q: b . Hess F . b
        dirs["g"][r] = gain / scale  # lam = g nu
        for i in range(n):
            dirs["m"][r, i] = sum((hf[i, j] * b[j] for j in range(n)), sp.S.Zero)  # grad F(a) . b = m . a + s
            dirs["e"][r, i] = b[i] / scale
            dirs["f"][r, i] = jinv[i] * grad[i] / scale
            dirs["y"][r, i] = grad[i] * minv[i]  # at q1 of the step: the projection's
            dirs["w"][r, i] = -grad[i] / w0
        dirs["s"][r] = sum((g.xreplace(zero) * b[i] for i, g in enumerate(grad)), sp.S.Zero)
        at = r * n
        # grad F(0) . b: 0 for a quadric centred at the origin, whose B then adds nothing to the chain (an add
        # of +0.0 the compiler must keep: it turns -0.0 into +0.0)
        s0 = s_.symbols[r] if dirs["s"][r] != 0 else sp.S.Zero
        big_b = sum((m_.symbols[at + i] * a[i] for i in range(n)), s0)
        big_c = f.xreplace(dict(zip(q.symbols, a)))
        two_a = 2 * a0 if cf.fixed else a2_.symbols[r]  # 2 A: a run constant, or the step's start's
        # in nu = 2 A Lam: nu^2 + 2 B nu + 4 A C = 0, D = B^2 - 4 A C
        d = big_b**2 - 2 * two_a * big_c
        if nu_form:  # its small root nu = sqrt(D) - B: no division on the chain (1 / A is formed at q0)
            nu = sp.sqrt(d) - big_b
        else:  # Lam = -2C / (B + sqrt(D)): no cancellation where A is small (a paraboloid's vertex: 0)
            nu = -2 * big_c / (big_b + sp.sqrt(d))
        nus[r] = nu
        slope[r], disc[r] = big_b, d
        dot = sum((y_.symbols[at + i] * pp.symbols[i] for i in range(n)), sp.S.Zero)
        for i in range(n):
            p1[r, i] = pp.symbols[i] + w_.symbols[at + i] * dot
        dirs["iw"][r] = 1 / w0
        iw = 1 / w0 if cf.fixed else iw_.symbols[r]  # 1 / W(q1): divided once, in held_root_dir
        force[r] = closed_force(cf._replace(w0=1 / iw), q.symbols, [p1[r, i] for i in range(n)], acc, minv)
        lam1[r] = -gain * iw * dot
        res[r] = f / gain
    return [
        (
            "held_root_dir",
            (q,),
            [(name, dirs[name]) for name in ("m", "e", "f", "s", "y", "w", "a2", "g", "iw")],
            "Per closed row, what its held step needs of grad F at q (held.closed_routines).",
        ),
        (
            "held_root",
            (q0, p0, m_, s_, a2_),
            [("v0", v0), ("a", sp.Matrix(a)), ("nu", nus), ("slope", slope), ("disc", disc)],
            "The closed held step's root on each closed row (held.closed_forms): v0, a, nu, B, D.",
        ),
        (
            "held_root_end",
            (q, pp, y_, w_, iw_),
            [("p1", p1), ("lam1", lam1), ("force", force), ("res", res)],
            "Its projection (p1, Lam'), force and residual F(q1)/gain.",
        ),
    ]


def free_parts(system: DiscreteSystem) -> dict:
    """What the held step reads of the free grid step, as expressions: the smooth routine's inputs
    (``q0_arg``, ``p0_arg``, ``tau``, ``par``; ``h``), ``v0`` and ``jinv`` (the free velocity of (46) over
    ``h`` and ``1/J_ii``), the segment's ``p_plus`` (51) and ``energy`` (55) at ``(q0, v)`` (``v_arg``), and
    at the rows' ``q`` (``q_arg``, ``q0`` its symbols) the constant ``mass``, ``minv`` and the free
    acceleration ``acc = M^-1 rhs(q)``. Needs a constant diagonal ``J`` and ``M`` (``Structure.held``)."""
    r = system.routines
    smooth = r["smooth"]
    xs, q0, p0, tau, par = smooth.inputs
    h = tau.symbols[0]
    n = system.n
    zero = dict.fromkeys(xs.symbols, sp.S.Zero)
    res, jac = smooth.output("res").expr, smooth_jacobian(system)
    v0 = sp.Matrix([-res[i].xreplace(zero) / jac[i, i] for i in range(n)])
    jinv = sp.Matrix([1 / jac[i, i] for i in range(n)])
    rows = r["rows"]
    q = Arg("q", tuple(rows.input("q").symbols))
    seg = r["segment"]
    v = Arg("v", tuple(seg.input("v").symbols))
    seg_rep = dict(zip(seg.input("q0").symbols, q0.symbols)) | {seg.input("tau").symbols[0]: h}
    p_plus = seg.output("p_plus").expr.xreplace(seg_rep)
    energy = shorter(seg.output("energy").expr[0]).xreplace(seg_rep)
    dyn, leg = r["dynamics"], r["legendre"]
    u0 = dict.fromkeys(dyn.input("u").symbols, sp.S.Zero)
    rhs = dyn.output("rhs").expr.xreplace(u0).xreplace(dict(zip(dyn.input("q").symbols, q.symbols)))
    mass = expanded(leg.output("mass").expr)
    minv = sp.Matrix([1 / mass[i, i] for i in range(n)])
    acc = sp.Matrix([rhs[i] * minv[i] for i in range(n)])
    return {
        "q0_arg": q0, "p0_arg": p0, "tau": tau, "par": par, "h": h, "q_arg": q, "v_arg": v, "q0": q0.symbols,
        "v0": v0, "jinv": jinv, "p_plus": p_plus, "energy": energy, "mass": mass, "minv": minv, "acc": acc,
    }  # fmt: skip


def held_routines(system: DiscreteSystem) -> list[Routine]:
    """``held_consts(tau, par) -> k`` and the four pieces of the held step, all reading ``k``:

    * ``held_free(q0, p0, k) -> v0, jinv``: the free velocity of (46) over ``h`` and ``1/J_ii``;
    * ``held_rows(q, k) -> psi, grad, hess``: every row's value, gradient and the entries of its Hessian
      on ``system.structure.held_pattern`` (the curvature ``u . Hess psi . u`` needs no others);
    * ``held_segment(q0, v, k) -> p_plus, energy``: ``p+`` (51) and ``E_d`` (55) of the segment;
    * ``held_end(q1, k) -> acc, minv``: ``M^-1 rhs(q1)`` (the free acceleration) and ``1/M_ii``;
    * if some row has a :func:`closed_forms` form, ``held_root_dir``, ``held_root`` and ``held_root_end``
      (:func:`closed_routines`);
    * if some row's closed step is a rotation (:func:`vcigen.held_circle.circle_forms`),
      ``held_circle_start``, ``held_circle_step`` and ``held_circle_lam``
      (:func:`vcigen.held_circle.circle_pieces`).
    """
    fp = free_parts(system)
    q0, p0, tau, par, q, v = (fp[k] for k in ("q0_arg", "p0_arg", "tau", "par", "q_arg", "v_arg"))
    h = fp["h"]
    v0, jinv, p_plus, energy, acc, minv = (fp[k] for k in ("v0", "jinv", "p_plus", "energy", "acc", "minv"))
    rows = system.routines["rows"]
    psi = rows.output("psi").expr
    grad = rows.output("grad").expr
    pattern = system.structure.held_pattern
    hess = sp.Matrix(
        system.r,
        len(pattern),
        [row_hessian(system, r)[i, j] for r in range(system.r) for i, j, _ in pattern],
    )
    pieces = [
        ("held_free", (q0, p0), [("v0", v0), ("jinv", jinv)], "Free velocity of (46) over h and 1/J_ii."),
        ("held_rows", (q,), [("psi", psi), ("grad", grad), ("hess", hess)], "Rows, gradients, Hessians."),
        (
            "held_segment",
            (q0, v),
            [("p_plus", p_plus), ("energy", sp.Matrix([energy]))],
            "p+ (51), E_d (55).",
        ),
        ("held_end", (q,), [("acc", acc), ("minv", minv)], "M^-1 rhs(q) and 1/M_ii."),
    ]
    if any(system.structure.held_closed):
        pieces += closed_routines(system, q0, p0, q, v0, jinv, acc, minv, h)
    if any(system.structure.held_circle):
        pieces += circle_pieces(system, list(system.structure.held_circle_forms), fp, p0)
    flat = [e for _, _, outs, _ in pieces for _, o in outs for e in o]
    varying = {*q0.symbols, *p0.symbols, *q.symbols, *v.symbols}
    varying |= {x for _, ins, _, _ in pieces for arg in ins for x in arg.symbols}
    consts, reduced = hoist(flat, varying)
    ks = Arg("k", tuple(k for k, _ in consts))
    out = [
        Routine(
            "held_consts",
            (tau, par),
            (Output("k", sp.Matrix([e for _, e in consts]) if consts else sp.zeros(1, 1)),),
            "Run constants of the held step: its subexpressions of (h, par) alone.",
        )
    ]
    i = 0
    for name, ins, outs, doc in pieces:
        made = []
        for oname, o in outs:
            made.append(Output(oname, sp.Matrix(o.rows, o.cols, reduced[i : i + len(o)])))
            i += len(o)
        out.append(Routine(name, (*ins, ks), tuple(made), doc))
    return out
