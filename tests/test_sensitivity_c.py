"""Sensitivities in C (``vcigen.backends.csens``, ``templates/sens.c.j2``): the tangent carried inside the
generated loop equals the Python stepper's (``vcigen.sensitivity``, CasADi backend) on every scene of
``test_sensitivity``, the steps no tangent goes through are the same, the variant's trajectory is the plain
library's bit for bit (explicit glide, held glide, general step), and a run resumed across calls (buffers
grown) or cut by a ``SolverError`` keeps its tangent. The agreement with finite differences on the C backend
is ``test_sensitivity``'s own (parametrized over both backends).
"""

from __future__ import annotations

from functools import cache

import hard_scenes
import numpy as np
import pytest
import test_sensitivity as ts
from scenes import load_example

import vcigen
from vcigen.backends import csens

pytestmark = pytest.mark.skipif(
    hard_scenes.c_backend_problem() is not None, reason=str(hard_scenes.c_backend_problem())
)
TOL = 1e-9  # C against CasADi, relative to the largest entry (test_sensitivity.relative_error)


def both(sim_of, *args, **kw) -> tuple[vcigen.Result, vcigen.Result]:
    """The same run with sensitivities on the CasADi and the C backend."""
    kw.update(sensitivities=True, progress=False)
    return sim_of("casadi").simulate(*args, **kw), sim_of("c").simulate(*args, **kw)


def assert_same_tangent(a: vcigen.Result, b: vcigen.Result, tol: float = TOL) -> float:
    """Same grid, same breaks, NaN in the same places and the finite entries within ``tol`` (relative)."""
    assert a.sensitivity.shape == b.sensitivity.shape and a.sensitivity_names == b.sensitivity_names
    assert a.sensitivity_breaks == b.sensitivity_breaks
    assert a.stats.get("sensitivity_lost") == b.stats.get("sensitivity_lost")
    nan = np.isnan(a.sensitivity)
    assert np.array_equal(nan, np.isnan(b.sensitivity))
    fin = ~nan
    if not fin.any():
        return 0.0
    rel = float(np.abs(a.sensitivity[fin] - b.sensitivity[fin]).max() / np.abs(a.sensitivity[fin]).max())
    assert rel <= tol, rel
    return rel


@pytest.mark.parametrize("scene", sorted(ts.SCENES))
def test_c_equals_casadi_on_every_scene(scene: str) -> None:
    _, q0, v0, h, t_end, params = ts.SCENES[scene]
    a, b = both(lambda backend: ts.simulator(scene, backend), q0, v0, h, t_end=t_end, params=params)
    rel = assert_same_tangent(a, b)
    print(f"{scene}: {b.n_impacts} impacts, C against CasADi {rel:.1e}")
    assert b.n_impacts >= 1 and b.sensitivity_breaks == [] and np.isfinite(b.sensitivity).all()


@cache
def midpoint(scene: str, backend: str) -> vcigen.Simulator:
    return vcigen.build(ts.SCENES[scene][0](), backend=backend, rule="midpoint")


@pytest.mark.parametrize("scene", ["star", "corner_lossy", "driven", "double_pendulum"])
def test_c_equals_casadi_under_the_midpoint_rule(scene: str) -> None:
    _, q0, v0, h, t_end, params = ts.SCENES[scene]
    a, b = both(lambda backend: midpoint(scene, backend), q0, v0, h, t_end=t_end, params=params)
    rel = assert_same_tangent(a, b)
    print(f"{scene} (midpoint): {b.n_impacts} impacts, C against CasADi {rel:.1e}")
    assert b.n_impacts >= 1 and np.isfinite(b.sensitivity).all()


@pytest.mark.parametrize("example", ["particle", "star"])
def test_c_equals_casadi_on_the_examples(example: str) -> None:
    """The explicit glide's steps (the straight-line grid step) carry the tangent as the general step does."""
    setup = load_example(example).SETUP
    model = load_example(example).model()
    sims = {backend: vcigen.build(model, backend=backend) for backend in ("casadi", "c")}
    a, b = both(sims.__getitem__, setup["q0"], setup["v0"], setup["h"], n_impacts=4)
    rel = assert_same_tangent(a, b)
    print(f"{example}: {b.n_impacts} impacts over {b.t.size - 1} steps, C against CasADi {rel:.1e}")


