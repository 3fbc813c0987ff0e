"""``simulate_many`` is ``K`` calls of ``simulate``, bit for bit, on both backends (issue 13).

Runs with impacts, parameters per run, sustained contact (a lossy ball coming to rest), runs of
unknown length (``n_impacts``, whose buffers grow), threads, and a run that fails.
"""

from __future__ import annotations

import numpy as np
import pytest
import sympy as sp
from hard_scenes import backend_param, simulator

import vcigen

BACKENDS = [backend_param("c"), backend_param("casadi")]


def assert_same(a: vcigen.Result, b: vcigen.Result) -> None:
    """Every array of the two runs equal bit for bit, the impact log and lift-offs too."""
    for name in (
        "t",
        "q",
        "p",
        "energy",
        "active",
        "contact_force",
        "constraint_force",
        "work",
        "friction_work",
    ):
        x, y = getattr(a, name), getattr(b, name)
        assert x.shape == y.shape and np.array_equal(x, y), name
    assert a.impacts == b.impacts and len(a.impacts) == len(b.impacts)
    assert a.liftoffs == b.liftoffs
    assert np.array_equal(a.v, b.v)  # each run's Legendre inverse at its own parameters
    for key in set(a.stats) | set(b.stats):
        if key not in ("wall_time", "seconds_per_step"):
            assert a.stats[key] == b.stats[key], key


@pytest.mark.parametrize("backend", BACKENDS)
def test_simulate_many_equals_serial_runs_with_params_per_run(backend: str) -> None:
    """A lossy ball from four heights and restitutions: bounces, then held on the floor (sustained
    contact); each run equals its own ``simulate`` call."""
    sim = simulator("ball", backend)
    q0s = [[0.0, 1.0], [0.0, 0.5], [0.1, 0.2], [0.0, 0.05]]
    v0s = [[0.3, 0.0], [0.0, 1.0], [-0.2, 0.0], [0.0, 0.0]]
    params = [{"e": 0.5}, {"e": 0.8}, None, {"e": 0.2}]
    h, t_end = 0.005, 1.5 if backend == "c" else 0.6
    many = sim.simulate_many(q0s, v0s, h, t_end=t_end, params=params)
    assert len(many) == 4
    held = 0
    for q0, v0, par, res in zip(q0s, v0s, params, many):
        one = sim.simulate(q0, v0, h, t_end=t_end, params=par)
        assert_same(res, one)
        held += bool(res.active.any())
        assert res.n_impacts > 0
    assert held >= 2, "the scene must reach sustained contact in some runs"
    # the parameters reached each run: different restitution, different first energy loss
    losses = [r.impacts[0].energy_before - r.impacts[0].energy_after for r in many[:2]]
    assert losses[0] != pytest.approx(losses[1], rel=1e-3)


@pytest.mark.parametrize("backend", BACKENDS)
def test_simulate_many_n_impacts_equals_serial_runs(backend: str) -> None:
    """Runs of unknown length (``n_impacts``): buffers grow per run, results still equal ``simulate``."""
    sim = simulator("ball", backend)
    n = 300 if backend == "c" else 6  # C: past the 144 records a run of simulate_many starts with
    q0s = [[0.0, 1.0], [0.0, 2.0], [0.0, 0.3]]
    v0s = [[0.0, 0.0]] * 3
    many = sim.simulate_many(q0s, v0s, 0.01, n_impacts=n, params={"e": 1.0})
    # a run of unknown length reuses the buffers of the last one (C): let that one leave a ball held
    # on the floor in them (active contact, forces), which the next runs must not inherit
    held = sim.simulate([0.0, 0.2], [0.0, 0.0], 0.01, n_impacts=20, t_end=3.0, params={"e": 0.5})
    assert held.active.any() and held.contact_force.any()
    for q0, v0, res in zip(q0s, v0s, many):
        assert res.n_impacts == n
        assert_same(res, sim.simulate(q0, v0, 0.01, n_impacts=n, params={"e": 1.0}))


