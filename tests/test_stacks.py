"""Bodies resting on bodies (issue 9, items 1 and 7), both backends, against closed forms and scipy.

Disks of radius ``R`` as particles in the plane (or on a line), each pair a contact ``|q_j - q_i| - 2R``, the
floor ``y - R``: a stack of three on a line comes to rest with each contact carrying the weight above it; a
disk set on top of another slides off it (the lower one free on a frictionless floor) and leaves it where the
contact force vanishes, at scipy's time on the reduced equations (event located, 1e-12) to O(h^2); three disks
in a pyramid rest on a rough floor with the forces of statics, and on a frictionless one the top disk pushes
the others apart and leaves both at once, at scipy's time to O(h^2). A ball landing on one of two disks side
by side on a rough floor, the first pushed against the second so that the second's friction rides on the
first's stick row (a dependent stick): the impact leaves the row between them with no impulse, and the struck
disk sticks or slides by its own cone (Coulomb's law at the impact, closed form; before stop 41 it slid with
no friction).
"""

from __future__ import annotations

import math
import sys
from functools import cache
from pathlib import Path

import numpy as np
import pytest
import sympy as sp
from hard_scenes import BACKENDS, G
from scipy.integrate import solve_ivp

import vcigen

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "examples" / "contact"))
import pyramid as example  # noqa: E402 - examples/contact/pyramid.py: its model (e = 0.3, mu a parameter)

R = example.R


def _pair(q, i: int, j: int):
    return sp.sqrt((q[2 * j] - q[2 * i]) ** 2 + (q[2 * j + 1] - q[2 * i + 1]) ** 2) - 2 * R


def line_stack() -> vcigen.Model:
    """Three disks of masses 1, 1.5 and 2 on a vertical line (heights ``y_i``), ``e = 0.5`` everywhere."""
    ys, vs = sp.symbols("y0:3"), sp.symbols("v0:3")
    masses = (1.0, 1.5, 2.0)
    contacts = {"floor": ys[0] - R, "pair1": ys[1] - ys[0] - 2 * R, "pair2": ys[2] - ys[1] - 2 * R}
    return vcigen.Model(
        name="line_stack",
        q=list(ys),
        qdot=list(vs),
        lagrangian=sum(m * v**2 / 2 - m * G * y for m, v, y in zip(masses, vs, ys)),
        contacts=contacts,
        restitution={name: 0.5 for name in contacts},
    )


def two_disks() -> vcigen.Model:
    """Two unit disks on a frictionless floor, the second free to rest on the first."""
    q, v = sp.symbols("x1 y1 x2 y2"), sp.symbols("a1 b1 a2 b2")
    contacts = {"floor1": q[1] - R, "floor2": q[3] - R, "pair": _pair(q, 0, 1)}
    return vcigen.Model(
        name="two_disks",
        q=list(q),
        qdot=list(v),
        lagrangian=sum(x**2 for x in v) / 2 - G * (q[1] + q[3]),
        contacts=contacts,
        restitution={name: 0.5 for name in contacts},
    )


BALL_MASS, MU, E_BALL = 0.2, 0.5, 0.5


def pushed_pair() -> vcigen.Model:
    """Two unit disks side by side on a rough floor (``MU``), the first pushed against the second by a force
    2, and a ball (a point of mass ``BALL_MASS``) that lands on the second with ``E_BALL``."""
    q, v = sp.symbols("x1 y1 x2 y2 x3 y3"), sp.symbols("a1 b1 a2 b2 a3 b3")
    ball = sp.sqrt((q[4] - q[2]) ** 2 + (q[5] - q[3]) ** 2) - R
    return vcigen.Model(
        name="pushed_pair",
        q=list(q),
        qdot=list(v),
        lagrangian=(v[0] ** 2 + v[1] ** 2 + v[2] ** 2 + v[3] ** 2 + BALL_MASS * (v[4] ** 2 + v[5] ** 2)) / 2
        - G * (q[1] + q[3] + BALL_MASS * q[5]),
        contacts={"f1": q[1] - R, "f2": q[3] - R, "p12": _pair(q, 0, 1), "ball": ball},
        restitution={"f1": 0.0, "f2": 0.0, "p12": 0.0, "ball": E_BALL},
        friction={"f1": (MU, q[0]), "f2": (MU, q[2])},
        forces=[2.0, 0, 0, 0, 0, 0],
    )


