"""Sustained contact in C and in CasADi: one algorithm (vcigen/sustained.py, templates/sustained*.c.j2).

The same scenes on both backends give the same grid trajectories, impact logs (kinds included),
active sets, contact forces and lift-offs; the Python stepper on the C kernels is the C loop bit
for bit. Scenes: a Zeno ball that comes to rest and slides, a particle leaving a dome, the paper's
star with restitution settling on a face (several rows held at once, a kink of eq. 81), a
Cartesian pendulum (bilateral rod) against a wall, a body held on a floor striking a wall.
"""

from __future__ import annotations

import shutil
from functools import cache

import numpy as np
import pytest
import sympy as sp
import test_ramp_to_floor
import test_rough_ladder
import test_sustained_closed_forms

import vcigen
from bench import groove_drops
from vcigen.stepper import Stepper

pytestmark = pytest.mark.skipif(shutil.which("cc") is None, reason="no C compiler")

X, Y, XD, YD = sp.symbols("x y xd yd")
G = 9.81


def _ball() -> vcigen.Model:
    e = sp.Symbol("e")
    return vcigen.Model(
        name="ag_ball",
        q=[X, Y],
        qdot=[XD, YD],
        lagrangian=(XD**2 + YD**2) / 2 - G * Y,
        contacts={"floor": Y},
        params={e: 0.5},
        restitution={"floor": e},
    )


def _dome() -> vcigen.Model:
    return vcigen.Model(
        name="ag_dome",
        q=[X, Y],
        qdot=[XD, YD],
        lagrangian=(XD**2 + YD**2) / 2 - G * Y,
        contacts={"dome": sp.sqrt(X**2 + Y**2) - 1},
    )


def _star() -> vcigen.Model:
    x, y, th, xd, yd, thd = sp.symbols("x y theta xd yd thetad")
    m, g, L, e = sp.symbols("m g L e", positive=True)
    inertia = sp.Rational(29, 192) * m * L**2
    return vcigen.Model(
        name="ag_star",
        q=[x, y, th],
        qdot=[xd, yd, thd],
        lagrangian=m / 2 * (xd**2 + yd**2) + inertia / 2 * thd**2 - m * g * y,
        contacts={"floor": y - L / 2 * (sp.Abs(sp.sin(th)) + sp.Abs(sp.cos(th)))},
        params={m: 1.0, g: G, L: 1.0, e: 0.8},
        restitution={"floor": e},
    )


def _pendulum() -> vcigen.Model:
    return vcigen.Model(
        name="ag_pend",
        q=[X, Y],
        qdot=[XD, YD],
        lagrangian=(XD**2 + YD**2) / 2 - G * Y,
        contacts={"wall": X + 0.5},
        constraints={"rod": X**2 + Y**2 - 1},
    )


def _floor_wall() -> vcigen.Model:
    return vcigen.Model(
        name="ag_fw",
        q=[X, Y],
        qdot=[XD, YD],
        lagrangian=(XD**2 + YD**2) / 2 - G * Y,
        contacts={"floor": Y, "wall": 1 - X},
    )


SCENES = {  # name: (model, q0, v0, h, t_end)
    "ball": (_ball, [0.0, 1.0], [0.3, 0.0], 0.002, 2.0),
    "dome": (_dome, [0.0, 1.0], [0.1, 0.0], 0.005, 1.6),
    "star": (_star, [0.0, 3.5, 0.0], [-2.0, 0.0, 5.0], 0.005, 9.0),
    "pendulum": (_pendulum, [float(np.sin(1.0)), -float(np.cos(1.0))], [0.0, 0.0], 0.01, 4.0),
    "floor_wall": (_floor_wall, [0.0037, 0.0], [1.0, 0.0], 0.01, 2.5),
    # a ladder at rest against a smooth wall: both ends held from the start, the wall released
    "ladder": (
        test_sustained_closed_forms.ladder,
        [np.sin(0.3) / 2, np.cos(0.3) / 2, 0.3],
        [0.0] * 3,
        0.01,
        0.6,
    ),
    # against a rough wall past its friction angle: the wall's stick rides on the floor's, their split breaks
    "rough_ladder": (test_rough_ladder.model, [np.sin(0.6) / 2, np.cos(0.6) / 2, 0.6], [0.0] * 3, 0.01, 1.2),
    # a rough V-groove: a stick row held on one wall made dependent by the other's landing at the vertex
    "groove": (groove_drops.model, [0.3, 1.0], [0.0, 0.0], 0.01, 2.0),
    # off a rough ramp onto a rough floor: the landing's law solved again without the ramp's leaving rows
    "ramp": (test_ramp_to_floor.model, [-np.cos(0.5), np.sin(0.5)], [0.0, 0.0], 0.01, 1.5),
}
# The star is chaotic: round-off differences between CasADi's SX and the printed C grow at every
# impact (tests/test_c_agreement.py); over its impacts to rest they stay far below 1e-6 in the
# state, and the event sequence (kinds, steps, the face it rests on) is the same.
TOL = {"ball": 1e-9, "dome": 1e-9, "star": 1e-6, "pendulum": 1e-9, "floor_wall": 1e-9}
TOL |= {"ladder": 1e-9, "rough_ladder": 1e-9, "groove": 1e-9, "ramp": 1e-9}


