"""Fast checks of the benchmark references and baselines (independent of vcigen)."""

from __future__ import annotations

import dataclasses
import sys
from pathlib import Path

import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from bench import baselines, reference  # noqa: E402
from bench import scenes as bench_scenes  # noqa: E402


def test_particle_closed_form_matches_dop853_reference() -> None:
    t = np.linspace(0.0, 3.0, 301)
    exact = reference.particle_closed_form(t)
    ode = reference.event_driven(bench_scenes.particle(), t)
    assert len(exact.impacts) == len(ode.impacts) == 3
    np.testing.assert_allclose(ode.impact_times, exact.impact_times, rtol=0, atol=1e-12)
    assert np.abs(ode.q - exact.q).max() < 1e-9
    assert np.abs(ode.v - exact.v).max() < 1e-9


def test_reference_energy_conserved() -> None:
    t = np.linspace(0.0, 3.0, 301)
    for traj in (
        reference.particle_closed_form(t),
        reference.event_driven(bench_scenes.particle(), t),
    ):
        assert np.ptp(traj.energy) < 1e-10


def test_star_exact_flight_and_dop853_agree_on_first_impacts() -> None:
    t = np.arange(0.0, 3.5, 0.005)
    exact = reference.star_exact(t, n_impacts=3)
    ode = reference.event_driven(bench_scenes.star(), t, n_impacts=3)
    assert len(exact.impacts) == len(ode.impacts) == 3
    np.testing.assert_allclose(ode.impact_times, exact.impact_times, rtol=0, atol=1e-8)
    assert np.ptp(exact.energy) < 1e-10
    assert bench_scenes.star_phi(exact.q.T).min() > -1e-12


def test_naive_verlet_is_first_order_after_one_impact() -> None:
    """RMS error at t=0.8 over 8 phases of the step grid relative to the impact."""
    sc = bench_scenes.particle()
    hs = np.array([0.01, 0.005, 0.0025, 0.00125])
    errs = []
    for h in hs:
        e = []
        for u in (np.arange(8) + 0.5) / 8:
            tau = u * h
            start = reference.particle_closed_form(np.array([tau]))
            shifted = dataclasses.replace(sc, q0=start.q[0], v0=start.v[0])
            run = baselines.run_verlet_full_flip(shifted, h, t_end=0.8)
            assert len(run["impacts"]) == 1
            ref = reference.particle_closed_form(np.array([tau + run["t"][-1]]))
            e.append(np.linalg.norm(run["q"][-1] - ref.q[0]))
        errs.append(np.sqrt(np.mean(np.square(e))))
    slope = np.polyfit(np.log(hs), np.log(errs), 1)[0]
    assert 0.8 < slope < 1.3, (slope, errs)


def test_pendulum_wall_scene_is_well_posed() -> None:
    sc = bench_scenes.pendulum_wall()
    m = sc.mass(sc.q0)
    np.testing.assert_allclose(m, m.T)
    assert np.linalg.eigvalsh(m).min() > 0
    for q in np.random.default_rng(0).uniform(-np.pi, np.pi, (20, 2)):
        assert np.linalg.eigvalsh(sc.mass(q)).min() > 0
    assert sc.contacts[0].phi(sc.q0) > 0


def test_baselines_return_the_common_keys() -> None:
    sc = bench_scenes.particle()
    for name in ("verlet_full_flip", "verlet_half_flip", "rk45_events"):
        arg = 1e-8 if "events" in name else sc.h
        res = baselines.METHODS[name](sc, arg, t_end=1.5)
        assert {"t", "q", "v", "energy", "impacts", "wall"} <= res.keys()
        assert res["q"].shape == (res["t"].size, 2) and res["wall"] > 0
        assert len(res["impacts"]) == 2
    skip = baselines.run_verlet_full_flip(bench_scenes.pendulum_wall(), 0.005, t_end=1.0)
    assert "constant mass" in skip["skip"]


@pytest.mark.parametrize("name", sorted(bench_scenes.SCENES))
def test_scene_gradients_match_finite_differences(name: str) -> None:
    sc = bench_scenes.get(name)
    q = sc.q0 + 0.013  # off the star's kink
    eps = 1e-6
    eye = np.eye(sc.n)
    fd_v = [(sc.potential(q + eps * e) - sc.potential(q - eps * e)) / (2 * eps) for e in eye]
    np.testing.assert_allclose(sc.grad_potential(q), fd_v, rtol=1e-6, atol=1e-6)
    for c in sc.contacts:
        fd = [(c.phi(q + eps * e) - c.phi(q - eps * e)) / (2 * eps) for e in eye]
        np.testing.assert_allclose(c.grad_phi(q), fd, rtol=1e-6, atol=1e-6)


def test_cvode_baseline_hits_the_particle_closed_form() -> None:
    """SUNDIALS CVODE with root-finding: impact times and positions of the exact bouncing particle."""
    pytest.importorskip("sksundae", reason="scikit-sundae (CVODE) does not install here; the bench skips it")
    sc = bench_scenes.particle()
    res = baselines.METHODS["cvode_events"](sc, 1e-10, t_end=1.5, grid_h=0.01)
    ref = reference.particle_closed_form(res["t"], q0=tuple(sc.q0), v0=tuple(sc.v0))
    np.testing.assert_allclose(res["q"], ref.q, atol=1e-8)
    u = np.sqrt(sc.v0[1] ** 2 + 2 * 9.81 * sc.q0[1])
    t1 = (sc.v0[1] + u) / 9.81
    np.testing.assert_allclose(res["impacts"], t1 + 2 * u / 9.81 * np.arange(len(res["impacts"])), atol=1e-9)
    assert len(res["impacts"]) == 2 and res["nfev"] > 0
