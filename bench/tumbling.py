"""A rigid box tumbling onto a rough floor, random drops; and a tall block rocking on a rough corner.

    .venv/bin/python -m bench.tumbling [--drops 200] [--seed 7] [--backend c casadi]
    .venv/bin/python -m bench.tumbling --agree [--drops 300] [--seed 7]

``--agree`` runs each drop on both backends and prints those that end in an error, below the floor or apart
(more than 1e-6, or other impact counts; ``bench.pyramids.fuzz``). Stop 42: 300 drops of seed 7, 0 apart (3
before: drop 138 8.4e-5 apart at t = 3, drops 178 and 238 on other impact logs).

* **Drops** (the model of ``tests/test_tumbling_box.py``: a box with half sides 0.5 x 0.25, four vertex
  contacts with restitution ``e`` and Coulomb friction ``mu``): thrown from ``y = 1`` with ``theta0`` in
  ``(-pi, pi)``, ``v0`` in ``(-2, 2) x (-1, 1) x (-5, 5)``, ``e, mu`` uniform in ``(0, 1)``, ``h = 0.005``,
  to ``t = 3``. Per backend: the runs that end in a ``SolverError`` (each printed with its drop), the most
  impacts and lift-offs logged in one grid step, the lowest vertex's height.
* **Rough rocking** (the block of ``tests/test_rocking_block.py``, half sides 0.5 x 0.2, ``e = 0``, each
  corner with one tangent and ``mu``), released on a corner tilted by 0.1 at rest, ``h = 1e-3``, to ``t = 3``:
  the first landings' ``thetad+ / thetad-`` (the grid velocities either side of the landing's step) against
  Housner's ``1 - 3/2 sin^2 alpha`` (the landing corner sticks, the pivot leaves) and the frictionless
  ``(a^2 - 2 b^2) / (a^2 + 4 b^2)``, at ``mu = 0.8`` and ``mu = 3``.
"""

from __future__ import annotations

import argparse
import math
import sys
from pathlib import Path

import numpy as np
import sympy as sp

import vcigen

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))

from test_tumbling_box import lowest_vertex, tumble  # noqa: E402

ROCK_A, ROCK_B = 0.5, 0.2


def drop(rng: np.random.Generator) -> dict:
    """One random drop: ``simulate``'s arguments (the draws in the order every seed's drops were made)."""
    th0 = rng.uniform(-math.pi, math.pi)
    v0 = [rng.uniform(-2, 2), rng.uniform(-1, 1), rng.uniform(-5, 5)]
    e, mu = rng.uniform(0, 1), rng.uniform(0, 1)
    return {"q0": [0.0, 1.0, th0], "v0": v0, "h": 0.005, "params": {"e": e, "mu": mu}}


def drops(backend: str, n: int, seed: int) -> None:
    sim = vcigen.build(tumble(), backend=backend)
    rng = np.random.default_rng(seed)
    fails, most, low = [], 0, math.inf
    for k in range(n):
        d = drop(rng)
        th0, v0, e, mu = d["q0"][2], d["v0"], d["params"]["e"], d["params"]["mu"]
        try:
            res = sim.simulate(**d, t_end=3.0, progress=False)
        except vcigen.SolverError as err:
            fails.append(k)
            print(f"  drop {k}: theta0 {th0!r}, v0 {v0}, e {e!r}, mu {mu!r}: {err}")
            res = err.result
        if res.impacts:
            most = max(most, int(np.bincount([im.step for im in res.impacts]).max()))
        low = min(low, float(lowest_vertex(res.q).min()))
    print(
        f"{backend}: {len(fails)} of {n} drops end in a SolverError; at most {most} impacts in a step; "
        f"lowest vertex {low:.1e}"
    )


def rough_block() -> vcigen.Model:
    x, y, th, xd, yd, thd = sp.symbols("x y th xd yd thd")
    mu = sp.Symbol("mu")
    inertia = (ROCK_A**2 + ROCK_B**2) / 3
    corners = {"left": (-ROCK_B, -ROCK_A), "right": (ROCK_B, -ROCK_A)}
    return vcigen.Model(
        name="rough_block",
        q=[x, y, th],
        qdot=[xd, yd, thd],
        lagrangian=(xd**2 + yd**2) / 2 + inertia * thd**2 / 2 - 9.81 * y,
        contacts={k: y + px * sp.sin(th) + py * sp.cos(th) for k, (px, py) in corners.items()},
        params={mu: 0.8},
        restitution={"left": 0.0, "right": 0.0},
        friction={k: (mu, x + px * sp.cos(th) - py * sp.sin(th)) for k, (px, py) in corners.items()},
    )


def rocking(backend: str) -> None:
    sim = vcigen.build(rough_block(), backend=backend)
    alpha = math.atan2(ROCK_B, ROCK_A)
    housner = 1 - 1.5 * math.sin(alpha) ** 2
    smooth = (ROCK_A**2 - 2 * ROCK_B**2) / (ROCK_A**2 + 4 * ROCK_B**2)
    y0 = ROCK_B * math.sin(0.1) + ROCK_A * math.cos(0.1)
    for mu in (0.8, 3.0):
        try:
            res = sim.simulate(
                [0.0, y0, 0.1], [0.0, 0.0, 0.0], 1e-3, t_end=3.0, params={"mu": mu}, progress=False
            )
            end = "to t = 3"
        except vcigen.SolverError as err:
            res, end = err.result, f"SolverError: {err}"
        ratios = [res.v[im.step + 1, 2] / res.v[im.step, 2] for im in res.impacts[:3]]
        out = f"thetad+/thetad- {', '.join(f'{r:.3f}' for r in ratios)}; {end}"
        print(f"{backend} mu = {mu}: {out} (Housner {housner:.3f}, frictionless {smooth:.3f})")


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--drops", type=int, default=200)
    ap.add_argument("--seed", type=int, default=7)
    ap.add_argument("--backend", nargs="+", default=["c", "casadi"])
    ap.add_argument(
        "--agree",
        action="store_true",
        help="run each drop on both backends and print those that end apart (bench.pyramids.fuzz) instead",
    )
    args = ap.parse_args(argv)
    if args.agree:
        from bench.pyramids import fuzz

        t = fuzz(tumble(), drop, lambda q: float(lowest_vertex(q).min()), 3.0, args.drops, args.seed)
        errors, below = t["errors"], t["below"]
        print(
            f"{args.drops} drops (seed {args.seed}): errors C {errors['c']}, CasADi {errors['casadi']}; "
            f"below the floor by 1e-9: C {below['c']}, CasADi {below['casadi']}; apart: {t['apart']}"
        )
        return 0
    for backend in args.backend:
        drops(backend, args.drops, args.seed)
        rocking(backend)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
