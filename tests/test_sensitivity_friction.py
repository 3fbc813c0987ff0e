"""Exact sensitivities through Coulomb friction in one mode (MATH.md *Friction*, *Exact sensitivities*).

A disk on a rough incline of angle ``a`` (``q = (x, y, theta)`` along and normal to it, sliding velocity
``xd - r thetad``; the level floor at ``a = 0``), every quantity a parameter. Within a mode the step maps are
smooth: a contact that slips throughout (the slot ``-mu_f s``, its tangent through ``mu_f``), one that sticks
throughout (its stick row held, its reference moving with the start); a one-tangent switch inside a step is a
located event (tests/test_sensitivity_friction_switch.py), a cone's stays a reported break.
The tangent against central differences of whole runs along directions that keep the mode, against the
closed forms of the motion (sliding: ``x(T) = x0 + v0 T + (mu_f cos a - sin a) g T^2 / 2``; rolling:
``x(T) = x0 + v0 T - g sin a T^2 / (2 (1 + I/(m r^2)))``; the trapezoidal rule reproduces a constant
acceleration exactly), and C against CasADi.

At an impact (a spinning disk dropped on a rough floor, ``vcigen.friction.impact_law``): the tangent through
Coulomb's impulse law in the branch it takes (slip then roll, or slip throughout), against central differences
of every column and the law's closed forms. The isotropic cone of a 3-D contact (a puck): slipping or sticking
in sustained contact, and at an impact (``vcigen.friction.cone_law_tangent``, covered in full by
tests/test_sensitivity_cone_impact.py).
"""

from __future__ import annotations

import math
from functools import cache

import hard_scenes
import numpy as np
import pytest
import sympy as sp
from hard_scenes import G

import vcigen

BACKENDS = [hard_scenes.backend_param("casadi"), hard_scenes.backend_param("c")]
PARAMS = {"m": 1.0, "I": 0.5, "r": 1.0, "g": G, "mu": 0.2, "a": 0.3}
H, T = 0.01, 0.3
FD_TOL = 1e-6  # the tangent against central differences, relative (test_sensitivity.relative_error)
C_TOL = 1e-9  # C against CasADi, relative
needs_c = pytest.mark.skipif(
    hard_scenes.c_backend_problem() is not None, reason=str(hard_scenes.c_backend_problem())
)


def incline_disk() -> vcigen.Model:
    x, y, th, xd, yd, thd = sp.symbols("x y th xd yd thd")
    m, inertia, r, g, mu, a = sp.symbols("m I r g mu a")
    return vcigen.Model(
        name="incline_disk",
        q=[x, y, th],
        qdot=[xd, yd, thd],
        lagrangian=m / 2 * (xd**2 + yd**2) + inertia / 2 * thd**2 - m * g * (y * sp.cos(a) + x * sp.sin(a)),
        contacts={"floor": y - r},
        params={m: 1.0, inertia: 0.5, r: 1.0, g: G, mu: 0.2, a: 0.3},
        friction={"floor": (mu, x - r * th)},
    )


@cache
def sim(backend: str) -> vcigen.Simulator:
    return vcigen.build(incline_disk(), backend=backend)


