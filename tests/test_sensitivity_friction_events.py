"""Exact sensitivities through events inside a held step while Coulomb friction acts (one tangent, in its
mode: ``vcigen.sensitivity`` ``Tracker.event``, ``impulse``, ``free_end`` with each sub-step's friction slots;
C ``templates/sens_events.c.j2``, ``sens_located``).

* a spinning disk sliding on a rough floor into a frictionless wall (restitution ``e``): an impact while held,
  the floor slipping the same way before and after it;
* a sliding block lifted off the rough floor by a force of time ``A t``: the lift-off of the slipping contact
  (its friction ends with its normal force), then free flight;
* a particle lifted off a smooth floor while a second one, coupled to it through the kinetic energy (an
  off-diagonal mass term ``k x1d y2d``), slips on a rough floor: the lift-off's force law with the slipping
  contact's direction ``grad psi + slip grad t`` (its slip moves the lifted row's force through ``k``);
* a particle landing plastically on a rough floor, sliding through the impact (Coulomb's sliding impulse, the
  landing's friction: ``ImpulseLaw._law_lands``) and on (its friction held anew), and the same landing of a
  second particle while the first is held and slips (a plastic impact while held);
* the disk into the wall slowly enough that its sliding stops in the rest of the impact's step: an impact
  while held, then a located friction stop (``vcigen.sensitivity_switch``) in the same step.

Against central differences of whole runs along paths that keep the mode, on both backends, under the
trapezoidal and the midpoint rules; the disk and the landing against the closed forms of their motion (sliding
deceleration ``mu g`` before and after the impact, the rebound ``-e u``, the fall; the discrete map reproduces
them exactly); the disk stopping after the impact against the closed form of its slide, rebound, stop and
roll; C against CasADi. A friction switch among the events that is not a located stop or slide (the sliding
turned by the impact, or a rolling contact slipping at it) stays a break, the same on both backends.
"""

from __future__ import annotations

from functools import cache

import hard_scenes
import numpy as np
import pytest
import sympy as sp
from test_sensitivity import BACKENDS, assert_lost, held_finite_differences, held_mode, relative_error
from test_sensitivity_c import assert_same_tangent

import vcigen

G = 9.81
FD_TOL = 1e-6  # the tangent against central differences, relative to the largest entry
C_TOL = 1e-9  # C against CasADi, relative
RULES = ("trapezoid", "midpoint")
needs_c = pytest.mark.skipif(
    hard_scenes.c_backend_problem() is not None, reason=str(hard_scenes.c_backend_problem())
)
DISK = {"m": 1.0, "I": 0.5, "r": 1.0, "g": G, "mu": 0.2, "W": 1.16, "e": 0.8}


def disk_wall() -> vcigen.Model:
    """A disk (``x, y, theta``) on the rough floor ``y >= r`` (sliding velocity ``xd - r thetad``) and the
    frictionless wall ``x <= W - r`` with restitution ``e``."""
    x, y, th, xd, yd, thd = sp.symbols("x y th xd yd thd")
    m, inertia, r, g, mu, w, e = sp.symbols("m I r g mu W e")
    return vcigen.Model(
        name="fe_disk_wall",
        q=[x, y, th],
        qdot=[xd, yd, thd],
        lagrangian=m / 2 * (xd**2 + yd**2) + inertia / 2 * thd**2 - m * g * y,
        contacts={"floor": y - r, "wall": w - x - r},
        params=dict(zip((m, inertia, r, g, mu, w, e), DISK.values())),
        friction={"floor": (mu, x - r * th)},
        restitution={"wall": e},
    )


