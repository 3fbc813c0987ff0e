"""``vcigen.casadi_functions``: the step maps as CasADi Functions (API.md, *Sensitivities ...*).

Two checks. Consistency of the API: along a run of ``vcigen.build(model, backend="casadi").simulate``, every
grid step without an impact equals ``"step"`` and every step with one impact equals ``"impact_<c>"``
(``q1``, ``p1``, ``alpha``, ``mu`` to 1e-12). Exactness of the derivatives: ``casadi.jacobian`` of the
Functions (implicit-function theorem through every rootfinder) against central finite differences of
one-step runs of ``simulate`` with respect to ``q0``, ``v0`` and the parameters.
"""

from __future__ import annotations

from functools import cache

import casadi as ca
import hard_scenes
import numpy as np
import pytest
from forced_scenes import driven_oscillator
from scenes import billiard, load_example

import vcigen
from vcigen.backends.casadi import routine_to_function

# scene -> (model maker, q0, v0, h, t_end): runs with single impacts of each kind
SCENES = {
    "particle": (lambda: load_example("particle").model(), [0.0, 1.0], [-2.0, 0.0], 0.01, 1.0),
    "star": (lambda: load_example("star").model(), [0.0, 1.2, 0.0], [-2.0, 0.0, 5.0], 0.005, 1.2),
    "double_pendulum": (hard_scenes.double_pendulum, [0.3, 0.6], [1.5, 2.0], 0.01, 0.6),
    "billiard": (billiard, [0.0, 0.2], [0.9, 1.3], 0.02, 3.0),
    "box_lossy": (lambda: hard_scenes.box(lossy=True), [0.5, 0.5], [1.3, -0.7], 0.01, 1.1),
    "driven": (driven_oscillator, [0.0], [3.0], 0.01, 4.0),
}
PARAMS = {"box_lossy": {"e": 0.6, "g": 9.81}}


@cache
def scene(name: str, rule: str = "trapezoid"):
    """``(model, functions, simulator)`` of a scene, built once."""
    model = SCENES[name][0]()
    return model, vcigen.casadi_functions(model, rule), vcigen.build(model, backend="casadi", rule=rule)


@cache
def run(name: str, rule: str = "trapezoid") -> vcigen.Result:
    _, _, q0, v0, h, t_end = (None, *SCENES[name])
    _, _, sim = scene(name, rule)
    return sim.simulate(q0=q0, v0=v0, h=h, t_end=t_end, params=PARAMS.get(name))


@pytest.mark.parametrize(
    "name,rule",
    [(n, "trapezoid") for n in SCENES]
    + [(n, "midpoint") for n in ("star", "double_pendulum", "driven")]
    # the internal points of lobatto3 solved inside the Functions, hidden from their signature
    + [(n, "lobatto3") for n in ("particle", "star", "double_pendulum", "box_lossy", "driven")],
)
def test_functions_reproduce_the_backend_step_by_step(name, rule):
    model, fs, _ = scene(name, rule)
    res = run(name, rule)
    h = res.h
    by_step: dict[int, list] = {}
    for im in res.impacts:
        by_step.setdefault(im.step, []).append(im)
    assert any(len(v) == 1 for v in by_step.values()), "the run must hold impacts"
    assert all(im.kind in ("elastic", "restitution") for im in res.impacts)
    checked = {"step": 0, "impact": 0}
    for k in range(res.t.size - 1):
        impacts = by_step.get(k, [])
        if len(impacts) > 1:
            continue  # several impacts in one step (78): not a function of this API
        par = vcigen.casadi_parameters(model, fs["step"], PARAMS.get(name), t=res.t[k])
        scale = 1.0 + np.abs(res.p[k + 1]).max()
        if not impacts:
            q1, p1 = (np.asarray(o).ravel() for o in fs["step"](res.q[k], res.p[k], h, par))
            checked["step"] += 1
        else:
            im = impacts[0]
            out = fs[f"impact_{im.contact}"](res.q[k], res.p[k], h, par)
            q1, p1, alpha, mu = (np.asarray(o).ravel() for o in out)
            assert abs(alpha[0] - im.alpha) <= 1e-12, (k, alpha, im.alpha)
            assert abs(mu[0] - im.impulse) <= 1e-12 * (1 + abs(im.impulse)), (k, mu, im.impulse)
            qc, pc, alpha_c = (
                np.asarray(o).ravel() for o in fs[f"contact_{im.contact}"](res.q[k], res.p[k], h, par)
            )
            assert np.abs(qc - im.q).max() <= 1e-12 * (1 + np.abs(im.q).max()) and alpha_c[0] == alpha[0], k
            checked["impact"] += 1
        assert np.abs(q1 - res.q[k + 1]).max() <= 1e-12 * (1 + np.abs(res.q[k + 1]).max()), k
        assert np.abs(p1 - res.p[k + 1]).max() <= 1e-12 * scale, k
    assert checked["impact"] >= 1 and checked["step"] >= 10, checked