# scene -> (v0, params, directions): the disk set down on the floor (y = r), each direction in z = (q0, v0,
# params) one that keeps the mode (the normal coordinates left out: they lift or press the disk; r moves
# with y0, so that the disk stays on the floor, and while rolling with w0 = vx0 / r, so that it stays rolling:
# r enters the stick row x - r th, whose reference moves with it)
SLIDE = {"x0": {0: 1.0}, "th0": {2: 1.0}, "vx0": {3: 1.0}, "w0": {5: 1.0}, "m": {6: 1.0}, "I": {7: 1.0}}
SLIDE |= {"r": {1: 1.0, 8: 1.0}, "g": {9: 1.0}, "mu": {10: 1.0}, "a": {11: 1.0}}
SCENES = {
    # sliding on the level floor, no spin: friction slows it and spins it up, slipping throughout to T
    "floor_slide": ([2.0, 0.0, 0.0], {"a": 0.0}, SLIDE),
    # sliding down the incline (tan a < 3 mu: it would roll later), slipping throughout to T
    "incline_slide": ([-1.0, 0.0, 0.0], {}, SLIDE),
    # rolling up the incline (sticking throughout: vx = r w): the rolling direction of (vx, w) keeps it
    "incline_roll": (
        [1.0, 0.0, 1.0],
        {},
        {"x0": {0: 1.0}, "th0": {2: 1.0}, "roll": {3: 1.0, 5: 1.0}, "m": {6: 1.0}, "I": {7: 1.0}}
        | {"r": {1: 1.0, 8: 1.0, 5: -1.0}, "g": {9: 1.0}, "mu": {10: 1.0}, "a": {11: 1.0}},  # w0 = vx0/r
    ),
}


def direction(spec: dict[int, float], k: int) -> np.ndarray:
    dz = np.zeros(k)
    for c, w in spec.items():
        dz[c] = w
    return dz


def start(v0, params) -> tuple[list[float], list[float], dict]:
    return [0.0, PARAMS["r"], 0.0], list(v0), {**PARAMS, **params}


def perturbed(q0, v0, par: dict, dz: np.ndarray, eps: float) -> tuple[list[float], list[float], dict]:
    names = list(PARAMS)
    q = [q0[i] + eps * dz[i] for i in range(3)]
    v = [v0[i] + eps * dz[3 + i] for i in range(3)]
    return q, v, {k: par[k] + eps * dz[6 + i] for i, k in enumerate(names)}


@pytest.fixture(scope="module", params=BACKENDS)
def runs(request) -> dict:
    """Each scene on one backend: the run with its tangent, and central differences along its directions."""
    backend = request.param
    s = sim(backend)
    out = {}
    for scene, (v0, params, dirs) in SCENES.items():
        q0, v0, par = start(v0, params)
        res = s.simulate(q0, v0, H, t_end=T, params=par, sensitivities=True, progress=False)
        fd = {}
        for label, spec in dirs.items():
            dz = direction(spec, res.sensitivity.shape[2])
            ends = []
            for sign in (1.0, -1.0):
                q, v, p = perturbed(q0, v0, par, dz, sign * 1e-6)
                r = s.simulate(q, v, H, t_end=T, params=p, progress=False)
                assert r.impacts == [] and np.array_equal(r.active, res.active), (scene, label)
                ends.append(np.hstack([r.q, r.p]))
            fd[label] = (res.sensitivity @ dz, (ends[0] - ends[1]) / 2e-6)
        out[scene] = (res, fd)
    return backend, out


@pytest.mark.parametrize("scene", sorted(SCENES))
def test_friction_tangent_matches_finite_differences(runs, scene: str) -> None:
    """Held steps slipping or sticking throughout: every step covered, the tangent along every direction that
    keeps the mode against central differences (the parameters' columns included: mu_f, g, a, m, I, r)."""
    backend, out = runs
    res, fd = out[scene]
    assert res.active[:, 0].all() and res.impacts == []
    assert res.sensitivity_breaks == [] and np.isfinite(res.sensitivity).all()
    scale = max(float(np.abs(ex).max()) for ex, _ in fd.values())  # mu_f moves nothing while rolling
    errs = {k: float(np.abs(ex - d).max()) / scale for k, (ex, d) in fd.items()}
    print(f"{scene} ({backend}): worst {max(errs, key=errs.get)} {max(errs.values()):.1e}")
    assert max(errs.values()) <= FD_TOL, errs