def block_lift() -> vcigen.Model:
    """A unit block sliding on the rough floor ``y >= 0``, lifted by the force of time ``A t`` (it leaves the
    floor at ``g / A``)."""
    x, y, xd, yd, t = sp.symbols("x y xd yd t")
    g, a, mu = sp.symbols("g A mu", positive=True)
    return vcigen.Model(
        name="fe_block_lift",
        q=[x, y],
        qdot=[xd, yd],
        lagrangian=(xd**2 + yd**2) / 2 - g * y,
        contacts={"floor": y},
        params={g: G, a: 17.0, mu: 0.3},
        forces=[0, a * t],
        time=t,
        friction={"floor": (mu, x)},
    )


def coupled_lift() -> vcigen.Model:
    """Particle 1 slipping on a rough floor, particle 2 on a smooth one lifted by ``A t``, coupled through the
    kinetic term ``k x1d y2d``: 2's force is ``g - A t - k slip g`` (``slip = -mu``), so it leaves at
    ``g (1 - k mu) / A``, a root that moves with the slip."""
    x1, y1, x2, y2, a1, b1, a2, b2, t = sp.symbols("x1 y1 x2 y2 x1d y1d x2d y2d t")
    g, a, mu, k = sp.symbols("g A mu k", positive=True)
    return vcigen.Model(
        name="fe_coupled_lift",
        q=[x1, y1, x2, y2],
        qdot=[a1, b1, a2, b2],
        lagrangian=(a1**2 + b1**2 + a2**2 + b2**2) / 2 + k * a1 * b2 - g * (y1 + y2),
        contacts={"floor1": y1, "floor2": y2},
        params={g: G, a: 17.0, mu: 0.3, k: 0.4},
        forces=[0, 0, 0, a * t],
        time=t,
        friction={"floor1": (mu, x1)},
    )


def land() -> vcigen.Model:
    """A unit particle dropped on the rough plastic floor ``y >= 0`` (restitution 0) while moving sideways."""
    x, y, xd, yd = sp.symbols("x y xd yd")
    g, mu = sp.symbols("g mu", positive=True)
    return vcigen.Model(
        name="fe_land",
        q=[x, y],
        qdot=[xd, yd],
        lagrangian=(xd**2 + yd**2) / 2 - g * y,
        contacts={"floor": y},
        params={g: G, mu: 0.3},
        friction={"floor": (mu, x)},
        restitution={"floor": 0},
    )


def land_held() -> vcigen.Model:
    """Particle 1 slipping on a rough floor (``mu``), particle 2 dropped on another, plastic (``nu``)."""
    x1, y1, x2, y2, a1, b1, a2, b2 = sp.symbols("x1 y1 x2 y2 x1d y1d x2d y2d")
    g, mu, nu = sp.symbols("g mu nu", positive=True)
    return vcigen.Model(
        name="fe_land_held",
        q=[x1, y1, x2, y2],
        qdot=[a1, b1, a2, b2],
        lagrangian=(a1**2 + b1**2 + a2**2 + b2**2) / 2 - g * (y1 + y2),
        contacts={"floor1": y1, "floor2": y2},
        params={g: G, mu: 0.2, nu: 0.3},
        friction={"floor1": (mu, x1), "floor2": (nu, x2)},
        restitution={"floor2": 0},
    )


def puck_wall() -> vcigen.Model:
    """A unit puck on the rough plane ``z >= 0`` (an isotropic cone: two tangents) tilted by ``a`` about the x
    axis (its sliding direction turns downhill), sliding into the smooth wall ``x <= W``."""
    x, y, z, xd, yd, zd = sp.symbols("x y z xd yd zd")
    g, mu, w, a = sp.symbols("g mu W a", positive=True)
    return vcigen.Model(
        name="fe_puck_wall",
        q=[x, y, z],
        qdot=[xd, yd, zd],
        lagrangian=(xd**2 + yd**2 + zd**2) / 2 - g * (z * sp.cos(a) + y * sp.sin(a)),
        contacts={"floor": z, "wall": w - x},
        params={g: G, mu: 0.2, w: 0.2, a: 0.15},
        friction={"floor": (mu, (x, y))},
    )


