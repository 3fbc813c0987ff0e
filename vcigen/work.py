"""The discrete work of the forces (Lagrange-d'Alembert, MATH.md *Forcing*), booked per grid step.

A segment ``(q0, v, tau)`` starting at ``t0`` carries the discrete forces ``f_d-`` (at its start) and
``f_d+`` (at its end); ``(f_d- + f_d+) . v`` is exactly the difference of its end energies
(``vcigen.derive.Segment``). Across an impact the energy at the end of one segment is the energy at the
start of the next (the alpha-variation with (37)), so there the segments' work is exact.

At a grid node the time is not varied and the two energies differ: the node joins a segment ``(v-, f_d+)``
to the next ``(v+, f_d-)`` through the DEL ``p+(seg-) = p-(seg+)``, i.e. the conservative map followed by
the kick ``J = f_d+ + f_d-``. A kick ``J`` changes the kinetic energy ``1/2 p M^-1 p`` by exactly
``J . (v- + v+)/2`` (M constant), so the node's work is ``J . (v- + v+)/2``, not the old
``f_d+ . v- + f_d- . v+``; the two differ by

    c = (f_d+ - f_d-) . (v+ - v-) / 2,

which for damping ``F = -c v`` (trapezoid) is ``c h/4 |v+ - v-|^2 >= 0``: O(h^3) a node, of one sign, an
O(h^2) drift over a run. With it the force part of the balance telescopes exactly, for both rules, and
what is left of ``E_k - E_0 - sum W + losses`` is the conservative mismatch of the discrete energy: for a
quadratic V it telescopes (trapezoid) or vanishes (midpoint). With a third derivative ``D3V`` of V its
remainder ``-(h^3/12) D3V[v, v, v]`` a step sums, on a forced trajectory, to
``(h^2/6) int grad^2 V(qdot, M^-1 F) dt`` (both rules): where ``L = 1/2 qdot^T M qdot + b . qdot - V(q)``
with ``M``, ``b`` constant and V not quadratic, the kick is booked at
``vbar + (h^2/6) M^-1 grad^2 V(q_k) vbar`` instead, which removes it. For a mass matrix of ``q`` the kick
is booked as its change of the modified Hamiltonian ``H~`` that the rule's conservative map keeps to
O(h^4) (:func:`_modified_hamiltonian`).

Step ``k``'s work is its segments' work plus the correction of the node it starts at (step 0 has none); a
node that is also an impact (a sub-segment of zero length there) takes none. On the steps of an impact the
conservative mismatch no longer telescopes: the nodes join segments of different lengths and (48a) keeps
``E_d`` across the impact; :func:`impact_work` books what is left, ``b = O(h^2)`` an impact (README,
*Forces*), without which the balance drifts in proportion to the number of impacts (with a mass matrix of
``q``: :func:`modified_impact_work`); a plastic impact, or one in a step with a row held, also books the
difference of its logged energy after it to the energy at the start of the segment after. An impact exactly
on a grid node is a segment of length 0 with the node momentum's velocity. Bilateral constraints: the
impulse of the DEL at a node does work (:func:`constraint_impulse`).

A rule with internal points (lobatto3) books only its segments' own quadrature of the work, ``E_end -
E_start`` (``vcigen.rules.StagedForces``), with no node term: the corrections above are O(h^2) ones and its
balance is O(h^4) without them, impact steps included (README *Fourth order*, measured there).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
import sympy as sp

from .derive import DiscreteSystem
from .result import Result

ForceFn = Callable[..., tuple[np.ndarray, np.ndarray]]
CurvatureFn = Callable[..., np.ndarray]
TINY = 1e-14  # a sub-segment shorter than TINY * h is no segment (simultaneous impacts, an impact on a node)


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


def _staged_step_work(res: Result, booking: Booking, par) -> np.ndarray:
    """``(N-1,)``: each grid step's segments' own work (split at its impacts) under a rule with internal
    points; no node term (README *Forces*, lobatto3: what that leaves in the balance is measured there)."""
    steps = res.energy.size
    q, t, h = res.q, res.t, res.h
    held = _held_rows(res, booking, par, q[:-1], q[1:], np.arange(steps))
    out = booking.staged(q[:-1], (q[1:] - q[:-1]) / h, np.full(steps, h), t[:-1], par, held).copy()
    ims = [im for im in res.impacts if im.step < steps]
    for k in sorted({im.step for im in ims}):
        here = sorted((im for im in ims if im.step == k), key=lambda im: im.t)
        ts = np.array([t[k], *(im.t for im in here), t[k + 1]])
        qs = np.array([q[k], *(np.asarray(im.q, float) for im in here), q[k + 1]])
        tau = np.diff(ts)
        keep = tau > TINY * h
        vs = (qs[1:] - qs[:-1])[keep] / tau[keep, None]
        ends = qs[:-1][keep], qs[1:][keep]
        act = _held_rows(res, booking, par, *ends, np.full(int(keep.sum()), k), either=True)
        out[k] = float(np.sum(booking.staged(ends[0], vs, tau[keep], ts[:-1][keep], par, act)))
        # an impact with a row held after it (a plastic entry, an impact while held) logs E_d less its loss,
        # not the energy at the start of the constrained segment that follows: the difference is the step's
        for m, im in enumerate(here, start=1):  # segment m starts at impact m
            j = int(np.sum(keep[:m]))  # its index among the kept segments
            if keep[m] and act is not None and act[j].any():
                at = (ends[0][j : j + 1], vs[j : j + 1], tau[keep][j : j + 1], ts[:-1][keep][j : j + 1])
                out[k] += float(booking.staged(*at, par, act[j : j + 1], start=True)[0]) - im.energy_after
    return out


HELD_PSI = 1e-10  # a row this close to 0 at both ends of a segment of a step its contact is held over is held


def _held_rows(
    res: Result, booking: Booking, par, q0: np.ndarray, q1: np.ndarray, step: np.ndarray, either: bool = False
):
    """``(K, r)``: the rows segments ``(q0, q1)`` of grid steps ``step`` held their internal points on (the
    constrained step's): the constraints, and a contact's rows at ``|psi| <= HELD_PSI`` at both ends where the
    contact is active at both grid points of the step (``res.active``; ``either``: at one of them, for the
    segments of a step split at its impacts, a plastic entry or a lift-off among them); ``None`` without
    rows."""
    if booking.rows is None:
        return None
    psi_fn, contact = booking.rows
    near = (np.abs(psi_fn(q0, par)) <= HELD_PSI) & (np.abs(psi_fn(q1, par)) <= HELD_PSI)
    act = np.zeros(near.shape)
    for r, j in enumerate(contact):
        if j < 0:  # a constraint: always held
            act[:, r] = 1.0
            continue
        now, nxt = res.active[step, j], res.active[step + 1, j]
        act[:, r] = near[:, r] & ((now | nxt) if either else (now & nxt))
    return act


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


def _dot(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    return np.einsum("kn,kn->k", a, b)


def step_work(res: Result, booking: Booking | None, par) -> np.ndarray:
    """``(N-1,)``: the discrete work over each grid step: its segments' ``(f_d- + f_d+) . v`` (split at its
    impacts) plus, at the grid node it starts at, ``(f_d+ - f_d-) . (v+ - v-) / 2`` and, with a curvature,
    ``(h^2/6) J . M^-1 grad^2 V vbar`` (with a mass matrix of ``q``: the kick's change of ``H~`` less the
    segments' ``f_d . v`` instead), and on the steps of an impact :func:`impact_work` and the plastic
    impacts' energy difference (module docstring). Exactly 0 without forces."""
    steps = res.energy.size
    if booking is None or steps == 0:
        return np.zeros(steps)
    if booking.staged is not None:
        return _staged_step_work(res, booking, par)
    forces = booking.forces
    q, t, h = res.q, res.t, res.h
    v = (q[1:] - q[:-1]) / h
    fm, fp = forces(q[:-1], v, np.full(steps, h), t[:-1], par)
    out = _dot(fm + fp, v)
    # the segments either side of each grid node: the last of step k-1 (v_end, f_end, tau_end) and the first
    # of step k (v_start, f_start, tau_start)
    v_start, f_start, v_end, f_end = v.copy(), fm.copy(), v.copy(), fp.copy()
    tau_start, tau_end = np.full(steps, h), np.full(steps, h)
    on_node = np.zeros(steps + 1, dtype=bool)  # an impact sits on grid node k
    ims = [im for im in res.impacts if im.step < steps]
    if ims:  # the impact steps, split at their impacts: all their sub-segments in one call
        hit = np.array([im.step for im in ims])
        ks = np.unique(hit)
        owner = np.concatenate([ks, hit, ks])
        place = np.concatenate(
            [np.zeros(ks.size), np.ones(hit.size), np.full(ks.size, 2.0)]
        )  # start, hit, end
        ts = np.concatenate([t[ks], [im.t for im in ims], t[ks + 1]])
        qs = np.concatenate([q[ks], np.array([im.q for im in ims]).reshape(hit.size, -1), q[ks + 1]])
        order = np.lexsort((ts, place, owner))
        owner, ts, qs = owner[order], ts[order], qs[order]
        tau = np.diff(ts)
        inside = owner[1:] == owner[:-1]  # consecutive points of one step bound a segment
        keep = inside & (tau > TINY * h)
        first, last = np.flatnonzero(place[order][:-1] == 0), np.flatnonzero(place[order][1:] == 2)
        zero = np.zeros(tau.size, dtype=bool)  # an impact on a grid node: a segment of length 0 there
        if booking.legendre is not None:
            zero[first], zero[last] = ~keep[first], ~keep[last]
            keep |= zero
        on_node[ks] |= ~keep[first]
        on_node[ks + 1] |= ~keep[last]
        seg = np.flatnonzero(keep)
        vs = (qs[seg + 1] - qs[seg]) / np.maximum(tau[seg, None], TINY * h)
        if zero.any():  # its velocity from its momentum, the node's: before the impact at a step's start,
            z = np.flatnonzero(zero[seg])  # after it at its end
            node = np.where(place[order][seg[z]] == 0, owner[seg[z]], owner[seg[z]] + 1)
            vs[z] = booking.legendre(q[node], res.p[node], par)
            tau[seg[z]] = 0.0
        gm, gp = forces(qs[seg], vs, tau[seg], ts[seg], par)
        out[ks] = 0.0
        np.add.at(out, owner[seg], _dot(gm + gp, vs))
        _, head = np.unique(owner[seg], return_index=True)  # the first kept segment of each impact step
        _, tail = np.unique(owner[seg][::-1], return_index=True)
        tail = seg.size - 1 - tail  # and the last
        k = owner[seg][head]
        v_start[k], f_start[k], v_end[k], f_end[k] = vs[head], gm[head], vs[tail], gp[tail]
        tau_start[k], tau_end[k] = tau[seg][head], tau[seg][tail]
    node = _dot(f_end[:-1] - f_start[1:], v_start[1:] - v_end[:-1]) / 2  # grid nodes 1 .. steps-1
    bilateral = res.constraint_force is not None and res.constraint_force.size > 0
    impulse = np.zeros((max(steps - 1, 0), q.shape[1]))  # the bilateral constraints' impulse at each node
    if bilateral and booking.momenta is not None and steps > 1:
        impulse = constraint_impulse(booking, res, (v_start, tau_start, v_end, tau_end), par)
        node += _dot(impulse, (v_start[1:] + v_end[:-1]) / 2)
    if booking.curvature is not None and steps > 1:  # the kick at vbar + h^2/6 M^-1 grad^2 V vbar
        kick, vbar = f_end[:-1] + f_start[1:] + impulse, (v_start[1:] + v_end[:-1]) / 2
        node += h * h / 6 * np.einsum("kn,knm,km->k", kick, booking.curvature(q[1:steps], par), vbar)
    if booking.modified is not None and steps > 1:  # the kick's change of H~, in place of J . vbar
        mom = res.p[1:steps]
        lo, hi = mom - f_end[:-1], mom + f_start[1:]  # p before and after the kick f_d+ + f_d-
        gain = booking.modified(q[1:steps], hi, h, par) - booking.modified(q[1:steps], lo, h, par)
        node = gain - _dot(f_end[:-1], v_end[:-1]) - _dot(f_start[1:], v_start[1:])
    out[1:] += np.where(on_node[1:steps], 0.0, node)
    if ims and booking.potential is not None:
        held = np.full(steps, bilateral)  # the steps with a row held: their DEL holds its impulse
        if res.contact_force is not None and res.contact_force.size:
            held |= np.any(res.contact_force != 0.0, axis=1)
        sub = (owner[seg], qs[seg], vs, tau[seg])
        ends = (v_start, tau_start, v_end, tau_end, f_end[:-1] + f_start[1:])
        curved = booking.curvature is not None
        out += impact_work(booking.potential, curved, q, h, ks, sub, ends, held, on_node, par)
        # a plastic impact's logged energy after it is E_d less its loss, not the energy at the start of the
        # constrained segment that follows: the difference is the step's too
        plastic = np.array([im.kind == "plastic" or held[im.step] for im in ims])[
            order[place[order] == 1] - ks.size
        ]
        after = np.array([im.energy_after for im in ims])[order[place[order] == 1] - ks.size]
        rows = np.flatnonzero(place[order] == 1)[plastic]  # the plastic impacts' points
        i = np.searchsorted(seg, rows)
        found = (i < seg.size) & (seg[np.minimum(i, seg.size - 1)] == rows)  # a segment starts there
        if found.any():
            j = i[found]
            e0 = booking.start(qs[seg[j]], vs[j], tau[seg[j]], ts[seg[j]], par)
            np.add.at(out, owner[seg[j]], e0 - after[plastic][found])
    elif ims and booking.modified is not None and steps > 1 and not bilateral:
        first, last = (v_start, tau_start, t[:-1]), (v_end, tau_end, t[1:] - tau_end)
        out += modified_impact_work(booking, res, h, ks, first, last, on_node, par)
    return out


def constraint_impulse(booking: Booking, res: Result, ends: tuple[np.ndarray, ...], par) -> np.ndarray:
    """``(N-2, n)``: at grid nodes 1 .. N-2 the bilateral constraints' impulse ``K``, the mismatch of the DEL
    there, ``K = p-(seg+) - p+(seg-)`` (RATTLE: ``(Lam' + Lam) grad psi``). As a kick it changes
    ``1/2 p.M^-1 p`` by ``K . (v- + v+)/2`` (M constant; README, *Forces*), not 0: the discrete path leaves
    ``q_k`` off the tangent, ``grad psi . v+- = -+(tau/2) v.Hess psi v``, so a node books
    ``(h^2/4) lambda (v-.Hess psi v- - v+.Hess psi v+)``, O(h^3); without forces it sums to a bounded
    O(h^2) (the tension a function of the state), with damping to a drift, O(h^2) times the dissipated
    energy. It is also part of the kick of the h^2 term with V not quadratic (``q'' = M^-1 (F - g + G^T
    lambda)`` in the integration by parts)."""
    v_start, tau_start, v_end, tau_end = ends
    steps = res.energy.size
    q, t = res.q[1:steps], res.t[1:steps]
    p_next, _ = booking.momenta(q, v_start[1:], tau_start[1:], t, False, par)
    p_prev, _ = booking.momenta(q, v_end[:-1], tau_end[:-1], t - tau_end[:-1], True, par)
    return p_next - p_prev


def modified_impact_work(
    booking: Booking,
    res: Result,
    h: float,
    ks: np.ndarray,
    first: tuple[np.ndarray, ...],
    last: tuple[np.ndarray, ...],
    on_node: np.ndarray,
    par,
) -> np.ndarray:
    """``(N-1,)``: the impacts' ``b`` for a mass matrix of ``q`` (README, *Forces*), where a node's kick is
    booked as its change of the modified Hamiltonian ``H~`` (:func:`_modified_hamiltonian`).

    With the node booking ``H~(q, p + f_d-) - H~(q, p - f_d+) - f_d+ . v- - f_d- . v+``, a grid node leaves
    in ``E_k - E_0 - sum W`` exactly ``D(s+) - D'(s-)``, with ``D(s) = E_d(s) - H~_h(q0, p0)`` at the start
    of segment ``s`` and ``D'(s) = E_d(s) - H~_h(q1, p1)`` at its end (``p0 = -D1 L_d``, ``p1 = D2 L_d``:
    the momenta of its conservative map). Over a segment of length ``h`` the map keeps ``H~_h`` to O(h^5),
    so ``D(s) - D'(s)`` is that defect and the nodes telescope; an impact (48a) keeps ``E_d``, not ``D``, and
    its sub-segments' maps keep ``H~`` of their own lengths. Per step with an impact the nodes leave

        b = D(first segment) [node k a grid node] - D'(last segment) [node k+1 a grid node],

    O(h^2), booked on the step (a segment between two impacts leaves nothing). An impact on a grid node makes
    the steps either side impact steps for this count. Steps in sustained contact (the node's DEL holds the
    contact impulse) book none."""
    steps = res.energy.size
    out = np.zeros(steps)
    touched = np.zeros(steps, dtype=bool)
    touched[ks] = True
    touched[:-1] |= on_node[1:steps]  # the step ending on an impact node
    touched |= on_node[:steps]  # and the one starting there
    if res.contact_force is not None and res.contact_force.size:
        touched &= ~np.any(res.contact_force != 0.0, axis=1)
    grid = np.zeros(steps + 1, dtype=bool)
    grid[1:steps] = ~on_node[1:steps]  # the grid nodes (not an impact, not the run's ends)
    head = np.flatnonzero(touched & grid[:-1])  # steps whose first segment starts at a grid node
    tail = np.flatnonzero(touched & grid[1:])  # steps whose last segment ends at one
    mom = res.p
    for rows, (v, tau, t0), at, sign in ((head, first, 0, 1.0), (tail, last, 1, -1.0)):
        if not rows.size:
            continue
        node, seg_tau, seg_t0 = rows + at, tau[rows], t0[rows]
        vel = booking.velocity(res.q[node], mom[node], v[rows], seg_tau, seg_t0, bool(at), par)
        start = res.q[node] - seg_tau[:, None] * vel if at else res.q[node]
        fm, fp = booking.forces(start, vel, seg_tau, seg_t0, par)
        energy = booking.start(start, vel, seg_tau, seg_t0, par) + _dot(fm, vel)
        p = mom[node] + fm if at == 0 else mom[node] - fp  # the conservative map's momentum
        np.add.at(out, rows, sign * (energy - booking.modified(res.q[node], p, h, par)))
    return out


def impact_work(
    potential: Potential,
    curved: bool,
    q: np.ndarray,
    h: float,
    ks: np.ndarray,
    sub: tuple[np.ndarray, ...],
    ends: tuple[np.ndarray, ...],
    held: np.ndarray,
    on_node: np.ndarray,
    par,
) -> np.ndarray:
    """``(N-1,)``: what the grid nodes' bookings miss on the steps of an impact, whose sub-segments are not
    ``h`` long (README, *Forces*; MATH.md (46), (48a)).

    The work booked at a node makes the forces cancel from the balance; what is left there is the
    conservative mismatch of ``E_d``. For segments of lengths ``t1``, ``t2`` and velocities ``v1``, ``v2``
    meeting at a node ``q`` it is, with ``g = grad V``, ``H = grad^2 V`` (exact for quadratic ``V``),

        trapezoid: 1/4 (t2^2 v2.H v2 - t1^2 v1.H v1) + 1/4 (t2 - t1) g(q) . (v2 - v1)
        midpoint:  1/4 (t2 - t1) (g(q - t1 v1/2) . v2 - g(q + t2 v2/2) . v1)

    With ``t1 = t2 = h`` the first telescopes over a run into ``1/4 h^2 v.H v`` of the last segment (bounded)
    and the rest vanishes. On an impact step the lengths differ, and across an impact (48a) keeps ``E_d``,
    not ``E_d - 1/4 t^2 v.H v``: per impact the balance keeps

        b = 1/4 (tA^2 vA.H vA - tB^2 vB.H vB)
            + 1/4 (tA - h) g(q_k) . (vA - v-) + 1/4 (h - tB) g(q_k+1) . (v+ - vB),

    O(h^2), of mean ``(h^2/12) [qdot.H qdot - g . M^-1 F]`` taken before less after the impact (trapezoid;
    over the impact's fraction ``alpha``), a drift proportional to the impacts' count wherever restitution
    or a force of the velocity changes that. ``b`` is booked: the nodes' terms on the step each node starts,
    the impacts' (trapezoid) on their step. Between free segments ``v2 - v1`` is taken from the DEL at the
    node, ``M (v2 - v1) = J - (t1 g(q) + t2 g(q))/2`` (trapezoid; midpoint ``J - (t1 g1 + t2 g2)/2``) with the
    kick ``J``, not from the positions: a sub-segment ``alpha h`` of round-off length would magnify their
    round-off. Next to a step ``held`` in sustained contact the node's DEL holds the contact's impulse too:
    there ``v2 - v1`` is taken from the positions.

    ``curved`` (the kick booked at ``vbar + (h^2/6) M^-1 grad^2 V vbar``, V not quadratic): that h^2 term
    equals the conservative remainder ``-(h^3/12) D3V[v, v, v]`` a step only up to the difference of
    ``-(h^2/12) (qdot.H qdot + g.M^-1 g)`` between the ends of each smooth stretch (integration by parts of
    ``D3V[qdot, qdot, qdot] = d/dt(qdot.H qdot) - 2 qdot.H qddot``). Across an impact ``qdot`` jumps: each
    impact also books ``(h^2/12) (vB.H vB - vA.H vA)``, with the velocity of a neighbouring segment for a
    sub-segment shorter than ``1e-3 h``.

    Impacts on a grid node take none."""
    steps = held.size
    out = np.zeros(steps)
    owner, qs, vs, tau = sub
    v_start, tau_start, v_end, tau_end, kick = ends
    pair = np.flatnonzero(owner[1:] == owner[:-1])  # the impacts inside a step: sub-segments pair, pair + 1
    if pair.size and (curved or potential.rule == "trapezoid"):
        hess = potential.hess(qs[pair + 1], par)
        jump = np.zeros(pair.size)
        if potential.rule == "trapezoid":  # 1/4 (tA^2 vA.H vA - tB^2 vB.H vB)
            a, b = vs[pair] * tau[pair, None], vs[pair + 1] * tau[pair + 1, None]
            jump += (_quad(a, hess) - _quad(b, hess)) / 4
        if curved:  # the jump of the h^2 term's boundary value -(h^2/12) qdot.H qdot (both rules)
            va, vb = _impact_velocities(pair, owner, vs, tau, v_start, v_end, h)
            jump += h * h / 12 * (_quad(vb, hess) - _quad(va, hess))
        np.add.at(out, owner[pair + 1], jump)
    nodes = np.unique(np.concatenate([ks, ks + 1]))
    nodes = nodes[(nodes >= 1) & (nodes < steps)]
    nodes = nodes[~on_node[nodes]]
    if nodes.size:
        t1, t2 = tau_end[nodes - 1, None], tau_start[nodes, None]
        v1, v2, qn, J = v_end[nodes - 1], v_start[nodes], q[nodes], kick[nodes - 1]
        minv = potential.minv(qn, par)
        contact = (held[nodes - 1] | held[nodes])[:, None]  # the DEL holds a contact impulse: positions
        if potential.rule == "trapezoid":
            g = potential.grad(qn, par)
            dv = np.where(contact, v2 - v1, np.einsum("knm,km->kn", minv, J - (t1 + t2) / 2 * g))
            mis = _dot(g, dv)
        else:  # g1 . v2 - g2 . v1 = g1 . (v2 - v1) + (g1 - g2) . v1 = g2 . (v2 - v1) + (g1 - g2) . v2
            g1, g2 = potential.grad(qn - v1 * t1 / 2, par), potential.grad(qn + v2 * t2 / 2, par)
            dv = np.where(contact, v2 - v1, np.einsum("knm,km->kn", minv, J - (t1 * g1 + t2 * g2) / 2))
            longer = t1 >= t2  # the velocity of the longer segment: the better conditioned
            mis = np.where(longer[:, 0], _dot(g1, dv) + _dot(g1 - g2, v1), _dot(g2, dv) + _dot(g1 - g2, v2))
        out[nodes] += (t2 - t1)[:, 0] / 4 * mis
    return out


def _quad(v: np.ndarray, mat: np.ndarray) -> np.ndarray:
    return np.einsum("kn,knm,km->k", v, mat, v)


def _impact_velocities(pair, owner, vs, tau, v_start, v_end, h: float) -> tuple[np.ndarray, np.ndarray]:
    """The velocities before and after the impacts between sub-segments ``pair`` and ``pair + 1``: theirs, or
    for one shorter than ``1e-3 h`` (its velocity, a difference of positions over its length, carries
    magnified round-off) that of the segment before it (after it), to O(h)."""
    short = tau < 1e-3 * h
    own = owner[pair]
    first = np.r_[True, owner[1:] != owner[:-1]]  # the first sub-segment of its step
    last = np.r_[owner[1:] != owner[:-1], True]
    prev = np.where(first[pair, None], v_end[np.maximum(own - 1, 0)], vs[np.maximum(pair - 1, 0)])
    nxt_seg = vs[np.minimum(pair + 2, vs.shape[0] - 1)]
    nxt = np.where(last[pair + 1, None], v_start[np.minimum(own + 1, v_start.shape[0] - 1)], nxt_seg)
    va = np.where(short[pair, None], prev, vs[pair])
    vb = np.where(short[pair + 1, None], nxt, vs[pair + 1])
    return va, vb


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


def friction_work(res: Result, tangents, mu_f, par) -> np.ndarray:
    """``(N-1,)``: the work of Coulomb friction in sustained contact, ``-mu_f lambda h |t . v|`` per step with
    the mean normal force ``lambda`` of ``res.contact_force`` and the tangent gradient ``t`` at the step's
    midpoint (0 while a contact sticks, to round-off). Friction at impacts is in each impact's energy loss."""
    steps = res.energy.size
    if tangents is None or steps == 0 or res.contact_force is None:
        return np.zeros(steps)
    q = res.q
    mid = 0.5 * (q[:-1] + q[1:])
    grads = tangents(mid, par)
    out = np.zeros(steps)
    for j, mu in enumerate(mu_f):
        lam = res.contact_force[:, j]
        held = lam != 0.0
        if not held.any() or mu <= 0.0:
            continue
        dq = q[1:][held] - q[:-1][held]
        if grads.ndim == 3:
            slide = np.abs(np.einsum("kn,kn->k", grads[held, j], dq))
        else:  # isotropic cones: the length of the two-tangent sliding
            slide = np.hypot(*np.einsum("kdn,kn->dk", grads[held, j], dq))
        out[held] -= mu_f[j] * lam[held] * slide
    return out
