"""A parallelogram four-bar linkage (a closed chain in maximal coordinates) bounces to rest on a floor.

Two unit bobs B = (xb, yb) and C = (xc, yc) on three bars: |AB| = 1 from the pivot A = (0, 0), |BC| = 2,
|CD| = 1 to the pivot D = (2, 0) (four coordinates, three bilateral constraints, one degree of freedom).
Started parallel at theta0 = -0.5 rad (B = (cos theta, sin theta)) turning at 1 rad/s, it stays a
parallelogram: both bobs ride a pendulum of mass 2 on unit bars, theta'' = -g cos theta. B lands on the
floor y_b = -0.9 (e = 0.5): the bounces shrink (Zeno) until it rests, held, where the floor pushes with
2 m g (virtual work: N dy_b = m g (dy_b + dy_c), dy_b = dy_c). Printed: impacts, the first bounce's time
against the pendulum's (scipy, event located) at three steps with its order, the bars' residuals, the
rest and the floor's force against 2 m g.
"""

import math

import matplotlib.pyplot as plt
import numpy as np
import sympy as sp
from _common import args, build, kinds, mark_impacts, save, simulate
from scipy.integrate import solve_ivp

import vcigen
from vcigen.analysis import fit_order

G, FLOOR, E, THETA0, OMEGA0 = 9.81, -0.9, 0.5, -0.5, 1.0
SETUP = {
    "q0": [math.cos(THETA0), math.sin(THETA0), 2 + math.cos(THETA0), math.sin(THETA0)],
    "v0": [-OMEGA0 * math.sin(THETA0), OMEGA0 * math.cos(THETA0)] * 2,
    "h": 0.005,
    "t_end": 4.0,
}
STEPS = (0.01, 0.005, 0.0025)


def model() -> vcigen.Model:
    xb, yb, xc, yc, ub, vb, uc, vc, e = sp.symbols("xb yb xc yc ub vb uc vc e")
    return vcigen.Model(
        name="four_bar",
        q=[xb, yb, xc, yc],
        qdot=[ub, vb, uc, vc],
        lagrangian=(ub**2 + vb**2 + uc**2 + vc**2) / 2 - G * (yb + yc),
        contacts={"floor": yb - FLOOR},
        constraints={
            "ab": xb**2 + yb**2 - 1,
            "bc": (xc - xb) ** 2 + (yc - yb) ** 2 - 4,
            "cd": (xc - 2) ** 2 + yc**2 - 1,
        },
        params={e: E},
        restitution={"floor": e},
    )


def first_landing() -> float:
    """The pendulum's first landing on the floor (scipy, event located, 1e-12)."""
    hit = lambda t, y: math.sin(y[0]) - FLOOR  # noqa: E731
    hit.terminal, hit.direction = True, -1
    sol = solve_ivp(
        lambda t, y: [y[1], -G * math.cos(y[0])], (0, 5), [THETA0, OMEGA0], events=hit, rtol=1e-12, atol=1e-12
    )
    return float(sol.t_events[0][0])


def bars(res: vcigen.Result) -> float:
    xb, yb, xc, yc = res.q.T
    return float(
        max(
            np.abs(xb**2 + yb**2 - 1).max(),
            np.abs((xc - xb) ** 2 + (yc - yb) ** 2 - 4).max(),
            np.abs((xc - 2) ** 2 + yc**2 - 1).max(),
        )
    )


def report(results: dict[float, vcigen.Result]) -> None:
    res = results[SETUP["h"]]
    exact = first_landing()
    print(f"impacts: {kinds(res)}")
    errors = [abs(r.impacts[0].t - exact) for r in results.values()]
    for (h, r), err in zip(results.items(), errors):
        print(f"h = {h}: first landing at t = {r.impacts[0].t:.8f} (pendulum: {exact:.8f}), error {err:.1e}")
    print(f"observed order of the first landing: {fit_order(list(results), errors):.2f} (expected 2)")
    print(f"bars kept: max |residual| {bars(res):.1e}; min y_b - floor {res.q[:, 1].min() - FLOOR:.1e}")
    held = np.flatnonzero(res.active[:-1, 0])
    rest = math.sqrt(1 - FLOOR**2)
    at_rest = [rest, FLOOR, 2 + rest, FLOOR]
    print(
        f"held on the floor from t = {res.t[held[0]]:.4f} (the last bounce at {res.impacts[-1].t:.4f}, "
        f"{res.impacts[-1].kind}); at the end q off the rest by {np.abs(res.q[-1] - at_rest).max():.1e}, "
        f"|v| {np.abs(res.v[-1]).max():.1e}"
    )
    late = res.t[:-1] >= res.impacts[-1].t + 0.1
    print(
        f"floor force at rest {res.contact_force[late, 0].mean():.12f} vs 2 m g = {2 * G:.12f} "
        f"(max dev {np.abs(res.contact_force[late, 0] - 2 * G).max():.1e})"
    )


def plot(res: vcigen.Result, out: str, backend: str) -> None:
    fig, (q_ax, f_ax) = plt.subplots(2, 1, figsize=(8, 5.6), dpi=110, sharex=True)
    theta_b = np.arctan2(res.q[:, 1], res.q[:, 0])
    theta_c = np.arctan2(res.q[:, 3], res.q[:, 2] - 2)
    q_ax.plot(res.t, theta_b, lw=0.9, color="C0", label="angle of AB")
    q_ax.plot(res.t, theta_c, lw=0.9, ls="--", color="C1", label="angle of DC (a parallelogram: the same)")
    q_ax.axhline(math.asin(FLOOR), ls=":", lw=0.7, color="k", label="B on the floor")
    mark_impacts(q_ax, res, [math.atan2(im.q[1], im.q[0]) for im in res.impacts])
    q_ax.set_ylabel("angle (rad)")
    q_ax.legend(loc="upper right", fontsize=7)
    f_ax.plot(res.t[:-1], res.contact_force[:, 0], lw=0.9, color="C4", label="floor force")
    f_ax.axhline(2 * G, ls=":", lw=0.8, color="C3", label="2 m g")
    f_ax.set_ylabel("floor force")
    f_ax.set_xlabel("t")
    f_ax.legend(loc="lower right", fontsize=7)
    q_ax.set_title(f"a four-bar bouncing to rest, h = {res.h} [{backend}]: {kinds(res)}", fontsize=10)
    save(fig, out, f"four_bar_{backend}")


if __name__ == "__main__":
    a = args(__doc__)
    sim = build(model(), a.backend)
    results = {h: simulate(sim, **{**SETUP, "h": h}) for h in STEPS}
    report(results)
    plot(results[SETUP["h"]], a.out, a.backend)