def puck_timed() -> vcigen.Model:
    """The puck on the level rough floor pushed sideways by a force of time ``c t``, into the wall
    ``x <= W``."""
    x, y, z, xd, yd, zd, t = sp.symbols("x y z xd yd zd t")
    g, mu, w, c = sp.symbols("g mu W c", positive=True)
    return vcigen.Model(
        name="fe_puck_timed",
        q=[x, y, z],
        qdot=[xd, yd, zd],
        lagrangian=(xd**2 + yd**2 + zd**2) / 2 - g * z,
        contacts={"floor": z, "wall": w - x},
        params={g: G, mu: 0.2, w: 0.2, c: 1.0},
        forces=[0, c * t, 0],
        time=t,
        friction={"floor": (mu, (x, y))},
    )


def rough_box() -> vcigen.Model:
    """The 2 x 1 box of ``test_sensitivity_held_events.box`` with Coulomb friction ``mu`` at every vertex (its
    tangent: the vertex's x), plastic (``e = 0``)."""
    x, y, th, xd, yd, thd = sp.symbols("x y theta xd yd thetad")
    e, mu = sp.symbols("e mu")
    corners = [(1.0, -0.5), (-1.0, -0.5), (1.0, 0.5), (-1.0, 0.5)]
    contacts = {f"v{i}": y + a * sp.sin(th) + b * sp.cos(th) for i, (a, b) in enumerate(corners)}
    return vcigen.Model(
        name="fe_rough_box",
        q=[x, y, th],
        qdot=[xd, yd, thd],
        lagrangian=(xd**2 + yd**2) / 2 + sp.Rational(5, 24) * thd**2 - G * y,
        contacts=contacts,
        params={e: 0.0, mu: 0.3},
        restitution=dict.fromkeys(contacts, e),
        friction={f"v{i}": (mu, x + a * sp.cos(th) - b * sp.sin(th)) for i, (a, b) in enumerate(corners)},
    )


def slide_wall() -> vcigen.Model:
    """A unit particle sliding on the rough floor into the wall ``x <= W``: the impact turns its sliding."""
    x, y, xd, yd = sp.symbols("x y xd yd")
    g, w, mu = sp.symbols("g W mu", positive=True)
    return vcigen.Model(
        name="fe_slide_wall",
        q=[x, y],
        qdot=[xd, yd],
        lagrangian=(xd**2 + yd**2) / 2 - g * y,
        contacts={"floor": y, "wall": w - x},
        params={g: G, w: 0.2, mu: 0.2},
        friction={"floor": (mu, x)},
    )


DISK_Q0, DISK_V0 = [0.0, 1.0, 0.0], [1.0, 0.0, -5.0]  # sliding at xd - r thetad = 6, down to 2.4 by t = 0.4
STOP_V0 = [1.0, 0.0, -1.27]  # sliding at 2.27: 1.27 at the wall (t = 0.17), 0.06 after it, stops in that step


def _disk(i: int | None = None, e: float = 0.0, par: str | None = None):
    q, v = list(DISK_Q0), list(DISK_V0)
    if i is not None and i < 3:
        q[i] += e
    elif i is not None:
        v[i - 3] += e
    return q, v, ({par: DISK[par] + e} if par else {})


def _block(i: int | None = None, e: float = 0.0, par: str | None = None):
    q, v = [0.0, 0.0], [1.0, 0.0]
    if i is not None:
        (q if i < 2 else v)[i % 2] += e
    return q, v, ({par: {"g": G, "A": 17.0, "mu": 0.3}[par] + e} if par else {})


def _coupled(i: int | None = None, e: float = 0.0, par: str | None = None):
    q, v = [0.0] * 4, [3.0, 0.0, 0.0, 0.0]
    if i is not None:
        (q if i < 4 else v)[i % 4] += e
    return q, v, ({par: {"g": G, "A": 17.0, "mu": 0.3, "k": 0.4}[par] + e} if par else {})