@cache
def sim(name: str, backend: str) -> vcigen.Simulator:
    return vcigen.build(SCENES[name][0](), backend=backend)


@cache
def run(name: str, backend: str) -> vcigen.Result:
    _, q0, v0, h, t_end = SCENES[name]
    return sim(name, backend).simulate(q0, v0, h, t_end=t_end)


def _counts(res: vcigen.Result) -> dict:
    return {k: v for k, v in res.stats.items() if k.startswith("impacts_") or k == "liftoffs"}


@pytest.mark.parametrize("name", sorted(SCENES))
def test_c_and_casadi_agree_through_sustained_contact(name: str) -> None:
    c, ca = run(name, "c"), run(name, "casadi")
    tol = TOL[name]
    assert c.q.shape == ca.q.shape
    np.testing.assert_allclose(c.q, ca.q, rtol=0, atol=tol)
    np.testing.assert_allclose(c.p, ca.p, rtol=0, atol=tol * 10)
    np.testing.assert_array_equal(c.active, ca.active)
    np.testing.assert_allclose(c.contact_force, ca.contact_force, rtol=0, atol=tol * 1e3)
    np.testing.assert_allclose(c.constraint_force, ca.constraint_force, rtol=0, atol=tol * 1e3)
    assert [(i.contact, i.kind, i.step) for i in c.impacts] == [
        (i.contact, i.kind, i.step) for i in ca.impacts
    ]
    for ic, ia in zip(c.impacts, ca.impacts):
        assert abs(ic.t - ia.t) <= tol and abs(ic.impulse - ia.impulse) <= tol * 10
    assert [lo[1] for lo in c.liftoffs] == [lo[1] for lo in ca.liftoffs]
    np.testing.assert_allclose(
        [lo[0] for lo in c.liftoffs], [lo[0] for lo in ca.liftoffs], rtol=0, atol=1e-10
    )
    assert _counts(c) == _counts(ca)


def test_each_scene_exercises_what_it_is_for() -> None:
    """So that the agreement above is not vacuous: the scenes rest, lift off, hold rows and constraints."""
    assert run("ball", "c").active[-1, 0] and run("ball", "c").impacts[-1].kind == "plastic"
    assert len(run("dome", "c").liftoffs) == 1
    star = run("star", "c")
    assert star.stats["impacts_plastic"] >= 1 and star.active[-1, 0]
    assert np.all(np.abs(run("pendulum", "c").constraint_force) > 0) and run("pendulum", "c").n_impacts >= 2
    fw = run("floor_wall", "c")
    assert fw.active[:, 0].all() and any(i.contact == "wall" for i in fw.impacts)
    ladder, rough = run("ladder", "c"), run("rough_ladder", "c")
    assert ladder.active[0].all() and not ladder.impacts and [j for _, j in ladder.liftoffs] == ["wall"]
    assert rough.active[0].all() and rough.q[-1, 2] > 0.7 and [j for _, j in rough.liftoffs][:1] == ["wall"]
    groove = run("groove", "c")
    assert groove.active[-1].all() and groove.stats["impacts_plastic"] >= 1
    ramp = run("ramp", "c")
    assert [j for _, j in ramp.liftoffs] == ["ramp"] and ramp.stats["landing_friction_dropped"] == 0


@pytest.mark.parametrize("name", ["star", "dome", "pendulum"])
def test_python_stepper_on_c_kernels_is_the_c_loop(name: str) -> None:
    assert_python_stepper_is_the_c_loop(sim(name, "c"), SCENES[name], run(name, "c"))


