"""The closed held step on a quadric's row (vcigen.held.closed_forms, rows that are not ``fixed``).

A row whose zero set is a quadric ``F = 0`` (an ellipse's, a paraboloid's, a circle's under an anisotropic
mass) held alone: RATTLE's position step ``q1 = a + Lam b`` (``b = h J^-1 grad F(q0)``) is the quadratic
``F(a + Lam b) = A Lam^2 + B Lam + C = 0``, but ``A`` and the projection's ``W = grad F . M^-1 grad F``
vary along the row. The step forms ``A`` at its start and ``W`` at its end: where ``Hess F`` is definite
the root is the fixed rows' ``nu = sqrt(D) - B`` divided by ``2 A`` off the state's chain; else (a
paraboloid, whose ``A`` is 0 at its vertex) ``Lam = -2C / (B + sqrt(D))``. Checked here: detection, each
step against the held Newton (the closed form off) and against RATTLE's equations themselves, the C loop
(``<model>_held_closed_loop``, which carries the direction at a step's end to the next) against CasADi's
Newton, the tangent through it against central differences, and the motion against scipy.
"""

from __future__ import annotations

import math
import shutil
from functools import cache

import numpy as np
import pytest
import sympy as sp
from scipy.integrate import solve_ivp
from test_held_closed import closed_and_newton

import vcigen
from vcigen import held, held_step
from vcigen.derive import derive

X, Y, Z, XD, YD, ZD = sp.symbols("x y z xd yd zd")
G = 9.81
A_AX, B_AX = 1.5, 0.75  # the ellipse x^2 + 4 y^2 = 2.25
needs_cc = pytest.mark.skipif(shutil.which("cc") is None, reason="no C compiler")


def _planar(name: str, psi, masses=(1, 1)) -> vcigen.Model:
    kinetic = (masses[0] * XD**2 + masses[1] * YD**2) / 2
    return vcigen.Model(
        name=name, q=[X, Y], qdot=[XD, YD], lagrangian=kinetic - masses[1] * G * Y, contacts={"row": psi}
    )


def _ellipse() -> vcigen.Model:
    return _planar("hq_ellipse", 3 - 2 * sp.sqrt(X**2 + 4 * Y**2))


def _aniso() -> vcigen.Model:
    return _planar("hq_aniso", 1 - sp.sqrt(X**2 + Y**2), (1, 3))


def _valley() -> vcigen.Model:
    return _planar("hq_valley", Y - X**2 / 2)


def _ellipsoid() -> vcigen.Model:
    return vcigen.Model(
        name="hq_ellipsoid",
        q=[X, Y, Z],
        qdot=[XD, YD, ZD],
        lagrangian=(XD**2 + YD**2 + ZD**2) / 2 - G * Z,
        contacts={"row": 1 - X**2 / 4 - Y**2 - Z**2 / 2},
    )


QUADRICS = {  # name: (model, Hess F definite, F in q (for the geometry checks), masses)
    "ellipse": (_ellipse, True, lambda q: q[0] ** 2 + 4 * q[1] ** 2 - 2.25, (1.0, 1.0)),
    "aniso": (_aniso, True, lambda q: q[0] ** 2 + q[1] ** 2 - 1.0, (1.0, 3.0)),
    "valley": (_valley, False, lambda q: q[1] - q[0] ** 2 / 2, (1.0, 1.0)),
    "ellipsoid": (_ellipsoid, True, lambda q: q[0] ** 2 / 4 + q[1] ** 2 + q[2] ** 2 / 2 - 1.0, (1.0,) * 3),
}


def _grad(name: str, q: np.ndarray) -> np.ndarray:
    """grad F (of QUADRICS' F) at q, by hand."""
    x = q
    return {
        "ellipse": lambda: np.array([2 * x[0], 8 * x[1]]),
        "aniso": lambda: np.array([2 * x[0], 2 * x[1]]),
        "valley": lambda: np.array([-x[0], 1.0]),
        "ellipsoid": lambda: np.array([x[0] / 2, 2 * x[1], x[2]]),
    }[name]()


@pytest.mark.parametrize("name", sorted(QUADRICS))
def test_quadric_rows_are_closed_not_fixed(name: str) -> None:
    """A quadric's row has the closed step with ``A`` and ``W`` in ``q`` (not ``fixed``), the definite ones
    on the fixed rows' root; the structure (both backends read it) and the generated header say so."""
    model, definite = QUADRICS[name][:2]
    system = derive(model())
    assert system.structure.held_closed == (True,)
    (cf,) = held.closed_forms(system)
    assert not cf.fixed and cf.definite == definite
    assert cf.w0.free_symbols & set(system.routines["rows"].input("q").symbols)
    text = " ".join(system.structure.lines())
    assert "a quadric's: [1]" in " ".join(text.split())


