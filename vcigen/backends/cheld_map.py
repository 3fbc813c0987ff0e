"""The tangent of a held grid step as one straight-line routine per active set (C sensitivity variant).

A held grid step with its active set ``A`` unchanged (MATH.md *Sustained contact*; ``Tracker.held`` in
:mod:`vcigen.sensitivity`, ``<model>_sens_held`` in ``templates/sens_held.c.j2``) maps ``S_k`` to ``S_k+1`` by
two implicit-function theorems and a chain:

* ``rattle`` at ``x = (v, Lam_A)`` given ``(q, p, par)`` (``tau`` and the active set fixed, ``Lam`` off ``A``
  fixed at 0): ``dx = -F_x^-1 (F_q dq + F_p dp + F_par dpar)``;
* ``q1 = q + tau v``, ``p+ = p+(q, v, tau)`` (``d_segment``);
* ``rattle_project`` at ``y = (u1, Lam'_A)`` given ``(q1, p+, par)``: ``dy = -F_y^-1 (...)``;
* ``p_k+1 = dL/dqdot(q1, u1)`` (``d_legendre``).

The numeric path evaluates the ``d_*`` routines, LU-factors ``F_x`` and ``F_y`` (``n + R`` square) and chains
``K``-column products at run time. For a given active set every piece is a known SymPy expression, so here the
map is built once symbolically, in three straight-line routines (``templates/sens_held_map.c.j2`` calls them):

* ``sens_held_atoms_<key>(q, p, tau, v, lam, lam1, u1, par) -> a``: the entries of the partials (``jac`` and
  ``d_*`` of ``rattle`` and ``rattle_project``, ``d_segment``'s ``dp+``, ``d_legendre``'s ``dmom``) that
  depend on the state, each distinct one a symbol (:class:`_Atoms`); entries of ``(tau, par)`` alone stay
  expressions, numbers stay numbers (a constant mass, a flat row's gradient);
* ``sens_held_phi_<key>(a, tau, par) -> f``: ``Phi = d(q1, p1)/d(q, p, params)`` (``2n x (2n + P)``), each
  ``F`` solved by its blocks -- the momentum block ``F_11`` (``n x n``, ``dp-/dv`` or ``M``: a division per
  row when diagonal, else adjugate over determinant) and the Schur complement ``F_22 - F_21 F_11^-1 F_12`` on
  the active rows (``R_A x R_A``, adjugate over determinant); the entries that are identically 0 or 1 found at
  generation (:func:`_settled`), the others that read ``a`` in ``f``;
* ``sens_held_map_<key>(f, tau, par, s) -> s1``: ``S_k+1 = Phi (S_k; 0 I_P)`` with Phi's zeros and ones left
  out (``s``, ``s1``: ``2n x K`` row-major).

So the run-time cost is that of the map's nonzero structure: the slide on a floor (one flat row, unit mass) is
``dq1 = dq + tau dp`` on ``x``, ``0`` on ``y``, ``dp1 = dp`` on ``x``, ``0`` on ``y``. The inactive rows'
multipliers never enter. A singular ``F`` shows as a non-finite ``s1``: the caller then runs the numeric path,
which decides (and names) the break.

Built for active sets of one or two rows (``ccontext.held_sets``: the keys of the held glide's per-set loops),
at most :data:`HELD_MAP_N` coordinates, on scenes with the held glide (:func:`held_maps`).
"""

from __future__ import annotations

import random
from typing import NamedTuple

import sympy as sp

from ..derive import DiscreteSystem
from ..explicit import expanded
from ..routines import Arg, Output, Routine

DPS = 60  # digits of the evaluations of _settled_on_states
HELD_MAP_N = 3  # coordinates at most for a held step's tangent as straight-line routines
HELD_MAP_ARGS = ("q", "p", "tau", "v", "lam", "lam1", "u1", "par", "s")


