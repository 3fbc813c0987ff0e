"""``simulate(..., sensitivities=True)`` under the fourth-order rule ``lobatto3`` (internal points).

The internal point ``u`` of each segment is one more unknown of every phase's implicit-function theorem
(its stationarity rows are in the residuals): smooth step (46), contact time (47), jump (48), several
impacts in one step (78), restitution (39), forces. Checked as ``tests/test_sensitivity.py`` checks the
trapezoid rule, on both backends (the Python stepper's tangent, ``vcigen.sensitivity``; the C loop's,
``templates/sens.c.j2``): against central finite differences of whole runs with the same mode sequence,
the symplecticity of impact steps from the exact tangent, and C = CasADi. The held phases (sustained
contact: held steps, bilateral constraints, the plastic entry, lift-off): FD agreement and the symplecticity
of held steps on the constraint manifold, on both backends, and C = CasADi.
"""

from __future__ import annotations

from functools import cache

import hard_scenes
import numpy as np
import pytest
import sympy as sp
from test_sensitivity import (
    HELD_SCENES,
    LIFT_SCENES,
    SCENES,
    finite_differences,
    held_finite_differences,
    held_mode,
    liftoff_tangent_matches_finite_differences,
    relative_error,
    step_jacobians,
)

import vcigen
from vcigen.analysis import jacobian_symplectic_defect

RULE = "lobatto3"


# The scenes of tests/test_sensitivity.py, but the two walls from x = 0.003: from 0.004 lobatto3 puts one
# impact within 1e-4 of a grid node, where the finite differences' perturbation moves it to the next step
# (a mode change, not differentiable).
SETUPS = SCENES | {"walls": (hard_scenes.walls, [0.003, 0.0], [0.9, 0.3], 0.02, 0.2, None)}


BACKENDS = ["casadi", hard_scenes.backend_param("c")]


@cache
def simulator(scene: str, backend: str = "casadi") -> vcigen.Simulator:
    return vcigen.build(SETUPS[scene][0](), backend=backend, rule=RULE)


@pytest.mark.parametrize("backend", BACKENDS)
@pytest.mark.parametrize("scene", ["box", "star", "double_pendulum", "box_lossy", "walls", "driven"])
def test_sensitivity_matches_finite_differences(scene: str, backend: str) -> None:
    sim = simulator(scene, backend)
    res, fd = finite_differences(sim, scene, setup=SETUPS[scene])
    n = sim.model.n
    assert res.sensitivity.shape == (res.t.size, 2 * n, 2 * n + len(sim.model.defaults))
    assert res.sensitivity_breaks == [] and "sensitivity_lost" not in res.stats
    rel = relative_error(res.sensitivity, fd)
    print(f"{scene} [lobatto3, {backend}]: {res.n_impacts} impacts, relative FD agreement {rel:.1e}")
    assert res.n_impacts >= 1 and rel <= 1e-6, (res.n_impacts, rel)


@pytest.mark.parametrize("backend", BACKENDS)
@pytest.mark.parametrize("scene", ["box", "star", "double_pendulum", "walls"])
def test_impact_steps_are_symplectic(scene: str, backend: str) -> None:
    """Elastic impact steps (and smooth ones) from the exact tangent: ``|J^T Omega J - Omega| <= 1e-12``."""
    sim = simulator(scene, backend)
    _, q0, v0, h, t_end, params = SETUPS[scene]
    res = sim.simulate(q0, v0, h, t_end=t_end, params=params, sensitivities=True, progress=False)
    impact_steps = sorted({im.step for im in res.impacts})
    defects = [jacobian_symplectic_defect(j) for j in step_jacobians(res, impact_steps)]
    free = [k for k in range(res.t.size - 1) if k not in impact_steps]
    smooth = max((jacobian_symplectic_defect(j) for j in step_jacobians(res, free)), default=0.0)
    print(
        f"{scene} [lobatto3, {backend}]: {len(defects)} impact steps, defect {max(defects):.1e}, "
        f"smooth {smooth:.1e}"
    )
    assert defects and max(defects) <= 1e-12 and smooth <= 1e-12, (defects, smooth)