def _point(q0: list[float], v0: list[float], base: dict[str, float]):
    def point(i: int | None = None, e: float = 0.0, par: str | None = None):
        q, v = list(q0), list(v0)
        if i is not None:
            (q if i < len(q0) else v)[i % len(q0)] += e
        return q, v, ({par: base[par] + e} if par else {})

    return point


_puck = _point([0.0, 0.0, 0.0], [1.0, 0.5, 0.0], {"g": G, "mu": 0.2, "W": 0.2, "a": 0.15})
_box = _point([0.0, 0.6, 0.1], [1.5, 0.0, 0.0], {"e": 0.0, "mu": 0.3})
_land = _point([0.0, 0.3], [2.0, -1.0], {"g": G, "mu": 0.3})
_land_held = _point([0.0, 0.0, 0.0, 0.3], [2.0, 0.0, 1.5, -1.0], {"g": G, "mu": 0.2, "nu": 0.3})
_stop = _point(DISK_Q0, STOP_V0, DISK)


def _paths(point, coords: dict[str, int], params: list[str]) -> dict:
    out = {name: (lambda e, i=i: point(i, e)) for name, i in coords.items()}
    return out | {name: (lambda e, p=name: point(None, e, p)) for name in params}


def _roll(i: int | None = None, e: float = 0.0, par: str | None = None):
    q, v = list(DISK_Q0), [1.05, 0.0, 1.05]  # rolling: xd = r thetad
    if i == 0 or i == 2:
        q[i] += e
    elif i is not None:  # along the rolling: xd and thetad together
        v = [1.05 + e, 0.0, 1.05 + e]
    return q, v, ({par: DISK[par] + e} if par else {})


# scene -> (model maker, q0, v0, h, t_end, params, paths): each path keeps the mode
# (test_sensitivity.held_mode)
SCENES = {
    # an impact (restitution 0.8) on the smooth wall while the floor is held and slips, the same way after it
    "disk_wall": (
        disk_wall,
        DISK_Q0,
        DISK_V0,
        0.01,
        0.4,
        None,
        _paths(_disk, {"q0[x]": 0, "q0[th]": 2, "v0[x]": 3, "v0[th]": 5}, ["m", "I", "g", "mu", "W", "e"]),
    ),
    # the disk into the wall (step 17) while the floor slips; the rebound leaves it sliding at 0.06 the same
    # way, and the sliding stops in the rest of that step (a located stop, SustainedSteps._sw_*): rolls on
    "wall_stop": (
        disk_wall,
        DISK_Q0,
        STOP_V0,
        0.01,
        0.3,
        None,
        _paths(_stop, {"q0[x]": 0, "q0[th]": 2, "v0[x]": 3, "v0[th]": 5}, ["m", "I", "g", "mu", "W", "e"]),
    ),
    # the slipping contact lifted off (at g / A = 0.577, inside step 57), then free flight
    "block_lift": (
        block_lift,
        *_block()[:2],
        0.01,
        0.8,
        None,
        _paths(_block, {"q0[x]": 0, "v0[x]": 2}, ["g", "A", "mu"]),
    ),
    # particle 2 lifted off (at g (1 - k mu) / A = 0.508) while particle 1 slips, coupled to it
    "coupled_lift": (
        coupled_lift,
        *_coupled()[:2],
        0.01,
        0.6,
        None,
        _paths(_coupled, {"q0[x1]": 0, "v0[x1]": 4}, ["g", "A", "mu", "k"]),
    ),
    # the puck (a cone) slipping across the incline into the wall (step 26): its direction aimed anew at every
    # sub-step's start over what is left of the step (Tracker._cone_slots with dtau)
    "puck_wall": (
        puck_wall,
        *_puck()[:2],
        0.01,
        0.4,
        None,
        _paths(_puck, {"q0[x]": 0, "q0[y]": 1, "v0[x]": 3, "v0[y]": 4}, ["g", "mu", "W", "a"]),
    ),
    # dropped tilted while moving sideways (h = 0.005): lands on v1 (plastic, slipping from there), turns onto
    # its face about it, v0 lands plastically while v1 is held and slips (both slip on to t = 0.4)
    "rough_box": (
        rough_box,
        *_box()[:2],
        0.005,
        0.4,
        None,
        _paths(_box, {"q0[x]": 0, "q0[theta]": 2, "v0[x]": 3, "v0[theta]": 5}, ["mu"]),
    ),
    # lands plastically in step 16, slipping from there (held anew: the slip slot set at the impact)
    "land": (
        land,
        *_land()[:2],
        0.01,
        0.5,
        None,
        _paths(_land, {"q0[x]": 0, "q0[y]": 1, "v0[x]": 2, "v0[y]": 3}, ["g", "mu"]),
    ),
    # particle 2 lands plastically (step 16) while particle 1 is held and slips: an impact while held
    "land_held": (
        land_held,
        *_land_held()[:2],
        0.01,
        0.5,
        None,
        _paths(_land_held, {"q0[y2]": 3, "v0[x1]": 4, "v0[x2]": 6, "v0[y2]": 7}, ["g", "mu", "nu"]),
    ),
}


