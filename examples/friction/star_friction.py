"""The paper's star (sec. 4.3) with restitution e = 0.8 and Coulomb friction mu = 0.5: it settles and stops.

Without friction the star settles on a face and slides on for ever at its launch speed (examples/contact/
star_settles.py). With friction along the floor, each vertex impact takes Coulomb's impulse (maximal
dissipation within the cone, so energy never rises), and once it rests on a face the sliding is braked
by mu lambda until it sticks. The tangent is the x-coordinate of the lowest vertex,
x - L/2 (sign(sin th) cos th - sign(cos th) sin th), whose rate is the contact point's sliding velocity
xd + L/2 (|sin th| + |cos th|) thd. Printed: the impacts, when it comes to rest, its energy and position;
plotted: x, y, theta and the energy.
"""

import sys
from pathlib import Path

import numpy as np
import sympy as sp

import vcigen

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "contact"))  # the examples' helpers
from _common import args, build, kinds, mark_impacts, save, simulate  # noqa: E402

SETUP = {"q0": [0.0, 3.5, 0.0], "v0": [-2.0, 0.0, 5.0], "h": 0.005, "t_end": 12.0}


def model() -> vcigen.Model:
    x, y, th, xd, yd, thd = sp.symbols("x y theta xd yd thetad")
    m, g, L = sp.symbols("m g L", positive=True)
    e, mu = sp.symbols("e mu")
    inertia = sp.Rational(29, 192) * m * L**2
    return vcigen.Model(
        name="star_friction",
        q=[x, y, th],
        qdot=[xd, yd, thd],
        lagrangian=m / 2 * (xd**2 + yd**2) + inertia / 2 * thd**2 - m * g * y,
        contacts={"floor": y - L / 2 * (sp.Abs(sp.sin(th)) + sp.Abs(sp.cos(th)))},  # eq. (81)
        params={m: 1.0, g: 9.81, L: 1.0, e: 0.8, mu: 0.5},
        restitution={"floor": e},
        friction={
            "floor": (mu, x - L / 2 * (sp.sign(sp.sin(th)) * sp.cos(th) - sp.sign(sp.cos(th)) * sp.sin(th)))
        },
    )


def report(res: vcigen.Result) -> None:
    print(kinds(res))
    moving = np.flatnonzero(np.abs(res.p).max(axis=1) > 1e-12)
    rest = res.t[moving[-1] + 1] if moving.size and moving[-1] + 1 < res.t.size else None
    print(f"at rest (|p| <= 1e-12) from t = {rest}" if rest is not None else "still moving at the end")
    rises = [im.energy_after - im.energy_before for im in res.impacts]
    print(f"largest energy change at an impact: {max(rises):+.2e} (never positive)")
    print(f"end: x = {res.q[-1, 0]:.6f}, y = {res.q[-1, 1]:.6f} (L/2 = 0.5), theta = {res.q[-1, 2]:.6f}")
    print(
        f"E_d: {res.energy[0]:.6f} at the start, {res.energy[-1]:.6f} at the end (m g L/2 = {9.81 / 2:.6f})"
    )


def plot(res: vcigen.Result, out: str, backend: str) -> None:
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(9, 3.8), dpi=110)
    for i, name in enumerate(("x", "y", "theta")):
        ax.plot(res.t, res.q[:, i], lw=0.9, label=name)
    ax.plot(res.t[1:], res.energy, lw=0.9, color="k", label="E_d")
    mark_impacts(ax, res, [im.q[1] for im in res.impacts], size=8)
    ax.set_xlabel("t")
    ax.legend(fontsize=8, ncol=3)
    ax.set_title(f"star, e = 0.8, mu = 0.5 [{backend}]: {kinds(res)}", fontsize=10)
    save(fig, out, f"star_friction_{backend}")


if __name__ == "__main__":
    a = args(__doc__)
    res = simulate(build(model(), a.backend), **SETUP)
    report(res)
    plot(res, a.out, a.backend)
