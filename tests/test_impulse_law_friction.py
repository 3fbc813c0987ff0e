"""Coulomb's cone in the impulse law of an impact while contacts are held (``SustainedSteps._impulse_law``, C
``impulse_law`` in ``templates/sustained_impacts.c.j2``; MATH.md *Sustained contact*, *Friction*).

A held stick row (a contact rolling or sticking) takes at an impact a tangential impulse ``|Lam_t| <= mu_f
Lam_n``, ``Lam_n`` its contact's normal impulse in that impact; beyond it the contact slips during the impact
(``Lam_t = -mu_f Lam_n sign(tangential velocity after)``) and slips on after it.

* a disk rolling on a rough floor into a smooth vertical wall (restitution ``e``): the floor's normal
  impulse is 0, so the wall turns ``xd`` to ``-e xd``, the spin is kept, and the disk slips on the floor
  until friction ``mu g`` makes it roll again (closed forms for the whole run);
* the same disk into a sloped wall (its normal pointing down into the floor: the floor's normal impulse is
  ``P sin b``): with a large ``mu`` the stick holds within the cone (the disk rolls back at ``-e xd``),
  with a small one it slips at the impact with ``Lam_t = mu_f Lam_n`` (closed forms of the impulse and the
  run after).

Both backends, both rules, against the closed forms; C against CasADi; the tangent through the stick that
holds against central differences, and a clear break ("friction switch in a held step") where it slips.
"""

from __future__ import annotations

import math
from functools import cache

import hard_scenes
import numpy as np
import pytest
import sympy as sp
from test_sensitivity import BACKENDS, assert_lost, held_finite_differences, held_mode, relative_error

import vcigen

G = 9.81
RULES = ("trapezoid", "midpoint")
needs_c = pytest.mark.skipif(
    hard_scenes.c_backend_problem() is not None, reason=str(hard_scenes.c_backend_problem())
)
V = 1.05  # the rolling speed: xd = r thetad = V
H = 0.01
X_HIT = 0.16  # the centre's x at the impact
DISK = {"m": 1.0, "I": 0.5, "r": 1.0, "g": G, "mu": 0.2, "e": 0.8}


def disk(slope: float | None) -> vcigen.Model:
    """A disk (``x, y, theta``) on the rough floor ``y >= r`` (tangent ``x - r theta``) rolling into the
    smooth wall ``W - r - x cos b - y sin b >= 0`` (restitution ``e``; ``b = 0`` vertical, ``b > 0`` its
    normal pointing down into the floor), placed so that the centre hits it at ``x = X_HIT``."""
    x, y, th, xd, yd, thd = sp.symbols("x y th xd yd thd")
    m, inertia, r, g, mu, e, b = sp.symbols("m I r g mu e b")
    par = dict(zip((m, inertia, r, g, mu, e), DISK.values())) | {b: slope or 0.0}
    w = sp.Symbol("W")
    par[w] = DISK["r"] + X_HIT * math.cos(par[b]) + DISK["r"] * math.sin(par[b])
    return vcigen.Model(
        name="ilf_disk" if slope is None else "ilf_disk_slope",
        q=[x, y, th],
        qdot=[xd, yd, thd],
        lagrangian=m / 2 * (xd**2 + yd**2) + inertia / 2 * thd**2 - m * g * y,
        contacts={"floor": y - r, "wall": w - r - x * sp.cos(b) - y * sp.sin(b)},
        params=par,
        friction={"floor": (mu, x - r * th)},
        restitution={"wall": e},
    )


@cache
def simulator(slope: bool, backend: str, rule: str = "trapezoid") -> vcigen.Simulator:
    return vcigen.build(disk(0.7 if slope else None), backend=backend, rule=rule)


def run(slope: bool, backend: str, rule: str = "trapezoid", mu: float = 0.2, t_end: float = 0.8, **kw):
    sim = simulator(slope, backend, rule)
    return sim.simulate([0.0, 1.0, 0.0], [V, 0.0, V], H, t_end=t_end, params={"mu": mu}, progress=False, **kw)


