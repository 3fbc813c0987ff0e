"""Exact sensitivities through a frictional impact on a contact with an isotropic Coulomb cone (two tangents,
``vcigen.friction.cone_law``; MATH.md *Friction*, *Exact sensitivities*), on both backends.

The impulse law is differentiated in the branch it takes (``vcigen.friction.cone_law_tangent``, C
``sens_cone_law``): stick (``H m + g = 0``) or slip on the cone's edge (the edge's equations in the tangential
impulse ``m`` and its multiplier ``nu``, by the implicit-function theorem). Checked:

* the law's tangent against central differences of the law itself (a pure function of nine scalars, ``mu_f``
  and ``e``), random inputs, both branches, tangents coupled to the normal (``b != 0``);
* whole runs against central differences of every column: a spinning ball dropped on a rough floor (rolling
  after the impact, or slipping throughout) and a turning rod's end (the normal coupled to the tangents, the
  branch confirmed by scipy's SLSQP in ``test_friction_3d.rod_reference``);
* the law's closed forms: a puck landing while sliding at ``v_t`` (``e = 1``): slipping, its tangential
  momentum after is ``v_t - mu_f P_n u``, ``u = v_t/|v_t|``, so across ``u`` its ``v_t`` columns are
  ``(1 - mu_f P_n/|v_t|) (I - u u^T)`` exactly, along ``u`` ``1`` and ``dp_t/dmu_f = -P_n u`` to the
  discrete impulse's O(h^2) from the continuous ``P_n = 2 sqrt(2 g z0)``; sticking, ``p_t = 0`` after, so
  its columns in ``v_t`` vanish to that order;
* C against CasADi to 1e-9.

A branch boundary (``-H^-1 g`` on the cone's edge) is a mode change: the branch taken is differentiated, no
break is reported; the scenes keep away from it.
"""

from __future__ import annotations

import math
from functools import cache

import hard_scenes
import numpy as np
import pytest
import test_friction_3d as rough
from hard_scenes import G

import vcigen
from vcigen.friction import cone_impulse, cone_law_tangent

BACKENDS = [hard_scenes.backend_param("casadi"), hard_scenes.backend_param("c")]
FD_TOL = 1e-6  # the tangent against central differences, relative to its largest entry
C_TOL = 1e-9  # C against CasADi, relative
EPS = 1e-6  # the central differences' step
needs_c = pytest.mark.skipif(
    hard_scenes.c_backend_problem() is not None, reason=str(hard_scenes.c_backend_problem())
)


# -- the law alone ----------------------------------------------------------------------------------------
def law(s: np.ndarray, mu_f: float, e: float) -> np.ndarray:
    """``(rho_1, rho_2, dK)`` of ``cone_law`` from its nine scalars (the same expressions)."""
    nv, t1v, t2v, nn, nt1, nt2, t11, t12, t22 = s
    a = -(1.0 + e) * nv / nn
    b = (nt1 / nn, nt2 / nn)
    g = (t1v - b[0] * nv, t2v - b[1] * nv)
    h = (t11 - nt1 * nt1 / nn, t12 - nt1 * nt2 / nn, t22 - nt2 * nt2 / nn)
    m = np.array(cone_impulse(g, h, b, mu_f, a))
    mu_n = a - b[0] * m[0] - b[1] * m[1]
    dk = (
        a * nv
        + 0.5 * a * a * nn
        + g @ m
        + 0.5 * (h[0] * m[0] ** 2 + 2 * h[1] * m[0] * m[1] + h[2] * m[1] ** 2)
    )
    return np.r_[m / mu_n, dk]


def test_cone_law_tangent_matches_finite_differences_of_the_law() -> None:
    """Random masses, normals, tangents (not M-orthogonal: b != 0), incoming velocities, mu_f and e: the
    tangent of (rho, dK) in all eleven inputs against central differences of the law, both branches met."""
    rng = np.random.default_rng(7)
    branches, worst = set(), 0.0
    for _ in range(40):
        root = rng.normal(size=(4, 4))
        minv = np.linalg.inv(root @ root.T + 4.0 * np.eye(4))
        n, t1, t2, vel = rng.normal(size=(4, 4))
        vel = -vel if n @ vel > 0 else vel
        s = np.array(
            [n @ vel, t1 @ vel, t2 @ vel]
            + [x @ minv @ y for x, y in ((n, n), (n, t1), (n, t2))]
            + [x @ minv @ y for x, y in ((t1, t1), (t1, t2), (t2, t2))]
        )
        mu_f, e = rng.uniform(0.05, 1.5), rng.uniform(0.0, 1.0)
        ds = np.zeros((9, 11))
        ds[:, :9] = np.eye(9)
        out = cone_law_tangent(s, ds, mu_f, np.eye(11)[9], e, np.eye(11)[10])
        assert out is not None
        rho, dk, drho, ddk, branch = out
        x = np.r_[s, mu_f, e]
        assert np.allclose(np.r_[rho, dk], law(s, mu_f, e), rtol=1e-13, atol=0)
        fd = np.empty((3, 11))
        for c in range(11):
            up, down = x.copy(), x.copy()
            up[c] += EPS
            down[c] -= EPS
            fd[:, c] = (law(up[:9], up[9], up[10]) - law(down[:9], down[9], down[10])) / (2 * EPS)
        exact = np.vstack([drho, ddk])
        worst = max(worst, float(np.abs(exact - fd).max() / np.abs(exact).max()))
        branches.add(branch)
    print(f"cone_law_tangent against central differences of the law: worst {worst:.1e}")
    assert branches == {0, 1} and worst <= 1e-7


