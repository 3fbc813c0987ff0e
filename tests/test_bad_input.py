"""Every bad input of API.md raises ValueError naming the problem."""

import math

import pytest
import sympy as sp
from scenes import load_example, simulator

import vcigen

x, y, xd, yd = sp.symbols("x y xd yd")
m, g = sp.symbols("m g", positive=True)
GOOD = dict(
    name="p",
    q=[x, y],
    qdot=[xd, yd],
    lagrangian=m / 2 * (xd**2 + yd**2) - m * g * y,
    contacts={"floor": y},
    params={m: 1.0, g: 9.81},
)


def model(**change):
    return vcigen.Model(**(GOOD | change))


@pytest.mark.parametrize(
    "change,words",
    [
        ({"lagrangian": m / 2 * xd**2 - m * g * y}, "singular"),
        ({"lagrangian": m / 2 * (xd**2 + yd**2) - m * g * y * sp.Symbol("k")}, "k"),
        ({"contacts": {"floor": y - sp.Symbol("c")}}, "c"),
        ({"contacts": {"floor": y + xd}}, "velocity"),
        ({"contacts": {"floor": g - 1}}, "does not depend on any coordinate"),
        ({"contacts": {"floor": y**2}}, "'floor' = y\\*\\*2 is never negative"),
        ({"contacts": {"floor": sp.sqrt(x**2 + y**2) + g}}, "never negative"),
        ({"name": "my model"}, "C identifier"),
        ({"name": "double"}, "reserved"),
        ({"contacts": {"2floor": y}}, "C identifier"),
        ({"qdot": [xd]}, "qdot has 1"),
        ({"qdot": None}, "qdot is required"),
        ({"params": {m: "heavy", g: 9.81}}, "not a number"),
        ({"params": {m: math.inf, g: 9.81}}, "not finite"),
    ],
)
def test_bad_model(change, words):
    with pytest.raises(ValueError, match=words):
        model(**change)


@pytest.mark.parametrize("tangent", [y, 2 * y + g, sp.sin(y)])
def test_a_friction_tangent_along_the_normal_is_refused(tangent):
    """A tangent whose gradient is parallel to the contact's normal everywhere measures no sliding: till
    stop 60 it was accepted, and the floor's friction acted along its normal."""
    with pytest.raises(ValueError, match="parallel to the contact's normal"):
        model(friction={"floor": (0.5, tangent)})
    # a tangent not parallel to the normal is kept
    assert str(model(friction={"floor": (0.5, x + y)}).friction_of["floor"][1]) == "x + y"


@pytest.fixture(scope="module")
def sim():
    return simulator("particle")


@pytest.mark.parametrize(
    "kwargs,words",
    [
        ({"q0": [0.0, -0.1]}, "violates contact 'floor'"),
        ({"h": 0.0}, "h = 0.0 must be > 0"),
        ({"h": -0.01}, "must be > 0"),
        ({"h": math.nan}, "not finite"),
        ({"q0": [0.0, math.inf]}, "non-finite"),
        ({"v0": [math.nan, 0.0]}, "non-finite"),
        ({"q0": [0.0, 1.0, 2.0]}, "q0 has 3 entries"),
        ({"v0": [1.0]}, "v0 has 1 entries"),
        ({"t_end": None}, "give t_end, n_impacts"),
        ({"t_end": -1.0}, "before t0"),
        ({"n_impacts": 2.5, "t_end": None}, "whole number"),
        ({"params": {"gravity": 1.0}}, "unknown parameter 'gravity'"),
        ({"params": {"g": math.nan}}, "not finite"),
    ],
)
def test_bad_simulate_arguments(sim, kwargs, words):
    run = {"q0": [0.0, 1.0], "v0": [-2.0, 0.0], "h": 0.01, "t_end": 1.0} | kwargs
    with pytest.raises(ValueError, match=words):
        sim.simulate(**run)


def test_bad_build_arguments():
    mod = load_example("particle").model()
    with pytest.raises(ValueError, match="unknown backend 'fortran'"):
        vcigen.build(mod, backend="fortran")
    with pytest.raises(ValueError, match="unknown rule 'simpson'"):
        vcigen.build(mod, rule="simpson")
    with pytest.raises(ValueError, match="needs a vcigen.Model"):
        vcigen.build("particle")


def test_singular_at_start_is_caught_numerically():
    """A mass matrix singular only at some q is caught where the run starts."""
    sim = vcigen.build(model(lagrangian=(1 + x**2) * xd**2 / 2 + x**2 * yd**2 / 2 - y))
    with pytest.raises(ValueError, match="singular"):
        sim.simulate(q0=[0.0, 1.0], v0=[0.0, 0.0], h=0.01, t_end=0.1)
