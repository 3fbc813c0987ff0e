"""A vibratory conveyor: the mean speed a rough plate vibrating at 50 Hz gives a particle, against the throw.

The plate vibrates as A sin(W t) along an angle beta = 30 degrees from its surface (W = 2 pi 50 Hz). In the
plate's frame the particle (x along the plate, y above it, y >= 0) feels a(t) = A W^2 sin(W t) along
(cos beta, sin beta) and gravity: a force of time (``Model(forces=[...], time=t)``). On the plate Coulomb
friction (mu = 0.5, ``Model(friction=...)``) holds it or lets it slide; where the throw
Gamma sin(beta) (Gamma = A W^2 / g) passes 1 the plate falls away faster than gravity pulls it: it hops
and lands (e = 0, with friction at the landing). Each cycle it creeps or hops forward: the conveying speed.

Printed: one run (Gamma = 2.5) against an event-driven scipy reference of its stick, slide, hop and landing
phases (``tests/forced_scenes.conveyor_reference``: DOP853 at rtol 1e-12) at two steps, with the order;
the mean speed over the last ten periods against Gamma, with the reference's at six points. Plotted (PNG):
the speed against Gamma, and that run's x(t), y(t) with its lift-offs and landings.
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

G, W, BETA, MU = 9.81, 2 * math.pi * 50, math.radians(30), 0.5
PERIOD = 2 * math.pi / W
SETUP = {"q0": [0.0, 0.0], "v0": [0.0, 0.0], "h": 2e-4, "t_end": 0.4}
GAMMAS = np.linspace(0.5, 4.0, 36)
CHECKED = (1.0, 1.5, 2.0, 2.5, 3.0, 3.5)  # Gamma where the reference runs too


def model() -> vcigen.Model:
    x, y, xd, yd, t = sp.symbols("x y xd yd t")
    a, w, beta, mu, e = sp.symbols("A W beta mu e")
    push = a * w**2 * sp.sin(w * t)  # the plate's acceleration, reversed: the particle's in its frame
    return vcigen.Model(
        name="conveyor",
        q=[x, y],
        qdot=[xd, yd],
        lagrangian=(xd**2 + yd**2) / 2 - G * y,
        contacts={"plate": y},
        forces=[push * sp.cos(beta), push * sp.sin(beta)],
        time=t,
        restitution={"plate": e},
        friction={"plate": (mu, x)},
        params={a: 2.5 * G / W**2, w: W, beta: BETA, mu: MU, e: 0.0},
    )


def shake(gamma: float, w: float = W, beta: float = BETA, mu: float = MU) -> dict[str, float]:
    """The parameters of a plate with throw ``gamma`` (``A W^2 / g``)."""
    return {"A": gamma * G / w**2, "W": w, "beta": beta, "mu": mu, "e": 0.0}


def speed(q: np.ndarray, t: np.ndarray) -> float:
    """The mean speed along the plate over the last ten periods."""
    late = t >= t[-1] - 10 * PERIOD
    return float((q[-1, 0] - q[late][0, 0]) / (t[-1] - t[late][0]))


def main() -> None:
    from forced_scenes import conveyor_reference

    opts = args(__doc__)
    sim = build(model(), opts.backend)
    p = shake(2.5)
    events, at = conveyor_reference(p, 0.1)
    errors = []
    for h in (SETUP["h"], SETUP["h"] / 2):
        res = sim.simulate(**{**SETUP, "h": h, "t_end": 0.1}, params=p, progress=False)
        errors.append(float(np.abs(res.q - np.array([at(t) for t in res.t])).max()))
    kinds = ", ".join(
        f"{sum(k == kind for k, _ in events)} {kind}" for kind in ("slide", "stop", "lift", "land")
    )
    print(
        f"Gamma = 2.5 to t = 0.1 ({kinds} in the reference): largest |q - reference| {errors[0]:.2e} at h ="
    )
    print(f"  {SETUP['h']}, {errors[1]:.2e} at h / 2: order {math.log2(errors[0] / errors[1]):.2f}")

    start = time.perf_counter()
    runs = [sim.simulate(**SETUP, params=shake(g), progress=False) for g in GAMMAS]
    wall = time.perf_counter() - start
    speeds = np.array([speed(r.q, r.t) for r in runs])
    print(f"{len(GAMMAS)} runs of {runs[0].t.size - 1} steps: {wall:.2f} s")
    print("  Gamma   speed (mm/s)   reference   apart")
    ref_speeds = []
    for g in CHECKED:
        _, ref_at = conveyor_reference(shake(g), SETUP["t_end"])
        t = np.arange(0.0, SETUP["t_end"] + SETUP["h"] / 2, SETUP["h"])
        ref_speeds.append(speed(np.array([ref_at(s) for s in t]), t))
        mine = speeds[int(np.argmin(np.abs(GAMMAS - g)))]
        print(
            f"  {g:5.2f}  {1e3 * mine:12.3f}  {1e3 * ref_speeds[-1]:10.3f}  {abs(mine - ref_speeds[-1]):.1e}"
        )

    import matplotlib.pyplot as plt

    fig, (ax, bx) = plt.subplots(1, 2, figsize=(11, 4))
    ax.plot(GAMMAS, 1e3 * speeds, "-", label=f"vcigen, h = {SETUP['h']}")
    ax.plot(CHECKED, 1e3 * np.array(ref_speeds), "o", mfc="none", label="event-driven reference (scipy)")
    ax.axvline(1 / math.sin(BETA), color="0.6", ls=":", label="throw Gamma sin(beta) = 1: hops")
    ax.set(xlabel="Gamma = A W^2 / g", ylabel="mean speed along the plate (mm/s)")
    ax.set_title(f"conveying at 50 Hz, beta = 30 deg, mu = {MU}")
    ax.legend(fontsize=8)
    run = runs[int(np.argmin(np.abs(GAMMAS - 2.5)))]
    late = run.t >= run.t[-1] - 5 * PERIOD
    bx.plot(run.t[late], 1e3 * (run.q[late, 0] - run.q[late][0, 0]), label="x (mm, from the window's start)")
    bx.plot(run.t[late], 1e5 * run.q[late, 1], label="y (10 um)")
    for t in [t for t, _ in run.liftoffs if t >= run.t[late][0]]:
        bx.axvline(t, color="C2", lw=0.6)
    for t in [im.t for im in run.impacts if im.t >= run.t[late][0]]:
        bx.axvline(t, color="C3", lw=0.6, ls="--")
    bx.set(xlabel="t (s)", title="Gamma = 2.5: lift-offs (green), landings (red, dashed)")
    bx.legend(fontsize=8)
    save(fig, opts.out, "conveyor")


if __name__ == "__main__":
    main()
