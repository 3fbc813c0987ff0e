"""Coulomb friction at an impact (MATH.md, *Friction*; paper (38)-(39)): the impulse law, pure functions.

At an impact on a contact with normal ``n = grad phi`` and tangent ``t = grad psi`` (the sliding velocity
is ``t . qdot``), the impulse is ``P = mu_n n + mu_t t``. The normal velocity leaves with ``-e`` times its
incoming value (Newton), and ``mu_t`` takes the most energy out that Coulomb's cone ``|mu_t| <= mu_f mu_n``
allows (maximal dissipation). With ``A = M^-1`` and ``d = t - b n``, ``b = n.A t / n.A n`` (the tangent
``A``-orthogonal to ``n``), ``mu_n = a - b mu_t`` with ``a = -(1 + e) n.qdot / n.A n``, and the kinetic
energy after is a quadratic in ``mu_t`` alone: minimised over the cone's interval. Where the minimiser is
inside, the contact sticks (with ``n.A t = 0``, e.g. a disk on a floor: the sliding velocity leaves at 0,
rolling); at an end it slips. ``mu_t = 0`` is in the interval, so the energy never rises above the
frictionless law's, which never rises above the incoming one. The stepper then solves the jump (48) along
the impulse direction ``n + (mu_t / mu_n) t`` with the energy target changed by ``dK``.

With two tangents (the isotropic cone of a 3-D contact, :func:`cone_law`) ``mu_t`` is a 2-vector and the
interval becomes the convex slice ``|mu_t| <= mu_f (a - b.mu_t)`` of the cone, over which the quadratic is
minimised exactly by two monotone 1-D roots (:func:`cone_impulse`); the direction is then
``n + (mu_t1/mu_n) t1 + (mu_t2/mu_n) t2``.
"""

from __future__ import annotations

import math

import numpy as np

from .held_roots import DEP_EPS, illinois_point, illinois_update


def impact_law(vel: np.ndarray, mass: np.ndarray, n: np.ndarray, t: np.ndarray, mu_f: float, e: float):
    """``(mu_n, mu_t, dK, M^-1 n, M^-1 t)``: the impulses, the kinetic energy change, and the two solves."""
    an, at = np.linalg.solve(mass, np.column_stack([n, t])).T
    nv, tv = float(n @ vel), float(t @ vel)
    nn, nt, tt = float(n @ an), float(n @ at), float(t @ at)
    a = max(-(1.0 + e) * nv / nn, 0.0)
    b = nt / nn
    dv, dad = tv - b * nv, tt - b * nt  # d . qdot and d . A d
    mu_t = -dv / dad if dad > 0.0 else 0.0
    hi = mu_f * a / (1.0 + mu_f * b) if 1.0 + mu_f * b > 0.0 else math.inf
    lo = -mu_f * a / (1.0 - mu_f * b) if 1.0 - mu_f * b > 0.0 else -math.inf
    mu_t = min(max(mu_t, lo), hi)
    mu_n = a - b * mu_t
    dk = mu_t * dv + 0.5 * mu_t * mu_t * dad + a * nv + 0.5 * a * a * nn
    return mu_n, mu_t, dk, an, at