@pytest.mark.parametrize("backend", BACKENDS)
@pytest.mark.parametrize("scene", ["box_lossy", "driven", "walls", "corner"])
def test_sensitivities_leave_the_run_unchanged(scene: str, backend: str) -> None:
    """Asking for sensitivities changes nothing else, bit for bit (the internal points are recovered for the
    tangent, never written back). In C the variant is another library: the corner (an impact step first, so
    the implicit grid step's carried ``u`` was never set) failed there before the carry took each step's."""
    sim = simulator(scene, backend)
    _, q0, v0, h, t_end, params = SETUPS[scene]
    off = sim.simulate(q0, v0, h, t_end=t_end, params=params, progress=False)
    on = sim.simulate(q0, v0, h, t_end=t_end, params=params, sensitivities=True, progress=False)
    for name in ("t", "q", "p", "energy", "work"):
        assert np.array_equal(getattr(off, name), getattr(on, name)), name
    assert off.impacts == on.impacts and on.n_impacts >= 1 and np.isfinite(on.sensitivity).all()


def test_closed_form_under_lobatto3() -> None:
    """A ball dropped on a floor (V = g y, e = 1): before the bounce y(t) = y0 + v0 t - g t^2/2 exactly (the
    rule is exact on quadratics), so dy/dg = -t^2/2 and dy/dv0 = t on the grid, to round-off."""
    y, yd, g = sp.symbols("y yd g")
    model = vcigen.Model(
        name="drop", q=[y], qdot=[yd], lagrangian=yd**2 / 2 - g * y, contacts={"floor": y}, params={g: 9.81}
    )
    sim = vcigen.build(model, backend="casadi", rule=RULE)
    res = sim.simulate([1.0], [0.5], 0.01, t_end=0.4, sensitivities=True, progress=False)
    assert res.n_impacts == 0
    t = res.t
    assert np.abs(res.sensitivity[:, 0, 2] + t**2 / 2).max() <= 1e-12
    assert np.abs(res.sensitivity[:, 0, 1] - t).max() <= 1e-12


ALL = ["box", "star", "double_pendulum", "box_lossy", "walls", "driven", "corner"]


@pytest.mark.parametrize("backend", [hard_scenes.backend_param("c")])
@pytest.mark.parametrize("scene", ALL)
def test_c_equals_casadi(scene: str, backend: str) -> None:
    """The C loop's tangent (``sens.c.j2`` with the internal points) equals the Python stepper's to 1e-9."""
    _, q0, v0, h, t_end, params = SETUPS[scene]
    kw = {"t_end": t_end, "params": params, "sensitivities": True, "progress": False}
    py, c = (simulator(scene, b).simulate(q0, v0, h, **kw) for b in ("casadi", backend))
    assert [(im.step, im.contact) for im in py.impacts] == [(im.step, im.contact) for im in c.impacts]
    assert not c.sensitivity_breaks and c.n_impacts >= 1
    rel = relative_error(c.sensitivity, py.sensitivity)
    print(f"{scene} [lobatto3]: C against CasADi {rel:.1e}")
    assert rel <= 1e-9, rel


# ------------------------------------------------------------------ held phases (sustained contact)
# The internal point is held on the active rows with its own multipliers Lam_m (derive.held_internal_points):
# the held step's tangent solves rattle's (v, Lam, Lam_m, u) by the implicit-function theorem and takes p+
# from rattle_end (Tracker._held_sub; C sens_held, sens_liftoff under internal points).


@cache
def held_simulator(scene: str, backend: str = "casadi") -> vcigen.Simulator:
    return vcigen.build(HELD_SCENES[scene][0](), backend=backend, rule=RULE)


@cache
def lift_simulator(scene: str, backend: str = "casadi") -> vcigen.Simulator:
    return vcigen.build(LIFT_SCENES[scene][0](), backend=backend, rule=RULE)


def _pairs(scenes):
    for scene in sorted(scenes):
        for b in BACKENDS:
            backend, marks = (b, ()) if isinstance(b, str) else (b.values[0], b.marks)
            yield pytest.param(scene, backend, marks=marks, id=f"{scene}-{backend}")


