"""The lift-off tangent inside the C loop (``sens_liftoff``, ``templates/sens_liftoff.c.j2``;
``Tracker.liftoff`` in Python): the C run never hands a lift-off step to the Python stepper, its tangent is
the Python stepper's, and a lift-off driven by a force of time (the time slot of ``par`` in the located root)
agrees with finite differences and with the closed form of the lift-off time on both backends; so does a
lift-off in the same step as the plastic impact that started the contact (the rest of that step, ``entry``).
A lift-off on a grid point is a kink of the run: the tangent is the earlier lift-off's side, no break.
"""

from __future__ import annotations

import hard_scenes
import numpy as np
import pytest
import sympy as sp
import test_sensitivity as ts
from test_sensitivity_c import assert_same_tangent

import vcigen
from vcigen import sensitivity, simulator

C = hard_scenes.backend_param("c")


@pytest.mark.skipif(hard_scenes.c_backend_problem() is not None, reason=str(hard_scenes.c_backend_problem()))
@pytest.mark.parametrize("scene", sorted(ts.LIFT_SCENES))
def test_c_liftoff_never_calls_python(scene: str, monkeypatch) -> None:
    """With the Python stepper's tangent (the base ``Simulator._run_sensitive`` and ``Tracker``) made to
    raise, the C run still carries its tangent across the lift-off, no break, the CasADi run's to 1e-9."""
    _, q0, v0, h, t_end, params, _ = ts.LIFT_SCENES[scene]
    kw = {"t_end": t_end, "params": params, "sensitivities": True, "progress": False}
    ref = ts.lift_simulator(scene, "casadi").simulate(q0, v0, h, **kw)

    def python_tangent(*args, **kwargs):
        raise AssertionError("the Python stepper's tangent was called")

    monkeypatch.setattr(simulator.Simulator, "_run_sensitive", python_tangent)
    monkeypatch.setattr(sensitivity.Tracker, "__init__", python_tangent)
    res = ts.lift_simulator(scene, "c").simulate(q0, v0, h, **kw)
    assert len(res.liftoffs) == 1 and res.sensitivity_breaks == [] and np.isfinite(res.sensitivity).all()
    rel = assert_same_tangent(ref, res)
    print(f"{scene}: C (no Python) against CasADi {rel:.1e}")


G, A = 9.81, 17.0  # the floor lets go at t = g / A = 0.5770588...


def _lifted(plastic: bool = False) -> vcigen.Model:
    """A unit particle on the floor ``y >= 0`` under gravity ``g`` and a rising lift ``A t``, sliding along
    ``x``: the normal force ``g - A t`` vanishes at ``t_l = g / A``, then ``y = A (t - t_l)^3 / 6``.
    ``plastic``: restitution 0 (a drop onto the floor starts sustained contact)."""
    x, y, xd, yd, t = sp.symbols("x y xd yd t")
    g, a = sp.symbols("g A", positive=True)
    return vcigen.Model(
        name="lifted",
        q=[x, y],
        qdot=[xd, yd],
        lagrangian=(xd**2 + yd**2) / 2 - g * y,
        contacts={"floor": y},
        params={g: G, a: A},
        forces=[0, a * t],
        time=t,
        restitution={"floor": 0} if plastic else {},
    )


T_END = 0.8
LIFTED = {
    "lifted": (
        _lifted,
        [0.0, 0.0],
        [0.5, 0.0],
        0.01,
        T_END,
        None,
        {
            "q0[x]": lambda e: ([e, 0.0], [0.5, 0.0], {}),
            "v0[x]": lambda e: ([0.0, 0.0], [0.5 + e, 0.0], {}),
            "g": lambda e: ([0.0, 0.0], [0.5, 0.0], {"g": G + e}),
            "A": lambda e: ([0.0, 0.0], [0.5, 0.0], {"A": A + e}),
        },
    )
}


