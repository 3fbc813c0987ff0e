"""Inelastic bouncing toward rest: a ball dropped from y = 1 on a floor with restitution e.

Infinitely many impacts in finite time: the flights shrink by e and accumulate at the Zeno
time t_1 + 2 e v_1 / (g (1 - e)). Once a rebound is below what the jump resolves at this h
it is plastic and the ball is held on the floor (sustained contact, README). Printed: the
measured flight ratio, the energy lost at the first impact against (1 - e^2) g (m = 1), the
number of impacts and when the ball is held against the Zeno time, and the height and energy
at rest (sliding at vx = 0.3).
"""

import numpy as np
from _common import args
from hard_scenes import G, simulator, zeno_time

if __name__ == "__main__":
    a = args(__doc__)
    sim = simulator("ball", a.backend, a.rule)
    for e in (0.5, 0.8):
        for h in (0.002, 0.001, 0.0005):
            t_inf = zeno_time(e)
            res = sim.simulate(q0=[0.0, 1.0], v0=[0.3, 0.0], h=h, t_end=t_inf + 0.5, params={"e": e})
            t = np.array([im.t for im in res.impacts])
            steps = np.array([im.step for im in res.impacts])
            ratio = np.diff(t)[1:6] / np.diff(t)[:5]
            loss = res.impacts[0].energy_before - res.impacts[0].energy_after
            held = res.t[np.argmax(res.active[:, 0])] if res.active[:, 0].any() else float("nan")
            late = res.t > t_inf + 0.1
            print(
                f"e = {e}, h = {h}: flight ratio {ratio.min():.5f}..{ratio.max():.5f}; first loss {loss:.6f} "
                f"(exact {(1 - e * e) * G:.6f}); {len(t)} impacts, at most {np.bincount(steps).max()} "
                f"per step; held from t = {held:.4f} (Zeno time {t_inf:.4f}); "
                f"at rest: y <= {res.q[late, 1].max():.1e}, "
                f"E_d - vx^2/2 = {res.energy[late[1:]].max() - 0.045:.1e}"
            )
