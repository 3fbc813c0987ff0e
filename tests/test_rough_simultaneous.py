"""Several frictional contacts hit at once from flight: Newton's law with Coulomb's cone (MATH.md
*Friction*; ``HeldImpacts._rough_rest``, C ``rough`` in ``stepper_impacts.c.j2``), not the frictionless jump
along the normal cone (86).

The square box of ``tests/test_friction_rod.py`` (side 1, ``m = 1``, ``I = m/6``, a contact at each vertex,
``e = 0.5``, ``mu = 0.2``) dropped flat from ``y = 1.5`` sliding at ``vx = 2``: its two bottom vertices land
at once at ``t* = sqrt(2/g)`` with the speed ``w = g t*``. Newton's law on each (``-e w`` after) and Coulomb's
sliding impulse ``T = -mu S`` (``S`` the two normal impulses together) keep it from turning: ``S = m (1 + e)
w``, ``vx+ = vx - mu (1 + e) w``, ``vy+ = e w``, ``thetad+ = 0``, and the torque of ``T`` about the centre
shifts the normal impulses, ``N = S (1 -+ mu b / a) / 2`` (``a = b = 1/2``). It flies flat and lands flat
again at ``t* + 2 e w / g``, where the same law takes ``e w``. Before: the jump kept ``vx = 2``.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from hard_scenes import BACKENDS, c_backend_problem
from test_friction_rod import G, sim

MU, E, VX, Y0, H = 0.2, 0.5, 2.0, 1.5, 0.01


def closed_form(t: np.ndarray):
    """The landings ``[(t_k, N_left, N_right)]`` and ``(x, y, vx)`` at the times ``t`` (two landings)."""
    t1 = math.sqrt(2 * (Y0 - 0.5) / G)
    w1 = G * t1
    t2 = t1 + 2 * E * w1 / G
    vx1 = VX - MU * (1 + E) * w1
    vx2 = vx1 - MU * (1 + E) * E * w1
    landings = []
    for tk, w in ((t1, w1), (t2, E * w1)):
        s = (1 + E) * w
        landings.append((tk, s * (1 - MU) / 2, s * (1 + MU) / 2))
    x = np.where(t <= t1, VX * t, VX * t1 + vx1 * (np.minimum(t, t2) - t1) + vx2 * np.clip(t - t2, 0, None))
    d = t - t1
    y = np.where(t <= t1, Y0 - G * t * t / 2, 0.5 + E * w1 * d - G * d * d / 2)
    vx = np.where(t < t1, VX, np.where(t < t2, vx1, vx2))
    return landings, x, y, vx, t2


@pytest.mark.parametrize("backend", BACKENDS)
def test_a_flat_landing_takes_coulombs_sliding_impulse(backend: str) -> None:
    """Two landings, each on both bottom vertices at once (kind restitution), their normal impulses on the
    closed form to 1e-12; between them and up to the second, ``x, y, vx`` at every grid point to 1e-12,
    the box never turning (``theta``, ``thetad`` 0 to 1e-14)."""
    res = sim("box", backend).simulate(
        q0=[0.0, Y0, 0.0], v0=[VX, 0.0, 0.0], h=H, t_end=1.0, params={"mu": MU, "e": E}, progress=False
    )
    landings, x, y, vx, t2 = closed_form(res.t)
    first = res.impacts[:4]
    assert [(im.contact, im.kind) for im in first] == [("c", "restitution"), ("d", "restitution")] * 2
    for k, (tk, n_left, n_right) in enumerate(landings):
        left, right = first[2 * k], first[2 * k + 1]
        assert abs(left.t - tk) <= 1e-12 and abs(right.t - tk) <= 1e-12
        assert abs(left.impulse - n_left) <= 1e-12 and abs(right.impulse - n_right) <= 1e-12
    upto = res.t < t2 + H  # the grid points up to the step of the second landing
    err = max(
        float(np.abs(res.q[upto, 0] - x[upto]).max()),
        float(np.abs(res.q[upto & (res.t <= t2), 1] - y[upto & (res.t <= t2)]).max()),
        float(np.abs(res.p[upto, 0] - vx[upto]).max()),
    )
    print(f"{backend}: flat landings on the closed form to {err:.1e}")
    assert err <= 1e-12
    assert np.abs(res.q[upto, 2]).max() <= 1e-14 and np.abs(res.p[upto, 2]).max() <= 1e-14


@pytest.mark.skipif(c_backend_problem() is not None, reason=str(c_backend_problem()))
def test_c_equals_casadi() -> None:
    """The same landings and states on both backends to 1e-12 (to rest on the face, t = 3)."""
    kw = {"q0": [0.0, Y0, 0.0], "v0": [VX, 0.0, 0.0], "h": H, "t_end": 3.0, "params": {"mu": MU, "e": E}}
    a, b = (sim("box", bk).simulate(progress=False, **kw) for bk in ("casadi", "c"))
    assert [(i.step, i.contact, i.kind) for i in a.impacts] == [
        (i.step, i.contact, i.kind) for i in b.impacts
    ]
    assert np.abs(a.q - b.q).max() <= 1e-12 and np.abs(a.p - b.p).max() <= 1e-12
