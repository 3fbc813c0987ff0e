"""The C simulator's grid buffers are reused from call to call (``vcigen.backends.crun.Block``): a
run's result must never change when later runs write, and a run on reused buffers must equal the same
run on fresh ones bit for bit (``A``, ``F``, ``FC`` read 0 where the C loop writes nothing).
"""

from __future__ import annotations

import gc

import numpy as np
import pytest
from hard_scenes import backend_param, simulator
from test_many_runs import assert_same

from vcigen.backends import crun

pytestmark = list(backend_param("c").marks)

ARRAYS = ("t", "q", "p", "energy", "active", "contact_force", "constraint_force")
HELD = dict(q0=[0.0, 0.05], v0=[0.3, 0.0], h=0.005, t_end=1.6, params={"e": 0.5})  # held from ~row 40 of 320


def snapshot(res) -> dict[str, np.ndarray]:
    return {name: getattr(res, name).copy() for name in ARRAYS}


def fresh(sim, *args, **kwargs):
    """The run on buffers of its own (no block from the pool)."""
    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(crun, "BLOCK_MIN_BYTES", 1 << 62)
        return sim.simulate(*args, **kwargs)


@pytest.fixture
def blocks(monkeypatch: pytest.MonkeyPatch):
    """Every simulate run on a block of the pool, however short."""
    monkeypatch.setattr(crun, "BLOCK_MIN_BYTES", 0)


def test_a_later_call_does_not_alter_an_earlier_result(blocks) -> None:
    """Results held while more runs (of unknown and known length) reuse the pool keep their values;
    each block lent to a result that is still alive is not lent again."""
    sim = simulator("ball", "c")
    first = sim.simulate([0.0, 1.0], [0.3, 0.0], 0.01, n_impacts=7, params={"e": 1.0})
    second = sim.simulate(**HELD)
    kept = [snapshot(first), snapshot(second)]
    for q0 in ([0.1, 0.7], [0.2, 0.3], [0.0, 0.9]):
        sim.simulate(q0, [0.0, 0.0], 0.01, n_impacts=5)
        sim.simulate(q0, [0.5, 0.0], 0.005, t_end=1.6, params={"e": 0.3})
    for res, was in zip((first, second), kept):
        for name in ARRAYS:
            assert np.array_equal(getattr(res, name), was[name]), name
    assert first.q.base is not None and not np.shares_memory(first.q, second.q)


def test_a_reused_block_gives_the_run_of_fresh_buffers(monkeypatch: pytest.MonkeyPatch, blocks) -> None:
    """A run held on the floor (rows of A and F written) gives its block back when its result is gone;
    the next runs on that block (of unknown and of known length) equal the same runs on fresh buffers,
    their A and F zero where nothing is held."""
    monkeypatch.setattr(crun, "RESERVE_BYTES", 8 * 2 * 200)  # an n_impacts run fits the held run's block
    sim = simulator("ball", "c")
    sim._pool.clear()
    held = sim.simulate(**HELD)
    assert held.active[:90].any() and held.contact_force[:90].any()  # rows the next run writes
    del held
    gc.collect()
    assert len(sim._pool) == 1
    block = sim._pool[0]
    bounce = sim.simulate([0.0, 1.0], [0.3, 0.0], 0.005, n_impacts=1, params={"e": 1.0})
    assert np.shares_memory(bounce.q, block.raw), "the run must have used the pooled block"
    ref = fresh(sim, [0.0, 1.0], [0.3, 0.0], 0.005, n_impacts=1, params={"e": 1.0})
    assert bounce.t.size > 80 and not bounce.active.any() and not bounce.contact_force.any()
    assert_same(bounce, ref)
    del bounce
    gc.collect()
    again = sim.simulate(**HELD)
    assert np.shares_memory(again.q, block.raw)
    assert_same(again, fresh(sim, **HELD))


def test_a_run_that_outgrows_its_block_equals_fresh_buffers(monkeypatch: pytest.MonkeyPatch, blocks) -> None:
    """A run of unknown length past its block's rows continues on copies (the block back to the pool)."""
    monkeypatch.setattr(crun, "RESERVE_BYTES", 8 * 2 * 64)  # 64 rows: the run doubles several times
    sim = simulator("ball", "c")
    sim._pool.clear()
    res = sim.simulate([0.0, 1.0], [0.3, 0.0], 0.01, n_impacts=12, params={"e": 1.0})
    assert res.t.size > 4 * 64
    assert_same(res, fresh(sim, [0.0, 1.0], [0.3, 0.0], 0.01, n_impacts=12, params={"e": 1.0}))
    assert len(sim._pool) == 1 and not np.shares_memory(res.q, sim._pool[0].raw)


def test_threads_calling_simulate_on_one_simulator(blocks) -> None:
    """Two threads sharing one simulator's pool: every result equals its run on fresh buffers and no
    two results share memory."""
    from concurrent.futures import ThreadPoolExecutor

    sim = simulator("ball", "c")
    starts = [([0.05 * k, 0.3 + 0.1 * k], [0.2, 0.0]) for k in range(8)]

    def run(start):
        return sim.simulate(*start, 0.01, n_impacts=4, params={"e": 0.9})

    with ThreadPoolExecutor(2) as pool:
        results = list(pool.map(run, starts))
    for (q0, v0), res in zip(starts, results):
        assert_same(res, fresh(sim, q0, v0, 0.01, n_impacts=4, params={"e": 0.9}))
    assert not any(np.shares_memory(a.q, b.q) for i, a in enumerate(results) for b in results[i + 1 :])
