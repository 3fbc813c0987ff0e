"""Run an example scene: simulate, write CSV and an energy plot, print a summary."""

from __future__ import annotations

import argparse
from collections.abc import Callable, Mapping
from pathlib import Path

from .analysis import plot_energy, summary
from .model import Model
from .result import Result
from .simulator import build


def run_example(
    name: str, model: Callable[[], Model], setup: Mapping, argv: list[str] | None = None, note: str = ""
) -> Result:
    """Command-line entry of an example: ``--backend``, ``--rule``, ``--out``, ``--n-impacts``."""
    ap = argparse.ArgumentParser(description=f"vcigen example: {name}")
    ap.add_argument("--backend", default="casadi", choices=["casadi", "c"])
    ap.add_argument("--rule", default="trapezoid", choices=["trapezoid", "midpoint"])
    ap.add_argument("--out", default="results", help="folder for the CSV files and the PNG plot")
    ap.add_argument("--n-impacts", type=int, default=None, help="override the number of impacts")
    args = ap.parse_args(argv)
    run = dict(setup)
    if args.n_impacts is not None:
        run["n_impacts"] = args.n_impacts
    sim = build(model(), backend=args.backend, rule=args.rule)
    res = sim.simulate(**run, progress=True)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    stem = f"{name}_{args.backend}_{args.rule}"
    res.to_csv(out / f"{stem}.csv")
    res.impacts_to_csv(out / f"{stem}_impacts.csv")
    plot_energy(
        res,
        out / f"{stem}_energy.png",
        title=f"{name} ({args.backend}, {args.rule}, h = {run['h']}): "
        f"{res.n_impacts} impacts, max |dE|/E = {res.max_energy_deviation():.2e}",
    )
    print(summary(f"{name} [{args.backend}, {args.rule}]", res) + (f" -- {note}" if note else ""))
    print(f"  wrote {out / stem}.csv, {stem}_impacts.csv, {stem}_energy.png")
    return res
