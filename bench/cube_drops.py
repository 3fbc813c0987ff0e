"""Random drops of a cube on its four lower vertices (``examples/contact/cube_settles.py``'s model), smooth
and rough, on both backends: how many end in a ``SolverError``, and the rough landings' known limit.

    .venv/bin/python -m bench.cube_drops [--drops 200] [--seed 7] [--backends c casadi]

* smooth: ``e`` in [0, 1] (half the drops ``e = 0``), from ``z = 1`` tilted up to 0.5 rad with random
  velocities, to t = 3 at h = 0.005: runs that end in a ``SolverError`` (by message), the lowest vertex, the
  largest energy rise at an impact, the runs resting on a face at the end, the most impacts in a step. A run
  whose pitch or roll passes 1.4 has tipped onto another face, where the model (its lower vertices only; ZYX
  angles singular at pitch pi/2) no longer holds: counted apart, with its error if it ends in one.
* rough: the same with ``mu`` in [0, 1] (a fifth of the drops on CasADi, which is slower), and the runs whose
  landing's friction was left out (their indices, the first 20).
* the rough landings (README *Known limits*): the cube set down flat from 0.3 while sliding at 2 (``mu =
  0.5``, ``e = 0``) against Coulomb's speed after the landing, ``2 - mu g t_land``; a symmetric edge landing
  (pitch 0.3, sliding at 1.5 along x) and the turn about z it ends with (0 by symmetry).
"""

from __future__ import annotations

import argparse
import math
import sys
import time
import warnings
from collections import Counter
from pathlib import Path

import numpy as np

import vcigen

sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "examples" / "contact"))
import cube_settles  # noqa: E402 - the example's folder on the path first

G, A = cube_settles.G, cube_settles.A
TIPPED = 1.4  # |theta| or |phi| above this: on another face (pitch: near the angles' singularity)


def scene(rng: np.random.Generator, rough: bool) -> tuple[list, list, dict]:
    """One random drop: ``(q0, v0, params)`` from ``z = 1``, tilted up to 0.5 rad, ``e`` 0 in half the drops
    (else in [0, 1]), rough: ``mu`` in [0, 1]."""
    q0 = [0.0, 0.0, 1.0, rng.uniform(0, 3), *rng.uniform(-0.5, 0.5, 2)]
    v0 = [*rng.uniform(-2, 2, 2), rng.uniform(-2, 0.5), *rng.uniform(-3, 3, 3)]
    params = {"e": float(rng.choice([0.0, rng.uniform(0, 1)]))}
    if rough:
        params["mu"] = float(rng.uniform(0, 1))
    return q0, v0, params


CUTS = ("loads_passed", "sticks_kept", "jams", "restitution_reduced")


def drops(sim: vcigen.Simulator, n: int, seed: int, rough: bool) -> str:
    rng = np.random.default_rng(seed)
    errors: Counter = Counter()
    low, rise, rest, most, ok, dropped = 0.0, 0.0, 0, 0, 0, []
    cut: Counter = Counter()  # runs with each of CUTS: cycles at one instant cut, restitution reduced
    start = time.perf_counter()
    for drop in range(n):
        q0, v0, params = scene(rng, rough)
        try:
            res = sim.simulate(q0=q0, v0=v0, h=0.005, t_end=3.0, params=params)
        except vcigen.SolverError as err:
            tipped = np.abs(err.result.q[:, 4:6]).max() > TIPPED
            errors[("tipped onto another face: " if tipped else "") + err.reason.split(";")[0][:60]] += 1
            continue
        if np.abs(res.q[:, 4:6]).max() > TIPPED:  # on another face (the model has the lower four vertices)
            errors["tipped onto another face, ran to t = 3"] += 1
            continue
        ok += 1
        dropped += [drop] if res.stats["landing_friction_dropped"] > 0 else []
        cut.update(key for key in CUTS if res.stats[key])
        heights = cube_settles.heights(res.q)
        low = min(low, float(heights.min()))
        rise = max([rise] + [(i.energy_after - i.energy_before) / abs(i.energy_before) for i in res.impacts])
        rest += bool(np.abs(heights[-1]).max() < 1e-9 and np.abs(res.p[-1, [2, 4, 5]]).max() < 1e-9)
        most = max(most, int(np.bincount([i.step for i in res.impacts]).max()) if res.impacts else 0)
    wall = time.perf_counter() - start
    lines = [
        f"  {ok} of {n} ran to t = 3 on their lower face ({wall:.1f} s); resting on a face at the end: "
        f"{rest}; lowest vertex {low:.1e}; largest energy rise at an impact {rise:.1e} (relative); most "
        f"impacts in a step {most}"
    ]
    if rough:
        listed = ", ".join(map(str, dropped[:20])) + (", ..." if len(dropped) > 20 else "")
        lines[0] += f"; runs with a landing's friction left out: {len(dropped)}"
        lines[0] += f" (drops {listed})" if dropped else ""
    lines[0] += "; runs with " + ", ".join(f"{key} > 0: {cut[key]}" for key in CUTS)
    lines += [f"  x{count}: {why}" for why, count in errors.most_common()]
    return "\n".join(lines)


def landings(sim: vcigen.Simulator) -> str:
    drop, v, mu = 0.3, 2.0, 0.5
    res = sim.simulate(
        q0=[0, 0, A / 2 + drop, 0, 0, 0],
        v0=[v, 0, 0, 0, 0, 0],
        h=0.005,
        t_end=0.3,
        params={"mu": mu, "e": 0.0},
    )
    t_land = res.impacts[0].t
    k = int(np.searchsorted(res.t, t_land))
    coulomb = v - mu * G * t_land - mu * G * (res.t[k] - t_land)
    flat = (
        f"  flat landing while sliding at {v}: speed {res.p[k, 0]:.4f} after it, Coulomb's {coulomb:.4f} "
        f"(landing contacts left without friction: {res.stats['landing_friction_dropped']})"
    )
    res = sim.simulate(
        q0=[0, 0, 0.9, 0, 0.3, 0], v0=[1.5, 0, 0, 0, 0, 0], h=0.005, t_end=1.5, params={"mu": mu, "e": 0.0}
    )
    edge = [f"{i.contact} {i.impulse:.4f}" for i in res.impacts[:2]]
    turn = math.degrees(res.q[-1, 3])
    return (
        flat + f"\n  symmetric edge landing: impulses {', '.join(edge)} (equal by symmetry); turn at rest "
        f"{turn:.2f} deg (0)"
    )


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--drops", type=int, default=200)
    ap.add_argument("--seed", type=int, default=7)
    ap.add_argument("--backends", nargs="+", default=["c", "casadi"], choices=["c", "casadi"])
    a = ap.parse_args(argv)
    warnings.simplefilter("ignore", RuntimeWarning)  # the landings' left-out friction: counted instead
    for backend in a.backends:
        n = a.drops if backend == "c" else max(1, a.drops // 5)
        smooth = vcigen.build(cube_settles.model(), backend=backend)
        rough = vcigen.build(cube_settles.model(mu=0.5), backend=backend)
        print(f"[{backend}] smooth, {n} drops (seed {a.seed}):\n{drops(smooth, n, a.seed, False)}")
        print(f"[{backend}] rough, {n} drops (seed {a.seed}):\n{drops(rough, n, a.seed, True)}")
        print(f"[{backend}] rough landings:\n{landings(rough)}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