def is_held_map(name: str) -> bool:
    """Whether routine ``name`` is one of a :class:`HeldMap`'s (printed with plain CSE: ``cprinter``)."""
    return name.startswith("sens_held_")


def _inverse(a: sp.Matrix) -> sp.Matrix:
    """``a^-1`` of a small symbolic matrix: per entry when diagonal, else adjugate over determinant."""
    a = expanded(a)
    if a.is_diagonal():
        return sp.diag(*[sp.Pow(a[i, i], -1) for i in range(a.rows)])
    return a.adjugate(method="berkowitz") * sp.Pow(a.det(method="berkowitz"), -1)


def _solve(jac: sp.Matrix, rhs: sp.Matrix, n: int) -> sp.Matrix:
    """``jac^-1 rhs`` by the blocks of ``jac`` (its first ``n`` rows and columns, then the rest): the
    Schur complement ``S = J22 - J21 J11^-1 J12`` on the second block."""
    j11, j12, j21, j22 = jac[:n, :n], jac[:n, n:], jac[n:, :n], jac[n:, n:]
    if jac.rows == n:
        return _inverse(j11) * rhs
    i11 = _inverse(j11)
    r1, r2 = rhs[:n, :], rhs[n:, :]
    schur = j22 - j21 * i11 * j12
    x2 = _inverse(schur) * (r2 - j21 * (i11 * r1))
    x1 = i11 * (r1 - j12 * x2)
    return x1.col_join(x2)


class _Atoms:
    """The entries of the partials as symbols: a number stays a number (after expansion: a constant mass,
    a flat row's gradient), every other distinct entry becomes one symbol ``a<k>`` (its expression
    evaluated once, in the atoms routine)."""

    def __init__(self, inline: set[sp.Symbol]) -> None:
        self.exprs: dict[sp.Expr, sp.Symbol] = {}
        self.inline = inline  # run constants (the step, the parameters): their entries stay expressions

    def __call__(self, m: sp.Matrix) -> sp.Matrix:
        return m.applyfunc(self._one)

    def _one(self, e: sp.Expr) -> sp.Expr:
        e = sp.sympify(e)
        if e.free_symbols <= self.inline:
            return e
        x = sp.expand(e)
        if x.free_symbols <= self.inline:
            return x
        if e not in self.exprs:
            self.exprs[e] = sp.Symbol(f"a{len(self.exprs)}", real=True)
        return self.exprs[e]


