"""A held contact *slipping* at an impact while held takes Coulomb's sliding impulse
(``SustainedSteps._impulse_law`` with ``_law_slips``, C ``impulse_law`` with ``law_slips`` in
``templates/sustained_impacts.c.j2``; MATH.md *Sustained contact*, *Friction*).

Its normal impulse ``Lam_n > 0`` in the impact comes with ``Lam_t = -mu Lam_n sign(s)`` along its slip ``s``
while the slip after is not reversed; if that impulse would stop or reverse it, the contact sticks within its
cone (``s+ = 0``, ``|Lam_t| <= mu Lam_n``). Before this law the slipping contact took its normal impulse only
(frictionless during the impact).

**Disk into a sloped wall** (the scene of ``test_impulse_law_friction.py``: ``m = 1, I = 0.5, r = 1``, floor
``y >= r`` with ``mu = 0.2`` on the tangent ``x - r theta``, smooth wall ``W - r - x cos b - y sin b >= 0``,
``b = 0.7``, ``e = 0.8``, hit at ``x = X_HIT = 0.16``), thrown at ``xd = V = 1.05`` with backspin ``thetad =
w0``: the slip ``s = xd - r thetad > 0``, so ``xd' = -mu g``, ``thetad' = r mu m g / I`` until the wall at
``t* = (V - sqrt(V^2 - 2 mu g X_HIT)) / (mu g)``, with ``xd-, thetad-`` there. The floor holds ``yd+ = 0``, so
its normal impulse is ``N = P sin b`` (``P`` the wall's), and the wall makes ``xd+ = -e xd-``:

* slipping on (``w0 = -3``): ``Lam_t = -mu N``, ``P (cos b + mu sin b) = m (1 + e) xd-``, ``thetad+ = thetad-
  + r mu N / I``; valid while ``s+ = -e xd- - r thetad+ > 0``. Frictionless (before): ``P = m (1 + e) xd- /
  cos b``, ``thetad+ = thetad-``.
* sticking (``w0 = -1.3``): the sliding impulse would reverse ``s``; ``thetad+ = -e xd- / r``, ``Lam_t = -I
  (thetad+ - thetad-) / r``, ``P cos b = m (1 + e) xd- + Lam_t``, ``|Lam_t| <= mu P sin b``.
* slipping the other way (``w0 = -0.2``, a small forward slip ``s- = 0.17`` at the wall): the sliding impulse
  would reverse it and the stick impulse leaves the cone, so it slips at the other edge, ``Lam_t = +mu N``,
  ``P (cos b - mu sin b) = m (1 + e) xd-`` (the law's third mode), ``s+ < 0``.

After the impact: slipping under ``mu m g`` until ``s = 0`` (``s' = -mu g (1 + m r^2 / I)``), rolling on.

**Box on a face, hit by a puck on a slanted face** (``M = 1``, half sides ``a = 0.5, b = 0.25``, the two
bottom vertices on the rough floor, ``mu = 0.3``, one tangent each: dependent sticks or slips; a puck ``m =
0.5`` with no gravity hits the box's face of normal ``n = (-sin c, cos c)``, ``c = 0.6``, elastically). The
floor holds ``y``, ``theta``: ``N = P cos c`` in all, the box gets ``P sin c`` along ``x`` and the friction
``F``:

* at rest, sticking (one vertex's stick row, the other dependent on it): ``tan c > mu``, so it slips in the
  impact, ``F = -mu N`` (the pooled cone of both vertices; the slip branch of a stick row carrying dependent
  sticks);
* sliding at ``V0 = 0.8`` (both vertices slipping, ``xd' = -mu g``): slips on, ``F = -mu N`` (both slipping
  vertices pooled);

``P = -(1 + e) v_rel / (1 / m + sin c (sin c - mu cos c) / M)``, ``v_rel = n.v_puck + sin c xd-``, ``xd+ = xd-
+ P (sin c - mu cos c) / M``, the puck ``v+ = v + P n / m``; then the box slides to rest at ``mu g``. The
discrete map is exact on all of these (constant accelerations, located impact and stop): every grid point on
the closed form to 1e-13, both backends, trapezoid and midpoint.
"""

