"""What books the work of the forces, built once per system (``vcigen.work`` books a run with it).

:func:`work_function` turns a :class:`~vcigen.derive.DiscreteSystem`'s discrete forces (MATH.md *Forcing*,
Lagrange-d'Alembert) into numpy functions: the segments' ``f_d-``/``f_d+``, and where ``L`` allows the
kick's h^2 term (``M^-1 grad^2 V``), the potential for the impact steps' node mismatches, the modified
Hamiltonian ``H~`` for a mass matrix of ``q``, the Legendre inverse, a staged rule's own quadrature of the
work and the rows a step held. Why each is booked the way it is: ``vcigen.work``'s docstring.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
import sympy as sp

from .derive import DiscreteSystem

ForceFn = Callable[..., tuple[np.ndarray, np.ndarray]]


CurvatureFn = Callable[..., np.ndarray]


@dataclass(frozen=True)
class Potential:
    """``grad V``, ``grad^2 V`` and ``M^-1`` of ``L = 1/2 qdot^T M qdot + b . qdot - V(q)`` (``M``, ``b``
    constant), for the impact steps' node mismatches (:func:`impact_work`)."""

    grad: Callable[..., np.ndarray]  # (q (K, n), par) -> (K, n)
    hess: Callable[..., np.ndarray]  # (q (K, n), par) -> (K, n, n)
    minv: Callable[..., np.ndarray]  # (q (K, n), par) -> (K, n, n): M^-1, the same at every q
    rule: str  # "trapezoid" or "midpoint"


@dataclass(frozen=True)
class Booking:
    """What books the work: the segments' discrete forces and, where ``L`` allows, the kick's h^2 term and
    the impact steps' unequal segment lengths."""

    forces: ForceFn  # (q0 (K, n), v (K, n), tau (K,), t0 (K,), par) -> (f_d- (K, n), f_d+ (K, n))
    curvature: CurvatureFn | None  # (q (K, n), par) -> (K, n, n): M^-1 grad^2 V, or None (module docstring)
    potential: Potential | None = None  # None: M of q, or a rule without a closed form (impact_work)
    start: Callable[..., np.ndarray] | None = None  # (q0, v, tau, t0, par) -> (K,): E_d - f_d- . v
    modified: Callable[..., np.ndarray] | None = None  # (q, p, h, par) -> (K,): H~ (midpoint, M of q)
    velocity: Callable[..., np.ndarray] | None = None  # (q, p, v, tau, t0, end, par) -> (K, n): with H~
    momenta: Callable[..., tuple[np.ndarray, np.ndarray]] | None = None  # (q, v, tau, t0, end, par) -> p, p_v
    legendre: Callable[..., np.ndarray] | None = None  # (q, p, par) -> qdot: L quadratic in qdot
    # a rule with internal points: (q0, v, tau, t0, par, act=None) -> (K,), each segment's own quadrature of
    # the work, with act (K, r) the rows each segment holds its internal points on (None: none)
    staged: Callable[..., np.ndarray] | None = None
    # with rows: (q (K, n), par) -> psi (K, r), per row its contact (-1: a constraint): which rows a step held
    rows: tuple[Callable[..., np.ndarray], tuple[int, ...]] | None = None


def _lambdify(system: DiscreteSystem, args: list, rows: list[list[sp.Expr]]):
    """``rows`` as a numpy function of ``args`` and then the parameter vector ``par``."""
    par = [sp.Symbol(f"_par{i}") for i in range(len(system.params))]
    rep = dict(zip(system.params, par))
    return sp.lambdify([*args, *par], [[e.xreplace(rep) for e in row] for row in rows], modules="numpy")