@pytest.mark.parametrize("scene, backend", list(_pairs(HELD_SCENES)))
def test_held_steps_match_finite_differences(scene: str, backend: str) -> None:
    """Sustained contact with a fixed active set under lobatto3 (the scenes of tests/test_sensitivity.py: the
    Cartesian pendulum on a rod, sliding on a floor and down an incline, resting, the box and the star on a
    face, the bowl, the dragged particle with forces of time): central differences of whole runs along paths
    that keep the mode; every step covered."""
    sim = held_simulator(scene, backend)
    res, per = held_finite_differences(sim, scene)
    assert res.active[1:].any(axis=1).all() or sim.model.constraint
    assert res.sensitivity_breaks == [] and np.isfinite(res.sensitivity).all()
    errs = {label: relative_error(exact, fd) for label, (exact, fd) in per.items()}
    print(f"{scene} [lobatto3, {backend}]: " + ", ".join(f"{k} {v:.1e}" for k, v in errs.items()))
    assert max(errs.values()) <= 1e-6, errs
    assert max(np.abs(exact[-1]).max() for exact, _ in per.values()) > 0.1


@pytest.mark.parametrize("backend", BACKENDS)
@pytest.mark.parametrize("scene", ["rod", "incline", "slide", "box_face"])
def test_held_steps_are_symplectic_on_the_constraint_manifold(scene: str, backend: str) -> None:
    """A held step maps the constraint manifold's cotangent bundle to itself symplectically (RATTLE, and the
    Lobatto IIIA-IIIB SPARK step): the tangent's columns after the first step lie on it, so the Gram matrix
    ``S_k^T Omega S_k`` of their symplectic products is the same at every grid point ``k >= 1`` (round-off).
    Dropping the internal points' share of ``p+`` (``d_rattle_end``'s ``u`` or ``Lam_m`` columns) moves it
    by 1e-7 and 2e-4 on the rod."""
    _, q0, v0, h, t_end, params, _ = HELD_SCENES[scene]
    sim = held_simulator(scene, backend)
    res = sim.simulate(q0, v0, h, t_end=t_end, params=params, sensitivities=True, progress=False)
    n = len(q0)
    s = res.sensitivity[:, :, : 2 * n]
    omega = np.block([[np.zeros((n, n)), np.eye(n)], [-np.eye(n), np.zeros((n, n))]])
    gram = np.einsum("kia,ij,kjb->kab", s, omega, s)
    drift = float(np.abs(gram[2:] - gram[1:-1]).max())
    print(
        f"{scene} [lobatto3, {backend}]: symplectic drift {drift:.1e} (|S^T W S| {np.abs(gram[1]).max():.2f})"
    )
    assert np.abs(gram[1]).max() > 0.5 and drift <= 1e-13, drift


@pytest.mark.parametrize("scene, backend", list(_pairs(LIFT_SCENES)))
def test_liftoff_matches_finite_differences(scene: str, backend: str) -> None:
    """A lift-off located inside a held step under lobatto3 (the dome, the hump): the constrained sub-step to
    the root of the row's force, its time by the implicit-function theorem, then the free rest (46) with its
    internal point; against central differences of whole runs along paths that keep the mode."""
    label = f"{scene} [lobatto3, {backend}]"
    liftoff_tangent_matches_finite_differences(lift_simulator(scene, backend), scene, label)


BALL = {"q0": [0.0, 1.0], "v0": [0.3, 0.0], "h": 0.005, "t_end": 3.0, "params": {"e": 0.5}, "progress": False}


@pytest.mark.parametrize("backend", BACKENDS)
def test_a_ball_coming_to_rest_matches_finite_differences(backend: str) -> None:
    """A lossy ball bouncing to rest under lobatto3: restitution impacts, the plastic entry (contact time,
    the impulse law, the constrained rest of its step from the impact point), then held steps: covered to the
    end, against central differences of every column (the perturbed runs keep impacts, kinds, active sets);
    asking for the tangent leaves the run unchanged."""
    sim = hard_scenes.simulator("ball", backend, RULE, None)
    res = sim.simulate(**BALL, sensitivities=True)
    np.testing.assert_array_equal(res.q, sim.simulate(**BALL).q)
    kinds = [im.kind for im in res.impacts]
    assert kinds[-1] == "plastic" and kinds.count("restitution") >= 4 and res.active[-1].all()
    assert res.sensitivity_breaks == [] and np.isfinite(res.sensitivity).all()
    fd = np.empty_like(res.sensitivity)
    z0 = np.array(BALL["q0"] + BALL["v0"] + [0.5])
    for c in range(5):
        ends = []
        for sign in (1.0, -1.0):
            z = z0.copy()
            z[c] += sign * 1e-6
            r = sim.simulate(**{**BALL, "q0": z[:2], "v0": z[2:4], "params": {"e": z[4]}})
            assert held_mode(r) == held_mode(res), res.sensitivity_names[c]
            ends.append(np.hstack([r.q, r.p]))
        fd[:, :, c] = (ends[0] - ends[1]) / 2e-6
    err = relative_error(res.sensitivity, fd)
    print(f"ball to rest [lobatto3, {backend}]: {len(kinds)} impacts, FD {err:.1e}")
    assert err <= 1e-6, err