from __future__ import annotations

import math
from functools import cache

import hard_scenes
import numpy as np
import pytest
import sympy as sp
from test_impulse_law_friction import DISK, X_HIT, max_error, simulator
from test_sensitivity import BACKENDS, assert_lost, held_finite_differences, held_mode, relative_error

import vcigen

G = 9.81
H = 0.01
RULES = ("trapezoid", "midpoint")
TOL = 1e-13
needs_c = pytest.mark.skipif(
    hard_scenes.c_backend_problem() is not None, reason=str(hard_scenes.c_backend_problem())
)
V = 1.05
SLOPE = 0.7  # the wall of test_impulse_law_friction.disk(0.7)
MU = 0.2
# case -> backspin thetad(0)
DISK_CASES = {"slip_on": -3.0, "slip_stops": -1.3, "slip_reverses": -0.2}
# case -> the mode of the closed form's impact
DISK_MODES = {"slip_on": "slip", "slip_stops": "stick", "slip_reverses": "reverse"}


def disk_impact(w0: float) -> dict[str, float]:
    """The disk's impact by the closed form of the module docstring: ``t*``, ``xd-, thetad-``, the mode,
    ``P``, ``Lam_t``, ``xd+, thetad+``."""
    m, inertia, r, e = DISK["m"], DISK["I"], DISK["r"], DISK["e"]
    a = MU * G
    ts = (V - math.sqrt(V * V - 2 * a * X_HIT)) / a
    xd, om = V - a * ts, w0 + r * MU * m * G / inertia * ts
    assert xd - r * om > 0  # slipping forwards up to the wall
    c, s = math.cos(SLOPE), math.sin(SLOPE)
    p = m * (1 + e) * xd / (c + MU * s)
    lam_t = -MU * p * s
    om_p = om - r * lam_t / inertia
    mode = "slip"
    if -e * xd - r * om_p <= 0:  # the sliding impulse would reverse the slip: it sticks within its cone
        om_p = -e * xd / r
        lam_t = -inertia * (om_p - om) / r
        p = (m * (1 + e) * xd + lam_t) / c
        mode = "stick"
        if abs(lam_t) > MU * p * s:  # the cone cannot stop it: it slips the other way, at the other edge
            p = m * (1 + e) * xd / (c - MU * s)
            lam_t = MU * p * s
            om_p = om - r * lam_t / inertia
            mode = "reverse"
            assert -e * xd - r * om_p < 0
    return {"t": ts, "xd": xd, "om": om, "mode": mode, "P": p, "lam_t": lam_t, "xd+": -e * xd, "om+": om_p}


def disk_closed_form(t: np.ndarray, w0: float) -> tuple[np.ndarray, ...]:
    """``(x, theta, xd, thetad)`` at ``t``: slipping to the wall, the impact, slipping until ``s = 0``,
    rolling."""
    m, inertia, r = DISK["m"], DISK["I"], DISK["r"]
    im = disk_impact(w0)
    ts, a, al0 = im["t"], MU * G, r * MU * m * G / inertia
    vx, om = im["xd+"], im["om+"]
    s0 = vx - r * om
    sgn = math.copysign(1.0, s0) if abs(s0) > 1e-12 else 0.0
    ax, al = -sgn * a, sgn * al0
    t_roll = ts + (abs(s0) / (a + r * al0) if sgn else 0.0)
    d = np.clip(t - ts, 0.0, t_roll - ts)
    after = np.clip(t - t_roll, 0.0, None)
    xd_n, om_n = vx + ax * d, om + al * d
    th_s = w0 * ts + al0 * ts * ts / 2
    before = t <= ts
    tb = np.where(before, t, 0.0)
    return (
        np.where(before, V * tb - a * tb * tb / 2, X_HIT + vx * d + ax * d * d / 2 + xd_n * after),
        np.where(before, w0 * tb + al0 * tb * tb / 2, th_s + om * d + al * d * d / 2 + om_n * after),
        np.where(before, V - a * tb, xd_n),
        np.where(before, w0 + al0 * tb, om_n),
    )


