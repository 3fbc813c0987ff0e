"""Random runs of an impact damper: a driven primary on a spring, a ball in its cavity that rattles, rides a
wall, leaves it, touches and goes.

    .venv/bin/python -m bench.damper_drops [--drops 3000] [--seed 1] [--h 0.002] [--backend c]
    .venv/bin/python -m bench.damper_drops --plastic [--drops 1000] [--seed 1] [--h 0.002]
    .venv/bin/python -m bench.damper_drops --agree [--drops 300] [--seed 5]

The model of ``tests/test_impact_damper.py`` (``M = 1``, ``k = 4 pi^2``). Each draw: ``m`` in (0.02, 3), the
drive ``F`` in (2, 60) at ``W`` 0.4-2.5 times the primary's frequency (not within 2 of a resonance of ``M`` or
``M + m``: the reference's closed forms divide by it), half-gap ``d`` in (0.2, 100) mm, ``e`` from {0, 0.1,
0.3, 0.5, 0.7, 0.9, 0.95}, level or upright (``g`` 0 or 9.81 along ``-X``); the primary from ``X`` in (-0.1,
0.1), the ball anywhere in the cavity, both at speeds up to 1; to ``t = 3``.

* Tallies per backend: the runs that end in a ``SolverError`` (each printed), the flags of
  ``bench.random_runs.contact_flags``, the ball outside the cavity by more than 1e-9; the extremes.
* ``--plastic``: ``e = 0``, from rest at the centre, against the test's event-driven closed-form reference:
  the runs whose lift-offs before ``t = 2.9`` differ from the reference's in number or by more than 50 h^2
  (each printed), and the largest difference over h^2 of the others. Impacts are first met at O(h^2), but a
  later crossing's time grows from it (a slow crossing of a wide cavity: 168 h^2 at the third impact of
  ``test_impact_damper.TOUCH``), and a landing near the instant the wall stops pressing can stick in one and
  touch and go in the other.
* ``--agree``: each draw on both backends, those more than 1e-6 apart printed.
"""

from __future__ import annotations

import math
import sys
from pathlib import Path

import numpy as np

import vcigen

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))

from test_impact_damper import ES, K, gap, lift_times, params, reference, simulator  # noqa: E402

from bench.random_runs import arguments, contact_flags, dispatch, least_force, lift_offs_against  # noqa: E402


def draw_params(rng: np.random.Generator, plastic: bool = False) -> dict[str, float]:
    """One damper's parameters, off the resonances."""
    while True:
        W = float(rng.uniform(0.4, 2.5)) * math.sqrt(K)
        m = float(rng.uniform(0.02, 3.0))
        p = params(
            m,
            float(rng.uniform(2, 60)),
            W,
            float(rng.uniform(2e-4, 0.1)),
            0.0 if plastic else float(rng.choice(ES)),
            float(rng.choice([0.0, 9.81])),
        )
        if min(abs(K - W * W), abs(K - (1 + m) * W * W)) >= 2.0:
            return p


def draw(rng: np.random.Generator):
    """One start ``(q0, v0, params)``: the primary and the ball anywhere in its cavity, moving."""
    p = draw_params(rng)
    X = float(rng.uniform(-0.1, 0.1))
    x = X + float(rng.uniform(-1.0, 1.0)) * p["d"]
    return [X, x], [float(v) for v in rng.uniform(-1.0, 1.0, 2)], p


def extremes(res: vcigen.Result, p: dict) -> dict[str, float]:
    return {
        "lowest gap": float(gap(res, p).min()),
        "least force": least_force(res),
        "most impacts in a step": int(np.bincount([im.step for im in res.impacts]).max(initial=0)),
        "most impacts in a run": len(res.impacts),
        "most lift-offs in a run": len(res.liftoffs),
    }


def flags(res: vcigen.Result, p: dict) -> dict[str, bool]:
    return {**contact_flags(res), "outside": extremes(res, p)["lowest gap"] < -1e-9}


def plastic(drops: int, seed: int, h: float) -> None:
    """``e = 0`` draws from rest at the centre: their lift-offs before ``t = 2.9`` against the reference,
    each within 50 h^2."""

    def lifts(start, t_end: float) -> list[float]:
        return lift_times(reference(start[2], t_end))

    def draw_plastic(rng: np.random.Generator):
        return [0.0, 0.0], [0.0, 0.0], draw_params(rng, plastic=True)

    lift_offs_against(simulator("c"), draw_plastic, lifts, drops, seed, h, 3.0, 2.9, 50 * h**2)


def main() -> None:
    ap = arguments(__doc__, seed=1, h=0.002)
    ap.add_argument("--plastic", action="store_true", help="e = 0: lift-offs against the reference")
    drops = {"agree": 300, "plastic": 1000, "tally": 3000}
    dispatch(ap.parse_args(), simulator, draw, flags, extremes, 3.0, drops, {"plastic": plastic})


if __name__ == "__main__":
    main()
