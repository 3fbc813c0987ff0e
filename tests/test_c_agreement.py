"""The C backend and the CasADi backend: one algorithm, two renderings, the same trajectories.

Positions, momenta, energies, impact times, points and impulses agree to 1e-10 on
every example and rule over a horizon with several impacts; parameters override
at run time in C; a failed step in C raises the same ``SolverError``.
"""

from __future__ import annotations

import shutil
from functools import cache
from pathlib import Path

import numpy as np
import pytest
import sympy as sp

import vcigen
from vcigen.cli import load_example
from vcigen.stepper import Stepper

pytestmark = pytest.mark.skipif(shutil.which("cc") is None, reason="no C compiler")

ROOT = Path(__file__).resolve().parents[1]
RULES = ["trapezoid", "midpoint"]
TOL = 1e-10
# The star is chaotic. Both backends take the same explicit grid steps, contact-time roots and
# closed-form jumps, so they agree bit for bit for a while; the first round-off difference (CasADi's
# SX vs the printed C, 1e-16 at the first impact) then grows about 30x per impact (midpoint: 2e-14
# at the fourth, 5.5e-12 at the fifth, 3.9e-11 at the sixth), so its horizon is 5 impacts.
N_IMPACTS = {"particle": 8, "star": 5}


@cache
def example(name: str):
    return load_example(ROOT / "examples" / f"{name}.py")


@cache
def sim(name: str, backend: str, rule: str) -> vcigen.Simulator:
    return vcigen.build(example(name).model(), backend=backend, rule=rule)


def run(name: str, backend: str, rule: str, **kw) -> vcigen.Result:
    s = example(name).SETUP
    kw.setdefault("n_impacts", N_IMPACTS[name])
    return sim(name, backend, rule).simulate(s["q0"], s["v0"], s["h"], **kw)


def assert_agree(a: vcigen.Result, b: vcigen.Result, tol: float = TOL) -> None:
    assert a.q.shape == b.q.shape and len(a.impacts) == len(b.impacts)
    np.testing.assert_allclose(a.t, b.t, rtol=0, atol=1e-12)
    np.testing.assert_allclose(a.q, b.q, rtol=0, atol=tol)
    np.testing.assert_allclose(a.p, b.p, rtol=0, atol=tol)
    np.testing.assert_allclose(a.energy, b.energy, rtol=0, atol=tol)
    for ia, ib in zip(a.impacts, b.impacts):
        assert (ia.contact, ia.step) == (ib.contact, ib.step)
        assert abs(ia.t - ib.t) <= tol and abs(ia.alpha - ib.alpha) <= tol / a.h
        assert abs(ia.impulse - ib.impulse) <= tol
        np.testing.assert_allclose(ia.q, ib.q, rtol=0, atol=tol)
        assert abs(ia.energy_after - ib.energy_after) <= tol


@pytest.mark.parametrize("rule", RULES)
@pytest.mark.parametrize("name", ["particle", "star"])
def test_c_and_casadi_trajectories_agree(name: str, rule: str) -> None:
    c, ca = run(name, "c", rule), run(name, "casadi", rule)
    assert len(c.impacts) == N_IMPACTS[name]
    assert_agree(c, ca)
    assert c.coordinate_names == ca.coordinate_names


@pytest.mark.parametrize("name", ["particle", "star"])
def test_fixed_horizon_agrees(name: str) -> None:
    c, ca = (
        run(name, "c", "trapezoid", n_impacts=None, t_end=2.0),
        run(name, "casadi", "trapezoid", n_impacts=None, t_end=2.0),
    )
    assert c.t[-1] == pytest.approx(2.0) and len(c.impacts) >= 1
    assert_agree(c, ca)


def test_long_run_resumes_across_chunks() -> None:
    """More than 1024 steps with n_impacts: the C loop resumes from (q, p) as buffers grow."""
    c, ca = (
        run("particle", "c", "midpoint", n_impacts=12),
        run("particle", "casadi", "midpoint", n_impacts=12),
    )
    assert c.t.size > 1025
    assert_agree(c, ca)


def test_params_override_in_c() -> None:
    g = sp.Symbol("g", positive=True)
    c, ca = (run("particle", b, "trapezoid", params={g: 3.7}, n_impacts=3) for b in ("c", "casadi"))
    assert_agree(c, ca)
    default = run("particle", "c", "trapezoid", n_impacts=3)
    assert abs(c.impacts[0].t - default.impacts[0].t) > 0.1
    named = run("particle", "c", "trapezoid", params={"g": 3.7}, n_impacts=3)
    assert_agree(named, c, 0.0)


def test_python_stepper_on_c_kernels_matches_the_c_loop() -> None:
    s, setup = sim("star", "c", "trapezoid"), example("star").SETUP
    kern = s.kernels.bind(s.model.resolve_params(None))
    py = Stepper(kern, s.tol).simulate(setup["q0"], setup["v0"], setup["h"], n_impacts=3)
    c = run("star", "c", "trapezoid", n_impacts=3)
    assert_agree(py, c, 1e-12)


@pytest.mark.parametrize("backend", ["c", "casadi"])
def test_solver_error_from_c_names_step_and_phase(backend: str) -> None:
    """No room for an impact in a step: the same SolverError from both backends."""
    model = example("particle").model()
    s = vcigen.build(model, backend=backend, tol=vcigen.Tolerances(max_impacts_per_step=0))
    setup = example("particle").SETUP
    with pytest.raises(vcigen.SolverError) as info:
        s.simulate(setup["q0"], setup["v0"], setup["h"], t_end=1.0)
    err = info.value
    assert (err.step, err.phase) == (45, "jump")
    assert err.time == pytest.approx(0.45)
    assert "more than 0 impacts in one step" in str(err)


def test_c_newton_failure_is_a_solver_error() -> None:
    """An unreachable residual tolerance fails the jump solve with phase and residual."""
    s = vcigen.build(example("star").model(), backend="c", tol=vcigen.Tolerances(residual=1e-300))
    setup = example("star").SETUP
    with pytest.raises(vcigen.SolverError) as info:
        s.simulate(setup["q0"], setup["v0"], setup["h"], t_end=1.0)
    assert info.value.phase in {"smooth", "contact time", "jump"} and info.value.residual > 0
    assert f"step {info.value.step} " in str(info.value)


def test_configuration_dependent_mass_uses_the_c_newton_and_agrees() -> None:
    """A particle in polar coordinates: the smooth step is a Newton solve in C, not a division."""
    r, th, rd, thd = sp.symbols("r theta rd thetad")
    g = sp.Symbol("g", positive=True)
    model = vcigen.Model(
        name="polar",
        q=[r, th],
        qdot=[rd, thd],
        lagrangian=(rd**2 + r**2 * thd**2) / 2 - g * r * sp.sin(th),
        contacts={"floor": r * sp.sin(th) + 1},
        params={g: 9.81},
    )
    q0, v0 = [1.0, 0.3], [0.5, 1.0]
    c, ca = (vcigen.build(model, backend=b).simulate(q0, v0, 0.01, n_impacts=3) for b in ("c", "casadi"))
    assert len(c.impacts) == 3
    assert_agree(c, ca)