@cache
def simulator(scene: str, backend: str, rule: str = "trapezoid") -> vcigen.Simulator:
    return vcigen.build(SCENES[scene][0](), backend=backend, rule=rule)


def _cases():
    for scene in sorted(SCENES):
        for rule in RULES:
            for b in BACKENDS:
                backend, marks = (b, ()) if isinstance(b, str) else (b.values[0], b.marks)
                yield pytest.param(scene, backend, rule, marks=marks, id=f"{scene}-{backend}-{rule}")


def _events(res: vcigen.Result, scene: str) -> None:
    """The scene makes its event inside a held step, friction acting, and keeps the floor slipping."""
    steps = (res.t[1] - res.t[0], res.t[0])
    if scene in ("disk_wall", "puck_wall", "wall_stop"):
        (im,) = res.impacts
        assert im.contact == "wall" and im.kind in ("restitution", "elastic") and res.active[im.step, 0]
        assert res.active[:, 0].all() and res.liftoffs == []
        if scene == "wall_stop":  # slipping up to the impact's step, rolling from its end on
            slide = disk_sliding(res)
            assert (slide[: im.step + 1] > 0.05).all() and (np.abs(slide[im.step + 1 :]) <= 1e-12).all()
    elif scene in ("land", "land_held"):
        (im,) = res.impacts
        assert im.kind == "plastic" and res.active[im.step + 1 :].all() and not res.active[im.step, -1]
        assert res.liftoffs == [] and (scene == "land" or res.active[im.step, 0])
    elif scene == "rough_box":
        first, second = res.impacts
        assert (first.contact, second.contact, first.kind, second.kind) == ("v1", "v0", "plastic", "plastic")
        assert res.active[second.step, 1] and res.active[-1, :2].all() and res.liftoffs == []
    else:
        (lift,) = res.liftoffs
        assert res.impacts == [] and lift[1] == ("floor" if scene == "block_lift" else "floor2")
        k = int((lift[0] - steps[1]) / steps[0])
        assert res.active[k, 0] and not res.active[k + 1, -1], res.active[k : k + 2]


def disk_sliding(res: vcigen.Result) -> np.ndarray:
    """The disk's sliding velocity ``xd - r thetad`` at the grid points (``p = (m xd, m yd, I thetad)``)."""
    return res.p[:, 0] / DISK["m"] - DISK["r"] * res.p[:, 2] / DISK["I"]


