"""A tall block rocking to rest on rough corners: Coulomb's cone at a landing while another contact is held
(MATH.md *Friction*: the tangential impulse at an impact opposes sliding within ``mu`` times the normal one;
``ImpulseLaw._law_lands``), Housner's rocking block.

The block of ``tests/test_rocking_block.py`` (``m = 1``, half height ``a = 0.5``, half width ``b = 0.2``,
``I = m (a^2 + b^2) / 3``), both bottom corners contacts with ``e = 0`` and Coulomb friction ``mu = 0.8`` (one
tangent each), released tilted by ``theta0 = 0.1`` on its left corner, at rest. The corner sticks: the block
is a pendulum about it, ``I_o = I + m (a^2 + b^2)``. The other corner lands at ``theta = 0`` plastic and
sticks (its tangential impulse ``m a |thetad-| (1 - eta)`` is within ``mu`` of its normal one ``m b |thetad-|
(1 + eta)``: 0.29 of it), the pivot leaves with no impulse, and angular momentum about the landing corner is
kept: ``thetad+ = eta thetad-``, Housner's ``eta = 1 - 3/2 sin^2 alpha`` (``tan alpha = b / a``). Between
landings, by energy, ``thetad^2 = 2 g (y(top) - y(theta)) / (I_o / m)``; each half swing's time is a
quadrature. The frictionless law at the landing (before this contract: the landing corner kept its
tangential velocity) leaves with ``(a^2 - 2 b^2) / (a^2 + 4 b^2) = 0.415`` instead of ``eta = 0.793``.
"""

from __future__ import annotations

import math
from functools import cache

import numpy as np
import pytest
from hard_scenes import BACKENDS, c_backend_problem
from test_rocking_block import CORNERS, INERTIA, MASS, THETA0, A, B, G, _drop, _top, block
from test_rocking_block import _down as down

import vcigen

MU = 0.8
PIVOT = INERTIA / MASS + A * A + B * B  # I_o / m
ETA = 1 - 1.5 * B * B / (A * A + B * B)


def _down(top: float) -> float:
    """The time from the turning point ``top`` down to ``theta = 0`` pivoting on a sticking corner."""
    return down(top, lambda th: PIVOT)


@cache
def closed_form() -> tuple[list[float], list[float], list[float], list[float], float]:
    """The landing times, their normal and tangential impulses, the landing speeds ``|thetad-|`` and the
    accumulation time ``t*``."""
    t = _down(THETA0)
    w = math.sqrt(2 * G * _drop(THETA0, 0.0) / PIVOT)
    times, normal, tangential, speeds = [], [], [], []
    while True:
        times.append(t)
        normal.append(MASS * B * w * (1 + ETA))
        tangential.append(MASS * A * w * (1 - ETA))
        speeds.append(w)
        w *= ETA
        rise = 0.5 * PIVOT * w * w / G
        if rise < 1e-30:
            return times, normal, tangential, speeds, t
        t += 2 * _down(_top(rise))


@cache
def simulator(backend: str) -> vcigen.Simulator:
    return vcigen.build(block(MU), backend=backend)


@cache
def run(backend: str, h: float, t_end: float = 0.8) -> vcigen.Result:
    y0 = max(-(px * math.sin(THETA0) + py * math.cos(THETA0)) for px, py in CORNERS.values())
    return simulator(backend).simulate([0.0, y0, THETA0], [0.0, 0.0, 0.0], h, t_end=t_end, progress=False)


def test_the_landing_sticks_inside_the_cone() -> None:
    """The scene's premise: Housner's landing impulse is inside the cone (``|T| / N = 0.29 < mu``)."""
    _, normal, tangential, _, _ = closed_form()
    assert max(t / n for t, n in zip(tangential, normal)) < 0.3 < MU