def test_definite_is_sylvesters_criterion() -> None:
    """``held.definite``: positive or negative definite (symbolic positive entries too); semidefinite and
    indefinite matrices are not."""
    a, b = sp.symbols("a b", positive=True)
    assert held.definite(sp.Matrix([[2, 0], [0, 3]]))
    assert held.definite(sp.Matrix([[-2, 1], [1, -3]]))
    assert held.definite(sp.diag(2 / a**2, 2 / b**2))
    assert not held.definite(sp.Matrix([[2, 0], [0, 0]]))
    assert not held.definite(sp.Matrix([[0, 1], [1, 0]]))
    assert not held.definite(sp.Matrix([[1, 2], [2, 1]]))


def _kernels(model):
    s = vcigen.build(model(), backend="casadi")
    return s, s.kernels.bind(s.model.resolve_params(None))


def _states(name: str, rng, count: int):
    """Points on the row, pressed into it by gravity, with momenta whose velocity is tangent; the valley's
    include its vertex (A = 0 there)."""
    masses = np.array(QUADRICS[name][3])
    for k in range(count):
        if name == "ellipse":
            t = rng.uniform(-math.pi + 0.3, -0.3)
            q = np.array([A_AX * math.cos(t), B_AX * math.sin(t)])
        elif name == "aniso":
            t = rng.uniform(-math.pi + 0.3, -0.3)
            q = np.array([math.cos(t), math.sin(t)])
        elif name == "valley":
            x = 0.0 if k < 2 else rng.uniform(-1.5, 1.5)
            q = np.array([x, x * x / 2])
        else:
            d = rng.normal(size=3)
            d[2] = -abs(d[2]) - 0.3
            q = d / math.sqrt(d[0] ** 2 / 4 + d[1] ** 2 + d[2] ** 2 / 2)
        n = _grad(name, q)
        u = rng.normal(size=len(q))
        u -= (u @ n) / (n @ n) * n
        speed = 0.0 if k == 0 else rng.uniform(0.0, 4.0)
        yield q, masses * speed * u / np.linalg.norm(u)


@pytest.mark.parametrize("name", sorted(QUADRICS))
@pytest.mark.parametrize("h", [1e-5, 1e-3, 1e-2])
def test_quadric_step_is_rattle_and_the_held_newton(name: str, h: float) -> None:
    """From states on the row, the closed step and the held Newton (the closed form off) take the same steps,
    to the Newton's tolerance; and the closed step solves RATTLE's equations: ``q1`` on the row, ``q1 - a``
    along ``J^-1 grad F(q0)``, the end velocity ``M^-1 p1`` tangent at ``q1``."""
    s, k = _kernels(QUADRICS[name][0])
    form, masses = QUADRICS[name][2], np.array(QUADRICS[name][3])
    taken = 0
    for q, p in _states(name, np.random.default_rng(5), 30):
        fast, slow = closed_and_newton(s, k, q, p, h)
        if fast is None:
            continue
        taken += 1
        scale = 1.0 + np.abs(p).max()
        np.testing.assert_allclose(fast.q1, slow.q1, rtol=0, atol=2 * held_step.ABSTOL)
        np.testing.assert_allclose(fast.p1, slow.p1, rtol=0, atol=2 * held_step.ABSTOL * scale)
        assert fast.energy == pytest.approx(slow.energy, abs=1e-12 * scale**2)
        # psi(q1) = 0 fixes Lam only to the rounding of q1 (eps |q1| / h in v), which Lam and Lam' each carry
        # and their sum (the impulse booked) does not: read from one nu (held.closed_routines)
        kc = k.held_consts(h)
        v0, jinv = k.held_free(q, p, kc)
        line = h * jinv * k.held_rows(q, kc)[1][: len(q)]  # q1 - a per unit Lam: the Newton's q1 within 1e-13
        lam_tol = 2 * held_step.ABSTOL / np.linalg.norm(line)
        np.testing.assert_allclose(fast.lam, slow.lam, rtol=0, atol=lam_tol)
        np.testing.assert_allclose(fast.lam + fast.lam1, slow.lam + slow.lam1, rtol=0, atol=1e-13 * scale)
        # RATTLE's equations, by hand
        assert abs(form(fast.q1)) <= 8e-16 * (1 + np.abs(fast.q1).max()) ** 2
        step, normal = fast.q1 - (q + h * v0), _grad(name, q) / masses
        cross = step - (step @ normal) / (normal @ normal) * normal
        assert np.linalg.norm(cross) <= 1e-15 * (1 + np.linalg.norm(step) / h)
        n1 = _grad(name, fast.q1)
        assert abs(n1 @ (fast.p1 / masses)) <= 4e-16 * np.linalg.norm(n1) * scale * 4
    assert taken >= 10