def impact_law_tangent(scalars, dscalars: np.ndarray, mu_f: float, dmu_f, e: float, de):
    """The tangent of :func:`impact_law` in its branch (stick, or slip at either edge of the cone): ``(rho,
    dK, drho, ddK, branch)``, ``rho = mu_t / mu_n`` the impulse direction's tangential share (``n + rho t``),
    each ``d`` a row of the ``K`` columns of ``z`` (forward mode), ``branch`` 0 stick, +1 or -1 the edge.

    ``scalars = (n.qdot, t.qdot, n.A n, n.A t, t.A t)``, ``dscalars`` their tangents (5, K); ``mu_f``, ``e``
    and theirs. The branch is the one :func:`impact_law` takes from the same numbers (the same expressions
    in the same order); within it every quantity is a closed form of the scalars, differentiated here. A
    branch at its boundary (the unconstrained impulse on the cone's edge) is a mode change: the derivative of
    the branch taken is returned, finite differences must stay away from it."""
    nv, tv, nn, nt, tt = scalars
    dnv, dtv, dnn, dnt, dtt = dscalars
    a = -(1.0 + e) * nv / nn
    da = -de * nv / nn - (1.0 + e) * (dnv * nn - nv * dnn) / (nn * nn)
    b = nt / nn
    db = (dnt * nn - nt * dnn) / (nn * nn)
    dv, dad = tv - b * nv, tt - b * nt
    ddv, ddad = dtv - db * nv - b * dnv, dtt - db * nt - b * dnt
    mu_t = -dv / dad
    hi = mu_f * a / (1.0 + mu_f * b) if 1.0 + mu_f * b > 0.0 else math.inf
    lo = -mu_f * a / (1.0 - mu_f * b) if 1.0 - mu_f * b > 0.0 else -math.inf
    if mu_t > hi:  # slip, the cone's upper edge
        branch, mu_t = 1, hi
        c = 1.0 + mu_f * b
        dmu_t = ((dmu_f * a + mu_f * da) * c - mu_f * a * (dmu_f * b + mu_f * db)) / (c * c)
    elif mu_t < lo:  # slip, the lower edge
        branch, mu_t = -1, lo
        c = 1.0 - mu_f * b
        dmu_t = -((dmu_f * a + mu_f * da) * c + mu_f * a * (dmu_f * b + mu_f * db)) / (c * c)
    else:  # stick: the sliding velocity leaves at what the normal impulse leaves it (0 when n.A t = 0)
        branch = 0
        dmu_t = -(ddv * dad - dv * ddad) / (dad * dad)
    mu_n = a - b * mu_t
    dmu_n = da - db * mu_t - b * dmu_t
    dk = mu_t * dv + 0.5 * mu_t * mu_t * dad + a * nv + 0.5 * a * a * nn
    ddk = (
        dmu_t * dv
        + mu_t * ddv
        + mu_t * dmu_t * dad
        + 0.5 * mu_t * mu_t * ddad
        + da * nv
        + a * dnv
        + a * da * nn
        + 0.5 * a * a * dnn
    )
    rho = mu_t / mu_n
    drho = (dmu_t * mu_n - mu_t * dmu_n) / (mu_n * mu_n)
    return rho, dk, drho, ddk, branch


CONE_ITER = 200  # iterations of each 1-D root of the cone's impulse at most (doublings of its bracket too)


def cone_law(
    vel: np.ndarray, mass: np.ndarray, n: np.ndarray, t1: np.ndarray, t2: np.ndarray, mu_f: float, e: float
):
    """:func:`impact_law` with two tangents (the isotropic cone of a 3-D contact): ``(mu_n, mu_t, dK, M^-1 n,
    M^-1 (t1, t2))`` with ``mu_t`` the tangential impulse, a 2-vector.

    As in one dimension, with ``A = M^-1``, ``b_i = n.A t_i / n.A n`` and ``d_i = t_i - b_i n``: ``mu_n = a -
    b.mu_t`` and the kinetic energy after is ``a n.qdot + a^2 n.A n / 2 + g.mu_t + mu_t.H mu_t / 2`` with
    ``g_i = d_i.qdot`` and ``H_ij = d_i.A d_j``. It is minimised (:func:`cone_impulse`) over Coulomb's cone
    ``|mu_t| <= mu_f (a - b.mu_t)``: inside it the contact sticks, else the impulse is on its edge.
    """
    an, at1, at2 = np.linalg.solve(mass, np.column_stack([n, t1, t2])).T
    nv, nn = float(n @ vel), float(n @ an)
    nt = (float(n @ at1), float(n @ at2))
    a = max(-(1.0 + e) * nv / nn, 0.0)
    b = (nt[0] / nn, nt[1] / nn)
    g = (float(t1 @ vel) - b[0] * nv, float(t2 @ vel) - b[1] * nv)
    h = (float(t1 @ at1) - nt[0] * nt[0] / nn, float(t1 @ at2) - nt[0] * nt[1] / nn)
    h = (h[0], h[1], float(t2 @ at2) - nt[1] * nt[1] / nn)  # H = [[h0, h1], [h1, h2]]
    m1, m2 = cone_impulse(g, h, b, mu_f, a)
    mu_n = a - b[0] * m1 - b[1] * m2
    dk = (
        a * nv
        + 0.5 * a * a * nn
        + g[0] * m1
        + g[1] * m2
        + 0.5 * (h[0] * m1 * m1 + 2 * h[1] * m1 * m2 + h[2] * m2 * m2)
    )
    return mu_n, np.array([m1, m2]), dk, an, np.stack([at1, at2])


