"""Figures of the core pipeline (issue 2), printed as a table: run `.venv/bin/python bench/core_figures.py`.

Fitted orders (phase-averaged), discrete Noether defects, symplectic defects of impact
steps, energy jump across impacts, and the CasADi path's cost per step.
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))

from scenes import simulator  # noqa: E402
from test_order import oscillator_exact  # noqa: E402
from test_symplectic import step_map  # noqa: E402

from vcigen.analysis import fit_order, impact_energy_jump, symplectic_defect  # noqa: E402


def order_oscillator(rule: str) -> float:
    sim, hs, errs = simulator("oscillator", rule), [0.04, 0.02, 0.01, 0.005], []
    for h in hs:
        n = round(2.0 / h)
        e = [
            abs(
                sim.simulate(q0=[np.cos(2 * t0)], v0=[-2 * np.sin(2 * t0)], h=h, t_end=n * h).q[-1, 0]
                - oscillator_exact(t0 + n * h, 1.0, 2.0, 0.5)
            )
            for t0 in np.linspace(0, h, 8, endpoint=False)
        ]
        errs.append(np.mean(e))
    return fit_order(hs, errs)


def order_star(rule: str) -> float:
    sim, hs = simulator("star_nonlinear", rule), [0.02, 0.01, 0.005, 0.0025]
    errs = np.zeros(len(hs))
    for dy in (0.0, 0.0031, 0.0063, 0.0094):
        setup = {"q0": [0.0, 3.5 + dy, 0.0], "v0": [-2.0, 0.0, 5.0], "t_end": 1.5}
        ref = sim.simulate(**setup, h=hs[0] / 128)
        for i, h in enumerate(hs):
            errs[i] += np.max(np.abs(sim.simulate(**setup, h=h).q[-1] - ref.q[-1])) / 4
    return fit_order(hs, errs)


def main() -> None:
    rows = []
    for rule in ("trapezoid", "midpoint"):
        star = simulator("star", rule).simulate(q0=[0, 3.5, 0], v0=[-2, 0, 5], h=0.005, n_impacts=100)
        bil = simulator("billiard", rule).simulate(q0=[0.2, 0], v0=[0.3, 1.5], h=0.01, n_impacts=100)
        ang = bil.q[:, 0] * bil.p[:, 1] - bil.q[:, 1] * bil.p[:, 0]
        f = step_map(simulator("billiard", rule), 0.05, [])
        z = np.array([0.0, 1.0 - 0.6 * 0.05 * 1.5 - 1e-3, 0.4, 1.5])
        fs = step_map(simulator("star_nonlinear", rule), 0.01, [])
        rows += [
            (rule, "order, oscillator vs closed form (8 phases)", f"{order_oscillator(rule):.3f}"),
            (rule, "order, star nonlinear gravity after 1st collision", f"{order_star(rule):.3f}"),
            (rule, "Noether: max |p_x - p_x0|, star, 100 impacts", f"{np.ptp(star.p[:, 0]):.1e}"),
            (rule, "Noether: max rel. angular momentum dev., billiard", f"{np.ptp(ang) / abs(ang[0]):.1e}"),
            (rule, "symplectic defect, billiard impact step (FD 1e-6)", f"{symplectic_defect(f, z):.1e}"),
            (
                rule,
                "symplectic defect, star impact step (FD 1e-6)",
                f"{symplectic_defect(fs, np.array([0, 0.64, 0.3, -1, -3, 2.0])):.1e}",
            ),
            (rule, "max |E_after - E_before| over 100 star impacts", f"{impact_energy_jump(star):.1e}"),
            (rule, "CasADi path, star: us per step", f"{1e6 * star.stats['seconds_per_step']:.1f}"),
        ]
    print("| rule | quantity | value |\n|---|---|---|")
    for r in rows:
        print(f"| {r[0]} | {r[1]} | {r[2]} |")


if __name__ == "__main__":
    main()
