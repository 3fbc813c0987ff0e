"""An impact damper: a ball rattling in a cavity of a driven primary takes the top off its resonance.

The primary (mass M = 1 on a spring k = 4 pi^2: 1 Hz, viscous damping c) is driven by F cos(W t); a ball
of mass m = 0.1 moves freely in its cavity of half-gap d (level here: the parameter g, gravity along -X, is
0; the tests run it upright too) and hits its walls with restitution e. Two bodies, both sides of each
contact move: at e = 0 the ball rides a wall while the wall decelerates into it and leaves where that stops
(its force m/(M+m) (-k X - c V + F cos(W t)) vanishes).

Printed: a plastic run (e = 0, c = 0, near resonance) against an event-driven reference of closed forms
(``tests/test_impact_damper.reference``) at two steps, with the order of its landings and lift-offs; the
primary's steady amplitude against W for the bare primary (the cavity too wide to touch; against its closed
form F / sqrt((k - M W^2)^2 + (c W)^2)) and with the ball at e = 0 and e = 0.6. Plotted (PNG): those
amplitudes, and one run's X(t), x(t) - X(t) with its impacts and lift-offs.
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
sys.path.insert(0, str(HERE.parents[1] / "tests"))  # the reference, shared with the tests
from _common import args, build, save  # noqa: E402

K = 4 * math.pi**2  # the primary alone at 1 Hz
SETUP = {"q0": [0.0, 0.0], "v0": [0.0, 0.0], "h": 1e-3, "t_end": 60.0}
SWEEP = {"M": 1.0, "m": 0.1, "k": K, "c": 0.3, "F": 2.0, "d": 0.3, "g": 0.0}
RATIOS = np.linspace(0.7, 1.3, 31)  # W over the primary's frequency
CASES = (("bare primary", 1e3, 0.0), ("ball, e = 0", SWEEP["d"], 0.0), ("ball, e = 0.6", SWEEP["d"], 0.6))


def model() -> vcigen.Model:
    X, x, V, v, t = sp.symbols("X x V v t")
    M, m, k, c, F, W, d, e, g = sp.symbols("M m k c F W d e g")
    return vcigen.Model(
        name="impact_damper",
        q=[X, x],
        qdot=[V, v],
        lagrangian=M * V**2 / 2 + m * v**2 / 2 - k * X**2 / 2 - g * (M * X + m * x),
        contacts={"right": X + d - x, "left": x - X + d},
        forces=[F * sp.cos(W * t) - c * V, 0],
        time=t,
        restitution={"right": e, "left": e},
        params={M: 1.0, m: 0.2, k: K, c: 0.0, F: 10.0, W: 6.0, d: 0.02, e: 0.0, g: 0.0},
    )


def amplitude(res: vcigen.Result, periods: float) -> float:
    """Half the primary's swing over the run's last ``periods`` drive periods."""
    late = res.q[res.t >= res.t[-1] - periods, 0]
    return float((late.max() - late.min()) / 2)


def main() -> None:
    from test_impact_damper import RIDE, impact_times, lift_times, reference

    opts = args(__doc__)
    sim = build(model(), opts.backend)
    ref = reference(RIDE, 2.9)
    events = impact_times(ref) + lift_times(ref)
    errors = []
    for h in (2e-3, 1e-3):
        res = sim.simulate([0.0, 0.0], [0.0, 0.0], h, t_end=2.9, params={**RIDE, "c": 0.0}, progress=False)
        mine = [im.t for im in res.impacts] + [t for t, _ in res.liftoffs]
        assert len(mine) == len(events), "the events differ from the reference's"
        errors.append(max(abs(a - b) for a, b in zip(mine, events)))
    n_land, n_lift = len(impact_times(ref)), len(lift_times(ref))
    print(f"e = 0, W = 6 to t = 2.9 ({n_land} landings, {n_lift} lift-offs in the reference): largest time")
    order = math.log2(errors[0] / errors[1])
    print(f"  apart {errors[0]:.2e} at h = 2e-3, {errors[1]:.2e} at 1e-3: order {order:.2f}")

    start, amps, runs = time.perf_counter(), {}, {}
    for name, d, e in CASES:
        amps[name] = []
        for r in RATIOS:
            p = {**SWEEP, "W": r * math.sqrt(K), "d": d, "e": e}
            res = sim.simulate(**SETUP, params=p, progress=False)
            amps[name].append(amplitude(res, 10.0))
            runs[name, r] = res
    wall = time.perf_counter() - start
    steps = len(CASES) * RATIOS.size * (runs[CASES[0][0], RATIOS[0]].t.size - 1)
    print(f"{len(CASES) * RATIOS.size} runs, {steps} steps: {wall:.2f} s")
    bare = SWEEP["F"] / np.sqrt(
        (K - SWEEP["M"] * (RATIOS * math.sqrt(K)) ** 2) ** 2 + (SWEEP["c"] * RATIOS * math.sqrt(K)) ** 2
    )
    apart = np.abs(np.array(amps["bare primary"]) - bare).max()
    print(f"  bare primary against its closed form: largest apart {apart:.1e}")
    print("  W / w0   bare    e = 0   e = 0.6   (steady amplitude of X)")
    for i in range(0, RATIOS.size, 5):
        print(
            f"  {RATIOS[i]:5.2f}  {amps['bare primary'][i]:.4f}  {amps['ball, e = 0'][i]:.4f}  "
            f"{amps['ball, e = 0.6'][i]:.4f}"
        )
    peak = {name: max(a) for name, a in amps.items()}
    print("  peaks: " + ", ".join(f"{name} {a:.4f}" for name, a in peak.items()))

    import matplotlib.pyplot as plt

    fig, (ax, bx) = plt.subplots(1, 2, figsize=(11, 4))
    ax.plot(RATIOS, bare, "-", color="0.6", label="bare primary, closed form")
    for (name, _, _), mark in zip(CASES, ("o", "s", "^")):
        ax.plot(RATIOS, amps[name], mark, mfc="none", ms=4, label=f"{name} (vcigen)")
    ax.set(xlabel="W / w0", ylabel="steady amplitude of the primary")
    ax.set_title(f"impact damper: m/M = {SWEEP['m']}, c = {SWEEP['c']}, gap 2d = {2 * SWEEP['d']}")
    ax.legend(fontsize=8)
    res = runs["ball, e = 0", RATIOS[RATIOS.size // 2]]
    late = res.t >= res.t[-1] - 3.0
    bx.plot(res.t[late], res.q[late, 0], label="X (primary)")
    bx.plot(res.t[late], 10 * (res.q[late, 1] - res.q[late, 0]), label="10 (x - X) (ball in the cavity)")
    for t in [im.t for im in res.impacts if im.t >= res.t[late][0]]:
        bx.axvline(t, color="C3", lw=0.5, ls="--")
    for t in [t for t, _ in res.liftoffs if t >= res.t[late][0]]:
        bx.axvline(t, color="C2", lw=0.5)
    bx.set(xlabel="t (s)", title="e = 0 at resonance: landings (red, dashed), lift-offs (green)")
    bx.legend(fontsize=8)
    save(fig, opts.out, "impact_damper")


if __name__ == "__main__":
    main()
