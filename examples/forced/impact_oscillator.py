"""The damped, sinusoidally driven impact oscillator: a bifurcation diagram over the drive amplitude.

A unit mass on a spring (stiffness k), with viscous damping c and a drive A cos(W t), hits a stop at
x = d with restitution e: x'' + c x' + k x = A cos(W t), x <= d (the classic vibro-impact system;
Shaw & Holmes 1983, Peterka). The damping and the drive are Lagrange-d'Alembert forces
(``Model(forces=[...], time=t)``, MATH.md *Forcing*); impacts keep the energy less the restitution loss,
and ``res.work`` books the work of the forces.

Printed: one run checked against the exact piecewise flow (closed form between impacts, impacts
located on it by brentq), its energy balance, and the sweep's timing. Plotted (PNG): the impact
velocities at steady state against A (period-1, period-doubling and irregular motion), and one run's
x(t) with its energy balance.
"""

import math
import sys
import time
from pathlib import Path

import numpy as np
import sympy as sp

import vcigen

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parent / "contact"))  # the examples' command line and plot helpers
sys.path.insert(0, str(HERE.parents[1] / "tests"))  # the closed form, shared with the tests
from _common import args, build, save  # noqa: E402

C, K, W, D, E = 0.1, 1.0, 2.8, 0.05, 0.8
SETUP = {"q0": [0.0], "v0": [0.0], "h": 0.01, "t_end": 60.0}
PERIOD = 2 * math.pi / W


def model() -> vcigen.Model:
    x, xd, t = sp.symbols("x xd t")
    c, k, A, w, d, e = sp.symbols("c k A W d e")
    return vcigen.Model(
        name="impact_oscillator",
        q=[x],
        qdot=[xd],
        lagrangian=xd**2 / 2 - k * x**2 / 2,
        contacts={"stop": d - x},
        params={c: C, k: K, A: 0.6, w: W, d: D, e: E},
        restitution={"stop": e},
        forces=[-c * xd + A * sp.cos(w * t)],
        time=t,
    )


CHECK = {"A": 0.6, "W": 1.3, "d": 0.25}  # period-1 motion, no chatter (the closed form cannot do Zeno)


def exact_check(sim: vcigen.Simulator) -> None:
    """One run against the exact piecewise flow (parameters CHECK): grid error and impact times."""
    try:
        import forced_scenes as fs
    except ImportError:
        print("closed-form check skipped (tests/forced_scenes.py not found)")
        return
    flow = fs.LinearFlow(C, K, CHECK["A"], CHECK["W"])
    for h in (0.01, 0.005):
        res = sim.simulate(**{**SETUP, "h": h}, params=CHECK)
        exact = fs.driven_exact_grid(0.0, 0.0, res.t, wall=CHECK["d"], e=E, flow=flow)
        _, _, hits = fs.driven_exact(0.0, 0.0, float(res.t[-1]), wall=CHECK["d"], e=E, flow=flow)
        dt = max((abs(im.t - th) for im, th in zip(res.impacts, hits)), default=0.0)
        print(
            f"closed form, {CHECK}, h = {h}: {len(res.impacts)} impacts (exact {len(hits)}), "
            f"max |x - x_exact| = "
            f"{np.max(np.abs(res.q[:, 0] - exact)):.2e}, max |t_impact - exact| = {dt:.2e}, "
            f"max |energy balance| = {np.max(np.abs(res.energy_balance())):.2e}"
        )


def sweep(
    sim: vcigen.Simulator, amplitudes: np.ndarray, periods: int, keep: int = 50, h: float | None = None
):
    """Impact velocities over the last ``keep`` drive periods of ``periods``, for each amplitude."""
    h = h or PERIOD / 400
    points = []
    start = time.perf_counter()
    for A in amplitudes:
        res = sim.simulate(q0=[0.0], v0=[0.0], h=h, t_end=periods * PERIOD, params={"A": float(A)})
        late = periods * PERIOD - keep * PERIOD
        points.append(np.array([im.impulse / (1 + E) for im in res.impacts if im.t > late]))  # mu = (1 + e) v
    wall = time.perf_counter() - start
    steps = len(amplitudes) * periods * PERIOD / h
    print(f"sweep: {len(amplitudes)} amplitudes x {periods} periods ({steps:.3g} steps) in {wall:.2f} s")
    return points


def plot(sim: vcigen.Simulator, amplitudes, points, out: str, backend: str) -> None:
    import matplotlib.pyplot as plt

    fig, (ax, bx) = plt.subplots(1, 2, figsize=(11, 4), dpi=110, gridspec_kw={"width_ratios": [3, 2]})
    for A, v in zip(amplitudes, points):
        ax.plot(np.full(v.size, A), v, ".", ms=1.2, color="k")
    ax.set_xlabel("drive amplitude A")
    ax.set_ylabel("impact speed at steady state")
    ax.set_title(f"impact oscillator: c = {C}, W = {W}, d = {D}, e = {E} [{backend}]", fontsize=10)
    res = sim.simulate(**SETUP)
    bx.plot(res.t, res.q[:, 0], lw=0.8, color="k", label="x(t), A = 0.6")
    bx.axhline(D, ls=":", color="C3", lw=0.8, label="stop")
    bal = bx.twinx()
    bal.plot(res.t[1:], res.energy_balance(), lw=0.7, color="C4")
    bal.set_ylabel("energy balance E - E0 - W + losses", color="C4")
    bx.set_xlabel("t")
    bx.legend(loc="lower left", fontsize=8)
    save(fig, out, f"impact_oscillator_{backend}")


if __name__ == "__main__":
    a = args(__doc__)
    sim = build(model(), a.backend)
    exact_check(sim)
    fast = a.backend == "c"  # CasADi takes ~25 us per step: a coarser sweep
    amplitudes = np.linspace(0.1, 1.6, 150 if fast else 12)
    pts = sweep(sim, amplitudes, periods=200 if fast else 100, keep=50 if fast else 30)
    plot(sim, amplitudes, pts, a.out, a.backend)