def work_function(system: DiscreteSystem) -> Booking | None:
    """The :class:`Booking` of ``system``'s forces, or ``None`` without forces."""
    seg = system.segment
    if not system.model.force or seg is None:
        return None
    if system.stages:
        rows = (_row_values(system), tuple(system.rows.contact)) if system.r else None
        return Booking(_none, None, staged=_staged_work(system), rows=rows)
    fn = _lambdify(system, [*seg.q0, *seg.v, seg.tau], [list(seg.f_minus), list(seg.f_plus)])
    start_fn = _lambdify(system, [*seg.q0, *seg.v, seg.tau], [[seg.energy_start]])

    def forces(q0: np.ndarray, v: np.ndarray, tau: np.ndarray, t0: np.ndarray, values):
        args = list(values) if not system.timed else [*list(values)[:-1], t0]
        fm, fp = fn(*q0.T, *v.T, tau, *args)
        return tuple(
            np.stack([np.broadcast_to(np.asarray(f, float), tau.shape) for f in fs], -1) for fs in (fm, fp)
        )

    def start(q0: np.ndarray, v: np.ndarray, tau: np.ndarray, t0: np.ndarray, values) -> np.ndarray:
        args = list(values) if not system.timed else [*list(values)[:-1], t0]
        return np.broadcast_to(np.asarray(start_fn(*q0.T, *v.T, tau, *args)[0][0], float), tau.shape)

    modified = _modified_hamiltonian(system)
    momenta = _segment_momenta(system) if modified is not None or system.model.constraint else None
    velocity = _segment_velocity(system.model.n, momenta) if modified is not None else None
    legendre = _legendre(system)
    return Booking(
        forces, _curvature(system), _potential(system), start, modified, velocity, momenta, legendre
    )


def _legendre(system: DiscreteSystem) -> Callable[..., np.ndarray] | None:
    """``(q (K, n), p (K, n), par) -> qdot``: ``M(q)^-1 (p - b(q))`` for ``L = 1/2 qdot.M qdot + b.qdot - V``,
    the velocity of a segment of length 0 with momentum ``p`` (``p- = dL/dqdot`` at ``tau = 0``); ``None``
    for another ``L``."""
    model = system.model
    vs, mass = list(model.velocities), model.mass_matrix
    if mass.free_symbols & set(vs):
        return None
    v = sp.Matrix(vs)
    zero = dict.fromkeys(vs, 0)
    b = sp.Matrix([model.L.diff(x) for x in vs]).xreplace(zero)
    if sp.expand(model.L - (v.T * mass * v)[0] / 2 - (b.T * v)[0] - model.L.xreplace(zero)) != 0:
        return None
    mass_fn, b_fn = _matrix_function(system, mass), _matrix_function(system, b)

    def legendre(q: np.ndarray, p: np.ndarray, values) -> np.ndarray:
        return np.linalg.solve(mass_fn(q, values), (p - b_fn(q, values)[:, :, 0])[..., None])[..., 0]

    return legendre


def _segment_momenta(system: DiscreteSystem) -> Callable[..., tuple[np.ndarray, np.ndarray]]:
    """``(q, v, tau, t0, end, par) -> (p (K, n), dp/dv (K, n, n))``: the DEL momentum of the segment of
    length ``tau`` and velocity ``v`` that starts (``end`` False: ``p- = -D1 L_d - f_d-``) or ends (True:
    ``p+ = D2 L_d + f_d+``) at ``q``."""
    seg = system.segment
    n = system.model.n
    q1 = sp.Matrix([sp.Dummy(f"q1_{i}") for i in range(n)])
    p_end = seg.p_plus.xreplace(dict(zip(seg.q0, q1 - seg.tau * seg.v)))  # the segment ending at q1
    rows = [
        [*seg.p_minus, *seg.p_minus.jacobian(seg.v)],
        [*p_end, *p_end.jacobian(seg.v)],
    ]
    fns = [_lambdify(system, [*q, *seg.v, seg.tau], [row]) for q, row in zip((seg.q0, q1), rows)]

    def momenta(q: np.ndarray, v: np.ndarray, tau: np.ndarray, t0: np.ndarray, end: bool, values):
        args = list(values) if not system.timed else [*list(values)[:-1], t0]
        out = fns[end](*q.T, *v.T, tau, *args)[0]
        cols = np.stack([np.broadcast_to(np.asarray(c, float), tau.shape) for c in out], -1)
        return cols[:, :n], cols[:, n:].reshape(-1, n, n)

    return momenta