def test_breaks_are_the_python_steppers() -> None:
    """A lossy ball to rest: restitution impacts, a plastic impact (sens_plastic, then the constrained
    rest of its step), then held steps (the held glide in C): covered on both backends, the same tangent.
    Sliding off a dome: held steps covered (the glide, one step at a time), the lift-off step too (on C by
    the generated sens_liftoff, as the Python stepper's Tracker.liftoff), no break. The paper's star with
    e = 0.8 settling: rocking on a vertex, impacts while held (sens_events.c.j2, Tracker.event and impulse)
    to rest on a face: covered on both backends (the breaks that remain: test_sensitivity_held_events)."""
    sims = {backend: vcigen.build(hard_scenes.ball(), backend=backend) for backend in ("casadi", "c")}
    a, b = both(sims.__getitem__, [0.0, 1.0], [0.3, 0.0], 0.01, t_end=2.8)
    rel = assert_same_tangent(a, b)
    print(f"ball to rest: C against CasADi {rel:.1e}")
    assert b.sensitivity_breaks == [] and b.active[-1].all() and b.stats["impacts_plastic"] == 1
    from test_c_agreement_sustained import _dome, _star

    dome = _dome()
    sims = {backend: vcigen.build(dome, backend=backend) for backend in ("casadi", "c")}
    a, b = both(sims.__getitem__, [0.0, 1.0], [0.1, 0.0], 0.005, t_end=1.6)
    rel = assert_same_tangent(a, b)
    print(f"dome across its lift-off: C against CasADi {rel:.1e}")
    assert a.sensitivity_breaks == b.sensitivity_breaks == [] and len(b.liftoffs) == 1
    star = _star()
    sims = {backend: vcigen.build(star, backend=backend) for backend in ("casadi", "c")}
    a, b = both(sims.__getitem__, [0.0, 3.5, 0.0], [-2.0, 0.0, 5.0], 0.005, t_end=9.0)
    # its two trajectories differ by ~1e-9 after some 40 restitution impacts (test_c_agreement_sustained.TOL:
    # 1e-6), and the tangents, which grow through them, by 3e-6 already before the first plastic impact
    assert np.abs(a.q - b.q).max() <= 1e-6
    rel = assert_same_tangent(a, b, tol=1e-4)
    held = [im for im in b.impacts if b.active[im.step].any()]  # an impact while the star was held
    print(f"star settling: C against CasADi {rel:.1e}, {len(held)} impacts while held, no break")
    assert b.sensitivity_breaks == [] and b.stats["impacts_plastic"] >= 1 and held and b.active[-1].any()


@pytest.mark.parametrize("scene", sorted(ts.HELD_SCENES))
def test_c_equals_casadi_on_held_steps(scene: str) -> None:
    """Held steps: the C glide's steps (the tangent from each step's solution) and the chain's, against the
    Python stepper's (vcigen.held / SustainedSteps._chain, then Tracker.held)."""
    _, q0, v0, h, t_end, params, _ = ts.HELD_SCENES[scene]
    a, b = both(lambda backend: ts.held_simulator(scene, backend), q0, v0, h, t_end=t_end, params=params)
    rel = assert_same_tangent(a, b)
    print(f"{scene}: {b.t.size - 1} held steps, C against CasADi {rel:.1e}")
    assert b.sensitivity_breaks == [] and np.isfinite(b.sensitivity).all()


@pytest.mark.parametrize("scene", sorted(ts.LIFT_SCENES))
def test_c_equals_casadi_across_a_liftoff(scene: str) -> None:
    """A lift-off at a located time: the C run's tangent (its lift-off step by the generated sens_liftoff)
    against the CasADi run's, and the C trajectory unchanged by asking for the tangent."""
    _, q0, v0, h, t_end, params, _ = ts.LIFT_SCENES[scene]
    a, b = both(lambda backend: ts.lift_simulator(scene, backend), q0, v0, h, t_end=t_end, params=params)
    rel = assert_same_tangent(a, b)
    print(f"{scene}: lift-off at {b.liftoffs[0][0]:.6f}, C against CasADi {rel:.1e}")
    assert a.sensitivity_breaks == b.sensitivity_breaks == [] and np.isfinite(b.sensitivity).all()
    off = ts.lift_simulator(scene, "c").simulate(q0, v0, h, t_end=t_end, params=params, progress=False)
    assert np.array_equal(off.q, b.q) and np.array_equal(off.p, b.p) and np.array_equal(off.energy, b.energy)


def test_simultaneous_impact_breaks_the_same() -> None:
    a, b = both(lambda backend: ts.simulator("corner", backend), [0.05, 0.05], [-1.0, -1.0], 0.1, t_end=0.3)
    assert_same_tangent(a, b)
    assert b.sensitivity_breaks[0][1] == "simultaneous impact"