def run_disk(case: str, backend: str, rule: str = "trapezoid", **kw) -> vcigen.Result:
    sim = simulator(True, backend, rule)
    v0 = [V, 0.0, DISK_CASES[case]]
    return sim.simulate([0.0, 1.0, 0.0], v0, H, t_end=0.8, params={"mu": MU}, progress=False, **kw)


@pytest.mark.parametrize("rule", RULES)
@pytest.mark.parametrize("backend", BACKENDS)
@pytest.mark.parametrize("case", sorted(DISK_CASES))
def test_the_disk_run_is_the_closed_form(case: str, backend: str, rule: str) -> None:
    """``x, theta, xd, thetad`` at every grid point are the closed form's; the wall's impulse is ``P`` (not
    the frictionless ``m (1 + e) xd- / cos b``); the disk stays on the floor; right after the impact it slips
    on forwards (``slip_on``), rolls (``slip_stops``) or slips backwards (``slip_reverses``); the impact's
    energy loss is the kinetic energy the closed form loses (wall and floor friction)."""
    res = run_disk(case, backend, rule)
    im_cf = disk_impact(DISK_CASES[case])
    assert im_cf["mode"] == DISK_MODES[case]
    (im,) = res.impacts
    x, th, xd, thd = disk_closed_form(res.t, DISK_CASES[case])
    vel = res.v
    err = max_error(res.q, vel, {0: x, 2: th}, {0: xd, 2: thd})
    print(f"{case} ({backend}, {rule}): closed form {err:.1e}")
    assert err <= TOL, err
    assert np.abs(res.q[:, 1] - DISK["r"]).max() <= 1e-14 and res.active[:, 0].all() and res.liftoffs == []
    assert im.contact == "wall" and im.kind == "restitution" and abs(im.t - im_cf["t"]) <= 1e-13
    assert abs(im.impulse - im_cf["P"]) <= 1e-12 * im_cf["P"]
    frictionless = DISK["m"] * (1 + DISK["e"]) * im_cf["xd"] / math.cos(SLOPE)
    assert abs(im.impulse - frictionless) > 1e-3  # what the law gave before
    m, inertia = DISK["m"], DISK["I"]
    lost = 0.5 * m * (im_cf["xd"] ** 2 - im_cf["xd+"] ** 2)
    lost += 0.5 * inertia * (im_cf["om"] ** 2 - im_cf["om+"] ** 2)
    assert abs((im.energy_before - im.energy_after) - lost) <= 1e-12
    slip_after = vel[im.step + 1, 0] - DISK["r"] * vel[im.step + 1, 2]
    if case == "slip_on":
        assert slip_after > 0.5
    elif case == "slip_reverses":
        assert slip_after < -0.5
    else:
        assert abs(slip_after) <= 1e-13


@needs_c
@pytest.mark.parametrize("rule", RULES)
@pytest.mark.parametrize("case", sorted(DISK_CASES))
def test_c_equals_casadi(case: str, rule: str) -> None:
    """The C stepper's run is the CasADi one's: the same impacts and modes, states to round-off."""
    a, b = (run_disk(case, backend, rule) for backend in ("casadi", "c"))
    assert held_mode(a) == held_mode(b)
    np.testing.assert_allclose(b.q, a.q, rtol=0, atol=1e-13)
    np.testing.assert_allclose(b.p, a.p, rtol=0, atol=1e-13)


@pytest.mark.parametrize("backend", BACKENDS)
@pytest.mark.parametrize("case", ["slip_stops", "slip_reverses"])
def test_the_tangent_breaks_where_the_slip_stops(case: str, backend: str) -> None:
    """Where the sliding impulse would reverse the slip the contact sticks at the impact, or slips the other
    way: a mode change, the step breaks with ``"friction switch in a held step"``, finite before, on both
    backends."""
    res = run_disk(case, backend, sensitivities=True)
    (im,) = res.impacts
    assert assert_lost(res, "friction switch in a held step") == im.step
    assert res.sensitivity_breaks[0] == (im.step, "friction switch in a held step")