def test_sliding_tangent_is_the_closed_forms(runs) -> None:
    """Slipping: x(t) = x0 + v0 t + (mu_f cos a - sin a) g t^2/2 (against the sliding: here v0 < 0 on the
    incline, v0 > 0 on the floor): dx/dv0 = t, dx/dmu_f = -+g cos a t^2/2, dx/dg, dx/da; the spin
    w(t) = w0 -+ mu_f m g cos a r t / I, so dtheta/dmu_f; both exact in the discrete map."""
    _, out = runs
    for scene, sign in (("floor_slide", -1.0), ("incline_slide", 1.0)):
        res, _ = out[scene]
        a, mu, g, inertia = SCENES[scene][1].get("a", PARAMS["a"]), PARAMS["mu"], G, PARAMS["I"]
        t, S = res.t, res.sensitivity
        col = {name: i for i, name in enumerate(res.sensitivity_names)}
        half = t**2 / 2
        acc = (sign * mu * math.cos(a) - math.sin(a)) * g
        x = res.q[0, 0] + SCENES[scene][0][0] * t + acc * half
        assert np.allclose(res.q[:, 0], x, atol=1e-12, rtol=0)
        expect = {
            "v0[x]": t,
            "mu": sign * g * math.cos(a) * half,
            "g": (sign * mu * math.cos(a) - math.sin(a)) * half,
            "a": -(sign * mu * math.sin(a) + math.cos(a)) * g * half,
        }
        for name, value in expect.items():
            assert np.allclose(S[:, 0, col[name]], value, atol=1e-10, rtol=0), (scene, name)
        # theta(t) = w0 t - sign mu m g cos a r t^2/(2 I): its mu_f column
        dth = -sign * g * math.cos(a) * PARAMS["m"] * PARAMS["r"] / inertia * half
        assert np.allclose(S[:, 2, col["mu"]], dth, atol=1e-10, rtol=0), scene


def test_rolling_tangent_is_the_closed_form(runs) -> None:
    """Sticking (rolling up the incline, slowing): x(t) = x0 + v0 t - g sin a t^2 / (2 (1 + I/(m r^2))); its
    columns in x0 and theta0 (the stick's reference moves with the start: dx/dx0 = 1, dx/dtheta0 = 0), g, a,
    I, m and none in mu_f."""
    _, out = runs
    res, _ = out["incline_roll"]
    t, S = res.t, res.sensitivity
    col = {name: i for i, name in enumerate(res.sensitivity_names)}
    m, inertia, r, a = PARAMS["m"], PARAMS["I"], PARAMS["r"], PARAMS["a"]
    k = 1.0 + inertia / (m * r * r)
    half = t**2 / 2
    assert np.allclose(res.q[:, 0], t - G * math.sin(a) / k * half, atol=1e-12, rtol=0)
    expect = {
        "q0[x]": np.ones_like(t),
        "q0[th]": np.zeros_like(t),
        "g": -math.sin(a) / k * half,
        "a": -G * math.cos(a) / k * half,
        "I": G * math.sin(a) / k**2 / (m * r * r) * half,
        "m": -G * math.sin(a) / k**2 * inertia / (m * m * r * r) * half,
        "mu": np.zeros_like(t),
    }
    for name, value in expect.items():
        assert np.allclose(S[:, 0, col[name]], value, atol=1e-10, rtol=0), name
    roll = S[:, 0, col["v0[x]"]] + S[:, 0, col["v0[th]"]]  # along the rolling direction (r = 1)
    assert np.allclose(roll, t, atol=1e-10, rtol=0)


