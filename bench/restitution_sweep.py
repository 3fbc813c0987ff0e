"""Lossy boxes under gravity: how the runs end, by decile of the coefficient of restitution.

    .venv/bin/python bench/restitution_sweep.py [--runs 400] [--backend c casadi] [--strict [c casadi]]
                                                [--csv bench/results/restitution_sweep.csv]

Random particles in a box (W, H in [0.2, 2], start anywhere inside, speeds in [-3, 3],
h in [0.005, 0.05], seed 1; ``box(lossy=True)`` of tests/hard_scenes.py) under gravity
g = 9.81 for 1 s, with coefficient of restitution e uniform in [0, 1] on every wall. The
same 400 draws run on every backend given.

Default mode ``Tolerances()`` (``grazing="contact"``: an impact the jump cannot resolve is
plastic and the contact is held, MATH.md *Sustained contact*). ``--strict`` adds the paper's
method alone, ``Tolerances(grazing="error")`` (a SolverError where (48a) has no root), on the
backends named (``--strict c``), or on every ``--backend`` if none is named; on CasADi it takes
~12 min (every failing run retries the jump for seconds), on C under a second.

Per backend, mode and decile of e: runs; SolverErrors (target 0 in the default mode); share
of runs at rest at the end (some contact active at the last grid point); mean impacts per run;
the most impacts in one grid step (from ``Impact.step``); the largest energy rise at an impact
``max(E_after - E_before) / max(1, max|E|)`` (<= ~1e-10, but at a touch and go by the continuous law,
``"grazing"``: within its bias ``g^2 h^2 / 8``, docs/limits.md *Grazing impacts*); the smallest phi over the
grid (admissibility); the wall time of ``simulate`` summed over the decile. A run that ends in
a SolverError is counted with its partial ``err.result``. The first SolverErrors of the default
mode are printed with a reproducer. One CSV row per (backend, mode, decile) goes to ``--csv``.
"""

from __future__ import annotations

import argparse
import csv
import sys
import time
import warnings
from collections import Counter
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))

from hard_scenes import box  # noqa: E402

import vcigen  # noqa: E402

G = 9.81
COLUMNS = [
    "backend",
    "mode",
    "decile",
    "runs",
    "solver_errors",
    "at_rest",
    "mean_impacts",
    "max_impacts_per_step",
    "max_energy_rise",
    "min_phi",
    "wall_s",
]


def draws(n: int, seed: int = 1) -> list[dict]:
    """The runs of the sweep (same draw order as the original script)."""
    rng = np.random.default_rng(seed)
    out = []
    for _ in range(n):
        W, H = rng.uniform(0.2, 2, 2)
        e = rng.uniform(0, 1)
        fx, fy = rng.uniform(0.02, 0.98, 2)
        vx, vy = rng.uniform(-3, 3, 2)
        h = rng.uniform(0.005, 0.05)
        out.append(dict(W=W, H=H, e=e, q0=[fx * W, fy * H], v0=[vx, vy], h=h))
    return out


def box_min_phi(q: np.ndarray, W: float, H: float) -> float:
    """min over the grid of the four walls' phi: x, W - x, y, H - y."""
    if q.size == 0:
        return float("nan")
    return float(min(q[:, 0].min(), (W - q[:, 0]).min(), q[:, 1].min(), (H - q[:, 1]).min()))


def run_one(sim: vcigen.Simulator, d: dict) -> dict:
    params = {"W": d["W"], "H": d["H"], "g": G, "e": d["e"]}
    err = None
    t0 = time.perf_counter()
    try:
        res = sim.simulate(d["q0"], d["v0"], d["h"], t_end=1.0, params=params)
    except vcigen.SolverError as exc:
        err, res = exc, exc.result
    wall = time.perf_counter() - t0
    out = dict(error=err, wall=wall, impacts=0, per_step=0, rise=-np.inf, min_phi=np.nan, rest=False)
    if res is None:
        return out
    out["impacts"] = len(res.impacts)
    if res.impacts:
        out["per_step"] = max(Counter(im.step for im in res.impacts).values())
        scale = max(1.0, float(np.max(np.abs(res.energy)))) if res.energy.size else 1.0
        out["rise"] = max(im.energy_after - im.energy_before for im in res.impacts) / scale
    out["min_phi"] = box_min_phi(res.q, d["W"], d["H"])
    out["rest"] = err is None and res.active is not None and bool(res.active[-1].any())
    return out


