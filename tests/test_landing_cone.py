"""An isotropic cone at a plastic landing from flight: Coulomb's impulse law at the landing (MATH.md
*Friction*; ``ImpulseLaw._law_lands`` with ``_law_slide``, C ``law_lands``, ``law_slide``).

The ball of ``tests/test_friction_3d.py`` (``m = 1, I = 0.4, r = 1``, ``mu = 0.3``, two tangents ``x - r ay``,
``y + r ax``) with ``e = 0``, dropped from ``z = 2`` at ``(vx, vy) = (2, -1)`` with a spin: it lands at
``t* = sqrt(2/g)`` with the normal impulse ``P = m sqrt(2 g)`` and the tangential one of Coulomb's law (the
cone's normal impulse is not coupled to it: the sliding after is along the sliding before). Spin ``(1, 4)``:
the stick impulse is inside the cone, it rolls from the landing on at the constant ``v1, w1``. Spin ``(3,
-20)``: it slides through the landing (``P_t = -mu P u/|u|``) and on, its sliding ``u`` shrinking along a
fixed direction at ``mu g (1 + m r^2/I)`` while the centre decelerates at ``mu g`` along it, until it rolls.
Before this contract the landing kept the tangential momentum (``v1 = (2, -1)``). The tangent through the
sliding landing (stop 28; before it a break, ``"friction at an impact"``) and the rolling one against central
differences.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from hard_scenes import BACKENDS
from test_friction_3d import BALL_MU, INERTIA, MASS, RADIUS, G, coulomb_ball, sim

import vcigen

V0, Z0, H = np.array([2.0, -1.0]), 2.0, 0.01


def closed_form(t: np.ndarray, spin) -> tuple[np.ndarray, np.ndarray, float, bool]:
    """The ball's ``(vx, vy)`` and spin ``(wx, wy)`` at the times ``t`` after its landing at ``t*``."""
    ts = math.sqrt(2 * (Z0 - RADIUS) / G)
    v1, w1, rolls = coulomb_ball(np.array([*V0, -G * ts]), np.array(spin), rest=0.0)
    u1 = np.array([v1[0] - RADIUS * w1[1], v1[1] + RADIUS * w1[0]])
    d = np.clip(t - ts, 0.0, None)[:, None]
    if not rolls:  # sliding on: the friction force -mu m g u/|u| until u = 0
        d = np.minimum(d, math.hypot(*u1) / (BALL_MU * G * (1 + MASS * RADIUS**2 / INERTIA)))
    force = np.zeros(2) if rolls else -BALL_MU * MASS * G * u1 / math.hypot(*u1)
    v = v1[:2] + force / MASS * d
    w = w1 + RADIUS / INERTIA * np.array([force[1], -force[0]]) * d
    return v, w, ts, rolls


@pytest.mark.parametrize("spin, rolls", [((1.0, 4.0), True), ((3.0, -20.0), False)])
@pytest.mark.parametrize("backend", BACKENDS)
def test_a_plastic_landing_takes_coulombs_cone(backend: str, spin, rolls: bool) -> None:
    """One plastic landing at ``t*`` with the normal impulse ``m sqrt(2 g)``; from the grid point after it
    the velocity and spin on the closed form to 1e-12 (rolling, or sliding then rolling); held throughout.
    The tangent is carried through both (no break; a sliding landing's impulse turns with the velocity after
    it: ``Tracker._cone_slides``, C ``sens_cone_slides``)."""
    res = sim("ball", backend).simulate(
        q0=[0.0, 0.0, Z0, 0.0, 0.0],
        v0=[*V0, 0.0, *spin],
        h=H,
        t_end=0.9,
        params={"e": 0.0},
        sensitivities=True,
        progress=False,
    )
    v, w, ts, roll = closed_form(res.t, spin)
    assert roll == rolls
    (im,) = res.impacts
    assert im.kind == "plastic" and abs(im.t - ts) <= 1e-12
    assert abs(im.impulse - MASS * G * ts) <= 1e-12
    after = slice(im.step + 1, None)
    err = max(
        float(np.abs(res.p[after, :2] / MASS - v[after]).max()),
        float(np.abs(res.p[after, 3:] / INERTIA - w[after]).max()),
    )
    print(f"{backend} spin {spin}: {'rolls' if rolls else 'slides'}, max error {err:.1e}")
    assert err <= 1e-12
    assert res.active[after, 0].all()
    assert res.sensitivity_breaks == []