def legendre(model) -> ca.Function:
    """``(q, v, par) -> p = dL/dqdot`` as a CasADi Function (the start of ``simulate``)."""
    return routine_to_function(vcigen.derive(model).routines["legendre"])


def exact_and_fd(name: str, k: int, eps: float = 1e-6, rule: str = "trapezoid"):
    """The Jacobian of grid step ``k`` of the scene's run with respect to ``(q_k, v_k, params)``: exact (the
    Functions composed with the Legendre transform) and by central differences of one-step ``simulate``
    runs from ``(q_k, v_k)``. ``v_k`` is the velocity of ``p_k``."""
    model, fs, sim = scene(name, rule)
    res = run(name, rule)
    h, n = res.h, model.n
    imps = [im for im in res.impacts if im.step == k]
    fn = fs["step"] if not imps else fs[f"impact_{imps[0].contact}"]
    par0 = vcigen.casadi_parameters(model, fn, PARAMS.get(name), t=res.t[k])
    npar = len(model.defaults)
    leg = legendre(model)
    mass = np.asarray(leg(res.q[k], np.zeros(n), par0)[1])
    v_k = np.linalg.solve(mass, res.p[k] - np.asarray(leg(res.q[k], np.zeros(n), par0)[0]).ravel())
    z = ca.MX.sym("z", 2 * n + npar)
    q, v, prm = z[:n], z[n : 2 * n], z[2 * n :]
    par = ca.vertcat(prm, par0[npar:])
    out = fn(q=q, p=leg(q, v, par)[0], h=h, par=par)
    qp = ca.vertcat(out["q1"], out["p1"])
    jac = ca.Function("step_jacobian", [z], [ca.jacobian(qp, z)])
    z0 = np.concatenate([res.q[k], v_k, par0[:npar]])
    exact = np.asarray(jac(z0))
    names = [str(s) for s in model.defaults]

    def one_step(zz):
        r = sim.simulate(
            q0=zz[:n],
            v0=zz[n : 2 * n],
            h=h,
            t_end=res.t[k] + h,
            t0=res.t[k],
            params=dict(zip(names, zz[2 * n :])),
        )
        assert len(r.impacts) == len(imps), "the perturbation changed the mode"
        return np.concatenate([r.q[-1], r.p[-1]])

    fd = np.empty_like(exact)
    for i in range(z0.size):
        dz = np.zeros(z0.size)
        dz[i] = eps * max(1.0, abs(z0[i]))
        fd[:, i] = (one_step(z0 + dz) - one_step(z0 - dz)) / (2 * dz[i])
    return exact, fd


def first_impact_step(name: str, rule: str = "trapezoid") -> int:
    res = run(name, rule)
    counts = np.bincount([im.step for im in res.impacts])
    return int(np.flatnonzero(counts == 1)[0])


@pytest.mark.parametrize("name", ["particle", "star", "double_pendulum", "box_lossy", "driven"])
@pytest.mark.parametrize("kind", ["step", "impact"])
def test_jacobian_matches_finite_differences(name, kind):
    k = first_impact_step(name)
    k = k if kind == "impact" else k - 3
    exact, fd = exact_and_fd(name, k)
    rel = np.abs(exact - fd).max() / np.abs(exact).max()
    assert rel <= 1e-6, (name, kind, rel)


@pytest.mark.parametrize("name", ["particle", "star", "double_pendulum", "box_lossy", "driven"])
@pytest.mark.parametrize("kind", ["step", "impact"])
def test_lobatto3_jacobian_matches_finite_differences(name, kind):
    """Under lobatto3 the internal points are unknowns of the same rootfinders: ``casadi.jacobian``
    differentiates through them (implicit-function theorem), against central differences of ``simulate``."""
    k = first_impact_step(name, "lobatto3")
    k = k if kind == "impact" else k - 3
    exact, fd = exact_and_fd(name, k, rule="lobatto3")
    rel = np.abs(exact - fd).max() / np.abs(exact).max()
    print(f"{name} {kind} [lobatto3]: relative FD agreement {rel:.1e}")
    assert rel <= 1e-6, (name, kind, rel)


def test_jacobian_is_not_the_smooth_one():
    """Through an impact the exact Jacobian is the impact's (the saltation), not the smooth step's."""
    model, fs, _ = scene("particle")
    res = run("particle")
    k = first_impact_step("particle")
    par = vcigen.casadi_parameters(model, fs["step"])
    jacs = []
    for f in (fs["step"], fs["impact_floor"]):
        z = ca.MX.sym("z", 4)
        out = f(q=z[:2], p=z[2:], h=res.h, par=par)
        jac = ca.Function("j", [z], [ca.jacobian(ca.vertcat(out["q1"], out["p1"]), z)])
        jacs.append(np.asarray(jac(np.concatenate([res.q[k], res.p[k]]))))
    # the bounce reverses the normal momentum: d p1_y / d p0_y is near -1 against +1 for the smooth step
    assert jacs[0][3, 3] > 0.9 and jacs[1][3, 3] < -0.9, (jacs[0][3, 3], jacs[1][3, 3])


