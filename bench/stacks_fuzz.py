"""Random piles of balls and boxes on boxes on both backends: errors, rows below 0, disagreements.

    .venv/bin/python -m bench.stacks_fuzz --scene pile [--draws 300] [--seed 2]
    .venv/bin/python -m bench.stacks_fuzz --scene boxes [--draws 150] [--seed 1]

The models of ``tests/test_stacks.py``:

* ``pile``: four unit balls in space, isotropic cones on the floor (``tetra_pile``). Each draw: ``mu`` 0 or
  uniform in [0, 1.5]; ``h`` 0.001, 0.005 or 0.02; the top 0 or up to 0.3 above the three lower balls and 0
  or up to 0.2 off the axis in ``x`` and in ``y``; the lower balls spread apart by up to 0.3 (7 draws in 10);
  half at rest, half with velocities of spread 0.5 (none vertical for the lower balls); to t = 2.
* ``boxes``: a box dropped onto a box on a rough floor (``two_boxes``): ``h`` 0.001, 0.005 or 0.02; the upper
  box up to 0.3 to the side, tilted by up to 0.3, 0 or up to 0.3 above; half at rest, half with velocities of
  spread 0.5; to t = 3. A run whose upper box leaves the lower one's face is out of the model (its face is a
  plane) and counted apart.

Printed as ``bench.pyramids`` prints: each draw that ends in an error, goes below a row by more than 1e-9 or
whose backends end apart (more than 1e-6, or other impact counts; with the times they first part by 1e-12,
1e-9 and 1e-6), then the tallies. Stop 41: pile seed 2, 300 draws: 0 errors (3 before the crowded laws), 3
apart; boxes seed 1, 150 draws: 0 errors, 1 out of the model, 11 apart. Stop 42: pile 2 apart (185 and 205,
mirror images); boxes 0 apart (an unconverged bracket end, a bounce's next crossing found at the bounce).
"""

from __future__ import annotations

import argparse
import math
import sys
from pathlib import Path

import numpy as np

from bench.pyramids import fuzz

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))
from test_stacks import HALF_H, HALF_W, R, _tetra_start, box_gap, tetra_pile, two_boxes  # noqa: E402


def pile_draw(rng: np.random.Generator) -> dict:
    rng.choice([0.0, 1.0, rng.uniform()])  # a restitution the model does not take: drawn so that seeds repeat
    mu = float(rng.choice([0.0, rng.uniform(0, 1.5)]))
    h = float(rng.choice([0.001, 0.005, 0.02]))
    lift = float(rng.choice([0.0, rng.uniform(0, 0.3)]))
    q0 = _tetra_start(lift)
    q0[3] += float(rng.choice([0.0, rng.uniform(-0.2, 0.2)]))
    q0[7] += float(rng.choice([0.0, rng.uniform(-0.2, 0.2)]))
    spread = float(rng.uniform(0, 0.3)) if rng.uniform() < 0.7 else 0.0
    for i in range(3):  # the lower balls apart, radially
        r0 = math.hypot(q0[i], q0[4 + i])
        q0[i] *= (r0 + spread) / r0
        q0[4 + i] *= (r0 + spread) / r0
    above = max(
        math.sqrt(max(4 * R * R - (q0[3] - q0[i]) ** 2 - (q0[7] - q0[4 + i]) ** 2, 0.0)) for i in range(3)
    )
    above += R
    q0[11] = max(q0[11], above + lift)  # the top admissible above its nearest lower ball
    v0 = rng.normal(0, 0.5, 12) * rng.choice([0, 1])
    v0[8] = v0[9] = v0[10] = 0.0
    return {"q0": q0, "v0": [float(x) for x in v0], "h": h, "params": {"mu": mu}}


def pile_gap(q: np.ndarray) -> float:
    x, y, z = q[:, 0:4], q[:, 4:8], q[:, 8:12]
    low = float((z - R).min())
    for i in range(4):
        for j in range(i + 1, 4):
            apart = np.sqrt((x[:, j] - x[:, i]) ** 2 + (y[:, j] - y[:, i]) ** 2 + (z[:, j] - z[:, i]) ** 2)
            low = min(low, float(apart.min()) - 2 * R)
    return low


def boxes_draw(rng: np.random.Generator) -> dict:
    h = float(rng.choice([0.001, 0.005, 0.02]))
    off, tilt = float(rng.uniform(-0.3, 0.3)), float(rng.uniform(-0.3, 0.3))
    drop = float(rng.choice([0.0, rng.uniform(0, 0.3)]))
    q0 = [0.0, HALF_H, 0.0, off, 3 * HALF_H + drop + HALF_W * abs(math.sin(tilt)) + 1e-9, tilt]
    v0 = [0.0, 0.0, 0.0] + [float(x) for x in rng.normal(0, 0.5, 3) * rng.choice([0, 1])]
    return {"q0": q0, "v0": v0, "h": h}


SCENES = {
    "pile": (tetra_pile, pile_draw, pile_gap, 2.0),
    "boxes": (two_boxes, boxes_draw, box_gap, 3.0),
}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--scene", choices=sorted(SCENES), default="pile")
    ap.add_argument("--draws", type=int, default=300)
    ap.add_argument("--seed", type=int, default=2)
    a = ap.parse_args()
    model, draw, gap, t_end = SCENES[a.scene]
    outside = None
    if a.scene == "boxes":  # the upper box off the lower one's face: its plane is the model's

        def outside(res) -> bool:
            return any(np.abs(r.q[:, 3] - r.q[:, 0]).max() > 2 * HALF_W for r in res.values())

    t = fuzz(model(), draw, gap, t_end, a.draws, a.seed, outside)
    errors, below = t["errors"], t["below"]
    print(
        f"{a.scene}: {a.draws} draws (seed {a.seed}): errors C {errors['c']}, CasADi {errors['casadi']}; "
        f"below a row by more than 1e-9: C {below['c']}, CasADi {below['casadi']}; out of the model: "
        f"{t['outside']}; backends apart: {t['apart']} (parted in one step: {t['parted']})"
    )


if __name__ == "__main__":
    main()
