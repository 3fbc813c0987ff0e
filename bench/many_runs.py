"""Many short runs: a Python loop of ``simulate`` against ``vcigen.sweep`` on 1 and 2 Dask workers (issue 13).

    .venv/bin/python bench/many_runs.py [--k 2000] [--repeats 3] [--workers 1,2]

For the paper's particle (h = 0.01, t_end = 0.5: 50 steps, one impact) and star (h = 0.005,
t_end = 2: 400 steps, a few impacts), K runs from K different starts (C backend):

* ``loop``: ``[sim.simulate(**run) for run in runs]`` in this process (the simulator built once);
* ``sweep W``: ``vcigen.sweep`` on a local cluster of W worker processes (one thread each), started
  once and warmed up by a first sweep (in which each worker builds its simulator: timed apart, as
  ``first sweep``), then timed with ``reduce`` (a few numbers per run come back) and without
  (every ``Result`` comes back).

Per run: wall time / K, the best of ``--repeats``. Speed-ups are against the loop, and 2 workers
against 1. ``sweep overhead`` is (sweep on 1 worker - loop) / K: what a run costs beyond ``simulate``
itself when it goes through Dask; ``loop inside a worker task`` times the same loop inside one task
on the 1-worker cluster, so that the worker's own speed is told apart from what Dask adds.
The machine is shared: read ratios from one run of this script.
Writes ``bench/results/many_runs.csv``.
"""

from __future__ import annotations

import argparse
import csv
import importlib
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

import numpy as np  # noqa: E402

import vcigen  # noqa: E402
from bench.timing import best_of  # noqa: E402
from vcigen.cli import load_example  # noqa: E402

sweep_module = importlib.import_module("vcigen.sweep")  # the module (vcigen.sweep is the function)
OUT = ROOT / "bench" / "results" / "many_runs.csv"
COLUMNS = ["scene", "k", "steps_per_run", "variant", "workers", "us_per_run", "vs_loop", "seconds"]


def particle_runs(k: int) -> list[dict]:
    """K drops of the particle from heights 0.5..1.5 and horizontal speeds -2..2: 50 steps each."""
    y = np.linspace(0.5, 1.5, k)
    vx = np.linspace(-2.0, 2.0, k)[::-1]
    return [{"q0": [0.0, float(a)], "v0": [float(b), 0.0], "h": 0.01, "t_end": 0.5} for a, b in zip(y, vx)]


def star_runs(k: int) -> list[dict]:
    """K drops of the star from heights 1.5..3.5 with spins -5..5: 400 steps each."""
    y = np.linspace(1.5, 3.5, k)
    om = np.linspace(-5.0, 5.0, k)[::-1]
    run = {"h": 0.005, "t_end": 2.0}
    return [{"q0": [0.0, float(a), 0.0], "v0": [-2.0, 0.0, float(b)], **run} for a, b in zip(y, om)]


SCENES = {"particle": particle_runs, "star": star_runs}


def impacts(res: vcigen.Result) -> int:
    """The reduce of the timed sweeps: one number per run travels back."""
    return res.n_impacts


def loop_on_worker(spec, runs: list[dict], repeats: int) -> float:
    """On a worker: the best wall time of the plain loop over ``runs`` with the worker's simulator."""
    sim = sweep_module.worker_simulator(spec)
    return best_of(lambda: [sim.simulate(**r) for r in runs], repeats=repeats)[1]


