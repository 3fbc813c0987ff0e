"""The star (phi with Abs, eq. 81) dropped flat: two vertices touch at once, omega must stay 0."""

import math

import numpy as np
from _common import args
from hard_scenes import G, simulator

import vcigen

if __name__ == "__main__":
    a = args(__doc__)
    sim = simulator("star", a.backend, a.rule)
    for h in (0.005, 0.01):
        try:
            res = sim.simulate(q0=[0.0, 1.0, 0.0], v0=[0.7, 0.0, 0.0], h=h, t_end=2.0)
        except vcigen.SolverError as err:
            print(f"h = {h}: SolverError: {err}")
            continue
        speed = math.sqrt(2 * G * 0.5)
        imp = ", ".join(f"{im.impulse:.4f}" for im in res.impacts)
        print(
            f"h = {h}: impulses [{imp}] (exact 2 v = {2 * speed:.4f} each), max |p_theta| = {np.abs(res.p[:, 2]).max():.2e}"  # noqa: E501
        )
