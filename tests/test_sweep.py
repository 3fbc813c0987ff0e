"""``vcigen.sweep`` on a 2-worker local Dask cluster: the results of serial runs, in order, bit for bit."""

from __future__ import annotations

import csv
import importlib
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

import vcigen
from vcigen import cli

distributed = pytest.importorskip("distributed")

from scenes import load_example  # noqa: E402

sweep_module = importlib.import_module("vcigen.sweep")  # the module (vcigen.sweep is the function)
G_OVERFLOW = 1e308  # gravity that overflows the first step: a SolverError at step 0


@pytest.fixture(scope="module")
def client():
    cluster = distributed.LocalCluster(
        n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None
    )
    cl = distributed.Client(cluster)
    yield cl
    cl.close()
    cluster.close()


@pytest.fixture(scope="module")
def model() -> vcigen.Model:
    return load_example("particle").model()


@pytest.fixture(scope="module")
def sim(model):
    return vcigen.build(model, backend="c")


def runs(k: int = 24) -> list[dict]:
    """Different starts, steps, stopping rules and gravities: no two runs alike."""
    out = []
    for i in range(k):
        run = {"q0": [0.1 * i, 0.5 + 0.05 * i], "v0": [-2.0 + 0.1 * i, 0.3 * (i % 3)]}
        run["h"] = 0.01 / (1 + i % 2)
        run.update({"t_end": 1.0 + 0.1 * i} if i % 4 else {"n_impacts": 3 + i % 5})
        if i % 3 == 0:
            run["params"] = {"g": 9.81 + i}
        out.append(run)
    return out


def assert_same(a: vcigen.Result, b: vcigen.Result) -> None:
    for name in ("t", "q", "p", "energy"):
        np.testing.assert_array_equal(getattr(a, name), getattr(b, name), err_msg=name)
    assert [(i.t, i.contact, i.alpha, i.kind) for i in a.impacts] == [
        (i.t, i.contact, i.alpha, i.kind) for i in b.impacts
    ]


def worker_cache_sizes(client) -> list[int]:
    return sorted(client.run(lambda: len(sweep_module._SIMULATORS)).values())


def test_sweep_equals_serial_runs_in_order_and_each_worker_builds_once(client, model, sim):
    todo = runs()
    got = vcigen.sweep(model, todo, backend="c", client=client, batch_size=3, progress=False)
    assert len(got) == len(todo)
    for run, res in zip(todo, got):
        assert_same(res, sim.simulate(**run))
    assert worker_cache_sizes(client) == [1, 1]  # both workers ran batches, each built the simulator once
    again = vcigen.sweep(model, todo[:6], backend="c", client=client, batch_size=1, progress=False)
    for a, b in zip(again, got[:6]):
        assert_same(a, b)
    assert worker_cache_sizes(client) == [1, 1]  # the second sweep found them in the cache


def test_reduce_runs_on_the_worker_and_only_its_value_comes_back(client, model, sim):
    todo = runs(12)
    got = vcigen.sweep(model, todo, client=client, reduce=lambda res: (res.n_impacts, float(res.q[-1, 1])))
    assert got == [(r.n_impacts, float(r.q[-1, 1])) for r in (sim.simulate(**run) for run in todo)]


def test_a_scheduler_address_runs_there(client, model, sim):
    todo = runs(4)
    got = vcigen.sweep(model, todo, client=client.scheduler.address, reduce=lambda res: res.t[-1])
    assert got == [sim.simulate(**run).t[-1] for run in todo]
    assert client.status == "running"  # the sweep closed only its own connection


def test_a_failed_run_raises_naming_its_index_or_takes_its_place(client, model, sim):
    todo = runs(8)
    todo[5] = {**todo[5], "params": {"g": G_OVERFLOW}}
    with pytest.raises(vcigen.SolverError, match="sweep run 5: step 0") as info:
        vcigen.sweep(model, todo, client=client, batch_size=2)
    assert info.value.run == 5
    assert info.value.result is not None and info.value.phase == "smooth"
    got = vcigen.sweep(model, todo, client=client, batch_size=2, errors="return", reduce=lambda r: r.t[-1])
    assert isinstance(got[5], vcigen.SolverError) and got[5].run == 5 and got[5].result is not None
    assert [v for i, v in enumerate(got) if i != 5] == [
        sim.simulate(**run).t[-1] for i, run in enumerate(todo) if i != 5
    ]


def test_bad_runs_are_named(client, model):
    with pytest.raises(ValueError, match=r"sweep run 1 has keyword\(s\) \['tend'\]"):
        vcigen.sweep(model, [runs(1)[0], {"q0": [0, 1], "v0": [0, 0], "h": 0.01, "tend": 1}], client=client)
    bad = runs(3)
    bad[2] = {**bad[2], "q0": [0.0, -1.0]}
    with pytest.raises(ValueError, match="sweep run 2 .*violates contact 'floor'"):
        vcigen.sweep(model, bad, client=client, batch_size=1)
    with pytest.raises(ValueError, match="unknown backend"):
        vcigen.sweep(model, runs(1), backend="fortran", client=client)
    with pytest.raises(ValueError, match="client must be"):
        vcigen.sweep(model, runs(1), client=42)
    with pytest.raises(RuntimeError, match="sweep run 0: reduce raised ZeroDivisionError"):
        vcigen.sweep(model, runs(2), client=client, reduce=lambda res: 1 / 0, batch_size=2)
    assert vcigen.sweep(model, [], client=client) == []


def test_without_dask_the_error_says_what_to_install(model, monkeypatch):
    monkeypatch.setitem(sys.modules, "distributed", None)
    with pytest.raises(ImportError, match=r"pip install 'dask\[distributed\]'"):
        vcigen.sweep(model, runs(1))


@pytest.mark.slow
def test_the_monte_carlo_example_runs_in_its_fast_setting(client, tmp_path):
    """examples/contact/star_rest_time.py --n 40 on this module's cluster: its rows are the serial runs'."""
    root = Path(__file__).resolve().parents[1]
    script = root / "examples" / "contact" / "star_rest_time.py"
    argv = [sys.executable, str(script), "--n", "40", "--t-end", "20", "--seed", "3", "--out", str(tmp_path)]
    env = {**os.environ, "PYTHONPATH": str(root)}
    proc = subprocess.run(
        [*argv, "--scheduler", client.scheduler.address], capture_output=True, text=True, env=env, timeout=600
    )
    assert proc.returncode == 0, proc.stderr[-2000:]
    assert "sweep: 40 runs of 4000 steps" in proc.stdout
    assert (tmp_path / "star_rest_time.png").stat().st_size > 1000
    with (tmp_path / "star_rest_time.csv").open() as fh:
        rows = list(csv.DictReader(fh))
    example = cli.load_example(script)
    starts = example.starts(40, 3)
    assert len(rows) == 40
    np.testing.assert_array_equal([[float(r[c]) for c in example.START] for r in rows], starts)
    settled = [r for r in rows if r["settled"] == "1"]
    assert len(settled) >= 36  # the star comes to rest within 20 s from almost every drop
    assert max(abs(float(r["rest_energy_dev"])) for r in settled) < 1e-9  # E_d at rest = m vx^2/2 + m g L/2
    sim = vcigen.build(example.model(), backend="c")
    for k in (0, 17, 39):  # the reduced values are those of serial runs
        want = example.rest_time(sim.simulate(**example.run_of(starts[k], 0.005, 20.0)))
        got = [rows[k][c] for c in ("settled", "rest_time", "impacts", "plastic")]
        assert [str(int(want[0])), repr(want[1]), str(want[2]), str(want[3])] == got
