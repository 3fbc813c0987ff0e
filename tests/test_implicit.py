"""The implicit grid step (vcigen.implicit): the hoisted routines are the smooth step's own, and the C
loop that carries the invariants from step to step runs the trajectory of the step that does not.

A scene whose smooth residual (46) is nonlinear in v (the double pendulum's M(q), the star under
nonlinear gravity with the midpoint rule) takes its grid steps by Newton on routines written in the
step's invariants of (q_k, h, par). These tests check, at random points, that those routines evaluate
to the smooth residual, its Jacobian, p+, E_d, phi, grad phi and the Legendre terms at q_k+1, that the
invariants handed to the next step are the invariants at q_k+1, and that in C the loop with the carry
agrees with the Python stepper on the same kernels (which computes the invariants afresh every step).
"""

from __future__ import annotations

import shutil

import numpy as np
import pytest
import sympy as sp
from hard_scenes import double_pendulum
from scenes import star_nonlinear

import vcigen
from vcigen.implicit import implicit_routines
from vcigen.routines import Routine
from vcigen.stepper import Stepper

RULES = ["trapezoid", "midpoint"]
# lobatto3 (internal points): its grid step is Newton on (v, u), u carried from the step before
ALL_RULES = [*RULES, "lobatto3"]
needs_cc = pytest.mark.skipif(shutil.which("cc") is None, reason="no C compiler")


def _numeric(r: Routine):
    """``r`` as a function of its named input vectors, returning its outputs as float arrays."""
    syms = [s for a in r.inputs for s in a.symbols]
    funs = [sp.lambdify(syms, list(o.expr), "numpy") for o in r.outputs]

    def call(**inputs):
        args = [float(x) for a in r.inputs for x in np.ravel(inputs[a.name])]
        return [np.array(f(*args), dtype=float).ravel() for f in funs]

    return call


@pytest.mark.parametrize("rule", ALL_RULES)
@pytest.mark.parametrize("make", [double_pendulum, star_nonlinear])
def test_hoisted_routines_are_the_smooth_steps_own(make, rule: str) -> None:
    system = vcigen.derive(make(), rule)
    routines = {r.name: _numeric(r) for r in implicit_routines(system)}
    consts, it, end = routines["smooth_consts"], routines["smooth_iter"], routines["smooth_end"]
    # the stage eliminated (vcigen.stage: the star's constant mass under lobatto3): smooth_iter is in z
    assert ("smooth_back" in routines) == (rule == "lobatto3" and make is star_nonlinear)
    smooth, seg = _numeric(system.routines["smooth"]), _numeric(system.routines["segment"])
    con, leg = _numeric(system.routines["contacts"]), _numeric(system.routines["legendre"])
    par = np.array(system.model.resolve_params(None), dtype=float)
    rng = np.random.default_rng(3)
    n = system.n
    for _ in range(5):
        # x = (v, u): with internal points p+ and E_d are the segment's at the unknowns' own u
        q0, p0, x = rng.normal(size=n), rng.normal(size=n), rng.normal(size=n + system.stages)
        q0[1] = abs(q0[1]) + 0.5  # the star's nonlinear gravity R^2/(R + y): away from y = -R
        h = 0.01 * (1 + rng.random())
        x[n:] *= 0.01  # u is O(h)
        v, inside = x[:n], ({"u": x[n:]} if system.stages else {})
        q1 = q0 + h * v
        (k,) = consts(q0=q0, tau=h, par=par)
        if "smooth_back" in routines:  # x = (v, u) from the internal point's mean velocity z = v/2 + u
            z = x[:n] / 2 + x[n:]
            (x,) = routines["smooth_back"](z=z, p0=p0, k=k)
            v, inside, q1 = x[:n], {"u": x[n:]}, q0 + h * x[:n]
            res, jac = it(z=z, p0=p0, k=k)
            step = 1e-6
            fd = [
                (it(z=z + step * e, p0=p0, k=k)[0] - it(z=z - step * e, p0=p0, k=k)[0]) / (2 * step)
                for e in np.eye(n)
            ]
            np.testing.assert_allclose(jac.reshape(n, n), np.array(fd).T, rtol=1e-6, atol=1e-8)
            full, _ = smooth(x=x, q0=q0, p0=p0, tau=h, par=par)
            np.testing.assert_allclose(full[system.stages :], 0.0, atol=1e-12)  # (46) holds at v(z)
            np.testing.assert_allclose(res, full[: system.stages], rtol=1e-12, atol=1e-12)  # the stationarity
            res, jac = full, None
        else:
            res, jac = it(x=x, p0=p0, k=k)
        p1, energy, phi, grad, mom, mass, k_next = end(x=x, k=k)
        want_res, want_jac = smooth(x=x, q0=q0, p0=p0, tau=h, par=par)
        _, want_p1, want_e = seg(q0=q0, v=v, tau=h, par=par, **inside)
        want_phi, want_grad = con(q=q1, par=par)
        want_mom, want_mass = leg(q=q1, v=v, par=par)
        got = [res, jac, p1, energy, phi, grad, mom, mass, k_next]
        want = [want_res, want_jac, want_p1, want_e, want_phi, want_grad, want_mom, want_mass]
        want.append(consts(q0=q1, tau=h, par=par)[0])  # the next step's invariants: those at q_k+1
        for g, w in zip(got, want):
            if g is not None:
                np.testing.assert_allclose(g, w, rtol=1e-12, atol=1e-12)


