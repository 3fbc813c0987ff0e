"""Scenes shared by the tests: the examples plus small scenes with known answers."""

from __future__ import annotations

import importlib.util
from functools import cache
from pathlib import Path

import sympy as sp

import vcigen

ROOT = Path(__file__).resolve().parents[1]


def load_example(name: str):
    """Import ``examples/<name>.py`` as a module."""
    path = ROOT / "examples" / f"{name}.py"
    spec = importlib.util.spec_from_file_location(f"example_{name.replace('/', '_')}", path)
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def star_nonlinear() -> vcigen.Model:
    """The star with nonlinear gravity V = -m g R^2/(R + y) (paper Fig. 5 set-up)."""
    x, y, th, xd, yd, thd = sp.symbols("x y theta xd yd thetad")
    m, g, L, R = sp.symbols("m g L R", positive=True)
    inertia = sp.Rational(29, 192) * m * L**2
    return vcigen.Model(
        name="star_nonlinear",
        q=[x, y, th],
        qdot=[xd, yd, thd],
        lagrangian=m / 2 * (xd**2 + yd**2) + inertia / 2 * thd**2 + m * g * R**2 / (R + y),
        contacts={"floor": y - L / 2 * (sp.Abs(sp.sin(th)) + sp.Abs(sp.cos(th)))},
        params={m: 1.0, g: 9.81, L: 1.0, R: 5.0},
    )


def billiard() -> vcigen.Model:
    """A particle in a circular billiard of radius R with a quartic central potential."""
    x, y, xd, yd = sp.symbols("x y xd yd")
    k, R = sp.symbols("k R", positive=True)
    return vcigen.Model(
        name="billiard",
        q=[x, y],
        qdot=[xd, yd],
        lagrangian=(xd**2 + yd**2) / 2 - k * (x**2 + y**2) ** 2 / 4,
        contacts={"rim": R**2 - x**2 - y**2},
        params={k: 1.0, R: 1.0},
    )


def oscillator_wall() -> vcigen.Model:
    """A 1-D harmonic oscillator x'' = -w^2 x against a wall at x = -a (closed-form solution)."""
    x, xd = sp.symbols("x xd")
    w, a = sp.symbols("w a", positive=True)
    return vcigen.Model(
        name="oscillator",
        q=[x],
        qdot=[xd],
        lagrangian=xd**2 / 2 - w**2 * x**2 / 2,
        contacts={"wall": x + a},
        params={w: 2.0, a: 0.5},
    )


@cache
def simulator(name: str, rule: str = "trapezoid", backend: str = "casadi") -> vcigen.Simulator:
    """Build each scene once per test session."""
    makers = {"star_nonlinear": star_nonlinear, "billiard": billiard, "oscillator": oscillator_wall}
    model = makers[name]() if name in makers else load_example(name).model()
    return vcigen.build(model, backend=backend, rule=rule)
