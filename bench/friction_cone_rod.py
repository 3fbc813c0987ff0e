"""Two cone contacts of one body sticking at once (two tangents each): the figures of README *Friction*.

    .venv/bin/python bench/friction_cone_rod.py

The scenes and closed forms are those of ``tests/test_friction_cone_rod.py`` (a rod lying on two rough ends of
a 3-D floor), on both backends (worst over both):

* sliding at v = (1.2, -0.9): the path against the stop after |v|^2/(2 mu g) at |v|/(mu g), friction's
  work against -m |v|^2 / 2 (h = 0.01, 0.003);
* spinning at w0 = 3: yaw against phi'' = -6 mu g / l to the stop, the centre's drift (h = 0.01, 0.005);
* sliding at (1, 0.3) and spinning at 2: against scipy's Coulomb ODE (``coulomb_rod``) to the stop;
* pushed from rest through its centre (along the rod, oblique) and turned by a torque: the breakaway instant
  (motion before it) and the path after it against the closed form (h = 0.02, 0.01), the yaw of a push;
* the drops of ``DROPPED_ON_MAIN`` (h = 0.005, t = 4): |p| over the last 50 steps, each end's force against
  m g / 2, E_d at the end, the largest friction work of a step, the time by which all are at rest;
* C against CasADi on the runs of ``test_c_equals_casadi_on_two_cones``.
"""

from __future__ import annotations

import math
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))
from test_friction_cone_rod import (  # noqa: E402
    DROPPED_ON_MAIN,
    INERTIA,
    LENGTH,
    MASS,
    MU,
    PHI0,
    PUSHES,
    G,
    coulomb_rod,
    drop,
    push_error,
    sim,
    slide,
    spin,
)


def main() -> None:
    worst: dict[str, float] = {}

    def note(key: str, value: float) -> None:
        worst[key] = max(worst.get(key, 0.0), float(value))

    for b in ("casadi", "c"):
        for h in (0.01, 0.003):
            v, r = slide(b, h)
            speed, t = math.hypot(*v), r.t
            s = np.where(t < speed / (MU * G), speed * t - MU * G * t**2 / 2, speed**2 / (2 * MU * G))
            note(f"slide h={h}: path error", np.abs(r.q[:, :2] - np.outer(s, v / speed)).max())
            note(f"slide h={h}: friction work error", abs(r.friction_work.sum() + MASS * speed**2 / 2))
        acc = 6 * MU * G / LENGTH
        for h in (0.01, 0.005):
            r = spin(b, h)
            t = r.t
            exact = PHI0 + np.where(t < 3.0 / acc, 3.0 * t - acc * t**2 / 2, 9.0 / (2 * acc))
            note(f"spin h={h}: yaw error", np.abs(r.q[:, 3] - exact).max())
            note(f"spin h={h}: centre drift", np.abs(r.q[:, :2]).max())
            note(f"spin h={h}: friction work error", abs(r.friction_work.sum() + INERTIA * 9.0 / 2))
        sol, t_stop = coulomb_rod((1.0, 0.3), 2.0)
        for h in (0.01, 0.005, 0.0025):
            r = sim(b).simulate(q0=[0, 0, 0, PHI0, 0], v0=[1.0, 0.3, 0, 2.0, 0], h=h, t_end=t_stop)
            m = r.t <= t_stop
            err = np.abs(r.q[m][:, [0, 1, 3]] - sol.sol(r.t[m])[:3].T).max()
            note(f"slide and spin h={h}: against scipy", err)
        for name, (params, t_star) in PUSHES.items():
            r = sim(b).simulate(q0=[0, 0, 0, PHI0, 0], v0=[0] * 5, h=0.01, t_end=t_star + 0.3, params=params)
            dq = np.abs(r.q - [0, 0, 0, PHI0, 0]).max(axis=1)
            note(f"{name}: motion before t*", dq[r.t <= t_star].max())
            for h in (0.02, 0.01):
                moving, other = push_error(b, name, h)
                note(f"{name} h={h}: error after t*", moving)
                note(f"{name} h={h}: {'centre drift' if name == 'torque' else 'yaw'}", other)
        for seed in DROPPED_ON_MAIN:
            q0, v0, params = drop(seed)
            r = sim(b).simulate(q0=q0, v0=v0, h=0.005, t_end=4.0, params=params)
            moving = np.flatnonzero(np.abs(r.p).max(axis=1) > 1e-12)
            note("drops: at rest from t", r.t[moving.max() + 1] if moving.size else 0.0)
            note("drops: |p| over the last 50 steps", np.abs(r.p[-50:]).max())
            note("drops: |end force - m g/2|", np.abs(r.contact_force[-50:] - MASS * G / 2).max())
            note("drops: |E_d| at the end", abs(r.energy[-1]))
            note("drops: largest friction work of a step", r.friction_work.max())
    runs = [
        dict(q0=[0, 0, 0, PHI0, 0], v0=[1.2, -0.9, 0, 0, 0], h=0.01, t_end=1.0),
        dict(q0=[0, 0, 0, PHI0, 0], v0=[0, 0, 0, 3.0, 0], h=0.01, t_end=1.0),
        dict(q0=[0, 0, 0, PHI0, 0], v0=[0] * 5, h=0.01, t_end=1.6, params={"T": 3.0}),
        dict(q0=[0, 0, 0, PHI0, 0], v0=[0] * 5, h=0.01, t_end=2.0, params={"Fx": 1.8, "Fy": 2.4}),
        dict(zip(("q0", "v0", "params"), drop(0)), h=0.005, t_end=4.0),
    ]
    for run in runs:
        a, c = (sim(bk).simulate(**run) for bk in ("casadi", "c"))
        note("C - CasADi: q", np.abs(a.q - c.q).max())
        note("C - CasADi: p", np.abs(a.p - c.p).max())
        note("C - CasADi: friction work", np.abs(a.friction_work - c.friction_work).max())
    for key, value in worst.items():
        print(f"{key:45s} {value:.3g}")


if __name__ == "__main__":
    main()
