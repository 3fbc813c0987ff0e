"""The hand-written held steps that ``bench/held_curved.py`` times as the generated loop's limit take the same
steps as the generated code (a limit that computed something else would be no limit)."""

from __future__ import annotations

import sys
import warnings
from pathlib import Path

import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

import vcigen  # noqa: E402
from bench import held_curved  # noqa: E402

STEPS = 2000


@pytest.mark.parametrize(
    ("scene", "label"),
    [(scene, label) for scene, hands in held_curved.HANDS.items() for label in hands],
)
def test_handwritten_step_is_the_generated_one(scene: str, label: str) -> None:
    name, model, h, _, (q0, v0, params), _ = next(run for run in held_curved.RUNS if run[0] == scene)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        res = vcigen.build(model(), backend="c").simulate(q0, v0, h, t_end=STEPS * h, params=params)
    assert res.active.all() and res.t.size == STEPS + 1
    _, Q, P, F = held_curved.handwritten(held_curved.HANDS[scene][label])(q0, v0, h, STEPS)
    assert held_curved.apart(scene, label, res, Q, P, F) < 1e-9
    assert np.abs(Q - res.q[:-1]).max() > 1e-4  # it moves: the check is not of a particle at rest