def _slipping(i: int | None = None, eps: float = 0.0, par: str | None = None):
    q, v = [0.0, 1.0, 0.0], [V, 0.0, DISK_CASES["slip_on"]]
    if i is not None:
        (q if i < 3 else v)[i % 3] += eps
    base = dict(DISK) | {
        "mu": MU,
        "b": SLOPE,
        "W": DISK["r"] * (1 + math.sin(SLOPE)) + X_HIT * math.cos(SLOPE),
    }
    return q, v, ({par: base[par] + eps} if par else {})


# the disk slipping on through the impact (to t = 0.3, before it rolls again): the tangent through the sliding
# impulse (Tracker.impulse with slides)
FD_SCENES = {
    "slip_on": (
        lambda: None,
        *_slipping()[:2],
        H,
        0.3,
        {"mu": MU},
        {
            **{
                name: (lambda e, i=i: _slipping(i, e))
                for name, i in (("q0[x]", 0), ("v0[x]", 3), ("v0[th]", 5))
            },
            **{name: (lambda e, p=name: _slipping(None, e, p)) for name in ("m", "I", "e", "W", "b", "mu")},
        },
    )
}


@pytest.mark.parametrize("rule", RULES)
@pytest.mark.parametrize("backend", BACKENDS)
def test_the_tangent_through_the_sliding_impulse(backend: str, rule: str) -> None:
    """The contact slipping on through the impact: the tangent carries its sliding impulse (``d = g_n + sgn
    mu g_t`` on its normal row, ``mu`` moving with its parameter) against central differences of whole runs,
    no break; its column in ``mu`` is not 0 (the impulse moves with it)."""
    res, per = held_finite_differences(simulator(True, backend, rule), "slip_on", scenes=FD_SCENES)
    (im,) = res.impacts
    assert im.contact == "wall" and res.active[:, 0].all()
    assert res.sensitivity_breaks == [] and np.isfinite(res.sensitivity).all()
    errs = {label: relative_error(exact, fd) for label, (exact, fd) in per.items()}
    worst = max(errs, key=errs.get)
    print(f"slip_on ({backend}, {rule}): worst {worst} {errs[worst]:.1e}")
    assert errs[worst] <= 1e-6, errs
    mu = res.sensitivity_names.index("mu")
    assert np.abs(res.sensitivity[im.step + 1 :, :, mu]).max() > 1e-3


# -- a box on a face (two vertices, one tangent each: dependent sticks or slips), hit by a puck -------------
BOX = {"M": 1.0, "a": 0.5, "b": 0.25, "m": 0.5, "mu": 0.3, "c": 0.6, "e": 1.0}
PUCK0, PUCK_V, T_HIT = (-1.0, 1.0), (1.0, -0.5), 0.123
BOX_CASES = {"rest": 0.0, "sliding": 0.8}  # the box's xd(0)


def box_model() -> vcigen.Model:
    """The box ``(x, y, theta)`` on the rough floor (vertices ``left``, ``right``) and the puck ``(u, w)`` (no
    gravity) on its face ``n.((u, w) - (x, y)) - d >= 0``, ``n = (-sin c, cos c)``."""
    x, y, th, u, w = sp.symbols("x y th u w")
    xd, yd, thd, ud, wd = sp.symbols("xd yd thd ud wd")
    mu, d = sp.symbols("mu d")
    big, a, b, m, c = BOX["M"], BOX["a"], BOX["b"], BOX["m"], BOX["c"]
    inertia = big * (a * a + b * b) / 3
    return vcigen.Model(
        name="ils_box",
        q=[x, y, th, u, w],
        qdot=[xd, yd, thd, ud, wd],
        lagrangian=big / 2 * (xd**2 + yd**2) + inertia / 2 * thd**2 - big * G * y + m / 2 * (ud**2 + wd**2),
        contacts={
            "left": y - a * sp.sin(th) - b * sp.cos(th),
            "right": y + a * sp.sin(th) - b * sp.cos(th),
            "face": -math.sin(c) * (u - x) + math.cos(c) * (w - y) - d,
        },
        params={mu: BOX["mu"], d: 0.0},
        friction={
            "left": (mu, x - a * sp.cos(th) + b * sp.sin(th)),
            "right": (mu, x + a * sp.cos(th) + b * sp.sin(th)),
        },
        restitution={"face": BOX["e"]},
    )


