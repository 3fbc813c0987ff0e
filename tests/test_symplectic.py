"""The one-step map (q_k, p_k) -> (q_k+1, p_k+1) is symplectic, impact steps included (sec. 3.3)."""

import hard_scenes
import numpy as np
import pytest
from scenes import billiard, load_example, simulator, star_nonlinear

import vcigen
from vcigen.analysis import exact_symplectic_defect, symplectic_defect
from vcigen.stepper import Stepper

RULES = ["trapezoid", "midpoint"]


def step_map(sim, h, count, par=None):
    kern = sim.kernels.bind(sim.model.resolve_params(None) if par is None else list(par))
    stepper = Stepper(kern, sim.tol)

    def f(z):
        n = z.size // 2
        impacts = []
        q, p, _, _ = stepper.step(0, 0.0, h, z[:n], z[n:], z[n:], impacts)
        count.append(len(impacts))
        return np.concatenate([q, p])

    return f


@pytest.mark.parametrize("rule", RULES)
def test_impact_step_is_symplectic(rule):
    sim = simulator("billiard", rule)
    h = 0.05
    count = []
    f = step_map(sim, h, count)
    # A state 0.6 h before the rim along the velocity: the step holds one impact at alpha ~ 0.6.
    q = np.array([0.0, 1.0 - 0.6 * h * 1.5 - 1e-3])
    z = np.concatenate([q, [0.4, 1.5]])
    defect = symplectic_defect(f, z, eps=1e-6)
    assert set(count) == {1}, "every perturbed step must hold exactly one impact"
    assert defect < 1e-7, defect


@pytest.mark.parametrize("rule", RULES)
def test_star_impact_step_is_symplectic(rule):
    sim = simulator("star_nonlinear", rule)
    h = 0.01
    count = []
    f = step_map(sim, h, count)
    # phi(q) = 0.64 - 0.625 = 0.015 and the star falls 0.03 in the step: a vertex strikes.
    z = np.array([0.0, 0.64, 0.3, -1.0, -3.0, 2.0])
    defect = symplectic_defect(f, z, eps=1e-6)
    assert set(count) == {1}
    assert defect < 1e-7, defect


def test_defect_detects_a_non_symplectic_map():
    """The measure is not vacuous: a dissipative map has a large defect."""
    assert symplectic_defect(lambda z: np.concatenate([z[:2], 0.9 * z[2:]]), np.ones(4)) > 0.05


# -- the exact Jacobian (vcigen.casadi_functions, implicit-function theorem): defect at round-off ----------


def exact_case(model, function: str, z, h: float, params=None):
    """The exact defect of ``function`` at ``z = (q, p)`` and the stepper's step there (the same map)."""
    fs = vcigen.casadi_functions(model)
    par = vcigen.casadi_parameters(model, fs["step"], params)
    n = z.size // 2
    sim = vcigen.build(model)
    count = []
    stepper_z1 = step_map(sim, h, count, par)(z)
    out = fs[function](z[:n], z[n:], h, par)
    z1 = np.concatenate([np.asarray(o).ravel() for o in out[:2]])
    assert count == [0 if function == "step" else 1]
    assert np.abs(z1 - stepper_z1).max() <= 1e-12 * (1 + np.abs(z1).max())
    return exact_symplectic_defect(fs[function], z[:n], z[n:], h, par), symplectic_defect(
        step_map(sim, h, [], par), z, eps=1e-6
    )


EXACT = {
    # billiard: 0.6 h before the rim; star: a vertex strikes (phi = 0.015, falling 0.03 in the step);
    # double pendulum: the step before its tip strikes the wall x = 1.2 (run from q0 = (0.3, 0.6)).
    "billiard": (billiard, 0.05, [0.0, 1.0 - 0.6 * 0.05 * 1.5 - 1e-3, 0.4, 1.5], "rim"),
    "star": (lambda: load_example("star").model(), 0.01, [0.0, 0.64, 0.3, -1.0, -3.0, 2.0], "floor"),
    "star_nonlinear": (star_nonlinear, 0.01, [0.0, 0.64, 0.3, -1.0, -3.0, 2.0], "floor"),
    "double_pendulum": (hard_scenes.double_pendulum, 0.01, None, "wall"),
}


def pendulum_state_before_impact() -> np.ndarray:
    sim = vcigen.build(hard_scenes.double_pendulum())
    res = sim.simulate(q0=[0.3, 0.6], v0=[1.5, 2.0], h=0.01, t_end=0.2)
    k = res.impacts[0].step
    return np.concatenate([res.q[k], res.p[k]])


@pytest.mark.parametrize("name", list(EXACT))
def test_elastic_impact_step_exactly_symplectic(name):
    """MATH.md: with the exact Jacobian the defect of an impact step is round-off (<= 1e-12); the FD
    defect of the same step (the cross-check) is far above it."""
    maker, h, z, contact = EXACT[name]
    z = pendulum_state_before_impact() if z is None else np.array(z)
    exact, fd = exact_case(maker(), f"impact_{contact}", z, h)
    print(f"{name}: exact defect {exact:.2e}, finite differences {fd:.2e}")
    assert exact <= 1e-12, exact
    assert fd < 1e-7, fd


def test_smooth_step_exactly_symplectic():
    z = pendulum_state_before_impact()
    z[:2] -= 0.2  # away from the wall: a smooth step
    exact, _ = exact_case(hard_scenes.double_pendulum(), "step", z, 0.01)
    assert exact <= 1e-12, exact


def test_exact_defect_sees_restitution():
    """Not vacuous: an impact with restitution e = 0.5 loses energy, and its step is not symplectic."""
    model = hard_scenes.box(lossy=True)
    z = np.array([0.5, 0.005, 0.3, -1.0])
    exact, _ = exact_case(model, "impact_bottom", z, 0.01, {"e": 0.5})
    elastic, _ = exact_case(model, "impact_bottom", z, 0.01, {"e": 1.0})
    assert exact > 0.1 and elastic <= 1e-12, (exact, elastic)
