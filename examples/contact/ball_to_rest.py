"""A ball with restitution e = 0.5 bounces to rest on a floor (Zeno), then slides at vx.

Dropped from y = 1 with vx = 0.3: it lands at t1 = sqrt(2/g) with speed v1 = sqrt(2 g), the
flights shrink by e and accumulate at the Zeno time t1 + 2 e v1 / (g (1 - e)). vcigen resolves
bounces until one falls below the jump's resolution, completes it as a plastic impact and
holds the floor (MATH.md, *Sustained contact*). Printed: the impact kinds; when the floor
becomes active against the Zeno time; the resting force against m g; the height while
active; p_x and x against free sliding; E_d at rest against m vx^2 / 2.
"""

import math

import matplotlib.pyplot as plt
import numpy as np
import sympy as sp
from _common import args, build, kinds, mark_impacts, save, simulate

import vcigen

M, G, E = 1.0, 9.81, 0.5
SETUP = {"q0": [0.0, 1.0], "v0": [0.3, 0.0], "h": 0.001, "t_end": 3.0}


def model() -> vcigen.Model:
    x, y, xd, yd = sp.symbols("x y xd yd")
    m, g = sp.symbols("m g", positive=True)
    e = sp.Symbol("e")
    return vcigen.Model(
        name="ball_to_rest",
        q=[x, y],
        qdot=[xd, yd],
        lagrangian=m / 2 * (xd**2 + yd**2) - m * g * y,
        contacts={"floor": y},
        params={m: M, g: G, e: E},
        restitution={"floor": e},
    )


def report(res: vcigen.Result) -> None:
    vx, y0 = SETUP["v0"][0], SETUP["q0"][1]
    t1, v1 = math.sqrt(2 * y0 / G), math.sqrt(2 * G * y0)
    zeno = t1 + 2 * E * v1 / (G * (1 - E))
    plastic = next(im for im in res.impacts if im.kind == "plastic")
    speed = math.sqrt(2 * (plastic.energy_before - plastic.energy_after) / M)  # K_n lost = m s^2 / 2
    skipped = plastic.t + 2 * E * speed / (G * (1 - E))  # the flights the plastic impact cut short
    held = res.active[:, 0]
    steps = held[:-1] & held[1:]  # grid steps with the floor active at both ends
    force = res.contact_force[steps, 0]
    late = res.t > plastic.t + 0.1
    px = res.p[:, 0]
    print(f"impacts: {kinds(res)}")
    print(
        f"active from t = {plastic.t:.6f} (the plastic impact, speed s = {speed:.3e}) vs Zeno time "
        f"t1 + 2 e v1/(g(1-e)) = {zeno:.6f}; with the skipped flights, t + 2 e s/(g(1-e)) = {skipped:.6f}"
    )
    print(
        f"resting force: mean {force.mean():.6f} vs m g = {M * G:.6f}, "
        f"max |lambda - m g| = {np.abs(force - M * G).max():.1e} over {force.size} steps"
    )
    print(f"max |y| while active: {np.abs(res.q[held, 1]).max():.1e}")
    print(f"p_x drift: max |p_x - m vx| = {np.abs(px - M * vx).max():.1e}")
    print(f"x(t_end) = {res.q[-1, 0]:.12f} vs vx t_end = {vx * res.t[-1]:.12f}")
    print(
        f"E_d at rest: {res.energy[late[:-1]].mean():.12f} (spread {np.ptp(res.energy[late[:-1]]):.1e}) "
        f"vs m vx^2/2 = {M * vx**2 / 2:.12f}"
    )


def plot(res: vcigen.Result, out: str, backend: str) -> None:
    fig, ax = plt.subplots(figsize=(8, 3.8), dpi=110)
    ax.plot(res.t, res.q[:, 1], lw=0.8, color="k", label="y(t)")
    mark_impacts(ax, res, [im.q[1] for im in res.impacts])
    ax.set_xlabel("t")
    ax.set_ylabel("height y")
    force_ax = ax.twinx()
    force_ax.step(
        res.t[:-1], res.contact_force[:, 0], where="post", lw=0.8, color="C4", label="contact force"
    )
    force_ax.axhline(M * G, ls=":", lw=0.7, color="C4")
    force_ax.set_ylabel(r"contact force $\lambda$ (m g dotted)", color="C4")
    force_ax.set_ylim(-0.5, 2.2 * M * G)
    lines = ax.get_legend_handles_labels()
    more = force_ax.get_legend_handles_labels()
    ax.legend(lines[0] + more[0], lines[1] + more[1], loc="upper right", fontsize=8)
    ax.set_title(f"ball, e = {E}, h = {SETUP['h']} [{backend}]: {kinds(res)}", fontsize=10)
    save(fig, out, f"ball_to_rest_{backend}")


if __name__ == "__main__":
    a = args(__doc__)
    res = simulate(build(model(), a.backend), **SETUP)
    report(res)
    plot(res, a.out, a.backend)