def test_only_a_nonlinear_smooth_step_gets_the_implicit_grid_step() -> None:
    from vcigen.backends.ccontext import render_context

    pendulum = render_context(vcigen.derive(double_pendulum(), "trapezoid"))
    star = render_context(vcigen.derive(star_nonlinear(), "trapezoid"))  # the trapezoid: explicit
    assert pendulum["structure"]["implicit_grid"] and pendulum["structure"]["carry"]
    assert {"smooth_consts", "smooth_iter", "smooth_end"} <= {r["name"] for r in pendulum["routines"]}
    assert not star["structure"]["implicit_grid"]
    staged = render_context(vcigen.derive(star_nonlinear(), "lobatto3"))  # Newton on (v, u) at any mass
    assert staged["structure"]["implicit_grid"] and staged["structure"]["carry"]


@needs_cc
@pytest.mark.parametrize("rule", ALL_RULES)
def test_c_loop_with_the_carry_matches_the_python_stepper_on_c_kernels(rule: str) -> None:
    """The C loop hands each smooth step's invariants to the next; the Python stepper on the same C
    kernels computes them afresh every step (Kernels.smooth_step): the same trajectory to round-off,
    across impacts (after which the C loop starts afresh too)."""
    sim = vcigen.build(double_pendulum(), backend="c", rule=rule)
    kern = sim.kernels.bind(sim.model.resolve_params(None))
    q0, v0, h = [0.0, 0.0], [6.0, 8.0], 0.005
    py = Stepper(kern, sim.tol).simulate(q0, v0, h, n_impacts=2)
    c = sim.simulate(q0, v0, h, n_impacts=2)
    assert len(c.impacts) == len(py.impacts) == 2 and c.q.shape == py.q.shape
    np.testing.assert_allclose(c.q, py.q, rtol=0, atol=1e-11)
    np.testing.assert_allclose(c.p, py.p, rtol=0, atol=1e-10)
    np.testing.assert_allclose(c.energy, py.energy, rtol=0, atol=1e-11)
    for a, b in zip(c.impacts, py.impacts):
        assert a.step == b.step and abs(a.t - b.t) <= 1e-12


@needs_cc
@pytest.mark.parametrize("rule", ALL_RULES)
def test_implicit_grid_step_agrees_with_casadi_on_the_double_pendulum(rule: str) -> None:
    """C (implicit grid step) and CasADi (rootfinder on the unhoisted residual): the same impacts and
    trajectory over three impacts against the wall (the pendulum is chaotic: the horizon is short)."""
    q0, v0, h = [0.0, 0.0], [6.0, 8.0], 0.005
    c, ca = (
        vcigen.build(double_pendulum(), backend=b, rule=rule).simulate(q0, v0, h, n_impacts=3)
        for b in ("c", "casadi")
    )
    assert len(c.impacts) == len(ca.impacts) == 3 and c.q.shape == ca.q.shape
    np.testing.assert_allclose(c.q, ca.q, rtol=0, atol=1e-10)
    np.testing.assert_allclose(c.energy, ca.energy, rtol=0, atol=1e-10)
    for a, b in zip(c.impacts, ca.impacts):
        assert a.step == b.step and abs(a.t - b.t) <= 1e-11