def tetra_pile() -> vcigen.Model:
    """Four unit balls of radius ``R`` in space (``x_i``, ``y_i``, ``z_i``), each on the floor ``z - R`` with
    an isotropic cone (``mu`` a parameter), each pair a contact; ``e = 0.3`` everywhere."""
    q, v = sp.symbols("x1:5 y1:5 z1:5"), sp.symbols("u1:5 v1:5 w1:5")
    x, y, z = q[0:4], q[4:8], q[8:12]
    mu = sp.Symbol("mu", nonnegative=True)
    contacts = {f"f{i + 1}": z[i] - R for i in range(4)}
    for i in range(4):
        for j in range(i + 1, 4):
            contacts[f"p{i + 1}{j + 1}"] = (
                sp.sqrt((x[j] - x[i]) ** 2 + (y[j] - y[i]) ** 2 + (z[j] - z[i]) ** 2) - 2 * R
            )
    return vcigen.Model(
        name="tetra_pile",
        q=list(q),
        qdot=list(v),
        lagrangian=sum(a**2 for a in v) / 2 - G * sum(z),
        contacts=contacts,
        params={mu: 0.5},
        restitution={name: 0.3 for name in contacts},
        friction={f"f{i + 1}": (mu, [x[i], y[i]]) for i in range(4)},
    )


def pushed_balls() -> vcigen.Model:
    """:func:`pushed_pair` in space: two unit balls side by side along ``x`` on a rough floor (isotropic
    cones, ``MU``), the first pushed against the second by a force 2 along ``x``, and a ball (a point of mass
    ``BALL_MASS``) that lands on the second with ``E_BALL``."""
    q, v = sp.symbols("x1 y1 z1 x2 y2 z2 x3 y3 z3"), sp.symbols("u1 v1 w1 u2 v2 w2 u3 v3 w3")

    def apart(i: int, j: int):
        return sp.sqrt(sum((q[3 * j + c] - q[3 * i + c]) ** 2 for c in range(3)))

    return vcigen.Model(
        name="pushed_balls",
        q=list(q),
        qdot=list(v),
        lagrangian=sum(a**2 for a in v[:6]) / 2
        + BALL_MASS * sum(a**2 for a in v[6:]) / 2
        - G * (q[2] + q[5] + BALL_MASS * q[8]),
        contacts={"f1": q[2] - R, "f2": q[5] - R, "p12": apart(0, 1) - 2 * R, "ball": apart(1, 2) - R},
        restitution={"f1": 0.0, "f2": 0.0, "p12": 0.0, "ball": E_BALL},
        friction={"f1": (MU, [q[0], q[1]]), "f2": (MU, [q[3], q[4]])},
        forces=[2.0] + [0] * 8,
    )


HALF_W, HALF_H = 0.5, 0.25  # the boxes' half sides


def two_boxes() -> vcigen.Model:
    """Two unit boxes (``(x, y, θ)`` each; half sides ``HALF_W x HALF_H``, inertia ``(w² + h²) / 12``): the
    lower one's bottom vertices on a rough floor, the upper one's bottom vertices on the lower one's top face
    (the distance along its normal, friction along it); ``e = 0.3`` and ``mu = 0.6`` everywhere."""
    x1, y1, t1, x2, y2, t2 = q = sp.symbols("x1 y1 t1 x2 y2 t2")
    v = sp.symbols("u1 v1 w1 u2 v2 w2")
    contacts, friction = {}, {}
    for side, cx in (("l", -HALF_W), ("r", HALF_W)):
        low = (x1 + cx * sp.cos(t1) + HALF_H * sp.sin(t1), y1 + cx * sp.sin(t1) - HALF_H * sp.cos(t1))
        contacts["f" + side], friction["f" + side] = low[1], (0.6, low[0])
        dx = x2 + cx * sp.cos(t2) + HALF_H * sp.sin(t2) - x1
        dy = y2 + cx * sp.sin(t2) - HALF_H * sp.cos(t2) - y1
        contacts["s" + side] = -dx * sp.sin(t1) + dy * sp.cos(t1) - HALF_H
        friction["s" + side] = (0.6, dx * sp.cos(t1) + dy * sp.sin(t1))
    inertia = (HALF_W**2 + HALF_H**2) / 3
    return vcigen.Model(
        name="two_boxes",
        q=list(q),
        qdot=list(v),
        lagrangian=(v[0] ** 2 + v[1] ** 2 + v[3] ** 2 + v[4] ** 2) / 2
        + inertia * (v[2] ** 2 + v[5] ** 2) / 2
        - G * (y1 + y2),
        contacts=contacts,
        restitution={name: 0.3 for name in contacts},
        friction=friction,
    )


@cache
def sim(name: str, backend: str) -> vcigen.Simulator:
    models = {
        "line": line_stack,
        "two": two_disks,
        "pyramid": example.model,
        "pushed": pushed_pair,
        "tetra": tetra_pile,
        "pushed3": pushed_balls,
        "boxes": two_boxes,
    }
    return vcigen.build(models[name](), backend=backend)


def _gaps(q: np.ndarray, pairs, floors) -> np.ndarray:
    out = [q[:, 2 * i + 1] - R for i in floors]
    out += [np.hypot(q[:, 2 * j] - q[:, 2 * i], q[:, 2 * j + 1] - q[:, 2 * i + 1]) - 2 * R for i, j in pairs]
    return np.column_stack(out)


