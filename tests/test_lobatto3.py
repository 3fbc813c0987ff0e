"""The fourth-order rule ``lobatto3`` (MATH.md *Higher order*) through every phase of an impact step.

References are independent of vcigen: closed forms (oscillator against a wall, straight flights
between walls, the corner, the parabola) or scipy's DOP853 with event location and the elastic law
(``bench.reference.event_driven``; ``hard_scenes.EventReference``).
"""

from __future__ import annotations

import math

import hard_scenes
import numpy as np
import pytest
import sympy as sp
from hard_scenes import G, backend_param, impact_energy_jumps, min_phi, unfold, walls_oscillator_exact
from scenes import simulator, star_nonlinear
from test_order import oscillator_wall_errors
from test_symplectic import step_map

import vcigen
from bench import scenes as bench_scenes
from bench.reference import event_driven
from vcigen.analysis import fit_order, symplectic_defect
from vcigen.rules import RULES
from vcigen.stepper import Tolerances

RULE = "lobatto3"
BACKENDS = [backend_param("casadi"), backend_param("c")]
both = pytest.mark.parametrize("backend", BACKENDS)


def sim_of(name: str, backend: str = "casadi", tol: Tolerances | None = None) -> vcigen.Simulator:
    """A hard-case scene (tests/hard_scenes.py) under lobatto3."""
    return hard_scenes.simulator(name, backend, RULE, tol)


def test_rules_declare_their_order_and_internal_points():
    assert RULES[RULE].order == 4 and RULES[RULE].stages == 1
    assert [(RULES[r].order, RULES[r].stages) for r in ("trapezoid", "midpoint")] == [(2, 0), (2, 0)]
    system = vcigen.derive(star_nonlinear(), RULE)
    assert system.stages == 3
    # every phase solves for its own unknowns plus the internal point, with its stationarity rows
    sizes = {name: system.routines[name].inputs[0].size for name in ("smooth", "jump", "contact_time_floor")}
    assert sizes == {"smooth": 6, "jump": 7, "contact_time_floor": 7}
    assert system.routines["jump_contact_floor"].output("res").expr.rows == 8


# ------------------------------------------------------------------ order 4 through collisions


@both
def test_order_four_oscillator_against_a_wall_closed_form(backend):
    """x'' = -4 x from phases of (cos 2t0, ...) against x = -0.5: one impact; error at t = 2."""
    sim = simulator("oscillator", RULE, backend)
    hs = [0.08, 0.04, 0.02, 0.01]
    mean_err, worst = oscillator_wall_errors(sim, hs, 4)
    order = fit_order(hs, mean_err)
    print(f"oscillator-wall [{backend}]: order {order:.2f}, errors {mean_err}")
    assert 3.7 < order < 4.3, (order, mean_err)
    assert worst < 0.1  # error <= C h^4 at every phase (C ~ 0.02 measured)


STAR_HS = [0.02, 0.01, 0.005, 0.0025]
PHASES = 8


@pytest.fixture(scope="module")
def star_reference():
    """Paper Fig. 5: the star under nonlinear gravity, DOP853 with event location (rtol 1e-13; it agrees
    with an mpmath Taylor integration at 30 digits to 6e-14) at every start and end time of the runs."""
    scene = bench_scenes.star_nonlinear()
    times = {
        round(t, 13)
        for h in STAR_HS
        for k in range(PHASES)
        for t in (k * h / PHASES, k * h / PHASES + round(1.5 / h) * h)
    }
    t_eval = np.array(sorted(times))
    ref = event_driven(scene, t_eval, q0=scene.q0, v0=scene.v0, max_step=0.005)
    assert ref.t.size == t_eval.size and 1.2 < ref.impacts[0].t < 1.3
    return {t: (q, v) for t, q, v in zip(t_eval, ref.q, ref.v, strict=True)}, ref.impacts


