"""Kinks of phi (Abs, Min, Max): the normal-cone centre at a kink (eq. 86)."""

import sys
from functools import cache
from pathlib import Path

import numpy as np
import pytest
import sympy as sp
from scenes import simulator

import vcigen


@pytest.mark.parametrize("backend", ["casadi", "c"])
@pytest.mark.parametrize("rule", ["trapezoid", "midpoint"])
def test_star_dropped_flat_bounces_straight_up(rule, backend):
    """theta = 0 is a kink of eq. (81): two vertices touch at once; no side may be picked."""
    res = simulator("star", rule, backend).simulate(q0=[0.0, 1.0, 0.0], v0=[0.5, 0.0, 0.0], h=0.01, t_end=0.5)
    assert res.n_impacts == 1
    assert np.max(np.abs(res.q[:, 2])) < 1e-15 and np.max(np.abs(res.p[:, 2])) < 1e-15
    assert res.impacts[0].energy_after == pytest.approx(res.impacts[0].energy_before, abs=1e-12)
    assert res.p[-1, 1] > 0


def test_min_contact_box_corner_symmetric():
    """A particle into the corner of phi = Min(x, y) at 45 degrees comes straight back."""
    x, y, xd, yd = sp.symbols("x y xd yd")
    model = vcigen.Model(
        name="corner",
        q=[x, y],
        qdot=[xd, yd],
        lagrangian=(xd**2 + yd**2) / 2,
        contacts={"corner": sp.Min(x, y)},
    )
    res = vcigen.build(model).simulate(q0=[0.5, 0.5], v0=[-1.0, -1.0], h=0.025, t_end=1.0)
    assert res.n_impacts == 1
    np.testing.assert_allclose(res.p[-1], [1.0, 1.0], atol=1e-12)
    np.testing.assert_allclose(res.q[-1], [0.5, 0.5], atol=1e-12)


@pytest.mark.parametrize("backend", ["casadi", "c"])
def test_the_elastic_stars_next_vertex_right_after_an_impact_is_its_own_impact(backend):
    """The paper's star (``examples/star.py``'s run) from its state at t = 437.675 on CasADi: after an impact
    its next vertex (the same contact, another branch of eq. 81's ``Abs``) crosses within the first 1e-3 of
    the segment. Stop 35's first rule for a contact crossing back at once (ffcd6a9) restarted that impact by
    the continuous law whatever the impact; here the restarts repeated until "more than 64 impacts in one
    step" (``make demo`` stopped at t = 437.705). The rule now holds only after an impact that left no normal
    speed (``e = 0``); the elastic star takes each vertex's impact as before: elastic, ``E_d`` kept to 1e-12,
    no continuous-law fallback."""
    q0 = [-875.3499999993517, 0.7296517411073138, 65.83513659411634]
    v0 = [-2.0, -7.415333416321096, 4.556252984208833]
    res = simulator("star", "trapezoid", backend).simulate(q0=q0, v0=v0, h=0.005, t_end=0.3)
    assert len(res.impacts) >= 2 and all(i.kind == "elastic" for i in res.impacts)
    assert res.stats["jump_fallbacks"] == 0
    assert all(abs(i.energy_after - i.energy_before) <= 1e-12 * abs(i.energy_before) for i in res.impacts)


@pytest.mark.parametrize("backend", ["casadi", "c"])
@pytest.mark.parametrize("spin, theta0", [(4.0, 0.0), (5.0, 0.0), (1.0, 1e-9)])
def test_a_star_flat_on_a_face_and_spinning_bounces_off_its_one_vertex_going_in(backend, spin, theta0):
    """``examples/contact/star_settles.py``'s star (``e = 0.5``) started flat on a face (``theta = 0``, a
    kink of eq. 81: two vertices touch) spinning at ``w``: one vertex goes in at ``w L/2``, the other out.
    Newton's law on that vertex at ``r = (-L/2, -L/2)``: impulse ``P = (1 + e) w L/2 / (1/m + (L/2)^2/I)``,
    then ``vy = P/m``, ``w+ = w - (L/2) P/I``. Before stop 36 the jump (48) took the normal cone's centre
    (86), whose normal speed (the mean of the two vertices', 0) made the impact plastic at ``w = 4``, and at
    ``w = 5`` (the vertex pulled off: not pressed in) found the root ``mu = g h/2`` again and again: "more
    than 64 impacts in one step". At ``theta0 = 1e-9`` the star starts 5e-10 below the floor (within
    ``Tolerances.admissible``), off the kink, one vertex moving in: the contact time's root lies before the
    step, where the root search found no sign change ("contact time solve failed" at step 0); it is the
    impact at t = 0, by the jump (48) on that vertex's branch, whose rebound is Newton's to O(g h)."""
    sim = _star_settles(backend)
    m, g, half, inertia, e, h = 1.0, 9.81, 0.5, 29 / 192, 0.5, 0.005
    res = sim.simulate(q0=[0.0, 0.5, theta0], v0=[0.0, 0.0, spin], h=h, t_end=0.2, params={"e": e})
    first = res.impacts[0]
    assert (first.step, first.t, first.kind) == (0, 0.0, "restitution")
    impulse = (1 + e) * spin * half / (1 / m + half**2 / inertia)
    tol = 1e-12 if theta0 == 0.0 else 0.1 * g * h  # Newton's law on the rows; else the jump (48)
    assert res.p[1, 1] / m == pytest.approx(impulse / m - g * h, abs=tol)
    assert res.p[1, 2] / inertia == pytest.approx(spin - half * impulse / inertia, abs=tol)
    assert res.p[1, 0] == 0.0 and all(im.step > 1 for im in res.impacts[1:])  # one impact, then flight


@cache
def _star_settles(backend: str) -> vcigen.Simulator:
    sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "examples" / "contact"))
    import star_settles

    return vcigen.build(star_settles.model(), backend=backend)


@pytest.mark.parametrize("backend", ["casadi", "c"])
def test_the_tangent_breaks_at_a_kinks_impulse_law(backend):
    """The spinning star's impact at its kink (the test above) takes the impulse law on its two vertex
    rows, which the tangent does not carry: ``sensitivities=True`` reports the break there, ``"simultaneous
    impact"`` (NaN from there), on both backends alike."""
    res = _star_settles(backend).simulate(
        q0=[0.0, 0.5, 0.0], v0=[0.0, 0.0, 4.0], h=0.005, t_end=0.1, params={"e": 0.5}, sensitivities=True
    )
    assert res.sensitivity_breaks[0] == (0, "simultaneous impact")
    assert np.isnan(res.sensitivity[-1]).all()
