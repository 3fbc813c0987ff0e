"""Speed against error, side by side (issue 5): ``make bench`` / ``vcigen bench``.

Sweeps the step size ``h`` (the step methods) and ``rtol`` (the event-driven
``solve_ivp`` methods) on four scenes and measures, per run: wall time of the
integration, position error at a fixed time after the first collision and after
a few impacts (against a reference), maximum energy deviation, energy drift,
impacts missed or spurious, and the largest constraint violation. Then long
runs (energy against time over >= 1e5 steps, drift after 1e6 steps with the C
backend). Writes ``bench/results/``: ``<scene>.csv``, ``longrun.csv``,
``wp_<scene>.png``, ``energy_<scene>.png``, ``summary.md``.

Every run starts at one of several *start phases* ``tau_j`` in ``[0, 0.02)``
(the reference state at ``tau_j``) and is evaluated at ``tau_j + T``, so the
first impact falls at different places inside a step; errors are RMS over the
phases, wall times the median. Under linear gravity free flight is exact for
every method here, so ``particle`` and ``star`` measure only impact handling;
``star_nonlinear`` and ``pendulum_wall`` measure accuracy.

Usage: ``python bench/run.py [--scenes a,b] [--methods m,n] [--hs 0.01,0.005]
[--rtols 1e-6,1e-10] [--targets 1e-4,1e-8] [--phases 8] [--no-long] [--out DIR]``.

This file is the entry point; one module per concern beside it: ``scenes.py`` (the scenes),
``methods.py`` (the methods and how each runs a scene), ``sweeps.py`` (start phases, references,
the sweep and its rows), ``long_runs.py`` (energy over long runs), ``plots.py`` (work-precision and
energy plots), ``summary.py`` (``summary.md`` and the README headline).
"""

from __future__ import annotations

import argparse
import dataclasses
import sys
import time
from collections.abc import Sequence
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

from bench import scenes as bench_scenes  # noqa: E402
from bench.long_runs import LongRun, long_runs  # noqa: E402
from bench.methods import METHODS, VcigenSims, log  # noqa: E402
from bench.plots import plot_work_precision  # noqa: E402
from bench.summary import README_END, README_START, order_of, update_readme, wall_at, write_summary  # noqa: E402
from bench.sweeps import CSV_COLUMNS, RTOLS, SETUPS, Row, match_impacts, sweep_scene, write_csv  # noqa: E402

DEFAULT_OUT = ROOT / "bench" / "results"
__all__ = [  # what tests and other scripts take from here
    "CSV_COLUMNS",
    "README_END",
    "README_START",
    "Row",
    "main",
    "match_impacts",
    "order_of",
    "update_readme",
    "wall_at",
]


def parse(argv: Sequence[str] | None) -> argparse.Namespace:
    ap = argparse.ArgumentParser(prog="bench/run.py", description=__doc__.split("\n\n")[0])
    ap.add_argument("--scenes", default=",".join(SETUPS), help="comma list (default: all four)")
    ap.add_argument("--methods", default=",".join(METHODS), help="comma list (default: all)")
    ap.add_argument("--hs", default=None, help="override the h sweep of every scene, comma list")
    ap.add_argument("--rtols", default=",".join(f"{r:g}" for r in RTOLS))
    ap.add_argument("--phases", type=int, default=8, help="start phases per (method, h)")
    ap.add_argument("--targets", default="1e-4,1e-8", help="accuracies for 'wall time to reach', comma list")
    ap.add_argument("--long-steps", type=int, default=100_000, help="steps of the energy long runs")
    ap.add_argument("--drift-steps", type=int, default=1_000_000, help="steps of the C drift runs")
    ap.add_argument("--no-long", action="store_true", help="skip the long runs")
    ap.add_argument("--out", type=Path, default=DEFAULT_OUT)
    return ap.parse_args(argv)


def main(argv: Sequence[str] | None = None) -> int:
    args = parse(argv)
    total0 = time.perf_counter()
    scenes = [s for s in args.scenes.split(",") if s]
    methods = [m for m in args.methods.split(",") if m]
    for s in scenes:
        if s not in SETUPS:
            raise SystemExit(f"unknown scene {s!r}; known: {', '.join(SETUPS)}")
    for m in methods:
        if m not in METHODS:
            raise SystemExit(f"unknown method {m!r}; known: {', '.join(METHODS)}")
    rtols = tuple(float(r) for r in args.rtols.split(","))
    targets = tuple(float(t) for t in args.targets.split(","))
    setups = dict(SETUPS)
    if args.hs:
        hs = tuple(float(h) for h in args.hs.split(","))
        setups = {k: dataclasses.replace(v, hs=hs, fine_hs=(), high_order_hs=hs) for k, v in setups.items()}
    out: Path = args.out
    out.mkdir(parents=True, exist_ok=True)
    sims = VcigenSims()
    skips: dict[str, str] = {}
    for backend in ("c",):
        reason = sims.backend_missing(backend)
        if reason and any(m.startswith(f"vcigen_{backend}_") for m in methods):
            log(f"[bench] SKIP vcigen C (both rules): {reason}")
            skips["vcigen C"] = reason
    n_runs = sum(
        len(setups[s].hs_for(m)) if METHODS[m].kind == "h" else len(rtols) for s in scenes for m in methods
    )
    counter = [0, n_runs, time.perf_counter()]  # runs done, runs in all, start: the ETA of each line
    all_rows: dict[str, list[Row]] = {}
    for s in scenes:
        scene = bench_scenes.get(s)
        rows = sweep_scene(sims, scene, setups[s], methods, rtols, args.phases, counter)
        all_rows[s] = rows
        write_csv(out / f"{s}.csv", CSV_COLUMNS, [r.csv() for r in rows])
        for r in rows:
            if r.note.startswith("skip") and f"{r.method} on {s}" not in skips:
                skips[f"{r.method} on {s}"] = r.note[6:]
        try:
            plot_work_precision(out / f"wp_{s}.png", s, rows, setups[s])
        except ImportError as exc:
            log(f"[bench] no plots: {exc}")
    longs: list[LongRun] = []
    drift_runs: list[LongRun] = []
    if not args.no_long:
        longs, drift_runs = long_runs(sims, scenes, methods, args, out, skips)
    total = time.perf_counter() - total0
    write_summary(out / "summary.md", all_rows, longs, drift_runs, targets, skips, total, args)
    if out.resolve() == DEFAULT_OUT.resolve():
        update_readme(out / "summary.md", ROOT / "README.md")
    log(f"[bench] done in {total:.0f}s; results in {out}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main(sys.argv[1:]))
