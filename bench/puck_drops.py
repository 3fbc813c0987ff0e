"""Random drops of three pucks on a rough floor (isotropic cones), both backends: the impulse law with several
cones slipping at once (stop 32; before, "impulse law: 2 isotropic cones slipping at once" ended most runs).

    .venv/bin/python -m bench.puck_drops [--drops 200] [--seed 1] [--backends c casadi]

Each drop: three unit point masses at random ``(x, y)`` in [-1, 1], each on the floor (40 %) or up to 0.1
above it, sliding at up to 2 along the floor (a lifted one also moving up to 1 vertically), ``mu`` in [0.05,
1], ``e`` 0 in half the drops (else in [0, 0.9]), to t = 1 at h = 0.005; a quarter with the tangent. Printed
per backend: the runs that end in a ``SolverError`` (by message), the largest rise of the energy ``|v|^2/2 +
g sum z`` between grid points (friction and plastic landings only take energy), the lowest puck, the runs
whose tangent broke (by reason), the wall time; CasADi's drops are C's first ones, and C against them (the
largest difference of ``q`` over every step).
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


def model(n: int = 3) -> vcigen.Model:
    """``n`` unit point masses over the floor ``z = 0``, each with its own isotropic cone (``mu``) and
    restitution ``e``."""
    q = sp.symbols(" ".join(f"x{i} y{i} z{i}" for i in range(n)))
    qd = sp.symbols(" ".join(f"x{i}d y{i}d z{i}d" for i in range(n)))
    mu, e = sp.symbols("mu e")
    return vcigen.Model(
        name="puck_drops",
        q=list(q),
        qdot=list(qd),
        lagrangian=sum(v**2 for v in qd) / 2 - G * sum(q[3 * i + 2] for i in range(n)),
        contacts={f"f{i}": q[3 * i + 2] for i in range(n)},
        params={mu: 0.3, e: 0.0},
        restitution={f"f{i}": e for i in range(n)},
        friction={f"f{i}": (mu, q[3 * i : 3 * i + 2]) for i in range(n)},
    )


def scene(rng: np.random.Generator, n: int = 3) -> tuple[np.ndarray, np.ndarray, dict]:
    """One random drop: ``(q0, v0, params)``."""
    q0, v0 = np.zeros(3 * n), np.zeros(3 * n)
    for i in range(n):
        q0[3 * i : 3 * i + 2] = rng.uniform(-1, 1, 2)
        q0[3 * i + 2] = 0.0 if rng.uniform() < 0.4 else rng.uniform(0, 0.1)
        v0[3 * i : 3 * i + 2] = rng.uniform(-2, 2, 2)
        v0[3 * i + 2] = 0.0 if q0[3 * i + 2] == 0.0 else rng.uniform(-1, 1)
    mu = float(rng.uniform(0.05, 1.0))
    return q0, v0, {"mu": mu, "e": float(rng.choice([0.0, rng.uniform(0, 0.9)]))}


def energy_rise(res: vcigen.Result) -> float:
    """The largest rise of ``|v|^2/2 + g sum z`` between grid points."""
    e = 0.5 * np.sum(res.v**2, axis=1) + G * np.sum(res.q[:, 2::3], axis=1)
    return float(np.max(np.diff(e), initial=0.0))


def drops(sim: vcigen.Simulator, n: int, seed: int) -> dict:
    """``n`` random drops (:func:`scene`): ``{"runs": [q or None], "errors": Counter, "rise", "low", "breaks":
    Counter, "wall"}``."""
    rng = np.random.default_rng(seed)
    out = {"runs": [], "errors": Counter(), "rise": 0.0, "low": 0.0, "breaks": Counter()}
    start = time.perf_counter()
    for d in range(n):
        q0, v0, params = scene(rng)
        try:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")  # a warning is not what is counted here
                res = sim.simulate(
                    q0, v0, h=0.005, t_end=1.0, params=params, sensitivities=d % 4 == 0, progress=False
                )
        except vcigen.SolverError as exc:
            out["errors"][str(exc).split(";")[-1].strip()[:70]] += 1
            out["runs"].append(None)
            continue
        out["runs"].append(res.q)
        out["rise"] = max(out["rise"], energy_rise(res))
        out["low"] = min(out["low"], float(res.q[:, 2::3].min()))
        out["breaks"].update({why for _, why in res.sensitivity_breaks})
    out["wall"] = time.perf_counter() - start
    return out


def report(out: dict) -> str:
    """:func:`drops`' figures as lines."""
    n, errors = len(out["runs"]), out["errors"]
    return "\n".join(
        [
            f"  SolverError: {sum(errors.values())} of {n}"
            + "".join(f"\n    {c} x {m}" for m, c in errors.items()),
            f"  largest energy rise between grid points: {out['rise']:.1e}; lowest puck: {out['low']:.1e}",
            f"  tangent breaks (runs with the tangent, by reason): {dict(out['breaks']) or 'none'}",
            f"  wall time: {out['wall']:.1f} s ({out['wall'] / n * 1e3:.0f} ms a drop)",
        ]
    )


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--drops", type=int, default=200)
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--backends", nargs="+", default=["c", "casadi"])
    args = ap.parse_args(argv)
    runs = {}
    for backend in args.backends:
        n = args.drops if backend == "c" else max(1, args.drops // 5)
        sim = vcigen.build(model(), backend=backend)
        out = drops(sim, n, args.seed)
        runs[backend] = out["runs"]
        print(f"{backend}: {n} drops of three pucks on a rough floor (seed {args.seed})\n{report(out)}")
    if {"c", "casadi"} <= set(runs):
        pairs = [(a, b) for a, b in zip(runs["c"], runs["casadi"]) if a is not None and b is not None]
        worst = max((float(np.abs(a - b).max()) for a, b in pairs if a.shape == b.shape), default=0.0)
        shapes = sum(a.shape != b.shape for a, b in pairs)
        print(f"C against CasADi on {len(pairs)} drops: max |q| difference {worst:.1e}", end="")
        print(f" ({shapes} of another length)")


if __name__ == "__main__":
    main()
