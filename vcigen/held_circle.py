"""The held step on a circle as a rotation: the closed held step (:func:`vcigen.held.closed_forms`) of a row
whose zero set is a circle in the plane, under a force affine in ``q``, with one multiplication on its chain.

Where it applies (:func:`circle_forms`, detected once in :mod:`vcigen.structure`): two coordinates, an
isotropic constant mass ``m`` (``J = M``), the row's ``F`` a circle of radius ``R`` about ``c``, the free
velocity ``v0 = (p0 + c_v) / m`` and the segment's momentum ``p+ = m v + c_p`` with ``c_v`` affine in
``q0`` and ``c_p`` in ``(q0, v)``, free of ``p`` (a force affine in ``q``: gravity, springs). Then, with
``n = (q - c) / R``, ``t = (-n_y, n_x)`` and ``omega = t . v0`` (MATH.md *Sustained contact*, the RATTLE
step held on the row):

* the position step is a rotation, ``n1 = s n + a t`` with ``a = h omega / R``, ``s = sqrt(arg)``,
  ``arg = 1 / |n|^2 - a^2`` (``z1 = z (s + i a)``: ``|n1| = 1`` and ``n1 - n`` along ``v0``'s tangential
  part; the small root of the closed step's quadratic, ``B > 0`` being ``R |n|^2 + h v0 . n > 0``);
* the projection of ``p+`` onto the tangent at ``q1`` is ``p1 = pi1 t1``, ``pi1 = m omega + c_p . t1``
  (``v . t1 = omega`` on the circle; ``c_p`` of the segment from ``q0`` to ``q1``);
* the next ``omega1 = t1 . v0(q1, p1) = omega + (c_p + c_v(q1)) . t1 / m``, a polynomial in ``s`` (``q1`` is
  affine in ``s``), is ``o0 + o1 s`` once ``s^2 = arg`` is taken off (a force constant in ``q``:
  ``o0 = omega - a g . d / R``, ``o1 = g . (-d_y, d_x) / R``, ``g = (c_v + c_p) / m``), so the next argument
  ``1 / |n1|^2 - (h omega1 / R)^2`` is ``A + B s`` (``s^2 = arg``, ``|n1|^2 = |n|^2 (arg + a^2)``,
  ``1 / x = 2 - x`` to ``O((x - 1)^2)``): formed off the chain, the chain from one ``sqrt`` to the next is
  one multiply-add (the C loop carries ``(omega, arg)`` from step to step; :class:`Carry` here);
* the impulse ``Lam + Lam'`` from the momentum change ``J = p1 - p0 - c_v - c_p = gamma (Lam n + Lam' n1)``
  (``grad psi = gamma n`` on the row) along ``n + n1``: ``n . (n + n1) = n1 . (n + n1) = 1 + s``; ``Lam``
  from ``m (v - v0) = gamma Lam n``;
* ``E_d`` (``held_segment``'s), the normal force and the residual ``F(q1) / gain`` (``held_root_end``'s) and
  the tests are the closed step's; the first three, with the impulse, are written in the end's own symbols
  (``held_circle_end``: in ``q1``, ``p1``, not in the rotation, where SymPy expands them) and the force with
  ``|q1 - c| = R`` (``|p1|^2 = pt^2 R^2``): about 40 products a step, 55 before (``bench.held_curved``).

The same RATTLE solution to round-off as :func:`vcigen.held_step.closed_step` (``bench.held_rot``:
``q`` <= 4e-15, ``p`` <= 1e-14 over 300 steps). The C loop is ``<model>_held_circle_loop``
(``templates/sustained_held_circle.c.j2``); :func:`circle_step` is the Python stepper's. A run recording
the tangent takes the closed step (its tangent reads that step's ``Lam``).
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np
import sympy as sp

from .routines import Arg


class Circle(NamedTuple):
    """A row whose held step is a rotation (:func:`circle_forms`)."""

    centre: tuple[sp.Expr, sp.Expr]
    radius: sp.Expr
    mass: sp.Expr
    cv: tuple[sp.Expr, sp.Expr]  # v0 = (p0 + cv) / m
    cp: tuple[sp.Expr, sp.Expr]  # p+ = m v + cp
    gamma: sp.Expr  # grad psi = gamma n on the row


def _affine(e: sp.Expr, of: tuple, others: set) -> bool:
    """Whether ``e`` is free of ``others`` and a polynomial of degree <= 1 in ``of``."""
    if e.free_symbols & others or not e.is_polynomial(*of):
        return False
    return sp.Poly(e, *of).total_degree() <= 1 if e.free_symbols & set(of) else True


def circle_forms(closed: list, q: tuple, p0: tuple, v: tuple, free: dict) -> list[Circle | None]:
    """Per row, its :class:`Circle` or ``None``: rows with a closed form (``closed``, :func:`closed_forms`)
    whose zero set is a circle, in a scene with two coordinates, an isotropic mass with ``J = M`` and a force
    affine in ``q`` (gravity, springs): ``c_v`` affine in ``q0``, ``c_p`` in ``(q0, v)``, the free
    acceleration in ``q``. ``free``: ``vcigen.held.free_parts`` (``v0``, ``jinv``, ``p_plus``, ``mass``,
    ``acc``)."""
    if len(q) != 2:
        return [None] * len(closed)
    v0, jinv, p_plus, mass, acc = (free[k] for k in ("v0", "jinv", "p_plus", "mass", "acc"))
    m = mass[0, 0]
    q0 = tuple(free["q0"])
    ok = sp.simplify(mass[1, 1] - m) == 0 and all(sp.simplify(m * jinv[i] - 1) == 0 for i in range(2))
    cv = [sp.simplify(m * v0[i] - p0[i]) for i in range(2)]
    cp = [sp.simplify(p_plus[i] - m * v[i]) for i in range(2)]
    ok = ok and all(_affine(e, q0, {*q, *p0, *v}) for e in cv)
    ok = ok and all(_affine(e, (*q0, *v), {*q, *p0}) for e in cp)
    ok = ok and all(_affine(e, tuple(q), {*q0, *p0, *v}) for e in acc)
    out: list[Circle | None] = []
    for cf in closed:
        if cf is None or not cf.fixed or not ok:
            out.append(None)
            continue
        poly = sp.Poly(sp.expand(cf.form), *q)
        kappa = poly.coeff_monomial(q[0] ** 2)
        if sp.simplify(poly.coeff_monomial(q[1] ** 2) - kappa) != 0 or poly.coeff_monomial(q[0] * q[1]) != 0:
            out.append(None)
            continue
        centre = tuple(sp.simplify(-poly.coeff_monomial(x) / (2 * kappa)) for x in q)
        r2 = sp.simplify(centre[0] ** 2 + centre[1] ** 2 - poly.coeff_monomial(1) / kappa)
        radius = sp.sqrt(r2)
        gamma = sp.simplify(2 * kappa * radius / cf.gain)  # grad F = 2 kappa R n = gain grad psi
        out.append(Circle(centre, radius, m, (cv[0], cv[1]), (cp[0], cp[1]), gamma))
    return out


def circle_energy(energy: sp.Expr, q0: tuple, v: tuple, q1: tuple, h: sp.Symbol) -> sp.Expr:
    """``E_d`` (55) of a segment (``energy`` at ``(q0, v)``, quadratic in ``v``) at ``v = (q1 - q0) / h``, in
    ``q1``'s own symbols: ``c |q1 - q0|^2 / h^2`` (an isotropic mass: one factor over the sum) plus the rest,
    in ``q0`` and ``q1``, its common factor taken out (the bowl's potential ``g (y0 + y1) / 2`` is one
    product, not three)."""
    poly = sp.Poly(energy, *v)
    quad = [poly.coeff_monomial(v[i] * v[j]) for i in range(2) for j in range(i, 2)]
    seg = {v[i]: (q1[i] - q0[i]) / h for i in range(2)}
    if quad[1] != 0 or sp.simplify(quad[0] - quad[2]) != 0:
        return energy.xreplace(seg)
    rest = sp.expand((energy - quad[0] * (v[0] ** 2 + v[1] ** 2)).xreplace(seg))
    squares = sp.Add(*((q1[i] - q0[i]) ** 2 for i in range(2)))
    return sp.Mul(quad[0] / h**2, squares, evaluate=False) + sp.factor_terms(rest)


def circle_pieces(system, circles: list[Circle | None], fp: dict, p_arg) -> list[tuple]:
    """The routines of the rotation step (pieces of ``vcigen.held.held_routines``; ``fp``:
    ``vcigen.held.free_parts``), per row (zeros for rows without one), on the state ``(q, p)`` (``q0_arg``,
    ``p_arg``) and the carried ``w = (omega, arg)``:

    * ``held_circle_start(q, p, k) -> w``: ``(omega, arg)`` formed from the state (a loop's entry);
    * ``held_circle_step(q, p, w, s, k) -> q1, p1, pt, w1, slope``: the rotation
      (:mod:`vcigen.held_circle`'s docstring) with ``s = sqrt(arg)``, ``p1 = pt (-D1_y, D1_x)``,
      ``w1 = (o0, o1, a0, a1)``: the next ``w`` is ``(o0 + o1 s, a0 + a1 s)``, and
      ``slope = |d|^2 + h v0 . d`` (> 0: the small root holds, ``B > 0``);
    * ``held_circle_end(q, p, q1, p1, e, k) -> imp, energy, force, res`` with ``e = (pt, s)``: the impulse
      ``(Lam + Lam') / h``, ``E_d`` (55), the closed step's normal force (``held_root_end``'s at
      ``u1 = M^-1 p1``, with ``|q1 - c| = R``: ``|p1|^2 = pt^2 R^2``) and its residual ``F(q1) / gain``, all
      in ``q1`` and ``p1``'s own symbols (its own routine: written in them, each is a few products; in the
      rotation's symbols SymPy expands them);
    * ``held_circle_lam(q, p, v, k) -> lam``: ``Lam`` of a step from its velocity
      (``m (v - v0) = gamma Lam n``).
    """
    from .held import closed_force  # held imports this module

    nr = system.r
    q0, h = fp["q0_arg"], fp["h"]
    x, y = q0.symbols
    px, py = p_arg.symbols
    w_arg = Arg("w", (sp.Dummy("om", real=True), sp.Dummy("arg", real=True)))
    s_arg = Arg("s", (sp.Dummy("s", real=True),))
    v_arg = Arg("v", tuple(sp.Dummy(f"v{i}", real=True) for i in range(2)))
    q1_arg = Arg("q1", tuple(sp.Dummy(f"q1_{i}", real=True) for i in range(2)))
    p1_arg = Arg("p1", tuple(sp.Dummy(f"p1_{i}", real=True) for i in range(2)))
    e_arg = Arg("e", (sp.Dummy("pt", real=True), sp.Dummy("s", real=True)))
    om, arg = w_arg.symbols
    qs = fp["q_arg"].symbols
    outs = {k: sp.zeros(nr, size) for k, size in (("w", 2), ("q1", 2), ("p1", 2), ("w1", 4))}
    outs |= {k: sp.zeros(nr, 1) for k in ("pt", "imp", "energy", "force", "res", "slope", "lam")}
    forms = system.structure.held_closed_forms
    for r, c in enumerate(circles):
        if c is None:
            continue
        f, gain = forms[r].form, forms[r].gain
        (cx, cy), big_r, m, (cvx, cvy), (cpx, cpy), gamma = c
        # in d = q - c and D1 = q1 - c (R n, R n1): each a common subexpression of its uses, no sign or factor
        # distributed into it (sympy distributes -1 * (a + b)), so that CSE shares them
        dx, dy = x - cx, y - cy
        v0x, v0y = (px + cvx) / m, (py + cvy) / m  # c_v at q0
        om0 = (v0y * dx - v0x * dy) / big_r
        nn = (dx**2 + dy**2) / big_r**2
        outs["w"][r, 0], outs["w"][r, 1] = om0, 1 / nn - (h * om0 / big_r) ** 2
        a, sq = h * om / big_r, s_arg.symbols[0]
        d1x, d1y = sq * dx - a * dy, sq * dy + a * dx
        seg = dict(zip(fp["v_arg"].symbols, ((d1x - dx) / h, (d1y - dy) / h)))
        cp1x, cp1y = cpx.xreplace(seg), cpy.xreplace(seg)  # c_p of the segment to q1
        pi1 = (m * om + (cp1y * d1x - cp1x * d1y) / big_r) / big_r  # pi1 / R: p1 = (pi1 / R) (-D1y, D1x)
        # the next omega = t1 . v0(q1, p1) = (t1 . p+ + t1 . c_v(q1)) / m, a polynomial in s (the force affine
        # in q): reduced by s^2 = arg to o0 + o1 s (a force constant in q: o0 = omega - a g . d / R,
        # o1 = (g_y d_x - g_x d_y) / R, g = (c_v + c_p) / m)
        at_q1 = {x: cx + d1x, y: cy + d1y}
        cv1x, cv1y = cvx.xreplace(at_q1), cvy.xreplace(at_q1)
        om1 = om + ((cp1y + cv1y) * d1x - (cp1x + cv1x) * d1y) / (big_r * m)
        c0, c1, c2 = (sp.Poly(sp.expand(om1), sq).all_coeffs()[::-1] + [sp.S.Zero] * 3)[:3]
        o0, o1 = sp.collect(sp.expand(c0 + c2 * arg), om), sp.collect(sp.expand(c1), om)
        ho0, ho1 = h * o0 / big_r, h * o1 / big_r
        outs["q1"][r, 0], outs["q1"][r, 1] = cx + d1x, cy + d1y
        outs["p1"][r, 0], outs["p1"][r, 1] = sp.Mul(-1, pi1, d1y, evaluate=False), pi1 * d1x
        outs["pt"][r] = pi1
        # the next (omega, arg) = (o0 + o1 s, a0 + a1 s): s^2 = arg taken off; the loop forms them (its chain
        # from one sqrt to the next is then one multiply-add)
        w1 = (o0, o1, (2 - nn * (arg + a**2) - ho1**2 * arg) - ho0**2, -2 * ho0 * ho1)
        for i in range(4):
            outs["w1"][r, i] = w1[i]
        outs["slope"][r] = dx**2 + dy**2 + h * (v0x * dx + v0y * dy)
        # the end, in q1 = (X, Y), p1 and e = (pt, s)
        (bx, by), (qx, qy), (pt, se) = q1_arg.symbols, p1_arg.symbols, e_arg.symbols
        ex, ey = bx - cx, by - cy
        seg_end = dict(zip(fp["v_arg"].symbols, ((bx - x) / h, (by - y) / h)))
        jx, jy = qx - px - cvx - cpx.xreplace(seg_end), qy - py - cvy - cpy.xreplace(seg_end)
        outs["imp"][r] = (jx * (dx + ex) + jy * (dy + ey)) / (big_r * gamma * (1 + se)) / h
        outs["energy"][r] = circle_energy(fp["energy"], (x, y), fp["v_arg"].symbols, (bx, by), h)
        # the force with p1 = pt (-D1y, D1x) and |D1|^2 = R^2 (the row): pt^2 R^2 for |p1|^2
        ux, uy = sp.Dummy("ux"), sp.Dummy("uy")
        force = closed_force(forms[r], qs, [-pt * uy, pt * ux], fp["acc"], fp["minv"])
        force = sp.expand(force.xreplace({qs[0]: cx + ux, qs[1]: cy + uy}))
        force = sp.rem(force, ux**2 + uy**2 - big_r**2, ux)
        outs["force"][r] = sp.factor_terms(sp.expand(force.xreplace({ux: ex, uy: ey})))
        outs["res"][r] = (f / gain).xreplace(dict(zip(qs, (bx, by))))
        vx, vy = v_arg.symbols
        outs["lam"][r] = m * ((vx - v0x) * dx + (vy - v0y) * dy) / (big_r * gamma)
    step = ("q1", "p1", "pt", "w1", "slope")
    end = ("imp", "energy", "force", "res")
    return [
        ("held_circle_start", (q0, p_arg), [("w", outs["w"])], "Per circle row, (omega, arg) at (q, p)."),
        (
            "held_circle_step",
            (q0, p_arg, w_arg, s_arg),
            [(k, outs[k]) for k in step],
            "Per circle row, the held step as a rotation (vcigen.held_circle).",
        ),
        (
            "held_circle_end",
            (q0, p_arg, q1_arg, p1_arg, e_arg),
            [(k, outs[k]) for k in end],
            "Per circle row, the rotation step's impulse, E_d, force and residual at its end.",
        ),
        ("held_circle_lam", (q0, p_arg, v_arg), [("lam", outs["lam"])], "Per circle row, Lam of a step."),
    ]


class Carry(NamedTuple):
    """What a rotation step hands the next (the C loop's ``w``), with the state, step and parameters it
    belongs to (:class:`vcigen.held_step.HeldSteps` uses it only from those)."""

    q: np.ndarray
    p: np.ndarray
    h: float
    par: np.ndarray
    w: np.ndarray  # (omega, arg); a closed step's (p+, Lam') (vcigen.held_step.closed_carried)
    row: int = -1  # the row held (HeldSteps hands it on only to a step on the same row)

    def at(self, q, p, h: float, par) -> np.ndarray | None:
        """``w`` if this carry belongs to ``(q, p, h, par)``, else ``None`` (the step forms its own)."""
        same = self.h == h and np.array_equal(self.par, par)
        return self.w if same and np.array_equal(self.q, q) and np.array_equal(self.p, p) else None


def circle_step(k, q, p, w, row: int, act, h: float, residual: float, phi_tol: float):
    """The rotation step from ``(q, p)`` on row ``row`` held alone, on CasADi's kernels (C:
    ``<model>_held_circle_one``, the body of ``<model>_held_circle_loop``, on the same routines):
    ``(Held, w1)`` with ``w1`` the next step's ``(omega, arg)``, or ``None`` where the closed step's tests
    refuse it (``B <= 0``, ``D < 0``, the residual, a lift-off, an inactive row crossed, a value not finite).
    ``w``: the previous rotation step's ``w1`` (the C loop carries it), or ``None``: formed here."""
    from .held_step import Held, one_row_clears

    kc = k.held_consts(h)
    if w is None:
        w = k.held_circle_start(q, p, kc)[row]
    if not w[1] >= 0.0:
        return None  # D < 0
    s = math.sqrt(w[1])
    q1, p1, pt, w1, slope = (x[row] for x in k.held_circle_step(q, p, w, [s], kc))
    if not slope > 0.0:
        return None  # the small root does not hold (B <= 0)
    imp, energy, force, res = (x[row] for x in k.held_circle_end(q, p, q1, p1, [pt, s], kc))
    v = (q1 - q) / h
    if not one_row_clears(
        k, kc, row, act, q, p, q1, p1, float(energy), float(force), float(res), residual, phi_tol
    ):
        return None
    lam, lam1 = np.zeros(k.r), np.zeros(k.r)
    lam[row] = k.held_circle_lam(q, p, v, kc)[row]
    lam1[row] = imp * h - lam[row]
    return Held(q1, p1, v, lam, lam1, float(energy)), np.array([w1[0] + w1[1] * s, w1[2] + w1[3] * s])
