"""The paper's four-point star bouncing on a rigid floor (sec. 4.3, Figs. 3-4).

q = (x, y, theta), M = diag(m, m, I), I = 29/192 m L^2, m = 1, L = 1,
phi = y - L/2 (|sin theta| + |cos theta|) written with Abs exactly as eq. (81),
h = 0.005, q0 = (0, 3.5, 0), qdot0 = (-2, 0, 5), 1500 impacts.
"""

import sympy as sp

import vcigen
from vcigen.demo import run_example

SETUP = {"q0": [0.0, 3.5, 0.0], "v0": [-2.0, 0.0, 5.0], "h": 0.005, "n_impacts": 1500}


def model() -> vcigen.Model:
    x, y, th, xd, yd, thd = sp.symbols("x y theta xd yd thetad")
    m, g, L = sp.symbols("m g L", positive=True)
    inertia = sp.Rational(29, 192) * m * L**2
    return vcigen.Model(
        name="star",
        q=[x, y, th],
        qdot=[xd, yd, thd],
        lagrangian=m / 2 * (xd**2 + yd**2) + inertia / 2 * thd**2 - m * g * y,
        contacts={"floor": y - L / 2 * (sp.Abs(sp.sin(th)) + sp.Abs(sp.cos(th)))},  # eq. (81)
        params={m: 1.0, g: 9.81, L: 1.0},
    )


if __name__ == "__main__":
    run_example("star", model, SETUP)
