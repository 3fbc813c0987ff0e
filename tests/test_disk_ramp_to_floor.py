"""A disk rolling or sliding down a rough ramp onto a rough floor (MATH.md *Friction*: Coulomb's impulse at a
landing; ``ImpulseLaw._law_leaving`` and ``_astray``, C ``law_leaving`` and ``astray``).

A uniform disk (``m = 1``, ``r = 0.5``, ``I = m r^2 / 2``; ``theta`` clockwise) on the ramp ``sin(a) x +
cos(a) y >= r`` (its centre's distance), which meets the floor ``y >= r`` where the centre is at ``(r
tan(a/2), r)``, both rough (``mu``) and plastic, the tangents the contact points' sliding (``x - r theta`` on
the floor). Released at rest a length 1 up the ramp it rolls down at ``g sin a / (1 + I / (m r^2))`` where
``mu >= tan(a) / 3``, else slides at ``g (sin a - mu cos a)`` while it spins up at ``mu g cos a m r / I``. At
the foot it lands on the floor (plastic, the ramp's row leaving with no impulse): normal impulse ``m v sin
a``, and Coulomb's tangential impulse at the floor's contact point, all that stops its sliding ``(r w - v cos
a) / (1/m + r^2/I)`` where that is within ``mu`` times the normal one, else ``mu`` times it. From then on the
floor's friction keeps the angular momentum about the contact line, so it rolls at ``(I w + m r v cos a) / (I
/ r + m r)``.

At the landing the floor's stick row is in the span of the two normal rows and the ramp's stick row, so it
rode on the ramp's: till stop 47 the ramp's stick row carried the floor's friction along the ramp, from the
leaving contact, and the disk left the landing sliding (its speed 2.1891 against 2.1381 at a = 0.4, mu = 0.6),
and rolled on 0.3 % slow. The law is now solved again with the floor's stick row its own.
"""

from __future__ import annotations

import math
from functools import cache

import numpy as np
import pytest
import sympy as sp
from hard_scenes import BACKENDS, G

import vcigen

MASS, RADIUS = 1.0, 0.5
INERTIA = MASS * RADIUS**2 / 2
SPAN = 1.0  # the distance rolled or slid along the ramp to its foot


def model() -> vcigen.Model:
    x, y, th, xd, yd, thd = sp.symbols("x y th xd yd thd")
    a, mu = sp.symbols("a mu")
    return vcigen.Model(
        name="disk_ramp_floor",
        q=[x, y, th],
        qdot=[xd, yd, thd],
        lagrangian=MASS * (xd**2 + yd**2) / 2 + INERTIA * thd**2 / 2 - MASS * G * y,
        contacts={"floor": y - RADIUS, "ramp": sp.sin(a) * x + sp.cos(a) * y - RADIUS},
        restitution={"floor": 0.0, "ramp": 0.0},
        friction={"floor": (mu, x - RADIUS * th), "ramp": (mu, sp.cos(a) * x - sp.sin(a) * y - RADIUS * th)},
        params={a: 0.4, mu: 0.6},
    )


def closed_form(a: float, mu: float) -> dict:
    """The landing's time, its velocity before (along the ramp, spin), its impulses, the velocity after it
    and the rolling speed on the floor."""
    rolls = mu >= math.tan(a) / 3
    accel = (
        G * math.sin(a) / (1 + INERTIA / (MASS * RADIUS**2))
        if rolls
        else G * (math.sin(a) - mu * math.cos(a))
    )
    t = math.sqrt(2 * SPAN / accel)
    v = accel * t
    w = v / RADIUS if rolls else mu * G * math.cos(a) * MASS * RADIUS / INERTIA * t
    normal = MASS * v * math.sin(a)
    stick = (RADIUS * w - v * math.cos(a)) / (1 / MASS + RADIUS**2 / INERTIA)
    tangential = stick if abs(stick) <= mu * normal else math.copysign(mu * normal, stick)
    vx, w1 = v * math.cos(a) + tangential / MASS, w - RADIUS * tangential / INERTIA
    roll = (INERTIA * w + MASS * RADIUS * v * math.cos(a)) / (INERTIA / RADIUS + MASS * RADIUS)
    return {
        "t": t,
        "rolls": rolls,
        "normal": normal,
        "tangential": tangential,
        "vx": vx,
        "w": w1,
        "roll": roll,
    }