def assert_python_stepper_is_the_c_loop(s: vcigen.Simulator, scene, c: vcigen.Result) -> None:
    """The Python stepper on ``s``'s C kernels over ``scene`` ``(model, q0, v0, h, t_end)`` is the C loop's
    run ``c``: the same grid to 1e-12, the same events and lift-offs."""
    _, q0, v0, h, t_end = scene
    kern = s.kernels.bind(s.model.resolve_params(None))
    py = Stepper(kern, s.tol).simulate(q0, v0, h, t_end=t_end)
    np.testing.assert_allclose(py.q, c.q, rtol=0, atol=1e-12)
    np.testing.assert_array_equal(py.active, c.active)
    assert [(i.kind, i.step) for i in py.impacts] == [(i.kind, i.step) for i in c.impacts]
    assert [lo[1] for lo in py.liftoffs] == [lo[1] for lo in c.liftoffs]
    np.testing.assert_allclose(
        [lo[0] for lo in py.liftoffs], [lo[0] for lo in c.liftoffs], rtol=0, atol=1e-12
    )


# -- the held grid step (vcigen.held): straight-line steps in sustained contact ----------------------
def _bowl() -> vcigen.Model:
    """A particle inside a circle of radius 1 (contact ``1 - |q|``), released on its wall: it slides to and
    fro, a curved row that moves, so that the held Newton iterates every step (C: ``<model>_held_newton``)."""
    return vcigen.Model(
        name="ag_bowl",
        q=[X, Y],
        qdot=[XD, YD],
        lagrangian=(XD**2 + YD**2) / 2 - G * Y,
        contacts={"bowl": 1 - sp.sqrt(X**2 + Y**2)},
    )


def _box() -> vcigen.Model:
    """A 2 x 1 rectangle with a contact at each vertex, resting on its long face: two nonlinear rows held."""
    x, y, th, xd, yd, thd = sp.symbols("x y theta xd yd thetad")
    contacts = {
        f"v{i}": y + a * sp.sin(th) + b * sp.cos(th)
        for i, (a, b) in enumerate([(1.0, -0.5), (-1.0, -0.5), (1.0, 0.5), (-1.0, 0.5)])
    }
    return vcigen.Model(
        name="ag_box",
        q=[x, y, th],
        qdot=[xd, yd, thd],
        lagrangian=(xd**2 + yd**2) / 2 + sp.Rational(5, 24) * thd**2 - G * y,
        contacts=contacts,
    )


def _box8() -> vcigen.Model:
    """The box of :func:`_box` with four more contacts that never touch on its long face (the top's midpoint
    and a point beside it, the sides' midpoints): 8 rows, more than ``ccontext.HELD_SETS_MAX``, so its C glide
    runs the held loop for one and two rows without the per-active-set loops."""
    x, y, th, xd, yd, thd = sp.symbols("x y theta xd yd thetad")
    points = [(1.0, -0.5), (-1.0, -0.5), (1.0, 0.5), (-1.0, 0.5)]
    points += [(0.0, 0.5), (0.5, 0.5), (1.0, 0.0), (-1.0, 0.0)]
    return vcigen.Model(
        name="ag_box8",
        q=[x, y, th],
        qdot=[xd, yd, thd],
        lagrangian=(xd**2 + yd**2) / 2 + sp.Rational(5, 24) * thd**2 - G * y,
        contacts={f"v{i}": y + a * sp.sin(th) + b * sp.cos(th) for i, (a, b) in enumerate(points)},
    )


HELD = {  # name: (model, q0, v0, h, t_end); each starts held and stays held for most of its steps
    "slide": (_ball, [0.0, 0.0], [1.0, 0.0], 0.001, 1.0),  # one linear row: one exact Newton step
    "bowl": (_bowl, [0.6, -0.8], [0.0, 0.0], 0.001, 1.5),  # a curved row that moves: Newton iterates
    "box": (_box, [0.0, 0.5, 0.0], [1.0, 0.0, 0.0], 0.002, 1.0),  # slides on a face: two nonlinear rows
    "box8": (_box8, [0.0, 0.5, 0.0], [1.0, 0.0, 0.0], 0.002, 1.0),  # 8 rows: no per-set loops in C
    "star": (
        _star,
        [0.0, 0.5, 0.0],
        [1.0, 0.0, 0.0],
        0.001,
        1.0,
    ),  # the Abs contact on a face: two branch rows
    "pendulum": SCENES["pendulum"],  # a bilateral row (a circle in q) against a wall
    "dome": SCENES["dome"],  # a nonlinear row to its lift-off
}


@cache
def held_sim(name: str, backend: str) -> vcigen.Simulator:
    return vcigen.build(HELD[name][0](), backend=backend)