def _segment_velocity(n: int, momenta) -> Callable[..., np.ndarray]:
    """``(q, p, v, tau, t0, end, par) -> v (K, n)``: the velocity of the segment of length ``tau`` that starts
    (``end`` False) or ends (True) at ``q`` with the DEL momentum ``p`` there (:func:`_segment_momenta`), by
    Newton from ``v``. A sub-segment's velocity from its end points carries their round-off over its
    length; ``dp/dv = M + O(tau)`` keeps this one at round-off."""

    def velocity(
        q: np.ndarray, p: np.ndarray, v: np.ndarray, tau: np.ndarray, t0: np.ndarray, end: bool, values
    ):
        v = v.copy()
        for _ in range(3):
            mom, jac = momenta(q, v, tau, t0, end, values)
            v -= np.linalg.solve(jac, (mom - p)[..., None])[..., 0]
        return v

    return velocity


def _none(*_args):
    raise NotImplementedError("a rule with internal points books its segments' work through Booking.staged")


def _row_values(system: DiscreteSystem) -> Callable[..., np.ndarray]:
    """``(q (K, n), par) -> (K, r)``: every row's ``psi`` (vcigen.rows)."""
    rows = system.routines["rows"]
    fn = _lambdify(system, list(rows.input("q").symbols), [list(rows.output("psi").expr)])

    def value(q: np.ndarray, values) -> np.ndarray:
        return np.stack(
            [np.broadcast_to(np.asarray(x, float), q.shape[:1]) for x in fn(*q.T, *values)[0]], -1
        )

    return value


def _staged_work(system: DiscreteSystem) -> Callable[..., np.ndarray]:
    """``(q0, v, tau, t0, par, act=None) -> (K,)``: ``E_end - E_start`` of each segment under a rule with
    internal points, the rule's own quadrature of ``int F . qdot dt`` (``vcigen.rules.StagedForces``: ``start
    + end``), at the internal points' stationarity ``dl/du + f_stage = 0``, solved here by Newton from ``u =
    0``; where ``act`` (K, r) holds rows, the internal points held on them as in the constrained step
    (``derive.held_internal_points``: ``dl/du + f_stage + G_m^T Lam_m = 0``, ``psi(q_m) = 0``), Newton on
    ``(u, Lam_m)``."""
    seg = system.segment
    u = list(seg.internal)
    args = [*seg.q0, *seg.v, seg.tau, *u]
    stat = _lambdify(system, args, [list(seg.stationarity)])
    jac = _lambdify(system, args, seg.stationarity.jacobian(seg.internal).tolist())
    work = _lambdify(system, args, [[seg.energy - seg.energy_start]])
    begin = _lambdify(system, args, [[seg.energy_start]])
    ns = len(u)
    held = _held_stationarity(system) if system.r else None

    def col(x, shape) -> np.ndarray:
        return np.broadcast_to(np.asarray(x, float), shape)

    def newton(res_fn, jac_fn, x: np.ndarray, head: tuple, pars: list) -> np.ndarray:
        for _ in range(20):
            at = (*head, *x.T, *pars)
            r = np.stack([col(y, x.shape[:1]) for y in res_fn(*at)[0]], -1)
            j = np.stack([np.stack([col(y, x.shape[:1]) for y in row], -1) for row in jac_fn(*at)], 1)
            dx = np.linalg.solve(j, r[..., None])[..., 0]
            x = x - dx
            if np.max(np.abs(dx), initial=0.0) < 1e-15:
                break
        return x

    def value(
        q0: np.ndarray, v: np.ndarray, tau: np.ndarray, t0: np.ndarray, values, act=None, start: bool = False
    ) -> np.ndarray:
        pars = list(values) if not system.timed else [*list(values)[:-1], t0]
        if held is None or act is None or not act.any():
            uu = newton(stat, jac, np.zeros((tau.size, ns)), (*q0.T, *v.T, tau), pars)
            if start:  # the energy at the segment's start
                return col(begin(*q0.T, *v.T, tau, *uu.T, *pars)[0][0], tau.shape)
        elif start:  # ... with the internal points held: E_d = -D3 L_d gains u . l_u (held_internal_points)
            x = newton(
                held[0], held[1], np.zeros((tau.size, ns + act.shape[1])), (*q0.T, *v.T, tau, *act.T), pars
            )
            return col(held[2](*q0.T, *v.T, tau, *act.T, *x.T, *pars)[0][0], tau.shape)
        else:
            x = newton(
                held[0], held[1], np.zeros((tau.size, ns + act.shape[1])), (*q0.T, *v.T, tau, *act.T), pars
            )
            uu = x[:, :ns]
        return col(work(*q0.T, *v.T, tau, *uu.T, *pars)[0][0], tau.shape)

    return value


