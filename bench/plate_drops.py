"""Random runs of a box on a rough vibrating plate: it sticks, slides, rocks, hops and lands on its vertices.

    .venv/bin/python -m bench.plate_drops [--drops 1500] [--seed 1] [--h 0.005] [--backend c]
    .venv/bin/python -m bench.plate_drops --agree [--drops 300] [--seed 7]

The model of ``tests/test_box_on_a_vibrating_plate.py`` (the plate's frame: a force of time on the box's
centre, a contact on each of its four corners with Coulomb friction ``mu`` and restitution ``e``; its
``draw``); to ``t = 2``. Before stop 58 the model had the two lower corners alone: a quarter of the runs
turned the box over, its upper corners through the plate unseen.

* Tallies per backend: the runs that end in a ``SolverError`` (each printed, with the flags its run so far
  holds), the flags of ``bench.random_runs.contact_flags``, a vertex below the plate by more than 1e-9,
  friction work above 1e-9 in a step, more than 3 impacts in a step, the box turned over (an impact on one
  of its upper corners); the extremes.
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
        "turned over": any(im.contact.startswith("upper") for im in res.impacts),
    }


def main() -> None:
    args = arguments(__doc__, seed=1, h=0.005).parse_args()
    dispatch(args, simulator, draw, flags, extremes, 2.0, {"agree": 300, "tally": 1500})


if __name__ == "__main__":
    main()