def _stepper_run(name: str, backend: str, held: bool):
    """The Python stepper on ``backend``'s kernels, with or without the held step; the held steps taken."""
    s = held_sim(name, backend)
    _, q0, v0, h, t_end = HELD[name]
    kern = s.kernels.bind(s.model.resolve_params(None))
    assert kern.held  # the scene has the structure
    taken = []
    step, rotation = kern.held_step, kern.circle_step

    def counted(*args):
        out = step(*args)
        taken.append(out is not None)
        return out

    def counted_rotation(*args):  # a circle's row held alone: the rotation (vcigen.held_circle)
        out = rotation(*args)
        taken.append(out is not None)
        return out

    kern.held, kern.held_step, kern.circle_step = held, counted, counted_rotation
    try:
        return Stepper(kern, s.tol).simulate(q0, v0, h, t_end=t_end), sum(taken)
    finally:
        kern.held = True
        del kern.held_step, kern.circle_step


@pytest.mark.parametrize("name", sorted(HELD))
def test_held_step_is_the_general_chain_to_solver_tolerance(name: str) -> None:
    """The held step against the constrained chain (two Newton solves on n + R unknowns), the same scene on
    the C kernels: the same trajectory to the Newton tolerance, the same events, lift-offs and forces."""
    fast, taken = _stepper_run(name, "c", True)
    slow, none = _stepper_run(name, "c", False)
    steps = len(fast.t) - 1
    assert none == 0 and taken >= steps // 2, (taken, steps)  # it is what takes the held steps
    _same_to_newton_tolerance(fast, slow)


def _same_to_newton_tolerance(fast: vcigen.Result, slow: vcigen.Result) -> None:
    """The same trajectory to the Newton tolerance, the same events, lift-offs and forces."""
    np.testing.assert_allclose(fast.q, slow.q, rtol=0, atol=1e-11)
    np.testing.assert_allclose(fast.p, slow.p, rtol=0, atol=1e-10)
    np.testing.assert_allclose(fast.energy, slow.energy, rtol=0, atol=1e-10)
    np.testing.assert_array_equal(fast.active, slow.active)
    np.testing.assert_allclose(fast.contact_force, slow.contact_force, rtol=0, atol=1e-8)
    np.testing.assert_allclose(fast.constraint_force, slow.constraint_force, rtol=0, atol=1e-8)
    assert [(i.contact, i.kind, i.step) for i in fast.impacts] == [
        (i.contact, i.kind, i.step) for i in slow.impacts
    ]
    assert [lo[1] for lo in fast.liftoffs] == [lo[1] for lo in slow.liftoffs]
    np.testing.assert_allclose(
        [lo[0] for lo in fast.liftoffs], [lo[0] for lo in slow.liftoffs], rtol=0, atol=1e-9
    )


@pytest.mark.parametrize("name", sorted(HELD))
def test_held_step_c_loop_casadi_and_python(name: str) -> None:
    """The C loop's held glide is the Python stepper on the C kernels bit for bit (to 1e-12), and CasADi's
    held step (vcigen.held_step.held_step on its routines) the same trajectory to round-off."""
    _, q0, v0, h, t_end = HELD[name]
    c = held_sim(name, "c").simulate(q0, v0, h, t_end=t_end)
    py, _ = _stepper_run(name, "c", True)
    ca, taken = _stepper_run(name, "casadi", True)
    assert taken >= (len(c.t) - 1) // 2
    np.testing.assert_allclose(py.q, c.q, rtol=0, atol=1e-12)
    np.testing.assert_array_equal(py.active, c.active)
    np.testing.assert_allclose(py.contact_force, c.contact_force, rtol=0, atol=1e-10)
    np.testing.assert_allclose(ca.q, c.q, rtol=0, atol=1e-9)
    np.testing.assert_array_equal(ca.active, c.active)
    np.testing.assert_allclose(ca.contact_force, c.contact_force, rtol=0, atol=1e-6)
    assert [(i.contact, i.kind, i.step) for i in ca.impacts] == [
        (i.contact, i.kind, i.step) for i in c.impacts
    ]
    np.testing.assert_allclose([lo[0] for lo in ca.liftoffs], [lo[0] for lo in c.liftoffs], rtol=0, atol=1e-9)


