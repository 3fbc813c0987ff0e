"""A block sliding down a rough ramp onto a rough floor (MATH.md *Friction*: Coulomb's impulse at a landing).

The ramp ``y >= -tan(a) x`` meets the floor ``y >= 0`` at the origin. Released at rest a length 1 up the ramp
(``mu < tan a``) the block slides down at ``g (sin a - mu cos a)``, reaches the foot at ``v_b`` and lands on
the floor there (plastic): normal impulse ``v_b sin a``, and Coulomb's tangential impulse, ``mu v_b sin a``
while it slides on (``mu < cot a``), all of ``v_b cos a`` where it sticks. The ramp's row takes no impulse and
leaves. It then slides to a stop after ``v_t^2 / (2 mu g)``. At the landing both normal rows are in the law
and the floor's stick row is in their span: till stop 46 its friction was left out
(``landing_friction_dropped``), and the block slid 26 % too far (a = 0.5, mu = 0.2; 109 % at a = 0.8, mu =
0.3). The law is now solved again with the landing stick rows tested against the rows that stay
(``ImpulseLaw._law_leaving``, C ``law_leaving``)."""

from __future__ import annotations

import math
from functools import cache

import numpy as np
import pytest
import sympy as sp
from hard_scenes import BACKENDS, G

import vcigen


def model() -> vcigen.Model:
    """A unit mass on the ramp (angle ``a``) and the floor, both rough (``mu``) and plastic."""
    x, y, xd, yd = sp.symbols("x y xd yd")
    a, mu = sp.symbols("a mu")
    return vcigen.Model(
        name="ramp_floor",
        q=[x, y],
        qdot=[xd, yd],
        lagrangian=(xd**2 + yd**2) / 2 - G * y,
        contacts={"ramp": sp.sin(a) * x + sp.cos(a) * y, "floor": y},
        restitution={"ramp": 0.0, "floor": 0.0},
        friction={"ramp": (mu, sp.cos(a) * x - sp.sin(a) * y), "floor": (mu, x)},
        params={a: 0.5, mu: 0.2},
    )


@cache
def ramp(backend: str) -> vcigen.Simulator:
    return vcigen.build(model(), backend=backend)


@pytest.mark.parametrize(("a", "mu"), [(0.5, 0.2), (0.3, 0.1), (0.8, 0.3), (1.0, 1.0)])
@pytest.mark.parametrize("backend", BACKENDS)
def test_a_block_sliding_off_a_rough_ramp_lands_with_coulombs_impulse_and_stops_where_it_should(
    backend, a, mu
):
    """The landing at the foot, the ramp's release there, and the stop: exact to 1e-12 (a = 1, mu = 1: it
    sticks at the landing, mu >= cot a, and stays at the foot, touching the ramp with no force)."""
    accel = G * (math.sin(a) - mu * math.cos(a))
    v_b = math.sqrt(2 * accel)
    t_b = v_b / accel
    v_t = max(v_b * math.cos(a) - mu * v_b * math.sin(a), 0.0)
    res = ramp(backend).simulate(
        q0=[-math.cos(a), math.sin(a)],
        v0=[0.0, 0.0],
        h=0.01,
        t_end=t_b + v_t / (mu * G) + 0.3,
        params={"a": a, "mu": mu},
    )
    assert [(i.contact, i.kind) for i in res.impacts] == [("floor", "plastic")]
    assert res.impacts[0].t == pytest.approx(t_b, abs=1e-12)
    assert res.stats["landing_friction_dropped"] == 0
    assert res.q[-1] == pytest.approx([v_t**2 / (2 * mu * G), 0.0], abs=1e-12)
    assert np.abs(res.p[-1]).max() < 1e-12
    if v_t > 0.0:  # the ramp's row leaves at the landing, moving away at v_t sin a
        assert [j for _, j in res.liftoffs] == ["ramp"] and res.active[-1].tolist() == [False, True]
        assert res.liftoffs[0][0] == pytest.approx(t_b, abs=1e-12)
    else:  # stopped in the corner: the ramp's row, at rest in the span of the floor's rows, stays held with 0
        assert not res.liftoffs and res.active[-1].all()
        assert res.contact_force[-1] == pytest.approx([0.0, G], abs=1e-12)