def _held_stationarity(system: DiscreteSystem):
    """``(residual, Jacobian, start energy)``, the first two in ``(u, Lam_m)``, of the internal points held
    on the rows ``act``, as numpy functions of ``(q0, v, tau, act, u, Lam_m, par)`` (the constrained step's
    rows of ``u`` and its ``E_d`` share, ``derive.held_internal_points``)."""
    from .derive import held_internal_points

    seg, rule = system.segment, system.rule
    rows = system.routines["rows"]
    q = tuple(rows.input("q").symbols)
    psi = list(rows.output("psi").expr)
    act = tuple(sp.Dummy(f"a{r}") for r in range(system.r))
    um = sp.Matrix(seg.internal)
    pts = held_internal_points(seg, rule, rows.output("grad").expr, psi, q, seg.q0, seg.v, seg.tau, um, act)
    res = (seg.stationarity - pts.stationarity).col_join(pts.rows)
    unknowns = [*seg.internal, *pts.lam]
    args = [*seg.q0, *seg.v, seg.tau, *act, *unknowns]
    return (
        _lambdify(system, args, [list(res)]),
        _lambdify(system, args, res.jacobian(unknowns).tolist()),
        _lambdify(system, args, [[seg.energy_start + pts.energy]]),
    )


def _separable(system: DiscreteSystem) -> bool:
    """Whether ``L = 1/2 qdot^T M qdot + b . qdot - V(q)``, ``M`` and ``b`` constant (no ``d2L/dq dqdot``)."""
    model = system.model
    qs, vs = model.coordinates, model.velocities
    if model.mass_matrix.free_symbols & set(qs + vs):
        return False
    return all(model.L.diff(a).diff(b) == 0 for a in qs for b in vs)


def _matrix_function(system: DiscreteSystem, mat: sp.Matrix) -> Callable[..., np.ndarray]:
    """``q (K, n), par -> (K, rows, cols)``: ``mat``, an expression of ``q`` and the parameters."""
    fn = _lambdify(system, list(system.model.coordinates), mat.tolist())

    def value(q: np.ndarray, values) -> np.ndarray:
        out = fn(*q.T, *values)  # L holds no time: the time slot's value does not matter
        return np.stack(
            [np.stack([np.broadcast_to(np.asarray(c, float), q.shape[:1]) for c in row], -1) for row in out],
            1,
        )

    return value


def _curvature(system: DiscreteSystem) -> CurvatureFn | None:
    """``M^-1 grad^2 V (q)`` when ``L`` is :func:`_separable` and ``V`` not quadratic; ``None`` otherwise."""
    if not _separable(system):
        return None
    model = system.model
    hess = -sp.hessian(model.L, sp.Matrix(model.coordinates))
    if not hess.free_symbols & set(model.coordinates):  # V quadratic: the kick at vbar is exact
        return None
    return _matrix_function(system, model.mass_matrix.inv() * hess)