@pytest.mark.parametrize("backend", BACKENDS)
def test_a_stop_is_carried(backend: str) -> None:
    """Sliding down the incline until the disk rolls (slip -> stick inside a step, formerly a break): the stop
    is a located event (vcigen.sensitivity_switch), the tangent carried through it with no break; the sliding
    stops in the step of the closed form's t*. Its values: tests/test_sensitivity_friction_switch.py."""
    q0, v0, par = start(SCENES["incline_slide"][0], {})
    res = sim(backend).simulate(q0, v0, H, t_end=0.5, params=par, sensitivities=True, progress=False)
    # the sliding velocity xd - r w rises from v0 at the rate mu m g cos a (1/m + r^2/I) - g sin a to 0 at t*
    m, inertia, r, a = par["m"], par["I"], par["r"], par["a"]
    rate = par["mu"] * m * G * math.cos(a) * (1 / m + r * r / inertia) - G * math.sin(a)
    t_stop = -(v0[0] - r * v0[2]) / rate
    k = int(t_stop / H)  # the step the sliding stops in
    slide = res.p[:, 0] / m - r * res.p[:, 2] / inertia
    assert (np.abs(slide[: k + 1]) > 1e-3).all() and (np.abs(slide[k + 1 :]) <= 1e-12).all()
    assert res.sensitivity_breaks == [] and np.isfinite(res.sensitivity).all()


@needs_c
def test_c_equals_casadi() -> None:
    """The C tangent (templates/sens_held_slots.c.j2: sens_slots, sens_add_slots) against the CasADi one."""
    for scene, (v0, params, _) in SCENES.items():
        q0, v0, par = start(v0, params)
        a, b = (
            sim(backend).simulate(q0, v0, H, t_end=T, params=par, sensitivities=True, progress=False)
            for backend in ("casadi", "c")
        )
        rel = float(np.abs(a.sensitivity - b.sensitivity).max() / np.abs(a.sensitivity).max())
        print(f"{scene}: C against CasADi {rel:.1e}")
        assert a.sensitivity_breaks == b.sensitivity_breaks == [] and rel <= C_TOL


# -- frictional impacts --------------------------------------------------------------------------------------
DROP = ([0.0, 2.0, 0.0], 0.01, 0.6)  # q0 (height 1 above the floor y >= r), h, t_end: one impact, at step 45


@cache
def rough_disk(backend: str) -> vcigen.Simulator:
    import test_friction

    return test_friction.sim("disk", backend)


@pytest.mark.parametrize("spin, branch", [(5.0, "roll"), (30.0, "slip")])
@pytest.mark.parametrize("backend", BACKENDS)
def test_frictional_impact_matches_finite_differences(backend: str, spin: float, branch: str) -> None:
    """A disk dropped with (vx, w) = (2, spin) on a floor with e = 0.7, mu_f = 0.3: one impact, the sliding
    stopped by it (rolls) or not (slips throughout). Every column against central differences; the law's
    direction n + rho t with t = (1, 0, -r): the spin's momentum jumps by -r times the x one, so their mu_f
    columns after it are in that ratio; rolling, mu_f moves nothing; slipping, d vx+/d mu_f = (1 + e) |vy| to
    the O(h^2) of the discrete impact."""
    sim = rough_disk(backend)
    q0, h, t_end = DROP
    v0 = [2.0, 0.0, spin]
    names = [str(s) for s in sim.model.defaults]
    values = dict(zip(names, sim.model.resolve_params(None)))
    res = sim.simulate(q0, v0, h, t_end=t_end, sensitivities=True, progress=False)
    assert [im.kind for im in res.impacts] == ["restitution"] and res.sensitivity_breaks == []
    S, n = res.sensitivity, 3
    fd = np.empty_like(S)
    for c in range(S.shape[2]):
        ends = []
        for sign in (1.0, -1.0):
            z, par = np.array(q0 + v0), dict(values)
            if c < 2 * n:
                z[c] += sign * 1e-6
            else:
                par[names[c - 2 * n]] += sign * 1e-6
            r = sim.simulate(z[:n], z[n:], h, t_end=t_end, params=par, progress=False)
            assert [im.step for im in r.impacts] == [res.impacts[0].step], res.sensitivity_names[c]
            ends.append(np.hstack([r.q, r.p]))
        fd[:, :, c] = (ends[0] - ends[1]) / 2e-6
    err = float(np.abs(S - fd).max() / np.abs(S).max())
    print(f"disk impact, {branch} ({backend}): FD {err:.1e}")
    assert err <= FD_TOL
    k = res.impacts[0].step + 1  # the grid point after the impact
    mu, r_ = names.index("mu") + 2 * n, values["r"]
    assert np.allclose(S[k:, 5, mu], -r_ * S[k:, 3, mu], rtol=1e-12, atol=1e-14)
    if branch == "roll":
        assert np.abs(S[:, :, mu]).max() == 0.0
    else:
        vy = math.sqrt(2 * values["g"] * 1.0)
        want = (1 + values["e"]) * vy / values["m"]
        assert abs(S[k, 3, mu] / values["m"] - want) <= 1e-4 * want, (S[k, 3, mu], want)