@pytest.mark.parametrize("backend", ["casadi", C])
def test_liftoff_under_a_force_of_time(backend: str) -> None:
    """The located root's time slot (``t_k + tau_s``) is chained: the lifted particle against central
    differences of whole runs (every step covered), and its tangent of ``y`` at the end against the closed
    form ``d/dA`` and ``d/dg`` of ``A (T - t_l)^3 / 6``, ``t_l = g / A`` (to the method's O(h^2))."""
    sim = vcigen.build(_lifted(), backend=backend)
    res, per = ts.held_finite_differences(sim, "lifted", scenes=LIFTED)
    ((t_l, _),) = res.liftoffs
    assert abs(t_l - G / A) <= 1e-12 and res.sensitivity_breaks == [] and np.isfinite(res.sensitivity).all()
    errs = {label: ts.relative_error(exact, fd) for label, (exact, fd) in per.items()}
    per_path = ", ".join(f"{k} {v:.1e}" for k, v in errs.items())
    print(f"lifted ({backend}): lift-off at {t_l:.12f}; {per_path}")
    assert max(errs.values()) <= 1e-6, errs
    tail = T_END - G / A
    exact = {"g": -(tail**2) / 2, "A": tail**3 / 6 + G * tail**2 / (2 * A)}  # dy(T)/dg, dy(T)/dA
    names = res.sensitivity_names
    for p, want in exact.items():
        got = res.sensitivity[-1, 1, names.index(p)]
        print(f"  dy(T)/d{p}: {got:.6e}, closed form {want:.6e}")
        assert abs(got - want) <= 1e-3 * abs(want), (p, got, want)
    if backend != "casadi":
        ref = vcigen.build(_lifted(), backend="casadi").simulate(
            [0.0, 0.0], [0.5, 0.0], 0.01, t_end=T_END, sensitivities=True, progress=False
        )
        print(f"  C against CasADi {assert_same_tangent(ref, res):.1e}")


Y_DROP = 1.0802  # dropped at rest from here, it lands (plastically) at t = 0.57393, in the lift-off's step
DROP = {
    "drop": (
        lambda: _lifted(plastic=True),
        [0.0, Y_DROP],
        [0.5, 0.0],
        0.01,
        T_END,
        None,
        {
            "q0[x]": lambda e: ([e, Y_DROP], [0.5, 0.0], {}),
            "q0[y]": lambda e: ([0.0, Y_DROP + e], [0.5, 0.0], {}),
            "v0": lambda e: ([0.0, Y_DROP], [0.5 + e, -e], {}),
            "g": lambda e: ([0.0, Y_DROP], [0.5, 0.0], {"g": G + e}),
            "A": lambda e: ([0.0, Y_DROP], [0.5, 0.0], {"A": A + e}),
        },
    )
}


@pytest.mark.parametrize("backend", ["casadi", C])
def test_liftoff_in_the_step_of_a_plastic_impact(backend: str) -> None:
    """The plastic impact (``Tracker.plastic``), then the constrained rest of its step from the impact point
    cut by the lift-off (``Tracker.liftoff`` with ``entry``: the sub-step's data have the tangents of the
    impact point, its time and the rest of the step), then the free rest: covered, against central
    differences."""
    sim = vcigen.build(_lifted(plastic=True), backend=backend)
    res, per = ts.held_finite_differences(sim, "drop", scenes=DROP)
    ((t_l, _),) = res.liftoffs
    (hit,) = res.impacts
    assert hit.kind == "plastic" and hit.step == int((t_l - res.t[0]) / (res.t[1] - res.t[0]))
    assert res.sensitivity_breaks == [] and np.isfinite(res.sensitivity).all()
    errs = {label: ts.relative_error(exact, fd) for label, (exact, fd) in per.items()}
    print(f"drop ({backend}): plastic at {hit.t:.6f}, lift-off at {t_l:.6f}; "
          + ", ".join(f"{k} {v:.1e}" for k, v in errs.items()))  # fmt: skip
    assert max(errs.values()) <= 1e-6, errs
    if backend != "casadi":
        ref = vcigen.build(_lifted(plastic=True), backend="casadi").simulate(
            [0.0, Y_DROP], [0.5, 0.0], 0.01, t_end=T_END, sensitivities=True, progress=False
        )
        print(f"  C against CasADi {assert_same_tangent(ref, res):.1e}")