def test_parameters_and_frictional_contacts():
    """``casadi_parameters`` is the vector ``simulate`` binds: friction slots 0, the start time last; a
    frictional contact has no impact Function (friction at impacts is not covered)."""
    block = load_example("friction/block").model()
    fs = vcigen.casadi_functions(block)
    assert set(fs) == {"step", "contact_floor"}
    par = vcigen.casadi_parameters(block, fs["step"], t=2.5)
    assert par.size == fs["step"].size1_in("par") > len(block.defaults)
    assert np.all(par[len(block.defaults) :] == 0.0)
    model = driven_oscillator()
    fd = vcigen.casadi_functions(model)
    par = vcigen.casadi_parameters(model, fd["impact_wall"], {"e": 0.5}, t=2.5)
    assert par[-1] == 2.5 and par.size == len(model.defaults) + 1
    assert par[list(map(str, model.defaults)).index("e")] == 0.5


def test_bad_input_is_refused_and_a_wrong_mode_shows_in_alpha():
    with pytest.raises(ValueError, match="vcigen.Model"):
        vcigen.casadi_functions("particle")
    with pytest.raises(ValueError, match="rule"):
        vcigen.casadi_functions(scene("particle")[0], rule="euler")
    model, fs, _ = scene("particle")
    par = vcigen.casadi_parameters(model, fs["step"])
    # far above the floor: the step holds no impact. The equations (47)-(48) still have a root, outside the
    # mode: alpha outside [0, 1] says so (the caller checks the mode; the Functions do not)
    for p0 in ([0.0, 1.0], [0.0, 0.0]):
        _, _, alpha, _ = fs["impact_floor"]([0.0, 5.0], p0, 0.01, par)
        assert not 0.0 <= float(alpha) <= 1.0, float(alpha)


def trajectory_jacobian(model, q0, v0, h: float, t_end: float) -> tuple[np.ndarray, np.ndarray, int]:
    """``d(q_N, p_N)/d v0`` of a whole run: the Functions composed along the run's mode sequence (exact), and
    central differences of whole ``simulate`` runs; and the number of impacts."""
    fs = vcigen.casadi_functions(model)
    sim = vcigen.build(model)
    par = vcigen.casadi_parameters(model, fs["step"])
    res = sim.simulate(q0=q0, v0=v0, h=h, t_end=t_end)
    modes = ["step"] * (res.t.size - 1)
    for im in res.impacts:
        assert modes[im.step] == "step", "one impact per step"
        modes[im.step] = f"impact_{im.contact}"
    n = model.n
    v = ca.MX.sym("v", n)
    q, p = ca.MX(np.asarray(q0, dtype=float)), legendre(model)(q0, v, par)[0]
    for mode in modes:
        out = fs[mode](q=q, p=p, h=h, par=par)
        q, p = out["q1"], out["p1"]
    exact = np.asarray(ca.Function("run_jacobian", [v], [ca.jacobian(ca.vertcat(q, p), v)])(v0))
    fd = np.empty_like(exact)
    for i in range(n):
        dv = np.zeros(n)
        dv[i] = 1e-6
        ends = []
        for sign in (1, -1):
            r = sim.simulate(q0=q0, v0=np.asarray(v0) + sign * dv, h=h, t_end=t_end)
            assert [(im.step, im.contact) for im in r.impacts] == [
                (im.step, im.contact) for im in res.impacts
            ]
            ends.append(np.concatenate([r.q[-1], r.p[-1]]))
        fd[:, i] = (ends[0] - ends[1]) / 2e-6
    return exact, fd, len(res.impacts)


@pytest.mark.parametrize(
    "name,q0,v0,h,t_end",
    [
        ("double_pendulum", [0.3, 0.6], [1.5, 2.0], 0.01, 0.6),
        ("star", [0.0, 1.2, 0.0], [-2.0, 0.0, 5.0], 0.005, 1.2),
    ],
)
def test_run_jacobian_through_impacts_matches_finite_differences(name, q0, v0, h, t_end):
    """Products along the run (MATH.md, *Exact sensitivities*): ``d(q_N, p_N)/d v0`` through every impact."""
    exact, fd, impacts = trajectory_jacobian(scene(name)[0], q0, v0, h, t_end)
    rel = np.abs(exact - fd).max() / np.abs(exact).max()
    print(f"{name}: {impacts} impacts, relative FD agreement {rel:.1e}")
    assert impacts >= 1 and rel <= 1e-6, (impacts, rel)
