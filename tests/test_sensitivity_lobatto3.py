"""``simulate(..., sensitivities=True)`` under the fourth-order rule ``lobatto3`` (internal points).

The internal point ``u`` of each segment is one more unknown of every phase's implicit-function theorem
(its stationarity rows are in the residuals): smooth step (46), contact time (47), jump (48), several
impacts in one step (78), restitution (39), forces. Checked as ``tests/test_sensitivity.py`` checks the
trapezoid rule: against central finite differences of whole runs with the same mode sequence, and the
symplecticity of impact steps from the exact tangent. The C loop's tangent has no internal points yet: a
``ValueError``.
"""

from __future__ import annotations

from functools import cache

import hard_scenes
import numpy as np
import pytest
import sympy as sp
from test_sensitivity import SCENES, finite_differences, mode, relative_error, step_jacobians

import vcigen
from vcigen.analysis import jacobian_symplectic_defect

RULE = "lobatto3"


@cache
def simulator(scene: str) -> vcigen.Simulator:
    return vcigen.build(SCENES[scene][0](), backend="casadi", rule=RULE)


@pytest.mark.parametrize("scene", ["box", "star", "double_pendulum", "box_lossy", "walls", "driven"])
def test_sensitivity_matches_finite_differences(scene: str) -> None:
    sim = simulator(scene)
    res, fd = finite_differences(sim, scene)
    n = sim.model.n
    assert res.sensitivity.shape == (res.t.size, 2 * n, 2 * n + len(sim.model.defaults))
    assert res.sensitivity_breaks == [] and "sensitivity_lost" not in res.stats
    rel = relative_error(res.sensitivity, fd)
    print(f"{scene} [lobatto3]: {res.n_impacts} impacts, relative FD agreement {rel:.1e}")
    assert res.n_impacts >= 1 and rel <= 1e-6, (res.n_impacts, rel)


@pytest.mark.parametrize("scene", ["box", "star", "double_pendulum", "walls"])
def test_impact_steps_are_symplectic(scene: str) -> None:
    """Elastic impact steps (and smooth ones) from the exact tangent: ``|J^T Omega J - Omega| <= 1e-12``."""
    sim = simulator(scene)
    _, q0, v0, h, t_end, params = SCENES[scene]
    res = sim.simulate(q0, v0, h, t_end=t_end, params=params, sensitivities=True, progress=False)
    impact_steps = sorted({im.step for im in res.impacts})
    defects = [jacobian_symplectic_defect(j) for j in step_jacobians(res, impact_steps)]
    free = [k for k in range(res.t.size - 1) if k not in impact_steps]
    smooth = max((jacobian_symplectic_defect(j) for j in step_jacobians(res, free)), default=0.0)
    print(f"{scene} [lobatto3]: {len(defects)} impact steps, defect {max(defects):.1e}, smooth {smooth:.1e}")
    assert defects and max(defects) <= 1e-12 and smooth <= 1e-12, (defects, smooth)
