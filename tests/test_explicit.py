"""The explicit grid step (vcigen.explicit): detection, hoisting, exactness, and both backends on it.

A scene with a constant diagonal mass whose smooth residual (46) is linear in v
takes its smooth grid steps as straight-line code with the subexpressions of
(h, par) hoisted into run constants. These tests check that the routines solve
(46) exactly, that hoisting changes nothing but the evaluation order, that both
backends run the same formula (bit-identical trajectories until the first
impact), and that a step going non-finite is reported at the step where it does.
"""

from __future__ import annotations

import numpy as np
import pytest
import sympy as sp
from hard_scenes import backend_param, walls_oscillator
from hard_scenes import double_pendulum as double_pendulum_model
from scenes import billiard, load_example, star_nonlinear

import vcigen
from vcigen.errors import NONFINITE
from vcigen.explicit import grid_routines, hoist, jump_quadratic
from vcigen.impact_step import quadratic_root

RULES = ["trapezoid", "midpoint"]
BACKENDS = [backend_param("casadi"), backend_param("c")]


def _model(name: str) -> vcigen.Model:
    makers = {
        "star_nonlinear": star_nonlinear,
        "walls_oscillator": walls_oscillator,
        "double_pendulum": double_pendulum_model,
        "billiard": billiard,
    }
    return makers[name]() if name in makers else load_example(name).model()


@pytest.mark.parametrize(
    "name,rule,expected",
    [
        ("particle", "trapezoid", True),
        ("particle", "midpoint", True),
        ("star", "trapezoid", True),
        ("star", "midpoint", True),
        ("star_nonlinear", "trapezoid", True),  # trapezoid: p- = M v + h/2 grad V(q0), linear in v
        ("star_nonlinear", "midpoint", False),  # V at the midpoint: (46) is nonlinear in v
        ("walls_oscillator", "midpoint", True),  # quadratic V: linear either way
        ("double_pendulum", "trapezoid", False),  # configuration-dependent mass
        ("billiard", "trapezoid", True),  # quartic V: linear once (4 q + 4 h v)/4 - (q + h v) cancels
        ("billiard", "midpoint", False),
    ],
)
def test_explicit_detection(name: str, rule: str, expected: bool) -> None:
    assert vcigen.derive(_model(name), rule).structure.explicit_grid is expected


def test_hoist_groups_invariants_and_keeps_the_value() -> None:
    p, q, m, g, h = sp.symbols("p q m g h", real=True)
    exprs = [(p - h * g * m / 2) / m, m * g * (q + h * p / m) + sp.sin(h * g) * q]
    consts, out = hoist(exprs, {p, q})
    # no division and no parameter left outside the constants
    for e in out:
        assert e.free_symbols <= {p, q} | {k for k, _ in consts}
        assert not any(b.is_Pow and b.exp.is_negative for b in sp.preorder_traversal(e))
    back = {k: v for k, v in consts}
    for e, o in zip(exprs, out):
        assert sp.simplify(o.xreplace(back) - e) == 0
    # invariants shared between outputs become one constant
    assert len({v for _, v in consts}) == len(consts)


def test_hoist_keeps_a_number_factored_out_of_a_sum() -> None:
    """A number factored out of a sum (``sympy.factor_terms``) becomes a constant, so that CSE's basic
    optimizations do not distribute it again: one product, not one a term. Other numbers stay literal."""
    y0, y1, k = sp.symbols("y0 y1 k", real=True)
    factored = sp.factor_terms(sp.Float(4.905) * y0 + sp.Float(4.905) * y1)
    consts, (out,) = hoist([factored + 2 * k * y0], {y0, y1})
    assert [v for _, v in consts] == [sp.Float(4.905), 2 * k]
    (c, _), (ck, _) = consts
    assert out == c * (y0 + y1) + ck * y0
    _, (reduced,) = sp.cse([out], optimizations="basic")
    assert reduced.count_ops(visual=True).coeff(sp.Symbol("MUL")) == 2  # c (y0 + y1), ck y0


def _numeric(routine: vcigen.routines.Routine, *args: np.ndarray) -> list[np.ndarray]:
    syms = [s for a in routine.inputs for s in a.symbols]
    f = sp.lambdify(syms, [o.expr for o in routine.outputs], modules="numpy")
    flat = np.concatenate([np.atleast_1d(np.asarray(a, dtype=float)) for a in args])
    return [np.asarray(o, dtype=float).reshape(-1) for o in f(*flat)]


