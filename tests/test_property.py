"""Property-based: random boxes and billiards, random starts -- admissible, energy kept, clear errors.

Hypothesis is bounded (25 examples, derandomized, no deadline) so CI is reproducible. In the
elastic box and billiard a SolverError is allowed only if it carries step, phase and residual;
every one is recorded in ``SOLVER_ERRORS`` and printed, and a seeded sweep asserts they are rare.
The lossy box under gravity (bounces dying out, resting, sliding: sustained contact) allows none:
one is recorded and printed the same way, and fails the test.
"""

import math
from collections import Counter

import numpy as np
import pytest
import scenes
from hard_scenes import BACKENDS, RULES, impact_energy_jumps, min_phi, simulator
from hypothesis import HealthCheck, example, given, settings
from hypothesis import strategies as st

import vcigen
from vcigen.errors import PHASES
from vcigen.result import KINDS

SETTINGS = settings(
    max_examples=25, deadline=None, derandomize=True, suppress_health_check=[HealthCheck.too_slow]
)
SOLVER_ERRORS: list[str] = []

unit = st.floats(0.02, 0.98)
speed = st.floats(-3.0, 3.0)
step = st.floats(0.005, 0.05)


def _box_run(backend, rule, W, H, g, fx, fy, vx, vy, h):
    sim = simulator("box", backend, rule)
    params = {"W": W, "H": H, "g": g}
    return sim, params, dict(q0=[fx * W, fy * H], v0=[vx, vy], h=h, t_end=1.0, params=params)


def _billiard_run(backend, rule, k, R, fr, angle, vx, vy, h):
    sim = scenes.simulator("billiard", rule, backend)
    r = R * math.sqrt(0.95 * fr)
    params = {"k": k, "R": R}
    return (
        sim,
        params,
        dict(q0=[r * math.cos(angle), r * math.sin(angle)], v0=[vx, vy], h=h, t_end=1.0, params=params),
    )


def _check(sim, params, run) -> str | None:
    """Run; assert the properties; return the SolverError message if one was raised."""
    try:
        res = sim.simulate(**run)
    except vcigen.SolverError as err:
        assert err.phase in PHASES
        assert isinstance(err.step, int) and err.step >= 0
        assert math.isfinite(err.time) and not math.isinf(err.residual)
        msg = f"{sim.model.name} {sim.backend} {run}: {err}"
        SOLVER_ERRORS.append(msg)
        print("SolverError:", msg)
        return msg
    assert min_phi(sim, res, params) >= -1e-9
    if res.impacts:
        scale = max(1.0, float(np.max(np.abs(res.energy))))
        assert impact_energy_jumps(res).max() <= 1e-10 * scale
        assert all(im.impulse > 0 for im in res.impacts)
    assert np.all(np.isfinite(res.q)) and np.all(np.isfinite(res.p))
    return None


@pytest.mark.parametrize("rule", RULES)
@pytest.mark.parametrize("backend", BACKENDS)
@SETTINGS
@given(
    W=st.floats(0.2, 2.0),
    H=st.floats(0.2, 2.0),
    g=st.sampled_from([0.0, 1.0, 9.81]),
    fx=unit,
    fy=unit,
    vx=speed,
    vy=speed,
    h=step,
)
def test_random_box_admissible_and_energy_kept(backend, rule, W, H, g, fx, fy, vx, vy, h):
    _check(*_box_run(backend, rule, W, H, g, fx, fy, vx, vy, h))


@pytest.mark.parametrize("rule", RULES)
@pytest.mark.parametrize("backend", BACKENDS)
@SETTINGS
@given(
    k=st.floats(0.0, 5.0),
    R=st.floats(0.5, 2.0),
    fr=st.floats(0.0, 1.0),
    angle=st.floats(0.0, 2 * math.pi),
    vx=speed,
    vy=speed,
    h=step,
)
def test_random_billiard_admissible_and_energy_kept(backend, rule, k, R, fr, angle, vx, vy, h):
    _check(*_billiard_run(backend, rule, k, R, fr, angle, vx, vy, h))


