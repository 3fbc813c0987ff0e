"""Double pendulum (m = l = 1, angles from the downward vertical) striking the wall x = 1.2.

Error at t = 1.5 (after the impact at t = 0.1327) against DOP853 (rtol 1e-12) + the elastic law.
"""

import numpy as np
from _common import args
from hard_scenes import EventReference, double_pendulum, impact_energy_jumps, simulator

from vcigen.analysis import fit_order

if __name__ == "__main__":
    a = args(__doc__)
    q0, v0, t_end = [0.3, 0.6], [1.5, 2.0], 1.5
    q_ref, _, impacts = EventReference(double_pendulum()).run(q0, v0, t_end)
    sim = simulator("double_pendulum", a.backend, a.rule)
    hs, errs = [0.01, 0.005, 0.0025], []
    for h in hs:
        res = sim.simulate(q0=q0, v0=v0, h=h, t_end=t_end)
        errs.append(np.abs(res.q[-1] - q_ref[-1]).max())
        print(
            f"h = {h}: error {errs[-1]:.2e}, impact t error {abs(res.impacts[0].t - impacts[0][0]):.1e}, "
            f"|dE| across impact {impact_energy_jumps(res).max():.1e}"
        )
    print(f"observed order {fit_order(hs, errs):.2f}")