def closed_form(t: np.ndarray, vx: float, om: float, mu: float) -> tuple[np.ndarray, ...]:
    """``(x, theta, xd, thetad)`` at ``t``: rolling at ``V`` to the wall (``t* = X_HIT / V``), there ``(xd,
    thetad)`` turn to ``(vx, om)``; then the floor's friction ``mu m g`` against the slip ``s = xd - r
    thetad`` (``xd' = -sign(s) mu g``, ``thetad' = sign(s) r mu m g / I``) until ``s = 0``, rolling on from
    there."""
    m, inertia, r = DISK["m"], DISK["I"], DISK["r"]
    ts = X_HIT / V
    s0 = vx - r * om
    ax = -math.copysign(mu * G, s0) if s0 else 0.0
    al = -r * m * ax / inertia
    t_roll = ts + (abs(s0) / abs(ax - r * al) if s0 else 0.0)
    d = np.clip(t - ts, 0.0, t_roll - ts)  # time slipping
    after = np.clip(t - t_roll, 0.0, None)  # time rolling again
    xd = vx + ax * d
    om_t = om + al * d
    x = X_HIT + vx * d + ax * d * d / 2 + xd * after
    th = X_HIT / r + om * d + al * d * d / 2 + om_t * after
    before = t <= ts
    return (
        np.where(before, V * t, x),
        np.where(before, V * t / r, th),
        np.where(before, V, xd),
        np.where(before, V / r, om_t),
    )


def slope_impact(mu: float, b: float) -> tuple[float, float, float, float]:
    """The sloped wall's impact on the rolling disk: ``(xd+, thetad+, P, Lam_t)``. The floor holds ``yd = 0``
    with ``N = P sin b``; the wall makes ``xd+ = -e V``. Sticking: ``Lam_t = I (1 + e) V / r^2``; if that is
    beyond ``mu N`` (``N`` from ``P cos b = m (1 + e) V + Lam_t``) the floor slips backwards in the impact:
    ``Lam_t = mu N = mu tan b m (1 + e) V / (1 - mu tan b)``."""
    m, inertia, r, e = DISK["m"], DISK["I"], DISK["r"], DISK["e"]
    stick = inertia * (1 + e) * V / r**2
    lam_t = stick
    if stick > mu * math.tan(b) * (m * (1 + e) * V + stick):
        lam_t = mu * math.tan(b) * m * (1 + e) * V / (1 - mu * math.tan(b))
    p = (m * (1 + e) * V + lam_t) / math.cos(b)
    return -e * V, V / r - r * lam_t / inertia, p, lam_t


# case -> (sloped wall, mu)
CASES = {
    "vertical": (False, 0.2),  # the floor's normal impulse is 0: the stick slips with Lam_t = 0
    "slope_slip": (True, 0.2),  # N > 0, I (1 + e) V / r^2 > mu N: slips during the impact, Lam_t = mu N
    "slope_stick": (True, 0.5),  # within the cone: the disk rolls back at -e V
}
TOL = 1e-13  # the discrete map is exact: uniform rolling, a located impact, constant friction, a located stop


def max_error(q: np.ndarray, vel: np.ndarray, q_ref: dict, vel_ref: dict) -> float:
    """The largest ``|q[:, i] - q_ref[i]|`` and ``|vel[:, i] - vel_ref[i]|`` over the grid (named columns)."""
    errs = [np.abs(q[:, i] - r).max() for i, r in q_ref.items()]
    return float(max(errs + [np.abs(vel[:, i] - r).max() for i, r in vel_ref.items()]))


def _impact(case: str) -> tuple[float, float]:
    slope, mu = CASES[case]
    if not slope:
        return -DISK["e"] * V, V / DISK["r"]
    return slope_impact(mu, 0.7)[:2]


