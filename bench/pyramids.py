"""Random pyramids of three disks on both backends: errors, disagreements and the lowest gap.

    .venv/bin/python -m bench.pyramids [--draws 600] [--seed 2] [--t-end 3]

``examples/contact/pyramid.py``'s model (three unit disks of radius 0.5, each pair a contact, each disk the
floor; ``e`` and ``mu`` parameters). Each draw: ``e`` 0, 1 or uniform in [0, 1]; ``mu`` 0 or uniform in
[0, 1.5]; ``h`` 0.001, 0.01 or 0.05; the lower disks 0 or up to 0.3 apart; the top 0 or up to 0.3 above its
contact with the nearer one and 0 or up to 0.3 to the side; half the draws at rest, half with velocities of
spread 0.5 (none vertical for the lower disks). Both backends run each draw to ``--t-end``. Printed: each
draw that ends in an error, goes below a row by more than 1e-9, or whose backends end more than 1e-6 apart or
with other impact counts; the draw's first divergence (the first grid point where the backends are 1e-12,
1e-9 and 1e-6 apart: a growth by orders over hundreds of steps is round-off amplified by near-elastic
bounces, a jump is a decision taken differently); then the tallies and the ``riders_cut`` count
(``res.stats``).
"""

from __future__ import annotations

import argparse
import sys
import warnings
from pathlib import Path

import numpy as np

import vcigen
from bench.random_runs import how_apart, parted

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "examples" / "contact"))
import pyramid  # noqa: E402 - examples/contact/pyramid.py: the model, R, gaps

R = pyramid.R


def draw(rng: np.random.Generator) -> dict:
    e = float(rng.choice([0.0, 1.0, rng.uniform()]))
    mu = float(rng.choice([0.0, rng.uniform(0, 1.5)]))
    h = float(rng.choice([0.001, 0.01, 0.05]))
    gap = float(rng.choice([0.0, rng.uniform(0, 0.3)]))
    drop = float(rng.choice([0.0, rng.uniform(0, 0.3)]))
    off = float(rng.choice([0.0, rng.uniform(-0.3, 0.3)]))
    d = R + gap / 2
    near = min(abs(off - d), abs(off + d))
    q0 = [-d, R, d, R, off, R + float(np.sqrt(max(4 * R * R - near**2, 0.0))) + drop]
    v0 = rng.normal(0, 0.5, 6) * rng.choice([0, 1])
    v0[1] = v0[3] = 0.0
    return {"q0": q0, "v0": [float(x) for x in v0], "h": h, "params": {"e": e, "mu": mu}}


def divergence(a: vcigen.Result, b: vcigen.Result) -> list[float | None]:
    n = min(a.t.size, b.t.size)
    apart = np.abs(a.q[:n] - b.q[:n]).max(axis=1)
    return [float(a.t[np.argmax(apart > th)]) if (apart > th).any() else None for th in (1e-12, 1e-9, 1e-6)]


def fuzz(model: vcigen.Model, draw, gap, t_end: float, draws: int, seed: int, outside=None) -> dict:
    """``draws`` runs of ``model`` from ``draw(rng)`` (seed ``seed``) on both backends to ``t_end``: each draw
    that ends in an error, goes below a row by more than 1e-9 (``gap(q)``: the lowest row over the run),
    ``outside(results)`` (out of the model) or whose backends end apart is printed; returns the tallies
    (``errors``, ``below``, ``cuts`` per backend; ``outside``, ``apart``)."""
    warnings.simplefilter("ignore")  # the counted warnings (friction kept sticking, ...) are in res.stats
    sims = {b: vcigen.build(model, backend=b) for b in ("c", "casadi")}
    rng = np.random.default_rng(seed)
    tally: dict = {key: dict.fromkeys(sims, 0) for key in ("errors", "below", "cuts")}
    tally |= {"outside": 0, "apart": 0, "parted": 0}
    for k in range(draws):
        d = draw(rng)
        res, why = {}, []
        for b, sim in sims.items():
            try:
                res[b] = sim.simulate(**d, t_end=t_end, progress=False)
            except vcigen.SolverError as err:
                res[b] = err.result
                tally["errors"][b] += 1
                why.append(f"{b}: {err}")
            low = gap(res[b].q)
            if low < -1e-9:
                tally["below"][b] += 1
                why.append(f"{b}: a gap of {low:.2e}")
            tally["cuts"][b] += int(res[b].stats.get("riders_cut", 0))
        if outside is not None and outside(res):
            tally["outside"] += 1
            why.append("out of the model")
        c, k_ = res["c"], res["casadi"]
        dq = float(np.abs(c.q[-1] - k_.q[-1]).max()) if c.t.size == k_.t.size else float("inf")
        if dq > 1e-6 or len(c.impacts) != len(k_.impacts):
            tally["apart"] += 1
            where = parted(c, k_)
            tally["parted"] += where is not None
            why.append(f"apart by {dq:.2e}, impacts {len(c.impacts)} / {len(k_.impacts)}; {how_apart(where)}")
            why.append("first apart by 1e-12, 1e-9, 1e-6 at t = " + str(divergence(c, k_)))
        if why:
            print(f"draw {k} {d}:\n  " + "\n  ".join(why), flush=True)
    return tally


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--draws", type=int, default=600)
    ap.add_argument("--seed", type=int, default=2)
    ap.add_argument("--t-end", type=float, default=3.0)
    a = ap.parse_args()
    t = fuzz(pyramid.model(), draw, lambda q: float(pyramid.gaps(q).min()), a.t_end, a.draws, a.seed)
    errors, below, cuts = t["errors"], t["below"], t["cuts"]
    print(
        f"{a.draws} draws (seed {a.seed}): errors C {errors['c']}, CasADi {errors['casadi']}; below a row by "
        f"more than 1e-9: C {below['c']}, CasADi {below['casadi']}; backends apart: {t['apart']} "
        f"(parted in one step: {t['parted']}); riders cut: C {cuts['c']}, CasADi {cuts['casadi']}"
    )


if __name__ == "__main__":
    main()