@pytest.mark.parametrize("backend", BACKENDS)
def test_a_stack_of_three_comes_to_rest_carrying_the_weights_above(backend):
    """Dropped with gaps of 0.3 between them, the three bounce (``e = 0.5``) and settle: all rows held, at
    rest, each contact's force the weight above it (``(4.5, 3.5, 2) g``), no row below 0, every impact losing
    energy."""
    res = sim("line", backend).simulate(q0=[0.8, 2.1, 3.4], v0=[0.0] * 3, h=0.01, t_end=6.0)
    q = res.q
    gaps = np.column_stack([q[:, 0] - R, q[:, 1] - q[:, 0] - 2 * R, q[:, 2] - q[:, 1] - 2 * R])
    assert gaps.min() > -1e-12
    assert res.active[-1].all()
    assert np.abs(res.p[-1]).max() < 1e-12
    np.testing.assert_allclose(res.contact_force[-1], np.array([4.5, 3.5, 2.0]) * G, rtol=1e-9)
    assert res.stats["impacts_plastic"] >= 1 and res.stats["impacts_restitution"] >= 5
    # a cascade through the stack: the most in one step (6 at t = 0.433), at distinct instants
    for step in {i.step for i in res.impacts}:
        times = [i.t for i in res.impacts if i.step == step]
        assert len(times) <= 8 and np.all(np.diff(times) > 0)
    for imp in res.impacts:
        assert imp.energy_after < imp.energy_before


def _leaves(inertia, theta0: float) -> float:
    """scipy (event located, 1e-12) on one angle ``θ`` from the vertical, from rest at ``θ0``, with ``L = θ'²
    inertia(θ) - 2 g R cos θ``: when the lower body's acceleration, ``∝ cos θ θ'' - sin θ θ'²`` (the contact
    force's), falls to 0."""
    t, th, w = sp.Symbol("t"), sp.Symbol("th"), sp.Symbol("w")
    f = sp.Function("f")(t)
    lag = f.diff(t) ** 2 * inertia(f) - 2 * G * R * sp.cos(f)
    euler = sp.diff(lag.diff(f.diff(t)), t) - lag.diff(f)
    acc = sp.solve(euler, f.diff(t, 2))[0].subs(f.diff(t), w).subs(f, th)
    accel = sp.lambdify((th, w), acc)
    force = sp.lambdify((th, w), sp.cos(th) * acc - sp.sin(th) * w**2)

    def event(_, s):
        return force(s[0], s[1])

    event.terminal, event.direction = True, -1
    sol = solve_ivp(
        lambda _, s: [s[1], accel(*s)], (0, 5), [theta0, 0.0], events=event, rtol=1e-12, atol=1e-12
    )
    return float(sol.t_events[0][0])


def _disk_off_disk(offset: float) -> float:
    """The time the upper of two unit disks (lower one free on a frictionless floor, both at rest, the upper
    ``offset`` to the right on top) leaves the lower: :func:`_leaves` on the angle of the line between their
    centres (total horizontal momentum 0: ``L = R² θ'² (1 + sin² θ) - 2 g R cos θ``)."""
    return _leaves(lambda f: R**2 * (1 + sp.sin(f) ** 2), math.asin(offset / (2 * R)))


@pytest.mark.parametrize("backend", BACKENDS)
@pytest.mark.parametrize("offset", [0.01, 0.2])
def test_a_disk_slides_off_a_disk_that_slides_away_at_the_exact_time_to_second_order(backend, offset):
    """The upper disk leaves the lower (``pair`` released) at scipy's time to O(h²); the horizontal momentum
    is 0 throughout (``x1 + x2`` constant to round-off, through the later impacts too), no row below 0."""
    exact = _disk_off_disk(offset)
    start = [0.0, R, offset, R + math.sqrt(4 * R * R - offset * offset)]
    errors = []
    for h in (0.01, 0.005):
        res = sim("two", backend).simulate(q0=start, v0=[0.0] * 4, h=h, t_end=3.0)
        released = [t for t, name in res.liftoffs if name == "pair"]
        errors.append(abs(released[0] - exact))
        np.testing.assert_allclose(res.q[:, 0] + res.q[:, 2], offset, rtol=0, atol=1e-12)
        assert _gaps(res.q, [(0, 1)], [0, 1]).min() > -1e-12
        assert len(res.impacts) >= 3  # it lands, and they meet again
    assert errors[0] < 5e-5
    assert 3.5 < errors[0] / errors[1] < 4.5