@pytest.mark.parametrize(
    "name,rule",
    [
        ("particle", "trapezoid"),
        ("star", "midpoint"),
        ("star_nonlinear", "trapezoid"),
        ("walls_oscillator", "midpoint"),
    ],
)
def test_grid_step_solves_the_smooth_step_exactly(name: str, rule: str) -> None:
    """v of grid_step zeroes the residual (46); p1, E_d, phi and d are the general routines' values."""
    system = vcigen.derive(_model(name), rule)
    consts, step, end = grid_routines(system)
    r = system.routines
    par = np.array([float(v) for v in system.model.defaults.values()])
    rng = np.random.default_rng(1)
    h = 0.01
    for _ in range(5):
        q0, p0 = rng.uniform(-1.0, 1.0, system.n), rng.normal(size=system.n)
        (k,) = _numeric(consts, [h], par)
        v, p1, e = _numeric(step, q0, p0, k)
        (res, _) = _numeric(r["smooth"], v, q0, p0, [h], par)
        assert np.max(np.abs(res)) <= 1e-13 * (1 + np.max(np.abs(p0)))
        p_minus, p_plus, energy = _numeric(r["segment"], q0, v, [h], par)
        np.testing.assert_allclose(p1, p_plus, rtol=0, atol=1e-13)
        assert e[0] == pytest.approx(energy[0], rel=1e-13, abs=1e-13)
        q1 = q0 + h * v
        phi, d = _numeric(end, q1, p1, k)
        phi_ref, grad = _numeric(r["contacts"], q1, par)
        mom, mass = _numeric(r["legendre"], q1, v, par)
        vel = v + np.linalg.solve(mass.reshape(system.n, system.n), p1 - mom)
        np.testing.assert_allclose(phi, phi_ref, rtol=0, atol=1e-13)
        np.testing.assert_allclose(d, h * grad.reshape(system.m, system.n) @ vel, rtol=1e-12, atol=1e-13)


@pytest.mark.parametrize("name", ["particle", "star"])
def test_explicit_step_has_no_division(name: str) -> None:
    """Every division depends on (h, par) alone, so it sits in grid_consts, outside the loop."""
    _, step, end = grid_routines(vcigen.derive(_model(name), "trapezoid"))
    for routine in (step, end):
        for o in routine.outputs:
            for e in o.expr:
                assert not any(b.is_Pow and b.exp.is_negative for b in sp.preorder_traversal(e)), e


@pytest.mark.parametrize(
    "name,rule,setup",
    [
        ("star", "trapezoid", None),
        ("star", "midpoint", None),
        ("billiard", "trapezoid", {"q0": [0.2, 0.0], "v0": [0.3, 1.5], "h": 0.01}),  # nonlinear force
    ],
)
def test_backends_are_bit_identical_until_the_first_impact(name: str, rule: str, setup: dict | None) -> None:
    """One formula, two renderings: the same floating-point operations on every smooth grid step."""
    pytest.importorskip("vcigen.backends.c")
    s = setup or load_example(name).SETUP
    model = _model(name)
    runs = [
        vcigen.build(model, backend=b, rule=rule).simulate(s["q0"], s["v0"], s["h"], n_impacts=1)
        for b in ("c", "casadi")
    ]
    first = runs[0].impacts[0].step
    assert first > 50  # a long stretch of smooth steps
    np.testing.assert_array_equal(runs[0].q[: first + 1], runs[1].q[: first + 1])
    np.testing.assert_array_equal(runs[0].p[: first + 1], runs[1].p[: first + 1])


def _sqrt_well(contacts: bool) -> vcigen.Model:
    """V = -sqrt(x): the force is NaN once x < 0, which a particle thrown at x = 0 reaches."""
    x, xd = sp.symbols("x xd")
    return vcigen.Model(
        name="sqrt_well",
        q=[x],
        qdot=[xd],
        lagrangian=xd**2 / 2 + sp.sqrt(x),
        contacts={"wall": x + 10} if contacts else {},
    )


@pytest.mark.parametrize("contacts", [False, True], ids=["no contacts", "a far wall"])
@pytest.mark.parametrize("rule", RULES)
@pytest.mark.parametrize("backend", BACKENDS)
def test_a_non_finite_step_is_reported_where_it_happens(backend: str, rule: str, contacts: bool) -> None:
    sim = vcigen.build(_sqrt_well(contacts), backend=backend, rule=rule)
    with pytest.raises(vcigen.SolverError) as info:
        sim.simulate([1.0], [-5.0], 0.01, t_end=1.0)
    err = info.value
    assert (err.phase, err.reason) == ("smooth", NONFINITE)
    assert not np.isfinite(err.residual)
    # the result up to the failed step is kept, all of it finite, and the step is the first to go below 0
    kept = err.result
    assert len(kept.t) == err.step + 1 and kept.t[-1] == pytest.approx(err.time)
    assert np.isfinite(kept.q).all() and np.isfinite(kept.p).all() and np.isfinite(kept.energy).all()
    assert kept.q[-1, 0] > 0
    ok = sim.simulate([1.0], [-5.0], 0.01, t_end=err.time)  # the same steps, without the failing one
    np.testing.assert_array_equal(ok.q, kept.q)
    assert err.step == 20


