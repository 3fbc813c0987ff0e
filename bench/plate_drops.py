"""Random runs of a box on a rough vibrating plate: it sticks, slides, rocks, hops and lands on its vertices.

    .venv/bin/python -m bench.plate_drops [--drops 1500] [--seed 1] [--h 0.005] [--backend c]
    .venv/bin/python -m bench.plate_drops --agree [--drops 300] [--seed 7]

The model of ``tests/test_box_on_a_vibrating_plate.py`` (the plate's frame: a force of time on the box's
centre, two lower vertices with Coulomb friction ``mu`` and restitution ``e``; its ``draw``); to ``t = 2``.

* Tallies per backend: the runs that end in a ``SolverError`` (each printed), the flags of
  ``bench.random_runs.contact_flags``, a vertex below the plate by more than 1e-9, friction work above 1e-9
  in a step, more than 3 impacts in a step; the extremes.
* ``--agree``: each draw on both backends, those more than 1e-6 apart printed.
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

import vcigen

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))

from test_box_on_a_vibrating_plate import draw, lowest, simulator  # noqa: E402

from bench.random_runs import arguments, contact_flags, dispatch, least_force  # noqa: E402


def extremes(res: vcigen.Result, params: dict) -> dict[str, float]:
    fw = res.friction_work
    return {
        "lowest vertex": lowest(res, params),
        "least force": least_force(res),
        "most friction work in a step": float(fw.max()) if fw is not None and fw.size else 0.0,
        "most impacts in a step": int(np.bincount([im.step for im in res.impacts]).max(initial=0)),
    }


def flags(res: vcigen.Result, params: dict) -> dict[str, bool]:
    most = extremes(res, params)
    return {
        **contact_flags(res),
        "below": most["lowest vertex"] < -1e-9,
        "friction pushing": most["most friction work in a step"] > 1e-9,
        "4+ impacts in a step": most["most impacts in a step"] > 3,
    }


def main() -> None:
    args = arguments(__doc__, seed=1, h=0.005).parse_args()
    dispatch(args, simulator, draw, flags, extremes, 2.0, {"agree": 300, "tally": 1500})


if __name__ == "__main__":
    main()
