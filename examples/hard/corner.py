"""Simultaneous impacts: a particle into the corner of x >= 0, y >= 0 at exactly 45 degrees.

No gravity: closed form q = |1 - t| (1, 1). Both orders of the contacts dict are run and compared.
With gravity: a parabola reaching the corner at t = 0.5 must retrace itself.
"""

import numpy as np
from _common import args
from hard_scenes import G, parabola, simulator

if __name__ == "__main__":
    a = args(__doc__)
    fwd, rev = simulator("corner", a.backend, a.rule), simulator("corner_reversed", a.backend, a.rule)
    for h in (0.3, 0.1):
        r1 = fwd.simulate(q0=[1, 1], v0=[-1, -1], h=h, t_end=2.5, params={"g": 0.0})
        r2 = rev.simulate(q0=[1, 1], v0=[-1, -1], h=h, t_end=2.5, params={"g": 0.0})
        err = np.abs(r1.q - np.abs(1 - r1.t)[:, None]).max()
        print(
            f"g = 0, h = {h}: max |q - exact| = {err:.2e}, order difference = {np.abs(r1.q - r2.q).max():.2e}"
        )
    q0, v0 = [1.5, 1.5 - G / 8], [-3.0, -3.0 + G / 2]
    for h in (0.3, 0.02, 0.01, 0.005):
        r1 = fwd.simulate(q0=q0, v0=v0, h=h, t_end=0.9, params={"g": G})
        r2 = rev.simulate(q0=q0, v0=v0, h=h, t_end=0.9, params={"g": G})
        err = np.abs(r1.q - parabola(q0, v0, np.minimum(r1.t, 1 - r1.t))).max()
        print(
            f"g = 9.81, h = {h}: max |q - exact| = {err:.2e}, order difference = {np.abs(r1.q - r2.q).max():.2e}"  # noqa: E501
        )