@both
def test_order_four_star_nonlinear_gravity_after_the_first_collision(backend, star_reference):
    """Error at t0 + 1.5 (after the collisions at 1.239 and 1.248) against DOP853 + events, averaged over
    eight start phases t0 = k h / 8 on the reference trajectory (the impacts at eight places in a step)."""
    states, impacts = star_reference
    sim = simulator("star_nonlinear", RULE, backend)
    errors = []
    for h in STAR_HS:
        errs = []
        for k in range(PHASES):
            t0, steps = round(k * h / PHASES, 13), round(1.5 / h)
            res = sim.simulate(q0=states[t0][0], v0=states[t0][1], h=h, t_end=steps * h)
            assert res.n_impacts == len(impacts) == 2
            assert res.impacts[0].t + t0 == pytest.approx(impacts[0].t, abs=h**4)
            assert impact_energy_jumps(res).max() <= 1e-12 * abs(res.energy[0])
            errs.append(np.max(np.abs(res.q[-1] - states[round(t0 + steps * h, 13)][0])))
        errors.append(np.mean(errs))
    order = fit_order(STAR_HS, errors)
    print(f"star_nonlinear [{backend}]: order {order:.2f}, errors {errors}")
    assert 3.7 < order < 4.3, (order, errors)


@both
def test_order_four_double_pendulum_against_a_wall(backend):
    """Configuration-dependent mass, nonlinear contact: DOP853 + events, four start phases, t = 1.5."""
    sim = sim_of("double_pendulum", backend)
    scene = bench_scenes.pendulum_wall()  # the same model: wall x = 1.2, m = l = 1
    hs = [0.02, 0.01, 0.005, 0.0025]
    errors = np.zeros(len(hs))
    shifts = np.linspace(0.0, 0.02, 4, endpoint=False)
    for d in shifts:
        q0, v0 = np.array([0.3 + d, 0.6]), np.array([1.5, 2.0])
        ref = event_driven(scene, np.array([0.0, 1.5]), q0=q0, v0=v0, max_step=0.005)
        assert len(ref.impacts) == 1
        for i, h in enumerate(hs):
            res = sim.simulate(q0=q0, v0=v0, h=h, t_end=1.5)
            assert res.n_impacts == 1
            assert impact_energy_jumps(res).max() <= 1e-12 * abs(res.energy[0])
            assert min_phi(sim, res) >= -1e-12
            errors[i] += np.max(np.abs(res.q[-1] - ref.q[-1])) / len(shifts)
    order = fit_order(hs, errors)
    print(f"double pendulum-wall [{backend}]: order {order:.2f}, errors {list(errors)}")
    assert 3.7 < order < 4.3, (order, errors)


# ------------------------------------------------------------------ energy, symplecticity, Noether

RUNS = {
    "particle": {"q0": [0.0, 1.0], "v0": [-2.0, 0.0], "h": 0.01},
    "star": {"q0": [0.0, 3.5, 0.0], "v0": [-2.0, 0.0, 5.0], "h": 0.005},
    "billiard": {"q0": [0.2, 0.0], "v0": [0.3, 1.5], "h": 0.01},
}


@pytest.mark.parametrize("scene", sorted(RUNS))
@both
def test_energy_equal_across_every_impact(backend, scene):
    res = simulator(scene, RULE, backend).simulate(**RUNS[scene], n_impacts=40)
    assert res.n_impacts == 40
    jumps = np.array([im.energy_after - im.energy_before for im in res.impacts])
    assert np.max(np.abs(jumps)) <= 1e-11 * abs(res.energy[0])
    for im in res.impacts:
        assert res.energy[im.step] == pytest.approx(im.energy_before, rel=1e-12)
    assert all(im.impulse > 0 for im in res.impacts)


def pendulum_wall() -> vcigen.Model:
    """A pendulum swinging into a wall at theta = -0.5: nonlinear gravity, one degree of freedom."""
    th, thd = sp.symbols("theta thetad")
    lag = thd**2 / 2 - G * (1 - sp.cos(th))
    wall = {"wall": th + 0.5}
    return vcigen.Model(name="pendulum_wall_1dof", q=[th], qdot=[thd], lagrangian=lag, contacts=wall)


