"""A tall block rocking to rest on a frictionless floor: Zeno through impacts while held (MATH.md *Sustained
contact*: a Zeno sequence reaches rest after finitely many impacts, never more than a few per step).

The block (``m = 1``, half height ``a = 0.5``, half width ``b = 0.2``, ``I = m (a^2 + b^2) / 3``) stands on
its left corner, tilted by ``theta0 = 0.1``, at rest, on a smooth floor; both bottom corners are contacts with
``e = 0``. It pivots on the held corner (its centre's ``x`` fixed: no horizontal force) until the other corner
lands at ``theta = 0``: plastic, and since ``a > sqrt(2) b`` the law pulls the pivot off (its impulse would be
negative), so the block tips onto the new corner with ``thetad+ = r thetad-``, ``r = (a^2 - 2 b^2) / (a^2 +
4 b^2)`` (the impulse ``2 b |thetad-| / (1/m + b^2/I)``), rises and comes back to ``theta = 0`` with the same
speed, and so on: infinitely many landings accumulating at ``t*``. Between landings, by energy,
``thetad^2 = 2 g (y(top) - y(theta)) / (I/m + (b cos theta - a sin theta)^2)``, ``y = b sin theta + a cos
theta``; each half swing's time is a quadrature (:func:`closed_form`, scipy ``quad`` to 1e-12).

The integrator: the landing times are second order; the corner a landing pulls off stays held once its speed
is below the jump's resolution, ``rate <= rest h |acc|``, ``acc`` its acceleration under the rows held after
the impact (``HeldImpacts._held_accel``); the block then rests on its face, ``O(h)`` from ``t*``.
"""

from __future__ import annotations

import math
from functools import cache

import numpy as np
import pytest
import sympy as sp
from hard_scenes import BACKENDS, c_backend_problem
from scipy.integrate import quad
from scipy.optimize import brentq

import vcigen

A, B, MASS, G = 0.5, 0.2, 1.0, 9.81
INERTIA = MASS * (A * A + B * B) / 3
THETA0 = 0.1
R = (A * A - 2 * B * B) / (A * A + 4 * B * B)
CORNERS = {"left": (-B, -A), "right": (B, -A)}


def block(mu: float | None = None) -> vcigen.Model:
    """The block on a smooth floor, or with Coulomb friction ``mu`` (a parameter) at each corner (one
    tangent: the corner's ``x``; ``tests/test_rocking_block_rough.py``)."""
    x, y, th, xd, yd, thd = sp.symbols("x y th xd yd thd")
    contacts = {k: y + px * sp.sin(th) + py * sp.cos(th) for k, (px, py) in CORNERS.items()}
    rough = {}
    if mu is not None:
        m = sp.Symbol("mu")
        tangents = {k: x + px * sp.cos(th) - py * sp.sin(th) for k, (px, py) in CORNERS.items()}
        rough = {"params": {m: mu}, "friction": {k: (m, t) for k, t in tangents.items()}}
    return vcigen.Model(
        name="rocking_block" if mu is None else "rough_rocking_block",
        q=[x, y, th],
        qdot=[xd, yd, thd],
        lagrangian=MASS * (xd**2 + yd**2) / 2 + INERTIA * thd**2 / 2 - G * MASS * y,
        contacts=contacts,
        restitution=dict.fromkeys(contacts, 0.0),
        **rough,
    )


def _inertia(th: float) -> float:
    """The pivoting block's inertia per unit mass about its held corner's line of sliding."""
    return INERTIA / MASS + (B * math.cos(th) - A * math.sin(th)) ** 2


def _drop(a: float, b: float) -> float:
    """``y(a) - y(b)`` without cancellation."""
    return 2 * math.sin((a - b) / 2) * (B * math.cos((a + b) / 2) - A * math.sin((a + b) / 2))


def _down(top: float, inertia=None) -> float:
    """The time from the turning point ``top`` down to ``theta = 0`` (``theta = top (1 - s^2)``), the
    inertia per unit mass about the pivot's line ``inertia(theta)`` (default: sliding, :func:`_inertia`)."""
    inertia = inertia or _inertia

    def f(s: float) -> float:
        th = top * (1 - s * s)
        if s == 0.0:
            return 2 * top / math.sqrt(2 * G * top * (B * math.cos(top) - A * math.sin(top)) / inertia(top))
        return 2 * s * top / math.sqrt(2 * G * _drop(top, th) / inertia(th))

    return quad(f, 0, 1, epsabs=1e-17, epsrel=1e-12, limit=200)[0]


def _top(rise: float) -> float:
    """The turning point of a swing whose centre rises by ``rise`` above its height at ``theta = 0``."""
    return brentq(lambda th: _drop(th, 0.0) - rise, 0.0, math.atan2(B, A), xtol=1e-300, rtol=1e-15)