@cache
def _ellipse_reference(theta0: float, t_end: float):
    """scipy on the ellipse x = a cos th, y = b sin th (unit mass, held throughout):
    (a^2 s^2 + b^2 c^2) th'' = -(a^2 - b^2) s c th'^2 - g b c; the constraint force f = q'' + (0, g)."""
    a, b = A_AX, B_AX

    def rhs(_t, z):
        th, w = z
        c, s = np.cos(th), np.sin(th)
        return [w, (-(a * a - b * b) * s * c * w * w - G * b * c) / (a * a * s * s + b * b * c * c)]

    sol = solve_ivp(
        rhs, (0.0, t_end), [theta0, 0.0], method="DOP853", rtol=1e-12, atol=1e-12, dense_output=True
    )

    def state(t):
        th, w = sol.sol(t)
        acc = np.array(rhs(0.0, [th, w]))[1]
        c, s = np.cos(th), np.sin(th)
        q = np.stack([a * c, b * s], axis=-1)
        qdd = np.stack([-a * c * w * w - a * s * acc, -b * s * w * w + b * c * acc], axis=-1)
        return q, qdd + np.array([0.0, G])

    return state


@pytest.mark.parametrize("backend", ["casadi", pytest.param("c", marks=needs_cc)])
def test_sliding_in_an_ellipse_is_second_order_against_scipy(backend: str) -> None:
    """Released at rest on the ellipse, the particle slides in it (held throughout, every step the quadric
    step): its path and its normal force ``lambda |grad psi|`` (the step's, against scipy's at the step's
    midpoint) are second order in h against scipy's reduced equation."""
    theta0, t_end = -math.pi / 2 + 0.9, 1.0
    ref = _ellipse_reference(theta0, t_end)
    sim = vcigen.build(_ellipse(), backend=backend)
    q0 = [A_AX * math.cos(theta0), B_AX * math.sin(theta0)]
    errs, ferrs = [], []
    for h in (2e-3, 1e-3):
        res = sim.simulate(q0, [0.0, 0.0], h, t_end=t_end, progress=False)
        assert res.active.all() and not res.liftoffs and not res.impacts
        q_ref, _ = ref(res.t)
        errs.append(np.abs(res.q - q_ref).max())
        mid = (res.t[:-1] + res.t[1:]) / 2
        qm, f_ref = ref(mid)
        grad_psi = np.linalg.norm((4 / 3) * np.stack([qm[:, 0], 4 * qm[:, 1]], axis=-1), axis=1)
        ferrs.append(np.abs(res.contact_force[:, 0] * grad_psi - np.linalg.norm(f_ref, axis=1)).max())
    assert errs[1] <= 1e-4
    assert 3.5 <= errs[0] / errs[1] <= 4.5, errs
    assert ferrs[1] <= 1e-5 * G and 3.5 <= ferrs[0] / ferrs[1] <= 4.5, ferrs


@needs_cc
@pytest.mark.parametrize(
    ("name", "q0", "v0"),
    [
        ("ellipse", [1.2, -0.45], [0.0, 0.0]),
        ("valley", [0.8, 0.32], [0.0, 0.0]),
        ("ellipsoid", [0.5, 0.3, -1.2], [0.4, -0.3, 0.15]),
    ],
)
def test_c_closed_loop_is_the_held_newton(name: str, q0, v0) -> None:
    """The C loop of the closed step (the direction carried from a step's end) on an ellipse, the valley
    (through its vertex, where A = 0) and an ellipsoid, 2000 held steps, against CasADi's held Newton (the
    closed form off): the same run to the Newton's tolerance."""
    from test_c_agreement_sustained import _same_to_newton_tolerance

    from vcigen.stepper import Stepper

    model, form = QUADRICS[name][0], QUADRICS[name][2]
    q0, v0 = np.array(q0), np.array(v0)
    if name == "ellipsoid":  # onto the row below (0.5, 0.3), v0 onto its tangent plane
        q0[2] = -math.sqrt(2 * (1 - q0[0] ** 2 / 4 - q0[1] ** 2))
        n = _grad(name, q0)
        v0 -= (v0 @ n) / (n @ n) * n
    assert abs(form(q0)) <= 1e-15
    c = vcigen.build(model(), backend="c").simulate(q0, v0, 1e-3, t_end=2.0, progress=False)
    s, k = _kernels(model)
    k.held_closed = [False]
    newton = Stepper(k, s.tol).simulate(q0, v0, 1e-3, t_end=2.0)
    assert c.active[1:].all() and not c.liftoffs
    if name == "valley":
        assert (np.diff(np.sign(c.q[:, 0])) != 0).sum() >= 2  # through the vertex
    _same_to_newton_tolerance(c, newton)


