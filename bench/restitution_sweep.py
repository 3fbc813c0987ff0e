"""How often a body coming to rest ends the run (restitution, no resting-contact mode).

    .venv/bin/python bench/restitution_sweep.py [--runs 400] [--backend c]

Random particles in a box (W, H in [0.2, 2], start anywhere inside, speeds in [-3, 3],
h in [0.005, 0.05], seed 1) under gravity g = 9.81 for 1 s, with coefficient of restitution
e uniform in [0, 1] on every wall. Prints the share of runs that stop early with a
SolverError, by decile of e, and the phases of those errors.
"""

from __future__ import annotations

import argparse
import sys
import warnings
from collections import Counter
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))

from hard_scenes import box  # noqa: E402

import vcigen  # noqa: E402


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--runs", type=int, default=400)
    ap.add_argument("--backend", default="c", choices=["c", "casadi"])
    a = ap.parse_args()
    warnings.simplefilter("ignore", RuntimeWarning)
    sim = vcigen.build(box(lossy=True), backend=a.backend)
    rng = np.random.default_rng(1)
    stopped, total, phases = np.zeros(10), np.zeros(10), Counter()
    for _ in range(a.runs):
        W, H = rng.uniform(0.2, 2, 2)
        e = rng.uniform(0, 1)
        fx, fy = rng.uniform(0.02, 0.98, 2)
        vx, vy = rng.uniform(-3, 3, 2)
        h = rng.uniform(0.005, 0.05)
        k = min(int(e * 10), 9)
        total[k] += 1
        try:
            sim.simulate([fx * W, fy * H], [vx, vy], h, t_end=1.0, params={"W": W, "H": H, "g": 9.81, "e": e})
        except vcigen.SolverError as err:
            stopped[k] += 1
            phases[err.phase + (" (grazing)" if "grazing" in err.reason else "")] += 1
    print("e decile      runs  stopped early")
    for k in range(10):
        print(f"[{k / 10:.1f}, {(k + 1) / 10:.1f})  {int(total[k]):5d}  {stopped[k] / max(total[k], 1):6.0%}")
    print("phases:", dict(phases))


if __name__ == "__main__":
    main()