def _eigen(h):
    """Eigenvalues ``l1 <= l2`` of the symmetric 2x2 ``[[h0, h1], [h1, h2]]`` and the unit eigenvector
    ``(c, s)`` of ``l1`` (that of ``l2`` is ``(-s, c)``)."""
    mean, half = 0.5 * (h[0] + h[2]), 0.5 * (h[0] - h[2])
    rad = math.hypot(half, h[1])
    if rad == 0.0:
        return mean, mean, 1.0, 0.0
    ang = 0.5 * math.atan2(h[1], half)  # the eigenvector of the larger eigenvalue is (cos ang, sin ang)
    return mean - rad, mean + rad, -math.sin(ang), math.cos(ang)


def _widen(f, hi: float) -> tuple[float, float]:
    """``(hi, f(hi))`` with ``hi`` doubled until ``f(hi) >= 0``, at most ``CONE_ITER`` times (``f(hi) < 0`` if
    it never held): a cone root's upper end (C ``<model>_widen``)."""
    f_hi = f(hi)
    for _ in range(CONE_ITER):
        if f_hi >= 0.0:
            break
        hi *= 2.0
        f_hi = f(hi)
    return hi, f_hi


def _illinois_up(fn, lo: float, hi: float, f_lo: float, f_hi: float) -> float:
    """Illinois on ``[lo, hi]`` for the root of increasing ``fn`` (``f_lo <= 0 <= f_hi``): the end where
    ``fn >= 0`` once the bracket is as narrow as the doubles allow (or ``fn = 0``). Illinois' steps
    (:func:`~vcigen.held_roots.illinois_point`, :func:`~vcigen.held_roots.illinois_update`) on ``g = -fn``,
    which has their signs."""
    g_lo, g_hi, side = -f_lo, -f_hi, 0
    for _ in range(CONE_ITER):
        c = illinois_point(lo, g_lo, hi, g_hi)
        if not lo < c < hi:
            break  # the bracket is as narrow as the doubles allow
        fc = fn(c)
        if fc == 0.0:
            return c
        lo, g_lo, hi, g_hi, side = illinois_update(lo, g_lo, hi, g_hi, side, c, -fc)
        if hi - lo <= 4e-16 * hi:
            break
    return hi


