"""Lagrange-d'Alembert forces (MATH.md, *Forcing*) on both backends, against closed forms.

The damped, driven oscillator against a wall with restitution (piecewise exact flow, impacts located on
it to round-off: ``forced_scenes``) gives order 2 through impacts; the work booked in ``res.work``
balances the energy to O(h^2) with no drift; forces of time act in sustained contact (a push along a
floor, a rising lift that makes a resting body leave exactly when it exceeds gravity); zero forces are
bit-identical to no forces; bad forces are refused.
"""

from __future__ import annotations

import math
from functools import cache

import numpy as np
import pytest
import sympy as sp
from forced_scenes import (
    AMPLITUDE,
    DAMPING,
    DRIVE,
    REST,
    STIFFNESS,
    LinearFlow,
    driven_exact,
    driven_oscillator,
    driven_wall_errors,
)
from hard_scenes import BACKENDS, G

import vcigen
from vcigen.analysis import fit_order

RULES = ["trapezoid", "midpoint"]


@cache
def driven(backend: str, rule: str = "trapezoid") -> vcigen.Simulator:
    return vcigen.build(driven_oscillator(), backend=backend, rule=rule)


def lifted() -> vcigen.Model:
    """A unit particle on a floor, pushed along it by ``A sin(W t)`` and lifted by ``B t`` (gravity G)."""
    x, y, xd, yd, t = sp.symbols("x y xd yd t")
    A, W, B = sp.symbols("A W B")
    return vcigen.Model(
        name="lifted",
        q=[x, y],
        qdot=[xd, yd],
        lagrangian=(xd**2 + yd**2) / 2 - G * y,
        contacts={"floor": y},
        params={A: 1.5, W: 2.0, B: 2.0},
        forces=[A * sp.sin(W * t), B * t],
        time=t,
    )


@cache
def lifted_sim(backend: str) -> vcigen.Simulator:
    return vcigen.build(lifted(), backend=backend)


# ------------------------------------------------------------------ order and agreement


@pytest.mark.parametrize("rule", RULES)
@pytest.mark.parametrize("backend", BACKENDS)
def test_order_two_through_impacts_with_damping_and_drive(backend, rule):
    """Max grid error against the exact piecewise flow: fitted order 2 through two lossy impacts."""
    sim = driven(backend, rule)
    hs = [0.02, 0.01, 0.005, 0.0025]
    errs, hit_errs = driven_wall_errors(sim, hs)
    assert abs(fit_order(hs, errs) - 2.0) < 0.2, errs
    assert abs(fit_order(hs, hit_errs) - 2.0) < 0.3, hit_errs
    assert errs[-1] < 2e-5


@pytest.mark.parametrize("backend", BACKENDS)
def test_impact_keeps_the_energy_at_the_impact_point(backend):
    """(37): across an impact the energy at the end of the segment before equals the one at the start of the
    segment after, less the restitution loss ``(1 - e^2) v^2 / 2`` of the incoming velocity."""
    res = driven(backend).simulate(q0=[0.0], v0=[0.0], h=0.01, t_end=10.0)
    _, _, hits = driven_exact(0.0, 0.0, float(res.t[-1]))
    for im in res.impacts:
        assert im.energy_before > im.energy_after
    # the loss is that of the located impact velocity, to O(h^2)
    flow = LinearFlow(DAMPING, STIFFNESS, AMPLITUDE, DRIVE)
    _, v_hit = flow(0.0, 0.0, 0.0, hits[0])
    loss = (1 - REST**2) * float(v_hit) ** 2 / 2
    im = res.impacts[0]
    assert abs((im.energy_before - im.energy_after) - loss) < 1e-3 * loss + 1e-4


def test_c_equals_casadi_with_forces_of_time():
    """The same trajectory, energies, work and impacts on both backends, from t0 != 0."""
    out = [driven(b).simulate(q0=[0.1], v0=[0.5], h=0.01, t_end=12.0, t0=0.37) for b in ("casadi", "c")]
    a, b = out
    assert len(a.impacts) == len(b.impacts) >= 2
    np.testing.assert_allclose(a.q, b.q, rtol=0, atol=1e-11)
    np.testing.assert_allclose(a.energy, b.energy, rtol=0, atol=1e-11)
    np.testing.assert_allclose(a.work, b.work, rtol=0, atol=1e-12)
    for ia, ib in zip(a.impacts, b.impacts):
        assert abs(ia.t - ib.t) < 1e-11 and abs(ia.energy_after - ib.energy_after) < 1e-11


