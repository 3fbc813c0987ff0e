"""The paper's particle bouncing on a rigid floor (sec. 4.2, Fig. 2).

m = 1, gravity, floor y = 0, trapezoidal rule (71), h = 0.01,
q0 = (0, 1), qdot0 = (-2, 0), 1000 impacts.
"""

import sympy as sp

import vcigen
from vcigen.demo import run_example

SETUP = {"q0": [0.0, 1.0], "v0": [-2.0, 0.0], "h": 0.01, "n_impacts": 1000}


def model() -> vcigen.Model:
    x, y, xd, yd = sp.symbols("x y xd yd")
    m, g = sp.symbols("m g", positive=True)
    return vcigen.Model(
        name="particle",
        q=[x, y],
        qdot=[xd, yd],
        lagrangian=m / 2 * (xd**2 + yd**2) - m * g * y,  # V = m g y, eq. (80)
        contacts={"floor": y},
        params={m: 1.0, g: 9.81},
    )


if __name__ == "__main__":
    run_example("particle", model, SETUP)