@pytest.mark.parametrize("backend", BACKENDS)
def test_a_pyramid_on_a_rough_floor_rests_with_the_forces_of_statics(backend):
    """The top disk dropped 0.05 onto two touching ones (``mu = 0.5``): at rest, the floor carries ``3 g / 2``
    under each lower disk, the top none; the top's two contacts each ``g / (2 cos β)``, ``β`` their angle from
    the vertical at the end; the lower disks' own contact none."""
    start = [-R, R, R, R, 0.0, R + math.sqrt(3) * R + 0.05]
    res = sim("pyramid", backend).simulate(q0=start, v0=[0.0] * 6, h=0.01, t_end=3.0, params={"mu": 0.5})
    q = res.q[-1]
    assert np.abs(res.p[-1]).max() < 1e-12
    assert _gaps(res.q, [(0, 1), (0, 2), (1, 2)], [0, 1, 2]).min() > -1e-12
    cos_b = (q[5] - q[1]) / (2 * R)
    want = [1.5 * G, 1.5 * G, 0.0, 0.0, G / (2 * cos_b), G / (2 * cos_b)]
    np.testing.assert_allclose(res.contact_force[-1], want, rtol=1e-9, atol=1e-9)
    assert res.active[-1].tolist() == [True, True, False, False, True, True]


@pytest.mark.parametrize("backend", BACKENDS)
def test_a_pyramid_on_a_frictionless_floor_lets_its_top_go_from_both_at_once(backend):
    """The top pushes the lower disks apart and leaves both (``p13``, ``p23`` released at one instant) at
    scipy's time to O(h²); the motion stays symmetric (``x1 = -x2``, ``x3 = 0``) and no row goes below 0."""
    exact = example.release_time()
    start = [-R, R, R, R, 0.0, R + math.sqrt(3) * R]
    errors = []
    for h in (0.01, 0.005):
        res = sim("pyramid", backend).simulate(q0=start, v0=[0.0] * 6, h=h, t_end=0.8, params={"mu": 0.0})
        released = {name: t for t, name in res.liftoffs}
        assert released["p13"] == released["p23"]
        errors.append(abs(released["p13"] - exact))
        np.testing.assert_allclose(res.q[:, 0], -res.q[:, 2], rtol=0, atol=1e-12)
        np.testing.assert_allclose(res.q[:, 4], 0.0, rtol=0, atol=1e-12)
        assert _gaps(res.q, [(0, 1), (0, 2), (1, 2)], [0, 1, 2]).min() > -1e-12
    assert errors[0] < 1e-5
    assert 3.5 < errors[0] / errors[1] < 4.5


@pytest.mark.parametrize("backend", BACKENDS)
@pytest.mark.parametrize("alpha", [0.35, 0.6])
def test_a_disk_struck_beside_its_neighbour_keeps_its_own_friction(backend, alpha):
    """The ball falls from 1 m above the second disk's centre, ``α`` left of its top (``n = (-sin α, cos
    α)``). Pushed against it, the first disk holds the second's tangent through the row between them (the
    second a dependent stick riding on the first's stick row); the impulse pushes the second away from the
    first, the row between them takes none (``res.stats["riders_cut"]``), and the second disk's own cone
    decides (Coulomb's law at the impact, the floor plastic). ``tan α < μ`` (0.35): it sticks; both disks stay
    where they are (exactly) and the ball leaves with ``v - (1 + e) (v.n) n``. ``tan α > μ`` (0.6): it slides
    with ``u = P (sin α - μ cos α)``, ``P = -(1 + e) v.n / (1 / m_b + sin α (sin α - μ cos α))``, braked by
    ``μ g`` after, and the ball leaves with ``v + P n / m_b``. Before stop 41 the second disk slid with no
    friction (0.43 m/s for 0.126 at ``α = 0.6``; 9.5 mm where it should stick)."""
    h, drop = 0.01, 1.0
    start = [0.0, R, 2 * R, R, 2 * R - R * math.sin(alpha), R + drop]
    res = sim("pushed", backend).simulate(q0=start, v0=[0.0] * 6, h=h, t_end=0.6)
    assert [(i.contact, i.kind) for i in res.impacts] == [("ball", "restitution")]
    imp = res.impacts[0]
    v = np.array([0.0, -math.sqrt(2 * G * (drop - R * math.cos(alpha)))])
    n = np.array([-math.sin(alpha), math.cos(alpha)])
    k = imp.step + 1  # the grid point after the impact
    np.testing.assert_allclose(res.q[:, 0], 0.0, atol=1e-15)  # the first disk: its own cone holds it
    if math.tan(alpha) < MU:
        np.testing.assert_allclose(res.q[:, 2], 2 * R, atol=1e-15)
        ball = v - (1 + E_BALL) * (v @ n) * n
    else:
        lean = math.sin(alpha) - MU * math.cos(alpha)
        push = -(1 + E_BALL) * (v @ n) / (1 / BALL_MASS + math.sin(alpha) * lean)
        slide = push * lean
        assert abs(res.p[k, 2] - (slide - MU * G * (res.t[k] - imp.t))) < 1e-12
        ball = v + push * n / BALL_MASS
    assert abs(res.p[k + 1, 4] / BALL_MASS - ball[0]) < 1e-12  # its horizontal momentum in flight
    assert res.stats["riders_cut"] == 1


