"""A pendulum in Cartesian coordinates (a bilateral rod constraint) strikes an elastic wall.

q = (x, y), rod x^2 + y^2 - l^2 = 0 (l = 1, always active, multiplier of either sign), wall
x + d >= 0 (d = 1/2, elastic), released from theta0 = 1 rad at rest, h = 0.01, t_end = 20. The bob
hits the wall at theta = -pi/6 with speed v = sqrt(2 g l (cos(pi/6) - cos theta0)) and reverses:
the wall's impulse is 2 m v / cos(pi/6). Between impacts it swings out to theta0 and back, which
takes 2 (K(k) + F(phi1, k)) / omega, k = sin(theta0/2), sin(phi1) = sin(pi/12)/k, omega = sqrt(g/l).
The rod tension is -2 l lambda = m g (3 cos theta - 2 cos theta0), m g (3 - 2 cos theta0) at the
bottom. Printed: impacts, wall impulse, rod residual, E_d, the impact interval at three steps
with errors and order, the tension.
"""

import math

import matplotlib.pyplot as plt
import numpy as np
import sympy as sp
from _common import args, build, kinds, mark_impacts, save, simulate
from scipy.special import ellipk, ellipkinc

import vcigen
from vcigen.analysis import fit_order

M, G, ROD, D, THETA0 = 1.0, 9.81, 1.0, 0.5, 1.0
SETUP = {
    "q0": [ROD * math.sin(THETA0), -ROD * math.cos(THETA0)],
    "v0": [0.0, 0.0],
    "h": 0.01,
    "t_end": 20.0,
}
STEPS = (0.01, 0.005, 0.0025)


def model() -> vcigen.Model:
    x, y, xd, yd = sp.symbols("x y xd yd")
    m, g, length, d = sp.symbols("m g l d", positive=True)
    return vcigen.Model(
        name="pendulum_wall",
        q=[x, y],
        qdot=[xd, yd],
        lagrangian=m / 2 * (xd**2 + yd**2) - m * g * y,
        contacts={"wall": x + d},
        constraints={"rod": x**2 + y**2 - length**2},
        params={m: M, g: G, length: ROD, d: D},
    )


def exact_interval() -> float:
    """Wall to wall: out to theta0 and back, 2 (K + F(phi1)) / omega (elliptic integrals, parameter k^2)."""
    k = math.sin(THETA0 / 2)
    theta_wall = math.asin(D / ROD)
    phi1 = math.asin(math.sin(theta_wall / 2) / k)
    return 2 * (ellipk(k * k) + ellipkinc(phi1, k * k)) / math.sqrt(G / ROD)


def tension(res: vcigen.Result) -> np.ndarray:
    """Rod tension over each grid step, -2 l lambda (lambda (2x, 2y) is the rod's force)."""
    return -2 * ROD * res.constraint_force[:, 0]


def report(results: dict[float, vcigen.Result]) -> None:
    res = results[SETUP["h"]]
    theta_wall = math.asin(D / ROD)
    speed = math.sqrt(2 * G * ROD * (math.cos(theta_wall) - math.cos(THETA0)))
    impulses = np.array([im.impulse for im in res.impacts])
    rod = np.abs(np.sum(res.q**2, axis=1) - ROD**2).max()
    print(f"impacts: {kinds(res)}")
    print(
        f"wall impulse {impulses.min():.6f}..{impulses.max():.6f} vs 2 m v/cos(pi/6) = "
        f"{2 * M * speed / math.cos(theta_wall):.6f}"
    )
    print(f"rod residual max |x^2 + y^2 - l^2| = {rod:.1e}")
    print(f"E_d bounded: max rel dev {res.max_energy_deviation():.1e}")
    exact = exact_interval()
    errors = []
    for h, r in results.items():
        measured = np.diff([im.t for im in r.impacts]).mean()
        errors.append(abs(measured - exact))
        print(
            f"h = {h}: impact interval {measured:.8f} vs 2(K+F)/omega = {exact:.8f}, "
            f"error {errors[-1]:.1e} ({r.n_impacts} impacts); first wall impulse error "
            f"{abs(r.impacts[0].impulse - 2 * M * speed / math.cos(theta_wall)):.1e}"
        )
    print(f"observed order of the impact interval: {fit_order(list(results), errors):.2f} (expected 2)")
    smooth = np.ones(res.t.size - 1, dtype=bool)
    smooth[[im.step for im in res.impacts]] = False
    bottom = np.flatnonzero(smooth & (res.q[:-1, 0] * res.q[1:, 0] < 0))  # steps through x = 0
    ten = tension(res)
    closed = M * G * (3 - 2 * math.cos(THETA0))
    cos_mid = -0.5 * (res.q[:-1, 1] + res.q[1:, 1]) / ROD
    along = np.abs(ten - M * G * (3 * cos_mid - 2 * math.cos(THETA0)))[smooth].max()
    print(
        f"tension at the bottom -2 l lambda = {ten[bottom].mean():.4f} ({bottom.size} passes, "
        f"{ten[bottom].min():.4f}..{ten[bottom].max():.4f}) vs m g (3 - 2 cos theta0) = {closed:.4f}; "
        f"vs m g (3 cos theta - 2 cos theta0) on every smooth step: max dev {along:.1e}"
    )


def plot(res: vcigen.Result, out: str, backend: str) -> None:
    fig, (q_ax, t_ax) = plt.subplots(2, 1, figsize=(8, 5.6), dpi=110, sharex=True)
    q_ax.plot(res.t, res.q[:, 0], lw=0.8, color="C0", label="x(t)")
    q_ax.plot(res.t, res.q[:, 1], lw=0.8, color="C1", label="y(t)")
    q_ax.axhline(-D, ls=":", lw=0.7, color="k", label="wall x = -d")
    mark_impacts(q_ax, res, [im.q[0] for im in res.impacts])
    q_ax.set_ylabel("position")
    q_ax.legend(loc="upper right", fontsize=7, ncol=2)
    smooth = np.ones(res.t.size - 1, dtype=bool)
    smooth[[im.step for im in res.impacts]] = False
    t_ax.plot(res.t[:-1][smooth], tension(res)[smooth], ".", ms=1.5, color="C4", label="rod tension")
    t_ax.axhline(
        M * G * (3 - 2 * math.cos(THETA0)), ls=":", lw=0.8, color="C3", label="m g (3 - 2 cos theta0)"
    )
    t_ax.set_ylabel(r"tension $-2\,l\,\lambda$")
    t_ax.set_xlabel("t")
    t_ax.legend(loc="lower right", fontsize=7)
    q_ax.set_title(f"pendulum against a wall, h = {res.h} [{backend}]: {kinds(res)}", fontsize=10)
    save(fig, out, f"pendulum_wall_{backend}")


if __name__ == "__main__":
    a = args(__doc__)
    sim = build(model(), a.backend)
    results = {h: simulate(sim, **{**SETUP, "h": h}) for h in STEPS}
    report(results)
    plot(results[SETUP["h"]], a.out, a.backend)