@cache
def simulator(backend: str) -> vcigen.Simulator:
    return vcigen.build(model(), backend=backend)


def run(backend: str, a: float, mu: float, h: float = 0.01) -> vcigen.Result:
    foot = np.array([RADIUS * math.tan(a / 2), RADIUS])
    start = foot - SPAN * np.array([math.cos(a), -math.sin(a)])
    t_end = closed_form(a, mu)["t"] + 1.0
    return simulator(backend).simulate(
        [start[0], start[1], 0.0], [0.0] * 3, h, t_end=t_end, params={"a": a, "mu": mu}
    )


CASES = [(0.4, 0.6), (0.8, 0.6), (0.8, 0.2), (0.4, 0.1)]


def test_the_cases_roll_and_slide_down_and_stick_and_slip_at_the_landing() -> None:
    forms = [closed_form(*case) for case in CASES]
    assert [f["rolls"] for f in forms] == [True, True, False, False]
    sticks = [abs(f["tangential"]) < case[1] * f["normal"] for f, case in zip(forms, CASES)]
    assert sticks == [True, True, True, False]


@pytest.mark.parametrize("backend", BACKENDS)
@pytest.mark.parametrize("a, mu", CASES)
def test_a_disk_lands_from_a_rough_ramp_with_coulombs_impulse_at_the_floor(backend: str, a: float, mu: float):
    """The landing at the closed-form time, the ramp released there, the floor's normal impulse and, where it
    sticks, the velocity after the landing (so its tangential impulse) to 1e-12; then it rolls on at the
    closed-form speed. Sticking, it failed on the code before (0.3 % slow at a = 0.4)."""
    form = closed_form(a, mu)
    res = run(backend, a, mu)
    assert [(i.contact, i.kind) for i in res.impacts] == [("floor", "plastic")]
    assert abs(res.impacts[0].t - form["t"]) < 1e-12
    assert [j for _, j in res.liftoffs] == ["ramp"] and abs(res.liftoffs[0][0] - form["t"]) < 1e-12
    assert abs(res.impacts[0].impulse - form["normal"]) < 1e-12  # the normal rows' impulse
    k = int(np.searchsorted(res.t, form["t"]))
    if abs(form["tangential"]) < mu * form["normal"]:  # it sticks: rolling from the landing on
        assert np.abs(res.v[k:] - [form["vx"], 0.0, form["w"]]).max() < 1e-12
    assert np.abs(res.v[-1] - [form["roll"], 0.0, form["roll"] / RADIUS]).max() < 1e-12
    assert res.stats["landing_friction_dropped"] == 0


@pytest.mark.parametrize("backend", BACKENDS)
def test_random_ramps_land_the_disk_at_the_closed_form_time_and_it_rolls_on_at_the_closed_form_speed(backend):
    """Eight random ``(a, mu)`` (a in [0.1, 1.2], mu in [0.02, 1.5]; seed 5): one plastic landing at the
    closed-form time, then, once the floor's friction has stopped any sliding (``|v_x - r w| / (mu g (1 + m
    r^2 / I))`` after the landing), rolling at the closed-form speed to 1e-12 (330 such draws, 300 in C:
    3.7e-14 at most)."""
    rng = np.random.default_rng(5)
    for _ in range(8):
        a, mu = float(rng.uniform(0.1, 1.2)), float(rng.uniform(0.02, 1.5))
        form = closed_form(a, mu)
        slides = abs(form["vx"] - RADIUS * form["w"]) / (mu * G * (1 + MASS * RADIUS**2 / INERTIA))
        foot = np.array([RADIUS * math.tan(a / 2), RADIUS])
        start = foot - SPAN * np.array([math.cos(a), -math.sin(a)])
        res = simulator(backend).simulate(
            [start[0], start[1], 0.0],
            [0.0] * 3,
            0.01,
            t_end=form["t"] + slides + 0.3,
            params={"a": a, "mu": mu},
        )
        assert [(i.contact, i.kind) for i in res.impacts] == [("floor", "plastic")]
        assert abs(res.impacts[0].t - form["t"]) < 1e-12
        assert np.abs(res.v[-1] - [form["roll"], 0.0, form["roll"] / RADIUS]).max() < 1e-12, (a, mu)


