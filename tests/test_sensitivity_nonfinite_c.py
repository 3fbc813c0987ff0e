"""A non-finite tangent on the C variant's fast paths is a reported break, never a silent NaN nor a wrong
tangent.

The fast paths (``templates/sens_run.c.j2``) check the tangent as they store it into its row: the explicit
glide's fused smooth map (``sens_smooth_map``, checked by ``sens_row``) and the held glide's fused held map
(``sens_held_step``: a non-finite map falls back to the numeric tangent of ``sens_held``, which then names the
break as the Python tracker does). The scenes put a parameter ``c = 0`` under a square root: the trajectory
is finite (``sqrt(0) = 0``), the tangent's column ``d/dc`` is not (``1/(2 sqrt(0))``). Both backends must
report the same break at the same step, the tangent finite before it and NaN after it
(``test_sensitivity.assert_lost``).
"""

from __future__ import annotations

import hard_scenes
import numpy as np
import pytest
import sympy as sp
import test_sensitivity as ts

import vcigen
from vcigen.backends.ccontext import render_context
from vcigen.derive import derive

pytestmark = pytest.mark.skipif(
    hard_scenes.c_backend_problem() is not None, reason=str(hard_scenes.c_backend_problem())
)
KINK = 0.3  # where the floor's d/dc turns infinite


def kinked_floor() -> vcigen.Model:
    """A unit ball held on the floor ``y = sqrt(c) (x - 0.3)`` for ``x > 0.3``, ``y = 0`` before: flat at
    ``c = 0``, its row's ``d/dc`` 0 up to the kink and infinite past it."""
    x, y, xd, yd = sp.symbols("x y xd yd")
    c, e = sp.symbols("c e")
    return vcigen.Model(
        name="kinked_floor",
        q=[x, y],
        qdot=[xd, yd],
        lagrangian=(xd**2 + yd**2) / 2 - 9.81 * y,
        contacts={"floor": y - sp.Piecewise((0, x <= KINK), (sp.sqrt(c) * (x - KINK), True))},
        params={c: 0.0, e: 0.5},
        restitution={"floor": e},
    )


def root_field() -> vcigen.Model:
    """A unit particle in free flight under gravity and the potential ``sqrt(c) x``: no force at ``c = 0``,
    the force's ``d/dc`` infinite."""
    x, y, xd, yd = sp.symbols("x y xd yd")
    c = sp.Symbol("c")
    return vcigen.Model(
        name="root_field",
        q=[x, y],
        qdot=[xd, yd],
        lagrangian=(xd**2 + yd**2) / 2 - 9.81 * y - sp.sqrt(c) * x,
        contacts={"floor": y},
        params={c: 0.0},
    )


def runs(model: vcigen.Model, q0, v0, h: float, t_end: float) -> tuple[vcigen.Result, vcigen.Result]:
    kw = {"sensitivities": True, "progress": False}
    out = []
    for backend in ("casadi", "c"):
        with np.errstate(invalid="ignore", divide="ignore"):  # the Python tracker's solve meets the inf
            out.append(vcigen.build(model, backend=backend).simulate(q0, v0, h, t_end=t_end, **kw))
    return out[0], out[1]


@pytest.mark.filterwarnings("ignore::RuntimeWarning")
def test_a_non_finite_fused_held_map_is_a_break() -> None:
    """The held glide's fused map goes non-finite mid-run (the step that crosses the kink): the row is not
    kept, the numeric tangent takes the step and the break is reported there, as in the Python tracker."""
    model = kinked_floor()
    ctx = render_context(derive(model, sensitivities=True), sensitivities=True)
    assert [m["rows"] for m in ctx["held_maps"]] == [[0]]  # the fast path exists for this row
    py, c = runs(model, [0.0, 0.0], [1.0, 0.0], 0.01, 1.0)
    assert c.active[1:, 0].all() and np.abs(c.q[:, 1]).max() == 0.0  # held on the floor throughout
    cross = int(np.flatnonzero(c.q[1:, 0] > KINK)[0])  # the first step whose end is past the kink
    assert ts.assert_lost(c, "non-finite") == ts.assert_lost(py, "non-finite") == cross
    assert c.sensitivity_breaks == py.sensitivity_breaks
    fin = np.isfinite(py.sensitivity)
    assert np.array_equal(fin, np.isfinite(c.sensitivity))
    assert np.abs(c.sensitivity[fin] - py.sensitivity[fin]).max() <= 1e-12


@pytest.mark.filterwarnings("ignore::RuntimeWarning")
def test_a_non_finite_smooth_map_is_a_break() -> None:
    """The explicit glide's fused smooth map is non-finite from the first step: a break at step 0 on both
    backends, not a run of NaN rows without one."""
    model = root_field()
    ctx = render_context(derive(model, sensitivities=True), sensitivities=True)
    assert ctx["sens_map"]  # the glide's tangent is the fused map
    py, c = runs(model, [0.5, 5.0], [1.0, 0.0], 0.01, 0.5)
    assert c.n_impacts == 0
    assert ts.assert_lost(c, "non-finite") == ts.assert_lost(py, "non-finite") == 0
    assert c.sensitivity_breaks == py.sensitivity_breaks
