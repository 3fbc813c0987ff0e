"""lobatto3 with its stage eliminated in closed form (vcigen.stage, ``Structure.stage_reduced``).

For ``L = 1/2 qdot.M qdot - V(q)`` with a constant ``M`` the momentum rows of every phase are linear in
``v`` at a fixed internal point: the generated C solves them for ``v`` in closed form and runs each
Newton on the internal point's mean velocity ``z`` (and the phase's own unknowns but ``v``). It solves
the same equations as the general path, so the trajectories must agree to solver tolerance; these tests
run both from one system (the general path by switching the flags off) through impacts, check where the
specialisation applies and where it must not (a mass matrix of ``q``), and that the reduced rows are the
general ones at ``v(z)``. The order through impacts against closed forms and DOP853 stays with
tests/test_lobatto3.py, whose C runs now take the reduced path.
"""

from __future__ import annotations

import dataclasses
import shutil

import numpy as np
import pytest
import sympy as sp
from forced_scenes import driven_oscillator
from hard_scenes import double_pendulum
from scenes import billiard, oscillator_wall, star_nonlinear

import vcigen
from vcigen.backends import registry
from vcigen.backends.c import render
from vcigen.backends.ccontext import render_context
from vcigen.stage import reduced_phases, reduced_smooth

RULE = "lobatto3"
needs_cc = pytest.mark.skipif(shutil.which("cc") is None, reason="no C compiler")


def _c(system: vcigen.DiscreteSystem, general: bool) -> vcigen.Simulator:
    """The C simulator of ``system``; ``general``: with the stage's elimination switched off (Newton on
    every phase's ``(x, u)``, the path of a configuration-dependent mass)."""
    if general:
        off = dataclasses.replace(system.structure, stage_reduced=False, stage_linear=False)
        system.__dict__["structure"] = off  # the cached_property's slot: read by both backends
    return registry.factory("c")(system, tol=vcigen.Tolerances())


def _pair(make) -> tuple[vcigen.Simulator, vcigen.Simulator]:
    reduced = _c(vcigen.derive(make(), RULE), general=False)
    general = _c(vcigen.derive(make(), RULE), general=True)
    assert reduced.kernels.structure.stage_reduced and not general.kernels.structure.stage_reduced
    return reduced, general


@pytest.mark.parametrize(
    "make,reduced,linear",
    [
        (star_nonlinear, True, False),  # constant diagonal mass, V of y
        (oscillator_wall, True, True),  # quadratic V: the stationarity is linear in z
        (billiard, True, False),  # quartic V coupling x and y
        (driven_oscillator, True, True),  # damping -c qdot and a drive of t: still linear in v
        (double_pendulum, False, False),  # M(q): the momentum rows are not linear in v
    ],
)
def test_where_the_stage_is_eliminated(make, reduced: bool, linear: bool) -> None:
    system = vcigen.derive(make(), RULE)
    s = system.structure
    assert (s.stage_reduced, s.stage_linear) == (reduced, linear), s.why
    assert (reduced_smooth(system) is not None) == reduced
    phases = [name for name, _, _ in reduced_phases(system)]
    want = ["smooth", *(f"contact_time_{c}" for c in system.contact_names), "jump"]
    want += [f"jump_contact_{c}" for c in system.contact_names]
    assert sorted(phases) == (sorted(want) if reduced else [])
    source = render(render_context(system), ["model.c.j2"])[f"{system.model.name}.c"]
    assert ("_newton_reduced(" in source) == reduced and ("_smooth_back(" in source) == reduced
    other = vcigen.derive(make(), "trapezoid").structure  # no internal points: never
    assert not other.stage_reduced and other.why["stage_reduced"] == "no internal points"


def test_reduced_phases_are_the_general_rows_at_v_of_z() -> None:
    """Each ``<phase>_z`` is the phase's own rows but the momentum rows at ``(v, ..., u) = <phase>_zback``,
    and there the momentum rows vanish: at random points of star_nonlinear (every phase, its contact)."""
    system = vcigen.derive(star_nonlinear(), RULE)
    n, ns = system.n, system.stages
    rng = np.random.default_rng(7)
    par = [float(x) for x in system.model.resolve_params(None)]
    for name, rz, back in reduced_phases(system):
        full = system.routines[name]
        args = [s for a in rz.inputs[1:] for s in a.symbols]
        f_z = sp.lambdify([*rz.inputs[0].symbols, *args], list(rz.output("res").expr))
        jac_z = sp.lambdify([*rz.inputs[0].symbols, *args], list(rz.output("jac").expr))
        f_x = sp.lambdify([*full.inputs[0].symbols, *args], list(full.output("res").expr))
        to_x = sp.lambdify([*rz.inputs[0].symbols, *args], list(back.output("full").expr))
        for _ in range(3):
            zx = rng.normal(size=rz.inputs[0].size)
            data = []
            for a in rz.inputs[1:-1]:
                data += list(rng.normal(size=a.size) if a.name != "tau" else [0.01 * (1 + rng.random())])
            if name.startswith("jump"):
                data[1] = abs(data[1]) + 1.0  # qc: the star's gravity R^2/(R + y) away from y = -R
            else:
                data[1] = abs(data[1]) + 1.0  # q0's height
            vals = [*data, *par]
            x = np.array(to_x(*zx, *vals), dtype=float)
            rows = np.array(f_x(*x, *vals), dtype=float)
            np.testing.assert_allclose(rows[ns : ns + n], 0.0, atol=1e-11)  # the momentum rows hold
            kept = np.concatenate([rows[:ns], rows[ns + n :]])
            np.testing.assert_allclose(f_z(*zx, *vals), kept, rtol=1e-11, atol=1e-11)
            # the internal point: z = v/2 + u
            np.testing.assert_allclose(zx[:ns], x[:n] / 2 + x[-ns:], rtol=1e-12, atol=1e-12)
            k = len(zx)
            jac = np.array(jac_z(*zx, *vals), dtype=float).reshape(k, k)
            step = 1e-6
            for j in range(k):
                e = np.zeros(k)
                e[j] = step
                fd = (np.array(f_z(*(zx + e), *vals)) - np.array(f_z(*(zx - e), *vals))) / (2 * step)
                np.testing.assert_allclose(jac[:, j], fd, rtol=1e-5, atol=1e-7)