@cache
def closed_form() -> tuple[list[float], list[float], float]:
    """The landing times, the landings' impulses and the accumulation time ``t*``."""
    t = _down(THETA0)
    w = math.sqrt(2 * G * _drop(THETA0, 0.0) / _inertia(0.0))
    times, impulses = [], []
    while True:
        times.append(t)
        impulses.append(2 * B * w / (1 / MASS + B * B / INERTIA))
        w *= R
        rise = 0.5 * _inertia(0.0) * w * w / G
        if rise < 1e-30:
            return times, impulses, t
        t += 2 * _down(_top(rise))


@cache
def simulator(backend: str) -> vcigen.Simulator:
    return vcigen.build(block(), backend=backend)


@cache
def run(backend: str, h: float) -> vcigen.Result:
    y0 = max(-(px * math.sin(THETA0) + py * math.cos(THETA0)) for px, py in CORNERS.values())
    return simulator(backend).simulate([0.0, y0, THETA0], [0.0, 0.0, 0.0], h, t_end=0.4, progress=False)


@pytest.mark.parametrize("backend", BACKENDS)
def test_the_landings_are_second_order(backend: str) -> None:
    """The first five landings' times and impulses against the closed form at h and h/2: errors below 4e-7
    (times) and 3e-6 (impulses) at h = 1e-3, falling as h^2 (ratio > 3.4); alternating corners, plastic."""
    times, impulses, _ = closed_form()
    errs = []
    for h in (1e-3, 5e-4):
        res = run(backend, h)
        first = [im for im in res.impacts if im.kind == "plastic"][:5]
        assert [im.contact for im in first] == ["right", "left", "right", "left", "right"]
        dt = max(abs(im.t - t) for im, t in zip(first, times))
        di = max(abs(im.impulse - p) for im, p in zip(first, impulses))
        errs.append((dt, di))
        print(f"{backend} h = {h:g}: landing times {dt:.2e}, impulses {di:.2e}")
    assert errs[0][0] <= 4e-7 and errs[0][1] <= 3e-6
    assert errs[0][0] / errs[1][0] > 3.4 and errs[0][1] / errs[1][1] > 3.4


@pytest.mark.parametrize("backend", BACKENDS)
@pytest.mark.parametrize("h", [1e-3, 5e-4])
def test_it_rests_on_its_face_at_the_accumulation_time(backend: str, h: float) -> None:
    """Finitely many landings (of the infinitely many), at most two in a step; then both corners held to the
    end, from within 3 h of ``t*``, upright (``theta`` ~ 0), at rest, its centre's ``x`` never moved."""
    _, _, t_star = closed_form()
    res = run(backend, h)
    held = res.active.all(axis=1)
    start = int(np.argmax(held))
    assert held[start:].all() and start > 0
    assert abs(res.t[start] - t_star) <= 3 * h
    steps = [im.step for im in res.impacts]
    assert max(np.bincount(steps)) <= 2
    assert abs(res.q[-1, 2]) <= 1e-12 and np.abs(res.v[-1]).max() <= 1e-12
    assert np.abs(res.q[:, 0]).max() <= 1e-15
    print(
        f"{backend} h = {h:g}: {len(res.impacts)} landings, rests from {res.t[start]:.4f} (t* = {t_star:.6f})"
    )


@pytest.mark.parametrize("backend", BACKENDS)
@pytest.mark.parametrize("h", [1e-3, 5e-4])
def test_the_pulled_off_corner_stays_once_below_the_resolution(backend: str, h: float) -> None:
    """The corner a landing pulls off leaves with ``2 b r |thetad-|`` and is pulled back at ``2 b g b / (I/m +
    b^2)`` (gravity's torque about the new pivot): it stays held from the first landing where that speed is
    at most ``rest h`` times that acceleration (``Tolerances.rest = 1``). The closed form's count of
    landings, 6 at h = 1e-3 and 7 at 5e-4, is the run's. (Under the corner's own force, its acceleration 0,
    it never stayed: 8 landings at h = 1e-3, two in one step.)"""
    _, impulses, _ = closed_form()
    back = 2 * B * G * B / (INERTIA / MASS + B * B)
    count = next(
        k + 1
        for k, p in enumerate(impulses)
        if 2 * B * R * p * (1 / MASS + B * B / INERTIA) / (2 * B) <= h * back
    )
    res = run(backend, h)
    assert len(res.impacts) == count
    assert len(res.liftoffs) == count - 1  # each landing but the last released the other corner


@pytest.mark.skipif(c_backend_problem() is not None, reason=str(c_backend_problem()))
def test_c_equals_casadi() -> None:
    """The C run is the CasADi one: the same landings (step, corner, kind), states to 1e-12."""
    a, b = run("casadi", 1e-3), run("c", 1e-3)
    assert [(i.step, i.contact, i.kind) for i in a.impacts] == [
        (i.step, i.contact, i.kind) for i in b.impacts
    ]
    assert np.abs(a.q - b.q).max() <= 1e-12
