"""Exact sensitivities through events inside held steps under the fourth-order rule ``lobatto3`` (issue
11 item 1): the scenes of tests/test_sensitivity_held_events.py built with internal points. A lift-off
located inside a held step, then free flight and an impact in the same step; two lift-offs in one step;
impacts while another row or a bilateral constraint is held (elastic, restitution, plastic); a plastic impact
released at once. The internal point of every constrained sub-step is held on the active rows with its own
multipliers (``Tracker._held_sub``; C ``sens_sub``), the free rest carries its own (``Tracker._free_end``;
C ``sens_free_end``). Against central differences of whole runs along paths that keep the mode and against
a closed form, on both backends; C = CasADi; what stays uncovered breaks with its reason.
"""

from __future__ import annotations

from functools import cache

import hard_scenes
import numpy as np
import pytest
from test_sensitivity import BACKENDS, HELD_SCENES, assert_lost, relative_error
from test_sensitivity_held_events import (
    SCENES,
    _pairs,
    c_equals_casadi,
    events_match_finite_differences,
    pair,
)

import vcigen

RULE = "lobatto3"


@cache
def _built(maker, backend: str) -> vcigen.Simulator:
    return vcigen.build(maker(), backend=backend, rule=RULE)


def simulator(scene: str, backend: str) -> vcigen.Simulator:
    """The scene's lobatto3 simulator, one build per model (the walls and the boxes share theirs)."""
    return _built(SCENES[scene][0], backend)


@pytest.mark.parametrize("scene, backend", list(_pairs()))
def test_events_inside_held_steps_match_finite_differences(scene: str, backend: str) -> None:
    """The tangent across events inside held steps under lobatto3 against central differences of whole runs
    (every grid point, every path of the scene), covered throughout (no break), with the events the scene is
    made for."""
    events_match_finite_differences(simulator(scene, backend), scene, f"lobatto3, {backend}")


@pytest.mark.skipif(hard_scenes.c_backend_problem() is not None, reason=str(hard_scenes.c_backend_problem()))
@pytest.mark.parametrize("scene", sorted(SCENES))
def test_c_equals_casadi(scene: str) -> None:
    """The C loop's tangent (sens_events.c.j2 over sens_sub with the internal points) is the Python
    stepper's to 1e-9, with the same (no) breaks, and its run is the plain library's bit for bit."""
    c_equals_casadi(simulator, scene, " [lobatto3]")


@pytest.mark.parametrize("backend", BACKENDS)
def test_the_wall_hit_while_held_has_its_closed_form(backend: str) -> None:
    """The particle held on the floor sliding into the elastic wall ``x <= W``: ``x`` moves freely at constant
    velocity and is reflected, so for every rule ``x = x0 + v0 t`` before the impact and ``2 W - x0 - v0 t``
    after it, ``p_x = +-v0``: ``dx/d(x0, v0, W) = (1, t, 0)`` then ``(-1, -t, 2)``, ``dp_x/dv0 = 1`` then
    ``-1``, to round-off. The impact's fraction inside its held step moves with ``x0``, ``v0`` and ``W``
    (``Tracker._located``'s ``d tau_s``): with it dropped the end reads ``dx/dW = 1``, ``dx/dv0 = -0.345``
    (against 2 and -0.8)."""
    _, q0, v0, h, t_end, params, _ = SCENES["wall"]
    res = simulator("wall", backend).simulate(q0, v0, h, t_end=t_end, sensitivities=True, progress=False)
    (im,) = res.impacts
    assert res.active[1:, 0].all() and res.sensitivity_breaks == []
    names = res.sensitivity_names
    col = {name: names.index(name) for name in ("q0[x]", "v0[x]", "W")}
    after = np.arange(res.t.size) > im.step
    sign = np.where(after, -1.0, 1.0)
    s = res.sensitivity
    err = max(
        np.abs(s[:, 0, col["q0[x]"]] - sign).max(),
        np.abs(s[:, 0, col["v0[x]"]] - sign * res.t).max(),
        np.abs(s[:, 0, col["W"]] - np.where(after, 2.0, 0.0)).max(),
        np.abs(s[:, 2, col["v0[x]"]] - sign).max(),
    )
    print(f"wall [lobatto3, {backend}]: impact in step {im.step}, closed form to {err:.1e}")
    assert after.sum() > 10 and err <= 1e-12, err


