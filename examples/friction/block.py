"""A block sliding to a stop on a rough floor, and at rest on a rough incline (Coulomb friction, MATH.md).

The block is a unit particle resting on the contact ``y >= 0`` in coordinates along (x) and normal to (y)
an incline of angle a, gravity g, ``friction={"floor": (mu, x)}``. Closed forms: launched at v on a level
floor it stops at t = v / (mu g) after v^2 / (2 mu g) and sticks; released on an incline it stays put when
tan(a) <= mu and otherwise slides down at g (sin a - mu cos a). vcigen holds the floor as a constraint and
the friction force as either a stick constraint (|force| inside Coulomb's cone) or a slip force -mu lambda
against the sliding, switching where the sliding stops or the stick force leaves the cone, located inside
the step. Printed: each case against its closed form; plotted: x(t) and the sliding speed.
"""

import math
import sys
from pathlib import Path

import numpy as np
import sympy as sp

import vcigen

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "contact"))  # the examples' helpers
from _common import args, build, save, simulate  # noqa: E402

G, MU, V = 9.81, 0.4, 2.0
SETUP = {"q0": [0.0, 0.0], "v0": [V, 0.0], "h": 0.01, "t_end": 1.5}


def model() -> vcigen.Model:
    x, y, xd, yd = sp.symbols("x y xd yd")
    g, mu, a = sp.symbols("g mu a")
    return vcigen.Model(
        name="block",
        q=[x, y],
        qdot=[xd, yd],
        lagrangian=(xd**2 + yd**2) / 2 - g * (y * sp.cos(a) + x * sp.sin(a)),
        contacts={"floor": y},
        params={g: G, mu: MU, a: 0.0},
        friction={"floor": (mu, x)},
    )


def main() -> None:
    a = args(__doc__)
    sim = build(model(), a.backend)
    import matplotlib.pyplot as plt

    fig, (ax, bx) = plt.subplots(1, 2, figsize=(10, 3.8), dpi=110)
    res = simulate(sim, **SETUP)
    ts, xs = V / (MU * G), V**2 / (2 * MU * G)
    stop = res.t[np.argmax(np.abs(res.p[:, 0]) < 1e-14)]
    print(
        f"level floor: x(end) = {res.q[-1, 0]:.15f} vs v^2/(2 mu g) = {xs:.15f}; at rest from the grid point "
        f"t = {stop:.2f} (t* = v/(mu g) = {ts:.6f}); friction's work {res.work.sum():.15f} "
        f"vs -v^2/2 = {-(V**2) / 2}"
    )
    ax.plot(res.t, res.q[:, 0], color="k", lw=1, label="level floor, v0 = 2")
    for angle in (0.3, 0.5):
        run = simulate(sim, q0=[0.0, 0.0], v0=[0.0, 0.0], h=0.01, t_end=1.5, params={"a": angle})
        acc = G * (math.sin(angle) - MU * math.cos(angle)) if math.tan(angle) > MU else 0.0
        err = np.max(np.abs(-run.q[:, 0] - acc * run.t**2 / 2))
        what = "sticks" if acc == 0 else f"slides at g(sin a - mu cos a) = {acc:.6f}"
        print(f"incline a = {angle} (tan a = {math.tan(angle):.3f}, mu = {MU}): {what}; max error {err:.1e}")
        ax.plot(run.t, run.q[:, 0], lw=1, label=f"incline a = {angle}")
        bx.plot(run.t, -run.p[:, 0], lw=1, label=f"incline a = {angle}")
    bx.plot(res.t, res.p[:, 0], color="k", lw=1, label="level floor")
    ax.set_xlabel("t")
    ax.set_ylabel("x along the floor")
    bx.set_xlabel("t")
    bx.set_ylabel("sliding speed")
    ax.legend(fontsize=8)
    bx.legend(fontsize=8)
    fig.suptitle(f"block on a rough floor, mu = {MU} [{a.backend}]", fontsize=10)
    save(fig, a.out, f"block_{a.backend}")


if __name__ == "__main__":
    main()
