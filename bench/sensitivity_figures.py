"""Figures of ``vcigen.casadi_functions`` (issue 11): run `.venv/bin/python bench/sensitivity_figures.py`.

Per scene, the relative agreement ``max |J_exact - J_fd| / max |J_exact|`` of the Jacobian of one grid step
(smooth, and holding one impact) with respect to ``(q_k, v_k, params)`` against central differences of
one-step ``simulate`` runs; the exact and finite-difference symplectic defects of elastic impact steps;
the optimisation examples' convergence.
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))

from scenes import load_example  # noqa: E402
from test_casadi_functions import exact_and_fd, first_impact_step  # noqa: E402
from test_symplectic import EXACT, exact_case, pendulum_state_before_impact  # noqa: E402

if __name__ == "__main__":
    print("| scene | smooth step | impact step |\n|---|---|---|")
    for name in ("particle", "star", "double_pendulum", "box_lossy", "driven"):
        k = first_impact_step(name)
        rel = []
        for kk in (k - 3, k):
            exact, fd = exact_and_fd(name, kk)
            rel.append(np.abs(exact - fd).max() / np.abs(exact).max())
        print(f"| {name} | {rel[0]:.1e} | {rel[1]:.1e} |")
    print("\n| elastic impact step | exact defect | central differences |\n|---|---|---|")
    for name, (maker, h, z, contact) in EXACT.items():
        z = pendulum_state_before_impact() if z is None else np.array(z)
        exact, fd = exact_case(maker(), f"impact_{contact}", z, h)
        print(f"| {name} | {exact:.1e} | {fd:.1e} |")
    for fast in (True, False):
        out = load_example("optimise/shooting").solve(fast=fast, verbose=False)
        print(f"\nshooting (fast={fast}): residuals " + ", ".join(f"{r:.1e}" for r in out["residuals"]))
        for torque in (False, True):
            out = load_example("optimise/throw").solve(fast=fast, verbose=False, torque=torque)
            gap = np.abs(out["replayed"] - out["target"]).max()
            print(
                f"throw (fast={fast}, torque={torque}): {out['iterations']} IPOPT iterations, "
                f"x = {out['x']}, |x|^2 = {out['effort']:.4f}, "
                f"replayed impact point {out['replayed']} vs {out['target']}: {gap:.1e}"
            )