@both
def test_energy_deviation_is_fourth_order_without_drift(backend):
    """60 impacts over 88 s: max |E_d - E_d(0)| shrinks as h^4, with no trend.

    The run is integrable (one degree of freedom), so a 1e-14 change of the start moves nothing: the
    fit measures the rule, not a chaotic trajectory. At an impact the deviation is ``C(alpha) h^4`` with
    ``alpha`` where the wall cuts the step, so single pairs of h wander (2.1 to 6.1); the fit runs over a
    factor 16 in h.
    """
    sim = vcigen.build(pendulum_wall(), backend=backend, rule=RULE)
    hs = [0.04, 0.028, 0.02, 0.014, 0.01, 0.007, 0.005, 0.0035, 0.0025]
    devs = []
    for h in hs:
        res = sim.simulate(q0=[0.8], v0=[0.0], h=h, n_impacts=60)
        assert res.n_impacts == 60
        devs.append(res.max_energy_deviation())
        k = res.energy.size // 10  # the last tenth of the run oscillates about the level of the first
        assert abs(res.energy[-k:].mean() - res.energy[:k].mean()) <= devs[-1] * abs(res.energy[0])
    order = fit_order(hs, devs)
    print(f"E_d deviation pendulum against a wall [{backend}]: order {order:.2f}, {devs}")
    assert 3.7 < order < 4.3, (order, devs)
    # trapezoid on the same run: second order and far larger (the rule is really different)
    trap = vcigen.build(pendulum_wall(), backend=backend).simulate(q0=[0.8], v0=[0.0], h=hs[-1], n_impacts=60)
    assert trap.max_energy_deviation() > 100 * devs[-1]


def test_impact_step_is_symplectic():
    """Central finite differences of the one-step map with one impact inside (billiard, star)."""
    for sim, h, z in (
        (simulator("billiard", RULE), 0.05, np.array([0.0, 1.0 - 0.6 * 0.05 * 1.5 - 1e-3, 0.4, 1.5])),
        (simulator("star_nonlinear", RULE), 0.01, np.array([0.0, 0.64, 0.3, -1.0, -3.0, 2.0])),
    ):
        count: list[int] = []
        defect = symplectic_defect(step_map(sim, h, count), z, eps=1e-6)
        assert set(count) == {1}, "every perturbed step must hold exactly one impact"
        assert defect < 1e-7, defect


def test_symplectic_defect_sees_restitution():
    """Not vacuous: the same finite-difference defect of a lossy impact step is large."""
    sim = sim_of("box_lossy")
    count: list[int] = []
    z = np.array([0.5, 0.005, 0.3, -1.0])
    assert symplectic_defect(step_map(sim, 0.01, count, _params(sim, e=0.5)), z, eps=1e-6) > 0.1
    assert symplectic_defect(step_map(sim, 0.01, count, _params(sim, e=1.0)), z, eps=1e-6) < 1e-7
    assert set(count) == {1}


def _params(sim: vcigen.Simulator, **values: float) -> list[float]:
    return sim.model.resolve_params(values)


@both
def test_discrete_noether_momenta(backend):
    """p_x on a floor (star) and angular momentum in a circular billiard, to round-off."""
    res = simulator("star", RULE, backend).simulate(**RUNS["star"], n_impacts=30)
    assert np.max(np.abs(res.p[:, 0] - res.p[0, 0])) < 1e-12 * abs(res.p[0, 0])
    res = simulator("billiard", RULE, backend).simulate(q0=[0.2, 0.0], v0=[0.3, 1.5], h=0.01, n_impacts=40)
    ang = res.q[:, 0] * res.p[:, 1] - res.q[:, 1] * res.p[:, 0]
    assert res.n_impacts == 40 and min(im.impulse for im in res.impacts) > 0.1
    assert np.max(np.abs(ang - ang[0])) < 1e-12 * abs(ang[0])


# ------------------------------------------------------------------ every phase