def test_simulate_many_threads_equal_one_thread() -> None:
    """Runs split over two threads give the same results as one thread (and as serial runs)."""
    sim = simulator("double_pendulum", "c")
    rng = np.random.default_rng(3)
    q0s = np.array([0.3, 0.6]) + 0.05 * rng.standard_normal((9, 2))
    v0s = np.tile([1.5, 2.0], (9, 1))
    one = sim.simulate_many(q0s, v0s, 0.01, t_end=1.0)
    two = sim.simulate_many(q0s, v0s, 0.01, t_end=1.0, threads=2)
    assert sum(r.n_impacts for r in one) > 0
    for a, b, q0, v0 in zip(one, two, q0s, v0s):
        assert_same(a, b)
        assert_same(a, sim.simulate(q0, v0, 0.01, t_end=1.0))


@pytest.mark.parametrize("backend", BACKENDS)
def test_a_failing_run_raises_with_its_index_or_is_returned(backend: str) -> None:
    """No room for an impact (max_impacts_per_step = 0): the run that hits the floor fails, the one
    that does not finishes. ``errors="raise"`` names the run; ``errors="return"`` returns the error."""
    sim = vcigen.build(
        simulator("ball", backend).model, backend=backend, tol=vcigen.Tolerances(max_impacts_per_step=0)
    )
    q0s, v0s = [[0.0, 5.0], [0.0, 0.1]], [[0.0, 0.0], [0.0, 0.0]]
    with pytest.raises(vcigen.SolverError, match=r"^run 1: step \d+") as info:
        sim.simulate_many(q0s, v0s, 0.01, t_end=0.5)
    err = info.value
    assert err.run == 1 and err.phase == "jump"
    assert isinstance(err.results[0], vcigen.Result) and err.results[1] is err
    assert err.result.t.size - 1 == err.step  # the run up to the last completed step
    out = sim.simulate_many(q0s, v0s, 0.01, t_end=0.5, errors="return")
    assert isinstance(out[0], vcigen.Result) and isinstance(out[1], vcigen.SolverError)
    with pytest.raises(vcigen.SolverError) as single:
        sim.simulate(q0s[1], v0s[1], 0.01, t_end=0.5)
    assert (out[1].step, out[1].time, out[1].residual) == (
        single.value.step,
        single.value.time,
        single.value.residual,
    )
    assert_same(out[1].result, single.value.result)


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"q0s": [[0.0, 1.0]], "v0s": [[0.0, 0.0], [0.0, 0.0]]}, "q0s has 1 runs but v0s has 2"),
        ({"q0s": [0.0, 1.0], "v0s": [0.0, 0.0]}, r"q0s has shape \(2,\)"),
        ({"q0s": [[0.0, 1.0], [0.0, -1.0]], "v0s": [[0.0, 0.0]] * 2}, "run 1: q0 violates contact 'floor'"),
        ({"q0s": [[0.0, 1.0]], "v0s": [[0.0, np.nan]]}, r"v0s\[0\]"),
        (
            {"q0s": [[0.0, 1.0]], "v0s": [[0.0, 0.0]], "params": [{}, {}]},
            "params has 2 entries but there are 1 runs",
        ),
        ({"q0s": [[0.0, 1.0]], "v0s": [[0.0, 0.0]], "errors": "ignore"}, "errors = 'ignore'"),
        ({"q0s": [[0.0, 1.0]], "v0s": [[0.0, 0.0]], "threads": 0}, "threads = 0"),
    ],
)
def test_simulate_many_bad_input(kwargs: dict, message: str) -> None:
    sim = simulator("ball", "casadi")
    with pytest.raises(ValueError, match=message):
        sim.simulate_many(h=0.01, t_end=0.1, **kwargs)