def held_map(system: DiscreteSystem, active: tuple[int, ...], key: int) -> HeldMap:
    """``sens_held_atoms_<key>(q, p, tau, v, lam, lam1, u1, par) -> a`` (the nonconstant partials of the
    step's phases) and ``sens_held_map_<key>(a, s) -> s1``: the tangent of a held grid step on the rows
    ``active``, ``S_k -> S_k+1``; ``s1 = Phi_(q, p) s + Phi_par`` with ``Phi = d(q1, p1)/d(q, p, params)``
    eliminated symbolically in the atoms and expanded (its zeros and ones gone at generation)."""
    r = system.routines
    n, nr = system.n, system.r
    big_p = len(system.model.defaults)
    k = 2 * n + big_p
    rat, drat = r["rattle"], r["d_rattle"]
    prj, dprj = r["rattle_project"], r["d_rattle_project"]
    dseg, dleg = r["d_segment"], r["d_legendre"]
    # the inputs of the atoms (one set of symbols; every routine's own are replaced by these)
    q = Arg("q", tuple(sp.Dummy(f"q{i}", real=True) for i in range(n)))
    p = Arg("p", tuple(sp.Dummy(f"p{i}", real=True) for i in range(n)))
    tau = Arg("tau", (sp.Dummy("tau", real=True),))
    v = Arg("v", tuple(sp.Dummy(f"v{i}", real=True) for i in range(n)))
    lam = Arg("lam", tuple(sp.Dummy(f"lam{i}", real=True) for i in range(nr)))
    lam1 = Arg("lam1", tuple(sp.Dummy(f"mu{i}", real=True) for i in range(nr)))
    u1 = Arg("u1", tuple(sp.Dummy(f"u{i}", real=True) for i in range(n)))
    par = rat.input("par")
    npar = par.size
    h = tau.symbols[0]
    act = [sp.S.One if j in active else sp.S.Zero for j in range(nr)]
    # the columns of Phi: (q, p, the model's parameters)
    dq = sp.eye(n).row_join(sp.zeros(n, n + big_p))
    dp = sp.zeros(n, n).row_join(sp.eye(n)).row_join(sp.zeros(n, big_p))
    dpar = sp.zeros(npar, 2 * n + big_p)
    for i in range(big_p):
        dpar[i, 2 * n + i] = 1
    idx = list(range(n)) + [n + j for j in active]  # the unknowns that move: (v, Lam_A)
    atom = _Atoms({h, *par.symbols})

    def at(routine, values: list) -> dict:
        return {
            sym: val
            for a, vals in zip(routine.inputs, values)
            if vals is not None
            for sym, val in zip(a.symbols, vals)
        }

    # rattle at x = (v, Lam), data (q0, p0, tau, act, par): columns q0 n, p0 n, tau 1, act R, par
    rep = at(rat, [(*v.symbols, *lam.symbols), q.symbols, p.symbols, (h,), act, None])
    fx = atom(rat.output("jac").expr.xreplace(rep)[idx, idx])
    fd = atom(drat.output("dres").expr.xreplace(rep)[idx, :])
    rhs = fd[:, :n] * dq + fd[:, n : 2 * n] * dp + fd[:, 2 * n + 1 + nr :] * dpar
    dv = (-_solve(fx, rhs, n))[:n, :]
    q1 = sp.Matrix(q.symbols) + h * sp.Matrix(v.symbols)
    dq1 = dq + h * dv
    # p+ (d_segment: columns q0 n, v n, tau 1, par)
    rep = at(dseg, [q.symbols, v.symbols, (h,), None])
    dpp_s = atom(dseg.output("dp_plus").expr.xreplace(rep))
    dpp = dpp_s[:, :n] * dq + dpp_s[:, n : 2 * n] * dv + dpp_s[:, 2 * n + 1 :] * dpar
    # rattle_project at y = (u1, Lam'), data (q1, p1, act, par): columns q1 n, p1 n, act R, par (p1 enters
    # the residual linearly: its value is never read)
    rep = at(prj, [(*u1.symbols, *lam1.symbols), list(q1), None, act, None])
    fy = atom(prj.output("jac").expr.xreplace(rep)[idx, idx])
    fd = atom(dprj.output("dres").expr.xreplace(rep)[idx, :])
    rhs = fd[:, :n] * dq1 + fd[:, n : 2 * n] * dpp + fd[:, 2 * n + nr :] * dpar
    du1 = (-_solve(fy, rhs, n))[:n, :]
    # p_k+1 = dL/dqdot(q1, u1) (d_legendre: columns q n, v n, par)
    rep = at(dleg, [list(q1), u1.symbols, None, None])
    dmom = atom(dleg.output("dmom").expr.xreplace(rep))
    dp1 = dmom[:, :n] * dq1 + dmom[:, n : 2 * n] * du1 + dmom[:, 2 * n :] * dpar
    phi = _settled(dq1.col_join(dp1), [*atom.exprs.values(), h, *par.symbols])
    state = [*q.symbols, *p.symbols, h, *v.symbols, *lam.symbols, *lam1.symbols, *u1.symbols, *par.symbols]
    phi = _settled_on_states(phi, {a: e for e, a in atom.exprs.items()}, state)
    # a set whose F is singular for every state (two rows of one coordinate, a floor and a ceiling in 1-D):
    # NaN, which sends the caller to the numeric path, not SymPy's infinities (C has no zoo)
    phi = phi.applyfunc(lambda e: sp.nan if e.has(sp.zoo, sp.oo, -sp.oo, sp.nan) else e)
    used = set().union(*(e.free_symbols for e in phi))
    atoms = [(e, a) for e, a in atom.exprs.items() if a in used]  # the partials Phi reads
    syms = tuple(a for _, a in atoms)
    # Phi's entries that read the partials, as one vector f; the others (numbers, run constants) are printed
    # into the map itself
    moving = [(i, j) for i in range(phi.rows) for j in range(phi.cols) if phi[i, j].free_symbols & set(syms)]
    f = Arg("f", tuple(sp.Symbol(f"f{m}", real=True) for m in range(len(moving))))
    phis = phi.copy()
    for m, (i, j) in enumerate(moving):
        phis[i, j] = f.symbols[m]
    s = Arg("s", tuple(sp.Dummy(f"s{i}", real=True) for i in range(2 * n * k)))
    s1 = phis[:, : 2 * n] * sp.Matrix(2 * n, k, list(s.symbols))
    for i in range(big_p):
        s1[:, 2 * n + i] += phis[:, 2 * n + i]
    rows = list(active)
    return HeldMap(
        key,
        rows,
        Routine(
            f"sens_held_atoms_{key}",
            (q, p, tau, v, lam, lam1, u1, par),
            (Output("a", sp.Matrix(len(syms), 1, [e for e, _ in atoms])),),
            f"The partials of a held grid step on rows {rows} that are not run constants (cheld_map).",
        ),
        Routine(
            f"sens_held_phi_{key}",
            (Arg("a", syms), tau, par),
            (Output("f", sp.Matrix(len(moving), 1, [phi[i, j] for i, j in moving])),),
            f"The entries of d(q1, p1)/d(q, p, params) of a held grid step on rows {rows} that read them.",
        ),
        Routine(
            f"sens_held_map_{key}",
            (f, tau, par, s),
            (Output("s1", s1),),
            f"The tangent of a held grid step on rows {rows}, S_k+1 = Phi (S_k; 0 I_P) (cheld_map).",
        ),
    )


