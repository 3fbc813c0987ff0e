"""Random pendulums and linkages in maximal coordinates with contacts on both backends: errors, rows below 0,
disagreements.

    .venv/bin/python -m bench.chains_fuzz --scene pendulum [--draws 150] [--seed 1]
    .venv/bin/python -m bench.chains_fuzz --scene four_bar [--draws 150] [--seed 2]

Bilateral constraints held beside unilateral contacts (issue 9, item 4), each draw's ``e`` 0, 1 or uniform in
[0, 1], ``mu`` 0 or uniform in [0, 1.5], ``h`` 0.001, 0.01 or 0.03, run to t = 3:

* ``pendulum``: a double pendulum as two unit bobs on two unit rods (``tests/test_closed_chains.py``'s), both
  bobs over a rough floor ``y >= -1.5`` and the second left of a wall ``x <= 0.9``. Each draw: both angles
  uniform (an admissible start), half at rest, half with angular velocities of spread 3.
* ``four_bar``: ``examples/contact/four_bar.py``'s parallelogram, both bobs over the rough floor ``y >=
  -0.9``: the coupler stays level, so both land at once on rows that the bars make dependent. Each draw: the
  angle uniform over the admissible ones (one draw in five on the floor), angular velocity 0 or of spread 2.

Printed as ``bench.pyramids`` prints: each draw that ends in an error, goes below a row by more than 1e-9 or
whose backends end apart (more than 1e-6, or other impact counts), then the tallies. Stop 43, before the held
rows' forces at an impact were read at its state (``HeldImpacts._chain_impact``): pendulum seed 1, 150 draws:
0 errors, 0 below, 7 apart (all ``e = 0``, impact counts alone: bounces of 1e-8 before the bob was held);
four_bar seed 2: 0 errors, 0 below, 36 apart (the same). After: 0 apart and 12 apart (all ``e = 0``, both bobs
landing at once: round-off decides whether the second row's crossing joins the instant; the states agree to
1e-12). Stop 50, since an impact while held that the incoming velocity does not press in is read again once
stopped (``HeldImpacts._stopped_pressed``: the bob is held at its landing, not stopped, let go and met again
at once): pendulum seed 1 and four_bar seeds 1 and 2, 150 draws each: 0 errors, 0 below, 0 apart.
"""

from __future__ import annotations

import argparse
import math
import sys
from pathlib import Path

import numpy as np
import sympy as sp

import vcigen
from bench.pyramids import fuzz

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "examples" / "contact"))
import four_bar  # noqa: E402 - examples/contact/four_bar.py: the linkage's bars

G, LOW, WALL, FLOOR4 = 9.81, -1.5, 0.9, four_bar.FLOOR


def _params() -> tuple[sp.Symbol, sp.Symbol]:
    return sp.Symbol("mu", nonnegative=True), sp.Symbol("e", nonnegative=True)


def pendulum() -> vcigen.Model:
    x1, y1, x2, y2, u1, v1, u2, v2 = sp.symbols("x1 y1 x2 y2 u1 v1 u2 v2")
    mu, e = _params()
    contacts = {"f1": y1 - LOW, "f2": y2 - LOW, "wall": WALL - x2}
    return vcigen.Model(
        name="pendulum_fuzz",
        q=[x1, y1, x2, y2],
        qdot=[u1, v1, u2, v2],
        lagrangian=(u1**2 + v1**2 + u2**2 + v2**2) / 2 - G * (y1 + y2),
        contacts=contacts,
        constraints={"rod1": x1**2 + y1**2 - 1, "rod2": (x2 - x1) ** 2 + (y2 - y1) ** 2 - 1},
        params={mu: 0.5, e: 0.5},
        restitution={n: e for n in contacts},
        friction={"f1": (mu, x1), "f2": (mu, x2)},
    )


def pendulum_gap(q: np.ndarray) -> float:
    return float(min((q[:, 1] - LOW).min(), (q[:, 3] - LOW).min(), (WALL - q[:, 2]).min()))


def _drawn(rng: np.random.Generator) -> dict:
    e = float(rng.choice([0.0, 1.0, rng.uniform()]))
    mu = float(rng.choice([0.0, rng.uniform(0, 1.5)]))
    return {"h": float(rng.choice([0.001, 0.01, 0.03])), "params": {"e": e, "mu": mu}}


def pendulum_draw(rng: np.random.Generator) -> dict:
    d = _drawn(rng)
    while True:
        a, b = rng.uniform(-math.pi, math.pi, 2)
        q = [math.sin(a), -math.cos(a)]
        q += [q[0] + math.sin(b), q[1] - math.cos(b)]
        if min(q[1] - LOW, q[3] - LOW, WALL - q[2]) > 1e-3:
            break
    wa, wb = rng.normal(0, 3, 2) * rng.choice([0, 1])
    v = [wa * math.cos(a), wa * math.sin(a)]
    v += [v[0] + wb * math.cos(b), v[1] + wb * math.sin(b)]
    return {"q0": q, "v0": [float(x) for x in v], **d}


def linkage() -> vcigen.Model:
    m = four_bar.model()
    (xb, yb, xc, yc), (mu, e) = m.q, _params()
    contacts = {"fb": yb - FLOOR4, "fc": yc - FLOOR4}
    return vcigen.Model(
        name="four_bar_fuzz",
        q=m.q,
        qdot=m.qdot,
        lagrangian=m.lagrangian,
        contacts=contacts,
        constraints=m.constraints,
        params={mu: 0.5, e: 0.5},
        restitution={n: e for n in contacts},
        friction={"fb": (mu, xb), "fc": (mu, xc)},
    )


def linkage_gap(q: np.ndarray) -> float:
    return float(min((q[:, 1] - FLOOR4).min(), (q[:, 3] - FLOOR4).min()))


def linkage_draw(rng: np.random.Generator) -> dict:
    d = _drawn(rng)
    low = math.asin(FLOOR4)  # B on the floor, right of the pivot; pi - low: left of it
    theta = float(rng.uniform(low + 1e-3, math.pi - low - 1e-3)) if rng.uniform() < 0.8 else low
    w = float(rng.normal(0, 2) * rng.choice([0, 1]))
    b = [math.cos(theta), math.sin(theta)]
    return {"q0": b + [2 + b[0], b[1]], "v0": [-w * b[1], w * b[0]] * 2, **d}


SCENES = {
    "pendulum": (pendulum, pendulum_draw, pendulum_gap),
    "four_bar": (linkage, linkage_draw, linkage_gap),
}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--scene", choices=sorted(SCENES), default="pendulum")
    ap.add_argument("--draws", type=int, default=150)
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--t-end", type=float, default=3.0)
    a = ap.parse_args()
    model, draw, gap = SCENES[a.scene]
    t = fuzz(model(), draw, gap, a.t_end, a.draws, a.seed)
    errors, below = t["errors"], t["below"]
    print(
        f"{a.scene}: {a.draws} draws (seed {a.seed}): errors C {errors['c']}, CasADi {errors['casadi']}; "
        f"below a row by more than 1e-9: C {below['c']}, CasADi {below['casadi']}; apart: {t['apart']} "
        f"(parted in one step: {t['parted']})"
    )


if __name__ == "__main__":
    main()