@pytest.mark.parametrize("backend", BACKENDS)
def test_the_rolling_landings_tangent_against_central_differences(backend: str) -> None:
    """The tangent carried through the sticking landing (spin ``(1, 4)``): the end state's derivatives in
    ``q0[z]`` (the landing time), ``v0[x]``, ``v0[y]``, ``v0[ax]``, ``v0[ay]`` against central differences of
    whole runs (eps 1e-6) to 1e-6 of the largest entry; the run's own paths keep the mode (it rolls)."""
    sim_ = sim("ball", backend)
    kw = {"h": H, "t_end": 0.9, "params": {"e": 0.0}, "progress": False}
    q0, v0 = [0.0, 0.0, Z0, 0.0, 0.0], [*V0, 0.0, 1.0, 4.0]
    res = sim_.simulate(q0=q0, v0=v0, sensitivities=True, **kw)
    assert res.sensitivity_breaks == []

    def end(name: str, e: float) -> np.ndarray:
        q, v = list(q0), list(v0)
        (q if name[0] == "q" else v)[["x", "y", "z", "ax", "ay"].index(name[3:-1])] += e
        r = sim_.simulate(q0=q, v0=v, **kw)
        return np.concatenate([r.q[-1], r.p[-1]])

    worst = 0.0
    for name in ("q0[z]", "v0[x]", "v0[y]", "v0[ax]", "v0[ay]"):
        fd = (end(name, 1e-6) - end(name, -1e-6)) / 2e-6
        exact = res.sensitivity[-1, :, res.sensitivity_names.index(name)]
        worst = max(worst, float(np.abs(fd - exact).max() / max(1.0, np.abs(exact).max())))
    print(f"{backend}: rolling landing's tangent vs central differences {worst:.1e}")
    assert worst <= 1e-6


NAMES = ("q0[z]", "v0[x]", "v0[y]", "v0[ax]", "v0[ay]", "mu", "m")
SLIDES = [*V0, 0.0, 3.0, -20.0]  # v0 of the landing that slides


def sliding_tangent(backend: str, t_end: float, eps: float) -> tuple[float, float | None, vcigen.Result]:
    """The run that lands sliding (``SLIDES``) to ``t_end`` with its tangent: ``(worst, gap, res)``, ``worst``
    the tangent's error against central differences of whole runs (``eps``; each with the same landing) over
    ``NAMES`` relative to the largest entry, ``gap`` C's tangent against CasADi's (None on CasADi)."""
    kw = {"h": H, "t_end": t_end, "progress": False}
    q0 = [0.0, 0.0, Z0, 0.0, 0.0]
    sim_ = sim("ball", backend)
    res = sim_.simulate(q0=q0, v0=SLIDES, sensitivities=True, params={"e": 0.0}, **kw)
    (im,) = res.impacts
    assert im.kind == "plastic" and res.sensitivity_breaks == []

    def end(name: str, e: float) -> np.ndarray:
        q, v, par = list(q0), list(SLIDES), {"e": 0.0}
        if name in ("mu", "m"):
            par[name] = {"mu": BALL_MU, "m": MASS}[name] + e
        else:
            (q if name[0] == "q" else v)[["x", "y", "z", "ax", "ay"].index(name[3:-1])] += e
        r = sim_.simulate(q0=q, v0=v, params=par, **kw)
        assert r.impacts[0].step == im.step and r.impacts[0].kind == "plastic"
        return np.concatenate([r.q[-1], r.p[-1]])

    worst = 0.0
    for name in NAMES:
        fd = (end(name, eps) - end(name, -eps)) / (2 * eps)
        exact = res.sensitivity[-1, :, res.sensitivity_names.index(name)]
        worst = max(worst, float(np.abs(fd - exact).max() / max(1.0, np.abs(exact).max())))
    gap = None
    if backend == "c":
        ref = sim("ball", "casadi").simulate(q0=q0, v0=SLIDES, sensitivities=True, params={"e": 0.0}, **kw)
        scale = max(1.0, float(np.abs(ref.sensitivity[-1]).max()))
        gap = float(np.abs(res.sensitivity[-1] - ref.sensitivity[-1]).max()) / scale
    return worst, gap, res