@pytest.mark.parametrize("backend", BACKENDS)
def test_a_solver_error_keeps_the_impacts_before_it(backend: str) -> None:
    """Bounces on a floor while drifting into y > 1, where V = -sqrt(1 - y) is NaN: nothing is lost."""
    x, y, xd, yd = sp.symbols("x y xd yd")
    model = vcigen.Model(
        name="drift",
        q=[x, y],
        qdot=[xd, yd],
        lagrangian=(xd**2 + yd**2) / 2 - 9.81 * x + sp.sqrt(1 - y),
        contacts={"floor": x},
    )
    sim = vcigen.build(model, backend=backend)
    with pytest.raises(vcigen.SolverError) as info:
        sim.simulate([0.1, 0.0], [0.0, 2.0], 0.01, t_end=5.0)
    kept = info.value.result
    assert kept.n_impacts >= 2 and all(im.step < info.value.step for im in kept.impacts)
    ok = sim.simulate([0.1, 0.0], [0.0, 2.0], 0.01, t_end=info.value.time)
    np.testing.assert_array_equal(ok.q, kept.q)
    assert [im.t for im in ok.impacts] == [im.t for im in kept.impacts]


@pytest.mark.parametrize("name,rule", [("particle", "trapezoid"), ("star", "midpoint")])
def test_jump_quadratic_roots_solve_the_jump(name: str, rule: str) -> None:
    """Both roots of a mu^2 + b mu + c, put into w = w0 + mu dw, zero the residual of (48)."""
    system = vcigen.derive(_model(name), rule)
    quad = jump_quadratic(system)
    assert quad is not None
    par = np.array([float(v) for v in system.model.defaults.values()])
    rng = np.random.default_rng(2)
    n = system.n
    for _ in range(5):
        # a jump with a known root mu_star: w_star leaves qc with p-(w_star) = p_in + mu_star n
        qc, nrm, w_star, mu_star, tau = (
            rng.uniform(-1, 1, n),
            rng.normal(size=n),
            rng.normal(size=n),
            0.7,
            0.004,
        )
        p_minus, _, (e_in,) = _numeric(system.routines["segment"], qc, w_star, [tau], par)
        p_in = p_minus - mu_star * nrm
        (a, b, c), w0, dw = _numeric(quad, qc, nrm, p_in, [e_in], [tau], par)
        roots = np.roots([a, b, c])
        assert np.min(np.abs(roots - mu_star)) < 1e-12
        for mu in roots:
            assert abs(mu.imag) < 1e-12
            x = np.append(w0 + mu.real * dw, mu.real)
            (res, _) = _numeric(system.routines["jump"], x, qc, nrm, p_in, [e_in], [tau], par)
            assert np.max(np.abs(res)) <= 1e-12 * (1 + abs(e_in) + np.max(np.abs(p_in)))


def test_jump_quadratic_needs_a_quadratic_energy() -> None:
    """Nonlinear gravity under the trapezoidal rule: explicit smooth step, but E_d is not quadratic in w."""
    system = vcigen.derive(_model("star_nonlinear"), "trapezoid")
    assert system.structure.explicit_grid and not system.structure.jump_quadratic
    assert jump_quadratic(system) is None


def test_quadratic_root_is_where_newton_goes() -> None:
    """The selected root is the one scalar Newton from mu_try converges to."""
    rng = np.random.default_rng(3)
    for _ in range(200):
        r0, r1 = sorted(rng.normal(size=2) * 10 ** rng.uniform(-3, 1, 2))
        a = rng.uniform(0.1, 2.0) * rng.choice([-1, 1])
        b, c = -a * (r0 + r1), a * r0 * r1
        mu_try = rng.normal() * 3
        mu = quadratic_root(a, b, c, mu_try)
        x = mu_try
        for _ in range(200):
            x -= (a * x * x + b * x + c) / (2 * a * x + b)
        assert mu == pytest.approx(x, rel=1e-9, abs=1e-12)
    assert quadratic_root(1.0, 0.0, 1.0, 0.5) is None  # no real root
    assert quadratic_root(0.0, 2.0, -1.0, 5.0) == 0.5  # linear