@pytest.mark.parametrize("backend", BACKENDS)
def test_a_simultaneous_impact_while_held_still_breaks(backend: str) -> None:
    """Two rows hit at the same instant while held (the weights of the impulse switch) under lobatto3: the
    tangent stops there with its reason, the same step on both backends."""
    sim = _built(pair, backend)
    res = sim.simulate([0.0] * 4, [1.0, 0.0, -1.0, 0.0], 0.01, t_end=0.6, sensitivities=True, progress=False)
    assert [im.step for im in res.impacts] == [45, 45] and res.active[45, :2].all()  # both on the floor
    assert assert_lost(res, "simultaneous impact") == 45


@pytest.mark.parametrize("backend", [hard_scenes.backend_param("c")])
def test_the_c_held_tangent_keeps_no_subnormal_entry(backend: str) -> None:
    """The box held on its long face under lobatto3: the two rows keep the tangent's ``y`` and ``theta``
    rows at 0 up to round-off that each held step scales down; in C such an entry, once subnormal, could
    stay there for the rest of the run (without the flush in ``sens_held``: 187 of these 7236 entries, 1.0e4
    of the bench run's 3.6e5, and its tangent ~15 % slower). C flushes subnormals to 0: none left, and the
    tangent is still the CasADi one."""
    make, q0, v0, h, t_end, params, _ = HELD_SCENES["box_face"]
    kw = {"t_end": t_end, "params": params, "sensitivities": True, "progress": False}
    c, py = (
        vcigen.build(make(), backend=b, rule=RULE).simulate(q0, v0, h, **kw) for b in (backend, "casadi")
    )
    s = np.abs(c.sensitivity)
    subnormal = int(((s > 0) & (s < np.finfo(float).tiny)).sum())
    print(f"box_face [lobatto3, c]: {subnormal} subnormal entries of {s.size}")
    assert subnormal == 0 and c.sensitivity_breaks == []
    assert relative_error(c.sensitivity, py.sensitivity) <= 1e-9


@pytest.mark.skipif(hard_scenes.c_backend_problem() is not None, reason=str(hard_scenes.c_backend_problem()))
def test_the_star_settles_under_lobatto3_without_a_break() -> None:
    """The paper's star with e = 0.8 (tests/test_sensitivity_c.py's run) under lobatto3: it rocks on a vertex,
    is hit while held 18 times (restitution and plastic) and comes to rest on a face; covered throughout on
    both backends, the same impacts in the same steps. The run is chaotic: C and CasADi part by 3.3e-6 in
    q and 8.2e-6 in the tangent (relative), as under trapezoid (1e-9 and 3e-6 there)."""
    from test_c_agreement_sustained import _star
    from test_sensitivity_c import assert_same_tangent

    kw = {"t_end": 9.0, "sensitivities": True, "progress": False}
    a, b = (
        _built(_star, backend).simulate([0.0, 3.5, 0.0], [-2.0, 0.0, 5.0], 0.005, **kw)
        for backend in ("casadi", "c")
    )
    assert [(im.step, im.kind) for im in a.impacts] == [(im.step, im.kind) for im in b.impacts]
    held = [im for im in b.impacts if b.active[im.step].any()]
    assert np.abs(a.q - b.q).max() <= 1e-5
    rel = assert_same_tangent(a, b, tol=1e-4)
    print(f"star settling [lobatto3]: {len(held)} impacts while held, C against CasADi {rel:.1e}, no break")
    assert b.sensitivity_breaks == [] and b.stats["impacts_plastic"] >= 1 and len(held) >= 10
    assert b.active[-1].any() and np.isfinite(b.sensitivity).all()