@pytest.mark.parametrize("scene, backend, rule", list(_cases()))
def test_events_under_friction_match_finite_differences(scene: str, backend: str, rule: str) -> None:
    """The tangent across the event against central differences of whole runs (every grid point, every path),
    covered throughout (no break)."""
    res, per = held_finite_differences(simulator(scene, backend, rule), scene, scenes=SCENES)
    _events(res, scene)
    assert res.sensitivity_breaks == [] and np.isfinite(res.sensitivity).all()
    errs = {label: relative_error(exact, fd) for label, (exact, fd) in per.items()}
    worst = max(errs, key=errs.get)
    print(f"{scene} ({backend}, {rule}): worst {worst} {errs[worst]:.1e}")
    assert errs[worst] <= FD_TOL, errs
    assert max(np.abs(exact[-1]).max() for exact, _ in per.values()) > 0.1  # the paths do move the end


def disk_closed_form(t: float, par: dict, v0: float = DISK_V0[0]) -> dict[str, float]:
    """``dx(t)/d(v0, W, mu, e)`` of the disk's centre: ``x = v0 s - a s^2/2`` (``a = mu g``) up to the wall
    ``x = W - r`` at ``t*``, where ``xd = u = v0 - a t*`` turns to ``-e u``; then ``x = W - r - e u (t - t*) -
    a (t - t*)^2 / 2`` (the floor slipping the same way throughout)."""
    a, wr, e = par["mu"] * par["g"], par["W"] - par["r"], par["e"]
    ts = (v0 - np.sqrt(v0 * v0 - 2.0 * a * wr)) / a
    u, d = v0 - a * ts, t - ts
    out = {}
    for name, dts, du, da in (
        ("v0[x]", -ts / u, 1.0 + a * ts / u, 0.0),
        ("W", 1.0 / u, -a / u, 0.0),
        ("mu", ts * ts * par["g"] / (2.0 * u), None, par["g"]),
    ):
        du = -ts * da - a * dts if du is None else du
        out[name] = (1.0 if name == "W" else 0.0) - e * du * d + e * u * dts - da * d * d / 2 + a * d * dts
    out["e"] = -u * d
    return out


@pytest.mark.parametrize("rule", RULES)
@pytest.mark.parametrize("backend", BACKENDS)
def test_disk_against_the_closed_form(backend: str, rule: str) -> None:
    """The disk's ``dx/d(v0, W, mu, e)`` at every grid point after the impact is the closed form's (the
    discrete map reproduces the constant deceleration and the impact time exactly)."""
    sim = simulator("disk_wall", backend, rule)
    res = sim.simulate(DISK_Q0, DISK_V0, 0.01, t_end=0.4, sensitivities=True, progress=False)
    names = res.sensitivity_names
    (im,) = res.impacts
    worst = 0.0
    for k in range(im.step + 1, res.t.size):
        for name, value in disk_closed_form(float(res.t[k]), DISK).items():
            got = res.sensitivity[k, 0, names.index(name)]
            worst = max(worst, abs(got - value) / max(1.0, abs(value)))
    print(f"disk closed form ({backend}, {rule}): {worst:.1e}")
    assert worst <= 1e-10, worst


@cache
def wall_stop_closed_form() -> tuple:
    """``x(t)`` of the disk that stops after the wall for ``t`` after the stop, as a SymPy expression; its
    symbols ``(t, v0, w0, m, I, g, mu, W, e)`` (``r = 1``, ``x0 = 0``); the stop time. Slipping forward,
    ``xd = v0 - a t`` (``a = mu g``), ``thetad = w0 + c t`` (``c = mu m g r / I``) up to the wall
    ``x = W - r`` at ``t*``; the impact turns ``u = xd(t*)`` to ``-e u`` (the wall frictionless); the sliding
    ``-e u - r thetad(t*) - (a + r c) d`` (``d = t - t*``) stops at ``d_s``; then it rolls at
    ``-e u - a d_s``."""
    t, v0, w0, m, inertia, g, mu, w, e = sp.symbols("t v0 w0 m I g mu W e")
    r = 1
    a, c = mu * g, mu * m * g * r / inertia
    ts = (v0 - sp.sqrt(v0**2 - 2 * a * (w - r))) / a
    u = v0 - a * ts
    ds = (-e * u - r * (w0 + c * ts)) / (a + r * c)
    x_stop = w - r - e * u * ds - a * ds**2 / 2
    return x_stop + (-e * u - a * ds) * (t - ts - ds), (t, v0, w0, m, inertia, g, mu, w, e), ts + ds