@pytest.mark.parametrize("backend", BACKENDS)
@pytest.mark.parametrize(("alpha", "phi"), [(0.35, 1.2), (0.6, 0.7)])
def test_a_ball_struck_beside_its_neighbour_keeps_its_own_cone(backend, alpha, phi):
    """:func:`test_a_disk_struck_beside_its_neighbour_keeps_its_own_friction` in space, with isotropic cones:
    the ball lands ``α`` from the second ball's top, turned ``φ`` about the vertical from the side of the
    first (``n = (-sin α cos φ, sin α sin φ, cos α)``), so that the push has a component across the line
    between them. ``tan α < μ``: the second ball sticks and the ball leaves with ``v - (1 + e) (v.n) n``;
    ``tan α > μ``: it slides along the push's horizontal direction with Coulomb's sliding impulse (the same
    closed form as in the plane). Before stop 41 its cone rode on the first ball's rows and the impact
    left it none: it took a frictionless impulse (the ball left at -1.5227 m/s for -1.5585 at ``α = 0.35, φ
    = 0``), then stopped at once where its cone stuck again, its momentum lost."""
    h, drop = 0.01, 1.0
    n = np.array([-math.sin(alpha) * math.cos(phi), math.sin(alpha) * math.sin(phi), math.cos(alpha)])
    start = [0.0, 0.0, R, 2 * R, 0.0, R, 2 * R + R * n[0], R * n[1], R + drop]
    res = sim("pushed3", backend).simulate(q0=start, v0=[0.0] * 9, h=h, t_end=0.6)
    assert [(i.contact, i.kind) for i in res.impacts] == [("ball", "restitution")]
    imp = res.impacts[0]
    v = np.array([0.0, 0.0, -math.sqrt(2 * G * (drop - R * math.cos(alpha)))])
    k = imp.step + 1
    np.testing.assert_allclose(res.q[:, 0:2], 0.0, atol=1e-15)
    if math.tan(alpha) < MU:
        np.testing.assert_allclose(res.q[:, 3:5], [[2 * R, 0.0]] * len(res.t), atol=1e-15)
        ball = v - (1 + E_BALL) * (v @ n) * n
    else:
        lean = math.sin(alpha) - MU * math.cos(alpha)
        push = -(1 + E_BALL) * (v @ n) / (1 / BALL_MASS + math.sin(alpha) * lean)
        along = -n[:2] / math.hypot(*n[:2])
        np.testing.assert_allclose(
            res.p[k, 3:5], (push * lean - MU * G * (res.t[k] - imp.t)) * along, atol=1e-12
        )
        ball = v + push * n / BALL_MASS
    np.testing.assert_allclose(res.p[k + 1, 6:8] / BALL_MASS, ball[:2], rtol=0, atol=1e-12)
    assert res.stats["riders_cut"] == 1


RC = 2 * R / math.sqrt(3)  # the lower balls' centres from the axis: touching, an equilateral triangle


def _tetra_start(lift: float) -> list[float]:
    """The lower balls touching on the floor around the z axis, the fourth on top of them, ``lift`` above."""
    angles = [math.pi / 2 + k * 2 * math.pi / 3 for k in range(3)]
    top = R + math.sqrt(4 * R * R - RC * RC) + lift
    return (
        [RC * math.cos(a) for a in angles]
        + [0.0]
        + [RC * math.sin(a) for a in angles]
        + [0.0]
        + [R] * 3
        + [top]
    )


def _tetra_release() -> float:
    """When the top ball of the pile (at rest, frictionless floor) leaves all three: :func:`_leaves` on the
    angle ``β`` of each lower-to-top line (``L = β'² (6 R² cos² β + 2 R² sin² β) - 2 g R cos β``)."""
    return _leaves(lambda f: 6 * R**2 * sp.cos(f) ** 2 + 2 * R**2 * sp.sin(f) ** 2, math.asin(RC / (2 * R)))


@pytest.mark.parametrize("backend", BACKENDS)
def test_a_pile_of_four_balls_rests_on_a_rough_floor_with_the_forces_of_statics(backend):
    """In space, isotropic cones on the floor (``mu = 0.5``): the top ball dropped 0.05 onto three touching
    ones settles; the floor carries ``4 g / 3`` under each lower ball, the top's three contacts ``g / (3 cos
    β)`` each, ``β`` their angle from the vertical at the end; the lower balls' own contacts and the top's
    floor none."""
    res = sim("tetra", backend).simulate(q0=_tetra_start(0.05), v0=[0.0] * 12, h=0.005, t_end=2.0)
    q = res.q[-1]
    assert np.abs(res.p[-1]).max() < 1e-12
    cos_b = (q[11] - q[8]) / (2 * R)
    want = [4 * G / 3] * 3 + [0.0] * 3 + [G / (3 * cos_b), 0.0] + [G / (3 * cos_b)] * 2  # f4, p12, p13: 0
    names = list(res.contact_names)
    assert names[:4] == ["f1", "f2", "f3", "f4"] and names[6] == "p14" and names[8:] == ["p24", "p34"]
    np.testing.assert_allclose(res.contact_force[-1], want, rtol=1e-9, atol=1e-9)