HELD_AGREEMENT = {**{s: (held_simulator, HELD_SCENES) for s in HELD_SCENES}}
HELD_AGREEMENT |= {s: (lift_simulator, LIFT_SCENES) for s in LIFT_SCENES}


@pytest.mark.parametrize("backend", [hard_scenes.backend_param("c")])
@pytest.mark.parametrize("scene", ["ball", *sorted(HELD_AGREEMENT)])
def test_c_held_phases_equal_casadi(scene: str, backend: str) -> None:
    """The C loop's held phases under internal points (sens_held, sens_plastic, sens_liftoff) equal the Python
    stepper's tangent to 1e-9, with the same (no) breaks."""
    if scene == "ball":
        py, c = (
            hard_scenes.simulator("ball", b, RULE, None).simulate(**BALL, sensitivities=True)
            for b in ("casadi", backend)
        )
    else:
        make, scenes = HELD_AGREEMENT[scene]
        _, q0, v0, h, t_end, params, _ = scenes[scene]
        kw = {"t_end": t_end, "params": params, "sensitivities": True, "progress": False}
        py, c = (make(scene, b).simulate(q0, v0, h, **kw) for b in ("casadi", backend))
    assert held_mode(py) == held_mode(c)
    assert c.sensitivity_breaks == py.sensitivity_breaks == [] and np.isfinite(c.sensitivity).all()
    rel = relative_error(c.sensitivity, py.sensitivity)
    print(f"{scene} [lobatto3]: C against CasADi {rel:.1e}")
    assert rel <= 1e-9, rel


@pytest.mark.parametrize("backend", BACKENDS)
@pytest.mark.parametrize("scene", ["lifted", "drop"])
def test_liftoff_under_a_force_of_time_and_after_a_plastic_impact(scene: str, backend: str) -> None:
    """tests/test_sensitivity_liftoff_c.py's scenes under lobatto3: a particle lifted off a floor by a force
    of time (the located root's time slot chained), and the same dropped onto the floor so that the plastic
    impact and the lift-off fall in one step (``Tracker.liftoff`` with ``entry``: the sub-step starts from the
    impact point); against central differences, and C = CasADi."""
    from test_sensitivity_liftoff_c import DROP, LIFTED

    scenes = DROP if scene == "drop" else LIFTED
    make, q0, v0, h, t_end, params, _ = scenes[scene]
    sim = vcigen.build(make(), backend=backend, rule=RULE)
    res, per = held_finite_differences(sim, scene, scenes=scenes)
    assert len(res.liftoffs) == 1 and res.sensitivity_breaks == [] and np.isfinite(res.sensitivity).all()
    lift = int((res.liftoffs[0][0] - res.t[0]) / (res.t[1] - res.t[0]))
    if scene == "drop":
        assert [(im.step, im.kind) for im in res.impacts] == [(lift, "plastic")]
    errs = {label: relative_error(exact, fd) for label, (exact, fd) in per.items()}
    print(f"{scene} [lobatto3, {backend}]: " + ", ".join(f"{k} {v:.1e}" for k, v in errs.items()))
    assert max(errs.values()) <= 1e-6, errs
    if backend != "casadi":
        kw = {"t_end": t_end, "params": params, "sensitivities": True, "progress": False}
        ref = vcigen.build(make(), backend="casadi", rule=RULE).simulate(q0, v0, h, **kw)
        assert relative_error(res.sensitivity, ref.sensitivity) <= 1e-9