@pytest.mark.parametrize("backend", BACKENDS)
def test_simulate_many_with_a_constraint_and_no_contact(backend: str) -> None:
    """A particle on a bilateral rod (no contact at all): each run starts its constraint held, stays on
    the rod, and equals its own ``simulate``; rod lengths per run."""
    x, y, xd, yd = sp.symbols("x y xd yd")
    length = sp.Symbol("l", positive=True)
    model = vcigen.Model(
        name="rod_many",
        q=[x, y],
        qdot=[xd, yd],
        lagrangian=(xd**2 + yd**2) / 2 - 9.81 * y,
        constraints={"rod": x**2 + y**2 - length**2},
        params={length: 1.0},
    )
    sim = vcigen.build(model, backend=backend)
    lengths = [1.0, 2.0, 0.5]
    q0s = [[0.6 * r, -0.8 * r] for r in lengths]
    v0s = [[0.8, 0.6], [0.0, 0.0], [-0.4, -0.3]]
    params = [{"l": r} for r in lengths]
    steps = 300 if backend == "c" else 40
    many = sim.simulate_many(q0s, v0s, 0.01, t_end=steps * 0.01, params=params)
    for q0, v0, par, r, res in zip(q0s, v0s, params, lengths, many):
        assert np.abs(np.hypot(res.q[:, 0], res.q[:, 1]) - r).max() <= 1e-12
        assert_same(res, sim.simulate(q0, v0, 0.01, t_end=steps * 0.01, params=par))


@pytest.mark.parametrize("backend", BACKENDS)
@pytest.mark.parametrize(
    ("q0s", "params", "message"),
    [
        ([[0.0, 1.0], [0.0, 0.5], [0.0, -1.0]], None, "run 2: q0 violates contact 'floor'"),
        ([[0.0, 1.0], [0.0, 0.5], [0.0, -1.0]], [None, {"e": 2.0}, None], "run 1: restitution of 'floor'"),
        ([[0.0, -1.0], [0.0, 0.5], [0.0, 1.0]], [None, {"e": 2.0}, None], "run 0: q0 violates contact"),
        ([[0.0, 1.0], [0.0, 0.5], [0.0, 1.0]], [None, None, {"e": -1.0}], "run 2: restitution of 'floor'"),
    ],
)
def test_simulate_many_names_the_first_bad_run(backend: str, q0s: list, params, message: str) -> None:
    """Starts and parameters checked run by run in order: the first bad run is named, whichever check
    fails (the C backend checks the starts on arrays, after resolving the parameters)."""
    sim = simulator("ball", backend)
    with pytest.raises(ValueError, match=message):
        sim.simulate_many(q0s, [[0.0, 0.0]] * 3, 0.01, t_end=0.05, params=params)
    ok = sim.simulate_many([[0.0, 1.0], [0.0, 0.0], [0.1, 0.3]], [[0.0, 0.0]] * 3, 0.01, t_end=0.05)
    assert [r.t.size for r in ok] == [6, 6, 6]


@pytest.mark.parametrize("n", [1, 2, 3])
def test_vectorised_condition_numbers_equal_the_scalar_ones(n: int) -> None:
    """``simulator.conditions`` (simulate_many's starts) against ``_condition`` (simulate's), singular,
    ill-conditioned and non-finite matrices included."""
    from vcigen.simulator import _condition, conditions

    rng = np.random.default_rng(n)
    a = rng.standard_normal((40, n, n))
    mass = a @ a.transpose(0, 2, 1) + 0.1 * np.eye(n)
    mass[1] = 0.0
    mass[2, 0, 0] = np.nan
    mass[3, -1, -1] = np.inf
    mass[4] = np.diag([1.0] * (n - 1) + [1e-14])
    mass[5] = -mass[6]
    got = conditions(mass)
    want = np.array([_condition(m) for m in mass])
    assert np.array_equal(np.isinf(got), np.isinf(want)) and np.isinf(want[1:4]).all()
    np.testing.assert_allclose(got[np.isfinite(want)], want[np.isfinite(want)], rtol=1e-12)
