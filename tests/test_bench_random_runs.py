"""``bench.random_runs.parted``: where two runs of one start part in one grid step, told from round-off that
grows smoothly (the agreement campaigns print which for each run apart)."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np

from bench.random_runs import PARTED, how_apart, parted


def _runs(gaps: np.ndarray) -> tuple[SimpleNamespace, SimpleNamespace]:
    t = np.linspace(0.0, 0.02 * (gaps.size - 1), gaps.size)
    q = np.column_stack([np.zeros_like(t), t])  # the gaps on a coordinate at 0: exact in floating point
    return SimpleNamespace(t=t, q=q), SimpleNamespace(t=t, q=q + np.column_stack([gaps, np.zeros_like(t)]))


def test_a_gap_grown_impact_by_impact_is_round_off() -> None:
    # a tumbling box's gap (bench.plate_drops --agree --seed 31 --h 0.02, drop 32): 1e-16 to 5e-6 over 100
    # steps, at most 25-fold in a step
    gaps = 1e-16 * np.cumprod(np.r_[1.0, np.where(np.arange(99) % 8 == 0, 25.0, 1.05)])
    a, b = _runs(gaps)
    assert gaps[-1] > 1e-6 and parted(a, b) is None
    assert how_apart(parted(a, b)) == "round-off grown"


def test_a_gap_that_jumps_in_one_step_is_where_they_parted() -> None:
    # drop 18 of the same campaign till stop 60: 3.6e-17 to 5.9e-4 in the step to t = 0.26
    gaps = np.r_[np.full(13, 3.6e-17), np.full(20, 5.9e-4)]
    a, b = _runs(gaps)
    t, before, after = parted(a, b)
    assert np.isclose(t, 0.26) and before == 3.6e-17 and after == 5.9e-4
    assert how_apart(parted(a, b)).startswith("parted in the step to t = 0.26 ")


def test_a_jump_below_1e_9_or_below_the_factor_is_not_a_parting() -> None:
    a, b = _runs(np.r_[np.full(5, 1e-16), np.full(5, 1e-10)])  # a 1e6-fold jump, but below 1e-9
    assert parted(a, b) is None
    a, b = _runs(np.r_[np.full(5, 1e-8), np.full(5, 0.9 * PARTED * 1e-8)])  # above 1e-9, below the factor
    assert parted(a, b) is None
