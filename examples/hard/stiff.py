"""Stiff spring pendulum (k = 1e4, omega ~ 100) swinging into the wall x = 0.5, h = 0.002."""

import math

from _common import args
from hard_scenes import EventReference, impact_energy_jumps, min_phi, simulator, stiff_pendulum

if __name__ == "__main__":
    a = args(__doc__)
    q0, v0 = [-math.sin(0.8), -math.cos(0.8)], [0.0, 0.0]
    _, _, impacts = EventReference(stiff_pendulum()).run(q0, v0, 3.0)
    sim = simulator("stiff_pendulum", a.backend, a.rule)
    for h in (0.004, 0.002, 0.001):
        res = sim.simulate(q0=q0, v0=v0, h=h, t_end=3.0)
        dt = [f"{abs(im.t - t):.1e}" for im, (t, _) in zip(res.impacts, impacts, strict=False)]
        print(
            f"h = {h}: {res.n_impacts} impacts (ref {len(impacts)}), impact time errors {dt}, "
            f"max |dE|/E {res.max_energy_deviation():.1e}, |dE| across impacts {impact_energy_jumps(res).max():.1e}, "  # noqa: E501
            f"min phi {min_phi(sim, res):.1e}"
        )