@pytest.mark.parametrize("scene", ["star", "ball", "double_pendulum", "box_lossy", "bowl", "box_face"])
def test_the_variant_leaves_the_trajectory_unchanged(scene: str) -> None:
    """The variant library takes the same steps as the plain one (its glides included), bit for bit."""
    if scene == "star":
        sim = vcigen.build(load_example("star").model(), backend="c")
        args, kw = ([0.0, 1.2, 0.0], [-2.0, 0.0, 5.0], 0.005), {"t_end": 2.0}
    elif scene == "ball":
        sim = vcigen.build(hard_scenes.ball(), backend="c")
        args, kw = ([0.0, 1.0], [0.3, 0.0], 0.01), {"t_end": 2.8}
    elif scene in ts.HELD_SCENES:  # held throughout: the glide one step at a time, with the tangent
        _, q0, v0, h, t_end, params, _ = ts.HELD_SCENES[scene]
        sim, args, kw = ts.held_simulator(scene, "c"), (q0, v0, h), {"t_end": t_end, "params": params}
    else:
        _, q0, v0, h, t_end, params = ts.SCENES[scene]
        sim, args, kw = ts.simulator(scene, "c"), (q0, v0, h), {"t_end": t_end, "params": params}
    off = sim.simulate(*args, **kw, progress=False)
    on = sim.simulate(*args, **kw, progress=False, sensitivities=True)
    for name in ("t", "q", "p", "energy", "active", "contact_force"):
        assert np.array_equal(getattr(off, name), getattr(on, name)), name
    assert off.impacts == on.impacts
    assert off.sensitivity is None and on.sensitivity.shape[0] == on.t.size


def test_a_run_resumed_across_calls_keeps_its_tangent(monkeypatch) -> None:
    """A run of unknown length (``n_impacts``) with buffers of 16 rows: the C loop stops each time S must
    grow and resumes from the tangent it left in ``s``; the same as one call of a ``t_end`` run."""
    sim = ts.simulator("box_lossy", "c")
    _, q0, v0, h, t_end, params = ts.SCENES["box_lossy"]
    full = sim.simulate(q0, v0, h, t_end=t_end, params=params, sensitivities=True, progress=False)
    monkeypatch.setattr(csens, "RESERVE_BYTES", 1)
    calls = []
    real = csens.SensRun.arm
    monkeypatch.setattr(csens.SensRun, "arm", lambda self, chunk: calls.append(self.cap) or real(self, chunk))
    parts = sim.simulate(
        q0, v0, h, n_impacts=full.n_impacts, params=params, sensitivities=True, progress=False
    )
    assert calls[:4] == [16, 16, 32, 64]  # 110 steps: calls of 16, 16, 32 and 64 rows (grown between)
    k = parts.t.size
    assert parts.t[-1] <= full.t[-1] and np.array_equal(parts.sensitivity, full.sensitivity[:k])


def test_a_failed_run_keeps_the_tangent_so_far() -> None:
    """No room for an impact in a step: the SolverError's result has the tangent up to the last step."""
    model = load_example("particle").model()
    tol = vcigen.Tolerances(max_impacts_per_step=0)
    setup = load_example("particle").SETUP
    out = []
    for backend in ("casadi", "c"):
        sim = vcigen.build(model, backend=backend, tol=tol)
        with pytest.raises(vcigen.SolverError) as info:
            sim.simulate(setup["q0"], setup["v0"], setup["h"], t_end=1.0, sensitivities=True, progress=False)
        out.append(info.value.result)
    a, b = out
    assert b.sensitivity.shape == (46, 4, 6) and np.isfinite(b.sensitivity).all()
    assert_same_tangent(a, b)


def test_parameters_are_columns_and_override_at_run_time() -> None:
    """``g`` is a column; a run at another ``g`` (the same library) has its own tangent, as CasADi's."""
    sims = {
        backend: vcigen.build(load_example("particle").model(), backend=backend)
        for backend in ("casadi", "c")
    }
    a, b = both(sims.__getitem__, [0.0, 1.0], [-2.0, 0.0], 0.01, t_end=0.8, params={"g": 3.0})
    assert_same_tangent(a, b)
    assert b.sensitivity_names[-2:] == ["m", "g"]
    # y(t) = 1 - g t^2 / 2 before the first impact (t = 0.8165 at g = 3): dy/dg = -t^2 / 2 up to O(h^2)
    k = 50
    assert abs(b.sensitivity[k, 1, -1] + b.t[k] ** 2 / 2) <= 1e-12


def test_grazing_impact_breaks_the_same() -> None:
    """Apex 1e-8 above a ceiling with ``grazing="reflect"``: the continuous law is no jump (48) to
    differentiate; the impact's step is reported, as in Python."""
    g, vy = 9.81, 9.81 * 0.5
    q0, v0 = [0.0, 1.0 + 1e-8 - vy**2 / (2 * g)], [1.0, vy]
    tol = vcigen.Tolerances(grazing="reflect")
    with pytest.warns(RuntimeWarning, match="grazing"):
        a, b = both(
            lambda backend: hard_scenes.simulator("ceiling", backend, tol=tol), q0, v0, 0.01, t_end=1.0
        )
    assert_same_tangent(a, b)
    assert [im.kind for im in b.impacts] == ["grazing"]
    assert b.sensitivity_breaks == [(b.impacts[0].step, "grazing impact")]