BALL_INERTIA = 0.4 * MASS * RADIUS**2


@cache
def ball(backend: str) -> vcigen.Simulator:
    """The same ramp and floor in 3-D for a ball (``I = 2/5 m r^2``), each contact an isotropic cone: ``q =
    (x, y, z, ax, ay, az)``, the rotation angles' rates the angular velocity, the contact points sliding at
    ``(x - r ay, y + r ax)`` on the floor and ``(cos a x - sin a z - r ay, y + r (cos a ax - sin a az))`` on
    the ramp ``sin(a) x + cos(a) z >= r``."""
    x, y, z, ax, ay, az = sp.symbols("x y z ax ay az")
    qd = sp.symbols("xd yd zd axd ayd azd")
    a, mu = sp.symbols("a mu")
    c, s = sp.cos(a), sp.sin(a)
    model = vcigen.Model(
        name="ball_ramp_floor",
        q=[x, y, z, ax, ay, az],
        qdot=list(qd),
        lagrangian=MASS * sum(v**2 for v in qd[:3]) / 2
        + BALL_INERTIA * sum(v**2 for v in qd[3:]) / 2
        - MASS * G * z,
        contacts={"floor": z - RADIUS, "ramp": s * x + c * z - RADIUS},
        restitution={"floor": 0.0, "ramp": 0.0},
        friction={
            "floor": (mu, (x - RADIUS * ay, y + RADIUS * ax)),
            "ramp": (mu, (c * x - s * z - RADIUS * ay, y + RADIUS * (c * ax - s * az))),
        },
        params={a: 0.4, mu: 0.6},
    )
    return vcigen.build(model, backend=backend)


@pytest.mark.parametrize("backend", BACKENDS)
@pytest.mark.parametrize("a, mu", [(0.4, 0.6), (0.4, 0.05)])
def test_a_ball_rolls_or_slides_off_a_rough_ramp_and_rolls_on_at_the_closed_form_speed(backend, a, mu):
    """The disk's closed form with the ball's ``I``: rolling down (``mu >= 2/7 tan a``), it lands sticking;
    at ``mu = 0.05`` it slides down and slips at the landing; both roll on at ``(I w + m r v cos a) / (I/r +
    m r)`` (the cones' loose landing, stop 32: already right before stop 47)."""
    rolls = mu >= math.tan(a) * 2 / 7
    accel = G * math.sin(a) * 5 / 7 if rolls else G * (math.sin(a) - mu * math.cos(a))
    t = math.sqrt(2 * SPAN / accel)
    v = accel * t
    w = v / RADIUS if rolls else mu * G * math.cos(a) * MASS * RADIUS / BALL_INERTIA * t
    roll = (BALL_INERTIA * w + MASS * RADIUS * v * math.cos(a)) / (BALL_INERTIA / RADIUS + MASS * RADIUS)
    foot = np.array([RADIUS * math.tan(a / 2), RADIUS])
    start = foot - SPAN * np.array([math.cos(a), -math.sin(a)])
    res = ball(backend).simulate(
        [start[0], 0, start[1], 0, 0, 0], [0.0] * 6, 0.01, t_end=t + 1.0, params={"a": a, "mu": mu}
    )
    assert [(i.contact, i.kind) for i in res.impacts] == [("floor", "plastic")]
    assert abs(res.impacts[0].t - t) < 1e-12 and abs(res.impacts[0].impulse - MASS * v * math.sin(a)) < 1e-12
    assert [j for _, j in res.liftoffs] == ["ramp"]
    assert np.abs(res.v[-1] - [roll, 0.0, 0.0, 0.0, roll / RADIUS, 0.0]).max() < 1e-12