def reproducer(d: dict, backend: str, mode: str, err: vcigen.SolverError) -> str:
    q0 = [repr(float(x)) for x in d["q0"]]
    v0 = [repr(float(x)) for x in d["v0"]]
    return (
        f"  backend={backend} mode={mode} W={d['W']!r} H={d['H']!r} e={d['e']!r} g={G}\n"
        f"  q0=[{', '.join(q0)}] v0=[{', '.join(v0)}] h={d['h']!r} t_end=1.0\n"
        f"  -> SolverError (phase {err.phase!r}): {err}"
    )


def table(backend: str, mode: str, runs: list[dict], outs: list[dict]) -> list[dict]:
    rows = []
    deciles = np.array([min(int(d["e"] * 10), 9) for d in runs])
    for k in [*range(10), None]:
        sel = [o for o, dk in zip(outs, deciles) if k is None or dk == k]
        n = len(sel)
        finite_phi = [o["min_phi"] for o in sel if np.isfinite(o["min_phi"])]
        rows.append(
            dict(
                backend=backend,
                mode=mode,
                decile="all" if k is None else f"[{k / 10:.1f},{(k + 1) / 10:.1f})",
                runs=n,
                solver_errors=sum(o["error"] is not None for o in sel),
                at_rest=sum(o["rest"] for o in sel) / max(n, 1),
                mean_impacts=sum(o["impacts"] for o in sel) / max(n, 1),
                max_impacts_per_step=max((o["per_step"] for o in sel), default=0),
                max_energy_rise=max((o["rise"] for o in sel), default=-np.inf),
                min_phi=min(finite_phi, default=np.nan),
                wall_s=sum(o["wall"] for o in sel),
            )
        )
    return rows


def print_table(rows: list[dict], outs: list[dict]) -> None:
    b, m = rows[0]["backend"], rows[0]["mode"]
    print(f"\nbackend {b}, mode {m}")
    print("e decile     runs  errors  at rest  impacts/run  max/step  max E rise   min phi     wall [s]")
    for r in rows:
        print(
            f"{r['decile']:<11} {r['runs']:5d}  {r['solver_errors']:6d}  {r['at_rest']:7.0%}"
            f"  {r['mean_impacts']:11.2f}  {r['max_impacts_per_step']:8d}  {r['max_energy_rise']:10.2e}"
            f"  {r['min_phi']:10.2e}  {r['wall_s']:9.3f}"
        )
    phases = Counter(
        o["error"].phase + (" (grazing)" if "grazing" in o["error"].reason else "")
        for o in outs
        if o["error"]
    )
    if phases:
        print("SolverError phases:", dict(phases))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--runs", type=int, default=400)
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--backend", nargs="+", default=["c", "casadi"], choices=["c", "casadi"])
    ap.add_argument(
        "--strict",
        nargs="*",
        choices=["c", "casadi"],
        metavar="BACKEND",
        help='also run Tolerances(grazing="error") (the paper alone) on these backends (none given: all)',
    )
    ap.add_argument(
        "--csv", type=Path, default=Path(__file__).resolve().parent / "results" / "restitution_sweep.csv"
    )
    ap.add_argument("--show-errors", type=int, default=5, help="reproducers printed per backend and mode")
    a = ap.parse_args()
    warnings.simplefilter("ignore", RuntimeWarning)
    runs = draws(a.runs, a.seed)
    strict = [] if a.strict is None else list(dict.fromkeys(a.strict or a.backend))
    tols = {"contact": vcigen.Tolerances(), "strict": vcigen.Tolerances(grazing="error")}
    all_rows = []
    for backend, mode in [*((b, "contact") for b in a.backend), *((b, "strict") for b in strict)]:
        tol = tols[mode]
        sim = vcigen.build(box(lossy=True), backend=backend, tol=tol)
        outs = [run_one(sim, d) for d in runs]
        rows = table(backend, mode, runs, outs)
        print_table(rows, outs)
        errs = [(d, o["error"]) for d, o in zip(runs, outs) if o["error"] is not None]
        for d, err in errs[: a.show_errors if mode == "contact" else 0]:
            print(reproducer(d, backend, mode, err))
        all_rows += rows
    a.csv.parent.mkdir(parents=True, exist_ok=True)
    with a.csv.open("w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=COLUMNS)
        w.writeheader()
        for r in all_rows:
            w.writerow({k: (repr(float(v)) if isinstance(v, float) else v) for k, v in r.items()})
    print(f"\nwrote {a.csv}")


if __name__ == "__main__":
    main()
