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
    write_run(name, res, args.out, args.backend, args.rule, run["h"], note)
    return res


def write_run(
    name: str, res: Result, out: str | Path, backend: str, rule: str, h: float, note: str = ""
) -> list[Path]:
    """``<out>/<name>_<backend>_<rule>.csv``, ``..._impacts.csv``, ``..._energy.png``; print the summary."""
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    stem = f"{name}_{backend}_{rule}"
    paths = [out / f"{stem}.csv", out / f"{stem}_impacts.csv", out / f"{stem}_energy.png"]
    res.to_csv(paths[0])
    res.impacts_to_csv(paths[1])
    plot_energy(
        res,
        paths[2],
        title=f"{name} ({backend}, {rule}, h = {h}): "
        f"{res.n_impacts} impacts, max |dE|/E = {res.max_energy_deviation():.2e}",
    )
    print(summary(f"{name} [{backend}, {rule}]", res) + (f" -- {note}" if note else ""))
    print(f"  wrote {paths[0]}, {paths[1].name}, {paths[2].name}")
    return paths
