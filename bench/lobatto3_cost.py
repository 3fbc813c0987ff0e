"""lobatto3 against trapezoid in generated C: cost per step and wall time at matched error (issue 12).

Per step also lobatto3 with the stage's closed-form elimination switched off (vcigen.stage), same run.
Error after the first collision (the scenes' t_end) against DOP853 with event location
(``bench.reference.event_driven``, rtol 1e-13), averaged over four start phases; wall time of a run
best of five. Run: ``python -m bench.lobatto3_cost`` (prints a table; nothing is written).
"""

from __future__ import annotations

import dataclasses
import time

import numpy as np

import vcigen
from bench import scenes as bench_scenes
from bench.reference import event_driven
from vcigen.backends import registry

SETS = {
    # scene: (t_end, start shifts of q0, step sizes)
    "star_nonlinear": (1.5, [np.array([0.0, d, 0.0]) for d in (0.0, 0.0031, 0.0063, 0.0094)]),
    "pendulum_wall": (0.5, [np.array([d, 0.0]) for d in (0.0, 0.005, 0.01, 0.015)]),
}
HS = [0.04, 0.02, 0.01, 0.005, 0.0025, 0.00125]
LONG = {"star_nonlinear": 200.0, "pendulum_wall": 50.0}  # long runs for the cost per step


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


def at_error(rows, target: float) -> tuple[float, str]:
    """Wall time at error ``target``: log-log interpolation between the bracketing runs, or below the
    smallest error an extrapolation along the last two runs' error order at the last run's cost per step
    (marked)."""
    for (_, e0, w0, _), (_, e1, w1, _) in zip(rows, rows[1:]):
        if e1 <= target <= e0 and e1 < e0:
            f = np.log(target / e0) / np.log(e1 / e0)
            return float(np.exp(np.log(w0) + f * (np.log(w1) - np.log(w0)))), ""
    (h0, e0, _, _), (h1, e1, w1, _) = rows[-2], rows[-1]
    if target < e1:
        order = np.log(e0 / e1) / np.log(h0 / h1)
        h = h1 * (target / e1) ** (1 / order)
        return float(w1 * h1 / h), f" (extrapolated, order {order:.2f})"
    return float("nan"), ""


def per_step(name: str, rule: str, h: float, t_end: float, general: bool = False) -> float:
    """Wall time per step of one long run (best of five): the cost without the per-call overhead.

    ``general``: with the stage's closed-form elimination switched off (``Structure.stage_reduced``,
    vcigen.stage), the general ``(x, u)`` Newton of every phase, for the before/after in one run."""
    scene = bench_scenes.get(name)
    system = vcigen.derive(scene.model_factory(), rule)
    if general:
        off = dataclasses.replace(system.structure, stage_reduced=False, stage_linear=False)
        system.__dict__["structure"] = off  # DiscreteSystem.structure is a cached_property
    sim = registry.factory("c")(system, tol=vcigen.Tolerances())
    return best_time(sim, {"q0": scene.q0, "v0": scene.v0, "h": h, "t_end": t_end}) / round(t_end / h)


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
        costs = {rule: per_step(name, rule, 0.005, LONG[name]) for rule in out}
        ct, cl = costs["trapezoid"], costs["lobatto3"]
        cg = per_step(name, "lobatto3", 0.005, LONG[name], general=True)
        steps = round(LONG[name] / 0.005)
        print(
            f"per step (h 0.005, {steps} steps): trapezoid {ct:.3e} s, lobatto3 {cl:.3e}, ratio "
            f"{cl / ct:.2f}; lobatto3 without the stage's elimination {cg:.3e}, ratio {cg / ct:.2f}"
        )
        for target in (1e-4, 1e-6, 1e-8):
            (wt, nt), (wl, nl) = at_error(out["trapezoid"], target), at_error(out["lobatto3"], target)
            ratio = wt / wl
            print(
                f"at error {target:g}: trapezoid {wt:.3e} s{nt}, lobatto3 {wl:.3e} s{nl}, ratio {ratio:.3g}"
            )


if __name__ == "__main__":
    main()
