"""Random drops of a particle into a rough V-groove, walls ``y = s |x|``: where it comes to rest, checked
against the closed forms, on both backends.

    .venv/bin/python -m bench.groove_drops [--drops 200] [--seed 1] [--backends c casadi]

Each drop: slope ``s`` in [0.2, 3], ``e`` 0 in half the drops (else in [0, 1]), ``mu`` in [0, 1.5], from a
random point up to 1 above the walls at a speed up to 2 per axis, to t = 4 at h = 0.01. Printed per backend:
the runs that end in a ``SolverError`` (by message), where the others end (at rest at the vertex, at rest on
one wall, moving), the runs at rest whose contact force is not the closed form (at the vertex ``m g / 2`` on
each wall; on one wall, which needs ``mu >= s``, ``m g / (1 + s^2)``), the lowest gap, the largest rise of
``E_d`` above its start (the discrete energy swings by ``g^2 h^2 / 8`` in flight) and the wall time; CasADi's
drops are C's first ones, and C against them (the same impacts, the largest difference of ``q``).

Till stop 46 a stick row held on one wall stayed held when the particle met the other wall at the vertex, in
the span of that wall's normal row and its own: 133 of C's 200 drops (seed 1) ended in a ``SolverError``.
"""

from __future__ import annotations

import argparse
import time
import warnings
from collections import Counter

import numpy as np
import sympy as sp

import vcigen

G = 9.81
H = 0.01
T_END = 4.0


def model() -> vcigen.Model:
    """The unit particle between the walls ``y = -s x`` (left) and ``y = s x`` (right), each rough (``mu``,
    unit tangents: the sliding velocity along it) with restitution ``e``."""
    x, y, xd, yd = sp.symbols("x y xd yd")
    s, e, mu = sp.symbols("s e mu", positive=True)
    n = sp.sqrt(1 + s**2)
    return vcigen.Model(
        name="groove",
        q=[x, y],
        qdot=[xd, yd],
        lagrangian=(xd**2 + yd**2) / 2 - G * y,
        contacts={"left": y + s * x, "right": y - s * x},
        restitution={"left": e, "right": e},
        friction={"left": (mu, (x - s * y) / n), "right": (mu, (x + s * y) / n)},
        params={s: 1.0, e: 0.5, mu: 0.4},
    )


def draw(rng: np.random.Generator) -> tuple[dict, list[float], list[float]]:
    """A random drop: ``(params, q0, v0)``."""
    slope = float(rng.uniform(0.2, 3.0))
    params = {
        "s": slope,
        "e": float(rng.choice([0.0, rng.uniform(0.0, 1.0)])),
        "mu": float(rng.uniform(0.0, 1.5)),
    }
    x0 = float(rng.uniform(-0.5, 0.5))
    q0 = [x0, abs(x0) * slope + float(rng.uniform(0.01, 1.0))]
    return params, q0, [float(v) for v in rng.uniform(-2.0, 2.0, 2)]


def gaps(res: vcigen.Result, slope: float) -> np.ndarray:
    """``(N, 2)``: each wall's gap at every grid point."""
    return np.stack([res.q[:, 1] + slope * res.q[:, 0], res.q[:, 1] - slope * res.q[:, 0]], axis=1)


def end(res: vcigen.Result, params: dict) -> tuple[str, bool]:
    """Where a run ends (``"vertex"``, ``"wall"``: at rest; ``"moving"``) and whether its contact force there
    is the closed form (a rest on one wall with ``mu < s`` is not)."""
    if np.abs(res.p[-1]).max() > 1e-9:
        return "moving", True
    force = res.contact_force[-1]
    if res.active[-1].all():
        return "vertex", bool(np.allclose(force, G / 2, rtol=1e-9, atol=0.0))
    wall = G / (1 + params["s"] ** 2)
    held = res.active[-1].sum() == 1 and params["mu"] >= params["s"]
    return "wall", bool(held and abs(force.sum() - wall) <= 1e-9 * wall)


def campaign(sim: vcigen.Simulator, drops: list) -> tuple[Counter, list, dict]:
    """Runs ``drops``: ``(counts, results, extremes)``, a result None where it raised."""
    counts, results = Counter(), []
    low, rise = np.inf, -np.inf
    for params, q0, v0 in drops:
        try:
            res = sim.simulate(q0=q0, v0=v0, h=H, t_end=T_END, params=params)
        except vcigen.SolverError as err:
            counts["SolverError: " + str(err).split(": ", 1)[1].split(";")[0]] += 1
            results.append(None)
            continue
        where, exact = end(res, params)
        counts[where] += 1
        counts["force not the closed form"] += not exact
        low = min(low, float(gaps(res, params["s"]).min()))
        rise = max(rise, float(res.energy.max() - res.energy[0]))
        results.append(res)
    return counts, results, {"lowest gap": low, "E_d rise": rise}


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--drops", type=int, default=200)
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--backends", nargs="+", default=["c", "casadi"], choices=["c", "casadi"])
    a = ap.parse_args(argv)
    warnings.simplefilter("ignore", RuntimeWarning)  # landings at the vertex: friction left out, counted
    rng = np.random.default_rng(a.seed)
    drops = [draw(rng) for _ in range(a.drops)]
    out = {}
    for backend in a.backends:
        sim = vcigen.build(model(), backend=backend)
        n = a.drops if backend == "c" else max(1, a.drops // 5)
        start = time.perf_counter()
        counts, results, ext = campaign(sim, drops[:n])
        out[backend] = results
        print(f"[{backend}] {n} drops (seed {a.seed}), {time.perf_counter() - start:.1f} s")
        for key, value in sorted(counts.items()):
            print(f"  {key}: {value}")
        print(
            f"  lowest gap {ext['lowest gap']:.1e}; E_d above its start at most {ext['E_d rise']:.2e}"
            f" (g^2 h^2 / 8 = {G**2 * H**2 / 8:.2e})"
        )
    if len(out) == 2:
        pairs = [(a_, b_) for a_, b_ in zip(out["c"], out["casadi"]) if a_ is not None and b_ is not None]
        apart = sum(
            [(i.contact, i.kind, i.step) for i in x.impacts]
            != [(i.contact, i.kind, i.step) for i in y.impacts]
            for x, y in pairs
        )
        dq = max((float(np.abs(x.q - y.q).max()) for x, y in pairs), default=0.0)
        print(f"C against CasADi on {len(pairs)} drops: impacts apart in {apart}; largest q apart {dq:.1e}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