RUNS = [
    # (model, setup): impacts in each; star_nonlinear's start from bench/scenes.py (paper Fig. 5)
    (star_nonlinear, {"q0": [0.0, 3.5, 0.0], "v0": [-2.0, 0.0, 5.0], "h": 0.01, "t_end": 4.0}),
    (star_nonlinear, {"q0": [0.0, 3.5, 0.0], "v0": [-2.0, 0.0, 5.0], "h": 0.1, "t_end": 4.0}),
    (oscillator_wall, {"q0": [0.3], "v0": [1.0], "h": 0.01, "t_end": 10.0}),
    (billiard, {"q0": [0.2, 0.1], "v0": [1.5, 0.7], "h": 0.01, "t_end": 5.0}),
    (driven_oscillator, {"q0": [0.0], "v0": [1.0], "h": 0.01, "t_end": 10.0}),
]


@needs_cc
@pytest.mark.parametrize("make,setup", RUNS)
def test_reduced_and_general_paths_agree_through_impacts(make, setup) -> None:
    reduced, general = _pair(make)
    a = reduced.simulate(**setup, progress=False)
    b = general.simulate(**setup, progress=False)
    assert len(a.impacts) == len(b.impacts) >= 2
    np.testing.assert_allclose([i.t for i in a.impacts], [i.t for i in b.impacts], rtol=0, atol=1e-11)
    np.testing.assert_allclose(a.q, b.q, rtol=0, atol=1e-10)
    np.testing.assert_allclose(a.p, b.p, rtol=0, atol=1e-9)
    np.testing.assert_allclose(a.energy, b.energy, rtol=0, atol=1e-9 * (1 + abs(b.energy[0])))


def test_the_grid_steps_guess_is_off_by_order_h_squared() -> None:
    """``smooth_guess`` (vcigen.stage.predictor, one Newton step from ``z = 0`` with the Jacobian at
    ``tau = 0``) is ``M^-1 (p0/2 - (tau/8) grad V(q0))`` and misses the root by O(tau^2): halving the step
    quarters the miss (star_nonlinear, its nonlinear gravity; the root by Newton on ``smooth_iter``)."""
    from vcigen.implicit import implicit_routines

    system = vcigen.derive(star_nonlinear(), RULE)
    funs = {}
    for r in implicit_routines(system):
        syms = [s for a in r.inputs for s in a.symbols]
        funs[r.name] = (r, [sp.lambdify(syms, list(o.expr)) for o in r.outputs])

    def call(name, **inputs):
        r, fs = funs[name]
        args = [float(x) for a in r.inputs for x in np.ravel(inputs[a.name])]
        return [np.array(f(*args), dtype=float) for f in fs]

    m, g, ell, big_r = (float(x) for x in system.model.resolve_params(None))
    inertia = 29 / 192 * m * ell**2
    par = [m, g, ell, big_r]
    q0, p0 = np.array([0.3, 2.0, 0.4]), np.array([-1.0, -3.0, 2.0])
    misses = []
    for h in (0.04, 0.02, 0.01):
        (k,) = call("smooth_consts", q0=q0, tau=h, par=par)
        (guess,) = call("smooth_guess", p0=p0, k=k)
        grad_v = np.array([0.0, m * g * big_r**2 / (big_r + q0[1]) ** 2, 0.0])
        want = (p0 / 2 - h / 8 * grad_v) / np.array([m, m, inertia])
        np.testing.assert_allclose(guess, want, rtol=1e-13, atol=1e-13)
        z = guess.copy()
        for _ in range(20):
            res, jac = call("smooth_iter", z=z, p0=p0, k=k)
            z -= np.linalg.solve(jac.reshape(3, 3), res)
        assert np.abs(call("smooth_iter", z=z, p0=p0, k=k)[0]).max() < 1e-13
        misses.append(np.abs(guess - z).max())
    assert misses[-1] > 0
    ratios = [a / b for a, b in zip(misses, misses[1:])]
    assert all(3.5 < r < 4.5 for r in ratios), (misses, ratios)
