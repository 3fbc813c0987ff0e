"""Stick-slip under a periodic drive (MATH.md *Forcing* and *Friction*): a block on a rough floor pushed by
``A sin(w t)``, ``A > mu m g``, sticks while ``|F| <= mu m g``, slips (``x'' = F - mu g sign(v)``) until its
speed is 0 again, and so on: 8 segments in 4 s. Reference: scipy (DOP853, rtol 1e-13) on each slip, its stop
located as an event (``v = 0`` crossed), each stick's end the root of ``|F| = mu g`` (brentq)."""

from __future__ import annotations

import math
from functools import cache

import numpy as np
import pytest
import sympy as sp
from hard_scenes import BACKENDS, G
from scipy.integrate import solve_ivp
from scipy.optimize import brentq

import vcigen
from vcigen.analysis import fit_order

A, W, MU, T_END = 6.0, 3.0, 0.4, 4.0


@cache
def block(backend: str) -> vcigen.Simulator:
    x, y, xd, yd, t = sp.symbols("x y xd yd t")
    model = vcigen.Model(
        name="ss_block",
        q=[x, y],
        qdot=[xd, yd],
        lagrangian=(xd**2 + yd**2) / 2 - G * y,
        contacts={"floor": y},
        friction={"floor": (MU, x)},
        forces=[A * sp.sin(W * t), 0],
        time=t,
    )
    return vcigen.build(model, backend=backend)


def drive(t: float) -> float:
    return A * math.sin(W * t)


def over_cone(t: float) -> float:
    return abs(drive(t)) - MU * G


@cache
def reference() -> list[tuple]:
    """The segments from rest at 0: ``("stick", t0, t1, x)`` or ``("slip", t0, t1, dense solution)``."""
    segments, t0, x0, sticking, side = [], 0.0, 0.0, True, 0
    while t0 < T_END:
        if sticking:  # till the drive reaches the cone: the first root of |F| - mu g after t0
            grid = np.linspace(t0, T_END, 4001)
            over = [over_cone(s) for s in grid]
            k = next((i for i in range(1, grid.size) if over[i] > 0.0 >= over[i - 1]), None)
            t1 = T_END if k is None else brentq(over_cone, grid[k - 1], grid[k], xtol=1e-15)
            segments.append(("stick", t0, t1, x0))
            t0, sticking, side = t1, False, (1 if drive(t1) > 0 else -1)
            continue

        def stop(t, z):
            return z[1]

        stop.terminal, stop.direction = True, -side
        sol = solve_ivp(
            lambda t, z, s=side: [z[1], drive(t) - MU * G * s],
            (t0, T_END),
            [x0, 0.0],
            method="DOP853",
            rtol=1e-13,
            atol=1e-14,
            events=stop,
            dense_output=True,
        )
        segments.append(("slip", t0, float(sol.t[-1]), sol.sol))
        t0, x0, sticking = float(sol.t[-1]), float(sol.y[0, -1]), abs(drive(sol.t[-1])) <= MU * G
        side = 1 if drive(t0) > 0 else -1
    return segments


def exact(t: float) -> float:
    for kind, t0, t1, x in reference():
        if t0 <= t <= t1:
            return x if kind == "stick" else float(x(t)[0])
    raise AssertionError(t)


@pytest.mark.parametrize("backend", BACKENDS)
def test_a_block_driven_back_and_forth_sticks_and_slips_as_scipy_at_order_two(backend):
    """Every stick and slip is located inside its step: ``x`` on the grid within 0.65 h^2 of the reference
    (measured 0.640-0.648 h^2, both backends alike), order 2; the block never leaves the floor."""
    assert [s[0] for s in reference()] == ["stick", "slip"] * 4
    hs, errs = [0.01, 0.005, 0.0025], []
    for h in hs:
        res = block(backend).simulate(q0=[0.0, 0.0], v0=[0.0, 0.0], h=h, t_end=T_END)
        assert res.active.all() and np.abs(res.q[:, 1]).max() < 1e-15
        errs.append(float(np.abs(res.q[:, 0] - [exact(t) for t in res.t]).max()))
        assert errs[-1] <= 0.65 * h * h, (h, errs[-1] / h**2)
    assert 1.95 < fit_order(hs, errs) < 2.05, errs