@pytest.mark.parametrize("backend", BACKENDS)
def test_the_landings_are_housners(backend: str) -> None:
    """The first five landings' times and normal impulses against the closed form at h and h/2 (alternating
    corners, plastic): errors below 1e-6 (times) and 1e-5 (impulses) at h = 1e-3, falling as h^2 (ratio >
    3.4). The impulses carry Housner's ``eta``: each is ``eta`` times the one before (the frictionless law:
    0.415). The pivot never slips: its corner's ``x`` stays put between landings."""
    times, normal, _, _, _ = closed_form()
    errs = []
    for h in (1e-3, 5e-4):
        res = run(backend, h, 1.2)
        first = [im for im in res.impacts if im.kind == "plastic"][:5]
        assert [im.contact for im in first] == ["right", "left", "right", "left", "right"]
        dt = max(abs(im.t - t) for im, t in zip(first, times))
        di = max(abs(im.impulse - p) for im, p in zip(first, normal))
        errs.append((dt, di))
        ratios = [b.impulse / a.impulse for a, b in zip(first, first[1:])]
        print(f"{backend} h = {h:g}: landing times {dt:.2e}, impulses {di:.2e}; ratios {np.round(ratios, 4)}")
        assert np.allclose(ratios, ETA, rtol=0, atol=1e-4)
        corner = {
            k: res.q[:, 0] + px * np.cos(res.q[:, 2]) - py * np.sin(res.q[:, 2])
            for k, (px, py) in CORNERS.items()
        }
        k0 = int(np.searchsorted(res.t, times[0])) - 1
        assert np.ptp(corner["left"][: k0 + 1]) <= 1e-12  # on the left corner until the first landing
    assert errs[0][0] <= 1e-6 and errs[0][1] <= 1e-5
    assert errs[0][0] / errs[1][0] > 3.4 and errs[0][1] / errs[1][1] > 3.4


@pytest.mark.parametrize("backend", BACKENDS)
@pytest.mark.parametrize("h", [1e-3, 5e-4])
def test_it_comes_to_rest_at_the_accumulation_time(backend: str, h: float) -> None:
    """Finitely many landings (of the infinitely many), at most two in a step, then at rest on its face (both
    corners held to the end) from within 10 h of ``t*``, upright, at rest. The count of landings is the closed
    form's: the corner a landing pulls off leaves at ``2 b eta |thetad-|`` and stays held once that is at most
    ``h`` times its pull-back ``2 b g b / (I_o / m)`` (gravity's about the landing corner, which sticks:
    ``HeldImpacts._landed``; under the frictionless pull-back the block rested 21 h before ``t*``)."""
    _, _, _, speeds, t_star = closed_form()
    back = 2 * B * G * B / PIVOT
    count = next(k + 1 for k, w in enumerate(speeds) if 2 * B * ETA * w <= h * back)
    res = run(backend, h, 2.0)
    held = res.active.all(axis=1)
    start = int(np.argmax(held))
    assert held[start:].all() and start > 0
    assert 0 <= t_star - res.t[start] <= 10 * h
    assert max(np.bincount([im.step for im in res.impacts])) <= 2
    assert len(res.impacts) == count and len(res.liftoffs) == count - 1
    assert abs(res.q[-1, 2]) <= 1e-12 and np.abs(res.v[-1]).max() <= 1e-12
    rest = f"at rest from {res.t[start]:.4f} (t* = {t_star:.6f})"
    print(f"{backend} h = {h:g}: {len(res.impacts)} landings, {rest}")


@pytest.mark.skipif(c_backend_problem() is not None, reason=str(c_backend_problem()))
def test_c_equals_casadi() -> None:
    """The C run is the CasADi one: the same landings (step, corner, kind), states to 1e-12."""
    a, b = run("casadi", 1e-3, 2.0), run("c", 1e-3, 2.0)
    assert [(i.step, i.contact, i.kind) for i in a.impacts] == [
        (i.step, i.contact, i.kind) for i in b.impacts
    ]
    assert np.abs(a.q - b.q).max() <= 1e-12
