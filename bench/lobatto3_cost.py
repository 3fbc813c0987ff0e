"""lobatto3 against trapezoid in generated C: cost per step and wall time at matched error (issue 12).

Error after the first collision (the scenes' t_end) against DOP853 with event location
(``bench.reference.event_driven``, rtol 1e-13), averaged over four start phases; wall time of a run
best of five. Run: ``python -m bench.lobatto3_cost`` (prints a table; nothing is written).
"""

from __future__ import annotations

import time

import numpy as np

import vcigen
from bench import scenes as bench_scenes
from bench.reference import event_driven

SETS = {
    # scene: (t_end, start shifts of q0, step sizes)
    "star_nonlinear": (1.5, [np.array([0.0, d, 0.0]) for d in (0.0, 0.0031, 0.0063, 0.0094)]),
    "pendulum_wall": (0.5, [np.array([d, 0.0]) for d in (0.0, 0.005, 0.01, 0.015)]),
}
HS = [0.04, 0.02, 0.01, 0.005, 0.0025, 0.00125]


def best_time(sim, kw, repeats: int = 5) -> float:
    best = np.inf
    for _ in range(repeats):
        t0 = time.perf_counter()
        sim.simulate(**kw)
        best = min(best, time.perf_counter() - t0)
    return best


def sweep(name: str, rule: str, refs, t_end: float):
    scene = bench_scenes.get(name)
    sim = vcigen.build(scene.model_factory(), backend="c", rule=rule)
    rows = []
    for h in HS:
        errs, wall = [], 0.0
        for (q0, v0), ref in refs:
            kw = {"q0": q0, "v0": v0, "h": h, "t_end": t_end}
            res = sim.simulate(**kw)
            errs.append(np.abs(res.q[-1] - ref.q[-1]).max())
            wall += best_time(sim, kw) / len(refs)
        rows.append((h, float(np.mean(errs)), wall, wall / round(t_end / h)))
    return rows


def at_error(rows, target: float) -> float:
    """Wall time at error ``target`` (log-log interpolation between the bracketing runs; nan outside)."""
    for (_, e0, w0, _), (_, e1, w1, _) in zip(rows, rows[1:]):
        if e1 <= target <= e0 and e1 < e0:
            f = np.log(target / e0) / np.log(e1 / e0)
            return float(np.exp(np.log(w0) + f * (np.log(w1) - np.log(w0))))
    return float("nan")


def main() -> None:
    for name, (t_end, shifts) in SETS.items():
        scene = bench_scenes.get(name)
        refs = []
        for d in shifts:
            q0, v0 = scene.q0 + d, scene.v0
            refs.append(((q0, v0), event_driven(scene, np.array([0.0, t_end]), q0=q0, v0=v0, max_step=0.005)))
        out = {rule: sweep(name, rule, refs, t_end) for rule in ("trapezoid", "lobatto3")}
        print(f"\n{name} (t_end {t_end}, impacts in reference: {len(refs[0][1].impacts)})")
        print("rule       h        mean error   wall [s]   per step [s]")
        for rule, rows in out.items():
            for h, e, w, ps in rows:
                print(f"{rule:10s} {h:<8g} {e:11.3e} {w:10.3e} {ps:10.3e}")
        ratio = [lb[3] / tr[3] for tr, lb in zip(out["trapezoid"], out["lobatto3"])]
        spread = f"{min(ratio):.2f}-{max(ratio):.2f}"
        print(f"cost per step lobatto3 / trapezoid: {np.median(ratio):.2f} (median over h; {spread})")
        for target in (1e-4, 1e-6, 1e-8):
            wt, wl = at_error(out["trapezoid"], target), at_error(out["lobatto3"], target)
            print(f"wall at error {target:g}: trapezoid {wt:.3e} s, lobatto3 {wl:.3e} s, ratio {wt / wl:.3g}")


if __name__ == "__main__":
    main()