@pytest.mark.parametrize("backend", ["casadi", pytest.param("c", marks=needs_cc)])
def test_a_run_with_its_tangent_takes_the_same_quadric_steps(backend: str) -> None:
    """The tangent reads each closed step's Lam, Lam' (the C run with it takes the step of
    <model>_held_closed_step, the run without it the closed loop's): the same steps bit for bit, and the
    tangent through 400 held steps on the ellipse is the central differences' along q0 and v0 along the
    row."""
    sim = vcigen.build(_ellipse(), backend=backend)
    theta0 = -math.pi / 2 + 0.6
    q0 = np.array([A_AX * math.cos(theta0), B_AX * math.sin(theta0)])
    t0 = np.array([-A_AX * math.sin(theta0), B_AX * math.cos(theta0)])
    t0 /= np.linalg.norm(t0)
    x0 = np.array([*q0, *(0.5 * t0)])

    def run(x, sens=False):
        return sim.simulate(x[:2], x[2:], 1e-3, t_end=0.4, progress=False, sensitivities=sens)

    plain, tan = run(x0), run(x0, True)
    assert plain.active[1:].all() and np.array_equal(plain.q, tan.q) and np.array_equal(plain.p, tan.p)
    assert not tan.sensitivity_breaks
    for d in ([*t0, 0, 0], [0, 0, *t0]):
        d = np.array(d, float)
        eps = 1e-6
        hi, lo = run(x0 + eps * d), run(x0 - eps * d)
        fd = (np.r_[hi.q[-1], hi.p[-1]] - np.r_[lo.q[-1], lo.p[-1]]) / (2 * eps)
        np.testing.assert_allclose(tan.sensitivity[-1] @ d, fd, rtol=0, atol=1e-6 * (1 + np.abs(fd).max()))


@pytest.mark.parametrize("backend", ["casadi", pytest.param("c", marks=needs_cc)])
@pytest.mark.parametrize("name", ["ellipse", "aniso", "valley", "ellipsoid"])
def test_a_carried_closed_step_is_the_fresh_step(backend: str, name: str) -> None:
    """The C loop starts each closed step's line from the previous step's p+ before its projection (w = (p+,
    Lam'), carried; the Python stepper alike): the root absorbs that move along the row's gradient, so a step
    from the carried w and one from (q, p) alone are the same step to round-off, end state and Lam, Lam'
    (Lam, Lam' to 1e-12: v's rounding, eps |q| / h, times the gradient), over 300 held steps of
    h = 1e-2 (the valley from rest at x = 0.8 through its vertex)."""
    sim = vcigen.build(QUADRICS[name][0](), backend=backend)
    k = sim.kernels.bind(sim.model.resolve_params(None))
    grad = _kernels(QUADRICS[name][0])[1]  # CasADi's, for the row's gradient
    act, tol, h = np.ones(1, dtype=bool), sim.tol, 1e-2
    q, p = next(_states(name, np.random.default_rng(3), 1))
    if name == "valley":
        q, p = np.array([0.8, 0.32]), np.zeros(2)
    x0, w, lp_seen, crossed = q[0], None, 0.0, False
    for _ in range(300):
        held, w1 = k.closed_step(q, p, w, 0, act, h, tol.residual, tol.phi)
        fresh, _ = k.closed_step(held.q1, held.p1, None, 0, act, h, tol.residual, tol.phi)
        carried, w = k.closed_step(held.q1, held.p1, w1, 0, act, h, tol.residual, tol.phi)
        scale = 1.0 + np.abs(held.p1).max()
        np.testing.assert_allclose(carried.q1, fresh.q1, rtol=0, atol=1e-14 * (1 + np.abs(q).max()))
        np.testing.assert_allclose(carried.p1, fresh.p1, rtol=0, atol=1e-14 * scale)
        np.testing.assert_allclose(carried.lam, fresh.lam, rtol=0, atol=1e-12 * scale)
        np.testing.assert_allclose(carried.lam1, fresh.lam1, rtol=0, atol=1e-12 * scale)
        g1 = grad.held_rows(held.q1, grad.held_consts(h))[1][0]
        np.testing.assert_allclose(w1[:-1], held.p1 - held.lam1[0] * g1, rtol=0, atol=1e-14 * scale)  # p+
        lp_seen = max(lp_seen, abs(w1[-1]))
        q, p = held.q1, held.p1
        crossed |= bool(q[0] * x0 < 0)
    assert lp_seen > 1e-6  # the carried Lam' is not 0: the line did move
    assert crossed or name != "valley"  # through the vertex