def _modified_hamiltonian(system: DiscreteSystem) -> Callable[..., np.ndarray] | None:
    """``(q, p, h, par) -> H~`` (K,): the modified Hamiltonian that the rule's conservative map keeps to
    O(h^4) a step, for a mass matrix of ``q`` (with ``M`` constant the kick's h^2 term of :func:`_curvature`
    does it), ``L = 1/2 qdot.M(q) qdot + b(q).qdot - V(q)`` and ``n <= 4``; ``None`` otherwise.

    midpoint:  ``H~ = H - (h^2/24) H''(J grad H, J grad H)``, the implicit midpoint rule's, which the
               midpoint DEL is in ``(q, p)`` (``p_mid = (p0 + p1)/2 = M(q_mid) v``);
    trapezoid: ``H~ - (h^2/8) L_qq(qdot, qdot)`` at ``qdot = H_p``: along a curve ``L_d^trap - L_d^mid``
               ``= (h^3/8) L_qq(qdot, qdot) + O(h^5)``, a term ``(h^2/8) L_qq`` of the modified Lagrangian,
               ``-(h^2/8) L_qq`` of the modified Hamiltonian (with ``M`` constant and ``b = 0``: velocity
               Verlet's ``H + h^2 [p.V''p/12 - |V'|^2/24]``)."""
    model = system.model
    qs, vs, n = list(model.coordinates), list(model.velocities), model.n
    mass = model.mass_matrix
    if system.rule.name not in ("trapezoid", "midpoint") or n > 4 or mass.free_symbols & set(vs):
        return None
    if not mass.free_symbols & set(qs):
        return None
    zero = dict.fromkeys(vs, 0)
    b = sp.Matrix([model.L.diff(x) for x in vs]).xreplace(zero)  # L = 1/2 v.M v + b.v - V
    pot = -model.L.xreplace(zero)
    v = sp.Matrix(vs)
    if sp.expand(model.L - ((v.T * mass * v)[0] / 2 + (b.T * v)[0] - pot)) != 0:
        return None
    p = sp.Matrix([sp.Dummy(f"p{i}") for i in range(n)])
    h = sp.Dummy("h")
    minv = mass.inv()
    ham = ((p - b).T * minv * (p - b))[0] / 2 + pot
    z = sp.Matrix([*qs, *p])
    grad = sp.Matrix([ham.diff(x) for x in z])
    flow = sp.Matrix([*grad[n:], *(-g for g in grad[:n])])  # J grad H
    modified = ham - h**2 / 24 * (flow.T * sp.hessian(ham, z) * flow)[0]
    if system.rule.name == "trapezoid":
        lqq = (v.T * sp.hessian(model.L, sp.Matrix(qs)) * v)[0]
        modified -= h**2 / 8 * lqq.xreplace(dict(zip(vs, minv * (p - b))))
    fn = _lambdify(system, [*qs, *p, h], [[modified]])

    def value(q: np.ndarray, mom: np.ndarray, step: float, values) -> np.ndarray:
        return np.broadcast_to(np.asarray(fn(*q.T, *mom.T, step, *values)[0][0], float), q.shape[:1])

    return value


def _potential(system: DiscreteSystem) -> Potential | None:
    """``grad V``, ``grad^2 V`` when ``L`` is :func:`_separable` and the rule is the trapezoid or the midpoint
    rule; ``None`` otherwise."""
    if system.rule.name not in ("trapezoid", "midpoint") or not _separable(system):
        return None
    model = system.model
    qs = sp.Matrix(model.coordinates)
    grad = -sp.Matrix([model.L.diff(a) for a in model.coordinates])  # no dL/dq dqdot: of q alone
    grad_fn = _matrix_function(system, grad.T)
    hess_fn = _matrix_function(system, -sp.hessian(model.L, qs))
    minv_fn = _matrix_function(system, model.mass_matrix.inv())
    return Potential(lambda q, values: grad_fn(q, values)[:, 0], hess_fn, minv_fn, system.rule.name)


def tangent_function(system: DiscreteSystem):
    """``q (K, n), par -> (K, m, n)``: each contact's tangent gradient (the derived ``friction`` routine's
    ``tgrad``; 0 where frictionless), or ``None`` without friction. With isotropic cones, ``(K, m, 2, n)``:
    the second tangent's (``friction_cone``'s ``tgrad2``) too."""
    routine = system.routines.get("friction")
    if routine is None:
        return None
    q, par = routine.input("q").symbols, routine.input("par").symbols
    cone = system.routines.get("friction_cone")
    grads = routine.output("tgrad").expr.tolist()
    fns = [sp.lambdify([*q, *par], grads, modules="numpy")]
    if cone is not None:
        fns.append(sp.lambdify([*q, *par], cone.output("tgrad2").expr.tolist(), modules="numpy"))

    def tangents(qs: np.ndarray, values) -> np.ndarray:
        out = [
            np.stack(
                [
                    np.stack([np.broadcast_to(np.asarray(g, float), qs.shape[:1]) for g in row], -1)
                    for row in fn(*qs.T, *values)
                ],
                1,
            )
            for fn in fns
        ]
        return out[0] if len(out) == 1 else np.stack(out, 2)

    return tangents