class HeldMap(NamedTuple):
    """One active set's fused tangent: its key (``ccontext.held_sets``), rows and three routines."""

    key: int
    rows: list[int]
    atoms: Routine
    phi: Routine
    map: Routine

    def context(self) -> dict:
        """What ``templates/sens_held_map.c.j2`` needs (sizes at least 1: C has no empty arrays)."""
        return {
            "key": self.key,
            "rows": self.rows,
            "na": max(self.atoms.outputs[0].size, 1),
            "nf": max(self.phi.outputs[0].size, 1),
        }


def held_maps(system: DiscreteSystem, sets: list[dict]) -> list[HeldMap]:
    """The fused tangents of a system's held steps, one per active set of ``sets``
    (``ccontext.held_sets``: one or two rows, none past ``HELD_SETS_MAX`` rows), or none: more than
    :data:`HELD_MAP_N` coordinates, or a scene without the held glide (``structure.held``: constant
    diagonal mass, no forces, no friction). There the held step is straight-line code of a few ns, and the
    numeric tangent was 7-50x it; on the general chain (Newton on ``rattle``) the numeric tangent is ~2x
    the step, and a map would cost its build (5-40 s of SymPy for a configuration-dependent mass such as
    the double pendulum's)."""
    rows = system.rows
    if not rows or system.n > HELD_MAP_N or "d_rattle" not in system.routines or not system.structure.held:
        return []
    if system.stages:  # internal points: rattle's unknowns are not (v, Lam) alone (and no held glide there)
        return []
    return [held_map(system, tuple(s["rows"]), s["key"]) for s in sets]


ROUGH = (sp.Abs, sp.sign, sp.Heaviside, sp.Piecewise, sp.Min, sp.Max, sp.floor, sp.ceiling)


