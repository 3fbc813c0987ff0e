"""A spun ball bouncing on a rough floor in 3-D: Coulomb's cone at every impact, its path curving, rolling.

q = (x, y, z, ax, ay): the centre and rotation angles about the x and y axes (m = 1, I = 2/5, a uniform ball
of radius 1; the spin about z does not slide and is left out), floor z >= r with restitution e = 0.7 and
friction mu = 0.3 in both directions of the floor (an isotropic cone): the contact point slides at
``(xd - r ayd, yd + r axd)``, so ``friction={"floor": (mu, (x - r ay, y + r ax))}``. Thrown along x with
back- and side-spin, the ball's horizontal velocity turns at every impact: the tangential impulse stops the
sliding if it fits in the cone, mu times the normal impulse m (1 + e) |vz| (then it leaves rolling), or else
is on the cone's edge against the sliding. Each impact is printed against that closed form. When the
bounces have died out (a plastic impact) the ball slides on the floor, the sliding velocity u shrinking
along a fixed direction at mu g (1 + m r^2 / I), until it rolls, then rolls on straight at constant
velocity: printed against the closed form from the state after the landing. Plotted: the path seen from
above and the sliding speed.
"""

import math
import sys
from pathlib import Path

import numpy as np
import sympy as sp

import vcigen

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "contact"))  # the examples' helpers
from _common import args, build, kinds, save, simulate  # noqa: E402

M, INERTIA, R, G, MU, E = 1.0, 0.4, 1.0, 9.81, 0.1, 0.5
SETUP = {"q0": [0.0, 0.0, 2.0, 0.0, 0.0], "v0": [2.0, 0.0, 0.0, -6.0, -15.0], "h": 0.002, "t_end": 7.0}


def model() -> vcigen.Model:
    x, y, z, ax, ay = sp.symbols("x y z ax ay")
    xd, yd, zd, axd, ayd = sp.symbols("xd yd zd axd ayd")
    m, inertia, r, g, mu, e = sp.symbols("m I r g mu e")
    return vcigen.Model(
        name="spun_ball",
        q=[x, y, z, ax, ay],
        qdot=[xd, yd, zd, axd, ayd],
        lagrangian=m / 2 * (xd**2 + yd**2 + zd**2) + inertia / 2 * (axd**2 + ayd**2) - m * g * z,
        contacts={"floor": z - r},
        params={m: M, inertia: INERTIA, r: R, g: G, mu: MU, e: E},
        restitution={"floor": e},
        friction={"floor": (mu, (x - r * ay, y + r * ax))},
    )


def sliding(v, w) -> np.ndarray:
    """The contact point's sliding velocity ``(vx - r wy, vy + r wx)``."""
    return np.array([v[0] - R * w[1], v[1] + R * w[0]])


def coulomb(v, w, vz: float):
    """Coulomb's impulse law on the floor (isotropic cone): ``(v+ (x, y), w+, "roll" or "slip")``."""
    pn = M * (1 + E) * (-vz)
    u = sliding(v, w)
    stick = -u / (1 / M + R**2 / INERTIA)
    rolls = math.hypot(*stick) <= MU * pn
    pt = stick if rolls else -MU * pn * u / math.hypot(*u)
    return v + pt / M, w + R * np.array([pt[1], -pt[0]]) / INERTIA, "roll" if rolls else "slip"


def state(res: vcigen.Result, k: int):
    """Horizontal velocity and spin ``(v (x, y), w (x, y))`` at grid point ``k``."""
    return res.p[k, :2] / M, res.p[k, 3:] / INERTIA


def report(res: vcigen.Result) -> None:
    print(kinds(res))
    v, w = np.array(SETUP["v0"][:2]), np.array(SETUP["v0"][3:])
    worst = 0.0
    for im in res.impacts:
        if im.kind not in ("restitution", "elastic"):
            continue
        kin = im.energy_before - M * G * R - 0.5 * M * v @ v - 0.5 * INERTIA * w @ w  # at z = r
        v1, w1, law = coulomb(v, w, -math.sqrt(max(2 * kin / M, 0.0)))
        got_v, got_w = state(res, min(im.step + 2, res.t.size - 1))
        worst = max(worst, float(np.max(np.abs(np.concatenate([got_v - v1, got_w - w1])))))
        print(
            f"impact t = {im.t:.4f}: {law}  v = ({got_v[0]:+.5f}, {got_v[1]:+.5f}) Coulomb ({v1[0]:+.5f}, "
            f"{v1[1]:+.5f}),  w = ({got_w[0]:+.4f}, {got_w[1]:+.4f}) Coulomb ({w1[0]:+.4f}, {w1[1]:+.4f})"
        )
        v, w = got_v, got_w
    print(f"max |velocity or spin - Coulomb's| after an impact: {worst:.1e}")
    landing = [im for im in res.impacts if im.kind == "plastic"]
    if not landing:
        return
    k = landing[-1].step + 1  # the first grid point on the floor
    v, w = state(res, k)
    u = sliding(v, w)
    slow = MU * G * (1 + M * R**2 / INERTIA)  # |du/dt| while it slides
    t_roll = res.t[k] + math.hypot(*u) / slow
    v_roll = v - MU * G * u / math.hypot(*u) * (t_roll - res.t[k])
    late = res.t > t_roll + 0.01
    got = res.p[late, :2] / M
    print(
        f"landed at t = {landing[-1].t:.4f} sliding at |u| = {math.hypot(*u):.4f}: "
        f"rolls from t = {t_roll:.4f} at v = ({v_roll[0]:+.6f}, {v_roll[1]:+.6f}); "
        f"simulated ({got[-1, 0]:+.6f}, {got[-1, 1]:+.6f}), "
        f"max error {np.max(np.abs(got - v_roll)):.1e}"
    )
    slide_late = [math.hypot(*sliding(*state(res, i))) for i in np.flatnonzero(late)]
    print(f"rolling: max |u| after t = {t_roll + 0.01:.3f} is {max(slide_late):.1e}")


def plot(res: vcigen.Result, out: str, backend: str) -> None:
    import matplotlib.pyplot as plt

    fig, (top, slide) = plt.subplots(1, 2, figsize=(11, 4.2), dpi=110)
    top.plot(res.q[:, 0], res.q[:, 1], lw=1.0, color="k")
    for im in res.impacts:
        top.scatter(im.q[0], im.q[1], s=14, color="C3" if im.kind == "plastic" else "C2", zorder=3)
    top.set_xlabel("x")
    top.set_ylabel("y")
    top.set_aspect("equal", adjustable="datalim")
    top.set_title("path seen from above (dots: impacts, red: the landing)", fontsize=9)
    u = np.array([np.hypot(*sliding(*state(res, k))) for k in range(res.t.size)])
    slide.plot(res.t, u, lw=0.9, label="sliding speed |u|")
    slide.plot(res.t, res.q[:, 2] - R, lw=0.9, color="k", label="height z - r")
    slide.set_xlabel("t")
    slide.legend(fontsize=8)
    slide.set_title(f"spun ball, mu = {MU}, e = {E} [{backend}]: {kinds(res)}", fontsize=9)
    save(fig, out, f"spun_ball_{backend}")


if __name__ == "__main__":
    a = args(__doc__)
    res = simulate(build(model(), a.backend), **SETUP)
    report(res)
    plot(res, a.out, a.backend)