# -- whole runs ------------------------------------------------------------------------------------------
def fd_error(
    sim: vcigen.Simulator, q0, v0, h: float, t_end: float, params: dict
) -> tuple[vcigen.Result, float]:
    """The run with its tangent and the worst entry of tangent - central differences over every column,
    relative to the tangent's largest (the same impact steps in every perturbed run)."""
    names = [str(s) for s in sim.model.defaults]
    values = {**dict(zip(names, sim.model.resolve_params(None))), **params}
    res = sim.simulate(q0, v0, h, t_end=t_end, params=values, sensitivities=True, progress=False)
    S, n = res.sensitivity, len(q0)
    fd = np.empty_like(S)
    for c in range(S.shape[2]):
        ends = []
        for sign in (1.0, -1.0):
            z, par = np.array([*q0, *v0], dtype=float), dict(values)
            if c < 2 * n:
                z[c] += sign * EPS
            else:
                par[names[c - 2 * n]] += sign * EPS
            r = sim.simulate(z[:n], z[n:], h, t_end=t_end, params=par, progress=False)
            assert [im.step for im in r.impacts] == [im.step for im in res.impacts], res.sensitivity_names[c]
            ends.append(np.hstack([r.q, r.p]))
        fd[:, :, c] = (ends[0] - ends[1]) / (2 * EPS)
    return res, float(np.abs(S - fd).max() / np.abs(S).max())


BALL = {"roll": (1.0, 4.0), "slip": (3.0, -20.0)}  # spins (wx, wy): test_friction_3d's two branches


def ball_run(spin) -> tuple[list[float], list[float]]:
    return [0.0, 0.0, 2.0, 0.0, 0.0], [2.0, -1.0, 0.0, *spin]


@pytest.mark.parametrize("branch", sorted(BALL))
@pytest.mark.parametrize("backend", BACKENDS)
def test_ball_impact_matches_finite_differences(backend: str, branch: str) -> None:
    """A ball (x, y, z, two rotation angles) dropped from height 1 with (vx, vy) = (2, -1) and a spin onto a
    floor with e = 0.7, mu_f = 0.3: one impact, after which it rolls (stick) or still slides (slip). Every
    column (q0, v0, m, I, r, g, mu, e) against central differences to t = 0.9 (before the second impact)."""
    q0, v0 = ball_run(BALL[branch])
    res, err = fd_error(rough.sim("ball", backend), q0, v0, 0.01, 0.9, {})
    print(f"ball impact, {branch} ({backend}): FD {err:.1e}")
    assert [im.kind for im in res.impacts] == ["restitution"] and res.sensitivity_breaks == []
    k = res.impacts[0].step + 2
    vel, w = res.p[k, :2] / rough.MASS, res.p[k, 3:] / rough.INERTIA
    sliding = math.hypot(vel[0] - rough.RADIUS * w[1], vel[1] + rough.RADIUS * w[0])
    assert (sliding < 1e-3) == (branch == "roll"), sliding
    assert err <= FD_TOL


ROD = {"stick": ((1.0, 0.5, 2.0), 0.7, 0.5, 0.3), "slip": ((3.0, 2.0, 0.5), 0.4, 0.3, 0.2)}  # v0, th0, e, mu


@pytest.mark.parametrize("branch", sorted(ROD))
@pytest.mark.parametrize("backend", BACKENDS)
def test_rod_impact_with_coupled_normal_matches_finite_differences(backend: str, branch: str) -> None:
    """A turning rod's end hits the floor, its cone's tangents coupled to the normal (b != 0): the branch as
    scipy's SLSQP finds it (test_friction_3d.rod_reference), every column against central differences."""
    v0, th0, e, mu = ROD[branch]
    assert rough.rod_reference(v0, th0, e, mu)[1] == (branch == "stick")
    res, err = fd_error(
        rough.sim("rod", backend),
        [0.0, 0.0, 1.0, th0],
        [v0[0], v0[1], 0.0, v0[2]],
        0.01,
        0.6,
        {"e": e, "mu": mu},
    )
    print(f"rod end impact, {branch} ({backend}): FD {err:.1e}")
    assert len(res.impacts) == 1 and res.sensitivity_breaks == []
    assert err <= FD_TOL


# -- closed forms: a puck landing while sliding ------------------------------------------------------------
PUCK_Z0, PUCK_H = 0.5, 0.01


@cache
def puck(backend: str) -> vcigen.Simulator:
    return vcigen.build(rough.puck(), backend=backend)