def _settled_on_states(m: sp.Matrix, atoms: dict[sp.Symbol, sp.Expr], state: list[sp.Symbol]) -> sp.Matrix:
    """``m`` (in the partials' symbols ``atoms``, each an expression of the ``state``) with its entries that
    are identically 0 or 1 *as functions of the state* as such. :func:`_settled` treats the partials as
    independent, so a zero that comes from their relations stays there: on the box held on its face the two
    rows fix ``y`` and ``theta``, so ``d(y1, theta1, p1_y, p1_theta)`` is 0 whatever the state, but as a
    rational function of the partials it is not. Here each entry is evaluated at three random states to
    ``DPS`` digits (the partials from their expressions, then the entry), and taken as 0 (or 1) where all
    three are within ``10^-(DPS/2)`` of it: a nonzero analytic function vanishes to 30 digits at three random
    points with probability nil. Entries that read a partial with a function that is not analytic
    (``ROUGH``: ``Abs``, ``sign``, ...), or that do not evaluate to a real number at each point, are left as
    they are."""
    smooth = {a for a, e in atoms.items() if not e.has(*ROUGH)}
    cells = [(i, j) for i in range(m.rows) for j in range(m.cols) if m[i, j].free_symbols]
    cells = [c for c in cells if m[c].free_symbols & set(atoms) and m[c].free_symbols & set(atoms) <= smooth]
    if not cells:
        return m
    rng = random.Random(20261203)
    points = []
    for _ in range(3):
        st = {x: sp.Rational(rng.randint(3 * 10**6, 13 * 10**6), 10**7) for x in state}
        vals = {a: _rational(atoms[a]).xreplace(st).evalf(DPS) for a in smooth}
        points.append(vals | {x: sp.Float(v, DPS) for x, v in st.items()})
    out = m.copy()
    tol = sp.Float(10) ** (-DPS // 2)
    for c in cells:
        e = _rational(m[c])
        first = e.xreplace(points[0]).evalf(DPS)
        for k in (0, 1):  # the other points only where the first is k (most entries are neither there)
            if _near(first, k, tol) and all(_near(e.xreplace(pt).evalf(DPS), k, tol) for pt in points[1:]):
                out[c] = sp.Integer(k)
    return out


def _near(v: sp.Expr, k: int, tol: sp.Float) -> bool:
    """Whether ``v`` is a real number within ``tol`` of ``k``."""
    return bool(v.is_Number and v.is_real and abs(v - k) <= tol)


def _rational(e: sp.Expr) -> sp.Expr:
    """``e`` with its floats as the rationals they are exactly (a model's ``0.5``, ``1.0``): else ``evalf``
    keeps them at 15 digits."""
    return e.xreplace({f: sp.Rational(f) for f in e.atoms(sp.Float)})


def _settled(m: sp.Matrix, symbols: list[sp.Symbol]) -> sp.Matrix:
    """``m`` (rational in ``symbols``) with its entries that are identically 0 or 1 as such, the others as
    they are. An entry is evaluated exactly at three random rational points (Schwartz-Zippel: a nonzero
    rational function of degree ``d`` vanishes at such a point with probability below ``d / 10^11``);
    ``cancel`` would decide it too, but takes minutes on the two-row sets of the star. The partials are
    independent symbols here, so a zero that needs their relations stays an expression (correct, only
    slower); a point where an entry is not a rational number (a parameter under ``sqrt``, a zero
    denominator) leaves it as it is."""
    rng = random.Random(20261202)
    big = 10**6
    points = [{s: sp.Rational(rng.randint(1, big), rng.randint(1, big)) for s in symbols} for _ in range(3)]

    def one(e: sp.Expr) -> sp.Expr:
        if not e.free_symbols:
            return e
        vals = [e.xreplace(pt) for pt in points]
        for c in (0, 1):
            if all(val.is_Rational and val == c for val in vals):
                return sp.Integer(c)
        return e

    return m.applyfunc(one)