@pytest.mark.parametrize("rule", RULES)
@pytest.mark.parametrize("backend", BACKENDS)
@pytest.mark.parametrize("case", sorted(CASES))
def test_the_run_is_the_closed_form(case: str, backend: str, rule: str) -> None:
    """``x, theta, xd, thetad`` at every grid point are the closed form's (the wall's impact by Coulomb's law
    on the held floor, then slipping under ``mu m g`` until it rolls again), the disk never leaves the floor;
    the impact's impulse is the wall's ``P`` (``m (1 + e) V`` on the vertical wall: none from the floor)."""
    slope, mu = CASES[case]
    res = run(slope, backend, rule, mu=mu)
    (im,) = res.impacts
    vx, om = _impact(case)
    x, th, xd, thd = closed_form(res.t, vx, om, mu)
    vel = res.p / np.array([DISK["m"], DISK["m"], DISK["I"]])
    err = max_error(res.q, vel, {0: x, 2: th}, {0: xd, 2: thd})
    print(f"{case} ({backend}, {rule}): closed form {err:.1e}")
    assert err <= TOL, err
    assert np.abs(res.q[:, 1] - DISK["r"]).max() <= 1e-14 and res.active[:, 0].all() and res.liftoffs == []
    assert im.contact == "wall" and im.kind == "restitution" and abs(im.t - X_HIT / V) <= 1e-14
    wall = slope_impact(mu, 0.7)[2] if slope else DISK["m"] * (1 + DISK["e"]) * V
    assert abs(im.impulse - wall) <= 1e-12 * wall
    if case != "slope_stick":  # it rolls again (the closed form's t_roll inside the run), backwards
        assert vel[-1, 0] < 0 and abs(vel[-1, 0] - DISK["r"] * vel[-1, 2]) <= 1e-13
        assert vel[im.step + 1, 0] - DISK["r"] * vel[im.step + 1, 2] < -0.5  # slipping after the impact


@pytest.mark.parametrize("backend", BACKENDS)
def test_the_vertical_wall_keeps_the_spin(backend: str) -> None:
    """The bug this law fixes: the stick row was held like a bilateral row, so the disk left the wall rolling
    backwards (``thetad = -e V``, a tangential impulse with no normal one). Now the spin is kept through the
    impact: at the first grid point after it, ``thetad`` has only lost ``r mu m g / I`` over the rest of the
    step, and the energy is the wall's loss ``(1 - e^2) m V^2 / 2`` less the friction work, never more."""
    res = run(False, backend, t_end=0.2)
    (im,) = res.impacts
    after = res.p[im.step + 1, 2] / DISK["I"]
    rest = res.t[im.step + 1] - im.t
    assert abs(after - (V - DISK["r"] * DISK["mu"] * G / DISK["I"] * rest)) <= 1e-13
    assert after > 0.9 * V  # the old law gave -e V
    lost = 0.5 * DISK["m"] * V**2 * (1 - DISK["e"] ** 2)
    assert abs((im.energy_before - im.energy_after) - lost) <= 1e-12


@needs_c
@pytest.mark.parametrize("rule", RULES)
@pytest.mark.parametrize("case", sorted(CASES))
def test_c_equals_casadi(case: str, rule: str) -> None:
    """The C stepper's run is the CasADi one's: the same impacts and modes, states to round-off."""
    slope, mu = CASES[case]
    a, b = (run(slope, backend, rule, mu=mu) for backend in ("casadi", "c"))
    assert held_mode(a) == held_mode(b)
    np.testing.assert_allclose(b.q, a.q, rtol=0, atol=1e-13)
    np.testing.assert_allclose(b.p, a.p, rtol=0, atol=1e-13)


@pytest.mark.parametrize("backend", BACKENDS)
@pytest.mark.parametrize("case", ["vertical", "slope_slip"])
def test_a_slip_at_the_impact_breaks_the_tangent(case: str, backend: str) -> None:
    """The stick row slipping at the impact is a mode change of the contact (stick -> slip): the tangent
    breaks there with its reason, finite before, on both backends (rolling again later is a second one)."""
    slope, mu = CASES[case]
    res = run(slope, backend, mu=mu, sensitivities=True)
    (im,) = res.impacts
    assert assert_lost(res, "friction switch in a held step") == im.step
    assert res.sensitivity_breaks[0] == (im.step, "friction switch in a held step")


def _rolling(i: int | None = None, eps: float = 0.0, par: str | None = None):
    q, v = [0.0, 1.0, 0.0], [V, 0.0, V]
    if i in (0, 2):
        q[i] += eps
    elif i is not None:  # along the rolling: xd and thetad together
        v = [V + eps, 0.0, V + eps]
    base = dict(DISK) | {"mu": 0.5, "b": 0.7, "W": DISK["r"] * (1 + math.sin(0.7)) + X_HIT * math.cos(0.7)}
    return q, v, ({par: base[par] + eps} if par else {})


