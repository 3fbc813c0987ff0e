"""A spinning disk bouncing on a rough floor: Coulomb's impulse law at every impact, then rolling.

q = (x, y, theta), m = 1, I = 1/2 (a uniform disk of radius 1), floor y >= r with restitution e = 0.7 and
friction mu = 0.3 along the contact point's sliding velocity xd - r thetad (``friction={"floor": (mu,
x - r theta)}``). At an impact the normal impulse is m (1 + e) |vy|; the tangential one stops the sliding
if it fits in the cone mu times the normal one (slip then roll), or else is the cone's edge (slip
throughout): each impact is printed against that closed form. When the bounces have died out (a plastic
impact) the disk slides on the floor under mu m g until it rolls (vx = r w) and then rolls on at constant
speed. Plotted: vx, r w and the height.
"""

import math
import sys
from pathlib import Path

import numpy as np
import sympy as sp

import vcigen

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "contact"))  # the examples' helpers
from _common import args, build, kinds, mark_impacts, save, simulate  # noqa: E402

M, INERTIA, R, G, MU, E = 1.0, 0.5, 1.0, 9.81, 0.3, 0.7
SETUP = {"q0": [0.0, 2.0, 0.0], "v0": [1.0, 0.0, 12.0], "h": 0.002, "t_end": 5.0}


def model() -> vcigen.Model:
    x, y, th, xd, yd, thd = sp.symbols("x y theta xd yd thetad")
    m, inertia, r, g, mu, e = sp.symbols("m I r g mu e")
    return vcigen.Model(
        name="rough_disk",
        q=[x, y, th],
        qdot=[xd, yd, thd],
        lagrangian=m / 2 * (xd**2 + yd**2) + inertia / 2 * thd**2 - m * g * y,
        contacts={"floor": y - r},
        params={m: M, inertia: INERTIA, r: R, g: G, mu: MU, e: E},
        restitution={"floor": e},
        friction={"floor": (mu, x - r * th)},
    )


def coulomb(vx: float, vy: float, w: float):
    """Coulomb's impulse law on the floor: ``(vx+, w+, "roll" or "slip")``."""
    pn = M * (1 + E) * (-vy)
    slide = vx - R * w
    stick = -slide / (1 / M + R**2 / INERTIA)
    rolls = abs(stick) <= MU * pn
    pt = stick if rolls else -MU * pn * math.copysign(1.0, slide)
    return vx + pt / M, w - R * pt / INERTIA, "roll" if rolls else "slip"


def report(res: vcigen.Result) -> None:
    print(kinds(res))
    vx, w = SETUP["v0"][0], SETUP["v0"][2]
    for im in res.impacts:
        if im.kind not in ("restitution", "elastic"):
            continue
        kin = im.energy_before - M * G * R - 0.5 * M * vx**2 - 0.5 * INERTIA * w**2  # at y = r
        vy = -math.sqrt(max(2 * kin / M, 0.0))
        vx1, w1, law = coulomb(vx, vy, w)
        k = min(im.step + 2, res.t.size - 1)
        got_vx, got_w = res.p[k, 0] / M, res.p[k, 2] / INERTIA
        print(
            f"impact t = {im.t:.5f}: {law:4s} vx {got_vx:+.6f} (Coulomb {vx1:+.6f}), "
            f"w {got_w:+.6f} (Coulomb {w1:+.6f})"
        )
        vx, w = got_vx, got_w
    late = res.t > res.t[-1] - 0.5
    roll = res.p[late, 0] / M - R * res.p[late, 2] / INERTIA
    print(f"at the end: rolling at vx = {res.p[-1, 0] / M:.6f}, max |vx - r w| = {np.max(np.abs(roll)):.1e}")


def plot(res: vcigen.Result, out: str, backend: str) -> None:
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(9, 3.8), dpi=110)
    ax.plot(res.t, res.p[:, 0] / M, lw=0.9, label="vx")
    ax.plot(res.t, R * res.p[:, 2] / INERTIA, lw=0.9, label="r w")
    ax.plot(res.t, res.q[:, 1] - R, lw=0.9, color="k", label="height y - r")
    mark_impacts(ax, res, [0.0 for _ in res.impacts], size=10)
    ax.set_xlabel("t")
    ax.legend(fontsize=8)
    ax.set_title(f"spinning disk on a rough floor, mu = {MU}, e = {E} [{backend}]: {kinds(res)}", fontsize=10)
    save(fig, out, f"rough_disk_{backend}")


if __name__ == "__main__":
    a = args(__doc__)
    res = simulate(build(model(), a.backend), **SETUP)
    report(res)
    plot(res, a.out, a.backend)