def cone_impulse(g, h, b, mu_f: float, a: float) -> tuple[float, float]:
    """``argmin g.m + m.H m / 2`` over ``|m| <= mu_f (a - b.m)`` (``m`` in R^2, ``H = [[h0, h1], [h1, h2]]``
    positive definite, ``a > 0``): exact, by two monotone 1-D roots.

    The set is convex (a slice of Coulomb's cone), so the minimiser is unique. If the unconstrained one
    ``-H^-1 g`` is inside, it is the answer (stick). Else it is ``m(nu)``, the minimiser of the Lagrangian
    ``g.m + m.H m / 2 + nu (|m| + mu_f b.m)``, at the multiplier ``nu > 0`` where
    ``c(nu) = |m(nu)| - mu_f (a - b.m(nu))`` reaches 0; ``c`` is the derivative of the concave dual, so
    it decreases with ``nu``. For one
    ``nu``, with ``gt = g + nu mu_f b``: ``m = 0`` if ``|gt| <= nu``, else ``m = -(H + sI)^-1 gt`` at the
    ``s > 0`` where ``|s (H + sI)^-1 gt| = nu``, increasing in ``s`` and bracketed by the eigenvalues of
    ``H``. The root returned is the feasible end of the last bracket: the impulse is inside the cone.
    """
    det = h[0] * h[2] - h[1] * h[1]
    if not (mu_f > 0.0 and a > 0.0 and h[0] > 0.0 and det > 0.0):
        return 0.0, 0.0
    m1, m2 = -(h[2] * g[0] - h[1] * g[1]) / det, -(h[0] * g[1] - h[1] * g[0]) / det
    if math.hypot(m1, m2) <= mu_f * (a - b[0] * m1 - b[1] * m2):
        return m1, m2  # stick
    l1, l2, c, s = _eigen(h)

    def lagrangian_min(nu: float) -> tuple[float, float]:
        gt = (g[0] + nu * mu_f * b[0], g[1] + nu * mu_f * b[1])
        norm = math.hypot(*gt)
        if norm <= nu:
            return 0.0, 0.0
        y1, y2 = c * gt[0] + s * gt[1], -s * gt[0] + c * gt[1]  # gt in H's eigenbasis

        def excess(sh: float) -> float:  # |sh (H + sh I)^-1 gt| - nu, increasing in sh
            return math.hypot(sh * y1 / (l1 + sh), sh * y2 / (l2 + sh)) - nu

        lo, hi = nu * l1 / (norm - nu), nu * l2 / (norm - nu)
        sh = _illinois_up(excess, lo, hi, excess(lo), excess(hi)) if hi > lo else lo
        z1, z2 = -y1 / (l1 + sh), -y2 / (l2 + sh)
        return c * z1 - s * z2, s * z1 + c * z2

    def infeasible(nu: float) -> float:  # -c(nu): increasing in nu
        p1, p2 = lagrangian_min(nu)
        return mu_f * (a - b[0] * p1 - b[1] * p2) - math.hypot(p1, p2)

    f_lo = infeasible(0.0)
    hi, f_hi = _widen(infeasible, max(math.hypot(*g), 1e-300))
    if f_hi < 0.0:
        return 0.0, 0.0
    nu = _illinois_up(infeasible, 0.0, hi, f_lo, f_hi)
    m1, m2 = lagrangian_min(nu)
    if g[0] * m1 + g[1] * m2 + 0.5 * (h[0] * m1 * m1 + 2 * h[1] * m1 * m2 + h[2] * m2 * m2) > 0.0:
        return 0.0, 0.0  # never above the frictionless law (round-off only)
    return m1, m2


def cone_slide(g, h, b, mu_f: float, a: float) -> tuple[float, float] | None:
    """Coulomb's sliding impulse of an isotropic cone held at an impact while held
    (``SustainedSteps._impulse_law``): the tangential impulse ``m`` (in R^2) with ``m = -mu_f N s``, ``s`` the
    unit tangential velocity *after*, ``N = a - b.m`` its normal impulse; ``0`` where ``a <= 0``; None where
    the stick ``-H^-1 g`` is inside the cone (or ``H`` is indefinite; singular to round-off, a tangent fixed
    by the law's other rows that cannot stick: the bracket starts at ``sigma = 1e-12 tr H``).

    The tangential velocity after is ``w = g + H m`` (``H = [[h0, h1], [h2, h3]]``, the law's Schur complement
    on the two stick rows, ``det H > 0``, ``tr H > 0``). Coulomb's law ``w = -sigma m``, ``sigma >= 0``, makes
    ``m = m(sigma) = -(H + sigma I)^-1 g``, so the slip direction is one unknown along a curve: the ``sigma >
    0`` where ``|m(sigma)| = mu_f (a - b.m(sigma))``. The room ``mu_f (a - b.m) - |m|`` is negative at ``sigma
    = 0`` (the stick is out of the cone) and ``-> mu_f a > 0`` as ``sigma -> oo``: a bracket (doubled until it
    holds) and Illinois' steps (:func:`_illinois_up`) to the last bit; the feasible end is returned (inside
    the cone). With ``b = 0`` and ``H`` symmetric this is :func:`cone_impulse`'s minimiser; with ``b != 0``
    maximal dissipation in Coulomb's sense (``m`` against the velocity after) is not the energy's minimum over
    the cone's slice, which :func:`cone_impulse` gives (its velocity after is along ``-(u + mu_f b)``)."""
    if not (mu_f > 0.0 and a > 0.0):
        return 0.0, 0.0  # no normal impulse (a < 0: the law's row check refuses it): no friction impulse
    det, tr = h[0] * h[3] - h[1] * h[2], h[0] + h[3]
    if not (det > -1e-12 * tr * tr and tr > 0.0):
        return None
    lo = 0.0 if det > 0.0 else 1e-12 * tr  # H singular to round-off (a tangent fixed by the law's other rows)

    def tangential(sg: float) -> tuple[float, float]:
        d = (h[0] + sg) * (h[3] + sg) - h[1] * h[2]
        return -((h[3] + sg) * g[0] - h[1] * g[1]) / d, -((h[0] + sg) * g[1] - h[2] * g[0]) / d

    def room(sg: float) -> float:  # mu_f N - |m|: < 0 out of the cone
        m1, m2 = tangential(sg)
        return mu_f * (a - b[0] * m1 - b[1] * m2) - math.hypot(m1, m2)

    f_lo = room(lo)
    if f_lo >= 0.0:
        return None  # the stick is inside the cone
    hi, f_hi = _widen(room, max(math.hypot(g[0], g[1]) / (mu_f * a), 2.0 * lo, 1e-300))
    if f_hi < 0.0:
        return None
    return tangential(_illinois_up(room, lo, hi, f_lo, f_hi))


