"""A particle dropped into a V with restitution under ``rule="lobatto3"`` (MATH.md *Sustained contact*: Zeno
into a corner; the contact time (47) of a segment that starts touching a contact it leaves).

The walls ``y = s |x|`` (``s = 0.424``), ``e = 0.169``, gravity: a draw of a random campaign (seed 3, draw
77) in which the particle bounces down both walls, slides, and ends at the vertex. At t = 1.9515 it sits in
the vertex, bounces off ``r`` while held on ``l``, and the free segment after it starts touching ``r`` (its
``phi`` +1e-20 in C). Where (47)'s Newton from the chord fails there, rules with internal points retry it
from the root of ``A s + B s^2`` through the segment's ends (``ImpactSteps._leave_guess``); C's retry called
the jump's system (78) with a first segment's arguments, read past them and crashed the process (a
segmentation fault, the run lost). It now solves the first segment's own system, as Python does.
"""

from __future__ import annotations

import warnings
from functools import cache

import numpy as np
import pytest
import sympy as sp
from hard_scenes import BACKENDS, G

import vcigen

SLOPE, E = 0.4239368843212526, 0.16893374286125729
START = ([0.0016164924077481935, 0.7137057185257542], [0.35703256, -1.852232])
H = 0.01


@cache
def run(backend: str) -> vcigen.Result:
    x, y, xd, yd = sp.symbols("x y xd yd")
    s, e = sp.symbols("s e", positive=True)
    n = sp.sqrt(1 + s**2)
    model = vcigen.Model(
        name="particle_in_v",
        q=[x, y],
        qdot=[xd, yd],
        lagrangian=(xd**2 + yd**2) / 2 - G * y,
        contacts={"l": (y + s * x) / n, "r": (y - s * x) / n},
        restitution={"l": e, "r": e},
        params={s: 1.0, e: 0.5},
    )
    sim = vcigen.build(model, backend=backend, rule="lobatto3")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        return sim.simulate(*START, H, t_end=2.5, params={"s": SLOPE, "e": E})


@pytest.mark.parametrize("backend", BACKENDS)
def test_a_particle_bouncing_into_a_v_ends_at_rest_in_its_vertex(backend: str) -> None:
    """It runs to t = 2.5 and rests in the vertex (both walls held, ``|q|`` and ``|v|`` below 1e-12); it
    never goes below a wall by more than 1e-12, and ``E_d`` never rises above its start by more than the
    flight's swing ``g^2 h^2 / 8``."""
    res = run(backend)
    assert res.t[-1] >= 2.5 and res.active[-1].all()
    assert np.abs(res.q[-1]).max() < 1e-12 and np.abs(res.v[-1]).max() < 1e-12
    gaps = np.minimum(res.q[:, 1] + SLOPE * res.q[:, 0], res.q[:, 1] - SLOPE * res.q[:, 0])
    assert gaps.min() / np.hypot(1.0, SLOPE) > -1e-12
    assert (res.energy - res.energy[0]).max() <= G**2 * H**2 / 8 * (1 + 1e-9)
    assert any(i.kind == "restitution" for i in res.impacts) and res.liftoffs


def test_the_particle_in_the_v_is_the_same_on_both_backends() -> None:
    """The grid's ``q`` agree to 1e-12. (Their logs part at t = 1.9515, in the vertex: ``phi_r`` of the
    free segment's start is -4.6e-20 on CasADi, which takes the landing at once, with an impulse of 0, and
    above 0 in C, which leaves ``r`` and lands on it 7 ms later; docs/limits.md.)"""
    c, ca = run("c"), run("casadi")
    assert np.abs(c.q - ca.q).max() < 1e-12
    before = [[(i.contact, i.kind, i.step) for i in r.impacts if i.t < 1.95] for r in (c, ca)]
    assert before[0] == before[1] and len(before[0]) >= 10