@pytest.mark.parametrize("rule", RULES)
@pytest.mark.parametrize("backend", BACKENDS)
def test_wall_then_stop_against_the_closed_form(backend: str, rule: str) -> None:
    """An impact while held and a located stop in one step: the disk's ``dx/dz`` at every grid point after
    the stop is the closed form's derivative (SymPy) in ``v0[x]``, ``v0[th]``, ``m``, ``I``, ``g``, ``mu``,
    ``W``, ``e``; no break."""
    res = simulator("wall_stop", backend, rule).simulate(
        DISK_Q0, STOP_V0, 0.01, t_end=0.3, sensitivities=True, progress=False
    )
    assert res.sensitivity_breaks == [] and np.isfinite(res.sensitivity).all()
    (im,) = res.impacts
    x, syms, t_stop = wall_stop_closed_form()
    at = dict(zip(syms[1:], (STOP_V0[0], STOP_V0[2], *(DISK[k] for k in ("m", "I", "g", "mu", "W", "e")))))
    assert im.step * 0.01 < float(t_stop.subs(at)) < (im.step + 1) * 0.01  # the stop is in the impact's step
    names, worst = res.sensitivity_names, 0.0
    columns = dict(zip(("v0[x]", "v0[th]", "m", "I", "g", "mu", "W", "e"), syms[1:]))
    for name, sym in columns.items():
        dx = sp.lambdify(syms[0], sp.diff(x, sym).subs(at))
        for k in range(im.step + 1, res.t.size):
            value = float(dx(float(res.t[k])))
            worst = max(worst, abs(res.sensitivity[k, 0, names.index(name)] - value) / max(1.0, abs(value)))
    print(f"wall then stop, closed form ({backend}, {rule}): {worst:.1e}")
    assert worst <= 1e-10, worst


def land_closed_form(t: float, g: float, mu: float, vx: float = 2.0, vy: float = -1.0, y0: float = 0.3):
    """``dx(t)/d(v0[y], g, mu)`` of the landing particle: it lands at ``t*`` (``y0 + vy t - g t^2/2 = 0``)
    with the speed ``rate = g t* - vy``, plastic: the normal impulse ``m rate`` and Coulomb's sliding impulse
    ``mu m rate`` against ``xd = vx`` (``vx > mu rate``: it slides through the impact), then slips on,
    decelerated by ``mu g``: ``x = vx t - mu rate (t - t*) - mu g (t - t*)^2 / 2``."""
    ts = (vy + np.sqrt(vy * vy + 2.0 * g * y0)) / g
    d, rate = t - ts, g * ts - vy  # rate: the speed of the fall at t*, -dy/dt
    assert vx > mu * rate
    dts = {"v0[y]": ts / rate, "g": -ts * ts / (2.0 * rate)}
    drate = {"v0[y]": g * dts["v0[y]"] - 1.0, "g": ts + g * dts["g"]}
    out = {name: mu * (rate + g * d) * dt - mu * drate[name] * d for name, dt in dts.items()}
    out["g"] -= mu * d * d / 2
    out["mu"] = -rate * d - g * d * d / 2
    return out


@pytest.mark.parametrize("rule", RULES)
@pytest.mark.parametrize("backend", BACKENDS)
def test_landing_against_the_closed_form(backend: str, rule: str) -> None:
    """The landing's ``dx/d(v0[y], g, mu)`` at every grid point after the plastic impact is the closed form's
    (the fall, the contact time (47) and the slipping deceleration are exact in the discrete map)."""
    res = simulator("land", backend, rule).simulate(
        *_land()[:2], 0.01, t_end=0.5, sensitivities=True, progress=False
    )
    (im,) = res.impacts
    names, worst = res.sensitivity_names, 0.0
    for k in range(im.step + 1, res.t.size):
        for name, value in land_closed_form(float(res.t[k]), G, 0.3).items():
            worst = max(worst, abs(res.sensitivity[k, 0, names.index(name)] - value) / max(1.0, abs(value)))
    print(f"landing closed form ({backend}, {rule}): {worst:.1e}")
    assert worst <= 1e-10, worst