def measure(name: str, k: int, workers: list[int], repeats: int) -> list[dict]:
    import distributed

    model = load_example(ROOT / "examples" / f"{name}.py").model()
    runs = SCENES[name](k)
    sim = vcigen.build(model, backend="c")
    serial, loop = best_of(lambda: [sim.simulate(**r) for r in runs], repeats=repeats)
    steps = int(np.mean([r.t.size - 1 for r in serial]))
    rows = [_row(name, k, steps, "loop of simulate", 0, loop, loop)]
    want = [r.n_impacts for r in serial]
    for w in workers:
        start = time.perf_counter()
        cluster = distributed.LocalCluster(
            n_workers=w, threads_per_worker=1, processes=True, dashboard_address=None
        )
        client = distributed.Client(cluster)
        started = time.perf_counter() - start
        rows.append(_row(name, k, steps, "cluster start", w, started, loop, per_run=False))
        try:
            kw = {"client": client, "progress": False}
            first, wall = best_of(vcigen.sweep, model, runs, reduce=impacts, repeats=1, **kw)
            assert first == want, "sweep differs from the loop"
            rows.append(_row(name, k, steps, "first sweep (workers build)", w, wall, loop))
            got, wall = best_of(vcigen.sweep, model, runs, reduce=impacts, repeats=repeats, **kw)
            assert got == want
            rows.append(_row(name, k, steps, "sweep, reduce", w, wall, loop))
            full, wall = best_of(vcigen.sweep, model, runs, repeats=repeats, **kw)
            assert all(np.array_equal(a.q, b.q) for a, b in zip(full, serial))
            rows.append(_row(name, k, steps, "sweep, full results", w, wall, loop))
            if w == 1:  # the same loop, timed inside one task on the worker: what Dask adds is the rest
                spec = sweep_module.SimulatorSpec(model, "c", "trapezoid", None, {})
                wall = client.submit(loop_on_worker, spec, runs, repeats, pure=False).result()
                rows.append(_row(name, k, steps, "loop inside a worker task", w, wall, loop))
        finally:
            client.close()
            cluster.close()
    return rows


def _row(scene, k, steps, variant, workers, seconds, loop, per_run=True) -> dict:
    return {
        "scene": scene,
        "k": k,
        "steps_per_run": steps,
        "variant": variant,
        "workers": workers,
        "us_per_run": 1e6 * seconds / k if per_run else float("nan"),
        "vs_loop": loop / seconds if per_run else float("nan"),
        "seconds": seconds,
    }


def report(rows: list[dict]) -> list[str]:
    """A markdown table, then speed-ups of 2 workers against 1 and the per-run overhead of a sweep."""
    lines = ["| scene | K | steps/run | variant | workers | us per run | speed-up vs loop | wall [s] |"]
    lines.append("|---|---|---|---|---|---|---|---|")
    for r in rows:
        us = "" if np.isnan(r["us_per_run"]) else f"{r['us_per_run']:.0f}"
        sp = "" if np.isnan(r["vs_loop"]) else f"x{r['vs_loop']:.2f}"
        lines.append(
            f"| {r['scene']} | {r['k']} | {r['steps_per_run']} | {r['variant']} | {r['workers'] or ''} "
            f"| {us} | {sp} | {r['seconds']:.2f} |"
        )
    for scene in dict.fromkeys(r["scene"] for r in rows):
        by = {(r["variant"], r["workers"]): r for r in rows if r["scene"] == scene}
        loop = by[("loop of simulate", 0)]
        one, two = by.get(("sweep, reduce", 1)), by.get(("sweep, reduce", 2))
        if one:
            over = one["us_per_run"] - loop["us_per_run"]
            lines.append(f"\n{scene}: sweep overhead on 1 worker {over:+.0f} us per run (sweep - loop)")
        if one and two:
            lines.append(f"{scene}: 2 workers against 1: x{one['seconds'] / two['seconds']:.2f}")
    return lines


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--k", type=int, default=2000, help="runs per scene (default 2000)")
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--workers", default="1,2", help="cluster sizes, comma list (default 1,2)")
    ap.add_argument("--scenes", default=",".join(SCENES))
    ap.add_argument("--out", type=Path, default=OUT)
    args = ap.parse_args(argv)
    workers = [int(w) for w in args.workers.split(",") if w]
    rows = []
    for name in args.scenes.split(","):
        rows += measure(name, args.k, workers, args.repeats)
    print("\n".join(report(rows)), flush=True)
    args.out.parent.mkdir(parents=True, exist_ok=True)
    with args.out.open("w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=COLUMNS)
        w.writeheader()
        w.writerows({k: (f"{v:.6g}" if isinstance(v, float) else v) for k, v in r.items()} for r in rows)
    print(f"wrote {args.out}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
