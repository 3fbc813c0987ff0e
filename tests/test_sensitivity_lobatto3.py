"""``simulate(..., sensitivities=True)`` under the fourth-order rule ``lobatto3`` (internal points).

The internal point ``u`` of each segment is one more unknown of every phase's implicit-function theorem
(its stationarity rows are in the residuals): smooth step (46), contact time (47), jump (48), several
impacts in one step (78), restitution (39), forces. Checked as ``tests/test_sensitivity.py`` checks the
trapezoid rule, on both backends (the Python stepper's tangent, ``vcigen.sensitivity``; the C loop's,
``templates/sens.c.j2``): against central finite differences of whole runs with the same mode sequence,
the symplecticity of impact steps from the exact tangent, and C = CasADi.
"""

from __future__ import annotations

from functools import cache

import hard_scenes
import numpy as np
import pytest
import sympy as sp
from test_sensitivity import SCENES, finite_differences, relative_error, step_jacobians

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


@pytest.mark.parametrize("backend", BACKENDS)
def test_held_phases_say_they_have_no_tangent(backend: str) -> None:
    """A ball coming to rest under lobatto3 (tests/test_lobatto3_sustained.py): the restitution impacts are
    differentiated, the plastic entry is reported as a break with its reason (never a wrong tangent), the run
    itself is the one without sensitivities, and the C loop breaks where the Python stepper does."""
    sim = hard_scenes.simulator("ball", backend, RULE, None)
    run = {"q0": [0.0, 1.0], "v0": [0.3, 0.0], "h": 0.005, "t_end": 3.0, "params": {"e": 0.5}}
    run["progress"] = False
    res = sim.simulate(**run, sensitivities=True)
    plain = sim.simulate(**run)
    np.testing.assert_array_equal(res.q, plain.q)
    kinds = [im.kind for im in res.impacts]
    assert "plastic" in kinds and kinds.index("plastic") >= 3
    k = res.stats["sensitivity_lost"]
    assert res.sensitivity_breaks[0] == (k, "held phases under a rule with internal points")
    entry = res.impacts[kinds.index("plastic")].t
    assert res.t[k] < entry <= res.t[k + 1]  # lost at the plastic impact's step, not before
    assert np.isfinite(res.sensitivity[: k + 1]).all() and np.isnan(res.sensitivity[k + 1 :]).all()
    if backend != "casadi":
        ref = hard_scenes.simulator("ball", "casadi", RULE, None).simulate(**run, sensitivities=True)
        assert ref.sensitivity_breaks == res.sensitivity_breaks
        assert np.max(np.abs(res.sensitivity[: k + 1] - ref.sensitivity[: k + 1])) <= 1e-9
