"""Grazing: a parabola whose apex is delta from the ceiling y = 1 (tangent or a 1e-10 crossing).

Run with the default ``Tolerances()`` (``grazing="contact"``: where (48a) has no root mu > 0 and nothing
presses the ball in, the continuous law, an impact of kind ``"grazing"``), the paper's method alone
``Tolerances(grazing="error")`` (a SolverError there) and ``grazing="reflect"`` (the continuous elastic
law there).
"""

import warnings

import numpy as np
from _common import args
from hard_scenes import G, parabola, simulator

import vcigen

if __name__ == "__main__":
    a = args(__doc__)
    warnings.simplefilter("ignore", RuntimeWarning)  # the reflect count is printed instead
    for grazing in ("contact", "error", "reflect"):
        print(f"Tolerances(grazing={grazing!r}):")
        sim = simulator("ceiling", a.backend, a.rule, tol=vcigen.Tolerances(grazing=grazing))
        for delta in (-1e-10, 0.0, 1e-10, 1e-8):
            for t_apex in (0.5, 0.503, 0.505):
                vy = G * t_apex
                q0, v0 = [0.0, 1.0 + delta - vy**2 / (2 * G)], [1.0, vy]
                try:
                    res = sim.simulate(q0=q0, v0=v0, h=0.01, t_end=1.0)
                except vcigen.SolverError as err:
                    print(f"delta = {delta:g}, apex t = {t_apex}: SolverError: {err}")
                    continue
                dev = np.abs(res.q - parabola(q0, v0, res.t)).max()
                v_n = np.sqrt(2 * G * delta) if delta > 0 else 0.0
                imp = [f"{im.impulse:.1e} {im.kind} (2 v_n = {2 * v_n:.1e})" for im in res.impacts]
                jump = [f"{im.energy_after - im.energy_before:.1e}" for im in res.impacts]
                print(
                    f"delta = {delta:g}, apex t = {t_apex}: impulses {imp}, energy jumps {jump}, "
                    f"max |q - free parabola| = {dev:.1e}"
                )