# ------------------------------------------------------------------ work and energy


@pytest.mark.parametrize("backend", BACKENDS)
def test_energy_balance_is_second_order(backend):
    """``E_k - E_0 - sum W + losses`` shrinks like h^2 (the method's own energy error), impacts included."""
    sim = driven(backend)
    worst = []
    for h in (0.01, 0.005):
        res = sim.simulate(q0=[0.0], v0=[0.0], h=h, t_end=10.0)
        assert res.work.shape == res.energy.shape
        worst.append(float(np.max(np.abs(res.energy_balance()))))
    assert worst[0] < 1.5e-3
    assert 3.0 < worst[0] / worst[1] < 5.5, worst


@pytest.mark.parametrize("rule,bound,drift", [("trapezoid", 6e-3, 1e-4), ("lobatto3", 1e-7, 1e-9)])
def test_energy_balance_has_no_drift_under_a_periodic_drive(rule, bound, drift):
    """2e5 steps of the undamped driven oscillator (C, wall out of reach): the balance is bounded, no drift
    (lobatto3 books its own work quadrature: measured max 3.1e-8, last tenth less first tenth 5.9e-11)."""
    res = driven("c", rule).simulate(q0=[0.0], v0=[0.0], h=0.01, t_end=2000.0, params={"c": 0.0, "d": 100.0})
    bal = res.energy_balance()
    n = bal.size
    assert np.sum(np.abs(res.work)) > 1000.0  # the drive does work, both ways
    assert np.max(np.abs(bal)) < bound
    assert abs(np.mean(bal[-n // 10 :]) - np.mean(bal[: n // 10])) < drift


def test_energy_balance_with_damping_and_impacts_is_second_order_and_bounded():
    """With dissipation and 541 impacts the balance stays at the method's own O(h^2) error: after 2e5 steps
    its largest value is below 1e-3 and quarters with h, far below sum |W| ~ 1.7e3 (the impact steps' node
    mismatch is booked, ``vcigen.work.impact_work``; without it the balance grew to 2.7e-2 here)."""
    worst = []
    for h in (0.02, 0.01):
        res = driven("c").simulate(q0=[0.0], v0=[0.0], h=h, t_end=2000.0)
        assert len(res.impacts) > 500 and np.sum(np.abs(res.work)) > 1500.0
        worst.append(float(np.max(np.abs(res.energy_balance()))))
    assert worst[1] < 1e-3 and 3.5 < worst[0] / worst[1] < 4.5, worst


def test_work_is_zero_without_forces_and_matches_damping():
    """A free damped oscillator: sum W = E_end - E_0 to O(h^2), E(t) the exact decay; no forces: W = 0."""
    x, xd = sp.symbols("x xd")
    c = sp.Symbol("c")
    damped = vcigen.Model(
        name="damped", q=[x], qdot=[xd], lagrangian=xd**2 / 2 - x**2 / 2, params={c: 0.2}, forces=[-c * xd]
    )
    free = vcigen.Model(name="free", q=[x], qdot=[xd], lagrangian=xd**2 / 2 - x**2 / 2)
    res = vcigen.build(damped, backend="casadi").simulate(q0=[1.0], v0=[0.0], h=0.01, t_end=5.0)
    # damping: each node's kick J = -c h vbar does the work J . vbar = -c h |vbar|^2 <= 0 (vcigen.work), so
    # the work done up to any step is <= 0 (a single step's need not be: it holds a part of two nodes)
    assert np.all(np.cumsum(res.work) <= 0.0)
    assert abs(res.energy_balance()[-1]) < 1e-4
    # the energy itself follows the exact decay: E(t) of x = e^{-ct/2}(cos wd t + c/(2wd) sin wd t)
    wd = math.sqrt(1 - 0.01)
    t = res.t[1:]
    xe = np.exp(-0.1 * t) * (np.cos(wd * t) + 0.1 / wd * np.sin(wd * t))
    ve = -np.exp(-0.1 * t) * (1 / wd) * np.sin(wd * t)
    assert np.max(np.abs(res.energy - (xe**2 + ve**2) / 2)) < 1e-4
    res0 = vcigen.build(free, backend="casadi").simulate(q0=[1.0], v0=[0.0], h=0.01, t_end=1.0)
    assert np.all(res0.work == 0.0)


@pytest.mark.parametrize("backend", BACKENDS)
def test_zero_forces_are_bit_identical_to_none(backend):
    """``forces=[0, 0]`` derives the same routines: the same bits as the model without forces."""
    x, y, xd, yd = sp.symbols("x y xd yd")
    kw = dict(
        q=[x, y],
        qdot=[xd, yd],
        lagrangian=(xd**2 + yd**2) / 2 - G * y,
        contacts={"floor": y},
        restitution={"floor": 0.5},
    )
    a = vcigen.build(vcigen.Model(name="plain", **kw), backend=backend)
    b = vcigen.build(vcigen.Model(name="zero_force", forces=[0, sp.S.Zero], **kw), backend=backend)
    ra, rb = (s.simulate(q0=[0.0, 1.0], v0=[1.0, 0.0], h=0.01, t_end=3.0) for s in (a, b))
    assert len(ra.impacts) > 3
    assert np.array_equal(ra.q, rb.q) and np.array_equal(ra.p, rb.p) and np.array_equal(ra.energy, rb.energy)
    assert [im.t for im in ra.impacts] == [im.t for im in rb.impacts]


# ------------------------------------------------------------------ forces in sustained contact


@pytest.mark.parametrize("backend", BACKENDS)
def test_push_along_a_floor_and_lift_off_when_the_lift_exceeds_gravity(backend):
    """Resting on the floor, ``x'' = A sin(W t)`` exactly while ``B t < g``; it leaves at ``t* = g / B``, then
    ``y = B (t - t*)^3 / 6``. The normal force is ``g - B t`` while held."""
    sim = lifted_sim(backend)
    A, W, B = 1.5, 2.0, 2.0
    t_star = G / B
    errs, lift = [], []
    for h in (0.01, 0.005):
        res = sim.simulate(q0=[0.0, 0.0], v0=[0.0, 0.0], h=h, t_end=6.0)
        assert len(res.liftoffs) == 1 and res.liftoffs[0][1] == "floor"
        lift.append(abs(res.liftoffs[0][0] - t_star))
        t = res.t
        xe = A / W * t - A / W**2 * np.sin(W * t)
        ye = np.where(t > t_star, B * np.clip(t - t_star, 0, None) ** 3 / 6, 0.0)
        errs.append(max(np.max(np.abs(res.q[:, 0] - xe)), np.max(np.abs(res.q[:, 1] - ye))))
        held = res.active[:-1, 0] & res.active[1:, 0]
        tm = t[:-1] + h / 2
        assert np.max(np.abs(res.contact_force[held, 0] - (G - B * tm[held]))) < 1e-6
        assert np.all(np.abs(res.q[t < t_star - h, 1]) < 1e-12)
    assert max(lift) < 1e-9, lift  # the normal force g - B t is linear in t: the lift-off is located exactly
    assert errs[1] < errs[0] / 3, errs


# ------------------------------------------------------------------ bad input


def test_bad_forces_are_refused():
    x, y, xd, yd, t, z = sp.symbols("x y xd yd t z")
    base = dict(name="bad", q=[x, y], qdot=[xd, yd], lagrangian=(xd**2 + yd**2) / 2)
    with pytest.raises(ValueError, match="one generalized force per coordinate"):
        vcigen.Model(forces=[-xd], **base)
    with pytest.raises(
        ValueError, match=r"contains z, which is neither a coordinate, a velocity, a parameter"
    ):
        vcigen.Model(forces=[z, 0], **base)
    with pytest.raises(ValueError, match=r"contains t.*needs Model\(time=t\)"):
        vcigen.Model(forces=[sp.cos(t), 0], **base)
    with pytest.raises(ValueError, match="time symbol x is also a coordinate"):
        vcigen.Model(forces=[0, 0], time=x, **base)
    with pytest.raises(ValueError, match="is not a SymPy symbol"):
        vcigen.Model(forces=[0, 0], time="t", **base)
    m = vcigen.Model(forces=[sp.cos(t), -yd], time=t, **base)
    assert m.time_symbol is not None and len(m.force) == 2
    assert vcigen.Model(forces=[sp.cos(x), 0], time=t, **base).time_symbol is None  # no time in the force


def test_time_in_a_contact_constraint_or_lagrangian_is_refused_naming_the_way_round():
    """Time enters through forces only: a contact, a constraint or a Lagrangian of the time symbol is a
    ``ValueError`` that says so and names the way round (the boundary's frame, a force of time), not the
    parameter hint a stray symbol gets."""
    x, y, xd, yd, t = sp.symbols("x y xd yd t")
    base = dict(name="bad", q=[x, y], qdot=[xd, yd], time=t, forces=[0, sp.cos(t)])
    lag = (xd**2 + yd**2) / 2 - 9.81 * y
    cases = [
        ("contact 'floor'", dict(lagrangian=lag, contacts={"floor": y - sp.sin(30 * t) / 100})),
        ("constraint 'rod'", dict(lagrangian=lag, constraints={"rod": x**2 + y**2 - 1 - t})),
        ("the Lagrangian", dict(lagrangian=lag * (1 + t))),
    ]
    for what, extra in cases:
        with pytest.raises(ValueError, match=rf"{what} depends on the time symbol t: .*a force of time"):
            vcigen.Model(**base, **extra)


def test_forced_scene_is_never_explicit():
    """The explicit straight-line step hoists (h, par); with forces (and their time slot) it must not."""
    from vcigen.derive import derive

    system = derive(driven_oscillator())
    assert system.timed and not system.structure.explicit_grid and not system.structure.explicit_path
    assert system.routines["smooth"].inputs[-1].symbols[-1].name == "t"


def shaker() -> vcigen.Model:
    """A unit ball on a floor pushed up by ``0.5 cos 3t``: a force of time and no parameter of its own, so
    time is the kernels' only parameter slot."""
    y, yd, t = sp.symbols("y yd t")
    return vcigen.Model(
        name="shaker",
        q=[y],
        qdot=[yd],
        lagrangian=yd**2 / 2 - G * y,
        contacts={"floor": y},
        forces=[0.5 * sp.cos(3 * t)],
        time=t,
        restitution={"floor": 0.5},
    )


@pytest.mark.parametrize("backend", BACKENDS)
def test_a_ball_resting_under_a_force_of_time_alone_feels_the_floor_push_back(backend):
    """Dropped from 0.5 with ``e = 0.5``, the ball bounces to rest (held from the Zeno point) and the floor
    then pushes with ``g - 0.5 cos 3t`` over each step (at its midpoint, to O(h^2)). Before stop 40 CasADi
    raised a bare RuntimeError from ``vertcat`` here (the segment's time slot, ``par[:-1]``, empty), and so
    did ``casadi_functions``."""
    errors = []
    for h in (0.01, 0.005):
        res = vcigen.build(shaker(), backend=backend).simulate([0.5], [0.0], h, t_end=3.0)
        late = res.t[:-1] >= 1.5
        assert (
            res.impacts[-1].kind == "plastic" and res.impacts[-1].t < 1.0 and res.active[:-1][late, 0].all()
        )
        assert np.abs(res.q[:-1][late]).max() < 1e-12
        mid = res.t[:-1][late] + h / 2
        errors.append(np.abs(res.contact_force[late, 0] - (G - 0.5 * np.cos(3 * mid))).max())
    assert errors[0] < 1e-4 and errors[0] / errors[1] > 3.8  # 5.6e-5, 1.4e-5
    assert {"step", "impact_floor"} <= set(vcigen.casadi_functions(shaker()))