@pytest.mark.parametrize("backend", BACKENDS)
def test_a_pile_of_four_balls_on_a_frictionless_floor_lets_its_top_go_from_all_three_at_once(backend):
    """The top pushes the lower balls apart and leaves all three at one instant (their lift-offs, each row's
    own root, within 1e-12), at scipy's time to O(h²); the motion keeps its symmetry (``Σ x_i = 0``, the top
    on the axis) to round-off."""
    exact = _tetra_release()
    errors = []
    for h in (0.01, 0.005):
        res = sim("tetra", backend).simulate(
            q0=_tetra_start(0.0), v0=[0.0] * 12, h=h, t_end=0.8, params={"mu": 0.0}
        )
        released = {name: t for t, name in res.liftoffs}
        assert max(released[p] for p in ("p14", "p24", "p34")) - min(released.values()) < 1e-12
        errors.append(abs(released["p14"] - exact))
        assert np.abs(res.q[:, 0:4].sum(axis=1)).max() < 1e-14
        assert np.abs(res.q[:, [3, 7]]).max() < 1e-14
    assert errors[0] < 1e-5
    assert 3.5 < errors[0] / errors[1] < 4.5


@pytest.mark.parametrize("backend", BACKENDS)
def test_a_pile_whose_six_contacts_meet_at_once_takes_one_law_on_fifteen_rows(backend):
    """The pile at rest on a rough floor (``mu = 1``), the lower balls given 0.3 m/s towards the axis: at ``t
    = 0`` all six ball contacts meet at once beside the three floors held and their cones' six stick rows,
    fifteen rows, more than the enumeration takes (``MAX_LAW_ROWS = 12``): the law is solved by projected
    Gauss-Seidel (cones only, ``ImpulseLaw._law_pgs``). The run keeps the pile's three-fold symmetry (``Σ x_i
    = Σ y_i = 0`` over the lower balls, the top on the axis) to 1e-13, no impact adds energy and no row goes
    below 0. Before stop 41 it ended at step 0: "impulse law on 15 contacts at once"."""
    q0 = _tetra_start(0.0)
    inward = [-0.3 * c / RC for c in q0[0:3]], [-0.3 * c / RC for c in q0[4:7]]
    v0 = inward[0] + [0.0] + inward[1] + [0.0] * 5
    res = sim("tetra", backend).simulate(q0=q0, v0=v0, h=0.005, t_end=1.0, params={"mu": 1.0})
    first = sorted(i.contact for i in res.impacts if i.t < 1e-12)
    assert first == ["p12", "p13", "p14", "p23", "p24", "p34"]
    assert np.abs(res.q[:, 0:3].sum(axis=1)).max() < 1e-13 and np.abs(res.q[:, 4:7].sum(axis=1)).max() < 1e-13
    assert np.abs(res.q[:, [3, 7]]).max() < 1e-13
    assert all(i.energy_after <= i.energy_before for i in res.impacts)
    z, (x, y) = res.q[:, 8:12], (res.q[:, 0:4], res.q[:, 4:8])
    apart = [
        np.sqrt((x[:, j] - x[:, i]) ** 2 + (y[:, j] - y[:, i]) ** 2 + (z[:, j] - z[:, i]) ** 2) - 2 * R
        for i in range(4)
        for j in range(i + 1, 4)
    ]
    assert min((z - R).min(), np.min(apart)) > -1e-12
    assert np.abs(res.p[-1]).max() < 1e-12  # at rest


