"""Do the two backends keep the same books of a rough cube drop? ``bench.cube_drops``' random rough drops
run on C and on CasADi, compared field by field.

    .venv/bin/python -m bench.cube_books [--drops 200] [--seed 7] [--tangent]

The trajectories agree to round-off (``q`` to ~1e-13) where no decision at an instant goes two ways; the books
(impacts and their kinds, lift-offs, the rows held each step, ``res.stats``' counts of passes, kept sticks,
jams, landing friction left out) hold every decision. Printed: how many drops differ in each, split into
those that stayed on their lower face and those that tipped onto another (where the model, its lower four
vertices only, no longer holds), and the largest ``|q_C - q_CasADi|`` of each group. About 1 s a drop
(CasADi's). ``--tangent``: the runs with ``sensitivities=True``, their ``sensitivity_breaks`` in the books
too.
"""

from __future__ import annotations

import argparse
import time
import warnings
from collections import Counter

import numpy as np

import vcigen
from bench.cube_drops import TIPPED, cube_settles, scene

STATS = ("loads_passed", "sticks_kept", "jams", "landing_friction_dropped", "jump_fallbacks")


def books(res: vcigen.Result) -> dict:
    """What a run decided: its impacts, lift-offs, held rows per step and counts."""
    return {
        "impacts": [(i.contact, i.kind, i.step) for i in res.impacts],
        "lift-offs": [j for _, j in res.liftoffs],
        "held rows": res.active.tobytes(),
        "tangent breaks": res.sensitivity_breaks,
        **{key: res.stats.get(key) for key in STATS},
    }


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--drops", type=int, default=200)
    ap.add_argument("--seed", type=int, default=7)
    ap.add_argument("--tangent", action="store_true", help="with sensitivities=True")
    a = ap.parse_args(argv)
    warnings.simplefilter("ignore", RuntimeWarning)  # the landings' left-out friction: counted instead
    sims = [vcigen.build(cube_settles.model(mu=0.5), backend=b) for b in ("c", "casadi")]
    rng = np.random.default_rng(a.seed)
    differ = {False: Counter(), True: Counter()}
    runs, dq = Counter(), {False: 0.0, True: 0.0}
    start = time.perf_counter()
    for _ in range(a.drops):
        q0, v0, params = scene(rng, True)
        out = []
        for sim in sims:
            try:
                res = sim.simulate(q0=q0, v0=v0, h=0.005, t_end=3.0, params=params, sensitivities=a.tangent)
                out.append((res, ""))
            except vcigen.SolverError as err:
                out.append((err.result, err.reason.split(";")[0]))
        (c, c_err), (py, py_err) = out
        tipped = bool(max(np.abs(r.q[:, 4:6]).max() for r in (c, py)) > TIPPED)
        runs[tipped] += 1
        n = min(len(c.q), len(py.q))
        dq[tipped] = max(dq[tipped], float(np.abs(c.q[:n] - py.q[:n]).max()))
        bc, bp = books(c), books(py)
        keys = [key for key in bc if bc[key] != bp[key]] + (["error"] if c_err != py_err else [])
        differ[tipped].update(keys)
        differ[tipped]["any"] += bool(keys)
    with_tangent = ", with the tangent" if a.tangent else ""
    spent = time.perf_counter() - start
    print(f"{a.drops} rough drops (seed {a.seed}{with_tangent}), C against CasADi ({spent:.0f} s)")
    for tipped, name in ((False, "on their lower face"), (True, "tipped onto another face")):
        counts = ", ".join(f"{key} {count}" for key, count in sorted(differ[tipped].items()) if key != "any")
        print(
            f"  {name}: {runs[tipped]} drops, books differ in {differ[tipped]['any']} ({counts or 'none'}); "
            f"largest |dq| {dq[tipped]:.1e}"
        )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