@needs_c
def test_frictional_impact_c_equals_casadi() -> None:
    """Both branches of the impulse law: the C tangent (sens_friction_impact) against the CasADi one."""
    q0, h, t_end = DROP
    for spin in (5.0, 30.0):
        a, b = (
            rough_disk(backend).simulate(
                q0, [2.0, 0.0, spin], h, t_end=t_end, sensitivities=True, progress=False
            )
            for backend in ("casadi", "c")
        )
        rel = float(np.abs(a.sensitivity - b.sensitivity).max() / np.abs(a.sensitivity).max())
        print(f"disk impact, spin {spin}: C against CasADi {rel:.1e}")
        assert a.sensitivity_breaks == b.sensitivity_breaks == [] and rel <= C_TOL


# -- the isotropic cone (two tangents): a puck on a rough plane ----------------------------------------------
@cache
def puck(backend: str) -> vcigen.Simulator:
    import test_friction_3d

    return vcigen.build(test_friction_3d.puck(), backend=backend)


def puck_run(backend: str, v0, params: dict, t_end: float) -> vcigen.Result:
    return puck(backend).simulate(
        [0.0, 0.0, 0.0], v0, H, t_end=t_end, params=params, sensitivities=True, progress=False
    )


@pytest.mark.parametrize("backend", BACKENDS)
def test_cone_slip_is_the_closed_form(backend: str) -> None:
    """A puck sliding on the level floor at v0 = (1.2, -0.9): its slip direction is aimed anew every step from
    the state (``SustainedSteps._cone_aim``), its tangent through that aim (``Tracker._cone_slots``, C
    ``sens_cone_slots``). Sliding straight, p(t) = p0 + v0 t - mu g t^2/2 e, e = v0/|v0| (exact in the
    discrete map), so dp/dv0 = I t - mu g t^2/2 (I - e e^T)/|v0|: the direction turns with v0; dp/dmu, dp/dg
    along -e."""
    import test_friction_3d

    mu, v0 = test_friction_3d.MU, np.array([1.2, -0.9])
    res = puck_run(backend, [*v0, 0.0], {"a": 0.0}, T)
    assert res.sensitivity_breaks == [] and res.active[:, 0].all()
    t, S = res.t, res.sensitivity
    col = {name: i for i, name in enumerate(res.sensitivity_names)}
    speed = float(np.linalg.norm(v0))
    e = v0 / speed
    half = (t**2 / 2)[:, None, None]
    dv = t[:, None, None] * np.eye(2) - mu * G * half * (np.eye(2) - np.outer(e, e)) / speed
    assert np.allclose(S[:, :2, [col["v0[x]"], col["v0[y]"]]], dv, atol=1e-10, rtol=0)
    assert np.allclose(S[:, :2, col["mu"]], -G * (t**2 / 2)[:, None] * e, atol=1e-10, rtol=0)
    assert np.allclose(S[:, :2, col["g"]], -mu * (t**2 / 2)[:, None] * e, atol=1e-10, rtol=0)