@cache
def box_simulator(backend: str, rule: str) -> vcigen.Simulator:
    return vcigen.build(box_model(), backend=backend, rule=rule)


def box_closed_form(t: np.ndarray, v0: float) -> tuple[dict[str, float], tuple[np.ndarray, ...]]:
    """The impact (``d`` placing it at ``T_HIT``, ``P``, ``xd-``, ``xd+``) and ``(x, xd, u, w, ud, wd)`` at
    ``t`` (module docstring)."""
    big, m, mu, e, b = BOX["M"], BOX["m"], BOX["mu"], BOX["e"], BOX["b"]
    s, c = math.sin(BOX["c"]), math.cos(BOX["c"])
    n = np.array([-s, c])
    a = mu * G
    x_hit, xd_m = v0 * T_HIT - a * T_HIT**2 / 2 * (v0 > 0), v0 - a * T_HIT * (v0 > 0)
    d = float(n @ (np.array(PUCK0) + np.array(PUCK_V) * T_HIT) - n @ np.array([x_hit, b]))
    assert math.tan(BOX["c"]) > mu  # at rest: the stick would leave the cone
    v_rel = float(n @ np.array(PUCK_V)) + s * xd_m
    p = -(1 + e) * v_rel / (1 / m + s * (s - mu * c) / big)
    xd_p = xd_m + p * (s - mu * c) / big
    puck_p = np.array(PUCK_V) + p * n / m
    assert xd_p > 0 and puck_p @ n > 0  # slips forwards after; the puck never comes back
    t_stop = T_HIT + xd_p / a
    before = t <= T_HIT
    tb = np.where(before, t, 0.0)
    dd = np.clip(t - T_HIT, 0.0, t_stop - T_HIT)
    ta = np.clip(t - T_HIT, 0.0, None)
    moving = float(v0 > 0)
    hit = np.array(PUCK0) + np.array(PUCK_V) * T_HIT
    out = (
        np.where(before, v0 * tb - moving * a * tb * tb / 2, x_hit + xd_p * dd - a * dd * dd / 2),
        np.where(before, v0 - moving * a * tb, xd_p - a * dd),
        np.where(before, PUCK0[0] + PUCK_V[0] * tb, hit[0] + puck_p[0] * ta),
        np.where(before, PUCK0[1] + PUCK_V[1] * tb, hit[1] + puck_p[1] * ta),
        np.where(before, PUCK_V[0], puck_p[0]),
        np.where(before, PUCK_V[1], puck_p[1]),
    )
    return {"d": d, "P": p, "xd": xd_m, "xd+": xd_p, "stop": t_stop}, out


def run_box(case: str, backend: str, rule: str = "trapezoid", **kw) -> vcigen.Result:
    v0 = BOX_CASES[case]
    im, _ = box_closed_form(np.zeros(1), v0)
    sim = box_simulator(backend, rule)
    q0, u0 = [0.0, BOX["b"], 0.0, *PUCK0], [v0, 0.0, 0.0, *PUCK_V]
    return sim.simulate(q0, u0, H, t_end=0.5, params={"d": im["d"]}, progress=False, **kw)


