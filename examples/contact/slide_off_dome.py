"""A particle slides off the top of a frictionless dome and leaves it where the normal force vanishes.

Contact sqrt(x^2 + y^2) - R >= 0 (R = 1), start on top with v0 = (0.1, 0), g = 9.81. On the dome
the angle from the top obeys theta'' = g sin(theta) / R and the normal force is
m (g cos theta - R theta'^2); it vanishes at cos theta = (v0^2 + 2 g R) / (3 g R), where the
contact is released (MATH.md, *Sustained contact*, lift-off). Printed: the exact lift-off time
(scipy solve_ivp with an event, rtol = atol = 1e-12), vcigen's (res.liftoffs) at three steps
with errors and the observed order, and the contact force against m (g cos theta - v^2/R).
"""

import math

import matplotlib.pyplot as plt
import numpy as np
import sympy as sp
from _common import args, build, mark_impacts, save, simulate
from scipy.integrate import solve_ivp

import vcigen
from vcigen.analysis import fit_order

M, G, R = 1.0, 9.81, 1.0
SETUP = {"q0": [0.0, R], "v0": [0.1, 0.0], "h": 0.01, "t_end": 1.6}
STEPS = (0.01, 0.005, 0.0025)


def model() -> vcigen.Model:
    x, y, xd, yd = sp.symbols("x y xd yd")
    m, g, r = sp.symbols("m g R", positive=True)
    return vcigen.Model(
        name="slide_off_dome",
        q=[x, y],
        qdot=[xd, yd],
        lagrangian=m / 2 * (xd**2 + yd**2) - m * g * y,
        contacts={"dome": sp.sqrt(x**2 + y**2) - r},
        params={m: M, g: G, r: R},
    )


def exact_sliding():
    """theta'' = g sin(theta) / R from the top until the normal force g cos theta - R theta'^2 is 0."""

    def normal(_t, z):
        return G * math.cos(z[0]) - R * z[1] ** 2

    normal.terminal, normal.direction = True, -1
    return solve_ivp(
        lambda _t, z: [z[1], G * math.sin(z[0]) / R],
        (0.0, 5.0),
        [0.0, SETUP["v0"][0] / R],
        method="DOP853",
        events=normal,
        rtol=1e-12,
        atol=1e-12,
        dense_output=True,
    )


def sliding_force(res: vcigen.Result) -> tuple[np.ndarray, np.ndarray]:
    """Measured contact force on the steps with the dome held, and m (g cos theta - v^2/R) there."""
    held = np.flatnonzero(res.active[:-1, 0] & res.active[1:, 0])
    mid = 0.5 * (res.q[held] + res.q[held + 1])
    vel = 0.5 * (res.p[held] + res.p[held + 1]) / M
    cos = mid[:, 1] / np.hypot(mid[:, 0], mid[:, 1])
    return res.contact_force[held, 0], M * (G * cos - np.sum(vel**2, axis=1) / R)


def report(results: dict[float, vcigen.Result], ref) -> None:
    v0 = SETUP["v0"][0]
    t_exact, (theta, _) = ref.t_events[0][0], ref.y_events[0][0]
    print(
        f"exact lift-off (solve_ivp, rtol = atol = 1e-12): t = {t_exact:.10f}, cos theta = "
        f"{math.cos(theta):.12f} vs (v0^2 + 2 g R)/(3 g R) = {(v0**2 + 2 * G * R) / (3 * G * R):.12f}"
    )
    errors = []
    for h, res in results.items():
        t_lift = [t for t, c in res.liftoffs if c == "dome"][0]
        errors.append(abs(t_lift - t_exact))
        lam, closed = sliding_force(res)
        print(
            f"h = {h}: lift-off t = {t_lift:.10f}, error {errors[-1]:.2e}; "
            f"{len(res.liftoffs)} lift-off(s), {res.n_impacts} impacts; contact force vs "
            f"m (g cos theta - v^2/R): max dev {np.abs(lam - closed).max():.1e}"
        )
    print(f"observed order of the lift-off time: {fit_order(list(results), errors):.2f} (expected 2)")


def plot(res: vcigen.Result, ref, out: str, backend: str) -> None:
    t_exact = ref.t_events[0][0]
    lift = [t for t, c in res.liftoffs if c == "dome"][0]
    fig, (path_ax, force_ax) = plt.subplots(1, 2, figsize=(10, 4.2), dpi=110)
    arc = np.linspace(0, 2 * np.pi, 400)
    path_ax.fill(R * np.cos(arc), R * np.sin(arc), color="0.85", label="dome")
    path_ax.plot(res.q[:, 0], res.q[:, 1], ".-", ms=2, lw=0.6, color="k", label="particle")
    k = np.searchsorted(res.t, lift)
    path_ax.plot(*res.q[k], "o", color="C3", label=f"first grid point after lift-off (t = {res.t[k]:.2f})")
    theta_lift = ref.y_events[0][0][0]
    path_ax.plot(
        R * np.sin(theta_lift), R * np.cos(theta_lift), "x", ms=8, color="C0", label="exact lift-off"
    )
    mark_impacts(path_ax, res, [im.q[1] for im in res.impacts])
    path_ax.set_aspect("equal")
    path_ax.set_xlim(-1.2, 1.6)
    path_ax.set_ylim(-1.2, 1.3)
    path_ax.set_xlabel("x")
    path_ax.set_ylabel("y")
    path_ax.legend(loc="lower left", fontsize=7)
    ts = np.linspace(0, t_exact, 300)
    theta, omega = ref.sol(ts)
    force_ax.plot(ts, M * (G * np.cos(theta) - R * omega**2), lw=2, color="0.7", label="exact")
    force_ax.step(res.t[:-1], res.contact_force[:, 0], where="post", lw=0.8, color="C4", label="vcigen")
    force_ax.axvline(t_exact, ls=":", lw=0.8, color="C3", label=f"exact lift-off t = {t_exact:.4f}")
    force_ax.set_xlabel("t")
    force_ax.set_ylabel(r"contact force $\lambda$")
    force_ax.legend(fontsize=8)
    fig.suptitle(f"particle sliding off a dome, h = {res.h} [{backend}]", fontsize=10)
    save(fig, out, f"slide_off_dome_{backend}")


if __name__ == "__main__":
    a = args(__doc__)
    sim = build(model(), a.backend)
    ref = exact_sliding()
    results = {h: simulate(sim, **{**SETUP, "h": h}) for h in STEPS}
    report(results, ref)
    plot(results[SETUP["h"]], ref, a.out, a.backend)