@pytest.mark.parametrize("backend", BACKENDS)
def test_solver_errors_are_rare_over_a_seeded_sweep(backend):
    """40 seeded random runs (box and billiard): at most 2 SolverErrors, each printed."""
    rng = np.random.default_rng(2024)
    errors = []
    for _ in range(20):
        h = rng.uniform(0.005, 0.05)
        box = (
            rng.uniform(0.2, 2.0),
            rng.uniform(0.2, 2.0),
            rng.choice([0.0, 9.81]),
            *rng.uniform(0.02, 0.98, 2),
        )
        errors.append(_check(*_box_run(backend, "trapezoid", *box, *rng.uniform(-3, 3, 2), h)))
        bil = (rng.uniform(0, 5), rng.uniform(0.5, 2.0), rng.uniform(), rng.uniform(0, 2 * math.pi))
        errors.append(_check(*_billiard_run(backend, "trapezoid", *bil, *rng.uniform(-3, 3, 2), h)))
    errors = [e for e in errors if e]
    assert len(errors) <= 2, errors


@pytest.mark.parametrize("backend", BACKENDS)
@SETTINGS
@given(
    W=st.floats(0.2, 2.0),
    H=st.floats(0.2, 2.0),
    g=st.sampled_from([0.0, 9.81]),
    e=st.floats(0.0, 1.0),
    fx=unit,
    fy=unit,
    vx=speed,
    vy=speed,
    h=step,
)
# Found by a wider random probe: a lossy impact into a corner whose (78) has no root (now re-resolved by
# the continuous law), and a grazing impact whose E_d restarts on a shorter segment.
@example(
    W=0.9028260448358989,
    H=1.6362809949746377,
    g=9.81,
    e=0.1,
    fx=0.38525635581759066,
    fy=0.704727549559474,
    vx=0.6751068249918712,
    vy=2.6460058514556106,
    h=0.04962545226455884,
)
@example(
    W=0.3668887611648406,
    H=0.46557992366583467,
    g=9.81,
    e=1.0,
    fx=0.6467930004626904,
    fy=0.7025986626179304,
    vx=0.1810239132325533,
    vy=0.0,
    h=0.048397469354913174,
)
def test_random_lossy_box_admissible_and_energy_never_gained(backend, W, H, g, e, fx, fy, vx, vy, h):
    """Restitution e on every wall, default ``Tolerances()`` (sustained contact): never a SolverError.

    Bounces that die out, a body at rest on the floor, one sliding along it and grazing impacts
    are modelled (MATH.md, *Sustained contact*), so every run reaches ``t_end``; it stays
    admissible, no impact adds energy (it loses (39), or the normal kinetic energy when
    plastic), impulses are >= 0, at most 4 impacts share a grid step, and the contact force is
    >= 0 in a step where the contact is active at either end and exactly 0 in any other step.
    """
    sim = simulator("box_lossy", backend)
    params = {"W": W, "H": H, "g": g, "e": e}
    run = dict(q0=[fx * W, fy * H], v0=[vx, vy], h=h, t_end=1.0, params=params)
    try:
        res = sim.simulate(**run)
    except vcigen.SolverError as err:
        msg = f"box_lossy {backend} {run}: {err}"
        SOLVER_ERRORS.append(msg)
        print("SolverError:", msg)
        pytest.fail(f"SolverError in the default (sustained contact) mode: {msg}")
    n_steps, m = res.q.shape[0], len(sim.model.phi)
    assert res.t[-1] == pytest.approx(1.0, abs=h)
    assert min_phi(sim, res, params) >= -1e-9
    assert np.all(np.isfinite(res.q)) and np.all(np.isfinite(res.p))
    scale = max(1.0, float(np.max(np.abs(res.energy))))
    # MATH.md: energy never rises at an impact by more than the jump's resolution. A grazing impact (the
    # continuous law, (48a) had no root) restarts E_d on a segment of another length: its O(h^2) bias
    # g^2 h^2 / 8 (unit mass) is that resolution; every other impact keeps E_d or loses energy.
    resolution = (g * h) ** 2 / 8
    for im in res.impacts:
        allowed = 1e-10 * scale + (resolution if im.kind == "grazing" else 0.0)
        assert im.energy_after <= im.energy_before + allowed, im
        assert im.impulse >= 0, im
        assert im.kind in KINDS, im
    if res.impacts:
        assert max(Counter(im.step for im in res.impacts).values()) <= 4
    active, force = np.asarray(res.active), np.asarray(res.contact_force)
    assert active.shape == (n_steps, m) and active.dtype == bool
    assert force.shape == (n_steps - 1, m) and np.all(np.isfinite(force))
    either = active[:-1] | active[1:]  # a force acts in a step whose contact is active at either end
    assert np.all(force[either] >= -1e-9), force[either].min()
    assert np.all(force[~either] == 0.0), np.abs(force[~either]).max()
