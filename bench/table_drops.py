"""Random runs of a ball on a shaken table: it rests, leaves where the table falls faster than gravity, flies,
lands, bounces to rest (Zeno) or locks in a cycle, or bounces chaotically.

    .venv/bin/python -m bench.table_drops [--drops 3000] [--seed 1] [--h 0.001] [--backend c]
    .venv/bin/python -m bench.table_drops --plastic [--drops 1000] [--seed 1] [--h 0.001]
    .venv/bin/python -m bench.table_drops --agree [--drops 1000] [--seed 5]

The model of ``tests/test_shaken_table.py`` (the table's frame: ``y'' = -g + A W^2 sin(W t)``, ``y >= 0``,
restitution ``e``). Each draw: ``Gamma = A W^2 / g`` uniform in (1.05, 8), ``W`` in (5, 120), ``e``
from {0, 0.1, 0.3, 0.5, 0.7, 0.9, 0.95}, at rest on the table or (one in two) dropped from up to 5 cm; to
``t = 2``.

* Tallies per backend: the runs that end in a ``SolverError`` (each printed), the flags of
  ``bench.random_runs.contact_flags``, a lift-off more than 1e-9 from an exact lift-off instant
  (``sin(W t) = 1 / Gamma``, rising), the ball below the table by more than 1e-9; the extremes.
* ``--plastic``: draws with ``e = 0`` and ``Gamma`` in (1.05, 3.3) against the test's event-driven closed-form
  reference: the runs whose lift-offs before ``t = 1.95`` differ from the reference's in number or by more
  than 1e-9 (each printed). With ``e > 0`` bounces shorter than a step land at first order and the cycle a
  run locks into can differ (e.g. ``Gamma = 2.6``, ``W = 66.8``, ``e = 0.1``: alike from ``h = 2.5e-4``).
* ``--agree``: each draw on both backends, those more than 1e-6 apart printed.
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

import vcigen

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))

from test_shaken_table import ES, phase_error, reference, shake, simulator  # noqa: E402

from bench.random_runs import arguments, contact_flags, dispatch, least_force, lift_offs_against  # noqa: E402


def draw(rng: np.random.Generator, plastic: bool = False):
    """One start ``(q0, v0, params)``."""
    gamma = float(rng.uniform(1.05, 3.3 if plastic else 8.0))
    p = shake(gamma, float(rng.uniform(5, 120)), 0.0 if plastic else float(rng.choice(ES)))
    return [float(rng.choice([0.0, rng.uniform(0, 0.05)]))], [0.0], p


def extremes(res: vcigen.Result, p: dict) -> dict[str, float]:
    return {
        "largest lift-off error": max((phase_error(t, p) for t, _ in res.liftoffs), default=0.0),
        "lowest y": float(res.q[:, 0].min()),
        "least force": least_force(res),
        "most impacts in a step": int(np.bincount([im.step for im in res.impacts]).max(initial=0)),
        "most impacts in a run": len(res.impacts),
    }


def flags(res: vcigen.Result, p: dict) -> dict[str, bool]:
    most = extremes(res, p)
    off = most["largest lift-off error"] > 1e-9
    return {**contact_flags(res), "lift-off off its instant": off, "below": most["lowest y"] < -1e-9}


def plastic(drops: int, seed: int, h: float) -> None:
    """``e = 0`` draws' lift-offs before ``t = 1.95`` against the reference, each to 1e-9."""

    def lifts(start, t_end: float) -> list[float]:
        return [ev[1] for ev in reference(start[0][0], start[2], t_end - 0.05) if ev[0] == "lift"]

    def draw_plastic(rng: np.random.Generator):
        return draw(rng, plastic=True)

    lift_offs_against(simulator("c"), draw_plastic, lifts, drops, seed, h, 2.0, 1.95, 1e-9)


def main() -> None:
    ap = arguments(__doc__, seed=1, h=0.001)
    ap.add_argument("--plastic", action="store_true", help="e = 0: lift-offs against the reference")
    drops = {"agree": 1000, "plastic": 1000, "tally": 3000}
    dispatch(ap.parse_args(), simulator, draw, flags, extremes, 2.0, drops, {"plastic": plastic})


if __name__ == "__main__":
    main()