@pytest.mark.parametrize("backend", BACKENDS)
def test_a_box_dropped_tilted_onto_a_box_rests_with_the_forces_of_statics(backend):
    """The upper box dropped from 0.05 above the lower one, 0.1 to the side and tilted by 0.1: it bounces and
    rocks to rest on the lower one's face, both on their faces (``θ = 0``). The floor carries ``2 m g`` split
    by the moments about the lower box's centre, ``f_r - f_l = m g d / a`` (``d = x2 - x1``, ``a`` the half
    width); the upper box's two vertices ``m g / 2`` each; both boxes at rest, no row below 0."""
    tilt = 0.1
    start = [0.0, HALF_H, 0.0, 0.1, 3 * HALF_H + 0.05 + HALF_W * math.sin(tilt), tilt]
    res = sim("boxes", backend).simulate(q0=start, v0=[0.0] * 6, h=0.005, t_end=3.0)
    q = res.q[-1]
    assert np.abs(res.p[-1]).max() < 1e-12 and abs(q[2]) < 1e-12 and abs(q[5]) < 1e-12
    assert res.active[-1].all() and len(res.impacts) >= 3
    d = q[3] - q[0]
    force = dict(zip(res.contact_names, res.contact_force[-1]))
    assert force["fl"] == pytest.approx(G - G * d / (2 * HALF_W), rel=1e-9)
    assert force["fr"] == pytest.approx(G + G * d / (2 * HALF_W), rel=1e-9)
    assert force["sl"] == pytest.approx(G / 2, rel=1e-9) and force["sr"] == pytest.approx(G / 2, rel=1e-9)
    assert box_gap(res.q) > -1e-12


def box_gap(q: np.ndarray) -> float:
    """The lowest of ``two_boxes``' four rows over the run ``q`` (from the coordinates)."""
    low = math.inf
    for x1, y1, t1, x2, y2, t2 in q:
        for cx in (-HALF_W, HALF_W):
            low = min(low, y1 + cx * math.sin(t1) - HALF_H * math.cos(t1))
            dx = x2 + cx * math.cos(t2) + HALF_H * math.sin(t2) - x1
            dy = y2 + cx * math.sin(t2) - HALF_H * math.cos(t2) - y1
            low = min(low, -dx * math.sin(t1) + dy * math.cos(t1) - HALF_H)
    return low


def test_a_jump_whose_sub_solves_have_no_root_at_the_crossing_restarts_alike_on_both_backends():
    """Box on box draw 68 of ``bench.stacks_fuzz --scene boxes --seed 1`` (dropped at rest, ``h = 0.02``): at
    t = 0.3 the segment after an impact on ``sr`` crosses ``sl``, and the jump (48) has no root at the
    fractions near the crossing (its sub-solves end with a residual ~1e-6), nor has (78) in the bracket. The
    bracket's end is then no root however small its ``phi`` (4e-12 on CasADi, which took it before, 4e-6 on
    C, which restarted): both restart the impact by the continuous law and stay together to t = 3."""
    start = [0.0, 0.25, 0.0, 0.0231566720602554, 1.0852830082667495, 0.23263969723468297]
    res = {b: sim("boxes", b).simulate(q0=start, v0=[0.0] * 6, h=0.02, t_end=3.0) for b in ("c", "casadi")}
    for r in res.values():
        assert r.stats["jump_fallbacks"] == 1 and box_gap(r.q) > -1e-12
    c, k = res["c"], res["casadi"]
    assert [im.step for im in c.impacts] == [im.step for im in k.impacts]
    assert np.abs(c.q - k.q).max() < 1e-12 and np.abs(c.p - k.p).max() < 1e-12


def test_a_vertex_bouncing_beside_held_ones_settles_where_its_flights_are_below_the_resolution():
    """Box on box draw 94 of ``bench.stacks_fuzz --scene boxes --seed 1``: in the step from t = 0.24 the upper
    box lands on ``fl`` and ``sr`` (plastic, held) and its vertex ``sl`` lands on the lower box (``e = 0.3``)
    at a normal speed of 0.221 while they hold it, the row accelerating in at 12.3 under their forces: a
    flight of ``2 e v / a`` = 0.011 < h, below the jump's resolution (``Tolerances.rest``), so it settles
    there (plastic). Before stop 43 the settle test read the forces of the step before, whose rows the
    landings had changed (1.3 in), and ``sl`` bounced four times in the step. With ``Tolerances(rest=0.01)``
    it bounces on, five times in that step: on CasADi its second bounce was met again at its own start
    (``psi_sl`` 1.4e-19 above 0 there, the crossing search's first point 1.7e-16 in, within its tolerance)
    and held with no impulse, where C bounced on; a row on the contact at a segment's start is bracketed
    from where it is above it (as free flight's). Both backends log the same impacts, ``q`` to 1e-12, above
    the lower box. Since stop 54 (``ImpactSteps._missed``) nine times: in the step before, after an impact on
    ``fr``, ``sr`` dipped 6.7e-5 into the lower box before the next impact found, unseen by the segment's
    end and the cubic; that impact was taken with ``sr`` inside, and now ``sr``'s is located first."""
    start = [0.0, 0.25, 0.0, -0.10886022511403867, 0.9320877425687052, 0.1430585133571342]
    for rest, kinds in ((1.0, ["plastic"]), (0.01, ["restitution"] * 9 + ["plastic"])):
        res = {}
        for b in ("c", "casadi"):
            s = vcigen.build(two_boxes(), backend=b, tol=vcigen.Tolerances(rest=rest))
            res[b] = s.simulate(q0=start, v0=[0.0] * 6, h=0.02, t_end=0.4)
            assert [im.kind for im in res[b].impacts if im.step == 12 and im.contact == "sl"] == kinds
            assert box_gap(res[b].q) > -1e-12
        c, k = res["c"], res["casadi"]
        assert [(im.step, im.contact, im.kind) for im in c.impacts] == [
            (im.step, im.contact, im.kind) for im in k.impacts
        ]
        assert np.abs(c.q - k.q).max() < 1e-12