@needs_c
@pytest.mark.parametrize("rule", RULES)
@pytest.mark.parametrize("scene", sorted(SCENES))
def test_c_equals_casadi(scene: str, rule: str) -> None:
    """The C loop's tangent is the Python stepper's to 1e-9, and its run the plain library's bit for bit."""
    _, q0, v0, h, t_end, params, _ = SCENES[scene]
    kw = {"t_end": t_end, "params": params, "sensitivities": True, "progress": False}
    a, b = (simulator(scene, backend, rule).simulate(q0, v0, h, **kw) for backend in ("casadi", "c"))
    assert held_mode(a) == held_mode(b) and b.sensitivity_breaks == []
    plain = simulator(scene, "c", rule).simulate(q0, v0, h, t_end=t_end, params=params, progress=False)
    np.testing.assert_array_equal(b.q, plain.q)
    np.testing.assert_array_equal(b.p, plain.p)
    rel = assert_same_tangent(a, b, C_TOL)
    print(f"{scene} ({rule}): C against CasADi {rel:.1e}")


@cache
def _switch_sim(backend: str) -> vcigen.Simulator:
    return vcigen.build(slide_wall(), backend=backend)


# break scene -> (simulator, q0, v0, t_end): the impact turns the sliding (slip -> the other way, a switch
# at the start of the rest of the step, not located), or the disk rolling into the wall slips there (the
# floor's normal impulse is 0, so its stick leaves the cone: SustainedSteps._impulse_law; the stick within
# the cone is tests/test_impulse_law_friction.py's). A stop after the impact is carried: ``wall_stop``.
SWITCHES = {
    "roll_slipped": (lambda backend: simulator("disk_wall", backend), *_roll()[:2], 0.4),
    "slip_turned": (_switch_sim, [0.0, 0.0], [1.0, 0.0], 0.5),
}


@pytest.mark.parametrize("backend", BACKENDS)
@pytest.mark.parametrize("scene", sorted(SWITCHES))
def test_a_friction_switch_among_the_events_breaks(scene: str, backend: str) -> None:
    """The impact turns the sliding (slip -> the other way, a switch at the start of the rest of the step, not
    located), or a rolling contact slips at it: a mode change, the step breaks with its reason (the tangent
    finite before it, NaN after), at the impact's step, the same on both backends."""
    make, q0, v0, t_end = SWITCHES[scene]
    res = make(backend).simulate(q0, v0, 0.01, t_end=t_end, sensitivities=True, progress=False)
    (im,) = res.impacts
    assert assert_lost(res, "friction switch in a held step") == im.step
    assert res.sensitivity_breaks == [(im.step, "friction switch in a held step")]


@cache
def _puck_sim(backend: str) -> vcigen.Simulator:
    return vcigen.build(puck_timed(), backend=backend)


@pytest.mark.parametrize("backend", BACKENDS)
def test_an_event_with_a_cone_under_forces_of_time_still_breaks(backend: str) -> None:
    """An impact while an isotropic cone is held and slipping under forces of time is not carried (the cone's
    aim is differentiated with the time held fixed): the step breaks as before, the same on both backends."""
    res = _puck_sim(backend).simulate(
        [0.0, 0.0, 0.0], [1.0, 0.5, 0.0], 0.01, t_end=0.4, sensitivities=True, progress=False
    )
    (im,) = res.impacts
    assert im.contact == "wall" and res.active[im.step, 0]
    assert assert_lost(res, "held step (sustained contact)") == im.step
