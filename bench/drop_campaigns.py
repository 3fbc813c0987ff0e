"""The command line of the random drop campaigns (``bench.groove_drops``, ``bench.box_v_drops``): the draws,
each backend's campaign and its counts, and C against CasADi."""

from __future__ import annotations

import argparse
import time
import warnings
from collections import Counter
from collections.abc import Callable

import numpy as np

import vcigen


def campaign(
    sim: vcigen.Simulator,
    drops: list,
    h: float,
    t_end: float,
    tally: Callable[[vcigen.Result, dict, Counter], None],
    gap: Callable[[vcigen.Result, dict], float],
) -> tuple[Counter, list, dict]:
    """Runs ``drops`` (``(params, q0, v0)`` each) to ``t_end`` at ``h``: ``(counts, results, extremes)``, a
    result None where it raised (counted by message); ``tally(res, params, counts)`` counts the others,
    ``gap(res, params)`` is a run's lowest gap."""
    counts, results = Counter(), []
    low, rise = np.inf, -np.inf
    names = {p.name for p in sim.model.defaults}
    for params, q0, v0 in drops:
        params = {k: v for k, v in params.items() if k in names}  # (--smooth: no mu)
        try:
            res = sim.simulate(q0=q0, v0=v0, h=h, t_end=t_end, params=params)
        except vcigen.SolverError as err:
            counts["SolverError: " + str(err).split(": ", 1)[1].split(";")[0]] += 1
            results.append(None)
            continue
        tally(res, params, counts)
        low = min(low, float(gap(res, params)))
        rise = max(rise, float(res.energy.max() - res.energy[0]))
        results.append(res)
    return counts, results, {"lowest gap": low, "E_d rise": rise}


def main(
    argv: list[str] | None,
    doc: str,
    model: Callable[[], vcigen.Model],
    draw: Callable[[np.random.Generator], tuple],
    campaign: Callable[[vcigen.Simulator, list], tuple],
    drops: int,
    swing: float,
    smooth: bool = False,
) -> int:
    """Parses ``--drops`` (default ``drops``), ``--seed``, ``--backends``, ``--rule`` and, where ``smooth``,
    ``--smooth`` (``model(rough=False)``: frictionless walls); runs ``campaign(sim, draws)`` (a
    result None where it raised; ``(counts, results, {"lowest gap", "E_d rise"})``) on C and on a fifth of the
    draws on CasADi, prints each backend's counts, the indices of the drops that raised and the extremes
    (``swing``: ``E_d``'s own swing in flight), and the drops whose impacts differ between the backends or
    whose ``q`` are more than 1e-6 apart."""
    ap = argparse.ArgumentParser(description=doc.splitlines()[0])
    ap.add_argument("--drops", type=int, default=drops)
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--backends", nargs="+", default=["c", "casadi"], choices=["c", "casadi"])
    ap.add_argument("--rule", default="trapezoid", choices=sorted(vcigen.RULES))
    if smooth:
        ap.add_argument("--smooth", action="store_true", help="frictionless walls (any rule)")
    a = ap.parse_args(argv)
    warnings.simplefilter("ignore", RuntimeWarning)  # friction left out, restitution reduced: counted
    rng = np.random.default_rng(a.seed)
    draws = [draw(rng) for _ in range(a.drops)]
    out = {}
    smooth_walls = getattr(a, "smooth", False)
    for backend in a.backends:
        try:
            sim = vcigen.build(model(rough=False) if smooth_walls else model(), backend=backend, rule=a.rule)
        except ValueError as exc:  # a rule without friction (lobatto3): the walls must be smooth
            ap.error(f"{exc}{'; add --smooth (frictionless walls)' if smooth and not smooth_walls else ''}")
        n = a.drops if backend == "c" else max(1, a.drops // 5)
        start = time.perf_counter()
        counts, results, ext = campaign(sim, draws[:n])
        out[backend] = results
        print(f"[{backend}, {a.rule}] {n} drops (seed {a.seed}), {time.perf_counter() - start:.1f} s")
        for key, value in sorted(counts.items()):
            print(f"  {key}: {value}")
        raised = [i for i, res in enumerate(results) if res is None]
        if raised:  # to rerun one: its draw is the i-th of the seed's generator
            print(f"  drops that raised (by index): {raised[:20]}{' ...' if len(raised) > 20 else ''}")
        print(
            f"  lowest gap {ext['lowest gap']:.1e}; E_d above its start at most {ext['E_d rise']:.2e}"
            f" (g^2 h^2 / 8 = {swing:.2e})"
        )
    if len(out) == 2:
        pairs = [(i, x, y) for i, (x, y) in enumerate(zip(out["c"], out["casadi"])) if None not in (x, y)]
        books = lambda r: [(m.contact, m.kind, m.step) for m in r.impacts]  # noqa: E731
        apart = [i for i, x, y in pairs if books(x) != books(y)]
        far = [i for i, x, y in pairs if float(np.abs(x.q - y.q).max()) > 1e-6]
        dq = max((float(np.abs(x.q - y.q).max()) for _, x, y in pairs), default=0.0)
        print(
            f"C against CasADi on {len(pairs)} drops: impacts apart in {len(apart)} {apart}; largest q apart "
            f"{dq:.1e}; more than 1e-6 apart: {far}"
        )
    return 0
