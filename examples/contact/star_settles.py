"""The paper's four-point star (examples/star.py) with restitution e = 0.8 settles on a face.

h = 0.005, q0 = (0, 3.5, 0), qdot0 = (-2, 0, 5). The bounces lose energy until one vertex
lands plastically and is held (a row of the kinked contact, eq. 86); the star rocks on it
while the next vertex bounces to rest, lands plastically too, and the star rests on a face
with two rows active, sliding at vx (MATH.md, *Sustained contact*). Printed: the impact
kinds; the two plastic impacts; the contact force while rocking on one vertex against the
pivot's closed form; the force at rest against m g; theta at rest; the vertical and
rotational kinetic energy left; admissibility; p_x; E_d at rest against m vx^2/2 + m g L/2.
"""

import math

import matplotlib.pyplot as plt
import numpy as np
import sympy as sp
from _common import args, build, kinds, mark_impacts, save, simulate

import vcigen

M, G, L, E = 1.0, 9.81, 1.0, 0.8
INERTIA = 29 / 192 * M * L**2
SETUP = {"q0": [0.0, 3.5, 0.0], "v0": [-2.0, 0.0, 5.0], "h": 0.005, "t_end": 20.0}


def model() -> vcigen.Model:
    x, y, th, xd, yd, thd = sp.symbols("x y theta xd yd thetad")
    m, g, L = sp.symbols("m g L", positive=True)
    e = sp.Symbol("e")
    inertia = sp.Rational(29, 192) * m * L**2
    return vcigen.Model(
        name="star_settles",
        q=[x, y, th],
        qdot=[xd, yd, thd],
        lagrangian=m / 2 * (xd**2 + yd**2) + inertia / 2 * thd**2 - m * g * y,
        contacts={"floor": y - L / 2 * (sp.Abs(sp.sin(th)) + sp.Abs(sp.cos(th)))},  # eq. (81)
        params={m: M, g: G, L: 1.0, e: E},
        restitution={"floor": e},
    )


def phi(q: np.ndarray) -> np.ndarray:
    """Eq. (81) on an array of positions."""
    return q[:, 1] - L / 2 * (np.abs(np.sin(q[:, 2])) + np.abs(np.cos(q[:, 2])))


def pivot_force(q: np.ndarray, omega: np.ndarray) -> np.ndarray:
    """Normal force on the lowest vertex held on a frictionless floor, the body rotating at omega.

    With the vertex row psi = y - L/2 (s1 sin theta + s2 cos theta) held at 0:
    lambda = (g - d omega^2) / (1/m + c^2 / I), d = L/2 (s1 sin + s2 cos), c = dpsi/dtheta.
    """
    s, co = np.sin(q[:, 2]), np.cos(q[:, 2])
    s1, s2 = np.sign(s), np.sign(co)
    d = L / 2 * (s1 * s + s2 * co)
    c = -L / 2 * (s1 * co - s2 * s)
    return (G - d * omega**2) / (1 / M + c**2 / INERTIA)


def report(res: vcigen.Result) -> None:
    vx = SETUP["v0"][0]
    omega = res.p[:, 2] / INERTIA
    first, face = [im for im in res.impacts if im.kind == "plastic"][:2]
    k1, k2 = np.searchsorted(res.t, [first.t, face.t])  # first grid points after each plastic impact
    impact_steps = {im.step for im in res.impacts}
    rocking = [k for k in range(k1, k2 - 1) if k not in impact_steps]  # one vertex, no impact inside
    lam = res.contact_force[rocking, 0]
    mid = 0.5 * (res.q[rocking] + res.q[[k + 1 for k in rocking]])
    exact = pivot_force(mid, 0.5 * (omega[rocking] + omega[[k + 1 for k in rocking]]))
    wobble = (res.q[k1:k2, 2] + math.pi / 4) % (math.pi / 2) - math.pi / 4
    rest = np.arange(k2 + 1, res.t.size - 1)
    theta_end = (res.q[-1, 2] + math.pi / 4) % (math.pi / 2) - math.pi / 4
    n_other = sum(first.t < im.t < face.t for im in res.impacts)
    print(f"impacts: {kinds(res)}")
    print(
        f"first plastic t = {first.t:.4f} (one vertex held, theta mod pi/2 in "
        f"[{wobble.min():.1e}, {wobble.max():.1e}], {n_other} bounces of the next vertex); "
        f"at rest on a face from t = {face.t:.4f}"
    )
    print(
        f"rocking on one vertex: contact force {lam.min():.4f}..{lam.max():.4f} (mean {lam.mean():.4f}) "
        f"vs m g I/(I + m (L/2)^2) = {M * G * INERTIA / (INERTIA + M * (L / 2) ** 2):.4f}; vs the pivot "
        f"(g - d w^2)/(1/m + c^2/I) at each step's midpoint: max dev {np.abs(lam - exact).max():.1e}"
    )
    force = res.contact_force[rest, 0]
    print(
        f"at rest: contact force mean {force.mean():.12f} vs m g = {M * G:.12f}, "
        f"max dev {np.abs(force - M * G).max():.1e}"
    )
    print(f"final theta mod pi/2: {theta_end:.1e}")
    ke = res.p[:, 1] ** 2 / (2 * M) + res.p[:, 2] ** 2 / (2 * INERTIA)
    print(f"vertical + rotational KE end/start: {ke[-1] / ke[0]:.1e} (target < 1e-9)")
    print(f"min phi on the grid: {phi(res.q).min():.1e} (>= -1e-9)")
    print(f"p_x: max |p_x - m vx| = {np.abs(res.p[:, 0] - M * vx).max():.1e}")
    print(f"E_d end = {res.energy[-1]:.12f} vs m vx^2/2 + m g L/2 = {M * vx**2 / 2 + M * G * L / 2:.12f}")


def plot(res: vcigen.Result, out: str, backend: str) -> None:
    fig, axes = plt.subplots(3, 1, figsize=(8, 7), dpi=110, sharex=True)
    y_ax, th_ax, e_ax = axes
    y_ax.plot(res.t, res.q[:, 1], lw=0.6, color="k")
    mark_impacts(y_ax, res, [im.q[1] for im in res.impacts], size=10)
    y_ax.set_ylabel("height y")
    y_ax.legend(loc="upper right", fontsize=8)
    th_ax.plot(res.t, res.q[:, 2], lw=0.6, color="k")
    mark_impacts(th_ax, res, [im.q[2] for im in res.impacts], size=10)
    th_ax.set_ylabel(r"angle $\theta$")
    e_ax.plot(res.t[:-1], res.energy, lw=0.6, color="k")
    mark_impacts(e_ax, res, [im.energy_before for im in res.impacts], size=10)
    e_ax.axhline(M * SETUP["v0"][0] ** 2 / 2 + M * G * L / 2, ls=":", lw=0.7, color="C3")
    e_ax.set_ylabel(r"$E_d$ (rest value dotted)")
    e_ax.set_xlabel("t")
    y_ax.set_title(f"star, e = {E}, h = {SETUP['h']} [{backend}]: {kinds(res)}", fontsize=10)
    save(fig, out, f"star_settles_{backend}")


if __name__ == "__main__":
    a = args(__doc__)
    res = simulate(build(model(), a.backend), **SETUP)
    report(res)
    plot(res, a.out, a.backend)