@pytest.mark.parametrize("name", ["bowl", "dome", "pendulum"])
def test_closed_held_step_in_c_is_the_held_newton(name: str) -> None:
    """A row held alone with a closed form (vcigen.held.closed_forms: the bowl's and the dome's circles, the
    rod): the C loop takes the closed step (one square root, no Newton), CasADi's stepper with the closed form
    off the held Newton. The same trajectory to the Newton's tolerance, the same events, forces and lift-off
    times."""
    sim_c, sim_ca = held_sim(name, "c"), held_sim(name, "casadi")
    assert any(sim_c.system.structure.held_closed)
    _, q0, v0, h, t_end = HELD[name]
    c = sim_c.simulate(q0, v0, h, t_end=t_end)
    kern = sim_ca.kernels.bind(sim_ca.model.resolve_params(None))
    kept = kern.held_closed
    kern.held_closed = [False] * len(kept)
    try:
        newton = Stepper(kern, sim_ca.tol).simulate(q0, v0, h, t_end=t_end)
    finally:
        kern.held_closed = kept
    _same_to_newton_tolerance(c, newton)


def test_held_scenes_exercise_what_they_are_for() -> None:
    """The held scenes hold rows throughout or lift off, so that the agreement above is not vacuous."""
    runs = {name: _stepper_run(name, "c", True)[0] for name in HELD}
    assert runs["slide"].active.all() and not runs["slide"].impacts
    assert runs["bowl"].active.all() and np.ptp(runs["bowl"].q[:, 0]) > 1.0  # held while it swings across
    assert runs["star"].active.all() and abs(runs["star"].contact_force.mean() - G) < 1e-9
    assert len(runs["dome"].liftoffs) == 1
    assert runs["box"].active[:, :2].all() and not runs["box"].active[:, 2:].any()
    assert runs["box8"].active[:, :2].all() and not runs["box8"].active[:, 2:].any()
    assert np.all(np.abs(runs["pendulum"].constraint_force) > 0)


def test_no_held_step_without_the_structure() -> None:
    """A configuration-dependent mass, or friction, keeps the general chain (vcigen.structure)."""
    from vcigen.derive import derive

    r, th, rd, thd = sp.symbols("r theta rd thetad")
    polar = vcigen.Model(
        name="ag_polar",
        q=[r, th],
        qdot=[rd, thd],
        lagrangian=(rd**2 + r**2 * thd**2) / 2 - G * r * sp.sin(th),
        contacts={"floor": r * sp.sin(th) + 1},
    )
    assert not derive(polar).structure.held
    assert derive(_ball()).structure.held and derive(_star()).structure.held


def test_held_step_keeps_the_solver_error_contract() -> None:
    """A held run driven into a NaN region (V = sqrt(1 - x) past x = 1): the held step does not take the step,
    the general chain raises the SolverError, at the same step on both backends and with the held step off,
    and its .result holds the run so far, held throughout, with a completed run's counters in its stats (the
    Python stepper's held the timings alone before stop 67: bench.hoop_drops --backend casadi --seed 417
    --h 0.05 raised a KeyError reading one)."""
    model = vcigen.Model(
        name="ag_held_nan",
        q=[X, Y],
        qdot=[XD, YD],
        lagrangian=(XD**2 + YD**2) / 2 - G * Y - sp.sqrt(1 - X),
        contacts={"floor": Y},
    )
    errors = {}
    for backend in ("c", "casadi"):
        s = vcigen.build(model, backend=backend)
        assert s.kernels.held
        with pytest.raises(vcigen.SolverError) as info:
            s.simulate([0.0, 0.0], [1.0, 0.0], 0.01, t_end=2.0)
        errors[backend] = info.value
    kern = vcigen.build(model, backend="c").kernels.bind([])
    kern.held = False
    with pytest.raises(vcigen.SolverError) as info:
        Stepper(kern, vcigen.Tolerances()).simulate([0.0, 0.0], [1.0, 0.0], 0.01, t_end=2.0)
    kern.held = True
    errors["chain"] = info.value
    where = {k: (e.step, e.phase) for k, e in errors.items()}
    assert len(set(where.values())) == 1, where
    err = errors["c"]
    assert 60 <= err.step <= 100 and err.result.active.all()  # x = 1 before t = 1 (pushed toward it)
    np.testing.assert_allclose(err.result.q, errors["casadi"].result.q, rtol=0, atol=1e-9)
    done = vcigen.build(model, backend="casadi").simulate([0.0, 0.0], [1.0, 0.0], 0.01, t_end=0.1).stats
    timings = {"wall_time", "seconds_per_step"}
    for e in errors.values():
        assert set(e.result.stats) == set(done), sorted(set(done) ^ set(e.result.stats))
    counts = [{k: v for k, v in e.result.stats.items() if k not in timings} for e in errors.values()]
    assert counts[0] == counts[1] == counts[2]
