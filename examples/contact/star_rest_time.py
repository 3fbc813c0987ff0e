"""Monte-Carlo: when does the restituting star (e = 0.8, star_settles.py) come to rest? 10^4 drops on Dask.

Each run drops the four-point star (eq. 81) from a random state: height y0 in [1, 3.5], angle in
[0, pi/2), velocities vx, vy in [-2, 2] and omega in [-6, 6] (seeded). It bounces, loses energy
at each restituting impact, lands plastically on one vertex, rocks, lands on the next vertex and
rests on a face (MATH.md, *Sustained contact*). The runs go through ``vcigen.sweep`` (a local
Dask cluster, or ``--scheduler ADDRESS``); on each worker ``rest_time`` reduces a run to a few
numbers, so no trajectory travels back:

- at rest: the contact held at the end, the vertical and rotational kinetic energy below 1e-9
  of the start's; the rest time is then the last event (impact or lift-off);
- the check: at rest the discrete energy must be m vx^2/2 + m g L/2 (the floor is frictionless,
  so p_x is conserved, and the centre sits L/2 above the floor) -- printed as the largest deviation.

Writes ``<out>/star_rest_time.csv`` (one row per run) and ``star_rest_time.png`` (histograms of
the rest time and of the number of impacts). ``--n 40 --t-end 20`` is the fast setting a test runs.
"""

from __future__ import annotations

import argparse
import csv
import math
import time
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402 - after the backend is chosen
import numpy as np  # noqa: E402
from star_settles import INERTIA, E, G, L, M, model  # noqa: E402 - the folder is on sys.path

import vcigen  # noqa: E402

REST_KE = 1e-9  # vertical + rotational kinetic energy at the end, relative to the start's: at rest
START = ["y0", "theta0", "vx", "vy", "omega"]
COLUMNS = [*START, "settled", "rest_time", "impacts", "plastic", "rest_energy_dev"]


def starts(n: int, seed: int) -> np.ndarray:
    """``(n, 5)``: y0, theta0, vx, vy, omega, uniform in the ranges of the docstring."""
    rng = np.random.default_rng(seed)
    lo = np.array([1.0, 0.0, -2.0, -2.0, -6.0])
    hi = np.array([3.5, math.pi / 2, 2.0, 2.0, 6.0])
    return lo + (hi - lo) * rng.random((n, 5))


def run_of(start: np.ndarray, h: float, t_end: float) -> dict:
    """The ``simulate`` keywords of one drop."""
    y0, th0, vx, vy, om = start.tolist()
    return {"q0": [0.0, y0, th0], "v0": [vx, vy, om], "h": h, "t_end": t_end}


def rest_time(res: vcigen.Result) -> tuple[bool, float, int, int, float]:
    """On the worker: (settled, rest time, impacts, plastic impacts, E_d at rest - m vx^2/2 - m g L/2)."""
    ke = res.p[:, 1] ** 2 / (2 * M) + res.p[:, 2] ** 2 / (2 * INERTIA)
    settled = bool(res.active[-1].all()) and ke[-1] <= REST_KE * max(ke[0], 1.0)
    events = [im.t for im in res.impacts] + [t for t, _ in res.liftoffs]
    plastic = sum(im.kind == "plastic" for im in res.impacts)
    vx = res.p[0, 0] / M
    dev = float(res.energy[-1] - (M * vx**2 / 2 + M * G * L / 2)) if settled else math.nan
    return settled, (max(events) if settled and events else math.nan), res.n_impacts, plastic, dev


def study(n: int, h: float, t_end: float, seed: int, client, workers: int | None) -> tuple[np.ndarray, list]:
    x = starts(n, seed)
    begin = time.perf_counter()
    runs = [run_of(s, h, t_end) for s in x]
    values = vcigen.sweep(model(), runs, backend="c", client=client, reduce=rest_time, workers=workers)
    wall = time.perf_counter() - begin
    print(f"sweep: {n} runs of {t_end / h:.0f} steps in {wall:.1f} s ({1e3 * wall / n:.2f} ms per run)")
    return x, values


def write_csv(path: Path, x: np.ndarray, values: list) -> None:
    with path.open("w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(COLUMNS)
        for start, (settled, t_rest, impacts, plastic, dev) in zip(x, values):
            w.writerow([*map(repr, start.tolist()), int(settled), repr(t_rest), impacts, plastic, repr(dev)])


def report(values: list, t_end: float) -> None:
    settled = [v for v in values if v[0]]
    t_rest = np.array([v[1] for v in settled])
    impacts = np.array([v[2] for v in values])
    print(f"at rest by t = {t_end:g}: {len(settled)} of {len(values)} runs")
    if settled:
        q = np.percentile(t_rest, [5, 50, 95])
        print(
            f"rest time: mean {t_rest.mean():.3f}, median {q[1]:.3f}, 5%..95% {q[0]:.3f}..{q[2]:.3f}, "
            f"max {t_rest.max():.3f}"
        )
        dev = max(abs(v[4]) for v in settled)
        print(f"E_d at rest vs m vx^2/2 + m g L/2: max |dev| {dev:.1e} over the runs at rest")
    print(f"impacts per run: mean {impacts.mean():.1f}, max {impacts.max()}")


def plot(path: Path, values: list, t_end: float, h: float) -> None:
    settled = [v for v in values if v[0]]
    fig, (a, b) = plt.subplots(1, 2, figsize=(11, 4), dpi=110)
    if settled:
        a.hist([v[1] for v in settled], bins=60, color="C0")
    a.set_xlabel("rest time t")
    a.set_ylabel("runs")
    at_rest = f"{len(settled)} of {len(values)} at rest by t = {t_end:g}"
    a.set_title(f"star, e = {E}: rest time ({at_rest})", size=9)
    counts = [v[2] for v in values]
    b.hist(counts, bins=np.arange(min(counts), max(counts) + 2) - 0.5, color="C2")
    b.set_xlabel("impacts per run")
    b.set_title(f"{len(values)} random drops, h = {h}", fontsize=9)
    fig.tight_layout()
    fig.savefig(path)
    plt.close(fig)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--n", type=int, default=10_000, help="number of random drops (default 10000)")
    ap.add_argument("--h", type=float, default=0.005)
    ap.add_argument("--t-end", type=float, default=30.0)
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--workers", type=int, default=None, help="local cluster size (default: one per core)")
    ap.add_argument("--scheduler", default=None, help="a Dask scheduler address instead of a local cluster")
    ap.add_argument("--out", default="results", help="folder for the CSV and the PNG")
    args = ap.parse_args(argv)
    x, values = study(args.n, args.h, args.t_end, args.seed, args.scheduler, args.workers)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    write_csv(out / "star_rest_time.csv", x, values)
    report(values, args.t_end)
    plot(out / "star_rest_time.png", values, args.t_end, args.h)
    print(f"wrote {out / 'star_rest_time.csv'}, star_rest_time.png")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