def _pulled() -> vcigen.Model:
    """A unit particle sliding on the floor ``y >= 0`` under gravity ``g``, pulled up by ``c x``: the normal
    force ``g - c x`` vanishes at ``x = g / c`` (no force of time: the lift-off is the rows' own root)."""
    x, y, xd, yd = sp.symbols("x y xd yd")
    g, c = sp.symbols("g c")
    return vcigen.Model(
        name="pulled_up",
        q=[x, y],
        qdot=[xd, yd],
        lagrangian=(xd**2 + yd**2) / 2 - g * y + c * x * y,
        contacts={"floor": y},
        params={g: 10.0, c: 10.0},
    )


# column -> (run's data moved by e, the sign of e that lifts off earlier)
PULLED = {
    "q0[x]": (lambda e: ([e, 0.0], [1.0, 0.0], {}), 1.0),
    "v0[x]": (lambda e: ([0.0, 0.0], [1.0 + e, 0.0], {}), 1.0),
    "g": (lambda e: ([0.0, 0.0], [1.0, 0.0], {"g": 10.0 + e}), -1.0),
    "c": (lambda e: ([0.0, 0.0], [1.0, 0.0], {"c": 10.0 + e}), 1.0),
}


@pytest.mark.parametrize("rule", ["trapezoid", "midpoint"])
@pytest.mark.parametrize("backend", ["casadi", C])
def test_a_liftoff_on_a_grid_point_is_one_sided(backend: str, rule: str) -> None:
    """From ``x = 0`` at speed 1 with ``g = c = 10`` the normal force vanishes at ``t = 1``, grid point 20 of
    ``h = 0.05``: the run is a kink there (an earlier lift-off is located at the end of step 19, a later one
    at the start of step 20, whose held sub-step the tangent does not see). No break: the tangent at every
    grid point is the earlier lift-off's one-sided derivative (one-sided differences of whole runs, 1e-6 of
    the largest entry), and the later side's differs by more than the kink (1e-4); C's is CasADi's."""
    sim = vcigen.build(_pulled(), backend=backend, rule=rule)
    kw = {"h": 0.05, "t_end": 1.25, "progress": False}
    res = sim.simulate([0.0, 0.0], [1.0, 0.0], sensitivities=True, **kw)
    ((t_l, _),) = res.liftoffs
    assert abs(t_l - 1.0) <= 1e-12 and res.sensitivity_breaks == [] and np.isfinite(res.sensitivity).all()
    base, eps = np.hstack([res.q, res.p]), 1e-7
    for name, (moved, early) in PULLED.items():
        tangent = res.sensitivity[:, :, res.sensitivity_names.index(name)]
        errs = []
        for side in (early, -early):
            q0, v0, params = moved(side * eps)
            run = sim.simulate(q0, v0, params=params, **kw)
            fd = (np.hstack([run.q, run.p]) - base) / (side * eps)
            errs.append(float(np.abs(fd - tangent).max() / np.abs(fd).max()))
        print(f"{name}: the earlier side {errs[0]:.1e}, the later {errs[1]:.1e}")
        assert errs[0] <= 1e-6 and errs[1] >= 1e-4, (name, errs)
    if backend != "casadi":
        ref = vcigen.build(_pulled(), backend="casadi", rule=rule)
        ref_res = ref.simulate([0.0, 0.0], [1.0, 0.0], sensitivities=True, **kw)
        print(f"C against CasADi {assert_same_tangent(ref_res, res):.1e}")