@pytest.mark.parametrize("backend", BACKENDS)
def test_cone_stick_holds_the_start(backend: str) -> None:
    """A puck at rest on an incline with tan a = mu/2 sticks (both stick rows held): it stays where it starts,
    so d(x, y)/d(x0, y0) = I and every other column of (x, y) is 0 (the references move with the start)."""
    import test_friction_3d

    res = puck_run(backend, [0.0, 0.0, 0.0], {"a": math.atan(test_friction_3d.MU / 2)}, T)
    assert res.sensitivity_breaks == [] and res.active[:, 0].all()
    want = np.zeros((2, res.sensitivity.shape[2]))
    want[:, :2] = np.eye(2)
    assert np.abs(res.sensitivity[:, :2, :] - want).max() <= 1e-12


def _puck_perturbed(backend: str, v0, par: dict, t_end: float, name: str, c: int, e: float) -> vcigen.Result:
    """The puck's run from the origin with column ``c`` (named ``name``: ``q0``, ``v0`` or a parameter) moved
    by ``e``."""
    q, v, p = [0.0, 0.0, 0.0], list(v0), dict(par)
    if c < 3:
        q[c] += e
    elif c < 6:
        v[c - 3] += e
    else:
        p[name] += e
    return puck(backend).simulate(q, v, H, t_end=t_end, params=p, progress=False)


@pytest.mark.parametrize("backend", BACKENDS)
def test_cone_slip_on_an_incline_matches_finite_differences(backend: str) -> None:
    """Launched across an incline (tan a = mu/2): the sliding direction turns downhill while friction slows
    it; to t = 0.4 the tangent along every column but the normal ones against central differences of whole
    runs; it stops at 0.46 and sticks, a located stop of the cone the tangent carries since stop 28 (before: a
    break): C against CasADi through the stop to t = 0.8, and the state there against central differences."""
    import test_friction_3d

    par = {"a": math.atan(test_friction_3d.MU / 2), "g": G, "mu": test_friction_3d.MU}
    v0, t_end = [1.5, 0.5, 0.0], 0.4
    res = puck_run(backend, v0, par, t_end)
    assert res.sensitivity_breaks == [] and np.isfinite(res.sensitivity).all()
    names = res.sensitivity_names
    errs = {}
    for c in (0, 1, 3, 4, 6, 7, 8):
        hi, lo = (_puck_perturbed(backend, v0, par, t_end, names[c], c, e) for e in (1e-6, -1e-6))
        assert hi.active[:, 0].all() and lo.active[:, 0].all()
        fd = (np.hstack([hi.q, hi.p]) - np.hstack([lo.q, lo.p])) / 2e-6
        errs[names[c]] = float(np.abs(res.sensitivity[:, :, c] - fd).max())
    err = max(errs.values()) / float(np.abs(res.sensitivity).max())
    print(f"puck on the incline ({backend}): FD {err:.1e}")
    assert err <= FD_TOL, errs
    if backend == "c":
        a = puck_run("casadi", v0, par, 0.8)
        b = puck_run("c", v0, par, 0.8)  # through the stop: the same break
        fin = np.isfinite(a.sensitivity)
        rel = float(np.abs(a.sensitivity[fin] - b.sensitivity[fin]).max() / np.abs(a.sensitivity[fin]).max())
        print(f"puck on the incline to 0.8: C against CasADi {rel:.1e}, breaks {b.sensitivity_breaks[:1]}")
        assert (
            a.sensitivity_breaks == b.sensitivity_breaks == []
            and fin.all()
            and np.isfinite(b.sensitivity).all()
        )
        assert rel <= C_TOL
    end = puck_run(backend, v0, par, 0.8)  # through the stop: carried
    worst = 0.0
    for c in (0, 1, 3, 4, 6, 7, 8):
        hi, lo = (_puck_perturbed(backend, v0, par, 0.8, names[c], c, e) for e in (1e-5, -1e-5))
        fd = (np.hstack([hi.q[-1], hi.p[-1]]) - np.hstack([lo.q[-1], lo.p[-1]])) / 2e-5
        worst = max(worst, float(np.abs(end.sensitivity[-1, :, c] - fd).max()))
    worst /= max(1.0, float(np.abs(end.sensitivity[-1]).max()))
    print(f"puck on the incline to 0.8 ({backend}), through its stop: FD {worst:.1e}")
    assert end.sensitivity_breaks == [] and worst <= FD_TOL