@pytest.mark.parametrize("rule", RULES)
@pytest.mark.parametrize("backend", BACKENDS)
@pytest.mark.parametrize("case", sorted(BOX_CASES))
def test_the_box_run_is_the_closed_form(case: str, backend: str, rule: str) -> None:
    """The box (at rest: a stick row carrying a dependent stick slips in the impact; sliding: two slipping
    vertices pooled) and the puck at every grid point on the closed form; the box stays flat on both vertices
    (``y = b``, ``theta = 0``) and comes to rest at ``x_hit + xd+^2 / (2 mu g)``; one elastic impact of
    impulse ``P``."""
    res = run_box(case, backend, rule)
    im_cf, (x, xd, u, w, ud, wd) = box_closed_form(res.t, BOX_CASES[case])
    (im,) = res.impacts
    vel = res.v
    err = max_error(res.q, vel, {0: x, 3: u, 4: w}, {0: xd, 3: ud, 4: wd})
    print(f"box {case} ({backend}, {rule}): closed form {err:.1e}")
    assert err <= TOL, err
    assert np.abs(res.q[:, 1] - BOX["b"]).max() <= 1e-14 and np.abs(res.q[:, 2]).max() <= 1e-14
    assert res.active[:, :2].all() and res.liftoffs == []
    assert im.contact == "face" and im.kind == "elastic" and abs(im.t - T_HIT) <= 1e-13
    assert abs(im.impulse - im_cf["P"]) <= 1e-12 * im_cf["P"]
    assert res.t[-1] > im_cf["stop"] and abs(vel[-1, 0]) <= 1e-14  # at rest again


@needs_c
@pytest.mark.parametrize("case", sorted(BOX_CASES))
def test_the_box_c_equals_casadi(case: str) -> None:
    """The C stepper's box run is the CasADi one's: the same impacts and modes, states to round-off."""
    a, b = (run_box(case, backend) for backend in ("casadi", "c"))
    assert held_mode(a) == held_mode(b)
    np.testing.assert_allclose(b.q, a.q, rtol=0, atol=1e-13)
    np.testing.assert_allclose(b.p, a.p, rtol=0, atol=1e-13)


@pytest.mark.parametrize("backend", BACKENDS)
@pytest.mark.parametrize("case", ["rest"])
def test_the_box_tangent_breaks_at_the_impact(case: str, backend: str) -> None:
    """At rest the stick -> slip in the impact is a mode change: the step breaks with ``"friction switch in a
    held step"``, finite before, on both backends."""
    res = run_box(case, backend, sensitivities=True)
    (im,) = res.impacts
    assert assert_lost(res, "friction switch in a held step") == im.step


def _box_path(i: int | None = None, eps: float = 0.0, par: str | None = None):
    im, _ = box_closed_form(np.zeros(1), BOX_CASES["sliding"])
    q, v = [0.0, BOX["b"], 0.0, *PUCK0], [BOX_CASES["sliding"], 0.0, 0.0, *PUCK_V]
    if i is not None:
        (q if i < 5 else v)[i % 5] += eps
    base = {"mu": BOX["mu"], "d": im["d"]}
    return q, v, {"d": base["d"]} | ({par: base[par] + eps} if par else {})


# the box sliding on both vertices through the puck's impact (to t = 0.3, before it stops)
BOX_PATHS = (("q0[x]", 0), ("v0[x]", 5), ("v0[u]", 8))
BOX_FD = {
    "sliding": (
        lambda: None,
        *_box_path()[:2],
        H,
        0.3,
        {"d": _box_path()[2]["d"]},
        {
            **{name: (lambda e, i=i: _box_path(i, e)) for name, i in (BOX_PATHS)},
            **{name: (lambda e, p=name: _box_path(None, e, p)) for name in ("mu", "d")},
        },
    )
}


@pytest.mark.parametrize("backend", BACKENDS)
def test_the_box_tangent_through_the_pooled_sliding_impulse(backend: str) -> None:
    """The box sliding on both vertices (the second's cone pooled on the first's stick row): the tangent
    through the impact carries both vertices' sliding impulses (``d = g_n + sgn mu g_t`` of the owner's
    tangent on each vertex's normal row) against central differences of whole runs, no break."""
    res, per = held_finite_differences(box_simulator(backend, "trapezoid"), "sliding", scenes=BOX_FD)
    (im,) = res.impacts
    assert im.contact == "face" and res.active[:, :2].all()
    assert res.sensitivity_breaks == [] and np.isfinite(res.sensitivity).all()
    errs = {label: relative_error(exact, fd) for label, (exact, fd) in per.items()}
    worst = max(errs, key=errs.get)
    print(f"box sliding ({backend}): worst {worst} {errs[worst]:.1e}")
    assert errs[worst] <= 1e-6, errs
