"""Several impacts in one step: a particle between walls 0.01 apart, h up to 0.2 (20 impacts/step).

Free flight: error against the unfolded closed form (exact, round-off expected).
Oscillator x'' = -16 x between walls at +-0.05: error at t = 0.2 vs the closed form, 8 phases.
"""

import math

import numpy as np
from _common import args
from hard_scenes import simulator, unfold, walls_oscillator_exact

if __name__ == "__main__":
    a = args(__doc__)
    sim = simulator("walls", a.backend, a.rule)
    for h in (0.2, 0.05, 0.0125):
        res = sim.simulate(q0=[0.0037, 1.0], v0=[1.0, 0.5], h=h, t_end=1.0, params={"g": 0.0})
        err = np.abs(res.q[:, 0] - unfold(0.0037, 1.0, 0.0, 0.01, res.t)).max()
        most = np.bincount([im.step for im in res.impacts]).max()
        print(f"free, h = {h}: {res.n_impacts} impacts, up to {most} per step, max |x - exact| = {err:.2e}")
    osc = simulator("walls_oscillator", a.backend, a.rule)
    t1 = math.asin(0.05) / 4
    for h in (0.04, 0.005, 0.0025, 0.00125):
        errs = []
        for t0 in np.linspace(0, t1, 8, endpoint=False):
            res = osc.simulate(q0=[math.sin(4 * t0)], v0=[4 * math.cos(4 * t0)], h=h, t_end=0.2)
            errs.append(abs(res.q[-1, 0] - walls_oscillator_exact(t0 + res.t[-1], 1.0, 4.0, 0.05)))
        print(
            f"oscillator, h = {h}: mean error at t = 0.2 = {np.mean(errs):.2e} (error/h^2 = {np.mean(errs) / h**2:.1f})"  # noqa: E501
        )