def puck_landing(backend: str, vt) -> vcigen.Result:
    return puck(backend).simulate(
        [0.0, 0.0, PUCK_Z0], [*vt, 0.0], PUCK_H, t_end=0.5, sensitivities=True, progress=False
    )


@pytest.mark.parametrize("backend", BACKENDS)
def test_puck_landing_slipping_is_the_closed_form(backend: str) -> None:
    """Landing at v_t = (4, 2) (|v_t| > 2 mu_f sqrt(2 g z0): it slips, e = 1): p_t+ = v_t - mu_f P_n u. Across
    u its v_t columns are (1 - mu_f P_n/|v_t|) (I - u u^T) and its mu_f column 0, exactly (P_n the discrete
    normal impulse, res.impacts[0].impulse: n's coefficient in n + rho t); along u, 1 and -P_n to the O(h^2)
    of the discrete impulse against the continuous 2 sqrt(2 g z0)."""
    vt = np.array([4.0, 2.0])
    res = puck_landing(backend, vt)
    assert [im.kind for im in res.impacts] == ["elastic"] and res.sensitivity_breaks == []
    k = res.impacts[0].step + 1
    speed, mu = float(np.linalg.norm(vt)), rough.MU
    u = vt / speed
    across = np.eye(2) - np.outer(u, u)
    p_n = res.impacts[0].impulse
    assert np.allclose(res.p[k, :2], vt - mu * p_n * u, rtol=0, atol=1e-12)  # slipping: along -u
    col = {name: i for i, name in enumerate(res.sensitivity_names)}
    S = res.sensitivity[k:, 3:5]  # the tangential momenta after the impact (constant in flight)
    dvt, dmu = S[:, :, [col["v0[x]"], col["v0[y]"]]], S[:, :, col["mu"]]
    assert np.abs(across @ dvt - (1 - mu * p_n / speed) * across).max() <= 1e-10
    assert np.abs(dmu @ across).max() <= 1e-10
    p_cont = 2.0 * math.sqrt(2.0 * G * PUCK_Z0)
    along = np.einsum("i,kij->kj", u, dvt)
    print(
        f"puck slipping ({backend}): along u {np.abs(along - u).max():.1e}, "
        f"dp/dmu {np.abs(dmu @ u + p_cont).max() / p_cont:.1e}"
    )
    assert np.abs(along - u).max() <= 1e-4 and np.abs(dmu @ u + p_cont).max() <= 1e-4 * p_cont


@pytest.mark.parametrize("backend", BACKENDS)
def test_puck_landing_sticking_stops_the_sliding(backend: str) -> None:
    """Landing at v_t = (1, 0.5) (|v_t| < 2 mu_f sqrt(2 g z0): it sticks): p_t = 0 after whatever v_t in the
    stick region, so its columns in v_t and mu_f vanish to the O(h^2) of the discrete impulse; every column
    against central differences too."""
    res, err = fd_error(puck(backend), [0.0, 0.0, PUCK_Z0], [1.0, 0.5, 0.0], PUCK_H, 0.5, {})
    assert [im.kind for im in res.impacts] == ["elastic"] and res.sensitivity_breaks == []
    k = res.impacts[0].step + 1
    col = {name: i for i, name in enumerate(res.sensitivity_names)}
    stuck = res.sensitivity[k:, 3:5][:, :, [col["v0[x]"], col["v0[y]"], col["mu"]]]
    print(f"puck sticking ({backend}): FD {err:.1e}, |dp_t/d(v_t, mu_f)| {np.abs(stuck).max():.1e}")
    assert np.abs(res.p[k, :2]).max() <= 1e-3 and np.abs(stuck).max() <= 1e-3
    assert err <= FD_TOL


@needs_c
def test_cone_impact_c_equals_casadi() -> None:
    """Every scene above: the C tangent (sens_cone_impact, sens_cone_law) against the CasADi one."""
    runs = {
        **{
            f"ball {b}": lambda be, b=b: rough.sim("ball", be).simulate(
                *ball_run(BALL[b]), 0.01, t_end=0.9, sensitivities=True, progress=False
            )
            for b in BALL
        },
        **{
            f"rod {b}": lambda be, b=b: rough.sim("rod", be).simulate(
                [0.0, 0.0, 1.0, ROD[b][1]],
                [ROD[b][0][0], ROD[b][0][1], 0.0, ROD[b][0][2]],
                0.01,
                t_end=0.6,
                params={"e": ROD[b][2], "mu": ROD[b][3]},
                sensitivities=True,
                progress=False,
            )
            for b in ROD
        },
        **{f"puck {vt}": lambda be, vt=vt: puck_landing(be, vt) for vt in ((4.0, 2.0), (1.0, 0.5))},
    }
    for scene, run in runs.items():
        a, b = run("casadi"), run("c")
        rel = float(np.abs(a.sensitivity - b.sensitivity).max() / np.abs(a.sensitivity).max())
        print(f"{scene}: C against CasADi {rel:.1e}")
        assert a.sensitivity_breaks == b.sensitivity_breaks == [] and rel <= C_TOL, scene
