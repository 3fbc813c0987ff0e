"""Long runs of the speed-against-error bench (bench/run.py): energy over >= 1e5 steps, drift over 1e6 (C)."""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from bench import baselines
from bench import scenes as bench_scenes
from bench.methods import METHODS, VcigenSims, log, vcigen_runs
from bench.plots import plot_energy
from bench.scenes import Scene
from bench.sweeps import SETUPS, Array, min_phi, relative_drift, write_csv


@dataclass
class LongRun:
    scene: str
    method: str
    h: float
    steps: int
    wall: float = float("nan")
    impacts: int = 0
    energy_dev: float = float("nan")
    drift: float = float("nan")  # fitted relative change of E over the whole run
    min_phi: float = float("nan")
    note: str = ""
    t: Array = field(default_factory=lambda: np.empty(0), repr=False)
    rel_e: Array = field(default_factory=lambda: np.empty(0), repr=False)


LONG_COLUMNS = [
    "scene",
    "method",
    "h",
    "steps",
    "wall_s",
    "impacts",
    "energy_dev",
    "drift",
    "min_phi",
    "note",
]


def long_run(sims: VcigenSims, scene: Scene, method: str, h: float, steps: int) -> LongRun:
    """One run of ``steps * h`` seconds from the scene's start; energy kept for the plot."""
    lr = LongRun(scene.name, method, h, steps)
    t_end = steps * h
    if method.startswith("vcigen_"):
        runs = vcigen_runs(sims, method, scene, h, [(0.0, scene.q0, scene.v0)], t_end)
    else:
        sc = scene
        kw = {"grid_h": h} if METHODS[method].kind == "rtol" else {}
        x = 1e-10 if METHODS[method].kind == "rtol" else h
        try:
            r = baselines.METHODS[method](sc, x, t_end=t_end, **kw)
        except Exception as exc:  # noqa: BLE001
            r = {"fail": f"{type(exc).__name__}: {exc}"}
        runs = [r if ("skip" in r or "fail" in r) else {**r, "steps": r["t"].size - 1}]
    r = runs[0]
    if "skip" in r or "fail" in r:
        lr.note = r.get("skip") or r.get("fail")
        return lr
    en = np.asarray(r["energy"], float)
    t = np.asarray(r["t"], float)[: en.size]
    e0 = en[0] if en[0] != 0 else 1.0
    lr.wall = float(r["wall"])
    lr.impacts = len(r["impacts"])
    lr.rel_e = (en - en[0]) / abs(e0)
    lr.t = t
    lr.energy_dev = float(np.max(np.abs(lr.rel_e)))
    lr.drift = relative_drift(t, en) * (t[-1] - t[0])
    lr.min_phi = min_phi(scene, np.asarray(r["q"]))
    if r.get("fell_through"):
        lr.note = f"fell through the contact at t = {t[-1]:.3g} after {lr.impacts} impacts (a missed impact)"
    elif r.get("stalled"):
        lr.note = f"stuck re-impacting at one instant (kink chatter) at t = {r['stalled']:.4g}"
    elif t[-1] < t_end - 2 * h:
        lr.note = f"stopped at t = {t[-1]:.4g}"
    lr.steps = int(t.size - 1) if method.startswith(("vcigen", "verlet")) else steps
    return lr


# the C methods of the drift runs (1e6 steps): both second-order rules and the fourth-order lobatto3
DRIFT_METHODS = ("vcigen_c_trapezoid", "vcigen_c_midpoint", "vcigen_c_lobatto3")


def long_csv_row(r: LongRun) -> list[object]:
    vals = (r.wall, r.impacts, r.energy_dev, r.drift, r.min_phi)
    return [r.scene, r.method, f"{r.h:g}", r.steps, *(f"{v:.6g}" for v in vals), r.note]


def long_runs(sims, scenes, methods, args, out: Path, skips) -> tuple[list[LongRun], list[LongRun]]:
    longs: list[LongRun] = []
    drift_runs: list[LongRun] = []
    have_c = sims.backend_missing("c") is None
    for s in scenes:
        setup = SETUPS[s]
        if setup.long_h is None:
            continue
        scene = bench_scenes.get(s)
        cand = ["vcigen_c_trapezoid", "vcigen_c_lobatto3", "vcigen_casadi_trapezoid"]
        cand += ["verlet_half_flip", "verlet_full_flip", "dop853_events", "dop853_events_ms"]
        mine = [m for m in cand if m in methods and (have_c or not m.startswith("vcigen_c_"))]
        here = []
        for m in mine:
            t0 = time.perf_counter()
            lr = long_run(sims, scene, m, setup.long_h, args.long_steps)
            here.append(lr)
            log(
                f"[bench long] {s:15s} {m:24s} h={setup.long_h:g} {args.long_steps} steps: "
                f"wall {lr.wall:.3g}s impacts {lr.impacts} max dE/E0 {lr.energy_dev:.2e} "
                f"drift {lr.drift:.2e} ({time.perf_counter() - t0:.1f}s) {lr.note}"
            )
        longs += here
        try:
            plot_energy(out / f"energy_{s}.png", s, here)
        except ImportError as exc:
            log(f"[bench] no plots: {exc}")
        if have_c:
            for m in DRIFT_METHODS:
                if m in methods:
                    lr = long_run(sims, scene, m, setup.long_h, args.drift_steps)
                    lr.t = lr.rel_e = np.empty(0)
                    drift_runs.append(lr)
                    log(
                        f"[bench drift] {s:15s} {m:24s} {args.drift_steps} steps: wall {lr.wall:.3g}s "
                        f"max dE/E0 {lr.energy_dev:.2e} drift {lr.drift:.2e} {lr.note}"
                    )
        else:
            skips.setdefault(
                "energy drift after 1e6 steps",
                "not measured: needs the vcigen C backend, which is not available",
            )
    write_csv(out / "longrun.csv", LONG_COLUMNS, [long_csv_row(r) for r in [*longs, *drift_runs]])
    return longs, drift_runs