@pytest.mark.parametrize("h", [0.2, 0.0125])
@both
def test_several_impacts_in_one_step_are_exact(backend, h):
    """(78): walls 0.01 apart, |vx| = 1, up to 20 impacts a step; straight flights are exact."""
    sim = sim_of("walls", backend)
    x0 = 0.0037
    res = sim.simulate(q0=[x0, 1.0], v0=[1.0, 0.5], h=h, t_end=1.0, params={"g": 0.0})
    assert int(np.bincount([im.step for im in res.impacts]).max()) >= max(2, math.floor(h / 0.01))
    assert res.n_impacts == pytest.approx(100, abs=1)
    np.testing.assert_allclose(res.q[:, 0], unfold(x0, 1.0, 0.0, 0.01, res.t), rtol=0, atol=1e-12)
    np.testing.assert_allclose(res.q[:, 1], 1.0 + 0.5 * res.t, rtol=0, atol=1e-12)
    assert impact_energy_jumps(res).max() <= 1e-12
    names = [im.contact for im in res.impacts]
    assert all(a != b for a, b in zip(names, names[1:], strict=False))


@both
def test_several_impacts_per_step_under_a_nonlinear_flow_converge_at_order_four(backend):
    """x'' = -16 x between walls at +-0.05 (an impact every 0.025 s), closed form, 8 start phases."""
    sim = sim_of("walls_oscillator", backend)
    amp, w, a = 1.0, 4.0, 0.05
    t1 = math.asin(a / amp) / w

    def mean_error(h):
        errs, most = [], 0
        for t0 in np.linspace(0.0, t1, 8, endpoint=False):
            res = sim.simulate(q0=[amp * math.sin(w * t0)], v0=[amp * w * math.cos(w * t0)], h=h, t_end=0.2)
            assert impact_energy_jumps(res).max() <= 1e-12 * abs(res.energy[0])
            most = max(most, int(np.bincount([im.step for im in res.impacts]).max()))
            errs.append(abs(res.q[-1, 0] - walls_oscillator_exact(t0 + res.t[-1], amp, w, a)))
        return float(np.mean(errs)), most

    err_big, most = mean_error(0.04)
    assert most >= 2 and err_big < 1e-4
    # h = 0.01 (an impact every 2.5 steps) is still pre-asymptotic: 0.01 -> 0.005 measures 3.4
    hs = [0.005, 0.0025, 0.00125]
    errs = [mean_error(h)[0] for h in hs]
    order = fit_order(hs, errs)
    print(f"oscillator between close walls [{backend}]: order {order:.2f}, errors {errs}")
    assert 3.7 < order < 4.3, (order, errs)


@pytest.mark.parametrize("h", [0.3, 0.1])  # the corner at alpha = 1/3, and on the grid
@both
def test_simultaneous_impacts_in_a_corner_in_either_contact_order(backend, h):
    """(1, 1) into the corner of x, y >= 0 with velocity (-1, -1): q(t) = |1 - t| (1, 1)."""
    run = {"q0": [1.0, 1.0], "v0": [-1.0, -1.0], "h": h, "t_end": 2.5, "params": {"g": 0.0}}
    a, b = (sim_of(name, backend).simulate(**run) for name in ("corner", "corner_reversed"))
    np.testing.assert_allclose(a.q, np.abs(1.0 - a.t)[:, None] * np.ones(2), rtol=0, atol=1e-12)
    np.testing.assert_allclose(a.p[-1], [1.0, 1.0], rtol=0, atol=1e-12)
    assert sorted(im.contact for im in a.impacts) == ["bottom", "left"]
    assert all(im.t == pytest.approx(1.0, abs=1e-12) for im in a.impacts)
    np.testing.assert_allclose(b.q, a.q, rtol=0, atol=1e-12)


@both
def test_kink_star_dropped_flat_bounces_straight_up(backend):
    """theta = 0 is a kink of eq. (81): two vertices at once, the normal cone's centre (86)."""
    res = simulator("star", RULE, backend).simulate(q0=[0.0, 1.0, 0.0], v0=[0.5, 0.0, 0.0], h=0.01, t_end=0.5)
    assert res.n_impacts == 1
    assert np.max(np.abs(res.q[:, 2])) < 1e-15 and np.max(np.abs(res.p[:, 2])) < 1e-15
    im = res.impacts[0]
    assert im.t == pytest.approx(math.sqrt(2 * 0.5 / G), abs=1e-12)
    assert im.impulse == pytest.approx(2 * math.sqrt(2 * G * 0.5), rel=1e-12)  # L_d exact: no O(h^2) bias
    assert im.energy_after == pytest.approx(im.energy_before, abs=1e-12)