def line_slide(g, h, b, mu_f: float, a: float) -> tuple[float, float] | None:
    """:func:`cone_slide` where ``H`` has rank 1 (``H = kappa u u^T``, a loose landing cone in
    ``ImpulseLaw._law_slide``): the law's other rows fix the cone's tangential velocity but along ``u`` (a box
    landing on two rough vertices, one sticking: the other can only turn about it), so it slides along ``u``
    with Coulomb's sliding impulse ``m = -mu_f N s u``, ``s = sign(u.g)``, ``N = a - b.m = a / (1 - mu_f s
    b.u)``; the impulse across ``u`` is the other rows' (two contacts' impulses along the line through them
    act alike). ``u``: ``H``'s larger column, normalised. ``0`` where ``a <= 0``; None where it sticks along
    ``u`` (``s u.g <= mu_f N kappa``, ``kappa = u.H u``) or ``g`` has a part across ``u`` beyond ``DEP_EPS
    |g|``."""
    if not (mu_f > 0.0 and a > 0.0):
        return 0.0, 0.0
    col = (h[0], h[2]) if math.hypot(h[0], h[2]) >= math.hypot(h[1], h[3]) else (h[1], h[3])
    norm = math.hypot(col[0], col[1])
    if not norm > 0.0:
        return None
    u = (col[0] / norm, col[1] / norm)
    kappa = u[0] * (h[0] * u[0] + h[1] * u[1]) + u[1] * (h[2] * u[0] + h[3] * u[1])
    gu = u[0] * g[0] + u[1] * g[1]
    across = math.hypot(g[0] - gu * u[0], g[1] - gu * u[1])
    if across > DEP_EPS * math.hypot(g[0], g[1]) or gu == 0.0 or not kappa > 0.0:
        return None
    s = math.copysign(1.0, gu)
    d = 1.0 - mu_f * s * (b[0] * u[0] + b[1] * u[1])
    if not d > 0.0:
        return None
    n = a / d
    if s * gu <= mu_f * n * kappa:
        return None  # it sticks along u
    return -mu_f * n * s * u[0], -mu_f * n * s * u[1]