@pytest.mark.parametrize("backend", BACKENDS)
def test_a_pyramid_whose_lower_disks_touch_at_no_force_comes_to_rest_with_the_forces_of_statics(backend):
    """Draw 297 of ``bench.pyramids --seed 2`` (``e = 0``, ``mu = 0.886``, ``h = 0.05``): the lower disks
    start touching and drifting apart, the top lands on them. On C their contact stays held at a force of 0
    (CasADi releases it at t = 0.0036, round-off's sign), so the second disk's stick row rides on the first's;
    the top's landing at t = 0.162 cuts it (``riders_cut``), and the law leaves their contact no impulse. Held
    on, the rows were dependent and C's held step failed ("sustained solve failed", residual 0.18): a row the
    law drops that the rows held after carry, stick rows too, now leaves after a cut. The pyramid comes to
    rest with the forces of statics: ``3 g / 2`` under each lower disk, ``g / (2 cos β)`` in each of the top's
    contacts, none between the lower disks; no impact adds energy, no row goes below 0."""
    res = sim("pyramid", backend).simulate(
        q0=[-R, R, R, R, 0.17325795509081332, 1.4451135572451403],
        v0=[0.07807483705302438, 0.0, 0.15845765530947606, 0.0, -0.6967253943491972, -0.6659595828463868],
        h=0.05,
        t_end=3.0,
        params={"e": 0.0, "mu": 0.8860717149520267},
    )
    q = res.q[-1]
    assert np.abs(res.p[-1]).max() < 1e-12
    cos_b = (q[5] - q[1]) / (2 * R)
    want = [1.5 * G, 1.5 * G, 0.0, 0.0, G / (2 * cos_b), G / (2 * cos_b)]
    np.testing.assert_allclose(res.contact_force[-1], want, rtol=1e-9, atol=1e-9)
    assert _gaps(res.q, [(0, 1), (0, 2), (1, 2)], [0, 1, 2]).min() > -1e-12
    assert all(im.energy_after <= im.energy_before + 1e-12 for im in res.impacts)


def test_a_disk_held_to_a_stuck_one_stops_slipping_and_sticks_under_the_tops_landing():
    """Draw 1 of ``bench.pyramids --seed 2`` (``e = 1``, ``mu = 1.45``, ``h = 0.05``): the lower disks start
    touching, both sliding right on the floor; the top lands on the second, they hold together, the first
    sticks at the top's bounce off it (t = 0.006) and the second, held to it by the row between them, stops
    with it in the held step after. In C its sliding was 0 exactly from there on, so no stop event saw it
    change sign and it slipped on at rest; CasADi's was 1e-17 and stopped. At t = 0.24 the top lands on it
    again, the row between them leaves: CasADi's disk stuck, C's slid off at 0.65 m/s with no friction
    (0.03 apart by t = 0.4). A contact slipping at a sliding of 0 whose stick row depends on the rows held
    now sticks (it rides on them). Coulomb's law at that landing: the top's impulse on the disk leans
    ``atan(dx / dy)`` = 30 degrees off the vertical, inside the floor's cone (``tan 30 < mu``), so the disk
    does not move; both backends log the same impacts and end 1e-12 apart at t = 1."""
    res = {}
    for b in ("c", "casadi"):
        res[b] = sim("pyramid", b).simulate(
            q0=[-R, R, R, R, 0.0066395841417462576, 1.3698249824327713],
            v0=[0.20525195648513142, 0.0, 0.39159049807203866, 0.0, -0.8192212516177626, -0.8647057335772408],
            h=0.05,
            t_end=1.0,
            params={"e": 1.0, "mu": 1.4511539287405149},
        )
        r = res[b]
        land = next(im for im in r.impacts if im.contact == "p23" and im.t > 0.2)
        dx, dy = land.q[4] - land.q[2], land.q[5] - land.q[3]
        assert abs(dx / dy) < 1.4511539287405149
        k = int(np.searchsorted(r.t, land.t))  # the grid point after the landing
        assert r.t[k] < 0.3 and abs(r.v[k, 2]) < 1e-12 and abs(r.q[k, 2] - land.q[2]) < 1e-12
    c, k = res["c"], res["casadi"]
    assert [(im.step, im.contact, im.kind) for im in c.impacts] == [
        (im.step, im.contact, im.kind) for im in k.impacts
    ]
    assert np.abs(c.q - k.q).max() < 1e-12