@both
def test_tunnelling_through_a_ceiling_is_caught_along_the_segment_map(backend):
    """An apex 1e-3 above the ceiling between two admissible grid points: detected, time exact."""
    from test_tunnelling import Y0, C, ceiling_model, launch

    model = ceiling_model()
    sim = vcigen.build(model, backend=backend, rule=RULE)
    blind = vcigen.build(model, backend=backend, rule=RULE, tol=Tolerances(dip=-math.inf))
    v, h = launch(1e-3), 0.1
    t_hit = (v - math.sqrt(v * v - 2 * G * (C - Y0))) / G
    k = int(t_hit // h)
    y = lambda t: Y0 + v * t - G * t * t / 2  # noqa: E731
    assert y(k * h) < C and y((k + 1) * h) < C, "both grid points admissible"
    res = sim.simulate(q0=[0.0, Y0], v0=[1.0, v], h=h, t_end=0.6)
    assert [im.contact for im in res.impacts] == ["ceiling"]
    im = res.impacts[0]
    assert im.t == pytest.approx(t_hit, abs=1e-10)
    assert im.energy_after == pytest.approx(im.energy_before, abs=1e-12)
    # lobatto3 is exact on the parabola, E_d is the energy: the bounce is the elastic one
    assert im.impulse == pytest.approx(2 * (v - G * t_hit), rel=1e-9)
    assert np.all(C - res.q[:, 1] >= -1e-9)
    assert blind.simulate(q0=[0.0, Y0], v0=[1.0, v], h=h, t_end=0.6).n_impacts == 0


@both
def test_impact_at_alpha_to_zero_and_one(backend):
    """Impacts a hair after or before a grid time: same trajectory, exact time, no lost impact."""
    sim = simulator("particle", RULE, backend)
    h, finals = 0.01, []
    for rel in (-1e-13, -1e-15, 0.0, 1e-15, 1e-13):
        y0 = G * (30 * h * (1 + rel)) ** 2 / 2
        res = sim.simulate(q0=[0.0, y0], v0=[0.0, 0.0], h=h, t_end=0.6)
        assert res.n_impacts == 1
        im = res.impacts[0]
        t_hit = math.sqrt(2 * y0 / G)
        assert im.t == pytest.approx(t_hit, abs=1e-12)
        assert min(im.alpha, 1 - im.alpha) < 1e-9
        assert im.energy_after == pytest.approx(im.energy_before, abs=1e-12)
        assert np.all(res.q[:, 1] >= -1e-9)
        t = res.t[-1] - t_hit
        assert abs(res.q[-1, 1] - (G * t_hit * t - G * t * t / 2)) < 1e-9  # exact flight
        finals.append(np.concatenate([res.q[-1], res.p[-1]]))
    assert np.max(np.ptp(np.array(finals), axis=0)) < 1e-9


@pytest.mark.parametrize("tau", [0.0, 1e-14, 1e-8, 0.01])
def test_phases_are_well_conditioned_on_vanishing_segments(tau):
    """The jump (48) and the smooth step (46) on a segment of length tau -> 0 (alpha -> 1, alpha -> 0):
    Newton converges to the continuous limits (no division by tau, no singular Jacobian)."""
    sim = simulator("star_nonlinear", RULE)
    k = sim.kernels.bind(sim.model.resolve_params(None))
    q, vel = np.array([0.0, 0.7071067811865476 + 1e-3, math.pi / 4 + 0.1]), np.array([0.3, -2.0, 1.0])
    p, mass = k.legendre(q, vel)
    v, res = k.solve("smooth", vel, q, p, tau)
    assert res <= 1e-12 and np.allclose(v, vel, atol=10 * tau + 1e-12)
    nrm = k.contacts(q)[1][0]
    e_in = k.segment(q, vel, tau)[2]
    minv_n = np.linalg.solve(mass, nrm)
    mu0 = -2 * (nrm @ vel) / (nrm @ minv_n)
    x, res = k.solve("jump", np.append(vel + mu0 * minv_n, mu0), q, nrm, p, e_in, tau)
    assert res <= 1e-12
    assert x[-1] == pytest.approx(mu0, rel=1e-6 + 100 * tau)  # the elastic law as tau -> 0


@both
def test_restitution_loses_the_normal_energy(backend):
    """A ball dropped from 1 with e = 0.5: the loss is (1 - e^2)/2 v^2, flights shrink by e."""
    sim = sim_of("ball", backend)
    e = 0.5
    res = sim.simulate([0.0, 1.0], [0.3, 0.0], 0.001, n_impacts=5, params={"e": e})
    t = np.array([im.t for im in res.impacts])
    np.testing.assert_allclose(np.diff(t)[1:] / np.diff(t)[:-1], e, rtol=1e-9)
    v1 = math.sqrt(2 * G)
    assert t[0] == pytest.approx(v1 / G, abs=1e-12)
    loss = np.array([im.energy_before - im.energy_after for im in res.impacts])
    np.testing.assert_allclose(loss, (1 - e * e) / 2 * v1 * v1 * (e * e) ** np.arange(5), rtol=1e-9)
    assert np.all(res.p[:, 0] == 0.3)


# ------------------------------------------------------------------ what lobatto3 does not do yet


def test_unsupported_features_are_refused_by_name():
    """Forces, bilateral constraints, sustained contact, casadi_functions and sensitivities are supported
    (tests/test_lobatto3_forces.py, test_lobatto3_sustained.py, test_casadi_functions.py,
    test_sensitivity_lobatto3.py); casadi_functions has no held step, so a constrained model is refused
    (under every rule) rather than given a step that leaves its constraint."""
    from test_sustained_closed_forms import pendulum

    for rule in (RULE, "trapezoid"):
        with pytest.raises(ValueError, match="bilateral constraints.*'rod'"):
            vcigen.casadi_functions(pendulum(), rule=rule)


# ------------------------------------------------------------------ C = CasADi


AGREE = [
    ("star_nonlinear", {"q0": [0.0, 3.5, 0.0], "v0": [-2.0, 0.0, 5.0], "h": 0.005, "t_end": 4.0}, {}),
    ("double_pendulum", {"q0": [0.3, 0.6], "v0": [1.5, 2.0], "h": 0.005, "t_end": 1.5}, {}),
    ("walls", {"q0": [0.0037, 1.0], "v0": [1.0, 0.5], "h": 0.05, "t_end": 1.0}, {}),
    ("corner", {"q0": [1.0, 1.0], "v0": [-1.0, -1.0], "h": 0.3, "t_end": 2.5}, {"g": 0.0}),
    ("ball", {"q0": [0.0, 1.0], "v0": [0.3, 0.0], "h": 0.001, "n_impacts": 5}, {"e": 0.5}),
]


def _either(name: str, backend: str) -> vcigen.Simulator:
    if name in hard_scenes.MAKERS:
        return hard_scenes.simulator(name, backend, RULE)
    return simulator(name, RULE, backend)


@pytest.mark.parametrize("name,setup,params", AGREE, ids=[a[0] for a in AGREE])
@pytest.mark.parametrize("backend", [backend_param("c")])
def test_c_and_casadi_agree(backend, name, setup, params):
    """The C stepper and the Python one on the same routines: the same impacts and trajectory."""
    a, b = (_either(name, bk).simulate(**setup, params=params) for bk in ("casadi", backend))
    assert a.n_impacts == b.n_impacts >= 1
    assert [im.contact for im in a.impacts] == [im.contact for im in b.impacts]
    np.testing.assert_allclose([im.t for im in a.impacts], [im.t for im in b.impacts], rtol=0, atol=1e-10)
    np.testing.assert_allclose(b.q, a.q, rtol=0, atol=1e-9)
    np.testing.assert_allclose(b.p, a.p, rtol=0, atol=1e-8)
    np.testing.assert_allclose(b.energy, a.energy, rtol=0, atol=1e-9 * abs(a.energy[0]))
