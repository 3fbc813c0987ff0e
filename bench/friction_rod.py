"""Two frictional contacts on one rigid body (dependent sticks): the figures of README *Friction*.

    .venv/bin/python bench/friction_rod.py

The scenes and closed forms are those of ``tests/test_friction_rod.py``, on both backends (worst over both):

* the rod drops that stopped with a SolverError before dependent sticks (seeds ``FAILED_ON_MAIN``,
  h = 0.005, t = 4): largest |p| over the last 50 steps, each end's force against m g / 2, ``E_d`` at the
  end, the largest friction work of a step (<= 0), and the time by which every drop is at rest (|p| <=
  1e-12 from then on);
* the rod set down sliding at v = 2 on both ends (theta = 0 and pi) and the box on a face: the path against
  the stop after v^2/(2 mu g) at v/(mu g), friction's work against -m v^2/2;
* the box with four frictional vertices dropped at random (seeds 0-7, t = 10): |p| at the end, the forces'
  sum against m g, the time by which every drop is at rest;
* C against CasADi on a rod drop, the rod slide and a box drop.

``--sweep``: 30 random drops of the rod and of the box at h = 0.01, 0.005, 0.002 on both backends (t = 10):
how many fail (any exception) and which are not at rest at the end.
"""

from __future__ import annotations

import math
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))
from test_friction_rod import FAILED_ON_MAIN, MASS, MU, G, drop, sim  # noqa: E402

V = 2.0


def at_rest_from(res) -> float:
    """The first grid time from which every momentum is <= 1e-12."""
    moving = np.flatnonzero(np.abs(res.p).max(axis=1) > 1e-12)
    return float(res.t[moving.max() + 1]) if moving.size else 0.0


def stop_error(res) -> float:
    t, ts = res.t, V / (MU * G)
    exact = np.where(t < ts, V * t - MU * G * t**2 / 2, V**2 / (2 * MU * G))
    return float(np.max(np.abs(res.q[:, 0] - exact)))


def main() -> None:
    worst: dict[str, float] = {}

    def note(key: str, value: float) -> None:
        worst[key] = max(worst.get(key, 0.0), float(value))

    for b in ("casadi", "c"):
        for seed in FAILED_ON_MAIN:
            q0, v0, params = drop(seed)
            r = sim("rod", b).simulate(q0=q0, v0=v0, h=0.005, t_end=4.0, params=params)
            note("rod drops: |p| over the last 50 steps", np.abs(r.p[-50:]).max())
            note("rod drops: |end force - m g/2|", np.abs(r.contact_force[-50:] - MASS * G / 2).max())
            note("rod drops: |E_d| at the end", abs(r.energy[-1]))
            note("rod drops: largest friction work of a step", r.friction_work.max())
            note("rod drops: at rest from t", at_rest_from(r))
        for theta in (0.0, math.pi):
            r = sim("rod", b).simulate(q0=[0.0, 0.0, theta], v0=[V, 0.0, 0.0], h=0.01, t_end=1.0)
            note("rod slide: path error", stop_error(r))
            note("rod slide: friction work error", abs(r.friction_work.sum() + MASS * V**2 / 2))
        r = sim("box", b).simulate(q0=[0.0, 0.5, 0.0], v0=[V, 0.0, 0.0], h=0.01, t_end=1.0)
        note("box slide: path error", stop_error(r))
        for seed in range(8):
            q0, v0, params = drop(seed, (1.2, 2.0))
            r = sim("box", b).simulate(q0=q0, v0=v0, h=0.005, t_end=10.0, params=params)
            note("box drops: |p| over the last 50 steps", np.abs(r.p[-50:]).max())
            note("box drops: |sum of forces - m g|", abs(r.contact_force[-1].sum() - G))
            note("box drops: at rest from t", at_rest_from(r))
    runs = [
        ("rod", dict(zip(("q0", "v0", "params"), drop(1)), h=0.005, t_end=4.0)),
        ("rod", dict(q0=[0.0, 0.0, 0.0], v0=[V, 0.0, 0.0], h=0.01, t_end=1.0)),
        ("box", dict(zip(("q0", "v0", "params"), drop(2, (1.2, 2.0))), h=0.005, t_end=10.0)),
    ]
    for name, run in runs:
        a, c = (sim(name, bk).simulate(**run) for bk in ("casadi", "c"))
        note("C - CasADi: q", np.abs(a.q - c.q).max())
        note("C - CasADi: p", np.abs(a.p - c.p).max())
        note("C - CasADi: friction work", np.abs(a.friction_work - c.friction_work).max())
    for key, value in worst.items():
        print(f"{key:45s} {value:.3g}")


def sweep() -> None:
    for name, height in (("rod", (0.8, 1.5)), ("box", (1.2, 2.0))):
        for b in ("casadi", "c"):
            for h in (0.01, 0.005, 0.002):
                fails, moving = [], []
                for seed in range(30):
                    q0, v0, params = drop(seed, height)
                    try:
                        r = sim(name, b).simulate(q0=q0, v0=v0, h=h, t_end=10.0, params=params)
                    except Exception as err:  # noqa: BLE001 -- counted, whatever it is
                        fails.append((seed, type(err).__name__))
                        continue
                    if np.abs(r.p[-1]).max() > 1e-12:
                        moving.append((seed, round(params["e"], 2)))
                print(f"{name} {b} h={h}: {len(fails)} failed {fails}; not at rest (seed, e): {moving}")


if __name__ == "__main__":
    sweep() if "--sweep" in sys.argv else main()