@pytest.mark.parametrize("backend", BACKENDS)
def test_cone_impact_is_covered(backend: str) -> None:
    """The isotropic cone's impulse law at an impact (a puck dropped while sliding, sticking at the impact:
    ``vcigen.friction.cone_law_tangent``) has its tangent now, no break: the tangential momentum after it is 0
    whatever v0's tangential part, so its columns in v0[x], v0[y] vanish (to the discrete impulse's O(h^2));
    central differences and the slip branch in tests/test_sensitivity_cone_impact.py."""
    res = puck(backend).simulate(
        [0.0, 0.0, 0.5], [1.0, 0.5, 0.0], H, t_end=0.5, sensitivities=True, progress=False
    )
    assert res.sensitivity_breaks == [] and np.isfinite(res.sensitivity).all()
    k = res.impacts[0].step + 1
    assert np.abs(res.sensitivity[k:, 3:5, 3:5]).max() <= 1e-3
    assert np.abs(res.sensitivity[k:, 3:5, 3:5] - res.sensitivity[k, 3:5, 3:5]).max() <= 1e-12  # in flight


@cache
def puck_timed(backend: str) -> vcigen.Simulator:
    """The puck on the level floor with a plastic landing (``e = 0``) and a vertical force of time ``c t``
    (``c = 0.1``, far below ``g``): a cone under forces of time."""
    x, y, z, xd, yd, zd, t = sp.symbols("x y z xd yd zd t")
    g, mu, c = sp.symbols("g mu c")
    model = vcigen.Model(
        name="sf_puck_timed",
        q=[x, y, z],
        qdot=[xd, yd, zd],
        lagrangian=(xd**2 + yd**2 + zd**2) / 2 - g * z,
        contacts={"floor": z},
        params={g: G, mu: 0.5, c: 0.1},
        forces=[0, 0, c * t],
        time=t,
        friction={"floor": (mu, (x, y))},
        restitution={"floor": 0},
    )
    return vcigen.build(model, backend=backend)


@pytest.mark.parametrize("backend", BACKENDS)
def test_a_cone_landing_under_a_force_of_time_breaks_as_a_plastic_impact(backend: str) -> None:
    """The tangent does not carry a cone's held events under forces of time (``_events_tangent``: its slots
    hold the time fixed), so the rest of the step after a cone's plastic landing is a break with its own
    reason, ``"plastic impact"`` (``Stepper._tangent_held``, C ``WHY_PLASTIC_IMPACT``), at the landing's
    step: finite before it, NaN from it (``sensitivity_lost``). Dropped from 0.1 sliding at (0.7, 0.2), it
    lands at sqrt(2 h0/g) (the force of time shifts it by ~1e-5); the cone's impulse mu |p_z| = 0.70 leaves
    0.028 of its 0.728, which mu g stops 5.7 ms later, inside the landing step (7.2 ms left): at rest from
    there. The same on both backends. The untimed puck's landing is carried (no break)."""
    res = puck_timed(backend).simulate(
        [0.0, 0.0, 0.1], [0.7, 0.2, 0.0], H, t_end=T, sensitivities=True, progress=False
    )
    (landing,) = res.impacts
    assert landing.kind == "plastic" and abs(landing.t - math.sqrt(2 * 0.1 / G)) < 1e-4
    assert res.sensitivity_breaks == [(landing.step, "plastic impact")]
    assert res.stats["sensitivity_lost"] == landing.step
    assert np.isfinite(res.sensitivity[: landing.step + 1]).all()
    assert np.isnan(res.sensitivity[landing.step + 1 :]).all()
    assert np.abs(res.p[landing.step + 1 :, :2]).max() < 1e-12