@pytest.mark.parametrize("backend", BACKENDS)
def test_the_sliding_landings_tangent_against_central_differences(backend: str) -> None:
    """The tangent carried through the landing that slides (spin ``(3, -20)``; it slides on to t = 2.14):
    Coulomb's sliding impulse ``-mu P w+/|w+|`` turns with the sliding after it, solved with the impulse's
    tangent. The state at t = 0.9 (a plastic landing at 0.45, sliding since) against central differences of
    whole runs (eps 1e-6) in ``q0[z]`` (the landing time), ``v0``, the spin, ``mu`` and ``m``, to 1e-6 of the
    largest entry; C's tangent against CasADi's to 1e-12 of it."""
    worst, gap, _ = sliding_tangent(backend, 0.9, 1e-6)
    print(f"{backend}: sliding landing's tangent vs central differences {worst:.1e}, C vs CasADi {gap}")
    assert worst <= 1e-6 and (gap is None or gap <= 1e-12)


@pytest.mark.parametrize("spin, rolls", [((1.0, 4.0), True), ((3.0, -20.0), False)])
@pytest.mark.parametrize("backend", BACKENDS)
def test_the_landing_steps_friction_work_is_the_closed_forms(backend: str, spin, rolls: bool) -> None:
    """``res.friction_work`` on the landing's step books the sliding after the landing only: from ``t*`` the
    friction force is ``-mu m g w/|w|`` with ``|w|`` shrinking at ``mu g k`` (``k = 1 + m r^2 / I``), so its
    work to the grid point is ``-mu m g (|w+| tau - mu g k tau^2 / 2)``, ``tau = t_k+1 - t*`` (0 rolling): to
    1e-12 (before stop 28 it booked the step's whole sliding, the flight's before ``t*`` too: -0.4518 for
    -0.4340). The energy balance after the landing is then the method's O(h^2) (ratio >= 3.5 at h/2; before,
    0.0187 and 0.0088 at h = 0.01)."""
    after = []
    for h in (H, H / 2):
        res = sim("ball", backend).simulate(
            q0=[0.0, 0.0, Z0, 0.0, 0.0], v0=[*V0, 0.0, *spin], h=h, t_end=0.9, params={"e": 0.0},
            progress=False,
        )  # fmt: skip
        (im,) = res.impacts
        k = im.step
        v1, w1, roll = coulomb_ball(np.array([*V0, -G * im.t]), np.array(spin), rest=0.0)
        assert roll == rolls
        slide = math.hypot(v1[0] - RADIUS * w1[1], v1[1] + RADIUS * w1[0])
        tau = res.t[k + 1] - im.t
        k_eff = 1 + MASS * RADIUS**2 / INERTIA
        exact = 0.0 if rolls else -BALL_MU * MASS * G * (slide * tau - BALL_MU * G * k_eff * tau**2 / 2)
        print(f"{backend} {spin} h {h}: landing step friction work {res.friction_work[k]:.6f}, {exact:.6f}")
        assert abs(res.friction_work[k] - exact) <= 1e-12
        after.append(abs(res.energy_balance()[k + 2 :]).max())
    print(f"{backend} spin {spin}: energy balance after the landing {after[0]:.2e}, {after[1]:.2e}")
    assert after[0] / after[1] >= 3.5


@pytest.mark.parametrize("backend", BACKENDS)
def test_the_tangent_through_the_cones_stop_against_central_differences(backend: str) -> None:
    """The ball that lands sliding (spin ``(3, -20)``) stops sliding at t = 2.14 and rolls on: the cone's stop
    is a located event the tangent carries (its root ``-slip . w`` along the frozen slip, the slots' tangents
    in it: ``SwitchTangents._cone_stop_root``, C ``sens_cone_stop_root``; before stop 28 a break, ``"friction
    switch in a held step"``). The state at t = 2.5 against central differences of whole runs (eps 1e-5, the
    event's time in them) in ``q0[z]``, ``v0``, the spin, ``mu``, ``m``: to 1e-6 of the largest entry; C's
    tangent against CasADi's to 1e-10 of it."""
    worst, gap, res = sliding_tangent(backend, 2.5, 1e-5)
    v, w = res.p[-1, :2] / MASS, res.p[-1, 3:] / INERTIA
    print(
        f"{backend}: through the cone's stop, tangent vs central differences {worst:.1e}, C vs CasADi {gap}"
    )
    assert math.hypot(v[0] - RADIUS * w[1], v[1] + RADIUS * w[0]) <= 1e-12  # rolling at the end
    assert worst <= 1e-6 and (gap is None or gap <= 1e-10)