# the stick holding within the cone at the sloped wall (mu = 0.5): the tangent through the impact while held
FD_SCENES = {
    "slope_stick": (
        lambda: disk(0.7),
        *_rolling()[:2],
        H,
        0.4,
        {"mu": 0.5},
        {
            **{name: (lambda e, i=i: _rolling(i, e)) for name, i in (("q0[x]", 0), ("q0[th]", 2), ("v0", 3))},
            **{name: (lambda e, p=name: _rolling(None, e, p)) for name in ("m", "I", "e", "W", "b")},
        },
    )
}


@pytest.mark.parametrize("rule", RULES)
@pytest.mark.parametrize("backend", BACKENDS)
def test_a_stick_within_the_cone_keeps_the_tangent(backend: str, rule: str) -> None:
    """The stick that holds at the impact (the floor's normal impulse ``P sin b`` gives the room): the
    tangent through the impact while held (``Tracker.impulse``) against central differences of whole runs, no
    break."""
    res, per = held_finite_differences(simulator(True, backend, rule), "slope_stick", scenes=FD_SCENES)
    (im,) = res.impacts
    assert im.contact == "wall" and res.active[:, 0].all()
    assert res.sensitivity_breaks == [] and np.isfinite(res.sensitivity).all()
    errs = {label: relative_error(exact, fd) for label, (exact, fd) in per.items()}
    worst = max(errs, key=errs.get)
    print(f"slope_stick ({backend}, {rule}): worst {worst} {errs[worst]:.1e}")
    assert errs[worst] <= 1e-6, errs
    mu = res.sensitivity_names.index("mu")  # the stick holds: mu moves nothing (its tangent exactly 0)
    assert np.all(res.sensitivity[:, :, mu] == 0.0)


def ball_wall() -> vcigen.Model:
    """A ball (centre ``x, y, z``, rotation angles ``ax, ay``) on a rough floor with an isotropic cone (two
    tangents ``x - r ay``, ``y + r ax``) rolling into the smooth wall ``x <= W - r``."""
    x, y, z, ax, ay = sp.symbols("x y z ax ay")
    xd, yd, zd, axd, ayd = sp.symbols("xd yd zd axd ayd")
    return vcigen.Model(
        name="ilf_ball_wall",
        q=[x, y, z, ax, ay],
        qdot=[xd, yd, zd, axd, ayd],
        lagrangian=(xd**2 + yd**2 + zd**2) / 2 + sp.Rational(2, 5) / 2 * (axd**2 + ayd**2) - G * z,
        contacts={"floor": z - 1, "wall": 1 + X_HIT - x - 1},
        params={},
        restitution={"wall": 0.8},
        friction={"floor": (0.2, (x - ay, y + ax))},
    )


@pytest.mark.parametrize("backend", BACKENDS)
def test_an_isotropic_cone_out_of_its_cone_at_an_impact_slips(backend: str) -> None:
    """Once the documented limit (a held isotropic cone could only stick at an impact: its stick impulse out
    of the cone was a ``SolverError``): the ball rolling into the wall now slips at its cone's edge
    (``tests/test_impulse_law_cone.py``), here with the floor's normal impulse 0, so no friction impulse: it
    leaves at ``xd = -e V`` with its spin, the impact's loss ``m V^2 (1 - e^2) / 2``, and slips on the floor
    (before: the SolverError; before that: it rolled back), on both backends."""
    sim = vcigen.build(ball_wall(), backend=backend)
    res = sim.simulate([0.0, 0.0, 1.0, 0.0, 0.0], [V, 0.0, 0.0, 0.0, V], H, t_end=0.4, progress=False)
    (im,) = res.impacts
    assert im.contact == "wall" and abs(im.t - X_HIT / V) <= 1e-13
    assert abs((im.energy_before - im.energy_after) - 0.5 * V * V * (1 - 0.8**2)) <= 1e-12
    v = res.v[im.step + 1]
    assert v[0] - v[4] < -1.0 and abs(v[1] + v[3]) <= 1e-15  # slipping backwards along x
    assert res.active[:, 0].all()