def cone_law_tangent(scalars, dscalars: np.ndarray, mu_f: float, dmu_f, e: float, de):
    """The tangent of :func:`cone_law` in its branch (stick, or slip on the cone's edge): ``(rho, dK, drho,
    ddK, branch)``, ``rho = mu_t / mu_n`` the impulse direction's tangential shares (``n + rho_1 t1 + rho_2
    t2``), each ``d`` rows of the ``K`` columns of ``z`` (forward mode), ``branch`` 0 stick, 1 slip; ``None``
    where :func:`cone_impulse` gave its degenerate ``0`` (no derivative).

    ``scalars = (n.qdot, t1.qdot, t2.qdot, n.A n, n.A t1, n.A t2, t1.A t1, t1.A t2, t2.A t2)``, ``dscalars``
    their tangents (9, K). ``a``, ``b``, ``g``, ``H`` as in :func:`cone_law` (the same expressions in the
    same order), the minimiser ``m`` by :func:`cone_impulse` from them. Stick: ``H m + g = 0``, so ``dm =
    -H^-1 (dg + dH m)``. Slip: ``m`` and the multiplier ``nu > 0`` solve the law's defining equations (the
    Lagrangian's stationarity on the edge) ``F = [g + H m + nu (u + mu_f b); |m| - mu_f (a - b.m)] = 0``,
    ``u = m/|m|``; by the implicit-function theorem ``d(m, nu) = -J^-1 dF`` with the symmetric ``J = [[H +
    nu (I - u u^T)/|m|, w], [w^T, 0]]``, ``w = u + mu_f b`` (``nu`` from the first rows at ``m``: ``-(g + H
    m).w / w.w``). At the branch's boundary (``-H^-1 g`` on the cone's edge) it is a mode change: the branch
    taken is returned."""
    nv, t1v, t2v, nn, nt1, nt2, t11, t12, t22 = scalars
    dnv, dt1v, dt2v, dnn, dnt1, dnt2, dt11, dt12, dt22 = dscalars
    a = -(1.0 + e) * nv / nn
    da = -de * nv / nn - (1.0 + e) * (dnv * nn - nv * dnn) / (nn * nn)
    b = np.array([nt1 / nn, nt2 / nn])
    db = np.array([(dnt1 * nn - nt1 * dnn) / (nn * nn), (dnt2 * nn - nt2 * dnn) / (nn * nn)])
    g = np.array([t1v - b[0] * nv, t2v - b[1] * nv])
    dg = np.array([dt1v - db[0] * nv - b[0] * dnv, dt2v - db[1] * nv - b[1] * dnv])
    h = (t11 - nt1 * nt1 / nn, t12 - nt1 * nt2 / nn, t22 - nt2 * nt2 / nn)
    dh = (
        dt11 - (2.0 * nt1 * dnt1 * nn - nt1 * nt1 * dnn) / (nn * nn),
        dt12 - ((dnt1 * nt2 + nt1 * dnt2) * nn - nt1 * nt2 * dnn) / (nn * nn),
        dt22 - (2.0 * nt2 * dnt2 * nn - nt2 * nt2 * dnn) / (nn * nn),
    )
    hm = np.array([[h[0], h[1]], [h[1], h[2]]])
    m = np.array(cone_impulse(tuple(g), h, tuple(b), mu_f, max(a, 0.0)))
    det = h[0] * h[2] - h[1] * h[1]
    if not (mu_f > 0.0 and a > 0.0 and h[0] > 0.0 and det > 0.0):
        return None
    free = -np.array([h[2] * g[0] - h[1] * g[1], h[0] * g[1] - h[1] * g[0]]) / det
    # dH m and dg: the first rows' partials (both branches)
    dhm = np.array([dh[0] * m[0] + dh[1] * m[1], dh[1] * m[0] + dh[2] * m[1]])
    if math.hypot(*free) <= mu_f * (a - b[0] * free[0] - b[1] * free[1]):  # stick (cone_impulse's test)
        branch = 0
        dm = -np.linalg.solve(hm, dg + dhm)
    else:  # slip: the implicit-function theorem on the edge's equations
        branch = 1
        norm = math.hypot(*m)
        if norm == 0.0:
            return None
        u = m / norm
        w = u + mu_f * b
        nu = -float((g + hm @ m) @ w) / float(w @ w)
        jac = np.zeros((3, 3))
        jac[:2, :2] = hm + nu * (np.eye(2) - np.outer(u, u)) / norm
        jac[:2, 2] = jac[2, :2] = w
        d_f = np.vstack(
            [
                dg + dhm + nu * (np.outer(b, dmu_f) + mu_f * db),
                -dmu_f * (a - b @ m) - mu_f * (da - m @ db),
            ]
        )
        dm = -np.linalg.solve(jac, d_f)[:2]
    mu_n = a - b @ m
    dmu_n = da - m @ db - b @ dm
    dk = a * nv + 0.5 * a * a * nn + g @ m + 0.5 * m @ hm @ m
    ddk = (
        da * nv
        + a * dnv
        + a * da * nn
        + 0.5 * a * a * dnn
        + m @ dg
        + (g + hm @ m) @ dm
        + 0.5 * (dh[0] * m[0] * m[0] + 2.0 * dh[1] * m[0] * m[1] + dh[2] * m[1] * m[1])
    )
    rho = m / mu_n
    drho = (dm * mu_n - np.outer(m, dmu_n)) / (mu_n * mu_n)
    return rho, dk, drho, ddk, branch
